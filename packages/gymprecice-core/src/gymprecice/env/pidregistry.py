"""Which processes an env started, on disk, and killing them without ever hitting another.

Every process group an env starts (solvers, the coupling worker) is recorded in
``<env_dir>/.gymprecice/pids`` with its number, its leader's start time and a random launch
token that the group's processes carry in their environment. An outer supervisor (the
vector env, a restarted run, :func:`~gymprecice.rundir.create_run_directory`) kills what the
registry records even after the env process died (:func:`kill_recorded_groups`).

Pid numbers are reused. A record whose group has gone may name an unrelated session leader
by the time it is read, so no signal is sent on a number alone. Each process is signalled
only when it is proven to be ours, and through a pidfd opened *before* the proof, so the
signal reaches the process that was checked and no later holder of its number:

* the leader, when its start time equals the recorded one (and its environment, where
  readable, holds the recorded token: start times tick only every 10 ms);
* any member of the group, or of the session the leader started (``mpirun`` puts each
  rank in a group of its own), while the proven leader still exists (alive or an
  unreaped zombie): neither number can be reused while the leader holds the pid;
* any process whose environment holds the record's launch token (members left behind
  after the leader exited, or a launch still being recorded).

Nothing else is signalled: a record with neither start time nor token proves nothing, and
once no proven member is alive the group gets no further signal. Kernels without pidfds
fall back to ``kill(2)`` right after the proof (a window of microseconds instead of none).
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "PROCESS_TOKEN_VARIABLE",
    "GroupRecord",
    "PidRegistry",
    "kill_group_records",
    "kill_recorded_groups",
    "process_starttime",
]

log = logging.getLogger("gymprecice.pidregistry")  # its name before the move to env/

#: Environment variable that carries a random token into every process gymprecice starts.
PROCESS_TOKEN_VARIABLE = "GYMPRECICE_PROCESS_TOKEN"

# How long to wait for a group to vanish after SIGKILL before giving up on it (a process
# in uninterruptible sleep cannot die until its I/O returns).
KILL_WAIT_S = 2.0

#: /proc/<pid>/stat flag of a task that has begun to exit (set before its files close).
PF_EXITING = 0x4

_PROC = Path("/proc")


# --------------------------------------------------------------------------------------
# /proc
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ProcStat:
    pid: int
    state: str
    ppid: int
    pgrp: int
    flags: int
    starttime: int
    session: int = -1

    def in_group_of(self, pgid: int) -> bool:
        """In the process group ``pgid``, or in the session its leader started.

        Solvers start in a session of their own (its id is the leader's pid, the group's
        number), and launchers may put what they start in groups of its own inside it:
        Open MPI's ``mpirun`` gives each rank its own process group.
        """
        return self.pgrp == pgid or self.session == pgid

    @property
    def dead(self) -> bool:
        """A zombie, or a task already tearing itself down."""
        return self.state in ("Z", "X", "x") or bool(self.flags & PF_EXITING)


def proc_stat(pid: int) -> ProcStat | None:
    try:
        data = (_PROC / str(pid) / "stat").read_bytes()
    except OSError:
        return None
    # The command name (field 2) may contain spaces and parentheses: split after the last ')'.
    rest = data[data.rfind(b")") + 2 :].split()
    try:
        return ProcStat(
            pid,
            rest[0].decode(),
            int(rest[1]),
            int(rest[2]),
            int(rest[6]),
            int(rest[19]),
            int(rest[3]),
        )
    except (IndexError, ValueError):
        return None


def process_starttime(pid: int) -> int | None:
    """The start time of ``pid`` in clock ticks since boot (``None`` when unknown)."""
    st = proc_stat(pid)
    return None if st is None else st.starttime


def have_proc() -> bool:
    return (_PROC / "self" / "stat").exists()


def _all_pids() -> Iterator[int]:
    for entry in os.scandir(_PROC):
        if entry.name.isdigit():
            yield int(entry.name)


def _token_state(pid: int, token: str) -> bool | None:
    """Whether ``pid``'s environment holds ``token`` (``None``: it cannot be read)."""
    try:
        environ = (_PROC / str(pid) / "environ").read_bytes()
    except OSError:
        return None
    return f"{PROCESS_TOKEN_VARIABLE}={token}".encode() in environ.split(b"\0")


def _carries_token(pid: int, token: str) -> bool:
    return _token_state(pid, token) is True


