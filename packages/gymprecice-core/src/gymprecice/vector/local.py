"""The local backend: each env in its own worker process on this machine.

A worker (``forkserver`` by default, ``spawn`` allowed) runs in its own process group,
builds its env from the pickled ``env_fn`` and answers requests on a pipe. The learner
waits on all pipes and process sentinels at once with one ``poll(2)``; a reply is read
with a deadline even after its first bytes arrived, so a worker stopped half-way through
a message cannot block the learner. A worker whose parent dies gets SIGTERM and kills
its env's recorded process groups, so a learner killed with SIGKILL leaves no solver.

Two layers tell a worker that its learner is gone. ``PR_SET_PDEATHSIG`` fires when the
worker's parent exits, but a forkserver worker's parent is the forkserver, which lives as
long as any worker holds its "alive" pipe: the worker would notice only when it next reads
a request, after the whole pre-run it may be busy with. So each worker also watches the
learner itself, through a pidfd (a descriptor that becomes readable when that very process
exits, never a recycled pid), and sends itself SIGTERM when it does.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import multiprocessing as mp
import os
import select
import signal
import struct
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from multiprocessing.connection import Connection, wait
from multiprocessing.reduction import ForkingPickler
from pathlib import Path
from typing import Any

from gymprecice.env.owner_watchdog import Owner, this_owner
from gymprecice.env.pidregistry import kill_recorded_groups
from gymprecice.vector import host
from gymprecice.vector.contract import CRASH, TIMEOUT, Reply
from gymprecice.vector.failures import TAIL_LINES, describe_exception

#: seconds a reply may take to arrive completely once its first bytes are there
MESSAGE_TIMEOUT_S = 60.0
_MAX_TAIL_BYTES = 64 * 1024


# -- the worker process -----------------------------------------------------------------------


def _die_with_parent() -> None:
    """Ask Linux to send SIGTERM to this worker when its parent exits.

    The parent is the forkserver (which exits with the learner) or, with ``spawn``, the
    learner's thread that started the worker. The SIGTERM handler kills the env's
    recorded process groups, so a learner killed with SIGKILL leaves no solver behind.
    """
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0)


def _die_with_learner(learner: Owner) -> None:
    """SIGTERM to this worker when ``learner`` (its pid and start time) exits.

    A thread waits on a pidfd of the learner; where pidfds are missing (Linux before 5.3)
    it looks every half second. A learner already gone, or a pid that now names another
    process, ends the worker at once.
    """
    if not sys.platform.startswith("linux") or learner.pid == os.getpid():
        return
    try:
        fd: int | None = os.pidfd_open(learner.pid)
    except (AttributeError, OSError):
        fd = None

    def wait_for_exit() -> None:
        if fd is not None and learner.alive():
            select.select([fd], [], [])
        else:
            while learner.alive():
                time.sleep(0.5)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=wait_for_exit, name="gymprecice-learner-watch", daemon=True).start()


def _redirect_output(log_path: str, index: int) -> None:
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    with contextlib.suppress(Exception):
        sys.stdout.reconfigure(line_buffering=True)  # type: ignore[union-attr]
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    print(f"[gymprecice.vector] {stamp} env {index}: worker pid {os.getpid()} started", flush=True)


def _send(conn: Connection, reply: tuple[str, Any], fatal: tuple[type[BaseException], ...]):
    """Send a reply; a reply that cannot be pickled becomes an error description."""
    try:
        data = ForkingPickler.dumps(reply)
    except Exception as exc:
        problem = TypeError(f"the env's reply cannot be pickled to reach the learner: {exc!r}")
        data = ForkingPickler.dumps(("error", describe_exception(problem, fatal)))
    conn.send_bytes(data)


def _worker_main(
    index: int,
    payload: bytes,
    conn: Connection,
    log_path: str,
    environ: dict[str, str],
    learner: Owner | None = None,
) -> None:
    """Body of an env worker process: build the env, then serve requests until closed.

    ``environ`` is the learner's environment when it started this worker: a forkserver
    child would otherwise see the environment the server was started with, and miss
    variables set since (``GYMPRECICE_PRECICE_LIBRARY``, MPI or license settings).
    ``learner`` is the learner's pid and start time: the worker ends when it does.
    """
    with contextlib.suppress(OSError):
        os.setsid()  # own process group: one signal reaches everything the env started
    os.environ.clear()
    os.environ.update(environ)
    _redirect_output(log_path, index)

    def on_term(signum: int, frame: Any) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, on_term)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the learner decides when to stop
    _die_with_parent()
    if learner is not None:
        _die_with_learner(learner)
    fatal: tuple[type[BaseException], ...] = ()
    env: Any = None
    run_dir: str | None = None
    try:
        env, reply, fatal = host.build(payload)
        if env is not None:
            run_dir = reply[1][0]["run_dir"]
        _send(conn, reply, fatal)
        while env is not None:
            try:
                command, data = conn.recv()
            except EOFError:
                return
            if command == "close":
                host.close(env)
                env = None
                _send(conn, ("ok", (None, 0.0)), fatal)
                return
            _send(conn, host.handle(env, command, data, fatal), fatal)
    except (SystemExit, KeyboardInterrupt, BrokenPipeError, EOFError):
        pass
    finally:
        # Leave nothing behind even when the learner vanished without closing us.
        if env is not None and run_dir:
            with contextlib.suppress(Exception):
                kill_recorded_groups(run_dir, grace=0.5)
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()


# -- the learner's side -----------------------------------------------------------------------


class LocalHost:
    """The learner's handle on one worker process (one life of one env)."""

    def __init__(self, process: Any, conn: Connection, log_path: Path, log_offset: int):
        self.process = process
        self.conn = conn
        self.pid: int = process.pid
        self.sentinel: int = process.sentinel
        self.log_path = log_path
        self.log_offset = log_offset

    @property
    def where(self) -> str:
        return f"worker process (pid {self.pid})"

    def send(self, command: str, data: Any) -> None:
        try:
            self.conn.send((command, data))
        except (OSError, ValueError):
            pass  # the worker is gone (broken pipe): the driver sees its sentinel

    def kill(self, join_timeout: float = 5.0) -> int | None:
        """SIGKILL the worker's whole process group, reap it, close the pipe."""
        # Signal the group before reaping the leader: until then its pid cannot be reused.
        for kill, target in ((os.killpg, self.pid), (os.kill, self.pid)):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                kill(target, signal.SIGKILL)
        self.process.join(join_timeout)
        with contextlib.suppress(Exception):
            self.conn.close()
        return self.process.exitcode

    def tail(self, lines: int = TAIL_LINES) -> str:
        """The end of what this worker (not its predecessors) wrote to its log."""
        try:
            with open(self.log_path, "rb") as f:
                size = f.seek(0, os.SEEK_END)
                f.seek(max(self.log_offset, size - _MAX_TAIL_BYTES))
                data = f.read()
        except OSError:
            return ""
        return "\n".join(data.decode("utf-8", errors="replace").splitlines()[-lines:])

    def receive(self, ready_fds: set[int]) -> Reply:
        """Read the reply of a worker whose pipe or process sentinel became readable."""
        fd = self.conn.fileno()
        try:
            # Only the sentinel fired: the worker exited; a reply it sent first still counts.
            if fd in ready_fds or _readable({fd: 0}, 0.0):
                data = recv_bytes(fd, time.monotonic() + MESSAGE_TIMEOUT_S)
                return Reply("message", ForkingPickler.loads(data))
        except TimeoutError:
            return TIMEOUT
        except (EOFError, OSError):
            return CRASH
        except Exception as exc:  # the reply could not be unpickled here
            problem = TypeError(
                f"the reply of a worker (pid {self.pid}) cannot be unpickled: {exc!r}"
            )
            return Reply("message", ("error", describe_exception(problem)))
        return CRASH


