"""Incremental readers of OpenFOAM function-object output (probes, forces, force coefficients).

An RL step needs the few rows the solver wrote since the last step, while the solver
is still writing: re-reading whole files every step costs O(episode length) per step.
These readers keep a byte offset per file, hand back only complete new lines, hold a
half-written last line until its newline arrives, and follow the solver into a new
start-time directory after a restart (``postProcessing/<name>/<startTime>/<file>``).

File layouts (checked against OpenFOAM v1912, and the other layouts in use):

* probes ``postProcessing/probes/<t>/<field>``: ``# Probe i (x y z)`` lines, then rows
  ``time v0 v1 ...`` (scalars) or ``time (x y z) (x y z) ...`` (vectors, tensors).
* forces: v1912 and later ESI write ``force.dat`` (and ``moment.dat``) with header
  ``# Time (total_x total_y total_z) (pressure_x ...) (viscous_x ...)`` and rows in that
  shape (v2006+ without the parentheses); OpenFOAM.org and older ESI write ``forces.dat``
  with ``# Time forces(pressure viscous porous) moment(...)`` and nested parentheses.
* force coefficients: ``coefficient.dat`` (ESI: ``# Time Cd Cs Cl CmRoll ...``) or
  ``forceCoeffs.dat`` (OpenFOAM.org: ``# Time Cm Cd Cl Cl(f) Cl(r)``).

Column names come from the file's own ``# Time`` header line, so every layout reads the
same way: ``rows.column("Cd")``, ``rows.column("total_x")``.

After a run, :func:`read_force_coeffs` reads a forceCoeffs function object's whole
history at once (restarts joined, the later run winning where they overlap).

The solver may run ahead of the controller, so by the time an env reads the step that
ended at ``t`` the files may hold rows past ``t``: ``wait_until(t)`` hands out only the
step's rows, up to ``t``, and keeps the later ones for the next read
(:mod:`gymprecice.readers`); an observation (``.last``) or a reward (``.mean()`` over the
step) is then the same whatever the solver's lead.
"""

from __future__ import annotations

import math
import os
import re
import time as _time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gymprecice.plugin import GymPreciceError, rows_through, time_tolerance

__all__ = [
    "ForceCoeffsReader",
    "ForcesReader",
    "OutputFormatError",
    "OutputTimeoutError",
    "ProbesReader",
    "Rows",
    "TableReader",
    "last_per_time",
    "read_force_coeffs",
    "time_dirs",
]


class OutputFormatError(GymPreciceError, ValueError):
    """A complete line of a solver output file cannot be read (names file and line)."""


class OutputTimeoutError(GymPreciceError, TimeoutError):
    """The solver did not write the awaited time within the timeout."""


@dataclass
class Rows:
    """Rows read from one output: ``time`` (k,) and ``values`` (k, ...).

    ``values`` is (k, columns) for tables and scalar probes, (k, probes, components) for
    vector or tensor probes. ``columns`` names the second axis.
    """

    time: np.ndarray
    values: np.ndarray
    columns: tuple[str, ...] = ()
    locations: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.time)

    def column(self, name: str) -> np.ndarray:
        """Values of one named column (e.g. ``"Cd"``, ``"total_x"``, ``"probe3"``)."""
        try:
            index = self.columns.index(name)
        except ValueError:
            raise KeyError(f"no column {name!r}; the columns are {list(self.columns)}") from None
        return self.values[:, index]

    @property
    def last(self) -> np.ndarray:
        """The newest row's values (what an observation usually needs)."""
        if not len(self):
            raise IndexError("no rows")
        return self.values[-1]

    def take(self, start: int, stop: int | None = None) -> Rows:
        """Rows ``start`` to ``stop`` (excluded), columns and locations kept."""
        return Rows(self.time[start:stop], self.values[start:stop], self.columns, self.locations)

    @staticmethod
    def concatenate(parts: Sequence[Rows]) -> Rows:
        parts = [p for p in parts if len(p)] or list(parts[:1])
        if not parts:
            return Rows(np.zeros(0), np.zeros((0, 0)))
        if len(parts) == 1:
            return parts[0]
        return Rows(
            np.concatenate([p.time for p in parts]),
            np.concatenate([p.values for p in parts]),
            parts[-1].columns,
            parts[-1].locations,
        )


def time_dirs(directory: Path) -> list[tuple[float, Path]]:
    """Sub-directories whose names are times, sorted by time."""
    out = []
    try:
        entries = list(os.scandir(directory))
    except FileNotFoundError:
        return []
    for entry in entries:
        if not entry.is_dir():
            continue
        try:
            value = float(entry.name)
        except ValueError:
            continue
        if math.isfinite(value):
            out.append((value, Path(entry.path)))
    out.sort(key=lambda item: item[0])
    return out


