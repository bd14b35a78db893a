"""How the double fails: preCICE's error, the misuses that kill real pyprecice, the hang,
a partner that is gone."""

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


#: the environment variable that says how long a participant whose partner is gone waits
PARTNER_LOSS_ENV = "GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS"


def partner_loss_wait() -> float | None:
    """Seconds a participant waits once its partner is gone before it gives up (``None``:
    forever, as preCICE 3.4.1 does), from :data:`fake_precice.PARTNER_LOSS
    <gymprecice.testing.fake_precice.PARTNER_LOSS>`."""
    from gymprecice.testing import fake_precice  # the switch lives on the public module

    text = str(fake_precice.PARTNER_LOSS).strip().lower()
    if text in ("hang", "forever"):
        return None
    try:
        seconds = float(text)
    except ValueError:
        seconds = -1.0
    if not seconds >= 0.0:  # also NaN
        raise PreciceError(
            f"{PARTNER_LOSS_ENV}={fake_precice.PARTNER_LOSS!r}: give the seconds a "
            "participant waits for a partner that is gone before it gives up, or 'hang' "
            "to wait forever as preCICE does"
        )
    return seconds


def partner_gone(direction: str, remote: str, reason: str) -> NoReturn:
    """A partner's connection closed under us (it was killed, crashed or exited).

    preCICE 3.4.1 then waits forever; so does the double for :func:`partner_loss_wait`
    seconds (a supervisor that watches the solver processes acts within them), then it
    gives up the way preCICE does when its socket reports the loss: a
    :class:`PreciceError` with preCICE's message. A solver run on the double therefore
    ends (non-zero, the message in its log) instead of waiting for hours on a peer that
    was SIGKILLed; ``PARTNER_LOSS = "hang"`` keeps preCICE's wait.
    """
    wait = partner_loss_wait()
    if wait is None:
        hang_forever()
    time.sleep(wait)
    raise PreciceError(
        f'{direction} participant "{remote}" (using sockets) failed with a system error: '
        f"{reason}. This often means that the other participant exited with an error "
        f"(look there). [gymprecice's preCICE test double: the partner was gone for "
        f"{wait:g} s; preCICE would wait forever here, {PARTNER_LOSS_ENV}=hang does too]"
    )
