"""Starting a child in its own session and process group, recorded before it exists.

Every solver (and the coupling worker) is started by :func:`launch`. Its own session and
process group mean that one signal to the group reaches everything the child started
(``mpirun``, its ranks, a shell script's background jobs) and nothing else. The group is
recorded on disk before it exists (:mod:`gymprecice.env.pidregistry`) and announced to
the owner's watchdog (:mod:`gymprecice.env.owner_watchdog`), so that it can still be
killed after the env process itself died; the child dies with this process
(:mod:`gymprecice.env.parent_death`).

A waiter learns of the child's exit from a descriptor that becomes readable then: a pidfd
where the kernel has them, or else a pipe whose write end only the child's processes hold.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import signal
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from gymprecice.env import owner_watchdog
from gymprecice.env.parent_death import call_in_lasting_thread, die_with_parent_hook
from gymprecice.env.pidregistry import (
    PROCESS_TOKEN_VARIABLE,
    GroupRecord,
    PidRegistry,
    process_starttime,
)

__all__ = ["Launched", "launch"]

_pidfd_checked: bool | None = None


def _pidfd_available() -> bool:
    """Whether ``os.pidfd_open`` works here (Linux >= 5.3, not blocked by seccomp)."""
    global _pidfd_checked
    if _pidfd_checked is None:
        pidfd_open = getattr(os, "pidfd_open", None)
        if pidfd_open is None:
            _pidfd_checked = False
        else:
            try:
                os.close(pidfd_open(os.getpid()))
                _pidfd_checked = True
            except OSError:
                _pidfd_checked = False
    return _pidfd_checked


@dataclass
class Launched:
    """A child started by :func:`launch`: how to wait for it and how to prove it is ours."""

    popen: subprocess.Popen[bytes]
    token: str
    starttime: int | None
    wake_fd: int
    wake_is_pidfd: bool

    @property
    def record(self) -> GroupRecord:
        return GroupRecord(self.popen.pid, self.starttime, self.token)


def launch(
    argv: Sequence[str],
    *,
    cwd: Path | str | None,
    env: Mapping[str, str],
    stdout: int,
    pass_fds: Sequence[int] = (),
    registry: PidRegistry | None = None,
) -> Launched:
    """Start ``argv`` in a new session and process group, recorded before it exists.

    The child's environment gets a fresh launch token (:data:`PROCESS_TOKEN_VARIABLE`) and
    its owner's identity (:data:`~gymprecice.owner_watchdog.OWNER_VARIABLE`). The token is
    written to ``registry`` and announced to this process's watchdog before ``fork``, and
    the group's number and start time recorded right after, so an env killed at any instant
    leaves a record a supervisor can act on. The child dies with this process
    (``PR_SET_PDEATHSIG``, forked from a lasting thread). The wake descriptor is a pidfd, or
    (kernels without pidfds) the read end of a pipe that only the child's processes hold.
    ``OSError`` from ``Popen`` propagates.
    """
    token = secrets.token_hex(8)
    child_env = {
        **env,
        PROCESS_TOKEN_VARIABLE: token,
        owner_watchdog.OWNER_VARIABLE: owner_watchdog.owner_variable(),
    }
    use_pidfd = _pidfd_available()
    pipe_r = pipe_w = -1
    if not use_pidfd:
        pipe_r, pipe_w = os.pipe()
    if registry is not None:
        registry.add_pending(token)
        owner_watchdog.watch(registry.env_dir, token)
    try:
        popen = call_in_lasting_thread(
            lambda: subprocess.Popen(
                list(argv),
                cwd=cwd,
                env=child_env,
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                close_fds=True,
                pass_fds=(*pass_fds, *(() if use_pidfd else (pipe_w,))),
                preexec_fn=die_with_parent_hook(),  # see the hook: libc's prctl only
            )
        )
    except BaseException:
        if pipe_r >= 0:
            os.close(pipe_r)
        if registry is not None:
            with contextlib.suppress(OSError):
                registry.remove_token(token)
        raise
    finally:
        if pipe_w >= 0:
            os.close(pipe_w)
    try:
        # The child is not reaped yet, so its pid cannot have been reused.
        wake_fd = os.pidfd_open(popen.pid) if use_pidfd else pipe_r
        launched = Launched(popen, token, process_starttime(popen.pid), wake_fd, use_pidfd)
        if registry is not None:
            registry.add_record(launched.record)
    except BaseException:
        # Still unreaped: the group number is ours, killpg cannot hit anyone else.
        with contextlib.suppress(OSError):
            os.killpg(popen.pid, signal.SIGKILL)
        popen.wait()
        raise
    return launched