class LocalBackend:
    """Start, send, wait, kill, clean up: env workers as processes of this machine.

    ``start_method``: ``"forkserver"`` (default where available) or ``"spawn"``; ``fork``
    is refused (a forked copy of a learner with threads can deadlock). ``daemon``: whether
    workers are daemonic (multiprocessing then also stops them at exit; a daemonic worker
    cannot start multiprocessing children of its own, ``subprocess`` is fine).
    """

    def __init__(self, start_method: str | None = None, daemon: bool = True) -> None:
        method = start_method or _default_start_method()
        if method == "fork":
            raise ValueError(
                "start_method='fork' is not supported: forking a learner that runs threads "
                "(PyTorch, logging) can deadlock the worker; use 'forkserver' or 'spawn'"
            )
        self._ctx = mp.get_context(method)
        if method == "forkserver":
            # Workers fork from a server that already imported numpy, gymnasium and us.
            self._ctx.set_forkserver_preload(["gymprecice.vector"])
        self.start_method = method
        self.daemon = daemon

    def spawn(self, index: int, payload: bytes, log_path: Path) -> LocalHost:
        parent, child = self._ctx.Pipe(duplex=True)
        try:
            offset = log_path.stat().st_size
        except OSError:
            offset = 0
        process = self._ctx.Process(  # type: ignore[attr-defined]
            target=_worker_main,
            args=(index, payload, child, str(log_path), dict(os.environ), this_owner()),
            name=f"gymprecice-env-{index}",
            daemon=self.daemon,
        )
        process.start()
        child.close()
        return LocalHost(process, parent, log_path, offset)

    def wait(self, hosts: Mapping[int, LocalHost], timeout: float | None) -> dict[int, Reply]:
        """Wait up to ``timeout`` for replies (or deaths) of ``hosts``; those that came."""
        fds: dict[int, int] = {}
        for index, worker in hosts.items():
            fds[worker.conn.fileno()] = index
            fds[worker.sentinel] = index
        ready = _readable(fds, timeout)
        return {index: hosts[index].receive(ready_fds) for index, ready_fds in ready.items()}

    def cleanup(self, run_dir: str | None, worker: LocalHost | None, grace: float) -> list[int]:
        """Kill the process groups the env recorded in its run directory's registry."""
        return kill_recorded_groups(run_dir, grace=grace) if run_dir else []

    def close(self, hosts: Sequence[LocalHost], timeout: float) -> None:
        """Ask every worker to close its env; wait up to ``timeout`` for them to exit."""
        for worker in hosts:
            worker.send("close", None)
        deadline = time.monotonic() + timeout
        remaining = {worker.sentinel for worker in hosts}
        while remaining:
            left = deadline - time.monotonic()
            if left <= 0:
                break
            for handle in wait(list(remaining), left):
                remaining.discard(handle)  # type: ignore[arg-type]

    def shutdown(self) -> None:
        """Nothing to release: the workers are gone once killed."""


