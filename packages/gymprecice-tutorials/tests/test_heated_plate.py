"""HeatedPlate-v0: its case files, its starts, and whole episodes on the test double.

Everything here runs without preCICE, OpenFOAM or FEniCS, in seconds: the double case
couples the controller through gymprecice's preCICE double to the lumped plate of
:mod:`gymprecice_tutorials.heated_plate.double`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.testing.conformance import make_solver_context
from gymprecice_fenics import plugin as fenics_plugin
from gymprecice_lab.common.registered_env import find_lab_env
from gymprecice_tutorials.heated_plate import CASE_DIR
from gymprecice_tutorials.heated_plate.environment import (
    EVAL_STARTS,
    HEATER_RANGE,
    REFERENCE_INFLOW,
    HeatedPlateEnv,
    case_files,
    draw_start,
)


@pytest.fixture
def env(tmp_path: Path):
    made = HeatedPlateEnv(double=True, episode_time=1.0, settle_time=0.2, run_root=tmp_path)
    yield made
    made.close()


def _episode(env: HeatedPlateEnv, heater: float, seed: int = 0) -> list[dict]:
    env.reset(seed=seed, options={"split": "eval"})
    infos = []
    while True:
        _, reward, terminated, truncated, info = env.step(np.array([heater], np.float32))
        infos.append({**info["metrics"], "reward": reward, "truncated": truncated})
        assert not terminated
        if truncated:
            return infos


# -- the case ---------------------------------------------------------------------------------


@pytest.mark.parametrize("solid", ["openfoam", "fenics"])
def test_case_files_keep_one_plate_and_end_the_coupling_at_the_episodes_end(solid: str) -> None:
    files = case_files(solid, 1.7)
    dirs = {rel.split("/", 1)[0] for rel in files if "/" in rel}
    assert dirs == {"fluid-openfoam", f"solid-{solid}"}
    config = json.loads(files["gymprecice-config.json"])
    assert config["physics_simulation_engine"]["solvers"]["solid"]["kind"] == solid
    max_times = re.findall(r'<max-time value="([^"]+)" />', files["precice-config.xml"])
    assert max_times == ["1.7", "1.7", "1.7"]  # fluid-solid, controller-fluid, controller-solid
    with pytest.raises(ValueError, match="solid must be one of"):
        case_files("nutils", 1.0)


def test_the_packaged_fenics_plate_agrees_with_the_precice_configuration(tmp_path: Path) -> None:
    solid = make_solver_context("fenics", CASE_DIR / "solid-fenics", tmp_path, name="solid")
    solid.participant = "Solid"
    solid.precice = load_precice_config(CASE_DIR / "precice-config.xml")
    assert fenics_plugin.gymprecice_validate_case(solid) == []


def test_a_controller_writing_heat_flux_where_the_fenics_plate_reads_temperature(
    tmp_path: Path,
) -> None:
    case = tmp_path / "case"
    case.mkdir()
    xml = CASE_DIR.joinpath("precice-config.xml").read_text()
    # The controller's heater sends Heat-Flux; the script reads Temperature on the heater.
    xml = xml.replace(
        '<mesh name="Controller-Mesh-heater" dimensions="2">\n    <use-data name="Temperature" />',
        '<mesh name="Controller-Mesh-heater" dimensions="2">\n    <use-data name="Heat-Flux" />',
    )
    xml = xml.replace(
        '<write-data name="Temperature" mesh="Controller-Mesh-heater" />',
        '<write-data name="Heat-Flux" mesh="Controller-Mesh-heater" />',
    )
    xml = xml.replace(
        '<exchange data="Temperature" mesh="Controller-Mesh-heater"',
        '<exchange data="Heat-Flux" mesh="Controller-Mesh-heater"',
    )
    (case / "precice-config.xml").write_text(xml)
    solid = make_solver_context("fenics", CASE_DIR / "solid-fenics", tmp_path, name="solid")
    solid.participant = "Solid"
    solid.precice = load_precice_config(case / "precice-config.xml")
    (problem,) = fenics_plugin.gymprecice_validate_case(solid)
    assert "reads 'Temperature' on mesh 'Solid-Mesh-heater'" in problem
    assert "'Heat-Flux' from 'Controller'" in problem
    assert "precice-adapter-config.json" in problem and "precice-config.xml" in problem


def test_heated_plate_is_registered_for_the_commands() -> None:
    info = find_lab_env("HeatedPlate-v0")
    assert info.name == "heated-plate"
    assert info.objective == "tracking_error"
    assert dict(info.baseline_kwargs) == {"uncontrolled": True}


# -- starts -----------------------------------------------------------------------------------


def test_training_never_draws_a_held_out_start() -> None:
    rng = np.random.default_rng(0)
    drawn = {draw_start(rng, 2.0) for _ in range(2000)}
    assert len(drawn) > 100
    for held_out in EVAL_STARTS:
        assert all(
            not np.isclose(held_out.setpoint, d.setpoint)
            and not np.isclose(held_out.step_time, d.step_time)
            and not np.isclose(held_out.velocity, d.velocity)
            for d in drawn
        )


def test_bad_times_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"multiple of 0\.1"):
        HeatedPlateEnv(double=True, episode_time=0.25, run_root=tmp_path)
    with pytest.raises(ValueError, match="must be positive"):
        HeatedPlateEnv(double=True, settle_time=0.0, run_root=tmp_path)


# -- episodes on the double --------------------------------------------------------------------


def test_an_episode_reads_the_plate_writes_the_heater_and_steps_the_inflow(env) -> None:
    obs, info = env.reset(seed=2, options={"split": "eval"})
    start = EVAL_STARTS[2]
    assert info["start"]["setpoint"] == start.setpoint and env.time == pytest.approx(0.2)
    assert obs.shape == (5,) and env.observation_space.contains(obs)  # with the integral
    assert obs[3] == pytest.approx(REFERENCE_INFLOW)
    velocities, times = [], []
    while True:
        obs, reward, terminated, truncated, info = env.step(np.array([320.0], np.float32))
        velocities.append(float(obs[3]))
        times.append(env.time)
        metrics = info["metrics"]
        assert obs[0] == pytest.approx(metrics["interface_temperature"] - start.setpoint)
        assert reward == pytest.approx(
            -(metrics["tracking_error"] + env.actuation_cost * abs(320.0 - 310.0))
        )
        if truncated:
            break
    assert not terminated and env.time == pytest.approx(1.2)
    # The inflow changes at the start's step time (after settling), not before; the
    # observation gives the velocity that holds from the step's end on.
    changed = [t for t, u in zip(times, velocities) if np.isclose(u, start.velocity)]
    assert changed and min(changed) == pytest.approx(0.2 + start.step_time)
    assert all(np.isclose(u, REFERENCE_INFLOW) for t, u in zip(times, velocities) if t < 0.85)


def test_a_hotter_heater_heats_the_interface_and_actions_are_clipped(env) -> None:
    cool = _episode(env, 305.0)
    hot = _episode(env, 330.0)
    assert hot[-1]["interface_temperature"] > cool[-1]["interface_temperature"] + 5.0
    clipped = _episode(env, 1000.0)
    assert {i["heater_temperature"] for i in clipped} == {HEATER_RANGE[1]}


def test_uncontrolled_holds_the_tutorials_heater_whatever_the_action(tmp_path: Path) -> None:
    env = HeatedPlateEnv(double=True, episode_time=0.5, uncontrolled=True, run_root=tmp_path)
    try:
        infos = _episode(env, 335.0)
    finally:
        env.close()
    assert {i["heater_temperature"] for i in infos} == {310.0}


# -- the PID baseline ------------------------------------------------------------------------


def test_pid_integral_is_clipped_to_the_heater_range() -> None:
    from gymprecice_tutorials.heated_plate.pid import PIDController

    pid = PIDController(kp=0.0, ki=100.0)
    for _ in range(50):  # far too cold for long: the integral must not wind up
        action = pid(np.array([-10.0, 0.0, 0.0, 0.1], np.float32))
    assert action[0] == pytest.approx(HEATER_RANGE[1])
    assert pid.integral == pytest.approx(HEATER_RANGE[1] - 310.0)
    # One step past the setpoint brings the heater down at once.
    assert pid(np.array([0.5, 0.0, 0.0, 0.1], np.float32))[0] < HEATER_RANGE[1]
    pid.reset()
    assert pid.integral == 0.0


def _controlled(env: HeatedPlateEnv, controller, seed: int = 0) -> list[dict]:
    """One episode from held-out start ``seed`` under ``controller`` (obs -> heater)."""
    obs, _ = env.reset(seed=seed, options={"split": "eval"})
    infos = []
    while True:
        obs, _, terminated, truncated, info = env.step(controller(obs))
        infos.append(info["metrics"])
        if terminated or truncated:
            return infos


def test_a_pid_tracks_the_setpoint_better_than_the_uncontrolled_plate(env) -> None:
    from gymprecice_tutorials.heated_plate.pid import PIDController

    uncontrolled = _controlled(env, lambda obs: np.array([310.0], np.float32))
    pid = _controlled(env, PIDController(2.0, 20.0))
    assert env.start.setpoint == EVAL_STARTS[0].setpoint
    errors = {k: [i["tracking_error"] for i in v] for k, v in (("u", uncontrolled), ("pid", pid))}
    assert np.mean(errors["pid"]) < 0.5 * np.mean(errors["u"])
    assert errors["pid"][-1] < errors["u"][-1] / 3


# -- bad input in the OpenFOAM participants (gymprecice check, no solver started) --------------


def _check_case(tmp_path: Path, capsys, edit) -> tuple[int, str]:
    from gymprecice.tools.cli import main

    case = tmp_path / "case"
    for rel, text in case_files("openfoam", 1.0).items():
        (case / rel).parent.mkdir(parents=True, exist_ok=True)
        (case / rel).write_text(text)
    edit(case)
    status = main(["check", str(case)])
    return status, capsys.readouterr().err


def test_the_packaged_case_passes_the_check(tmp_path: Path, capsys) -> None:
    status, err = _check_case(tmp_path, capsys, lambda case: None)
    assert status == 0, err


def test_a_fluid_without_the_cht_module_is_named(tmp_path: Path, capsys) -> None:
    def drop_cht(case: Path) -> None:
        pdict = case / "fluid-openfoam" / "system" / "preciceDict"
        pdict.write_text(pdict.read_text().replace("modules (CHT FF);", "modules (FF);"))

    status, err = _check_case(tmp_path, capsys, drop_cht)
    assert status == 1
    assert "fluid-openfoam/system/preciceDict: interface 'plate' exchanges 'Heat-Flux'" in err
    assert "CHT module" in err and "'modules (FF CHT);'" in err


def test_a_laplacianfoam_plate_without_the_heater_patch_is_named(tmp_path: Path, capsys) -> None:
    def rename_bottom(case: Path) -> None:
        mesh = case / "solid-openfoam" / "system" / "blockMeshDict"
        mesh.write_text(mesh.read_text().replace("    bottom\n", "    base\n"))

    status, err = _check_case(tmp_path, capsys, rename_bottom)
    assert status == 1
    assert "solid-openfoam/system/preciceDict: interface 'heater' names patch 'bottom'" in err
    assert "solid-openfoam/system/blockMeshDict" in err


def test_the_integral_observation_sums_the_episodes_error_and_starts_each_episode_at_zero(
    tmp_path: Path,
) -> None:
    """The default observation's fifth number, the error integrated over the episode's
    actions (K s), is zero at every reset; ``observation="state"`` gives the first four,
    unchanged. Cost: under 2 s."""
    plain = HeatedPlateEnv(
        double=True, episode_time=0.5, settle_time=0.2, observation="state",
        run_root=tmp_path / "a",
    )  # fmt: skip
    env = HeatedPlateEnv(double=True, episode_time=0.5, settle_time=0.2, run_root=tmp_path / "b")
    try:
        assert env.observation_space.shape == (5,) and plain.observation_space.shape == (4,)
        for _episode in range(2):
            obs, _ = env.reset(seed=3)
            reference, _ = plain.reset(seed=3)
            assert obs[4] == 0.0
            np.testing.assert_allclose(obs[:4], reference)
            total = 0.0
            done = False
            while not done:
                obs, _, terminated, truncated, _ = env.step(np.array([330.0], np.float32))
                plain.step(np.array([330.0], np.float32))
                total += float(obs[0]) * 0.1
                assert obs[4] == pytest.approx(total, abs=1e-5)
                done = terminated or truncated
            assert total != 0.0
    finally:
        env.close()
        plain.close()


def test_an_unknown_observation_is_refused(tmp_path: Path) -> None:
    """Cost: under 0.1 s."""
    with pytest.raises(ValueError, match="observation must be one of state, integral"):
        HeatedPlateEnv(double=True, observation="history", run_root=tmp_path)
