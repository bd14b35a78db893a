"""Two flaps in one channel: the PettingZoo API on the double, the case, the real stack.

The double tests run TwoFlapsFastEnv against gymprecice's preCICE test double and two
scripted flaps (:mod:`gymprecice_tutorials.two_flaps.double`), rendering included (their
stand-in fluid and both bent flaps in one frame); the tests marked
``precice``/``openfoam``/``dealii`` run the training case with all four participants:
pimpleFoam, two deal.II ``elasticity`` solids and the controller.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test, parallel_seed_test

import gymprecice  # noqa: F401  (registers the ids)
from gymprecice.env.processes import kill_recorded_groups
from gymprecice.multiagent import JointEnv
from gymprecice.plugin.fields import FIELDS_DIR, read_field_file
from gymprecice.tools.stack import stack_which
from gymprecice_openfoam.testing import missing_coupled_stack
from gymprecice_tutorials.two_flaps import CASE_DIR
from gymprecice_tutorials.two_flaps.double import training_slots
from gymprecice_tutorials.two_flaps.environment import FLAPS, slot_velocity
from gymprecice_tutorials.two_flaps.fast import EVAL_GUSTS, GUST_STEP, TwoFlapsFastEnv, gust
from gymprecice_tutorials.two_flaps.training_case import fast_case_files

AGENTS = ["upstream", "downstream"]
#: a frame that shows a field has far more pixel variance than a blank or one-colour one
VARIANCE_FLOOR = 100.0


def _double(tmp_path: Path, **kwargs) -> TwoFlapsFastEnv:
    kwargs.setdefault("settle_time", 0.3)
    kwargs.setdefault("episode_time", 0.5)
    return TwoFlapsFastEnv(double=True, run_root=tmp_path, **kwargs)


def _act(env, value: float) -> dict:
    return {agent: np.array([value], np.float32) for agent in env.agents}


# -- the PettingZoo API on the double ---------------------------------------------------------


def test_parallel_api_test_passes_on_the_double(tmp_path: Path) -> None:
    env = _double(tmp_path)
    try:
        parallel_api_test(env, num_cycles=12)
        assert env.possible_agents == AGENTS
    finally:
        env.close()


def test_seed_test_passes_and_the_seed_draws_the_gust(tmp_path: Path) -> None:
    made = iter(range(100))

    def make():
        return TwoFlapsFastEnv(
            double=True,
            settle_time=0.3,
            episode_time=0.3,
            run_root=tmp_path / f"runs-{next(made)}",
        )

    parallel_seed_test(make, num_cycles=3)
    env = make()
    try:
        first = env.reset(seed=1)[1]["upstream"]["start"]["gust"]
        again = env.reset(seed=1)[1]["upstream"]["start"]["gust"]
        other = env.reset(seed=2)[1]["upstream"]["start"]["gust"]
        assert first == again and first != other
    finally:
        env.close()


def test_an_episode_truncates_both_agents_at_the_end_time(tmp_path: Path) -> None:
    env = _double(tmp_path)
    try:
        obs, infos = env.reset(seed=0, options={"split": "eval"})
        assert env.time == pytest.approx(0.3)  # the gust is not part of the episode
        assert infos["upstream"]["start"]["gust"] == [list(g) for g in EVAL_GUSTS[0][:2]]
        assert obs["upstream"][-1] == 1.0 and obs["downstream"][-1] == -1.0
        steps = 0
        while env.agents:
            obs, rewards, terms, truncs, infos = env.step(_act(env, 0.5))
            steps += 1
            for agent in AGENTS:
                assert env.observation_space(agent).contains(obs[agent])
                metrics = infos[agent]["metrics"]
                assert rewards[agent] == -metrics["mean_tip_displacement"] < 0
                assert infos[agent]["action"] == [5.0]  # half of the slot's 10 m/s
        assert steps == 5 and env.time == pytest.approx(0.8)
        assert all(truncs.values()) and not any(terms.values())
    finally:
        env.close()


def test_each_agent_sees_its_own_tip_and_its_neighbours(tmp_path: Path) -> None:
    env = _double(tmp_path)
    try:
        obs, _ = env.reset(seed=0, options={"split": "eval"})
        up, down = obs["upstream"], obs["downstream"]
        np.testing.assert_array_equal(up[6:8], down[[0, 2]])
        np.testing.assert_array_equal(down[6:8], up[[0, 2]])
        assert up[0] != down[0]  # the gust set them swinging differently
    finally:
        env.close()


def test_uncontrolled_closes_both_slots_after_the_gust(tmp_path: Path) -> None:
    env = _double(tmp_path, uncontrolled=True)
    try:
        env.reset(seed=0, options={"split": "eval"})
        _, _, _, _, infos = env.step(_act(env, 1.0))
        assert infos["upstream"]["action"] == [0.0] == infos["downstream"]["action"]
    finally:
        env.close()


def test_base_damping_adds_the_classical_law_to_each_action(tmp_path: Path) -> None:
    """``base_damping=KV``: each slot is ``-KV vx`` of its own flap's tip (the velocity
    the agent saw) plus its action, clipped; an action of 0 is the law alone."""
    env = _double(tmp_path, base_damping=30.0)
    try:
        obs, _ = env.reset(seed=0, options={"split": "eval"})
        for action in (0.0, 0.25):
            seen = {agent: float(obs[agent][2]) for agent in env.agents}
            obs, _, _, _, infos = env.step(_act(env, action))
            for agent, vx in seen.items():
                slot = np.clip(action - 30.0 * vx, -1.0, 1.0) * env.jet_max_velocity
                assert infos[agent]["action"] == [pytest.approx(slot, abs=1e-5)]
        assert any(abs(vx) > 1e-4 for vx in seen.values())  # the law had a motion to damp
    finally:
        env.close()
    with pytest.raises(ValueError, match="base_damping is a gain >= 0"):
        _double(tmp_path, base_damping=-1.0)


def test_a_held_out_start_out_of_range_is_refused(tmp_path: Path) -> None:
    env = _double(tmp_path)
    try:
        with pytest.raises(ValueError, match="3 held-out gusts"):
            env.reset(options={"split": "eval", "start": 3})
    finally:
        env.close()


def test_the_shared_policy_route_stacks_both_agents(tmp_path: Path) -> None:
    env = JointEnv(_double(tmp_path))
    try:
        obs, _ = env.reset(seed=0)
        assert obs.shape == (2, 9) and env.action_space.shape == (2, 1)
        obs, reward, _, _, info = env.step(np.zeros((2, 1), np.float32))
        assert reward == pytest.approx(float(np.mean(info["agent_rewards"])))
    finally:
        env.close()


# -- rendering on the double ------------------------------------------------------------------


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def _check_frame(env, frame: np.ndarray) -> None:
    width, height = env.render_size  # a height of None follows the domain
    assert frame.shape[1:] == (width, 3) and frame.dtype == np.uint8
    assert frame.shape[0] == (height or frame.shape[0]) and frame.shape[0] % 16 == 0
    assert frame.var() > VARIANCE_FLOOR


def test_the_pettingzoo_env_draws_the_fluid_both_flaps_and_both_slots(tmp_path: Path) -> None:
    env = _double(tmp_path, render_mode="rgb_array")
    try:
        assert env.render_mode == "rgb_array"
        assert env.metadata["render_fps"] == 10 and "rgb_array" in env.metadata["render_modes"]
        env.reset(seed=0, options={"split": "eval"})
        first = env.render()
        _check_frame(env, first)
        settings = {"upstream": np.array([1.0], np.float32), "downstream": np.array([-1.0])}
        env.step(settings)
        env.step(settings)
        second = env.render()
        _check_frame(env, second)
        assert second.shape == first.shape
        assert np.abs(second.astype(int) - first.astype(int)).sum() > 0
        overlay = env._render_overlay()
        # blowing: up out of the floor at the upstream slot; suction: down into it
        assert overlay.arrows == [(-1.35, 0.0, 0.0, 0.5), (0.65, 0.5, 0.0, -0.5)]
        assert "+10.0 m/s blowing" in overlay.text[0] and "-10.0 m/s suction" in overlay.text[1]
        solvers = env.solver_dirs
    finally:
        env.close()
    fluid = read_field_file(solvers["upstream"] / FIELDS_DIR / "U.npz")
    assert fluid.points[:, 0].min() == -3.0 and fluid.points[:, 0].max() == 3.0
    for flap in FLAPS:
        bent = read_field_file(solvers[flap.solver] / FIELDS_DIR / "displacement.npz")
        # the frame's step (0.3 s gust, 2 actions), or the window the flap ran ahead to
        assert 0.5 - 1e-9 <= bent.time <= 0.55 + 1e-9
        assert np.mean(bent.points[:, 0]) == pytest.approx(flap.x)
        assert np.abs(bent.displacement[:, 0]).max() > 0


def test_without_render_mode_the_scripted_flaps_write_nothing_more(tmp_path: Path) -> None:
    plain = _double(tmp_path / "plain")
    rendering = _double(tmp_path / "rendering", render_mode="rgb_array")
    for env in (plain, rendering):
        env.reset(seed=0)
        while env.agents:
            env.step(_act(env, 0.5))
        env.close()
    extra = _files(rendering.run_dir) - _files(plain.run_dir)
    assert extra == {
        f"solid-upstream-dealii/{FIELDS_DIR}/U.npz",
        f"solid-upstream-dealii/{FIELDS_DIR}/displacement.npz",
        f"solid-downstream-dealii/{FIELDS_DIR}/displacement.npz",
    }
    with pytest.warns(UserWarning, match=r"TwoFlapsFastEnv.render\(\) called without"):
        assert plain.render() is None


def test_a_render_mode_the_env_lacks_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"TwoFlapsFastEnv.*render_mode='human'.*\['rgb_array'\]"):
        _double(tmp_path, render_mode="human")


def test_the_joint_env_renders_and_records_a_playable_video(tmp_path: Path) -> None:
    pytest.importorskip("moviepy", reason="the render extra: gymprecice-core[render]")
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="gymprecice-core[render]")
    env = gym.make(
        "gymprecice/TwoFlapsFast-v0",
        double=True,
        run_root=str(tmp_path / "runs"),
        settle_time=0.3,
        episode_time=0.3,
        render_mode="rgb_array",
    )
    assert env.render_mode == "rgb_array" and env.metadata["render_fps"] == 10
    videos = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(env, str(videos), episode_trigger=lambda _: True)
    try:
        env.reset(seed=0)
        frames = [env.render()]
        done = False
        while not done:
            *_, terminated, truncated, _ = env.step(np.full((2, 1), 0.5, np.float32))
            done = terminated or truncated
            if not done:
                frames.append(env.render())
    finally:
        env.close()
    for frame in frames:
        _check_frame(env.unwrapped, frame)
        assert frame.shape == frames[0].shape
    assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).sum() > 0
    (video,) = videos.glob("*.mp4")
    reader = imageio_ffmpeg.read_frames(str(video))  # decodes it: a playable file
    assert tuple(next(reader)["size"]) == (frames[0].shape[1], frames[0].shape[0])
    assert len(list(reader)) == 4  # reset + 3 actions


# -- the case, the gusts, the slots ----------------------------------------------------------


def test_training_gusts_are_reproducible_and_never_a_held_out_start() -> None:
    draws = [gust(np.random.default_rng(seed), 1.0) for seed in range(200)]
    again = [gust(np.random.default_rng(seed), 1.0) for seed in range(200)]
    assert draws == again
    held_out = {v for g in EVAL_GUSTS for v in (*g.first, *g.second)}
    for g in draws:
        for value in (*g.first, *g.second):
            assert -1 < value < 1 and value not in held_out
            assert abs((value + 1) / GUST_STEP % 1 - 0.5) < 1e-9
        assert 0.1 - 1e-9 <= g.switch <= 0.9 + 1e-9


def test_a_slot_carries_its_flow_rate_and_blows_or_sucks() -> None:
    faces = training_slots()["upstream_jet"]
    for mean in (10.0, -4.0):
        velocity = slot_velocity(faces.coordinates[:, 0], -1.35, mean, faces.areas)
        assert velocity[:, 0].tolist() == [0.0] * len(velocity)
        flux = float(velocity[:, 1] @ faces.areas)
        assert flux == pytest.approx(mean * 0.2)
    assert not slot_velocity(faces.coordinates[:, 0], -1.35, 0.0).any()


def test_the_tip_feedback_sets_each_slot_from_its_own_flap() -> None:
    """The two flaps' classical law: each slot from its own flap's dx and vx only (the
    other's, in the same row, does not move it), clipped to the slot's range, on the joint
    env's action box; another box is refused with the env to run it on."""
    from gymprecice_tutorials.two_flaps.feedback import TIP_LAW

    space = gym.spaces.Box(-1.0, 1.0, shape=(2, 1), dtype=np.float32)  # TwoFlapsFast-v0's
    law = TIP_LAW.build(space, {"kx": 50.0, "kv": 10.0})
    obs = np.zeros((2, 9), dtype=np.float32)
    obs[0, [0, 2]] = [0.01, 0.02]  # upstream: bent 1 cm, moving 2 cm/s downstream
    obs[1, [0, 2]] = [-0.001, 0.5]  # downstream: moving fast, so its slot saturates
    obs[:, 6:8] = 9.0  # the neighbour's tip, which the law does not read
    action = law(obs, 0.0)
    assert action.shape == (2, 1) and space.contains(action)
    np.testing.assert_allclose(action[:, 0], [-(0.5 + 0.2), -1.0], rtol=1e-6)
    assert TIP_LAW.label({"kx": -50.0, "kv": 30.0}) == "tip-kx-50-kv30"
    with pytest.raises(ValueError, match="run it on TwoFlapsFast-v0"):
        TIP_LAW.build(gym.spaces.Box(-1.0, 1.0, shape=(1,)), {"kx": 0.0, "kv": 0.0})


def test_the_training_case_is_the_packaged_case_with_its_edits() -> None:
    files = fast_case_files(4.0)
    xml = files["precice-config.xml"]
    assert xml.count('<max-time value="4" />') == 2
    assert xml.count('<time-window-size value="0.05" />') == 2
    assert xml.count('limit="1e-3"') == 4
    for flap in FLAPS:
        prm = files[f"solid-{flap.agent}-dealii/parameters.prm"]
        assert "set Polynomial degree = 2" in prm and "set Time step size  = 0.05" in prm
    packaged = (CASE_DIR / "fluid-openfoam/system/blockMeshDict").read_text()
    assert (
        "nxIn        14;" in packaged
        and "nxIn        7;" in files["fluid-openfoam/system/blockMeshDict"]
    )


# -- the real stack: four participants ---------------------------------------------------------


def _real_missing() -> list[str]:
    missing = missing_coupled_stack("pimpleFoam")
    if stack_which("elasticity") is None:
        missing.append("the deal.II adapter (elasticity)")
    return missing


_MISSING = _real_missing()
real = pytest.mark.skipif(bool(_MISSING), reason="needs " + ", ".join(_MISSING))


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(600)
@real
def test_one_coupled_episode_of_four_participants(tmp_path: Path) -> None:
    """TwoFlapsFast's default episode on the real stack: a 1 s gust, then 30 actions of
    the shared API, every agent truncated at the end, both flaps moving.

    Cost: about 25 s on 2 idle cores (4 s of flow: pimpleFoam on 1,208 cells, two
    degree-2 deal.II solids; mesh and reset about 5 s).
    """
    env = TwoFlapsFastEnv(run_root=tmp_path)
    try:
        env.reset(seed=0, options={"split": "eval"})
        solvers = {process.name for process in env._gymprecice.run.session.solvers}
        assert solvers == {"fluid", "upstream", "downstream"}
        swing = {agent: [] for agent in AGENTS}
        steps = 0
        while env.agents:
            obs, _, terms, truncs, _ = env.step(_act(env, 0.0))
            steps += 1
            for agent in AGENTS:
                assert np.isfinite(obs[agent]).all()
                swing[agent].append(float(obs[agent][0]))
        assert steps == 30 and all(truncs.values()) and not any(terms.values())
        for agent in AGENTS:
            assert np.ptp(swing[agent]) > 5e-3, f"the {agent} flap does not swing"
    finally:
        env.close()
    assert kill_recorded_groups(env.env_dir) == []


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(600)
@real
def test_one_rendered_step_draws_the_fluid_and_both_bent_flaps(tmp_path: Path) -> None:
    """One step of the training case with ``render_mode="rgb_array"``: pimpleFoam's ``U``
    and both deal.II solids' snapshots in one frame, which changes with the step.

    Cost: about 20 s on 2 cores (18 s measured on a busy machine: 0.2 s of flow, a 0.1 s
    gust and one action of an episode of two; mesh and reset about 5 s).
    """
    from gymprecice_dealii.fields import read_vtk

    env = TwoFlapsFastEnv(
        run_root=tmp_path, settle_time=0.1, episode_time=0.2, render_mode="rgb_array"
    )
    try:
        env.reset(seed=0, options={"split": "eval"})
        solvers = {process.name for process in env._gymprecice.run.session.solvers}
        assert solvers == {"fluid", "upstream", "downstream"}
        first = env.render()
        env.step(_act(env, 1.0))
        second = env.render()
        dirs = env.solver_dirs
    finally:
        env.close()
    for frame in (first, second):
        _check_frame(env, frame)
    assert second.shape == first.shape
    assert np.abs(second.astype(int) - first.astype(int)).sum() > 0
    assert (dirs["fluid"] / "0.2" / "U").is_file()  # one U per action: the frame's fluid
    for flap in FLAPS:
        output = dirs[flap.solver] / "dealii-output"
        # the start, and one snapshot per action: the gust's and the step's
        written = {p.name for p in output.iterdir()}
        assert {f"solution-{k:03d}.vtk" for k in range(3)} <= written
        moved = read_vtk(output / "solution-002.vtk").point_data["displacement"]
        assert np.abs(moved[:, 0]).max() > 1e-4, f"the {flap.agent} flap is not bent"
    assert kill_recorded_groups(env.env_dir) == []


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(600)
@real
def test_killing_one_solid_is_reported_and_reset_recovers(tmp_path: Path) -> None:
    """SIGKILL of the downstream solid mid-episode: the step raises an error naming it,
    no process of the episode (fluid, the other solid, the worker) is left, and the next
    reset starts a whole new four-participant run.

    Cost: about 25 s on 2 idle cores (two resets and a few steps of the training case).
    """
    from gymprecice.plugin.errors import CouplingError, SolverError

    env = TwoFlapsFastEnv(run_root=tmp_path, settle_time=0.2, episode_time=1.0)
    try:
        env.reset(seed=0, options={"split": "eval"})
        env.step(_act(env, 0.0))
        session = env._gymprecice.run.session
        groups = {process.name: process.pgid for process in session.solvers}
        worker = session.worker.pid
        os.killpg(groups["downstream"], signal.SIGKILL)
        with pytest.raises((SolverError, CouplingError)) as raised:
            for _ in range(5):
                env.step(_act(env, 0.0))
        assert "downstream" in str(raised.value)
        assert env.agents == []
        assert not any(_group_alive(pgid) for pgid in groups.values())
        from gymprecice.testing.chaos import pid_alive

        assert not pid_alive(worker)
        assert kill_recorded_groups(env.env_dir) == []
        obs, _ = env.reset(seed=1, options={"split": "eval"})
        assert all(np.isfinite(o).all() for o in obs.values())
        _, _, _, truncs, _ = env.step(_act(env, 0.0))
        assert not any(truncs.values())
    finally:
        env.close()
    assert kill_recorded_groups(env.env_dir) == []
