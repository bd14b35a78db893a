"""A solver's log: the file its output goes to, and its last lines for messages.

A solver's stdout and stderr go to one file in its run directory, opened here so that the
descriptor the child inherits appends (both streams, and the lines of earlier episodes
when asked to keep them). An error reports the log's tail, read from its end: solver logs
grow to gigabytes over a training run.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["open_log", "read_tail"]


def open_log(path: Path, append: bool) -> int:
    """A descriptor for a solver's stdout and stderr: ``path`` emptied first unless ``append``.

    ``O_APPEND`` puts every write at the file's end, from whichever of the solver's
    processes makes it; ``O_CLOEXEC`` keeps the descriptor out of a program another thread
    starts meanwhile. The solver gets its own copy as stdout and stderr; the caller closes
    this one once the solver started.
    """
    flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | getattr(os, "O_CLOEXEC", 0)
    if not append:
        flags |= os.O_TRUNC
    return os.open(path, flags, 0o644)


def read_tail(path: Path, lines: int = 40, *, block: int = 8192) -> str:
    """The last ``lines`` lines of a file, reading blocks backwards from its end.

    Solver logs grow to gigabytes over a training run; only the tail is read. Invalid
    UTF-8 is replaced, a missing file gives ``""``.
    """
    if lines <= 0:
        return ""
    chunks: list[bytes] = []
    newlines = 0
    try:
        with open(path, "rb") as f:
            pos = f.seek(0, os.SEEK_END)
            # One newline more than lines asked for marks the start of the first line
            # kept (a final newline ends the last line, it does not start a new one).
            while pos > 0 and newlines <= lines:
                step = min(block, pos)
                pos -= step
                f.seek(pos)
                chunk = f.read(step)
                chunks.append(chunk)
                newlines += chunk.count(b"\n")
    except OSError:
        return ""
    data = b"".join(reversed(chunks))
    text = data.decode("utf-8", errors="replace")
    # Split on "\n" only: a solver's progress output may contain bare "\r".
    ends_with_newline = text.endswith("\n")
    parts = text.split("\n")
    if ends_with_newline:
        parts.pop()
    return "\n".join(parts[-lines:]) + ("\n" if ends_with_newline else "")
