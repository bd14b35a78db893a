"""Reading OpenFOAM files: foamlib for dictionaries and fields, plus two narrow gaps.

foamlib parses dictionaries, headers, ``boundary`` files and ASCII/binary vector lists
well, and everything that is a dictionary goes through it. Two things it does not cover,
so they are handled here, each kept as small as possible:

* binary lists: foamlib ignores the header's ``arch`` and assumes 32-bit labels and
  64-bit scalars, so a ``label=64`` or ``scalar=32`` mesh would be misread.
  :func:`binary_lists` reads ``N(<raw bytes>)`` with the sizes the header gives.
* ASCII ``faceList`` files with polygons of more than four vertices (snappyHexMesh,
  polyDualMesh, gmsh): foamlib's fast path accepts only triangles and quads and its
  general parser takes seconds for a few hundred polygons (and misreads a one-polygon
  list as binary). :func:`ascii_faces` reads any polygon size with numpy.

For large ASCII lists written one item per line (OpenFOAM's layout), only the lines a
patch needs are handed to the parser: a patch is a few hundred of a mesh's 10^5 faces.

Files may be gzip-compressed (``points.gz``): OpenFOAM writes that with
``writeCompression on`` and reads either.
"""

from __future__ import annotations

import gzip
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import CaseError

_HEADER = re.compile(rb"FoamFile\s*\{[^{}]*\}", re.S)
_ARCH = re.compile(r"label\s*=\s*(\d+)|scalar\s*=\s*(\d+)|(LSB|MSB)")


def existing(path: str | os.PathLike[str]) -> Path | None:
    """``path`` or ``path.gz``, whichever exists (OpenFOAM reads both)."""
    path = Path(path)
    if path.is_file():
        return path
    gz = path.with_name(path.name + ".gz")
    if gz.is_file():
        return gz
    return None


def read_bytes(path: str | os.PathLike[str]) -> tuple[Path, bytes]:
    """The file's contents (decompressed when gzip), with the path actually read."""
    found = existing(path)
    if found is None:
        raise CaseError(f"{path}: no such file (nor {Path(path).name}.gz)")
    data = found.read_bytes()
    if found.suffix == ".gz":
        data = gzip.decompress(data)
    return found, data


def loads(path: Path, data: bytes) -> Any:
    """Parse a whole OpenFOAM file with foamlib (no defensive deep copies).

    Returns a dict with ``"FoamFile"`` (the header) and the entries, or the bare data
    under key ``None`` for list files. Parse errors become :class:`CaseError` naming the
    file.
    """
    # foamlib (and the asyncio and rich it brings) is imported where a file is read: every
    # `import gymprecice` loads this plugin to register environments, and most processes
    # that do (coupling workers, env workers, the lab's commands) never parse a file
    from foamlib import FoamFile, FoamFileDecodeError

    try:
        return FoamFile.loads(data, include_header=True)
    except (FoamFileDecodeError, ValueError, TypeError) as exc:
        raise CaseError(f"{path}: cannot be parsed as an OpenFOAM file: {exc}") from None


def _standalone(parsed: Any) -> Any:
    """The bare data of a list file (foamlib keys it ``None`` when there is a header)."""
    return parsed.get(None) if isinstance(parsed, dict) else parsed


def load(path: str | os.PathLike[str]) -> Any:
    """:func:`loads` on a file found with :func:`existing` (``.gz`` accepted)."""
    found, data = read_bytes(path)
    return loads(found, data)


@dataclass(frozen=True)
class Header:
    """The ``FoamFile`` header fields that decide how to read a file's data."""

    format: str = "ascii"
    class_name: str = ""
    label_bytes: int = 4
    scalar_bytes: int = 8
    little_endian: bool = True
    end: int = 0  # offset just after the header block

    @property
    def default_arch(self) -> bool:
        """True for the layout foamlib assumes for binary data."""
        return self.label_bytes == 4 and self.scalar_bytes == 8 and self.little_endian

    def label_dtype(self) -> np.dtype:
        return np.dtype(("<" if self.little_endian else ">") + f"i{self.label_bytes}")

    def scalar_dtype(self) -> np.dtype:
        return np.dtype(("<" if self.little_endian else ">") + f"f{self.scalar_bytes}")


def header(path: Path, data: bytes) -> Header:
    """Parse only the ``FoamFile { ... }`` block (cheap, whatever the file size)."""
    match = _HEADER.search(data, 0, min(len(data), 8192))
    if match is None:
        return Header()
    fields = loads(path, match.group(0)).get("FoamFile", {})
    label_bytes, scalar_bytes, little = 4, 8, True
    arch = str(fields.get("arch", "")).strip('"')
    for label, scalar, order in _ARCH.findall(arch):
        if label:
            label_bytes = int(label) // 8
        if scalar:
            scalar_bytes = int(scalar) // 8
        if order:
            little = order == "LSB"
    return Header(
        format=str(fields.get("format", "ascii")),
        class_name=str(fields.get("class", "")),
        label_bytes=label_bytes,
        scalar_bytes=scalar_bytes,
        little_endian=little,
        end=match.end(),
    )


_SKIP = re.compile(rb"(?:\s+|//[^\n]*|/\*.*?\*/)*", re.S)
_COUNT = re.compile(rb"(\d+)\s*\(")


def _list_start(path: Path, data: bytes, pos: int) -> tuple[int, int]:
    """(count, offset after the opening parenthesis) of the list starting at ``pos``."""
    pos = _SKIP.match(data, pos).end()
    match = _COUNT.match(data, pos)
    if match is None:
        raise CaseError(f"{path}: expected '<count>(' at byte {pos}")
    return int(match.group(1)), match.end()


