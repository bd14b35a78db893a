"""One running solver: its process group, its log, its exit notifier, its end.

:meth:`SolverProcess.start` turns a plugin's :class:`~gymprecice.plugin.solver.LaunchSpec`
into a running process group (:func:`~gymprecice.env.launching.launch`), its output in a
log file (:mod:`gymprecice.env.solver_log`) and its environment without the MPI runtime
variables of an enclosing job (:mod:`gymprecice.env.mpi_environment`). An env waits on
the coupling worker's pipe and on its solvers at the same time with
:func:`multiprocessing.connection.wait`; :meth:`SolverProcess.fileno` makes that possible.
:meth:`SolverProcess.terminate` kills the whole group, proving the identity of what it
signals first (:mod:`gymprecice.env.pidregistry`).

A solver's leader is never reaped before its group is known to be empty: until then its
pid, and so the group's number, cannot be reused, and no signal can reach a stranger.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import shlex
import signal
import subprocess
import threading
import time
from pathlib import Path

from gymprecice.env.exit_status import describe_returncode
from gymprecice.env.launching import launch
from gymprecice.env.mpi_environment import clean_mpi_environment
from gymprecice.env.pidregistry import (
    KILL_WAIT_S,
    GroupRecord,
    PidRegistry,
    kill_group_records,
    live_group_members,
    proc_stat,
    process_starttime,
)
from gymprecice.env.solver_log import open_log, read_tail
from gymprecice.plugin.errors import CaseError
from gymprecice.plugin.solver import LaunchSpec

__all__ = ["SolverProcess"]

log = logging.getLogger("gymprecice.processes")  # its name before the move to env/


class SolverProcess:
    """One running solver: its own process group, its log file and an exit notifier.

    Start it with :meth:`start`. ``fileno()`` lets :func:`multiprocessing.connection.wait`
    wake up when the solver exits. :meth:`terminate` (idempotent) kills the whole group,
    stopped members included, and reaps the child, so nothing of an episode survives it.

    ``fileno()`` is a pidfd where the kernel has them (Linux >= 5.3). Elsewhere it is the
    read end of a pipe whose write end only the solver's processes hold: it becomes
    readable once the last of them exits (or closes it), which may be later than the
    direct child's exit when the solver leaves background processes. :meth:`poll` stays
    the authority on the child's exit; it reads the status without reaping the child
    (``waitid(WNOWAIT)``), which only :meth:`terminate` does, after the group is empty.
    """

    def __init__(
        self,
        name: str,
        popen: subprocess.Popen[bytes],
        *,
        argv: list[str],
        log_path: Path,
        wake_fd: int,
        wake_is_pidfd: bool = True,
        env_index: int = 0,
        registry: PidRegistry | None = None,
        token: str | None = None,
        starttime: int | None = None,
    ) -> None:
        # Use SolverProcess.start(); this only wires up an already started child.
        self.name = name
        self.argv = argv
        self.log_path = log_path
        self.env_index = env_index
        self.pid: int = popen.pid
        self.pgid: int = popen.pid  # start_new_session: the child leads its own group
        self._popen = popen
        self._wake_fd: int | None = wake_fd
        self._wake_is_pidfd = wake_is_pidfd
        self._registry = registry
        self._record = GroupRecord(
            popen.pid, process_starttime(popen.pid) if starttime is None else starttime, token
        )
        self._status: int | None = None
        # Re-entrant: a signal handler may end the episode while terminate() waits.
        self._lock = threading.RLock()
        self._terminating = False
        self._closed = False

    # -- starting ----------------------------------------------------------------------

    @classmethod
    def start(
        cls,
        name: str,
        spec: LaunchSpec,
        *,
        env_index: int = 0,
        registry: PidRegistry | None = None,
        append: bool = False,
    ) -> SolverProcess:
        """Start ``spec.argv`` in ``spec.cwd`` in a new session and process group.

        stdin is ``/dev/null``; stdout and stderr go to ``spec.cwd / spec.log_name``, which
        is truncated first unless ``append`` (keep earlier episodes' output). The
        environment is ``os.environ`` without MPI runtime variables, plus ``spec.env``,
        plus :data:`PROCESS_TOKEN_VARIABLE`. With a ``registry`` the group is recorded
        there (before it starts) until :meth:`terminate` has killed it.

        Raises :class:`~gymprecice.errors.CaseError` when the directory or the program is
        missing or the program cannot be executed.
        """
        argv = [os.fspath(a) for a in spec.argv]
        if not argv:
            raise ValueError(f"LaunchSpec of solver {name!r} (env {env_index}) has an empty argv")
        cwd = Path(spec.cwd)
        where = f"solver {name!r} of env {env_index}"
        if not cwd.is_dir():
            raise CaseError(
                f"cannot start {where}: its run directory {cwd} does not exist "
                f"(command: {shlex.join(argv)})"
            )
        log_path = cwd / spec.log_name
        log_path.parent.mkdir(parents=True, exist_ok=True)
        env = clean_mpi_environment(os.environ)
        env.update({str(k): str(v) for k, v in spec.env.items()})
        log_fd = open_log(log_path, append)
        try:
            launched = launch(argv, cwd=cwd, env=env, stdout=log_fd, registry=registry)
        except OSError as exc:
            raise _launch_error(exc, argv, cwd, where) from exc
        finally:
            os.close(log_fd)
        proc = cls(
            name,
            launched.popen,
            argv=argv,
            log_path=log_path,
            wake_fd=launched.wake_fd,
            wake_is_pidfd=launched.wake_is_pidfd,
            env_index=env_index,
            registry=registry,
            token=launched.token,
            starttime=launched.starttime,
        )
        log.debug("started %s: pid %d, %s, log %s", where, proc.pid, shlex.join(argv), log_path)
        return proc

    # -- state -------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (
            f"<SolverProcess {self.name!r} env={self.env_index} pid={self.pid} "
            f"{describe_returncode(self.returncode)}>"
        )

    @property
    def record(self) -> GroupRecord:
        """What proves this group is ours: pgid, leader start time, launch token."""
        return self._record

    @property
    def returncode(self) -> int | None:
        """Exit status of the direct child (negative: killed by that signal); ``None`` while it runs."""
        return self.poll()

    def _peek(self) -> int | None:
        """The child's exit status, read without reaping it."""
        if self._popen.returncode is not None:
            return self._popen.returncode
        if self._status is not None:
            return self._status
        try:
            info = os.waitid(os.P_PID, self.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
        except ChildProcessError:
            return self._popen.poll()
        if info is None:
            return None
        code = info.si_status if info.si_code == os.CLD_EXITED else -info.si_status
        self._status = code
        return code

    def poll(self) -> int | None:
        """The child's exit status if it exited (see :attr:`returncode`); never reaps it.

        Once ``fileno()`` has become readable this gives the exit status: with the pipe
        fallback the pipe closes a moment before the exiting child is a zombie, so a short
        bounded wait bridges that gap.
        """
        returncode = self._peek()
        if returncode is None and not self._wake_is_pidfd and self._wake_fd is not None:
            readable, _, _ = select.select([self._wake_fd], [], [], 0)
            if readable:
                deadline = time.monotonic() + 0.1
                while returncode is None and time.monotonic() < deadline:
                    time.sleep(0.002)
                    returncode = self._peek()
        return returncode

    def exited(self) -> bool:
        """Whether the child exited or has begun to exit (killed, its files closing)."""
        if self.poll() is not None:
            return True
        st = proc_stat(self.pid)
        return st is None or st.dead

    def wait(self, timeout: float | None = None) -> int | None:
        """Wait for the child to exit; return its status, or ``None`` on timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            returncode = self.poll()
            if returncode is not None:
                return returncode
            left = 1.0 if deadline is None else deadline - time.monotonic()
            if left <= 0:
                return None
            if self._wake_is_pidfd and self._wake_fd is not None:
                select.select([self._wake_fd], [], [], min(left, 1.0))
            else:
                time.sleep(min(left, 0.01))

    def describe_status(self) -> str:
        """``exited with status 1`` / ``was killed by SIGSEGV`` / ``is still running``."""
        return describe_returncode(self.returncode)

    @property
    def command(self) -> str:
        """The command line, shell-quoted, for messages."""
        return shlex.join(self.argv)

    def fileno(self) -> int:
        """A descriptor that becomes readable when the solver exits (see the class doc).

        Raises :class:`OSError` after :meth:`terminate`, like a closed connection.
        """
        if self._wake_fd is None:
            raise OSError(errno.EBADF, f"solver process {self.name!r} is closed")
        return self._wake_fd

    @property
    def closed(self) -> bool:
        """Whether :meth:`terminate` has run (group killed, child reaped, fd closed)."""
        return self._closed

    # -- the log -----------------------------------------------------------------------

    def log_size(self) -> int:
        """Bytes in the log so far (0 when it is gone); growth means progress."""
        try:
            return self.log_path.stat().st_size
        except OSError:
            return 0

    def log_tail(self, lines: int = 40) -> str:
        """The last ``lines`` lines of the log, read backwards from its end."""
        return read_tail(self.log_path, lines)

    # -- stopping ----------------------------------------------------------------------

    def terminate(self, grace: float = 2.0) -> int | None:
        """Kill the whole process group, reap the child and close the descriptors.

        SIGTERM goes to the group's proven members, followed by SIGCONT so that stopped
        members can act on it; members still alive after ``grace`` seconds get SIGKILL.
        The child is reaped only once its group is empty. A call made while another is
        waiting out the grace (a signal handler ending the episode) escalates to SIGKILL
        at once. Calling it after it finished does nothing. Returns the exit status.
        """
        with self._lock:
            if self._closed:
                return self.returncode
            nested, self._terminating = self._terminating, True
            try:
                survivors = self._kill_group(0.0 if nested else grace)
                if survivors:
                    log.warning(
                        "process group %d of solver %r (env %d) survived SIGKILL",
                        self.pgid,
                        self.name,
                        self.env_index,
                    )
                try:
                    self._popen.wait(KILL_WAIT_S)
                except subprocess.TimeoutExpired:
                    log.warning("solver %r (pid %d) could not be reaped", self.name, self.pid)
                if self._registry is not None and not survivors:
                    try:
                        self._registry.remove_records(lambda r: r.pgid == self.pgid)
                    except OSError as exc:  # the env dir may already be gone
                        log.debug("could not update %s: %s", self._registry.path, exc)
            finally:
                self._close_fd()
                self._closed = True
            return self.returncode

    close = terminate

    def _kill_group(self, grace: float) -> bool:
        """Kill the group; True when some member survived SIGKILL."""
        if self._popen.returncode is not None:
            return False  # reaped: the number may belong to someone else now
        if live_group_members(self.pgid) is None:
            return self._killpg_without_proc(grace)
        _, survivors = kill_group_records([self._record], grace)
        return bool(survivors)

    def _killpg_without_proc(self, grace: float) -> bool:
        """No /proc: signal the group while the unreaped leader pins its number."""
        for sig in (signal.SIGTERM, signal.SIGCONT):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.pgid, sig)
        if self.wait(grace) is None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.pgid, signal.SIGKILL)
        return self.wait(KILL_WAIT_S) is None

    def _close_fd(self) -> None:
        if self._wake_fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._wake_fd)
            self._wake_fd = None

    def __enter__(self) -> SolverProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.terminate()

    def __del__(self) -> None:
        # Do not leak the descriptor when terminate() was forgotten; killing is explicit.
        with contextlib.suppress(Exception):
            self._close_fd()


def _launch_error(exc: OSError, argv: list[str], cwd: Path, where: str) -> CaseError:
    """Why ``argv`` did not start, in the case's words, with what to do about it."""
    program = argv[0]
    if isinstance(exc, FileNotFoundError):
        reason = f"program {program!r} was not found"
        advice = (
            "check the spelling, that it exists relative to the run directory, "
            "or that its directory is on PATH"
        )
    elif isinstance(exc, PermissionError):
        reason = f"program {program!r} is not executable"
        advice = f"make it executable (chmod +x {program})"
    elif exc.errno == errno.ENOEXEC:
        reason = f"program {program!r} is not a valid executable"
        advice = "a script needs a '#!' line, e.g. '#!/usr/bin/env bash'"
    else:
        reason = f"program {program!r} could not be started ({exc})"
        advice = "check the command of the solver"
    return CaseError(
        f"cannot start {where}: {reason} (working directory {cwd}, command "
        f"{shlex.join(argv)}); {advice}"
    )