#: Parentheses, tabs and carriage returns become blanks before numbers are read.
_BLANKS = bytes.maketrans(b"()\t\r", b"    ")

_GROUP = re.compile(r"(\w+)\(([^()]*)\)|\(([^()]*)\)|([^\s()]+)")


def _column_names(header: str) -> list[str]:
    """Names from a ``# Time ...`` header, parentheses resolved.

    ``(total_x total_y total_z)`` gives its three words; ``forces(pressure viscous)``
    gives ``forces_pressure_x`` ... ``forces_viscous_z``; ``Cd(f)`` stays ``Cd(f)``.
    """
    names: list[str] = []
    for outer, inner, bare_group, word in _GROUP.findall(header):
        if outer:
            parts = inner.split()
            if len(parts) <= 1:
                names.append(f"{outer}({inner.strip()})")
            else:
                names += [f"{outer}_{p}_{c}" for p in parts for c in "xyz"]
        elif bare_group:
            names += bare_group.split()
        elif word:
            names.append(word)
    return names


class _Segment:
    """One output file being followed, with its offset and unfinished last line."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0
        self.partial = b""
        self.line_no = 0  # complete lines consumed so far
        self.inode: int | None = None
        self.width: int | None = None  # numbers per data row
        self.header: list[str] = []

    def read_block(self) -> tuple[int, bytes]:
        """New complete lines as one block (no final newline) and its first line number."""
        try:
            st = self.path.stat()
        except FileNotFoundError:
            return self.line_no + 1, b""
        if self.inode is not None and (st.st_ino != self.inode or st.st_size < self.offset):
            # The file was replaced (e.g. a restart at the same time overwrote it).
            self.offset, self.partial, self.line_no = 0, b"", 0
            self.width, self.header = None, []
        self.inode = st.st_ino
        first = self.line_no + 1
        if st.st_size == self.offset:
            return first, b""
        with self.path.open("rb") as handle:
            handle.seek(self.offset)
            chunk = handle.read()
        self.offset += len(chunk)
        data = self.partial + chunk
        cut = data.rfind(b"\n")
        if cut < 0:
            self.partial = data
            return first, b""
        self.partial = data[cut + 1 :]
        block = data[:cut]
        self.line_no += block.count(b"\n") + 1
        return first, block


class TableReader:
    """Follow ``<directory>/<startTime>/<file>`` across restarts, returning new rows.

    ``file_names`` are tried in order in each start-time directory (the first that exists
    is followed); ``start_time`` skips start-time directories before it (an episode's
    reader ignores the pre-run's output). Files renamed by OpenFOAM on a restart at an
    existing time (``force_0.1.dat``) are followed after the original.

    ``wait_until(t, timeout)`` returns the rows of the step that ended at ``t`` (those
    after the previous ``wait_until``, up to ``t``) and keeps rows past ``t`` for the next
    read; asked again for the same ``t`` it returns the same rows. ``read_new()`` returns
    every row not handed out yet, whatever its time.
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        file_names: Sequence[str],
        *,
        start_time: float | None = None,
        time_tolerance: float = 1e-9,
    ) -> None:
        self.directory = Path(directory)
        self.file_names = tuple(file_names)
        self.start_time = start_time
        self.time_tolerance = time_tolerance
        self._segments: list[_Segment] = []
        self._current = -1
        self._columns: tuple[str, ...] = ()
        self._last_time: float | None = None
        #: rows read from the files but not handed out yet (past a wait_until's time)
        self._pending: Rows | None = None
        #: the last wait_until's time and answer, returned again for the same time
        self._step: tuple[float, Rows] | None = None
        self._closed = False

    # ---------------------------------------------------------------- public API
    @property
    def latest_time(self) -> float | None:
        """Time of the newest row handed out so far (``None`` before the first)."""
        return self._last_time

    @property
    def files(self) -> list[Path]:
        """The files followed so far, in order."""
        return [s.path for s in self._segments]

    def read_new(self) -> Rows:
        """Every complete row not handed out yet (possibly none), whatever its time."""
        self._read_files()
        rows, self._pending = self._pending, None
        return self._handed_out(rows if rows is not None else self._empty())

    def _read_files(self) -> None:
        """Add the rows completed in the files since the last look to the pending rows."""
        if self._closed:
            raise ValueError(f"reader of {self.directory} is closed")
        parts = [] if self._pending is None else [self._pending]
        if self._current < 0:
            self._discover()
        while self._current >= 0:
            seg = self._segments[self._current]
            rows = self._parse(seg, *seg.read_block())
            parts.append(rows)
            if not len(rows) and self._current + 1 == len(self._segments):
                # Nothing new here: has the solver restarted into a newer directory?
                # (Looked for only then, so a growing file costs no directory listing.)
                self._discover()
            if self._current + 1 < len(self._segments):
                # A newer start-time directory exists: this file is finished. Whatever is
                # left after its last newline was cut off when that run stopped.
                self._current += 1
                continue
            break
        rows = Rows.concatenate(parts) if parts else self._empty()
        self._pending = rows if len(rows) else None

    def _handed_out(self, rows: Rows) -> Rows:
        if len(rows):
            self._last_time = float(rows.time[-1])
        return rows

    def wait_until(self, time: float, timeout: float, *, max_interval: float = 0.05) -> Rows:
        """Block until a row at ``time`` (or later) has been read; return the step's rows.

        The step's rows are the rows not handed out yet up to the row at ``time``
        (:func:`~gymprecice.readers.rows_through`); rows past ``time`` stay for the next
        read, and a second call for the same ``time`` returns the same rows. Polls with
        intervals growing from 1 ms to ``max_interval`` (file polling works on every file
        system, unlike inotify on network mounts). Raises :class:`OutputTimeoutError`
        after ``timeout`` seconds.
        """
        tolerance = time_tolerance(time, self.time_tolerance)
        if self._step is not None and abs(self._step[0] - time) <= tolerance:
            return self._step[1]
        deadline = _time.monotonic() + timeout
        target = time - tolerance
        interval = 0.001
        while True:
            self._read_files()
            pending = self._pending
            seen = float(pending.time[-1]) if pending is not None else self._last_time
            if seen is not None and seen >= target:
                if pending is None:
                    rows = self._empty()
                else:
                    count = rows_through(
                        pending.time, time, self.time_tolerance, handed_out=self._last_time
                    )
                    rows = pending.take(0, count)
                    self._pending = pending.take(count) if count < len(pending) else None
                self._step = (time, self._handed_out(rows))
                return rows
            remaining = deadline - _time.monotonic()
            if remaining <= 0:
                seen = "nothing yet" if seen is None else f"t={seen:g}"
                where = ", ".join(str(p) for p in self.files) or f"{self.directory}/<time>/" + (
                    "|".join(self.file_names)
                )
                raise OutputTimeoutError(
                    f"no output for t={time:g} within {timeout:g} s in {where} (read {seen}); "
                    "is the solver running and is the function object writing every step?"
                )
            _time.sleep(min(interval, remaining))
            interval = min(interval * 2, max_interval)

    def read_all(self) -> Rows:
        """Every row from the start (a fresh pass, independent of ``read_new``)."""
        clone = type(self).__new__(type(self))
        clone.__dict__.update(self.__dict__)
        clone._segments, clone._current, clone._last_time = [], -1, None
        clone._pending, clone._step = None, None
        return clone.read_new()

    def close(self) -> None:
        """Release the reader (files are opened per read, so nothing stays open)."""
        self._closed = True

    def __enter__(self) -> TableReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---------------------------------------------------------------- internals
    def _empty(self) -> Rows:
        return Rows(np.zeros(0), np.zeros((0, len(self._columns))), self._columns)

    def _discover(self) -> None:
        known = {s.path for s in self._segments}
        found: list[Path] = []
        for value, path in time_dirs(self.directory):
            if self.start_time is not None and value < self.start_time - self.time_tolerance * max(
                1.0, abs(self.start_time)
            ):
                continue
            found += self._files_in(path)
        new = [p for p in found if p not in known]
        if not new:
            return
        # Only files that sort after the one being followed can be joined.
        order = {p: i for i, p in enumerate(found)}
        current = self._segments[self._current].path if self._current >= 0 else None
        floor = order.get(current, -1) if current is not None else -1
        for path in new:
            if order[path] > floor:
                self._segments.append(_Segment(path))
        self._segments.sort(key=lambda s: order.get(s.path, -1))
        if current is None and self._segments:
            self._current = 0
        elif current is not None:
            self._current = next(i for i, s in enumerate(self._segments) if s.path == current)

    def _files_in(self, directory: Path) -> list[Path]:
        for name in self.file_names:
            base = directory / name
            if base.is_file():
                stem, suffix = os.path.splitext(name)
                renamed = []
                pattern = re.compile(re.escape(stem) + r"_([-+0-9.eE]+)" + re.escape(suffix) + "$")
                for entry in os.scandir(directory):
                    match = pattern.match(entry.name)
                    if match:
                        try:
                            renamed.append((float(match.group(1)), Path(entry.path)))
                        except ValueError:
                            continue
                return [base] + [p for _, p in sorted(renamed)]
        return []

    def _header_line(self, seg: _Segment, text: str) -> None:
        seg.header.append(text)
        body = text.lstrip("#").strip()
        if body.startswith("Time"):
            names = _column_names(body[4:])
            if names:
                self._columns = tuple(names)

    def _parse(self, seg: _Segment, first: int, block: bytes) -> Rows:
        """Rows of a block of complete lines; comment lines update the header state."""
        if not block.strip():
            return self._empty()
        if b"#" not in block:
            return self._rows(seg, self._table(seg, first, block))
        tables = []
        run: list[bytes] = []
        run_start = first
        for number, line in enumerate(block.split(b"\n"), start=first):
            if line.lstrip().startswith(b"#"):
                if run:
                    tables.append(self._table(seg, run_start, b"\n".join(run)))
                    run = []
                self._header_line(seg, line.decode("utf-8", "replace").strip())
                continue
            if not run:
                run_start = number
            run.append(line)
        if run:
            tables.append(self._table(seg, run_start, b"\n".join(run)))
        tables = [t for t in tables if len(t)]
        if not tables:
            return self._empty()
        return self._rows(seg, np.concatenate(tables))

    def _table(self, seg: _Segment, first: int, block: bytes) -> np.ndarray:
        """Numbers of data lines as a (rows, width) array.

        numpy's C reader converts the block and refuses ragged rows; only when it
        refuses, or the width differs from the file's first row, are the lines looked at
        one by one to name the bad one.
        """
        lines = block.translate(_BLANKS).decode("ascii", "replace").split("\n")
        try:
            table = np.loadtxt(lines, dtype=float, comments=None, ndmin=2)
        except ValueError:
            table = None
        if table is not None and table.size == 0:
            return np.zeros((0, seg.width or 0))
        if table is not None and seg.width is None:
            seg.width = self._row_width(seg, table.shape[1])
        if table is None or table.shape[1] != seg.width:
            self._diagnose(seg, first, block)
        return table

    def _diagnose(self, seg: _Segment, first: int, block: bytes) -> None:
        """Raise :class:`OutputFormatError` for the first bad line of ``block``."""
        for index, raw in enumerate(block.split(b"\n")):
            tokens = raw.translate(_BLANKS).split()
            if not tokens:
                continue
            shown = raw.decode("utf-8", "replace").strip()[:120]
            if seg.width is None:
                seg.width = self._row_width(seg, len(tokens))
            if len(tokens) != seg.width:
                raise OutputFormatError(
                    f"{seg.path}:{first + index}: expected {seg.width} numbers, found "
                    f"{len(tokens)} (truncated or corrupt line: {shown!r})"
                )
            try:
                [float(x) for x in tokens]
            except ValueError:
                raise OutputFormatError(
                    f"{seg.path}:{first + index}: not a number in line {shown!r}"
                ) from None
        raise OutputFormatError(f"{seg.path}:{first}: unreadable rows")

    def _row_width(self, seg: _Segment, numbers: int) -> int:
        return numbers

    def _rows(self, seg: _Segment, table: np.ndarray) -> Rows:
        ncols = table.shape[1] - 1
        if len(self._columns) != ncols:
            self._columns = tuple(f"c{i}" for i in range(1, ncols + 1))
        return Rows(table[:, 0], table[:, 1:], self._columns)


