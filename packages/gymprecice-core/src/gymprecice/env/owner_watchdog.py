"""A watchdog per owner process, and the per-user index of who owns which run directory.

The process that owns an env (a script, ``gymprecice evaluate``, a vector-env worker) can
die without running any clean-up: ``kill -9``, the OOM killer, a cluster job's time
limit, a closed terminal. Its solvers run in sessions of their own
(:mod:`gymprecice.env.launching`), so nothing reaches them then, and they compute for hours
for a controller that is gone. Three layers stop them, each covering the one before it
failing:

1. every process core launches asks the kernel to SIGKILL it when its parent dies
   (``PR_SET_PDEATHSIG``, :func:`gymprecice.env.launching.launch`); that reaches only the
   direct child, not what a script or ``mpirun`` started below it;
2. this watchdog: a small process per owner, started at the owner's first launch, that holds
   the read end of a pipe whose write end only the owner holds. The owner tells it each
   launch (token and run directory) *before* the fork. When the pipe closes, or the owner's
   pidfd says it exited (the write end may have leaked into a ``fork``), the owner is gone,
   whatever killed it: the watchdog kills every recorded group it was told about, with the
   identity proofs of :mod:`gymprecice.pidregistry` (start time, launch token; never a
   name), and exits. An owner that closes normally has already ended its solvers, so the
   watchdog finds nothing and just exits. It runs in a session of its own (no terminal
   SIGHUP or SIGINT reaches it, nor a kill of the owner's process group), has no
   ``PR_SET_PDEATHSIG`` and imports nothing heavy (no gymnasium, numpy or plugins);
3. the index: every owner writes the run directories it uses to
   ``$XDG_STATE_HOME/gymprecice/owners/<host>/<pid>-<starttime>`` (``~/.local/state`` by
   default); the watchdog removes the file once it has cleaned up. A file whose owner is
   gone names the run directories whose registries ``gymprecice doctor`` and
   ``gymprecice clean`` check for left-overs (:mod:`gymprecice.clean_command`), e.g. after
   the watchdog itself was killed with its owner.

Every launched process also carries :data:`OWNER_VARIABLE` (``<pid>:<starttime>`` of its
owner) in its environment, so that a clean-up never stops a group a live owner runs, even
in a run directory that a dead owner used before.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from gymprecice.env.pidregistry import (
    PROCESS_TOKEN_VARIABLE,
    GroupRecord,
    PidRegistry,
    kill_group_records,
    process_starttime,
)

__all__ = [
    "OWNER_VARIABLE",
    "Owner",
    "owner_index",
    "owners_dir",
    "this_owner",
    "watch",
    "watchdog_pid",
]

log = logging.getLogger("gymprecice.owner_watchdog")  # its name before the move to env/

#: Environment variable naming the owner of a launched process: ``<pid>:<starttime>``.
OWNER_VARIABLE = "GYMPRECICE_OWNER"
#: Seconds between SIGTERM and SIGKILL when the watchdog ends an owner's groups.
GRACE_S = 1.0
#: Seconds between owner checks where no pidfd watches the owner.
CHECK_S = 2.0
#: Tokens remembered per run directory before those no longer recorded are forgotten.
_PRUNE_AT = 64
_LOG_NAME = "watchdog.log"


# --------------------------------------------------------------------------------------
# Owners and the per-user index
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Owner:
    """A process that owns envs, named so that a later holder of its pid is not taken for it."""

    pid: int
    starttime: int | None

    @property
    def key(self) -> str:
        return f"{self.pid}-{'-' if self.starttime is None else self.starttime}"

    @property
    def variable(self) -> str:
        return f"{self.pid}:{'-' if self.starttime is None else self.starttime}"

    @classmethod
    def parse(cls, text: str, sep: str = "-") -> Owner | None:
        pid, _, start = text.partition(sep)
        try:
            return cls(int(pid), None if start in ("", "-") else int(start))
        except ValueError:
            return None

    def alive(self) -> bool:
        """Still running (the same process: its start time matches)."""
        now = process_starttime(self.pid)
        if now is None:
            return False
        return self.starttime is None or now == self.starttime


def this_owner() -> Owner:
    return Owner(os.getpid(), process_starttime(os.getpid()))


def state_dir() -> Path:
    """``$XDG_STATE_HOME/gymprecice`` (``~/.local/state/gymprecice`` by default)."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(
        os.path.expanduser("~"), ".local", "state"
    )
    return Path(base) / "gymprecice"


def owners_dir() -> Path:
    """This host's owner index (pids mean something only on the machine that gave them)."""
    return state_dir() / "owners" / (socket.gethostname() or "localhost")


def owner_index() -> list[tuple[Owner, list[Path], Path]]:
    """Every indexed owner of this host: ``(owner, run directories, index file)``."""
    found = []
    try:
        entries = sorted(owners_dir().iterdir())
    except OSError:
        return []
    for path in entries:
        owner = Owner.parse(path.name)
        if owner is None:
            continue
        try:
            lines = path.read_text().splitlines()
        except OSError:
            continue
        dirs = list(dict.fromkeys(Path(line) for line in lines if line.strip()))
        found.append((owner, dirs, path))
    return found