def binary_lists(
    path: Path, data: bytes, head: Header, dtypes: list[np.dtype], widths: list[int]
) -> list[np.ndarray]:
    """Consecutive binary lists ``N(<raw bytes>)`` read with explicit element types.

    ``widths`` gives the components per element (3 for a vector). Used for meshes whose
    ``arch`` differs from what foamlib assumes.
    """
    pos = head.end
    out = []
    for dtype, width in zip(dtypes, widths):
        count, pos = _list_start(path, data, pos)
        nbytes = count * width * dtype.itemsize
        end = pos + nbytes
        if data[end : end + 1] != b")":
            raise CaseError(
                f"{path}: binary list of {count} items ({dtype}, x{width}) is truncated "
                f"or its arch header is wrong"
            )
        arr = np.frombuffer(data, dtype=dtype, count=count * width, offset=pos)
        arr = arr.astype(dtype.newbyteorder("="), copy=True)
        out.append(arr.reshape(-1, width) if width > 1 else arr)
        pos = end + 1
    return out


@dataclass(frozen=True)
class _Lines:
    """An ASCII list written one item per line (OpenFOAM's layout for long lists)."""

    count: int
    region: bytes  # from just after "(" to just before the closing ")"
    starts: np.ndarray  # item i is region[starts[i] + 1 : starts[i + 1] + 1]

    def item_lines(self, index: np.ndarray) -> bytes:
        """The lines of the given items (in the given order), newline-terminated."""
        s, r = self.starts, self.region
        return b"".join(r[s[i] + 1 : s[i + 1] + 1] for i in index.tolist())

    def span(self, start: int, stop: int) -> bytes:
        return self.region[self.starts[start] + 1 : self.starts[stop] + 1] if stop > start else b""


def _one_per_line(path: Path, data: bytes, head: Header) -> tuple[int, _Lines | None, bytes]:
    """(count, line layout or None, list body) of the ASCII list after the header."""
    count, body = _list_start(path, data, head.end)
    close = data.rfind(b")")
    region = data[body:close]
    newlines = np.flatnonzero(np.frombuffer(region, dtype=np.uint8) == 10)
    if len(newlines) == count + 1 and (count == 0 or newlines[0] == 0):
        return count, _Lines(count, region, np.append(newlines, len(region))), region
    return count, None, region


def ascii_faces(
    path: Path, data: bytes, head: Header, start: int = 0, stop: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Faces ``start:stop`` of an ASCII ``faceList`` as compact (offsets, vertex labels).

    OpenFOAM writes one face per line, so when the file has that shape only the lines of
    the wanted faces are converted (a patch is a small slice of a large mesh); any other
    layout falls back to converting the whole list.
    """
    count, lines, region = _one_per_line(path, data, head)
    stop = count if stop is None else stop
    if not 0 <= start <= stop <= count:
        raise CaseError(f"{path}: faces {start}:{stop} requested but the file has {count}")
    if lines is not None:
        offsets, flat = _parse_faces_text(path, lines.span(start, stop))
        if len(offsets) - 1 == stop - start:
            return offsets, flat
    offsets, flat = _parse_faces_text(path, region)
    if len(offsets) - 1 != count:
        raise CaseError(f"{path}: header says {count} faces but {len(offsets) - 1} were read")
    lo, hi = offsets[start], offsets[stop]
    return offsets[start : stop + 1] - lo, flat[lo:hi]


def ascii_vectors(path: Path, data: bytes, head: Header, rows: np.ndarray | None) -> np.ndarray:
    """Rows of an ASCII vector list (all when ``rows`` is None), parsed by foamlib.

    With the one-per-line layout only the wanted lines are handed to foamlib (a patch
    uses a few hundred of a mesh's points); otherwise the whole list is parsed.
    """
    count, lines, _ = _one_per_line(path, data, head)
    if rows is not None and len(rows) and (rows.min() < 0 or rows.max() >= count):
        raise CaseError(f"{path}: point {int(rows.max())} requested but the file has {count}")
    if lines is not None and rows is not None:
        text = b"%d\n(\n" % len(rows) + lines.item_lines(rows) + b")\n"
        parsed = np.asarray(_standalone(loads(path, text)), dtype=np.float64).reshape(-1, 3)
        if len(parsed) == len(rows):
            return parsed
    parsed = np.asarray(_standalone(loads(path, data)), dtype=np.float64)
    if parsed.ndim != 2 or parsed.shape != (count, 3):
        raise CaseError(f"{path}: expected {count} 3-vectors, got shape {parsed.shape}")
    return parsed if rows is None else parsed[rows]


def _parse_faces_text(path: Path, text: bytes) -> tuple[np.ndarray, np.ndarray]:
    """``k(a b c ...)`` items -> offsets and flat labels, vectorised.

    Each ``(`` becomes a ``-1`` marker so the vertex count is the token before it; labels
    are never negative, so markers cannot be confused with data.
    """
    if not text.strip():
        return np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64)
    tokens = text.replace(b"(", b" -1 ").replace(b")", b" ").decode("ascii", "replace")
    values = np.fromstring(tokens, dtype=np.int64, sep=" ")
    markers = np.flatnonzero(values == -1)
    if len(markers) == 0 or markers[0] == 0:
        raise CaseError(f"{path}: faces list is not of the form k(v1 ... vk)")
    sizes = values[markers - 1]
    keep = np.ones(len(values), dtype=bool)
    keep[markers] = False
    keep[markers - 1] = False
    flat = values[keep]
    offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    if offsets[-1] != len(flat):
        raise CaseError(f"{path}: faces list is malformed (vertex counts do not add up)")
    return offsets, flat
