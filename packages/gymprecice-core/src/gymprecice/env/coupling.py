"""The env's side of the coupling: requests to the coupling worker, under a watchdog.

Every blocking preCICE call happens in the worker process (see :mod:`gymprecice._worker`).
Here we send it a request and wait on three things at once with
:func:`multiprocessing.connection.wait`: the worker's reply, the worker's own exit, and each
solver process's exit (their pidfds). While nothing arrives we check, once a second, that
some solver log grew; if neither a reply nor log growth came for ``progress_timeout``
seconds, the solver counts as hung. Any failure ends the episode at once: the worker and all
solver process groups are killed, and a :class:`~gymprecice.errors.SolverError` carrying the
env index and the solver's log tail is raised. Nothing is left running, so the next reset
starts clean.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.env.exit_status import describe_returncode
from gymprecice.env.launching import launch
from gymprecice.env.pidregistry import KILL_WAIT_S, PidRegistry
from gymprecice.env.solver_log import read_tail
from gymprecice.env.solver_process import SolverProcess
from gymprecice.plugin.divergence import HARD_FAULT_STATUSES
from gymprecice.plugin.errors import (
    CouplingError,
    PreciceNotInstalledError,
    SolverCrashedError,
    SolverDivergedError,
    SolverError,
    SolverTimeoutError,
)

log = logging.getLogger("gymprecice.coupling")  # its name before the move to env/

DataKey = tuple[str, str]
#: how long a solver that exited while we wait may still be followed by the worker's reply
EXIT_GRACE_S = 1.0
POLL_S = 1.0


@dataclass
class CouplingState:
    """What the worker reports after init and after each step."""

    time: float
    windows: int
    ongoing: bool
    dt: float
    read: dict[DataKey, np.ndarray]
    precice_s: float
    advanced: int = 0
    #: vertices of direct-access meshes, as the partner defined them (init only)
    coordinates: dict[str, np.ndarray] | None = None


class WorkerProcess:
    """The coupling worker child: a socket-pair connection, an exit notifier and a log file.

    Recorded in the pid registry like a solver (group, start time, launch token), so a
    supervisor never mistakes a later holder of its pid for it. It asks the kernel to
    SIGKILL it when the thread that forked it exits (``PR_SET_PDEATHSIG`` follows the
    *thread*, not the process), so it is forked from a thread that lives as long as the
    process (:func:`~gymprecice.env.parent_death.call_in_lasting_thread`, as every
    launch): an env reset from a worker thread of a ``ThreadPoolExecutor`` keeps its
    coupling worker after that thread ends.
    """

    def __init__(
        self, log_path: Path, registry: PidRegistry | None = None, *, io_timeout: float = 120.0
    ) -> None:
        parent, child = socket.socketpair()
        # A request or reply larger than the socket buffer blocks until the other side
        # reads; a stopped worker never does. The kernel ends such a send or receive
        # after ``io_timeout`` seconds (an OSError: the worker counts as gone).
        timeval = struct.pack("ll", int(io_timeout), int(io_timeout % 1 * 1e6))
        for option in (socket.SO_SNDTIMEO, socket.SO_RCVTIMEO):
            parent.setsockopt(socket.SOL_SOCKET, option, timeval)
        self.log_path = log_path
        env = {**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"}  # the worker needs no plugins
        argv = [sys.executable, "-m", "gymprecice._worker", str(child.fileno()), str(os.getpid())]
        try:
            with open(log_path, "ab") as log:
                launched = launch(
                    argv,
                    cwd=None,
                    env=env,
                    stdout=log.fileno(),
                    pass_fds=(child.fileno(),),
                    registry=registry,
                )
        except BaseException:
            parent.close()
            raise
        finally:
            child.close()
        self.popen = launched.popen
        self.record = launched.record
        self.conn = Connection(parent.detach())
        self.pid = self.popen.pid
        self._wake_fd = launched.wake_fd
        self._wake_is_pidfd = launched.wake_is_pidfd
        self.registry = registry

    def fileno(self) -> int:
        return self._wake_fd

    def poll(self) -> int | None:
        return self.popen.poll()

    def kill(self) -> None:
        """SIGKILL the worker (it starts nothing of its own), reap it and close up."""
        if self.popen.poll() is None:
            # Not reaped, so the pid is still the worker's: a direct signal is exact.
            try:
                if self._wake_is_pidfd and self._wake_fd >= 0:
                    signal.pidfd_send_signal(self._wake_fd, signal.SIGKILL)
                else:
                    os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        try:
            self.popen.wait(KILL_WAIT_S)
        except subprocess.TimeoutExpired:
            log.warning(
                "coupling worker %d did not die within %g s of SIGKILL", self.pid, KILL_WAIT_S
            )
            self.close(forget=False)
            return
        self.close()

    def close(self, *, forget: bool = True) -> None:
        if self._wake_fd >= 0:
            with contextlib.suppress(OSError):
                os.close(self._wake_fd)
            self._wake_fd = -1
        self.conn.close()
        if self.registry is not None and forget:
            with contextlib.suppress(OSError):
                self.registry.remove_token(self.record.token or "")
            self.registry = None

    def log_size(self) -> int:
        try:
            return self.log_path.stat().st_size
        except OSError:
            return 0

    def log_tail(self, lines: int = 30) -> str:
        return read_tail(self.log_path, lines)


#: what preCICE logs in a participant whose partner went away (3.4.1's sockets): its
#: exit is a consequence of another solver's, never the cause
PARTNER_LOST = "This often means that the other participant exited"


def _why_exited(status: int | None) -> str:
    """A solver's exit, said for an error raised while the coupling still runs."""
    if status in (0, None):
        return "exited while the coupling was still running"
    return describe_returncode(status)


