"""PerpendicularFlapFast-v0 on the test double: the scripted flap and whole episodes.

Everything here runs without preCICE, OpenFOAM or deal.II, in seconds: the controller is
coupled through gymprecice's preCICE double to the scripted flap of
:mod:`gymprecice_tutorials.perpendicular_flap.double`, and the env reads the watch-point
log that the flap writes with its own, unchanged code.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.config import load_config
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.plugin.watchpoints import WatchPointLog
from gymprecice_lab.common.registered_env import find_lab_env
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.perpendicular_flap import double
from gymprecice_tutorials.perpendicular_flap.environment import jet_profile
from gymprecice_tutorials.perpendicular_flap.fast import (
    ACTION_TIME,
    EVAL_GUSTS,
    PerpendicularFlapFastEnv,
    fast_case_files,
)

LOG = "precice-Solid-watchpoint-Flap-Tip.log"


def _flap(tmp_path: Path, **options: object) -> double.FlapOscillator:
    xml = tmp_path / "precice-config.xml"
    xml.write_text(double.precice_config(4.0, 0.05))
    config = load_precice_config(xml)
    return double.FlapOscillator(config, double.PARTICIPANT, {"outputs": tmp_path, **options})


def _hold(flap: double.FlapOscillator, centre: float, seconds: float, dt: float = 0.05) -> None:
    inlet = flap.inlet.coordinates
    u = jet_profile(inlet[:, 1], centre, 2.0, mean_velocity=20.0 / 3.0)
    velocity = np.column_stack([u, np.zeros_like(u)])
    for k in range(round(seconds / dt)):
        flap.step(k * dt, dt, {("Velocity", double.MESH): velocity})


def test_inlet_faces_are_the_training_mesh_faces() -> None:
    inlet = double.training_inlet()
    blockmesh = fast_case_files(4.0)["fluid-openfoam/system/blockMeshDict"]
    assert "nyFlap      8;" in blockmesh and "nyAbove     22;" in blockmesh
    assert len(inlet.coordinates) == 8 + 22
    assert np.all(inlet.coordinates[:, 0] == -3.0)
    assert inlet.areas.sum() == pytest.approx(4.0)  # the inlet, 4 m tall and 1 m deep
    np.testing.assert_allclose(inlet.coordinates[:2, 1], [0.0625, 0.1875])
    with pytest.raises(ValueError, match="no 'nyAbove <value>;'"):
        double.inlet_faces(blockmesh.replace("nyAbove", "nyOver"))


def test_the_flap_settles_where_the_real_flap_does(tmp_path: Path) -> None:
    on_flap, at_top = _flap(tmp_path), _flap(tmp_path)
    _hold(on_flap, 1.0, 120.0)
    _hold(at_top, 3.0, 120.0)
    assert on_flap.state["x"] == pytest.approx(0.07, rel=0.02)
    assert at_top.state["x"] == pytest.approx(0.01, abs=0.002)


def test_the_flap_swings_at_its_natural_frequency_and_barely_damps(tmp_path: Path) -> None:
    flap = _flap(tmp_path)
    dt = 0.01
    crossings, previous, amplitudes = [], 0.0, []
    inlet = flap.inlet.coordinates
    u = jet_profile(inlet[:, 1], 1.0, 2.0, mean_velocity=20.0 / 3.0)
    velocity = {("Velocity", double.MESH): np.column_stack([u, np.zeros_like(u)])}
    for k in range(1000):  # a step load from rest: swings about the static deflection
        flap.step(k * dt, dt, velocity)
        deviation = flap.state["x"] - flap.state["static"]
        amplitudes.append(abs(deviation))
        if previous < 0.0 <= deviation:
            crossings.append(k * dt)
        previous = deviation
    period = float(np.mean(np.diff(crossings)))
    assert period == pytest.approx(1.0 / 0.62 / math.sqrt(1 - 0.02**2), rel=0.02)
    # a damping ratio of 0.02 leaves exp(-0.02 * omega * 5 T) ~ 53 % after five periods
    n = round(period / dt)
    assert max(amplitudes[5 * n : 6 * n]) / max(amplitudes[:n]) == pytest.approx(
        math.exp(-0.02 * 2 * math.pi * 0.62 * 5 * period), rel=0.03
    )


def test_the_flap_writes_the_watch_point_log_in_precices_format(tmp_path: Path) -> None:
    flap = _flap(tmp_path)
    _hold(flap, 1.0, 0.5)
    flap.write_outputs(tmp_path, 0.5)
    text = (tmp_path / LOG).read_text()
    assert text.startswith("  Time  Coordinate0  Coordinate1  Displacement0  Displacement1")
    assert not text.endswith("\n")  # preCICE writes the newline before each row
    log = WatchPointLog(tmp_path / LOG)
    rows = log.wait_until(0.5, timeout=1.0)
    assert log.field("Time", log.data).tolist() == [0.0, 0.5]
    dx, dy = log.field("Displacement", rows)[-1]
    assert dx == pytest.approx(flap.state["x"], rel=1e-7) and dx > 0.0  # 8 digits, as preCICE
    assert dy == pytest.approx(-0.6 * dx * dx, rel=1e-7)
    assert log.field("Force", rows).shape == (2, 2)


def test_the_double_case_is_the_training_controller_against_the_flap(tmp_path: Path) -> None:
    case = write_case_files("flap-double", double.double_case_files(4.0), tmp_path)
    config = load_config(case / "gymprecice-config.json")
    training = json.loads(fast_case_files(4.0)["gymprecice-config.json"])
    assert config.model.actions.windows == training["actions"]["windows"]
    solid = config.solvers["solid"]
    assert (solid.kind, solid.path, solid.participant) == ("command", "solid-dealii", "Solid")
    assert solid.options["outputs"] == "dealii"
    xml = load_precice_config(case / "precice-config.xml")
    assert {s.max_time for s in xml.coupling_schemes} == {4.0}


@pytest.fixture
def env(tmp_path: Path):
    environment = PerpendicularFlapFastEnv(double=True, episode_time=0.5, run_root=tmp_path)
    yield environment
    environment.close()


def test_an_episode_runs_from_a_gust_start_with_reward_minus_mean_tip_displacement(
    env: PerpendicularFlapFastEnv, tmp_path: Path
) -> None:
    observation, info = env.reset(seed=0, options={"split": "eval"})
    assert info["start"] == {"gust": list(EVAL_GUSTS[0]), "split": "eval"}
    assert env.time == pytest.approx(env.settle_time) and observation.shape == (6,)
    log = WatchPointLog(next(tmp_path.rglob(f"solid-dealii/{LOG}")))
    rewards, truncated = [], False
    while not truncated:
        start = env.time
        observation, reward, terminated, truncated, info = env.step(np.array([2.0], np.float32))
        assert not terminated
        rows = log.wait_until(env.time, timeout=5.0)
        times = log.field("Time", log.data)
        step = log.data[(times > start + 1e-9) & (times <= env.time + 1e-9)]
        assert len(step) == round(ACTION_TIME / 0.05)  # both windows of the step
        displacement = log.field("Displacement", step)
        assert reward == pytest.approx(-np.mean(np.linalg.norm(displacement, axis=1)), rel=1e-5)
        assert info["metrics"]["mean_tip_displacement"] == pytest.approx(-reward)
        np.testing.assert_allclose(observation[:2], log.field("Displacement", rows)[-1], 1e-5)
        rewards.append(reward)
    assert len(rewards) == 5 and env.time == pytest.approx(1.5)
    assert max(-r for r in rewards) > 0.02  # the gust left the flap swinging


def test_the_held_out_starts_differ(env: PerpendicularFlapFastEnv) -> None:
    starts = []
    for seed in range(len(EVAL_GUSTS)):
        observation, info = env.reset(seed=seed, options={"split": "eval"})
        assert info["start"]["gust"] == list(EVAL_GUSTS[seed])
        starts.append(observation)
    for i in range(len(starts)):
        for j in range(i):
            assert np.abs(starts[i][:4] - starts[j][:4]).max() > 1e-3, (i, j)


def test_double_refuses_a_case_of_ones_own(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="leave double out"):
        PerpendicularFlapFastEnv(tmp_path / "case", double=True)


def test_a_short_training_run_on_the_double_completes(tmp_path: Path) -> None:
    assert find_lab_env("perpendicular-flap-fast").double
    command = [sys.executable, "-m", "gymprecice", "train", "perpendicular-flap-fast"]
    command += ["--double", "--vec-env", "dummy", "--n-envs", "1", "--n-steps", "8"]
    command += ["--batch-size", "8", "--n-epochs", "1", "--net", "8,8", "--timesteps", "8"]
    command += ["--seed", "3", "--out", "train", "--no-progress-bar"]
    run = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=240)
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "train" / "model.zip").is_file()
    manifest = json.loads((tmp_path / "train" / "manifest.json").read_text())
    assert manifest["segments"][-1]["settings"]["double"] is True
