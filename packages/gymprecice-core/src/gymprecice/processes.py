"""Supervision of solver processes: process groups, logs, exit notification, clean kills.

Plugins only describe how a solver starts (:class:`~gymprecice.solver.LaunchSpec`); core
starts it here. Every solver runs in its own session and process group, so one signal to
the group reaches everything the solver started (``mpirun``, its ranks, a shell script's
background jobs) and nothing else. The group ids are recorded on disk
(:class:`PidRegistry`) so that an outer supervisor can still kill them after the env
process itself died (:func:`kill_recorded_groups`).

An env waits on the coupling worker's pipe and on its solvers at the same time with
:func:`multiprocessing.connection.wait`; :meth:`SolverProcess.fileno` makes that possible
by handing out a pidfd, which becomes readable when the solver exits.

Solver scripts often call ``mpirun``. That breaks when the Python process initialised an
MPI singleton (``from mpi4py import MPI``) before its environment reached the solver:
:func:`clean_mpi_environment` removes the MPI runtime variables that make ``mpirun``
refuse to start, and keeps the user's MPI configuration.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import logging
import os
import secrets
import select
import shlex
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from gymprecice.errors import CaseError, SolverCrashedError, SolverTimeoutError
from gymprecice.solver import LaunchSpec

__all__ = [
    "PROCESS_TOKEN_VARIABLE",
    "GroupRecord",
    "PidRegistry",
    "SolverProcess",
    "clean_mpi_environment",
    "describe_returncode",
    "kill_recorded_groups",
    "read_tail",
    "run_to_completion",
]

log = logging.getLogger(__name__)

#: Environment variable that carries a random token into every process a solver starts.
#: :func:`kill_recorded_groups` uses it to recognise a group whose leader already exited.
PROCESS_TOKEN_VARIABLE = "GYMPRECICE_PROCESS_TOKEN"

# How long to wait for a group to vanish after SIGKILL before giving up on it (a process
# in uninterruptible sleep cannot die until its I/O returns).
_KILL_WAIT_S = 2.0

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


# --------------------------------------------------------------------------------------
# /proc helpers (Linux); every caller copes with their absence
# --------------------------------------------------------------------------------------

_PROC = Path("/proc")


@dataclass(frozen=True)
class _ProcStat:
    pid: int
    state: str
    ppid: int
    pgrp: int
    starttime: int


def _proc_stat(pid: int) -> _ProcStat | None:
    try:
        data = (_PROC / str(pid) / "stat").read_bytes()
    except OSError:
        return None
    # The command name (field 2) may contain spaces and parentheses: split after the last ')'.
    rest = data[data.rfind(b")") + 2 :].split()
    try:
        return _ProcStat(pid, rest[0].decode(), int(rest[1]), int(rest[2]), int(rest[19]))
    except (IndexError, ValueError):
        return None


def _have_proc() -> bool:
    return (_PROC / "self" / "stat").exists()


def _live_group_members(pgid: int) -> list[int] | None:
    """Pids of the group's processes that are not zombies; ``None`` without /proc.

    Zombies are excluded: an orphaned member that died waits for init to reap it, which
    may take seconds in a container, yet it holds nothing and cannot be killed again.
    """
    if not _have_proc():
        return None
    members = []
    for entry in os.scandir(_PROC):
        if not entry.name.isdigit():
            continue
        st = _proc_stat(int(entry.name))
        if st is not None and st.pgrp == pgid and st.state not in ("Z", "X", "x"):
            members.append(st.pid)
    return members


def _group_alive(pgid: int) -> bool:
    """Whether the process group still has a member that is not a zombie."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # exists, but some member is not ours; fall through to /proc
    members = _live_group_members(pgid)
    return True if members is None else bool(members)