class ProbesReader(TableReader):
    """Rows of ``postProcessing/<name>/<t>/<field>``: one value (or vector) per probe.

    ``values`` is (k, probes) for scalar fields and (k, probes, components) otherwise;
    ``locations`` holds the probe positions from the file header.
    """

    _PROBE = re.compile(r"#\s*Probe\s+(\d+)\s*\(([^)]*)\)")

    def __init__(
        self,
        directory: str | os.PathLike[str],
        field: str,
        *,
        start_time: float | None = None,
        time_tolerance: float = 1e-9,
    ) -> None:
        super().__init__(directory, [field], start_time=start_time, time_tolerance=time_tolerance)
        self.field = field
        self._locations: dict[int, tuple[float, ...]] = {}
        self._components: int | None = None
        self._cached: tuple[tuple[str, ...], np.ndarray | None] | None = None

    @property
    def locations(self) -> np.ndarray | None:
        """Probe positions (n, 3) as the file header lists them."""
        return self._described()[1]

    def _described(self) -> tuple[tuple[str, ...], np.ndarray | None]:
        if self._cached is None:
            order = sorted(self._locations)
            where = np.array([self._locations[i] for i in order]) if order else None
            self._cached = (tuple(f"probe{i}" for i in order), where)
        return self._cached

    def _header_line(self, seg: _Segment, text: str) -> None:
        seg.header.append(text)
        match = self._PROBE.match(text)
        if match:
            self._locations[int(match.group(1))] = tuple(float(x) for x in match.group(2).split())
            self._cached = None

    def _row_width(self, seg: _Segment, numbers: int) -> int:
        nprobes = len(self._locations)
        values = numbers - 1
        if nprobes == 0 or values % nprobes:
            raise OutputFormatError(
                f"{seg.path}: {values} values per row do not match the {nprobes} probes of "
                "the header"
            )
        self._components = values // nprobes
        return numbers

    def _empty(self) -> Rows:
        n = len(self._locations)
        shape = (0, n) if (self._components or 1) == 1 else (0, n, self._components)
        return Rows(np.zeros(0), np.zeros(shape), self._probe_columns(), self.locations)

    def _probe_columns(self) -> tuple[str, ...]:
        return self._described()[0]

    def _rows(self, seg: _Segment, table: np.ndarray) -> Rows:
        values = table[:, 1:]
        if self._components and self._components > 1:
            values = values.reshape(len(table), -1, self._components)
        return Rows(table[:, 0], values, self._probe_columns(), self.locations)


