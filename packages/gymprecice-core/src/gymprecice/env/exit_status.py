"""A process's exit status in words, for the messages of errors and logs.

A ``Popen`` return code is negative when a signal killed the process; a message that
says ``was killed by SIGSEGV`` tells a crash from a solver that gave up
(``exited with status 1``), which a bare number does not.
"""

from __future__ import annotations

import signal

__all__ = ["describe_returncode"]


def describe_returncode(returncode: int | None) -> str:
    """``exited with status 3`` / ``was killed by SIGKILL`` / ``is still running``."""
    if returncode is None:
        return "is still running"
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        return f"was killed by {name}"
    return f"exited with status {returncode}"