def _culprit_first(exited: Sequence[SolverProcess]) -> list[SolverProcess]:
    """Exited solvers, the likeliest cause first.

    A solver killed from outside or by its binary (SIGKILL, SIGSEGV, SIGBUS) comes first;
    one whose log says preCICE lost its partner comes last; the rest keep their order.
    """

    def rank(solver: SolverProcess) -> int:
        if solver.poll() in HARD_FAULT_STATUSES:
            return 0
        return 2 if PARTNER_LOST in solver.log_tail(40) else 1

    return sorted(exited, key=rank)


class CouplingSession:
    """One episode's coupling: a worker, the solvers it talks to, and the watchdog."""

    def __init__(
        self,
        worker: WorkerProcess,
        solvers: Sequence[SolverProcess],
        *,
        env_index: int,
        progress_timeout: float,
        kill_grace: float,
        health_check: Callable[[SolverProcess], str | None] | None = None,
        watch: Callable[[SolverProcess], str | None] | None = None,
    ) -> None:
        self.worker = worker
        self.solvers = list(solvers)
        self.env_index = env_index
        self.progress_timeout = progress_timeout
        self.kill_grace = kill_grace
        self.health_check = health_check
        #: asked about a running solver whose log grew: divergence evidence, or None
        self.watch = watch
        self.closed = False
        self._killing = False

    # -- requests ---------------------------------------------------------------------------
    def initialize(self, request: dict[str, Any], timeout: float) -> CouplingState:
        return self._state(self._request("init", request, timeout, checking_health=True))

    def advance(
        self, writes: list[dict[DataKey, np.ndarray]], timeout: float | None
    ) -> CouplingState:
        return self._state(self._request("advance", {"writes": writes}, timeout))

    def finish(self, solver_exit_timeout: float) -> None:
        """End a completed episode: finalize, let solvers exit, then kill what remains."""
        try:
            self._request("finalize", {}, timeout=max(solver_exit_timeout, 1.0))
            self.worker.conn.send(("exit", {}))
        except (SolverError, OSError, CouplingError):
            pass
        deadline = time.monotonic() + solver_exit_timeout
        pending = [s for s in self.solvers if s.poll() is None]
        while pending and time.monotonic() < deadline:
            wait(pending, timeout=max(0.0, deadline - time.monotonic()))
            pending = [s for s in pending if s.poll() is None]
        self.kill()

    def kill(self) -> None:
        """Kill the worker and every solver group. Idempotent.

        A call made while another one waits out the kill grace (a signal handler ending
        the episode) does not return early: it finishes the job at once with SIGKILL, so
        a process that dies of that signal leaves nothing behind.
        """
        if self.closed:
            return
        nested, self._killing = self._killing, True
        try:
            self.worker.kill()
        finally:
            try:
                for solver in list(self.solvers):
                    solver.terminate(0.0 if nested else self.kill_grace)
            finally:
                self.closed = True

    def ensure_solvers_running(self, op: str) -> None:
        """Fail (and end the session) if a solver has exited while the coupling goes on.

        Called while the controller waits for something other than preCICE, a solver's
        output file for instance: a solver that died there would otherwise be noticed
        only when that wait times out. When several have died since the last look, the
        one named is the cause (:func:`_culprit_first`), not a partner that preCICE
        aborted because the cause went away.
        """
        for solver in _culprit_first([s for s in self.solvers if s.poll() is not None]):
            what = _why_exited(solver.poll()) + self._diagnosis(solver)
            self._fail(SolverCrashedError, solver, what, op)

    # -- the watchdog ---------------------------------------------------------------------
    @staticmethod
    def _state(payload: dict[str, Any]) -> CouplingState:
        return CouplingState(**payload)

    def _request(
        self, op: str, request: dict[str, Any], timeout: float | None, checking_health: bool = False
    ) -> dict[str, Any]:
        if self.closed:
            raise CouplingError(f"env {self.env_index}: the coupling session is already closed")
        try:
            self.worker.conn.send((op, request))
        except OSError:
            self._fail_worker_gone(op)
        start = time.monotonic()
        last_progress = start
        log_sizes = self._log_sizes()
        exited_at: float | None = None
        watched: list[Any] = [self.worker.conn, self.worker, *self.solvers]
        while True:
            ready = wait(watched, timeout=POLL_S)
            if self.worker.conn in ready:
                try:
                    reply = self.worker.conn.recv()
                except (EOFError, OSError):
                    self._fail_worker_gone(op)
                payload = self._unpack(reply, op)
                self._check_solvers_lived(payload, op)
                return payload
            if self.worker in ready:
                self._fail_worker_gone(op)
            now = time.monotonic()
            for solver in [s for s in self.solvers if s in ready]:
                watched.remove(solver)
                if solver.poll() not in (0, None):
                    what = describe_returncode(solver.poll()) + self._diagnosis(solver)
                    self._fail(SolverCrashedError, solver, what, op)
                exited_at = exited_at or now
            if exited_at is not None and now - exited_at > EXIT_GRACE_S:
                done = next(s for s in self.solvers if s.poll() is not None)
                what = "exited (status 0) while the controller was still waiting for it"
                self._fail(SolverCrashedError, done, what + self._diagnosis(done), op)
            sizes = self._log_sizes()
            if sizes != log_sizes:
                grown = [s for s, a, b in zip(self.solvers, sizes[1:], log_sizes[1:]) if a != b]
                log_sizes = sizes
                last_progress = now
                self._watch(grown, op)
            if checking_health and self.health_check is not None:
                for solver in self.solvers:
                    problem = self.health_check(solver)
                    if problem:
                        self._fail(SolverCrashedError, solver, f"has a problem: {problem}", op)
            if now - last_progress > self.progress_timeout:
                self._fail(
                    SolverTimeoutError,
                    self._quietest(),
                    f"made no progress for {self.progress_timeout:g} s (no reply from preCICE "
                    "and no new solver output); it looks hung",
                    op,
                )
            if timeout is not None and now - start > timeout:
                self._fail(
                    SolverTimeoutError,
                    self._quietest(),
                    f"did not finish '{op}' within {timeout:g} s",
                    op,
                )

    def _check_solvers_lived(self, payload: dict[str, Any], op: str) -> None:
        """Refuse a reply that a dead solver may not have computed.

        preCICE does not always block when a partner dies: it may finish a window or two
        with the data it had (measured with 3.4.1), so a reply can arrive after a solver
        was killed, carrying data no live solver computed for this step. Every solver
        must therefore still be running when the reply is taken; a solver that exited
        (or is exiting: /proc shows it before its sockets close) fails the step. Only a
        clean exit (status 0) at the end of the coupling is a normal ending.
        """
        if op == "finalize":
            return
        for solver in self.solvers:
            if not solver.exited():
                continue
            ending = not payload.get("ongoing", True)
            status = solver.poll()
            if status is None:
                solver.wait(EXIT_GRACE_S)  # exiting: its status comes in a moment
                status = solver.poll()
            if ending and status == 0:
                continue
            what = _why_exited(status) + "; the data of this step is discarded"
            what += self._diagnosis(solver)
            self._fail(SolverCrashedError, solver, what, op)

    def _diagnosis(self, solver: SolverProcess) -> str:
        """What the solver's plugin makes of a solver that exited, for the error message.

        The exit status alone ("exited with status 127") rarely says what to fix; the
        plugin's ``gymprecice_check_solver`` reads the log ("a program the script calls
        is not on PATH"). A health check that fails itself must not hide the crash.
        """
        if self.health_check is None:
            return ""
        try:
            problem = self.health_check(solver)
        except Exception as exc:
            log.warning("the health check of solver %r failed: %s", solver.name, exc)
            return ""
        return f"; diagnosis: {problem}" if problem else ""

    def _watch(self, solvers: Sequence[SolverProcess], op: str) -> None:
        """End the request when a running solver shows divergence (see ``watch``)."""
        if self.watch is None:
            return
        for solver in solvers:
            if solver.poll() is not None:
                continue
            evidence = self.watch(solver)
            if evidence:
                self._fail(SolverDivergedError, solver, f"diverged: {evidence}", op, evidence)

    def _log_sizes(self) -> list[int]:
        """Sizes of every log of the episode: growth in any of them counts as progress."""
        return [self.worker.log_size(), *(s.log_size() for s in self.solvers)]

    def _quietest(self) -> SolverProcess | None:
        return self.solvers[0] if self.solvers else None

    def _unpack(self, reply: tuple[Any, ...], op: str) -> dict[str, Any]:
        if reply[0] == "ok":
            return reply[1]
        _, kind, message = reply
        self.kill()
        if kind == "missing-precice":
            raise PreciceNotInstalledError(message)
        raise CouplingError(f"env {self.env_index}: preCICE failed during '{op}': {message}")

    def _fail_worker_gone(self, op: str) -> None:
        tail = self.worker.log_tail()
        status = self.worker.poll()
        self.kill()
        raise SolverCrashedError(
            f"env {self.env_index}: the coupling worker {describe_returncode(status)} during '{op}'",
            env_index=self.env_index,
            solver="coupling-worker",
            returncode=status,
            log_tail=tail,
            log_file=str(self.worker.log_path),
        )

    def _fail(
        self,
        error: type[SolverError],
        solver: SolverProcess | None,
        what: str,
        op: str,
        evidence: str = "",
    ) -> None:
        name = solver.name if solver else "solver"
        tail = solver.log_tail() if solver else ""
        log = str(solver.log_path) if solver else None
        code = solver.poll() if solver else None
        self.kill()
        extra = {"evidence": evidence} if error is SolverDivergedError else {}
        raise error(
            f"env {self.env_index}: solver {name!r} {what} (during '{op}')",
            **extra,
            env_index=self.env_index,
            solver=name,
            returncode=code,
            log_tail=tail,
            log_file=log,
        )