class ForcesReader(TableReader):
    """Rows of ``postProcessing/<name>/<t>/force.dat`` (or ``forces.dat``).

    ``which="moment"`` reads ``moment.dat`` instead. Columns are named from the header,
    e.g. ``total_x`` (ESI) or ``forces_pressure_x`` (OpenFOAM.org ``forces.dat``).
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        which: str = "force",
        start_time: float | None = None,
        time_tolerance: float = 1e-9,
    ) -> None:
        if which not in ("force", "moment"):
            raise ValueError(f"which must be 'force' or 'moment', not {which!r}")
        names = ["force.dat", "forces.dat"] if which == "force" else ["moment.dat", "forces.dat"]
        super().__init__(directory, names, start_time=start_time, time_tolerance=time_tolerance)
        self.which = which


class ForceCoeffsReader(TableReader):
    """Rows of ``postProcessing/<name>/<t>/coefficient.dat`` (or ``forceCoeffs.dat``)."""

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        start_time: float | None = None,
        time_tolerance: float = 1e-9,
    ) -> None:
        super().__init__(
            directory,
            ["coefficient.dat", "forceCoeffs.dat"],
            start_time=start_time,
            time_tolerance=time_tolerance,
        )


def last_per_time(rows: Rows) -> Rows:
    """``rows`` with one row per time: the last one written at it.

    Under preCICE's implicit coupling the fluid computes a time window once per coupling
    iteration, and its function objects write a row each time: the same time several
    times in a row, the converged one last. This keeps that one.
    """
    if len(rows) < 2:
        return rows
    keep = np.append(rows.time[1:] != rows.time[:-1], True)
    return Rows(rows.time[keep], rows.values[keep], rows.columns, rows.locations)


def read_force_coeffs(case_dir: str | os.PathLike[str], name: str = "forceCoeffs") -> Rows:
    """The whole history of the forceCoeffs function object ``name`` of a finished run.

    Reads ``<case_dir>/postProcessing/<name>/<t>/coefficient.dat`` (or
    ``forceCoeffs.dat``) of every start-time directory ``<t>`` in time order, as
    :class:`ForceCoeffsReader` does. A run continued from an earlier time than the one
    before it had reached (a restart) computed that stretch again: its rows replace the
    earlier run's from its start on, so that a row is kept only when no later row lies
    at or before its time and the times increase. Columns are named from the files'
    header (``rows.column("Cd")``, ``rows.column("Cl")``); ``rows.time`` holds the times.

    For the rows a running solver adds step by step, follow the directory with a
    :class:`ForceCoeffsReader` instead. Raises ``FileNotFoundError`` when there is no
    row, :class:`OutputFormatError` for a line that is not a row of numbers.
    """
    directory = Path(case_dir) / "postProcessing" / name
    rows = ForceCoeffsReader(directory).read_all()
    if not len(rows):
        raise FileNotFoundError(f"no force coefficients under {directory}")
    # the earliest time at or after each row, over the rows that follow it
    after = np.append(np.minimum.accumulate(rows.time[::-1])[::-1][1:], np.inf)
    keep = rows.time < after - 1e-12
    return Rows(rows.time[keep], rows.values[keep], rows.columns, rows.locations)
