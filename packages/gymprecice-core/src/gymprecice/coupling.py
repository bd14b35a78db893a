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

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.errors import (
    CouplingError,
    PreciceNotInstalledError,
    SolverCrashedError,
    SolverError,
    SolverTimeoutError,
)
from gymprecice.processes import PidRegistry, SolverProcess, describe_returncode, read_tail

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
    """The coupling worker child: a socket-pair connection, a pidfd and a log file."""

    def __init__(self, log_path: Path, registry: PidRegistry | None = None) -> None:
        parent, child = socket.socketpair()
        self.log_path = log_path
        with open(log_path, "ab") as log:
            self.popen = subprocess.Popen(
                [sys.executable, "-m", "gymprecice._worker", str(child.fileno())],
                pass_fds=(child.fileno(),),
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                # the worker needs no plugins: skip loading them (a faster reset)
                env={**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"},
            )
        child.close()
        self.conn = Connection(parent.detach())
        self.pid = self.popen.pid
        self._pidfd = os.pidfd_open(self.pid)
        self.registry = registry
        if registry is not None:
            registry.add(self.pid)

    def fileno(self) -> int:
        return self._pidfd

    def poll(self) -> int | None:
        return self.popen.poll()

    def kill(self) -> None:
        if self.popen.poll() is None:
            try:
                os.killpg(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.popen.wait()
        self.close()

    def close(self) -> None:
        if self._pidfd >= 0:
            os.close(self._pidfd)
            self._pidfd = -1
        self.conn.close()
        if self.registry is not None:
            self.registry.remove(self.pid)
            self.registry = None

    def log_size(self) -> int:
        try:
            return self.log_path.stat().st_size
        except OSError:
            return 0

    def log_tail(self, lines: int = 30) -> str:
        return read_tail(self.log_path, lines)


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
    ) -> None:
        self.worker = worker
        self.solvers = list(solvers)
        self.env_index = env_index
        self.progress_timeout = progress_timeout
        self.kill_grace = kill_grace
        self.health_check = health_check
        self.closed = False

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
        """Kill the worker and every solver group. Idempotent."""
        if self.closed:
            return
        self.closed = True
        self.worker.kill()
        for solver in self.solvers:
            solver.terminate(self.kill_grace)

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
                return self._unpack(reply, op)
            if self.worker in ready:
                self._fail_worker_gone(op)
            now = time.monotonic()
            for solver in [s for s in self.solvers if s in ready]:
                watched.remove(solver)
                if solver.poll() not in (0, None):
                    self._fail(SolverCrashedError, solver, describe_returncode(solver.poll()), op)
                exited_at = exited_at or now
            if exited_at is not None and now - exited_at > EXIT_GRACE_S:
                done = next(s for s in self.solvers if s.poll() is not None)
                self._fail(
                    SolverCrashedError,
                    done,
                    "exited (status 0) while the controller was still waiting for it",
                    op,
                )
            sizes = self._log_sizes()
            if sizes != log_sizes:
                log_sizes = sizes
                last_progress = now
            if checking_health and self.health_check is not None:
                for solver in self.solvers:
                    problem = self.health_check(solver)
                    if problem:
                        self._fail(SolverCrashedError, solver, problem, op)
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
        self, error: type[SolverError], solver: SolverProcess | None, what: str, op: str
    ) -> None:
        name = solver.name if solver else "solver"
        tail = solver.log_tail() if solver else ""
        log = str(solver.log_path) if solver else None
        code = solver.poll() if solver else None
        self.kill()
        raise error(
            f"env {self.env_index}: solver {name!r} {what} (during '{op}')",
            env_index=self.env_index,
            solver=name,
            returncode=code,
            log_tail=tail,
            log_file=log,
        )
