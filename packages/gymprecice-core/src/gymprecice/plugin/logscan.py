"""Find a solver's own error lines in its log, wherever they are.

A crash message that shows only the last lines of a log often shows a backtrace or MPI's
epilogue, while the line that says what went wrong came earlier: preCICE prints
``ERROR: <message>`` and then the solver unwinds for dozens of lines. So a failed solver's
error message carries these lines too, found by a scan of the log, not only its tail.

Recognised (after removing ANSI colours, which preCICE's default formatter uses):

* preCICE's ``ERROR:`` lines (``(0) 12:00:00 [impl::ParticipantImpl]:231 in configure:
  ERROR: ...``, from preCICE's ``logging/LogConfiguration.cpp``);
* OpenFOAM's ``FOAM FATAL ERROR`` / ``FOAM FATAL IO ERROR`` banners with the lines that
  follow them (the message is printed below the banner);
* the OpenFOAM-preCICE adapter's ``Error in the preCICE adapter:`` (and ``deferred``).

Logs grow to gigabytes over training, so only the first and the last few MiB are read.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

#: a CSI escape sequence (colours, cursor moves): ESC [ parameters final byte
_ANSI = re.compile(r"\x1b\[[0-9;?]*[ -/]*[@-~]")
_ERROR = re.compile(
    r"\bERROR:|FOAM FATAL (?:IO )?ERROR|Error (?:\(deferred[^)]*\) )?in the preCICE adapter"
)
#: lines kept after a match whose message is printed below it (OpenFOAM's banner)
_FOLLOWING = {"FOAM FATAL": 4, "in the preCICE adapter": 2}
HEAD_BYTES = 1 << 20
TAIL_BYTES = 8 << 20


def _read(path: Path) -> str:
    try:
        with open(path, "rb") as handle:
            size = handle.seek(0, os.SEEK_END)
            handle.seek(0)
            if size <= HEAD_BYTES + TAIL_BYTES:
                data = handle.read()
            else:
                head = handle.read(HEAD_BYTES)
                handle.seek(size - TAIL_BYTES)
                data = head + b"\n" + handle.read(TAIL_BYTES)
    except OSError:
        return ""
    return data.decode("utf-8", errors="replace")


def without_colours(text: str) -> str:
    """``text`` without ANSI escape sequences (preCICE colours its log levels on a terminal)."""
    return _ANSI.sub("", text)


def error_lines(path: str | os.PathLike[str] | None, *, limit: int = 12) -> list[str]:
    """The solver's own error lines in the log at ``path``, in order, without duplicates."""
    if path is None:
        return []
    lines = without_colours(_read(Path(path))).splitlines()
    found: list[str] = []
    i = 0
    while i < len(lines) and len(found) < limit:
        line = lines[i].strip()
        i += 1
        if not _ERROR.search(line):
            continue
        block = [line]
        extra = next((n for key, n in _FOLLOWING.items() if key in line), 0)
        while extra and i < len(lines):
            following = lines[i].strip()
            i += 1
            if following:
                block.append(following)
                extra -= 1
        for item in block:
            if item not in found and len(found) < limit:
                found.append(item)
    return found