# --------------------------------------------------------------------------------------
# The owner's side
# --------------------------------------------------------------------------------------


class _OwnerSide:
    """This process's watchdog: started at the first launch, again after a fork or a death."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.pid = os.getpid()
        self.owner: Owner | None = None
        self.process: subprocess.Popen[bytes] | None = None
        self.write_fd = -1
        self.indexed: set[str] = set()
        self.warned = False
        self.inherited: subprocess.Popen[bytes] | None = None

    def watch(self, env_dir: Path, token: str) -> None:
        with self.lock:
            if self.pid != os.getpid():
                self._forget()
            if self.owner is None:
                self.owner = this_owner()
            key = str(env_dir)
            if key not in self.indexed:
                self._index(key)
                self.indexed.add(key)
            message = (json.dumps(["w", token, key]) + "\n").encode()
            if self._alive() and self._send(message):
                return
            if self._start() and self._send(message):
                return
            if not self.warned:
                self.warned = True
                log.warning(
                    "could not start the watchdog that stops this process's solvers if it is "
                    "killed; run `gymprecice clean` after a crash"
                )

    # -- internals (under the lock) ----------------------------------------------------------

    def _alive(self) -> bool:
        return self.process is not None and self.write_fd >= 0 and self.process.poll() is None

    def _send(self, message: bytes) -> bool:
        try:
            return os.write(self.write_fd, message) == len(message)
        except OSError:  # full (a stopped watchdog) or closed (a dead one): start another
            return False

    def _index(self, env_dir: str) -> None:
        assert self.owner is not None
        try:
            directory = owners_dir()
            directory.mkdir(parents=True, exist_ok=True)
            fd = os.open(
                directory / self.owner.key, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_CLOEXEC
            )
            try:
                os.write(fd, f"{env_dir}\n".encode())
            finally:
                os.close(fd)
        except OSError as exc:
            log.debug("could not index %s under %s: %s", env_dir, state_dir(), exc)

    def _start(self) -> bool:
        """A new watchdog, told about every group still recorded in our run directories."""
        assert self.owner is not None
        self._close_fd()
        try:
            read_fd, write_fd = os.pipe2(os.O_CLOEXEC)
        except OSError:
            return False
        env = {
            k: v for k, v in os.environ.items() if k not in (PROCESS_TOKEN_VARIABLE, OWNER_VARIABLE)
        }
        env["GYMPRECICE_DISABLE_PLUGINS"] = "1"  # nothing to register: start in milliseconds
        argv = [sys.executable, "-m", "gymprecice.owner_watchdog", str(read_fd)]
        argv += [str(self.owner.pid), str(self.owner.starttime or "-"), self.owner.key]
        try:
            self.process = subprocess.Popen(
                argv,
                cwd="/",  # pin no directory
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,  # no SIGHUP/SIGINT of our terminal, not in our group
                close_fds=True,
                pass_fds=(read_fd,),
            )
        except OSError as exc:
            log.debug("could not start the watchdog: %s", exc)
            os.close(write_fd)
            return False
        finally:
            os.close(read_fd)
        os.set_blocking(write_fd, False)  # a stopped watchdog must never block a launch
        self.write_fd = write_fd
        for key in self.indexed:
            with contextlib.suppress(OSError):
                for record in PidRegistry(key).entries():
                    if record.token:
                        self._send((json.dumps(["w", record.token, key]) + "\n").encode())
        return True

    def _close_fd(self) -> None:
        if self.write_fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self.write_fd)
            self.write_fd = -1

    def _forget(self) -> None:
        """In a forked child: the watchdog is the parent's; this process gets its own."""
        self.lock = threading.Lock()
        self._close_fd()
        self.pid = os.getpid()
        self.owner = None
        # Kept referenced: collected here, its __del__ would poll a child that is not ours
        # (in a child about to exec a solver, too).
        self.inherited, self.process = self.process, None
        self.indexed = set()


_owner = _OwnerSide()


def _after_fork_in_child() -> None:
    # The child of a plain fork (multiprocessing's "fork") must not hold the parent's write
    # end: the pipe would then stay open after the parent died.
    _owner._forget()


os.register_at_fork(after_in_child=_after_fork_in_child)


def watch(env_dir: Path | str, token: str) -> None:
    """Tell this process's watchdog about a launch in ``env_dir`` (call it before the fork).

    Starts the watchdog on first use and again when it died; indexes ``env_dir`` for
    ``gymprecice doctor``/``clean``. Never raises: a watchdog that cannot start is said once
    in the log, and the other layers still hold.
    """
    try:
        _owner.watch(Path(env_dir), token)
    except Exception as exc:  # pragma: no cover - defensive: a launch must not fail here
        log.debug("watchdog: %s", exc)


