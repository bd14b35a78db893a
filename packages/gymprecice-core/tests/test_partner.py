"""The scripted partner participant and its flows: fault flags, outputs, physics contracts."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.testing import case_config, partner_command
from gymprecice.testing.flows import (
    CylinderFlow,
    FlapFluid,
    FlapSolid,
    JetController,
    fake_cylinder_geometry,
    mesh_vertices,
)
from gymprecice.testing.partner import command, load_flow

pytestmark = pytest.mark.timeout(60)

JETS = "gymprecice.testing.flows:JetController"


class Run:
    """Partner processes started by one test; whatever still runs is killed at teardown."""

    def __init__(self, cwd: Path) -> None:
        self.cwd = cwd
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(self, argv: list[str], name: str) -> subprocess.Popen[bytes]:
        env = {**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"}
        with (
            (self.cwd / f"{name}.out").open("wb") as out,
            (self.cwd / f"{name}.err").open("wb") as err,
        ):
            proc = subprocess.Popen(
                argv, cwd=self.cwd, stdout=out, stderr=err, env=env, start_new_session=True
            )
        self.procs.append(proc)
        return proc

    def out(self, name: str) -> str:
        return (self.cwd / f"{name}.out").read_text()

    def err(self, name: str) -> str:
        return (self.cwd / f"{name}.err").read_text()

    def windows(self, name: str) -> list[str]:
        return [ln for ln in self.out(name).splitlines() if "] window " in ln]

    def pair(
        self, config: Path, fluid_flags: dict[str, object] | None = None, **ctrl_flags: object
    ) -> tuple[subprocess.Popen[bytes], subprocess.Popen[bytes]]:
        ctrl = self.start(
            partner_command(config, "Controller", flow=JETS, **ctrl_flags), "controller"
        )
        fluid = self.start(partner_command(config, "Fluid", **(fluid_flags or {})), "fluid")
        return ctrl, fluid

    def stop(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(10)


@pytest.fixture
def run(tmp_path: Path) -> Iterator[Run]:
    r = Run(tmp_path)
    yield r
    r.stop()


def test_two_partners_run_to_the_end_with_outputs(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, max_time=0.05)
    ctrl, fluid = run.pair(cfg, {"write_outputs": "out"})
    assert ctrl.wait(30) == 0, run.err("controller")
    assert fluid.wait(30) == 0, run.err("fluid")
    lines = run.windows("fluid")
    assert [ln.split()[2] for ln in lines] == ["1", "2", "3", "4", "5"]
    assert "finished after 5 windows" in run.out("fluid")
    # The coefficient file has OpenFOAM's layout: comment header, then Time Cd Cs Cl ...
    coeffs = (tmp_path / "out/postProcessing/forceCoeffs/0/coefficient.dat").read_text()
    header = [ln for ln in coeffs.splitlines() if ln.startswith("#")]
    rows = [ln.split() for ln in coeffs.splitlines() if not ln.startswith("#")]
    assert header[-1].split()[1:4] == ["Time", "Cd", "Cs"]
    assert [float(r[0]) for r in rows] == pytest.approx([0.01, 0.02, 0.03, 0.04, 0.05])
    logged_cd = [float(ln.split("Cd=")[1].split()[0]) for ln in lines]
    assert [float(r[1]) for r in rows] == pytest.approx(logged_cd, rel=1e-5)
    assert all(len(r) == 13 for r in rows)
    probes = (tmp_path / "out/postProcessing/probes/0/p").read_text().splitlines()
    assert sum(ln.startswith("# Probe ") for ln in probes) == 151
    data = [ln.split() for ln in probes if not ln.startswith("#")]
    assert len(data) == 5 and all(len(r) == 152 for r in data)


def test_subcycling_flag_takes_smaller_steps(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, max_time=0.03)
    ctrl, fluid = run.pair(cfg, {"dt": 0.004})
    assert fluid.wait(30) == 0, run.err("fluid")
    assert ctrl.wait(30) == 0, run.err("controller")
    steps = [int(ln.split("steps=")[1].split()[0]) for ln in run.windows("fluid")]
    assert steps == [3, 6, 9]  # 0.004 + 0.004 + 0.002 per window


def test_implicit_case_iterates(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, variant="implicit", max_time=0.03)
    ctrl, fluid = run.pair(cfg)
    assert ctrl.wait(30) == 0, run.err("controller")
    assert fluid.wait(30) == 0, run.err("fluid")
    steps = [int(ln.split("steps=")[1].split()[0]) for ln in run.windows("controller")]
    assert len(steps) == 3 and steps[-1] >= 6  # at least two iterations per window


def test_crash_before_initialize_with_exit_code(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path)
    proc = run.start(partner_command(cfg, "Fluid", crash_at_window=0, exit_code=3), "fluid")
    assert proc.wait(30) == 3
    assert "FOAM FATAL ERROR" in run.err("fluid")
    assert "window 0" in run.err("fluid")
    assert not (tmp_path / "precice-run").exists()  # it never reached initialize()


def test_crash_mid_run_by_sigkill(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, max_time=1.0)
    ctrl, fluid = run.pair(cfg, {"crash_at_window": 2})
    assert fluid.wait(30) == -signal.SIGKILL
    assert len(run.windows("fluid")) == 2
    assert run.err("fluid") == ""  # a killed process says nothing
    assert ctrl.poll() is None  # and its partner waits (see test_fake_precice for more)


def test_hang_keeps_the_process_alive_and_silent(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, max_time=1.0)
    ctrl, fluid = run.pair(cfg, {"hang_at_window": 2})
    deadline = time.monotonic() + 30
    while "hanging at window 2" not in run.out("fluid") and time.monotonic() < deadline:
        time.sleep(0.05)
    # the controller may still finish what it was writing (a busy machine delays it): wait
    # until neither has written for half a second, then neither may write for a second more
    size, quiet_since = None, time.monotonic()
    while time.monotonic() - quiet_since < 0.5 and time.monotonic() < deadline:
        now = len(run.out("fluid")), len(run.out("controller"))
        if now != size:
            size, quiet_since = now, time.monotonic()
        time.sleep(0.05)
    time.sleep(1.0)
    assert fluid.poll() is None and ctrl.poll() is None
    assert (len(run.out("fluid")), len(run.out("controller"))) == size
    assert len(run.windows("fluid")) == 2


def test_exit_code_alone_fails_after_a_complete_run(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, max_time=0.02)
    ctrl, fluid = run.pair(cfg, {"exit_code": 2})
    assert fluid.wait(30) == 2
    assert ctrl.wait(30) == 0
    assert "finished after 2 windows" in run.out("fluid")
    assert "injected error" in run.err("fluid")


def test_step_sleep_slows_every_step(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path, max_time=0.04)
    start = time.monotonic()
    ctrl, fluid = run.pair(cfg, {"step_sleep": 0.15})
    assert fluid.wait(30) == 0
    assert ctrl.wait(30) == 0
    assert time.monotonic() - start >= 4 * 0.15


def test_unknown_participant_or_flow_fail_clearly(tmp_path: Path, run: Run) -> None:
    cfg = case_config("fake_cylinder", tmp_path)
    bad = run.start(partner_command(cfg, "Nobody"), "nobody")
    assert bad.wait(30) != 0
    assert "no participant named 'Nobody'" in run.err("nobody")
    with pytest.raises(SystemExit, match="module:ClassName"):
        load_flow("gymprecice.testing.flows")
    with pytest.raises(SystemExit, match="has no class"):
        load_flow("gymprecice.testing.flows:Nope")
    assert load_flow(JETS) is JetController


def test_command_spells_flags_and_options() -> None:
    argv = command(
        "c.xml", "Fluid", flow=JETS, library="precice", options={"amplitude": 2},
        python="py", write_outputs="out", dt=0.5, hang_at_window=None,
    )  # fmt: skip
    assert argv == [
        "py", "-m", "gymprecice.testing.partner", "--config", "c.xml", "--participant",
        "Fluid", "--flow", JETS, "--library", "precice", "--option", "amplitude=2",
        "--write-outputs", "out", "--dt", "0.5",
    ]  # fmt: skip


# --------------------------------------------------------------------------- flows


@pytest.fixture
def cylinder_cfg(tmp_path: Path):
    return load_precice_config(case_config("fake_cylinder", tmp_path))


def _jet_inputs(flow: CylinderFlow, rate: float) -> dict[tuple[str, str], np.ndarray]:
    inputs = {}
    for jet, sign in (("jet1", 1.0), ("jet2", -1.0)):
        mesh = f"Fluid-Mesh-{jet}"
        coords = flow.mesh_coordinates(mesh)
        normals = coords / np.linalg.norm(coords, axis=1, keepdims=True)
        inputs[("Velocity", mesh)] = sign * rate * normals
    return inputs


def test_cylinder_jets_quiet_the_wake_and_lower_the_drag(cylinder_cfg) -> None:
    free, forced = CylinderFlow(cylinder_cfg, "Fluid"), CylinderFlow(cylinder_cfg, "Fluid")
    free_in, forced_in = _jet_inputs(free, 0.0), _jet_inputs(forced, 2.0)
    for k in range(300):
        free.step(k * 0.01, 0.01, free_in)
        forced.step(k * 0.01, 0.01, forced_in)
    assert forced.state["r"] < 1e-3 < free.state["r"]
    assert free.drag == pytest.approx(3.0 + 0.2, rel=1e-3)  # saturated shedding
    assert forced.drag < free.drag
    assert forced.summary()["q"] == pytest.approx(2.0)
    surface = free.mesh_coordinates("Fluid-Mesh-cylinder")
    assert free.output("Pressure", "Fluid-Mesh-cylinder").shape == (len(surface),)


def test_cylinder_flow_is_deterministic_and_checkpointable(cylinder_cfg) -> None:
    a, b = CylinderFlow(cylinder_cfg, "Fluid"), CylinderFlow(cylinder_cfg, "Fluid")
    inputs = _jet_inputs(a, 0.7)
    _jet_inputs(b, 0.7)
    saved = a.checkpoint()
    for k in range(10):
        a.step(k * 0.01, 0.01, inputs)
        b.step(k * 0.01, 0.01, inputs)
    assert a.state == b.state
    a.restore(saved)
    assert a.state["r"] == 1.0 and a.state["phase"] == 0.0


def test_jet_controller_writes_a_synthetic_jet(cylinder_cfg) -> None:
    flow = JetController(cylinder_cfg, "Controller", {"frequency": 0, "amplitude": 3})
    geometry = fake_cylinder_geometry()
    for jet in geometry:
        coords = flow.mesh_coordinates(f"Controller-Mesh-{jet}")
        assert np.allclose(coords, geometry[jet].coordinates)
    flow.step(0.0, 0.01, {})
    v1 = flow.output("Velocity", "Controller-Mesh-jet1")
    v2 = flow.output("Velocity", "Controller-Mesh-jet2")
    n1 = geometry["jet1"].normals[:, :2]
    n2 = geometry["jet2"].normals[:, :2]
    assert np.allclose(np.sum(v1 * n1, axis=1), 3.0)  # blowing out of jet 1
    assert np.allclose(np.sum(v2 * n2, axis=1), -3.0)  # sucking into jet 2


def test_flap_flows_form_a_contraction(tmp_path: Path) -> None:
    cfg = load_precice_config(case_config("fake_flap", tmp_path))
    fluid, solid = FlapFluid(cfg, "Fluid"), FlapSolid(cfg, "Solid")
    fluid.mesh_coordinates("Fluid-Mesh-Flap")
    solid.mesh_coordinates("Solid-Mesh")
    d = np.zeros((6, 2))
    history = []
    for _ in range(40):
        fluid.step(
            0.0, 0.01, {("Displacement", "Fluid-Mesh-Flap"): np.full((11, 2), d[:, 0].mean())}
        )
        force = fluid.output("Force", "Fluid-Mesh-Flap")
        solid.step(0.0, 0.01, {("Force", "Solid-Mesh"): force})
        d = solid.output("Displacement", "Solid-Mesh")
        history.append(solid.state["d"])
    assert history[-1] == pytest.approx(2 / 3, rel=1e-9)
    assert abs(history[1] - history[0]) > abs(history[2] - history[1])
    assert d[-1, 0] == pytest.approx(2 * 2 / 3)  # the tip moves twice the mean


def test_mesh_vertices_by_name() -> None:
    assert mesh_vertices("Fluid-Mesh-jet1", 2).shape == (8, 2)
    assert mesh_vertices("Fluid-Mesh-cylinder", 2).shape == (32, 2)
    assert mesh_vertices("Solid-Mesh", 3).shape == (6, 3)
    assert mesh_vertices("Anything", 2).shape == (8, 2)
    assert np.allclose(np.linalg.norm(mesh_vertices("Controller-Mesh-jet2", 2), axis=1), 0.05)