def live_group_members(pgid: int) -> list[int] | None:
    """Pids of the group's processes that are neither zombies nor exiting; ``None`` without /proc."""
    if not have_proc():
        return None
    members = []
    for pid in _all_pids():
        st = proc_stat(pid)
        if st is not None and st.pgrp == pgid and not st.dead:
            members.append(pid)
    return members


# --------------------------------------------------------------------------------------
# A handle that signals exactly one process
# --------------------------------------------------------------------------------------


class _Handle:
    """One process, pinned by a pidfd where the kernel has them."""

    def __init__(self, pid: int, fd: int | None) -> None:
        self.pid = pid
        self.fd = fd

    @classmethod
    def open(cls, pid: int) -> _Handle | None:
        pidfd_open = getattr(os, "pidfd_open", None)
        if pidfd_open is None:
            return cls(pid, None)
        try:
            return cls(pid, pidfd_open(pid))
        except ProcessLookupError:
            return None
        except OSError:  # ENOSYS, or blocked by seccomp: fall back to kill(2)
            return cls(pid, None)

    def exists(self) -> bool:
        """Still there (alive or an unreaped zombie): its number cannot have been reused."""
        try:
            self.send(0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True

    def send(self, sig: int) -> None:
        if self.fd is not None:
            signal.pidfd_send_signal(self.fd, sig)
        else:
            os.kill(self.pid, sig)

    def close(self) -> None:
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = None


# --------------------------------------------------------------------------------------
# The registry
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GroupRecord:
    """One recorded process group: its id, its leader's start time and the launch token.

    ``pgid`` is ``None`` while a launch is being recorded (the process may exist already,
    recognisable only by its token). ``starttime`` is in clock ticks since boot (/proc).
    """

    pgid: int | None
    starttime: int | None = None
    token: str | None = None

    def to_line(self) -> str:
        pgid = "-" if self.pgid is None else str(self.pgid)
        start = "-" if self.starttime is None else str(self.starttime)
        return f"{pgid} {start} {self.token or '-'}\n"

    @classmethod
    def from_line(cls, line: str) -> GroupRecord | None:
        parts = line.split()
        if not parts:
            return None
        try:
            pgid = int(parts[0]) if parts[0] != "-" else None
            start = int(parts[1]) if len(parts) > 1 and parts[1] != "-" else None
        except ValueError:
            return None
        token = parts[2] if len(parts) > 2 and parts[2] != "-" else None
        if pgid is None and token is None:
            return None
        return cls(pgid, start, token)


class PidRegistry:
    """The process groups an env started, in ``<env_dir>/.gymprecice/pids``.

    One group per line: ``pgid starttime token`` (``-`` for an unknown field; the first
    field alone is the pgid). Updates take an ``flock`` on a lock file and replace the file
    atomically, so a reader never sees half a file and concurrent writers (threads or
    processes) never lose an entry.
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
        """The recorded process group ids (launches still being recorded excluded)."""
        return [r.pgid for r in self.entries() if r.pgid is not None]

    def add_pending(self, token: str) -> None:
        """Record a launch before it happens, so a crash right after it leaves a trace."""
        self.add_record(GroupRecord(None, None, token))

    def add(self, pgid: int, *, starttime: int | None = None, token: str | None = None) -> None:
        """Record a group (replacing an older record of the same pgid or token).

        Without ``starttime`` or ``token`` the leader's start time is read now, while the
        pid is known to be the caller's own child: a record that proves nothing is never
        signalled, so a bare ``add(pid)`` must not write one.
        """
        if starttime is None and token is None:
            starttime = process_starttime(pgid)
        self.add_record(GroupRecord(pgid, starttime, token))

    def add_record(self, record: GroupRecord) -> None:
        def change(rs: list[GroupRecord]) -> list[GroupRecord]:
            kept = [
                r
                for r in rs
                if not (record.pgid is not None and r.pgid == record.pgid)
                and not (record.token is not None and r.token == record.token)
            ]
            return [*kept, record]

        self._update(change)

    def remove(self, *pgids: int) -> None:
        """Forget groups; unknown ones are ignored."""
        drop = set(pgids)
        self.remove_records(lambda r: r.pgid in drop)

    def remove_token(self, token: str) -> None:
        """Forget the group (or pending launch) of a launch token."""
        self.remove_records(lambda r: r.token == token)

    def remove_records(self, drop: Callable[[GroupRecord], bool]) -> None:
        if not self.path.exists():
            return  # nothing recorded; do not recreate a run directory being deleted
        self._update(lambda rs: [r for r in rs if not drop(r)])

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


# --------------------------------------------------------------------------------------
# Identity-proven kills
# --------------------------------------------------------------------------------------


def proven_members(record: GroupRecord) -> list[_Handle]:
    """Handles on the live processes of ``record``'s group that are proven ours.

    The caller closes the handles. Empty without /proc (nothing can be proven).
    """
    if not have_proc():
        return []
    leader: _Handle | None = None
    proven: list[_Handle] = []
    if record.pgid is not None and record.starttime is not None:
        handle = _Handle.open(record.pgid)
        if handle is not None:
            st = proc_stat(record.pgid)
            # Start times tick every 10 ms: where the environment is readable, a token
            # recorded with the group must be there too.
            if (
                st is not None
                and st.pgrp == record.pgid
                and st.starttime == record.starttime
                and (record.token is None or _token_state(record.pgid, record.token) is not False)
                and handle.exists()
            ):
                leader = handle
                if not st.dead:
                    proven.append(handle)
            if leader is None:
                handle.close()
    for pid in _all_pids():
        if pid == record.pgid and leader is not None:
            continue
        st = proc_stat(pid)
        if st is None or st.dead:
            continue
        if record.pgid is not None and not st.in_group_of(record.pgid):
            continue
        if record.pgid is None and record.token is None:
            continue
        handle = _Handle.open(pid)
        if handle is None:
            continue
        st = proc_stat(pid)  # read again: the handle now pins what we read
        ours = (
            st is not None
            and not st.dead
            and (record.pgid is None or st.in_group_of(record.pgid))
            and (
                (leader is not None and leader.exists())
                or (record.token is not None and _carries_token(pid, record.token))
            )
            and handle.exists()
        )
        if ours:
            proven.append(handle)
        else:
            handle.close()
    if leader is not None and leader not in proven:
        leader.close()
    return proven


def _signal_proven(records: Iterable[GroupRecord], sigs: Iterable[int]) -> list[GroupRecord]:
    """Send ``sigs`` to every proven member; return the records that had any."""
    sigs = list(sigs)
    hit = []
    for record in records:
        handles = proven_members(record)
        try:
            for handle in handles:
                for sig in sigs:
                    with contextlib.suppress(ProcessLookupError, PermissionError):
                        handle.send(sig)
        finally:
            for handle in handles:
                handle.close()
        if handles:
            hit.append(record)
    return hit


def _any_proven(record: GroupRecord) -> bool:
    handles = proven_members(record)
    for handle in handles:
        handle.close()
    return bool(handles)


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


def kill_group_records(
    records: list[GroupRecord], grace: float, reap: Callable[[], object] | None = None
) -> tuple[list[GroupRecord], list[GroupRecord]]:
    """SIGTERM + SIGCONT the proven members, SIGKILL those left after ``grace``.

    SIGCONT lets stopped members act on the SIGTERM. ``reap`` is called while waiting
    (a parent reaping its own exited children). Returns ``(signalled, survivors)``: the
    records whose groups had a proven member, and those still alive at the end.
    """
    signalled = _signal_proven(records, (signal.SIGTERM, signal.SIGCONT))
    if not signalled:
        return [], []

    def all_gone() -> bool:
        if reap is not None:
            reap()
        return not any(_any_proven(r) for r in signalled)

    if grace > 0 and _wait_until(all_gone, grace):
        return signalled, []
    _signal_proven(signalled, (signal.SIGKILL,))
    _wait_until(all_gone, KILL_WAIT_S)
    return signalled, [r for r in signalled if _any_proven(r)]


def kill_recorded_groups(env_dir: Path | str, grace: float = 1.0) -> list[int]:
    """Kill every process group recorded for ``env_dir`` that is still ours; return their pgids.

    Meant for an outer supervisor (the vector env, a new run over an old run directory)
    after an env process died or hung. Each recorded process proven to be the one the env
    started (see the module docstring) gets SIGTERM and SIGCONT, then SIGKILL after
    ``grace`` seconds. Stale records (group gone, number reused) are dropped without a
    signal; records of groups that survive even SIGKILL stay so a later call can retry.
    """
    registry = PidRegistry(env_dir)
    records = registry.entries()
    if not records:
        return []
    signalled, survivors = kill_group_records(records, grace)
    if survivors:
        log.warning("process groups %s of %s survived SIGKILL", survivors, env_dir)
    with contextlib.suppress(OSError):
        registry.remove_records(lambda r: r in records and r not in survivors)
    return [r.pgid for r in signalled if r.pgid is not None]
