"""Children that die with this process, whatever kills it.

A solver must not outlive the process that owns its env (``kill -9``, the OOM killer, a
job's time limit). The first layer of that promise is the kernel's: every child
:func:`~gymprecice.env.launching.launch` starts asks for SIGKILL when its parent dies
(``PR_SET_PDEATHSIG``, set between fork and exec by :func:`die_with_parent_hook`). The
kernel sends it when the *thread* that forked the child exits, not the process, so every
fork happens on a thread that lasts as long as the process (:func:`call_in_lasting_thread`):
a reset from a short-lived thread must not kill the solvers it started when that thread
ends. What a solver itself started (``mpirun``'s ranks, a script's background jobs) is the
owner's watchdog's to stop (:mod:`gymprecice.env.owner_watchdog`).
"""

from __future__ import annotations

import ctypes
import os
import queue
import signal
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

__all__ = ["call_in_lasting_thread", "die_with_parent_hook"]

_T = TypeVar("_T")
_lasting: tuple[int, queue.SimpleQueue[Any], threading.Thread] | None = None
_lasting_lock = threading.Lock()


def call_in_lasting_thread(fn: Callable[[], _T]) -> _T:
    """Run ``fn`` on a thread that lives until the process exits; return its result.

    The kernel sends a child's ``PR_SET_PDEATHSIG`` when the *thread* that forked it exits,
    not the process; an env reset from a ``ThreadPoolExecutor`` worker would otherwise lose
    its solvers when the pool shuts down. The main thread lasts already; any other caller
    hands ``fn`` to a daemon thread started once per process (again after a ``fork``).
    """
    global _lasting
    if threading.current_thread() is threading.main_thread():
        return fn()
    with _lasting_lock:
        if _lasting is None or _lasting[0] != os.getpid():
            requests: queue.SimpleQueue[Any] = queue.SimpleQueue()
            thread = threading.Thread(
                target=_serve_calls, args=(requests,), name="gymprecice-launcher", daemon=True
            )
            thread.start()
            _lasting = (os.getpid(), requests, thread)
        requests, lasting = _lasting[1], _lasting[2]
    if threading.current_thread() is lasting:
        return fn()
    future: Future[_T] = Future()
    requests.put((fn, future))
    return future.result()


def _serve_calls(requests: queue.SimpleQueue[Any]) -> None:
    while True:
        fn, future = requests.get()
        try:
            future.set_result(fn())
        except BaseException as exc:
            future.set_exception(exc)


_PR_SET_PDEATHSIG = 1
_prctl: Any = None


def _prctl_function() -> Any:
    """libc's ``prctl``, looked up once in the parent (``None`` where there is none)."""
    global _prctl
    if _prctl is None:
        try:
            _prctl = ctypes.CDLL(None, use_errno=True).prctl
        except (OSError, AttributeError):
            _prctl = False
    return _prctl or None


def die_with_parent_hook() -> Callable[[], None] | None:
    """What the child runs between fork and exec: SIGKILL when this process dies.

    ``PR_SET_PDEATHSIG`` survives ``exec`` (of a program that is not set-user-ID). A parent
    that died between the fork and the ``prctl`` sends nothing: the child sees it by its
    parent's pid, now another process's (init or a subreaper), and exits at once. The hook
    calls only a pre-resolved libc function and ``getppid``.
    """
    prctl = _prctl_function()
    if prctl is None:
        return None
    parent = os.getpid()
    kill = int(signal.SIGKILL)

    def in_child() -> None:
        prctl(_PR_SET_PDEATHSIG, kill, 0, 0, 0)
        if os.getppid() != parent:
            os._exit(1)

    return in_child
