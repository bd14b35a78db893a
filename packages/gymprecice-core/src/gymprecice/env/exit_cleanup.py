"""No solver outlives the script that started it.

An env whose episode may be running is tracked here (:func:`track`) until it is closed
(:func:`forget`). At interpreter exit, and on SIGTERM or SIGHUP where nobody else handles
them, every tracked env is closed: a script that forgets ``env.close()``, dies on an
exception, or is stopped by a scheduler leaves no solver waiting for a controller that is
gone.
"""

from __future__ import annotations

import atexit
import os
import signal
import threading
import weakref
from typing import Protocol

__all__ = ["end_live_episodes", "forget", "track"]


class Closable(Protocol):
    """What is tracked: an env whose ``close()`` ends all it started."""

    def close(self) -> None: ...


#: Envs with an episode possibly running, closed at interpreter exit.
_LIVE: weakref.WeakSet[Closable] = weakref.WeakSet()


def track(env: Closable) -> None:
    """From now on ``env`` may run solvers: close it at exit and on SIGTERM/SIGHUP."""
    _LIVE.add(env)
    _clean_up_on_termination_signals()


def forget(env: Closable) -> None:
    """``env`` is closed: nothing of it is left to clean up."""
    _LIVE.discard(env)


@atexit.register
def end_live_episodes() -> None:
    """Close every tracked env (a failing close does not stop the others)."""
    for env in list(_LIVE):
        try:
            env.close()
        except Exception:
            pass


def _end_live_episodes_and_die(signum: int, frame: object) -> None:
    """SIGTERM/SIGHUP (a scheduler, ``timeout``, a closed terminal): clean up, then die.

    atexit does not run when a signal kills Python, which would leave the solvers waiting
    for a controller that is gone. The signal is re-raised with its default action, so
    the process still ends as the sender meant (exit status -signum).
    """
    end_live_episodes()
    signal.signal(signum, signal.SIG_DFL)
    os.kill(os.getpid(), signum)


def _clean_up_on_termination_signals() -> None:
    """Install :func:`_end_live_episodes_and_die` where nobody else handles the signal.

    Only signals at their default action are taken (a learner's or a vector worker's own
    handler stays in charge), and only from the main thread, the one Python allows.
    """
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, _end_live_episodes_and_die)
