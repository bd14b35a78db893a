"""The coupling scenarios gymprecice relies on, run against real preCICE (and the double).

Every scenario runs once with real pyprecice (marked ``precice``; skipped, with the import
error as reason, where ``import precice`` fails) and once with
``gymprecice.testing.fake_precice``. Passing both ways is what "the double is faithful"
means; a scenario that passes only with the double is a bug in the double.

Each participant is a separate process (``python -m gymprecice.testing.partner --library
...``, or a short script): real preCICE allows one participant per process.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from gymprecice.testing import case_config, partner_command

pytestmark = pytest.mark.timeout(120)

REAL = "precice"
FAKE = "gymprecice.testing.fake_precice"
JETS = "gymprecice.testing.flows:JetController"

_import_errors: dict[str, str | None] = {}


def _import_error(library: str) -> str | None:
    """Why ``import <library>`` fails in a fresh interpreter (``None`` when it works).

    Checked in a child process: importing real pyprecice initializes MPI, which the test
    process (which forks partners) is better off without.
    """
    if library not in _import_errors:
        proc = subprocess.run(
            [sys.executable, "-c", f"import {library}"], capture_output=True, text=True
        )
        tail = proc.stderr.strip().splitlines()
        _import_errors[library] = None if proc.returncode == 0 else (tail[-1] if tail else "?")
    return _import_errors[library]


@pytest.fixture(
    params=[pytest.param(REAL, marks=pytest.mark.precice, id="real"), pytest.param(FAKE, id="fake")]
)
def library(request: pytest.FixtureRequest) -> str:
    error = _import_error(request.param)
    if error is not None:
        pytest.skip(f"cannot import {request.param!r} (pyprecice and preCICE): {error}")
    return request.param


class Procs:
    """Participant processes of one test, by name; whatever still runs is killed at the end."""

    def __init__(self, cwd: Path, library: str) -> None:
        self.cwd = cwd
        self.library = library
        self.procs: dict[str, subprocess.Popen[bytes]] = {}

    def start(self, argv: list[str], name: str) -> subprocess.Popen[bytes]:
        # the double waits forever for a partner that is gone, as preCICE does
        env = {
            **os.environ,
            "GYMPRECICE_DISABLE_PLUGINS": "1",
            "GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS": "hang",
        }
        with (
            (self.cwd / f"{name}.out").open("wb") as out,
            (self.cwd / f"{name}.err").open("wb") as err,
        ):
            proc = subprocess.Popen(
                argv, cwd=self.cwd, stdout=out, stderr=err, env=env, start_new_session=True
            )
        self.procs[name] = proc
        return proc

    def partner(self, config: Path, participant: str, **kwargs: Any) -> subprocess.Popen[bytes]:
        argv = partner_command(config, participant, library=self.library, **kwargs)
        return self.start(argv, participant.lower())

    def out(self, name: str) -> str:
        return (self.cwd / f"{name}.out").read_text()

    def err(self, name: str) -> str:
        return (self.cwd / f"{name}.err").read_text()

    def windows(self, name: str) -> list[dict[str, str]]:
        """The partner's per-window lines, as ``{"window": "3", "t": ..., "Cd": ...}``."""
        rows = []
        for line in self.out(name).splitlines():
            if "] window " not in line:
                continue
            words = line.split("] window ", 1)[1].split()
            row = {"window": words[0]}
            row.update(w.split("=", 1) for w in words[1:] if "=" in w)
            rows.append(row)
        return rows

    def wait_all(self, timeout: float = 60.0) -> None:
        for name, proc in self.procs.items():
            rc = proc.wait(timeout)
            assert rc == 0, f"{name} exited with {rc}:\n{self.err(name)}\n{self.out(name)}"

    def stop(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(10)


@pytest.fixture
def procs(tmp_path: Path, library: str) -> Iterator[Procs]:
    p = Procs(tmp_path, library)
    yield p
    p.stop()


def pair_config(tmp_path: Path, kind: str = "parallel-explicit", initialize: bool = False) -> Path:
    """A writes "Up", B answers "Down" (mapped back conservatively).

    The partner flows place "A-Inlet" on 5 inlet points (x = -3) and "B-Line" on 8 points
    of the segment y = 0, 0 <= x <= 1: every B vertex is nearest to A's vertex (-3, 0).
    """
    init = ' initialize="true"' if initialize else ""
    xml = f"""<?xml version="1.0"?>
<precice-configuration>
  <log><sink filter="%Severity% > info" enabled="true" /></log>
  <data:scalar name="Up" />
  <data:scalar name="Down" />
  <mesh name="A-Inlet" dimensions="2"><use-data name="Up" /><use-data name="Down" /></mesh>
  <mesh name="B-Line" dimensions="2"><use-data name="Up" /><use-data name="Down" /></mesh>
  <participant name="A">
    <provide-mesh name="A-Inlet" />
    <write-data name="Up" mesh="A-Inlet" />
    <read-data name="Down" mesh="A-Inlet" />
  </participant>
  <participant name="B">
    <provide-mesh name="B-Line" />
    <receive-mesh name="A-Inlet" from="A" />
    <read-data name="Up" mesh="B-Line" />
    <write-data name="Down" mesh="B-Line" />
    <mapping:nearest-neighbor direction="read" from="A-Inlet" to="B-Line" constraint="consistent" />
    <mapping:nearest-neighbor direction="write" from="B-Line" to="A-Inlet"
                              constraint="conservative" />
  </participant>
  <m2n:sockets acceptor="A" connector="B" exchange-directory="" />
  <coupling-scheme:{kind}>
    <participants first="A" second="B" />
    <max-time value="0.04" />
    <time-window-size value="0.01" />
    <exchange data="Up" mesh="A-Inlet" from="A" to="B"{init} />
    <exchange data="Down" mesh="A-Inlet" from="B" to="A" />
  </coupling-scheme:{kind}>
</precice-configuration>
"""
    path = tmp_path / "precice-config.xml"
    path.write_text(xml)
    return path


_MISUSE = textwrap.dedent(
    """
    import importlib, json, sys
    import numpy as np
    precice = importlib.import_module(sys.argv[1])
    p = precice.Participant("A", sys.argv[2], 0, 1)
    ids = p.set_mesh_vertices("A-Inlet", np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))
    when, call = sys.argv[3].split(":")
    if when == "after_finalize":
        p.finalize()
    calls = {
        "advance": lambda: p.advance(0.01),
        "initialize": p.initialize,
        "finalize": p.finalize,
        "read": lambda: p.read_data("A-Inlet", "Down", ids, 0.0),
        "write": lambda: p.write_data("A-Inlet", "Up", ids, np.ones(3)),
        "write_read_only": lambda: p.write_data("A-Inlet", "Down", ids, np.ones(3)),
        "invalid_vertex": lambda: p.write_data("A-Inlet", "Up", [0, 9, 1], np.ones(3)),
        "wrong_dimensions": lambda: p.set_mesh_vertices("A-Inlet", np.zeros((2, 3))),
        "unknown_mesh": lambda: p.get_mesh_dimensions("Nowhere"),
        "unknown_data": lambda: p.get_data_dimensions("A-Inlet", "Nothing"),
        "mesh_dimensions": lambda: p.get_mesh_dimensions("A-Inlet"),
        "ongoing": p.is_coupling_ongoing,
        "max_dt": p.get_max_time_step_size,
        "writing_checkpoint": p.requires_writing_checkpoint,
        "initial_data": p.requires_initial_data,
    }
    try:
        calls[call]()
        out = ["ok", ""]
    except Exception as exc:  # preCICE errors are RuntimeErrors (or subclasses)
        kind = "RuntimeError" if isinstance(exc, RuntimeError) else type(exc).__name__
        out = [kind, str(exc)]
    print("RESULT " + json.dumps(out), flush=True)
    """
)

_IS_ABORT = "initialize() has to be called before "
#: What preCICE 3.4.1 does with each misuse (run with a config that wants initial data).
MISUSE_OUTCOMES = {
    "before_initialize:advance": ("segfault", ""),
    "before_initialize:read": ("RuntimeError", "readData(...) cannot be called before initialize"),
    "before_initialize:ongoing": ("abort", _IS_ABORT + "isCouplingOngoing() can be evaluated."),
    "before_initialize:max_dt": ("abort", _IS_ABORT + "getMaxTimeStepSize() can be evaluated."),
    "before_initialize:writing_checkpoint": ("abort", _IS_ABORT + "requiresWritingCheckpoint()."),
    "before_initialize:initialize": (
        "RuntimeError", "Initial data has to be written to preCICE before calling initialize()"
    ),
    "before_initialize:write_read_only": (
        "RuntimeError", 'This participant does not use data "Down" via mesh "A-Inlet"'
    ),
    "before_initialize:invalid_vertex": ("RuntimeError", "invalid Vertex ID at vertices[1]"),
    "before_initialize:wrong_dimensions": ("AssertionError", "Provided dimensions: 3"),
    "before_initialize:unknown_mesh": (
        "RuntimeError", 'The mesh named "Nowhere" is unknown to preCICE. This participant only '
        'knows mesh "A-Inlet".'
    ),
    "before_initialize:unknown_data": (
        "RuntimeError", 'The given data "Nothing" is unknown to preCICE mesh "A-Inlet". '
        "Available data are: Up, Down"
    ),
    "after_finalize:initialize": ("RuntimeError", "initialize() cannot be called after finalize()."),
    "after_finalize:finalize": ("abort", "finalize() may only be called once."),
    "after_finalize:ongoing": ("abort", "isCouplingOngoing() cannot be called after finalize()."),
    "after_finalize:initial_data": (
        "abort", "requiresInitialData() has to be called before initialize()."
    ),
    "after_finalize:advance": ("segfault", ""),
    "after_finalize:write": ("segfault", ""),
    "after_finalize:read": ("segfault", ""),
    "after_finalize:mesh_dimensions": ("segfault", ""),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(MISUSE_OUTCOMES))
def test_misuse_outcomes(tmp_path: Path, library: str, case: str) -> None:
    """Raise, abort or segfault: each misuse ends like it does with preCICE 3.4.1.

    The double runs with ``GYMPRECICE_FAKE_PRECICE_MISUSE=crash`` here; by default it raises
    ``PreciceError`` where preCICE aborts or crashes.

    Cost: about 1 s per case and library (one or two short-lived participants).
    """
    cfg = pair_config(tmp_path, initialize=True)
    env = {
        **os.environ,
        "GYMPRECICE_DISABLE_PLUGINS": "1",
        "GYMPRECICE_FAKE_PRECICE_MISUSE": "crash",
        "PYTHONFAULTHANDLER": "",
    }
    proc = subprocess.run(
        [sys.executable, "-c", _MISUSE, library, str(cfg), case],
        cwd=tmp_path, capture_output=True, text=True, timeout=60, env=env,
    )  # fmt: skip
    if proc.returncode == -signal.SIGSEGV:
        outcome = ("segfault", "")
    elif proc.returncode == -signal.SIGABRT:
        what = [ln for ln in proc.stderr.splitlines() if "what():" in ln]
        outcome = ("abort", what[0].split("what():", 1)[1].strip() if what else "")
    else:
        assert proc.returncode == 0, proc.stderr
        line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT "))
        outcome = tuple(json.loads(line[len("RESULT ") :]))
    kind, message = MISUSE_OUTCOMES[case]
    assert outcome[0] == kind, (outcome, proc.stderr[-500:])
    assert message in outcome[1]


_AFTER_INITIALIZE = textwrap.dedent(
    """
    import importlib, json, sys
    import numpy as np
    precice = importlib.import_module(sys.argv[1])
    p = precice.Participant("A", sys.argv[2], 0, 1)
    ids = p.set_mesh_vertices("A-Inlet", np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))
    p.initialize()
    checks = {
        "set_vertices": lambda: p.set_mesh_vertices("A-Inlet", np.zeros((1, 2))),
        "initialize_twice": p.initialize,
        "dt_zero": lambda: p.advance(0.0),
        "dt_negative": lambda: p.advance(-0.01),
        "dt_infinite": lambda: p.advance(float("inf")),
        "read_beyond_window": lambda: p.read_data("A-Inlet", "Down", ids, 0.02),
        "read_before_now": lambda: p.read_data("A-Inlet", "Down", ids, -0.001),
        "dt_too_large": lambda: p.advance(0.015),
        "ids_of_provided_mesh": lambda: p.get_mesh_vertex_ids_and_coordinates("A-Inlet"),
    }
    out = {"max_dt": p.get_max_time_step_size(), "ongoing": p.is_coupling_ongoing(),
           "complete": p.is_time_window_complete(),
           "checkpoint": p.requires_writing_checkpoint()}
    for name, call in checks.items():
        try:
            call()
            out[name] = None
        except Exception as exc:  # preCICE errors are RuntimeErrors (or subclasses)
            kind = "RuntimeError" if isinstance(exc, RuntimeError) else type(exc).__name__
            out[name] = [kind, str(exc)]
    print("RESULT " + json.dumps(out), flush=True)
    """
)


def test_misuse_after_initialize_raises(tmp_path: Path, procs: Procs) -> None:
    """Cost: about 1 s per library (two participants, one window)."""
    cfg = pair_config(tmp_path)
    procs.partner(cfg, "B", flow="gymprecice.testing.flows:NullFlow")
    env = {**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"}
    proc = subprocess.run(
        [sys.executable, "-c", _AFTER_INITIALIZE, procs.library, str(cfg)],
        cwd=tmp_path, capture_output=True, text=True, timeout=60, env=env,
    )  # fmt: skip
    line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT "))
    out = json.loads(line[len("RESULT ") :])
    assert (out.pop("max_dt"), out.pop("ongoing"), out.pop("complete")) == (0.01, True, False)
    assert out.pop("checkpoint") is False
    messages = {
        "set_vertices": 'attempted to modify the Mesh "A-Inlet" while locked',
        "initialize_twice": "initialize() may only be called once.",
        "dt_zero": "advance() cannot be called with a time step size of 0.",
        "dt_negative": "advance() cannot be called with a negative time step size -0.01.",
        "dt_infinite": "advance() cannot be called with an infinite time step size.",
        "read_beyond_window": "readData(...) cannot sample data outside of current time window.",
        "read_before_now": "readData(...) cannot sample data before the current time.",
        "dt_too_large": 'The time step size given to preCICE in "advance" 0.015 exceeds the '
        "maximum allowed time step size 0.01 in the remaining of this time window.",
        "ids_of_provided_mesh": 'via "getMeshVertexIDsAndCoordinates") from mesh "A-Inlet", but '
        'mesh "A-Inlet" is either not a received mesh',
    }
    for name, message in messages.items():
        kind, text = out[name]
        assert kind == "RuntimeError", (name, kind, text)
        assert message in text, (name, text)


@pytest.mark.parametrize(
    ("kind", "b_reads", "a_reads"),
    [
        # parallel: each side reads what the other wrote one window earlier (zero first).
        ("parallel-explicit", [0.0, 3.0, 3.0, 3.0], [0.0, 8.0, 8.0, 8.0]),
        # serial: the second participant already reads the first's current window.
        ("serial-explicit", [3.0, 3.0, 3.0, 3.0], [0.0, 8.0, 8.0, 8.0]),
    ],
)
def test_explicit_data_flow_and_mappings(
    tmp_path: Path, procs: Procs, kind: str, b_reads: list[float], a_reads: list[float]
) -> None:
    """Cost: about 1 s per scheme and library (two participants, a few windows)."""
    cfg = pair_config(tmp_path, kind=kind)
    const = {"frequency": 0}
    procs.partner(cfg, "A", flow=JETS, options={**const, "amplitude": 3})
    procs.partner(cfg, "B", flow=JETS, options={**const, "amplitude": 5})
    procs.wait_all()
    b = [float(r["Up@B-Line"]) for r in procs.windows("b")]
    a = [float(r["Down@A-Inlet"]) for r in procs.windows("a")]
    # B writes 5 on each of its 8 vertices; conservatively they all land on A's vertex
    # (-3, 0): A reads [40, 0, 0, 0, 0], whose mean the partner logs.
    assert b == pytest.approx(b_reads)
    assert a == pytest.approx(a_reads)


def test_initial_data_is_read_in_the_first_window(tmp_path: Path, procs: Procs) -> None:
    """Cost: about 1 s per library (two participants, a few windows)."""
    cfg = pair_config(tmp_path, initialize=True)
    procs.partner(cfg, "A", flow=JETS, options={"frequency": 0, "amplitude": 3})
    procs.partner(cfg, "B", flow=JETS, options={"frequency": 0, "amplitude": 5})
    procs.wait_all()
    assert [float(r["Up@B-Line"]) for r in procs.windows("b")] == pytest.approx([3.0] * 4)


def test_explicit_cylinder_with_subcycling(tmp_path: Path, procs: Procs) -> None:
    """Cost: about 2 s per library (two participants, 0.03 s simulated)."""
    cfg = case_config("fake_cylinder", tmp_path, max_time=0.03)
    procs.partner(cfg, "Controller", flow=JETS)
    procs.partner(cfg, "Fluid", dt=0.004)
    procs.wait_all()
    fluid = procs.windows("fluid")
    assert [int(r["steps"]) for r in fluid] == [3, 6, 9]
    assert [float(r["t"]) for r in fluid] == pytest.approx([0.01, 0.02, 0.03])
    ctrl = procs.windows("controller")
    assert len(ctrl) == 3
    # The controller reads the pressure the fluid wrote: zero before the first exchange.
    pressure = [float(r["Pressure@Fluid-Mesh-cylinder"]) for r in ctrl]
    assert pressure[0] == 0.0 and pressure[1] != 0.0


def test_implicit_cylinder_iterates(tmp_path: Path, procs: Procs) -> None:
    """Cost: about 2 s per library (two participants, 0.03 s simulated, implicit)."""
    cfg = case_config("fake_cylinder", tmp_path, variant="implicit", max_time=0.03)
    procs.partner(cfg, "Controller", flow=JETS)
    procs.partner(cfg, "Fluid")
    procs.wait_all()
    for name in ("controller", "fluid"):
        steps = [int(r["steps"]) for r in procs.windows(name)]
        assert len(steps) == 3 and steps[-1] >= 6, (name, steps)
    assert (tmp_path / "precice-Controller-iterations.log").is_file()


@pytest.mark.parametrize("variant", [None, "compositional"])
def test_fsi_three_participants(tmp_path: Path, procs: Procs, variant: str | None) -> None:
    """Cost: about 2 s per variant and library (three participants, 0.03 s simulated)."""
    cfg = case_config("fake_flap", tmp_path, variant=variant, max_time=0.03)
    procs.partner(cfg, "Controller", flow=JETS, options={"frequency": 0, "amplitude": 0.5})
    procs.partner(cfg, "Fluid", flow="gymprecice.testing.flows:FlapFluid")
    procs.partner(cfg, "Solid", flow="gymprecice.testing.flows:FlapSolid")
    procs.wait_all()
    fluid, solid = procs.windows("fluid"), procs.windows("solid")
    assert len(fluid) == len(solid) == len(procs.windows("controller")) == 3
    assert float(fluid[-1]["F"]) == pytest.approx(float(solid[-1]["F"]), rel=1e-3)
    assert int(solid[-1]["steps"]) > 3
    tip = (tmp_path / "precice-Solid-watchpoint-Flap-Tip.log").read_text().split()
    assert tip[:3] == ["Time", "Coordinate0", "Coordinate1"]


def test_survivor_blocks_when_the_partner_is_killed(tmp_path: Path, procs: Procs) -> None:
    """Cost: about 2 s per library (two participants; one is killed, the other is watched
    blocking).
    """
    cfg = case_config("fake_cylinder", tmp_path, max_time=10.0)
    ctrl = procs.partner(cfg, "Controller", flow=JETS)
    fluid = procs.partner(cfg, "Fluid", crash_at_window=2)
    assert fluid.wait(60) == -signal.SIGKILL
    time.sleep(0.5)
    before = procs.out("controller")
    time.sleep(1.5)
    assert ctrl.poll() is None, procs.err("controller")
    assert procs.out("controller") == before
    assert len(procs.windows("controller")) in (2, 3)