def _signal_group(pgid: int, sig: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


def _wait_until(done: Callable[[], bool], timeout: float) -> bool:
    """Poll ``done`` with a short back-off until it is true or ``timeout`` passes."""
    deadline = time.monotonic() + timeout
    delay = 0.002
    while not done():
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return done()
        time.sleep(min(delay, remaining))
        delay = min(delay * 2, 0.05)
    return True


def _kill_groups(
    pgids: list[int], grace: float, reap: Callable[[], object] | None = None
) -> list[int]:
    """SIGTERM (+SIGCONT) the groups, SIGKILL what is left after ``grace``.

    ``reap`` is called while waiting so that our own child does not linger as a zombie
    member (which keeps a group "alive" where /proc cannot tell zombies apart).
    Returns the groups that are still alive at the end (normally none).
    """

    def all_gone() -> bool:
        if reap is not None:
            reap()
        return not any(_group_alive(g) for g in pgids)

    for pgid in pgids:
        _signal_group(pgid, signal.SIGTERM)
        # A stopped process keeps SIGTERM pending until it is continued.
        _signal_group(pgid, signal.SIGCONT)
    if _wait_until(all_gone, grace):
        return []
    for pgid in pgids:
        _signal_group(pgid, signal.SIGKILL)
    _wait_until(all_gone, _KILL_WAIT_S)
    return [g for g in pgids if _group_alive(g)]


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
# Pid registry
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GroupRecord:
    """One recorded process group: its id, its leader's start time and the launch token.

    ``starttime`` (clock ticks since boot, from /proc) and ``token`` tell a live group
    started by gymprecice from an unrelated group that later got the same number.
    """

    pgid: int
    starttime: int | None = None
    token: str | None = None

    def to_line(self) -> str:
        start = "-" if self.starttime is None else str(self.starttime)
        return f"{self.pgid} {start} {self.token or '-'}\n"

    @classmethod
    def from_line(cls, line: str) -> GroupRecord | None:
        parts = line.split()
        if not parts:
            return None
        try:
            pgid = int(parts[0])
            start = int(parts[1]) if len(parts) > 1 and parts[1] != "-" else None
        except ValueError:
            return None
        token = parts[2] if len(parts) > 2 and parts[2] != "-" else None
        return cls(pgid, start, token)


class PidRegistry:
    """The process groups an env started, in ``<env_dir>/.gymprecice/pids``.

    One group per line: ``pgid starttime token`` (the first field alone is the pgid, so
    ``cut -d' ' -f1`` gives a plain list). Updates take an ``flock`` on a lock file and
    replace the file atomically, so a reader never sees half a file and concurrent
    writers (threads or processes) never lose an entry.
    """

    def __init__(self, env_dir: Path | str) -> None:
        self.env_dir = Path(env_dir)
        self.path = self.env_dir / ".gymprecice" / "pids"

    def __repr__(self) -> str:
        return f"PidRegistry({str(self.env_dir)!r})"

    def entries(self) -> list[GroupRecord]:
        """The recorded groups (empty when nothing was recorded)."""
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return []
        return [r for r in map(GroupRecord.from_line, text.splitlines()) if r is not None]

    def pgids(self) -> list[int]:
        """The recorded process group ids."""
        return [r.pgid for r in self.entries()]

    def add(self, pgid: int, *, starttime: int | None = None, token: str | None = None) -> None:
        """Record a group (replacing an older record of the same pgid)."""
        record = GroupRecord(pgid, starttime, token)
        self._update(lambda rs: [r for r in rs if r.pgid != pgid] + [record])

    def remove(self, *pgids: int) -> None:
        """Forget groups; unknown ones are ignored."""
        if not self.path.exists():
            return  # nothing recorded; do not recreate a run directory being deleted
        drop = set(pgids)
        self._update(lambda rs: [r for r in rs if r.pgid not in drop])

    def clear(self) -> None:
        """Forget every group."""
        if not self.path.exists():
            return
        self._update(lambda rs: [])

    @contextlib.contextmanager
    def _locked(self) -> Iterator[None]:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path.with_name("pids.lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def _update(self, change: Callable[[list[GroupRecord]], list[GroupRecord]]) -> None:
        with self._locked():
            records = change(self.entries())
            tmp = self.path.with_name(f"pids.{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text("".join(r.to_line() for r in records))
            os.replace(tmp, self.path)


def _record_is_ours(record: GroupRecord) -> bool:
    """Whether a live group with the recorded number is the one gymprecice started.

    A pid number cannot be reused while any process still has it as its group id, so a
    live leader with a different start time means the recorded group is gone and the
    number now belongs to someone else. A group whose leader already exited is
    recognised by the launch token in its members' environment.
    """
    if not _have_proc():
        return True
    leader = _proc_stat(record.pgid)
    if leader is not None and leader.pgrp == record.pgid:
        return record.starttime is None or leader.starttime == record.starttime
    if record.token is None:
        return leader is None
    needle = f"{PROCESS_TOKEN_VARIABLE}={record.token}".encode()
    readable = False
    for pid in _live_group_members(record.pgid) or []:
        try:
            environ = (_PROC / str(pid) / "environ").read_bytes()
        except OSError:
            continue
        readable = True
        if needle in environ.split(b"\0"):
            return True
    # Nothing readable: trust the record rather than leave a solver running.
    return not readable


def kill_recorded_groups(env_dir: Path | str, grace: float = 1.0) -> list[int]:
    """Kill every live process group recorded for ``env_dir``; return the pgids signalled.

    Meant for an outer supervisor (the vector env) after an env process died or hung:
    each recorded group that is still alive and still the one the env started gets
    SIGTERM and SIGCONT, then SIGKILL after ``grace`` seconds. Stale records (group gone,
    number reused) are dropped without a signal. Records of groups that survive even
    SIGKILL stay in the registry so a later call can retry.
    """
    registry = PidRegistry(env_dir)
    records = registry.entries()
    if not records:
        return []
    live = [r.pgid for r in records if _group_alive(r.pgid) and _record_is_ours(r)]
    survivors = _kill_groups(live, grace) if live else []
    if survivors:
        log.warning("process groups %s of %s survived SIGKILL", survivors, env_dir)
    registry.remove(*(r.pgid for r in records if r.pgid not in survivors))
    return live


# --------------------------------------------------------------------------------------
# Solver processes
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


def _open_log(path: Path, append: bool) -> int:
    flags = os.O_WRONLY | os.O_CREAT | os.O_APPEND | getattr(os, "O_CLOEXEC", 0)
    if not append:
        flags |= os.O_TRUNC
    return os.open(path, flags, 0o644)


class SolverProcess:
    """One running solver: its own process group, its log file and an exit notifier.

    Start it with :meth:`start`. ``fileno()`` lets :func:`multiprocessing.connection.wait`
    wake up when the solver exits. :meth:`terminate` (idempotent) kills the whole group,
    stopped members included, and reaps the child, so nothing of an episode survives it.

    ``fileno()`` is a pidfd where the kernel has them (Linux >= 5.3). Elsewhere it is the
    read end of a pipe whose write end only the solver's processes hold: it becomes
    readable once the last of them exits (or closes it), which may be later than the
    direct child's exit when the solver leaves background processes. No thread is needed
    either way; :meth:`poll` stays the authority on the child's exit.
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
        self._lock = threading.Lock()
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
        there until :meth:`terminate` has killed it.

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
        token = secrets.token_hex(8)
        env = clean_mpi_environment(os.environ)
        env.update({str(k): str(v) for k, v in spec.env.items()})
        env[PROCESS_TOKEN_VARIABLE] = token

        use_pidfd = _pidfd_available()
        pipe_r = pipe_w = -1
        if not use_pidfd:
            pipe_r, pipe_w = os.pipe()
        log_fd = _open_log(log_path, append)
        try:
            popen = subprocess.Popen(
                argv,
                cwd=cwd,
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=log_fd,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                close_fds=True,
                pass_fds=() if use_pidfd else (pipe_w,),
            )
        except OSError as exc:
            if pipe_r >= 0:
                os.close(pipe_r)
            raise _launch_error(exc, argv, cwd, where) from exc
        finally:
            os.close(log_fd)
            if pipe_w >= 0:
                os.close(pipe_w)

        # The child is not reaped yet, so its pid cannot have been reused.
        wake_fd = os.pidfd_open(popen.pid) if use_pidfd else pipe_r
        proc = cls(
            name,
            popen,
            argv=argv,
            log_path=log_path,
            wake_fd=wake_fd,
            wake_is_pidfd=use_pidfd,
            env_index=env_index,
            registry=registry,
        )
        if registry is not None:
            try:
                st = _proc_stat(popen.pid)
                registry.add(
                    proc.pgid, starttime=st.starttime if st is not None else None, token=token
                )
            except BaseException:
                proc.terminate(grace=0.0)
                raise
        log.debug("started %s: pid %d, %s, log %s", where, proc.pid, shlex.join(argv), log_path)
        return proc

    # -- state -------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (
            f"<SolverProcess {self.name!r} env={self.env_index} pid={self.pid} "
            f"{describe_returncode(self.returncode)}>"
        )

    @property
    def returncode(self) -> int | None:
        """Exit status of the direct child (negative: killed by that signal); ``None`` while it runs."""
        return self.poll()

    def poll(self) -> int | None:
        """Reap the child if it exited and return :attr:`returncode`.

        Once ``fileno()`` has become readable this gives the exit status: with the pipe
        fallback the pipe closes a moment before the exiting child can be reaped, so a
        short bounded wait bridges that gap.
        """
        returncode = self._popen.poll()
        if returncode is None and not self._wake_is_pidfd and self._wake_fd is not None:
            readable, _, _ = select.select([self._wake_fd], [], [], 0)
            if readable:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    returncode = self._popen.wait(0.1)
        return returncode

    def wait(self, timeout: float | None = None) -> int | None:
        """Wait for the child to exit; return its status, or ``None`` on timeout."""
        try:
            return self._popen.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

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

        SIGTERM goes to the group, followed by SIGCONT so that stopped members can act on
        it; members still alive after ``grace`` seconds get SIGKILL. Calling it again
        does nothing. Returns the child's exit status.
        """
        with self._lock:
            if self._closed:
                return self.returncode
            try:
                survivors = (
                    _kill_groups([self.pgid], grace, reap=self._popen.poll)
                    if _group_alive(self.pgid)
                    else []
                )
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
                        self._registry.remove(self.pgid)
                    except OSError as exc:  # the env dir may already be gone
                        log.debug("could not update %s: %s", self._registry.path, exc)
            finally:
                self._close_fd()
                self._closed = True
            return self.returncode

    close = terminate

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