def watchdog_pid() -> int | None:
    """The pid of this process's watchdog while it runs (``None`` before the first launch)."""
    process = _owner.process
    if process is None or _owner.pid != os.getpid() or process.poll() is not None:
        return None
    return process.pid


def owner_variable() -> str:
    """The value of :data:`OWNER_VARIABLE` for processes this process launches."""
    if _owner.owner is None or _owner.pid != os.getpid():
        return this_owner().variable
    return _owner.owner.variable


# --------------------------------------------------------------------------------------
# The watchdog process
# --------------------------------------------------------------------------------------


class _Watchdog:
    def __init__(self, fd: int, owner: Owner, key: str) -> None:
        self.fd = fd
        self.owner = owner
        self.key = key
        self.buffer = b""
        #: run directory -> launch tokens the owner announced there
        self.watched: dict[str, set[str]] = {}

    def take(self, data: bytes) -> None:
        self.buffer += data
        *lines, self.buffer = self.buffer.split(b"\n")
        for line in lines:
            try:
                kind, token, env_dir = json.loads(line)
            except (ValueError, TypeError):
                continue
            if kind != "w":
                continue
            tokens = self.watched.setdefault(env_dir, set())
            tokens.add(token)
            if len(tokens) > _PRUNE_AT:
                self._prune(env_dir)

    def _prune(self, env_dir: str) -> None:
        """Forget the tokens whose records are gone (groups the owner ended itself)."""
        try:
            recorded = {r.token for r in PidRegistry(env_dir).entries()}
        except OSError:
            return
        self.watched[env_dir] &= recorded

    def drain(self) -> None:
        """Read what the owner wrote before it died (the pipe may still be open)."""
        os.set_blocking(self.fd, False)
        with contextlib.suppress(OSError):
            while data := os.read(self.fd, 65536):
                self.take(data)

    def wait_for_the_owner(self) -> None:
        pidfd = None
        if os.getppid() == self.owner.pid:  # still our parent: the number is surely its
            with contextlib.suppress(AttributeError, OSError):
                pidfd = os.pidfd_open(self.owner.pid)
        elif not self.owner.alive():
            self.drain()
            return
        # poll(2), not select(2): the pipe keeps the owner's descriptor number, which may be
        # above select's limit of 1024 in a process with many files open.
        poller = select.poll()
        poller.register(self.fd, select.POLLIN)
        if pidfd is not None:
            poller.register(pidfd, select.POLLIN)
        while True:
            ready = {fd for fd, _ in poller.poll(CHECK_S * 1000)}
            if self.fd in ready:
                data = os.read(self.fd, 65536)
                if not data:
                    return
                self.take(data)
            if (pidfd is not None and pidfd in ready) or (
                not ready and pidfd is None and not self.owner.alive()
            ):
                self.drain()
                return

    def clean_up(self) -> bool:
        """Kill what the owner left; True when nothing survived."""
        clean = True
        for env_dir, tokens in self.watched.items():
            registry = PidRegistry(env_dir)
            try:
                records = [r for r in registry.entries() if r.token in tokens]
            except OSError:
                continue
            if not records:
                continue
            signalled, survivors = kill_group_records(records, GRACE_S)
            with contextlib.suppress(OSError):
                registry.remove_records(lambda r, rs=records, s=survivors: r in rs and r not in s)
            if signalled:
                self._say(env_dir, signalled, survivors)
            clean = clean and not survivors
        return clean

    def _say(
        self, env_dir: str, signalled: list[GroupRecord], survivors: list[GroupRecord]
    ) -> None:
        stamp = time.strftime("%Y-%m-%d %H:%M:%S")
        groups = ", ".join(str(r.pgid) for r in signalled)
        line = f"{stamp} owner {self.owner.pid} is gone: stopped process groups {groups}"
        if survivors:
            line += f"; {', '.join(str(r.pgid) for r in survivors)} survived SIGKILL"
        with (
            contextlib.suppress(OSError),
            open(Path(env_dir) / ".gymprecice" / _LOG_NAME, "a") as f,
        ):
            f.write(line + "\n")


def main(argv: list[str] | None = None) -> int:
    """``python -m gymprecice.owner_watchdog FD OWNER_PID OWNER_STARTTIME KEY``."""
    argv = sys.argv[1:] if argv is None else argv
    fd, pid, start, key = int(argv[0]), int(argv[1]), argv[2], argv[3]
    for signum in (signal.SIGINT, signal.SIGHUP, signal.SIGPIPE):
        signal.signal(signum, signal.SIG_IGN)
    owner = Owner(pid, None if start == "-" else int(start))
    dog = _Watchdog(fd, owner, key)
    dog.wait_for_the_owner()
    if dog.clean_up():
        with contextlib.suppress(OSError):
            (owners_dir() / key).unlink()
    return 0


if __name__ == "__main__":
    sys.exit(main())
