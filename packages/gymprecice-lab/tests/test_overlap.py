"""``overlap_updates``: SAC's and TD3's gradient steps run while the envs step."""

from __future__ import annotations

import json
import shlex

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import SAC, TD3
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnvWrapper

from gymprecice_lab import hyperparams as hp
from gymprecice_lab.training.overlap import OverlappedUpdates, overlapping


class _Journal(VecEnvWrapper):
    """Writes "send" when the actions leave and "wait" when the learner waits for them."""

    def __init__(self, venv, events: list[str]):
        super().__init__(venv)
        self.events = events

    def step_async(self, actions):
        self.events.append("send")
        self.venv.step_async(actions)

    def step_wait(self):
        self.events.append("wait")
        return self.venv.step_wait()

    def reset(self):
        return self.venv.reset()


@pytest.mark.parametrize("cls", [SAC, TD3])
def test_each_update_runs_between_sending_a_step_and_waiting_for_it(cls):
    events: list[str] = []
    vec = _Journal(DummyVecEnv([lambda: gym.make("Pendulum-v1")] * 2), events)
    env = OverlappedUpdates(vec)

    class Journaled(cls):
        def train(self, gradient_steps, batch_size=64):
            events.append("train")
            super().train(gradient_steps, batch_size)

    model = overlapping(Journaled)(
        "MlpPolicy",
        env,
        learning_starts=10,
        gradient_steps=3,
        batch_size=8,
        policy_kwargs={"net_arch": [8]},
        seed=0,
    )
    model.overlap_with(env)
    model.learn(40)  # 20 steps of two envs; SB3 asks for an update after steps 6..20
    steps = events.count("send")
    assert steps == 20 and events.count("wait") == 20
    assert events.count("train") == 15  # every update SB3 asked for ran, the last one too
    assert model._n_updates == 15 * 3
    # each update ran after a step's actions left and before the learner waited for them,
    # but the last, which ran when learn ended
    body = events[:-1]
    assert events[-1] == "train"
    for i, event in enumerate(body):
        if event == "train":
            assert body[i - 1] == "send" and body[i + 1] == "wait"
    first = body.index("train")
    assert body[:first].count("send") == 7  # asked for after step 6, run during step 7


def test_plain_sb3_order_for_comparison():
    """Without the key SB3's order is unchanged: the envs wait while the learner updates."""
    events: list[str] = []
    vec = _Journal(DummyVecEnv([lambda: gym.make("Pendulum-v1")] * 2), events)

    class Journaled(SAC):
        def train(self, gradient_steps, batch_size=64):
            events.append("train")
            super().train(gradient_steps, batch_size)

    model = Journaled(
        "MlpPolicy",
        vec,
        learning_starts=10,
        gradient_steps=3,
        batch_size=8,
        policy_kwargs={"net_arch": [8]},  # the order is the question, not the network
        seed=0,
    )
    model.learn(40)
    assert events.count("train") == 15
    for i, event in enumerate(events):
        if event == "train":
            assert events[i - 1] == "wait" and (i + 1 == len(events) or events[i + 1] == "send")


def test_an_update_that_raises_raises_from_the_step_and_leaves_nothing_pending():
    env = OverlappedUpdates(DummyVecEnv([lambda: gym.make("Pendulum-v1")]))
    env.reset()

    def broken():
        raise RuntimeError("nan in the critic")

    env.defer(broken)
    with pytest.raises(RuntimeError, match="nan in the critic"):
        env.step(np.zeros((1, 1)))
    env.step_wait()  # the actions had been sent: their step is still there to collect
    env.step(np.zeros((1, 1)))  # and nothing is left to run
    env.close()


def test_the_key_is_sac_and_td3s_and_says_so(tmp_path):
    path = tmp_path / "o.yml"
    path.write_text("overlap_updates: true\n")
    params = hp.resolve("sac", hp.load_hyperparams_file(path, "sac", ()), {})
    cls = hp.algorithm_class("sac", params)
    assert issubclass(cls, SAC) and cls is not SAC
    assert issubclass(hp.algorithm_class("td3", {"overlap_updates": True}), TD3)
    assert "overlap_updates" not in hp.model_kwargs(params)
    assert hp.algorithm_class("sac", {"overlap_updates": False}) is SAC
    with pytest.raises(SystemExit, match=r"o\.yml: overlap_updates overlaps SAC's and TD3's"):
        hp.load_hyperparams_file(path, "ppo", ())
    path.write_text("overlap_updates: yes please\n")
    with pytest.raises(SystemExit, match=r"o\.yml: overlap_updates is true or false"):
        hp.load_hyperparams_file(path, "sac", ())


def test_torch_threads_is_a_whole_number_of_threads(tmp_path):
    path = tmp_path / "t.yml"
    path.write_text("torch_threads: 1\n")
    params = hp.resolve("ppo", hp.load_hyperparams_file(path, "ppo", ()), {})
    assert params["torch_threads"] == 1 and "torch_threads" not in hp.model_kwargs(params)
    import torch

    from gymprecice_lab.training.learner import learner_threads

    before = torch.get_num_threads()
    try:
        assert learner_threads(params) == 1 == torch.get_num_threads()
        torch.set_num_threads(2)
        assert learner_threads({"algo": "ppo"}) == 2  # unset: torch's own choice stands
    finally:
        torch.set_num_threads(before)
    for bad in ("0", "1.5", "true", "two"):
        path.write_text(f"torch_threads: {bad}\n")
        with pytest.raises(SystemExit, match=r"t\.yml: torch_threads is a whole number"):
            hp.load_hyperparams_file(path, "sac", ())


def test_train_overlaps_on_the_double_resumes_and_saves_a_plain_sac_model(tmp_path, gymprecice_cli):
    (tmp_path / "o.yml").write_text(
        "overlap_updates: true\ntorch_threads: 1\nlearning_starts: 16\n"
    )
    train = shlex.split(
        "train jet-cylinder-fast --double --algo sac --n-envs 2 --episode-time 0.2 "
        "--net 16,16 --batch-size 8 --normalize --hyperparams o.yml --no-progress-bar --out run"
    )
    out = gymprecice_cli(tmp_path, *train, "--timesteps", "32")
    assert "overlap_updates: each update runs while the solvers compute" in out
    run = tmp_path / "run"
    assert json.loads((run / "hyperparams.json").read_text())["overlap_updates"] is True
    model = SAC.load(run / "model.zip")  # what evaluate loads: a plain SAC
    # one gradient step per batch step of two envs after step 8, the last one included
    assert model.num_timesteps == 32 and model._n_updates == 8
    assert (run / "model_vecnormalize.pkl").is_file()
    gymprecice_cli(tmp_path, *train, "--timesteps", "48")
    assert SAC.load(run / "model.zip")._n_updates == 16
