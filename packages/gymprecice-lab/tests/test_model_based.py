"""Model-ensemble PPO: its settings, its recorded data, its models, its model env, and a run.

The parts are tested on small systems whose answer is known (a linear flow the ensemble
must learn, a counter env whose every transition is predictable); the whole is run as a
user runs it, ``gymprecice train`` with ``model_ensemble`` in the hyperparameter file, on
the test double, then resumed.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv

from gymprecice_lab import hyperparams as hp
from gymprecice_lab.model_based.ensemble import EnvironmentEnsemble, windows
from gymprecice_lab.model_based.model_env import ModelVecEnv
from gymprecice_lab.model_based.ppo import ModelEnsemblePPO
from gymprecice_lab.model_based.recorder import Segment, TransitionRecorder
from gymprecice_lab.model_based.settings import EnsembleSettings

# -- settings ------------------------------------------------------------------------------


def test_settings_take_true_or_a_mapping_and_refuse_what_they_do_not_have():
    assert EnsembleSettings.from_value(True, "f.yml") == EnsembleSettings()
    got = EnsembleSettings.from_value({"members": 3, "hidden": "64,32"}, "f.yml")
    assert (got.members, got.hidden) == (3, (64, 32))
    with pytest.raises(
        SystemExit, match=r"f\.yml: model_ensemble has no setting 'member'.*members"
    ):
        EnsembleSettings.from_value({"member": 3}, "f.yml")
    with pytest.raises(SystemExit, match=r"model_ensemble\.members must be at least 1, got 0"):
        EnsembleSettings.from_value({"members": 0}, "f.yml")
    with pytest.raises(SystemExit, match=r"model_ensemble\.history must be like 2, got 1\.5"):
        EnsembleSettings.from_value({"history": 1.5}, "f.yml")
    with pytest.raises(SystemExit, match=r"quorum must be a share between 0 and 1"):
        EnsembleSettings.from_value({"quorum": 2}, "f.yml")
    with pytest.raises(SystemExit, match=r"must be true or a mapping"):
        EnsembleSettings.from_value([1], "f.yml")


def test_a_hyperparameter_file_turns_ppo_into_model_ensemble_ppo_and_refuses_it_for_sac(
    tmp_path,
):
    path = tmp_path / "me.yml"
    path.write_text("gymprecice/JetCylinderFast-v0:\n  model_ensemble:\n    updates: 2\n")
    keys = ("gymprecice/JetCylinderFast-v0",)
    params = hp.resolve("ppo", hp.load_hyperparams_file(path, "ppo", keys), {})
    assert params["model_ensemble"]["updates"] == 2
    assert params["model_ensemble"]["members"] == EnsembleSettings().members
    assert hp.algorithm_class("ppo", params) is ModelEnsemblePPO
    assert "model_ensemble" not in hp.model_kwargs(params)
    with pytest.raises(SystemExit, match=r"me\.yml: model_ensemble is model-ensemble PPO's"):
        hp.load_hyperparams_file(path, "sac", keys)


# -- recorded transitions ------------------------------------------------------------------


class _Counter(gym.Env):
    """obs = [k, 10 * action of the step before]; reward = -k; episodes of ``length``."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (2,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, length: int = 5) -> None:
        self.length = length
        self.k = 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.k = 0
        return np.array([0.0, 0.0], np.float32), {}

    def step(self, action):
        self.k += 1
        obs = np.array([self.k, 10.0 * float(action[0])], np.float32)
        return obs, -float(self.k), False, self.k >= self.length, {}


def _recorded(steps: int, n_envs: int = 2, length: int = 5) -> TransitionRecorder:
    recorder = TransitionRecorder(DummyVecEnv([lambda: _Counter(length)] * n_envs))
    recorder.reset()
    for i in range(steps):
        recorder.step(np.full((n_envs, 1), 0.1 * (i % 3), np.float32))
    return recorder


def test_recorder_keeps_raw_transitions_per_episode_and_a_resume_gets_them_back(tmp_path):
    recorder = _recorded(steps=7)
    segments = recorder.segments()
    # two envs: one finished episode of 5 each and one of 2 under way
    assert sorted(len(s) for s in segments) == [2, 2, 5, 5]
    assert recorder.transitions == 14
    finished = next(s for s in segments if len(s) == 5)
    obs, actions, rewards = finished.arrays()
    assert obs[:, 0].tolist() == [0, 1, 2, 3, 4, 5]  # the terminal observation ends it
    assert rewards.tolist() == [-1, -2, -3, -4, -5]
    assert np.allclose(obs[1:, 1], 10 * actions[:, 0])

    recorder.save(tmp_path / "t.npz")
    again = TransitionRecorder(DummyVecEnv([_Counter]))
    assert again.load(tmp_path / "t.npz") == 14
    restored = sorted((s.arrays() for s in again.segments()), key=lambda a: -len(a[1]))
    original = sorted((s.arrays() for s in segments), key=lambda a: -len(a[1]))
    for got, want in zip(restored, original):
        for g, w in zip(got, want):
            assert np.array_equal(g, w)


def test_windows_read_the_history_in_order_and_never_across_an_episode():
    segment = Segment(
        obs=[np.array([float(k)]) for k in range(4)],
        actions=[np.array([10.0 + k]) for k in range(3)],
        rewards=[100.0, 101.0, 102.0],
    )
    x, y = windows([segment, Segment(obs=[np.zeros(1)] * 2, actions=[np.zeros(1)], rewards=[0])], 2)
    # steps t = 1, 2 of the first episode; the second (one step) has no two-step history
    assert x.tolist() == [[0, 1, 10, 11], [1, 2, 11, 12]]
    assert y.tolist() == [[1, 101], [1, 102]]


# -- the ensemble and its env --------------------------------------------------------------


