"""The coupling worker: the one process that owns the preCICE participant.

pyprecice holds the GIL while a preCICE call blocks, and ``advance`` blocks forever when
the other participant dies instead of raising. Nothing inside the blocked process can
interrupt it, so the participant lives here, in a child of the env process, and the env
watches it from outside and kills it when a solver crashes or hangs.

Started as ``python -m gymprecice._worker FD PARENT_PID``: FD is one end of a socket pair on which
the env sends requests and this process answers, one reply per request:

``("init", {...})``      create the participant, set vertices, initial data, initialize
``("advance", {...})``   write + advance for a list of windows (implicit: checkpoints), read
``("finalize", {})``     finalize the participant
Replies are ``("ok", payload)`` or ``("error", kind, message)``.
"""

from __future__ import annotations

import ctypes
import importlib
import os
import signal
import sys
import time
import traceback
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

DataKey = tuple[str, str]  # (mesh, data)


def _die_with_parent(parent: int | None) -> None:
    """Ask Linux to SIGKILL us when the env process dies, so no worker outlives its env.

    ``PR_SET_PDEATHSIG`` fires when the *thread* that forked us exits; the env forks the
    worker from a thread that lasts as long as its process. An env that died before the
    request took effect is seen here: our parent is then no longer ``parent``.
    """
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass
    if parent is not None and os.getppid() != parent:
        os._exit(1)


class _Session:
    def __init__(self, request: dict[str, Any]) -> None:
        os.chdir(request["cwd"])
        library = request["library"]
        try:
            precice = importlib.import_module(library)
        except ImportError as exc:
            raise _Reply(
                "missing-precice",
                f"cannot import the preCICE Python bindings module {library!r} ({exc}). "
                "Install the preCICE v3 C++ library, then `pip install gymprecice-core[precice]` "
                "(pyprecice); or run against the test double with "
                "precice.library = 'gymprecice.testing.fake_precice'.",
            ) from None
        _say(f"using {library}; creating participant {request['participant']!r}")
        self.participant = precice.Participant(request["participant"], request["config_file"], 0, 1)
        self.vertex_ids: dict[str, np.ndarray] = {}
        for mesh, coords in request["meshes"].items():
            self.vertex_ids[mesh] = self.participant.set_mesh_vertices(mesh, coords)
        direct: dict[str, Any] = request.get("direct", {})
        for mesh, region in direct.items():
            self.participant.set_mesh_access_region(mesh, np.asarray(region, dtype=float))
        self.read_keys: list[DataKey] = [tuple(k) for k in request["read"]]
        self.precice_s = 0.0
        t0 = time.perf_counter()
        if self.participant.requires_initial_data():
            self._write(request["initial_data"])
        _say("initializing (waits for the other participants to connect)")
        self.participant.initialize()
        _say("initialized")
        self.coordinates: dict[str, np.ndarray] = {}
        for mesh in direct:
            ids, coords = self.participant.get_mesh_vertex_ids_and_coordinates(mesh)
            self.vertex_ids[mesh] = ids
            self.coordinates[mesh] = coords
        self.precice_s += time.perf_counter() - t0
        self.time = 0.0
        self.windows = 0

    def _write(self, values: dict[DataKey, np.ndarray]) -> None:
        for (mesh, data), array in values.items():
            self.participant.write_data(mesh, data, self.vertex_ids[mesh], array)

    def _read(self) -> dict[DataKey, np.ndarray]:
        # preCICE v3 allows relativeReadTime = 0 after the coupling has ended, so the last
        # step's observation still sees the data of the final window.
        return {
            (mesh, data): self.participant.read_data(mesh, data, self.vertex_ids[mesh], 0.0)
            for mesh, data in self.read_keys
        }

    def state(self, **extra: Any) -> dict[str, Any]:
        ongoing = self.participant.is_coupling_ongoing()
        return {
            "time": self.time,
            "windows": self.windows,
            "ongoing": ongoing,
            "dt": self.participant.get_max_time_step_size() if ongoing else 0.0,
            "read": self._read(),
            "precice_s": self.precice_s,
            **extra,
        }

    def advance(self, writes: list[dict[DataKey, np.ndarray]]) -> dict[str, Any]:
        self.precice_s = 0.0
        participant = self.participant
        done = 0
        t0 = time.perf_counter()
        for values in writes:
            if not participant.is_coupling_ongoing():
                break
            window_start = self.time
            while True:
                if participant.requires_writing_checkpoint():
                    window_start = self.time
                dt = participant.get_max_time_step_size()
                self._write(values)
                participant.advance(dt)
                self.time += dt
                if participant.requires_reading_checkpoint():
                    self.time = window_start  # implicit iteration: redo the window
                    continue
                if participant.is_time_window_complete():
                    break
            self.windows += 1
            done += 1
        self.precice_s = time.perf_counter() - t0
        return self.state(advanced=done)

    def finalize(self) -> None:
        self.participant.finalize()


class _Reply(Exception):
    """A control-flow signal carrying an error reply."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind
        self.message = message


def serve(conn: Connection) -> int:
    session: _Session | None = None
    while True:
        try:
            op, request = conn.recv()
        except (EOFError, OSError):
            return 0
        try:
            if op == "init":
                session = _Session(request)
                reply: Any = ("ok", session.state(coordinates=session.coordinates))
            elif op == "advance":
                assert session is not None, "advance before init"
                reply = ("ok", session.advance(request["writes"]))
            elif op == "finalize":
                if session is not None:
                    session.finalize()
                reply = ("ok", {})
            elif op == "exit":
                conn.send(("ok", {}))
                return 0
            else:
                reply = ("error", "protocol", f"unknown request {op!r}")
        except _Reply as exc:
            reply = ("error", exc.kind, exc.message)
        except Exception as exc:
            reply = ("error", "precice", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}")
        conn.send(reply)


def _say(message: str) -> None:
    """One line in the worker's log: the env counts log growth as progress."""
    print(f"[gymprecice worker {os.getpid()}] {message}", flush=True)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    _die_with_parent(int(argv[1]) if len(argv) > 1 else None)
    _say("started")
    conn = Connection(int(argv[0]))
    return serve(conn)


if __name__ == "__main__":
    sys.exit(main())
