"""How the double fails: preCICE's error, the misuses that kill real pyprecice, the hang."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import time
from typing import NoReturn


class PreciceError(RuntimeError):
    """What preCICE's ``precice::Error`` becomes in Python: a ``RuntimeError`` with its message."""


def fatal(kind: str, message: str) -> NoReturn:
    """A misuse that real pyprecice does not survive (measured with preCICE 3.4.1).

    ``kind`` is "abort" where the C++ call is not declared ``except +`` in the bindings (the
    ``precice::Error`` reaches ``std::terminate``) and "segfault" where preCICE dereferences
    state that does not exist yet (or anymore). With :data:`MISUSE` "raise" the double raises
    :class:`PreciceError` instead, which is what tests usually want to see.
    """
    from gymprecice.testing import fake_precice  # the switch lives on the public module

    if fake_precice.MISUSE != "crash":
        raise PreciceError(message)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    if kind == "abort":
        os.write(
            2,
            b"terminate called after throwing an instance of 'precice::Error'\n  what():  "
            + message.encode()
            + b"\n",
        )
        os.abort()
    os.write(2, f"[fake_precice] Segmentation fault ({message})\n".encode())
    signal.signal(signal.SIGSEGV, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGSEGV)
    hang_forever()


def hang_forever() -> NoReturn:
    """What preCICE does when a partner is gone: wait, never raise (measured with 3.4.1)."""
    while True:
        time.sleep(3600.0)