def _readable(fds: Mapping[int, int], timeout: float | None) -> dict[int, set[int]]:
    """Wait until some of ``fds`` is readable (or hung up); ``{value: {ready fds}}``.

    ``multiprocessing.connection.wait`` builds a ``selectors`` object per call, which
    costs tens of microseconds per env and step in the learner's process; one
    ``poll(2)`` on the raw descriptors costs a few.
    """
    if not hasattr(select, "poll"):  # pragma: no cover - not Linux/macOS
        ready_fds = set(wait(list(fds), timeout))  # type: ignore[arg-type]
    else:
        poller = select.poll()
        for fd in fds:
            poller.register(fd, select.POLLIN)
        ms = None if timeout is None else math.ceil(timeout * 1000)
        while True:
            try:
                events = poller.poll(ms)
                break
            except InterruptedError:  # pragma: no cover - retried by Python already
                continue
        ready_fds = {fd for fd, _ in events}
    ready: dict[int, set[int]] = {}
    for fd in ready_fds:
        ready.setdefault(fds[fd], set()).add(fd)
    return ready


def recv_bytes(fd: int, deadline: float) -> bytes:
    """One message framed like :meth:`multiprocessing.connection.Connection.send_bytes`.

    ``Connection.recv`` blocks until the whole message is there: a worker stopped (or
    swapped out for good) half-way through a large reply would block the learner
    forever. Here every read after the first waits with a deadline. Call only when ``fd``
    is readable. A worker sends exactly one reply per request, so reading ahead in
    large chunks never takes bytes of a next message.
    """
    buffer = bytearray()
    header: int | None = None  # 4, or 12 for messages of 2 GiB and more
    needed = 4
    first = True
    while len(buffer) < needed:
        if not first and not _readable({fd: fd}, max(0.0, deadline - time.monotonic())):
            raise TimeoutError("a message from an env worker stopped arriving half-way")
        first = False
        chunk = os.read(fd, max(needed - len(buffer), 1 << 16))
        if not chunk:
            raise EOFError
        buffer += chunk
        if header is None and len(buffer) >= 4:
            (size,) = struct.unpack_from("!i", buffer)
            if size != -1:
                header, needed = 4, 4 + size
            else:
                needed = 12
        if header is None and needed == 12 and len(buffer) >= 12:
            header, needed = 12, 12 + struct.unpack_from("!Q", buffer, 4)[0]
    return bytes(buffer[header:needed])


def _default_start_method() -> str:
    return "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
