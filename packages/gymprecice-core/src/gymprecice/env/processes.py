"""Starting solver processes and ending them: process groups, logs, exit notification.

Plugins only describe how a solver starts (:class:`~gymprecice.solver.LaunchSpec`); core
starts it here. Every solver runs in its own session and process group, so one signal to
the group reaches everything the solver started (``mpirun``, its ranks, a shell script's
background jobs) and nothing else. Each group is recorded on disk before it exists
(:mod:`gymprecice.pidregistry`), so an outer supervisor can still kill it after the env
process itself died, and every kill proves the identity of what it signals first.

An env waits on the coupling worker's pipe and on its solvers at the same time with
:func:`multiprocessing.connection.wait`; :meth:`SolverProcess.fileno` makes that possible
by handing out a pidfd, which becomes readable when the solver exits.

A solver's leader is never reaped before its group is known to be empty: until then its
pid, and so the group's number, cannot be reused, and no signal can reach a stranger.

No solver outlives the process that owns its env, whatever kills that process (``kill -9``,
the OOM killer, a job's time limit): every child :func:`launch` starts asks the kernel for
SIGKILL when its parent dies (``PR_SET_PDEATHSIG``, set between fork and exec), and the
owner's watchdog (:mod:`gymprecice.owner_watchdog`), told about each launch before the
fork, kills the rest of the group and of its session (what a script or ``mpirun``
started) once the owner is gone. ``PR_SET_PDEATHSIG`` fires when the *thread* that forked
the child exits, so every fork happens on a thread that lasts as long as the process
(:func:`call_in_lasting_thread`): a reset from a short-lived thread must not kill the
solvers it started when that thread ends.

Solver scripts often call ``mpirun``. That breaks when the Python process initialised an
MPI singleton (``from mpi4py import MPI``) before its environment reached the solver:
:func:`clean_mpi_environment` removes the MPI runtime variables that make ``mpirun``
refuse to start, and keeps the user's MPI configuration.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import logging
import os
import queue
import secrets
import select
import shlex
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from gymprecice.env import owner_watchdog
from gymprecice.env.pidregistry import (
    KILL_WAIT_S,
    PROCESS_TOKEN_VARIABLE,
    GroupRecord,
    PidRegistry,
    kill_group_records,
    kill_recorded_groups,
    live_group_members,
    proc_stat,
)
from gymprecice.plugin.errors import CaseError, SolverCrashedError, SolverTimeoutError
from gymprecice.plugin.solver import LaunchSpec

__all__ = [
    "PROCESS_TOKEN_VARIABLE",
    "GroupRecord",
    "Launched",
    "PidRegistry",
    "SolverProcess",
    "call_in_lasting_thread",
    "clean_mpi_environment",
    "describe_returncode",
    "kill_recorded_groups",
    "launch",
    "read_tail",
    "run_to_completion",
]

log = logging.getLogger("gymprecice.processes")  # its name before the move to env/

_KILL_WAIT_S = KILL_WAIT_S

# --------------------------------------------------------------------------------------
# MPI environment cleaning
# --------------------------------------------------------------------------------------

# Variables a launcher (mpirun/orted/prterun, Hydra, srun's PMI) or an Open MPI singleton
# sets for the processes it starts. A child ``mpirun`` that sees them believes it runs
# inside an MPI job and stops ("mpirun does not support recursive calls", or a silent
# exit status 1 with OMPI_MCA_ess=singleton on Open MPI 4.1).
_RUNTIME_EXACT = frozenset(
    {
        # Open MPI 4 (ORTE) singleton and launcher
        "OMPI_MCA_ess",
        "OMPI_MCA_pmix",
        "OMPI_MCA_initial_wdir",
        "OMPI_MCA_mpi_oversubscribe",
        "OMPI_MCA_shmem_RUNTIME_QUERY_hint",
        "OMPI_UNIVERSE_SIZE",
        "OMPI_FILE_LOCATION",
        "OMPI_NUM_APP_CTX",
        "OMPI_FIRST_RANKS",
        "OMPI_COMMAND",
        "OMPI_ARGV",
        # MPICH / Intel MPI (Hydra) per-rank information
        "MPI_LOCALRANKID",
        "MPI_LOCALNRANKS",
    }
)
_RUNTIME_PREFIXES = (
    "OMPI_COMM_WORLD_",
    "OMPI_APP_CTX_",
    "OMPI_MCA_ess_",
    "OMPI_MCA_orte_",
    "OMPI_MCA_pmix_",
    "ORTE_",
    "PMIX_",
    "PRTE_",
    "PMI_",
    "HYDI_",
)
# User configuration that matches a runtime prefix above but must survive.
_USER_PREFIXES = ("PMIX_MCA_", "PRTE_MCA_")
_USER_EXACT = frozenset(
    {
        "OMPI_MCA_orte_tmpdir_base",
        "OMPI_MCA_orte_default_hostfile",
        "OMPI_MCA_orte_keep_fqdn_hostnames",
        "OMPI_MCA_orte_base_help_aggregate",
        "OMPI_MCA_orte_abort_on_non_zero_status",
        "OMPI_MCA_orte_allowed_exit_without_sync",
    }
)


def _is_mpi_runtime_variable(name: str) -> bool:
    if name in _USER_EXACT or name.startswith(_USER_PREFIXES):
        return False
    return name in _RUNTIME_EXACT or name.startswith(_RUNTIME_PREFIXES)


def clean_mpi_environment(environ: Mapping[str, str]) -> dict[str, str]:
    """Return a copy of ``environ`` without the MPI runtime variables of an enclosing job.

    Gym-preCICE v0.1 dropped every variable containing ``MPI``, which also dropped the
    user's ``OMPI_ALLOW_RUN_AS_ROOT*`` and MCA settings (``OMPI_MCA_btl*``,
    ``OMPI_MCA_rmaps_base_oversubscribe``, ``I_MPI_*``, ``MPIR_CVAR_*``, ...) and so broke
    runs as root and tuned clusters. Only what a launcher or a singleton sets is removed
    here: ``OMPI_COMM_WORLD_*``, ``OMPI_MCA_ess*``, ``OMPI_MCA_orte_*`` (except a few
    documented user settings such as ``OMPI_MCA_orte_tmpdir_base``), ``OMPI_MCA_pmix*``,
    ``PMIX_*`` and ``PRTE_*`` (except ``PMIX_MCA_*`` / ``PRTE_MCA_*``), ``PMI_*``,
    ``ORTE_*``, ``OMPI_APP_CTX_*``, ``OMPI_UNIVERSE_SIZE``, ``OMPI_FILE_LOCATION``,
    ``MPI_LOCALRANKID`` and similar. ``HYDRA_*`` variables are kept: Hydra reads them as
    user settings (``HYDRA_HOST_FILE``, ``HYDRA_LAUNCHER``).

    Note that an MPI singleton sets its variables with ``putenv``, which Python's
    ``os.environ`` does not see in the process that imported mpi4py; they reach
    ``os.environ`` of every process started from it (vector-env workers, the coupling
    worker), and from there the solvers unless they are removed.
    """
    return {k: v for k, v in environ.items() if not _is_mpi_runtime_variable(k)}


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


# --------------------------------------------------------------------------------------
# Launching
# --------------------------------------------------------------------------------------

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


def _die_with_parent_hook() -> Callable[[], None] | None:
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


def _open_log(path: Path, append: bool) -> int:
    flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | getattr(os, "O_CLOEXEC", 0)
    if not append:
        flags |= os.O_TRUNC
    return os.open(path, flags, 0o644)


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
                preexec_fn=_die_with_parent_hook(),  # see the hook: libc's prctl only
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
        launched = Launched(popen, token, _starttime(popen.pid), wake_fd, use_pidfd)
        if registry is not None:
            registry.add_record(launched.record)
    except BaseException:
        # Still unreaped: the group number is ours, killpg cannot hit anyone else.
        with contextlib.suppress(OSError):
            os.killpg(popen.pid, signal.SIGKILL)
        popen.wait()
        raise
    return launched


def _starttime(pid: int) -> int | None:
    st = proc_stat(pid)
    return None if st is None else st.starttime


# --------------------------------------------------------------------------------------
# Solver processes
# --------------------------------------------------------------------------------------


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
            popen.pid, _starttime(popen.pid) if starttime is None else starttime, token
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
        log_fd = _open_log(log_path, append)
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
                    self._popen.wait(_KILL_WAIT_S)
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
        return self.wait(_KILL_WAIT_S) is None

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


def _launch_error(exc: OSError, argv: list[str], cwd: Path, where: str) -> CaseError:
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


def run_to_completion(
    name: str,
    spec: LaunchSpec,
    *,
    timeout: float | None,
    env_index: int = 0,
    what: str = "prerun",
    registry: PidRegistry | None = None,
    append: bool = False,
) -> None:
    """Run a short command (prerun, reset) in its own group and wait for it.

    Raises :class:`~gymprecice.errors.SolverCrashedError` on a non-zero exit and
    :class:`~gymprecice.errors.SolverTimeoutError` (after killing the group) when it runs
    longer than ``timeout`` seconds. Processes the command left in the background are
    killed too: nothing it started outlives it.
    """
    proc = SolverProcess.start(name, spec, env_index=env_index, registry=registry, append=append)
    try:
        returncode = proc.wait(timeout)
        if returncode is None:
            proc.terminate()
            raise SolverTimeoutError(
                f"the {what} command of solver {name!r} (env {env_index}) did not finish "
                f"within {timeout:g} s and was killed: {proc.command}",
                env_index=env_index,
                solver=name,
                returncode=proc.returncode,
                log_tail=proc.log_tail(),
                log_file=str(proc.log_path),
            )
        if returncode != 0:
            proc.terminate()
            raise SolverCrashedError(
                f"the {what} command of solver {name!r} (env {env_index}) "
                f"{describe_returncode(returncode)}: {proc.command}",
                env_index=env_index,
                solver=name,
                returncode=returncode,
                log_tail=proc.log_tail(),
                log_file=str(proc.log_path),
            )
    finally:
        proc.terminate()
