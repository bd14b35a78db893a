"""PerpendicularFlapFast-v0 without solvers: its case, its starts, its actions and data.

The coupled runs (the shipped policy against the uncontrolled flap on the real
three-participant stack) are in ``tests/test_tutorials_real_solvers.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.config import load_config
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.plugin.solver import SolverContext
from gymprecice.plugin.watchpoints import WatchPointLog
from gymprecice_dealii.plugin import check_against_precice
from gymprecice_dealii.prm import ElasticityParameters
from gymprecice_lab.common.registered_env import find_lab_env
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.perpendicular_flap import fast, training_case
from gymprecice_tutorials.perpendicular_flap.fast import (
    EVAL_GUSTS,
    PerpendicularFlapFastEnv,
    fast_case_files,
    gust,
)


def test_the_training_case_is_the_packaged_case_with_its_edits(tmp_path: Path) -> None:
    case = write_case_files("flap-fast", fast_case_files(4.0), tmp_path)
    precice = load_precice_config(case / "precice-config.xml")
    assert {s.max_time for s in precice.coupling_schemes} == {4.0}
    assert {s.time_window_size for s in precice.coupling_schemes} == {fast.WINDOW}
    blockmesh = (case / "fluid-openfoam/system/blockMeshDict").read_text()
    assert "nxSide      15;" in blockmesh and "nyAbove     22;" in blockmesh
    config = load_config(case / "gymprecice-config.json")
    assert config.model.actions.windows == 2
    params = ElasticityParameters.read(case / "solid-dealii/parameters.prm")
    assert params.time_step == fast.WINDOW and params.end_time >= 4.0
    solid = case / "solid-dealii"
    check_against_precice(
        SolverContext(
            name="solid",
            kind="dealii",
            run_dir=solid,
            source_dir=solid,
            env_dir=case,
            participant="Solid",
            precice=precice,
        ),
        params,
    )  # raises on any disagreement
    # the same end time writes the same directory; another writes another
    assert write_case_files("flap-fast", fast_case_files(4.0), tmp_path) == case
    assert write_case_files("flap-fast", fast_case_files(5.0), tmp_path) != case


def test_the_precice_route_gives_the_controller_a_tip_mesh_fed_by_solid_and_fluid(
    tmp_path: Path,
) -> None:
    case = write_case_files("flap-fast-precice", fast_case_files(4.0, "precice"), tmp_path)
    precice = load_precice_config(case / "precice-config.xml")
    assert len(precice.coupling_schemes) == 3
    assert {s.max_time for s in precice.coupling_schemes} == {4.0}
    controller = precice.participant("Controller")
    assert ("Displacement", "Controller-Mesh-tip") in controller.read_data
    assert ("Force", "Controller-Mesh-force") in controller.read_data
    config = load_config(case / "gymprecice-config.json")
    assert config.interfaces["tip"].mesh == "Controller-Mesh-tip"
    assert config.interfaces["tip"].read == ("Displacement",)
    assert config.interfaces["force"].mesh == "Controller-Mesh-force"
    assert config.interfaces["force"].read == ("Force",)
    assert config.interfaces["inlet"].write == ("Velocity",)


def test_the_precice_route_needs_the_packaged_case_on_the_real_solvers(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"observe='precice'.*real solvers"):
        PerpendicularFlapFastEnv(double=True, observe="precice", run_root=tmp_path)
    with pytest.raises(ValueError, match="observe must be"):
        PerpendicularFlapFastEnv(observe="file", run_root=tmp_path)


def test_an_edit_that_no_longer_matches_the_packaged_case_fails_naming_the_file(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    edits = (("fluid-openfoam/system/controlDict", "deltaT 0.5;", "deltaT 1;"),)
    monkeypatch.setattr(training_case, "FAST_EDITS", edits)
    with pytest.raises(ValueError, match=r"controlDict.*occurs 0 times.*FAST_EDITS"):
        fast_case_files(4.0)


def test_training_gusts_are_reproducible_and_never_a_held_out_start() -> None:
    draws = [gust(np.random.default_rng(seed), 1.0, 1.0, 3.0) for seed in range(2000)]
    assert draws[:5] == [gust(np.random.default_rng(seed), 1.0, 1.0, 3.0) for seed in range(5)]
    held_out = {h for g in EVAL_GUSTS for h in (g.first, g.second)}
    heights = {h for g in draws for h in (g.first, g.second)}
    assert all(1.0 < h < 3.0 for h in heights)
    assert not heights & held_out
    assert all(0.0 < g.switch < 1.0 for g in draws)
    assert len({g.switch for g in draws}) == 9  # every whole action inside the settle
    assert len(set(draws)) > 1700  # 14,400 possible starts: few repeats in 2,000 draws


def test_gust_switches_height_at_its_instant() -> None:
    start = fast.Gust(1.0, 3.0, 0.5)
    assert (start.centre(0.0), start.centre(0.4), start.centre(0.5)) == (1.0, 1.0, 3.0)


@pytest.fixture
def env(tmp_path: Path):
    environment = PerpendicularFlapFastEnv(run_root=tmp_path / "runs")
    yield environment
    environment.close()


def test_env_is_registered_with_its_objective_and_uncontrolled_flap() -> None:
    info = find_lab_env("gymprecice/PerpendicularFlapFast-v0")
    assert info.name == "perpendicular-flap-fast"
    assert info.objective == "mean_tip_displacement"
    assert dict(info.baseline_kwargs) == {"uncontrolled": True}


@pytest.mark.parametrize(
    ("name", "value"), [("episode_time", 0.25), ("settle_time", 0.0), ("episode_time", -1.0)]
)
def test_times_that_are_not_whole_actions_are_refused(tmp_path: Path, name: str, value) -> None:
    with pytest.raises(ValueError, match=f"{name} must be a positive multiple of 0.1"):
        PerpendicularFlapFastEnv(run_root=tmp_path, **{name: value})


def test_the_case_ends_after_gust_and_episode(env: PerpendicularFlapFastEnv) -> None:
    assert env.end_time == pytest.approx(env.settle_time + env.episode_time) == 4.0
    assert env.observation_space.shape == (6,)


def test_the_start_comes_from_the_split(env: PerpendicularFlapFastEnv) -> None:
    env._split, env._split_seed = "eval", 4
    assert env._initial_action()[0] == EVAL_GUSTS[1].first and env.start == EVAL_GUSTS[1]
    env._split = "train"
    env._np_random = np.random.default_rng(11)
    env._initial_action()
    assert env.start == gust(np.random.default_rng(11), 1.0, 1.0, 3.0)


def test_the_held_out_starts_are_the_held_out_gusts_in_order(env: PerpendicularFlapFastEnv) -> None:
    assert len(env.held_out_starts) == len(EVAL_GUSTS) == 3
    assert env.held_out_starts[1] == "jet 3 -> 1 m at 0.3 s"


@pytest.mark.parametrize("start", [3, -1, "0", True])
def test_a_start_index_outside_the_held_out_gusts_is_refused_before_anything_runs(
    env: PerpendicularFlapFastEnv, start: object
) -> None:
    with pytest.raises(ValueError, match="3 held-out gusts, use 0 to 2"):
        env.reset(seed=0, options={"split": "eval", "start": start})


def test_uncontrolled_writes_the_reference_inflow_after_the_gust(tmp_path: Path) -> None:
    env = PerpendicularFlapFastEnv(run_root=tmp_path, uncontrolled=True)
    try:
        y = (np.arange(40) + 0.5) * 0.1
        env.set_interface_vertices("inlet", np.column_stack([np.full(40, -3.0), y]))
        (ref,) = env.write_var_list
        env.time = 0.5  # during the gust: the jet
        jet = env._get_action(np.array([1.0], np.float32), env.write_var_list)[ref][:, 0]
        assert np.all(jet[y > 2.0] == 0)
        env.time = 1.0  # the episode: the parabola across the whole inlet, any action
        inflow = env._get_action(np.array([1.0], np.float32), env.write_var_list)[ref][:, 0]
        np.testing.assert_allclose(inflow, 10 * 4 * (y / 4) * (1 - y / 4), rtol=0.01)
    finally:
        env.close()


def test_observation_adds_the_tip_velocity(
    env: PerpendicularFlapFastEnv, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    log = tmp_path / "precice-Solid-watchpoint-Flap-Tip.log"
    columns = ["Time", "Coordinate0", "Coordinate1", "Displacement0", "Displacement1"]
    columns += ["Force0", "Force1"]
    rows = [(0.0, 0.0, 0.0), (0.05, 0.01, 0.001), (0.1, 0.03, 0.002)]
    text = "".join(f"  {c}" for c in columns)
    for t, dx, dy in rows:
        text += "\n" + "  ".join(f"{v:15.8e}" for v in (t, 0.0, 1.0, dx, dy, 1.5, -2.0))
    log.write_text(text)
    monkeypatch.setattr(env, "open_output", lambda solver, name, **o: WatchPointLog(log))
    env.time = 0.1
    observation = env._get_observation({}, [])
    np.testing.assert_allclose(observation, [0.03, 0.002, 0.4, 0.02, 1.5, -2.0], rtol=1e-6)


def test_the_history_observation_shows_the_tips_last_positions_newest_first(
    tmp_path: Path,
) -> None:
    """``observation="history"``: the six numbers of the state, then the tip's (dx, dy) at
    the ends of the three steps before (the gust's, at the episode's start), shifted by
    one each step. Cost: under 3 s."""
    from gymprecice_tutorials.perpendicular_flap.environment import TIP_HISTORY

    env = PerpendicularFlapFastEnv(double=True, observation="history", run_root=tmp_path)
    try:
        assert env.observation_space.shape == (6 + 2 * TIP_HISTORY,)
        obs, _ = env.reset(seed=1)
        past = obs[6:].reshape(TIP_HISTORY, 2)
        assert np.all(past != 0.0)  # the gust's steps
        for _ in range(4):
            expected = np.concatenate([obs[None, :2], past[:-1]])
            obs, *_ = env.step(np.array([2.0], np.float32))
            past = obs[6:].reshape(TIP_HISTORY, 2)
            np.testing.assert_array_equal(past, expected)
    finally:
        env.close()


def test_an_unknown_observation_or_history_on_the_precice_route_is_refused(
    tmp_path: Path,
) -> None:
    """Cost: under 0.1 s."""
    with pytest.raises(ValueError, match="observation must be one of state, history"):
        PerpendicularFlapFastEnv(double=True, observation="tip", run_root=tmp_path)
    with pytest.raises(ValueError, match="with observe='precice' leave it out"):
        PerpendicularFlapFastEnv(observe="precice", observation="history", run_root=tmp_path)