def _linear_flow(episodes: int, steps: int, seed: int) -> list[Segment]:
    """o' = R o + b a (a damped rotation, the shedding's caricature), reward = -o0^2 - a^2."""
    rng = np.random.default_rng(seed)
    angle = 0.3
    rot = 0.97 * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    b = np.array([0.0, 0.5])
    segments = []
    for _ in range(episodes):
        o = rng.normal(size=2)
        seg = Segment(obs=[o.astype(np.float32)])
        for _ in range(steps):
            a = rng.uniform(-1, 1, size=1)
            seg.actions.append(a.astype(np.float32))
            seg.rewards.append(float(-(o[0] ** 2) - a[0] ** 2))
            o = rot @ o + b * a[0]
            seg.obs.append(o.astype(np.float32))
        segments.append(seg)
    return segments


def test_the_ensemble_learns_a_known_flow_far_better_than_holding_it_still():
    settings = EnsembleSettings(members=3, history=1, hidden=(32, 32), epochs=200, patience=20)
    ensemble = EnvironmentEnsemble(settings, obs_dim=2, act_dim=1, seed=0)
    report = ensemble.fit(_linear_flow(episodes=30, steps=40, seed=1))
    assert report.transitions == 1200 and len(report.validation_loss) == 3

    test = _linear_flow(episodes=5, steps=40, seed=2)
    x, y = windows(test, 1)
    obs, act = x[:, None, :2], x[:, None, 2:]
    for member in range(3):
        nxt, reward = ensemble.predict(np.full(len(x), member), obs, act)
        truth = obs[:, 0, :] + y[:, :2]
        still = np.mean((obs[:, 0, :] - truth) ** 2)
        assert np.mean((nxt - truth) ** 2) < 0.05 * still, member
        assert np.mean((reward - y[:, 2]) ** 2) < 0.1 * np.var(y[:, 2]), member


def test_model_env_starts_from_recorded_flow_truncates_at_its_horizon_and_stays_in_range():
    settings = EnsembleSettings(members=2, history=2, hidden=(8,), epochs=2)
    segments = _linear_flow(episodes=4, steps=10, seed=3)
    ensemble = EnvironmentEnsemble(settings, obs_dim=2, act_dim=1, seed=0)
    ensemble.fit(segments)
    space = gym.spaces.Box(-np.inf, np.inf, (2,), np.float32)
    actions = gym.spaces.Box(-1, 1, (1,), np.float32)
    env = ModelVecEnv(ensemble, space, actions, 3, seed=0, trajectories=2)
    assert env.num_envs == 4 and env._members.tolist() == [0, 1, 0, 1]
    with pytest.raises(RuntimeError, match=r"use\(segments\)"):
        env.reset()
    env.use(segments)
    recorded = {tuple(o) for s in segments for o in s.arrays()[0]}
    first = env.reset()
    assert first.shape == (4, 2) and all(tuple(o) in recorded for o in first)
    low, high = env._bounds
    for step in range(3):
        obs, rewards, dones, infos = env.step(np.ones((4, 1), np.float32))
        assert np.all(obs >= low) and np.all(obs <= high)
        assert rewards.shape == (4,)
        last = step == 2
        assert dones.tolist() == [last] * 4
        assert all(info["TimeLimit.truncated"] == last for info in infos)
    assert all("terminal_observation" in info for info in infos)
    assert all(tuple(o) in recorded for o in obs)  # the next episode starts from the record
    # every reset until the next use() starts where the first did: rollouts compare policies
    assert np.array_equal(env.reset(), first)
    env.use(segments)
    assert not np.array_equal(env.reset(), first)


# -- the algorithm -------------------------------------------------------------------------


def test_model_based_updates_add_ppo_updates_but_only_cfd_actions_count(tmp_path):
    recorder = TransitionRecorder(DummyVecEnv([lambda: _Counter(8)] * 2))
    common = {"n_steps": 8, "batch_size": 8, "n_epochs": 1, "seed": 0}
    model = ModelEnsemblePPO("MlpPolicy", recorder, **common)
    settings = EnsembleSettings(
        members=3, updates=2, trajectories=2, hidden=(8,), epochs=2, quorum=0.0
    )
    assert model.attach(settings, recorder, tmp_path / "t.npz") == 0
    model.learn(48)
    assert model.num_timesteps == 48  # three CFD rollouts of 2 x 8
    assert recorder.transitions == 48
    plain = PPO("MlpPolicy", DummyVecEnv([_Counter] * 2), **common)
    plain.learn(48)
    # the first rollout warms up; the next two add 2 model-based updates each
    assert model._n_updates == plain._n_updates + 2 * 2 * common["n_epochs"]
    assert model._model_env.num_envs == 6  # 2 trajectories of each of 3 members
    logged = model.logger.name_to_value
    assert logged["model/updates"] == 2
    assert logged["train/n_updates"] == model._n_updates
    assert model.rollout_buffer.n_envs == 2  # the CFD buffer is back
    assert model._last_obs.shape == (2, 2)
    with np.load(tmp_path / "t.npz") as data:
        assert len(data["actions"]) == 48


def test_model_ensemble_refuses_an_env_whose_observation_is_not_a_flat_box(tmp_path):
    class _Pixels(_Counter):
        observation_space = gym.spaces.Box(0, 1, (2, 2), np.float32)

        def reset(self, *, seed=None, options=None):
            return np.zeros((2, 2), np.float32), {}

    recorder = TransitionRecorder(DummyVecEnv([_Pixels]))
    model = ModelEnsemblePPO("MlpPolicy", recorder, n_steps=8, batch_size=8)
    with pytest.raises(ValueError, match=r"flat Box observation space"):
        model.attach(EnsembleSettings(), recorder, tmp_path / "t.npz")
