"""The validation score of an env with a physical reference: the settled fraction of its floor.

The benchmark and ``time-to-floor`` judge a cylinder by the fraction of its drag floor
that the settled mean drag reaches; the model a training run keeps must be chosen on that
same number, from the validation starts, over episodes long enough to settle.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.plugin.card import EnvCard, Reference
from gymprecice_lab.common.settled_score import UNSETTLED_SCORE, SettledFloorScore
from gymprecice_lab.rollouts.records import floor_metrics
from gymprecice_lab.training.validation_score import settled_reference, validation_episode_time

FLOOR = Reference(metric="Cd", uncontrolled=3.0, floor=2.0, settle_time=0.5, label="drag floor")


class _Drag(gym.Env):
    """Actions of 0.25 s from t = 1 s whose drag is given; ends after ``len(drag)``."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,))
    action_space = gym.spaces.Box(-1.0, 1.0, (1,))

    def __init__(self, drag, terminate_at=None):
        self.drag, self.terminate_at = list(drag), terminate_at

    def reset(self, *, seed=None, options=None):
        self.k = 0
        return np.zeros(1, np.float32), {"time": 1.0}

    def step(self, action):
        value, self.k = self.drag[self.k], self.k + 1
        info = {"time": 1.0 + 0.25 * self.k, "metrics": {"Cd": value}}
        terminated = self.k == self.terminate_at
        return np.zeros(1, np.float32), -value, terminated, self.k == len(self.drag), info


def _return(env):
    env.reset()
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        total, done = total + reward, terminated or truncated
    return total


def test_the_return_is_the_settled_fraction_of_the_floor_as_evaluation_computes_it():
    drag = [3.0, 2.9, 2.4, 2.2, 2.3, 2.1]  # the first action ends inside the transient
    rows = [{"time": 1.0 + 0.25 * (k + 1), "Cd": v} for k, v in enumerate(drag)]
    expected = floor_metrics([], 1.0, FLOOR, rows)["settled_floor_fraction"]
    assert _return(SettledFloorScore(_Drag(drag), FLOOR)) == pytest.approx(expected)
    assert expected == pytest.approx(FLOOR.fraction(np.mean(drag[1:])))


def test_an_episode_that_ends_before_it_settles_scores_below_no_control():
    env = SettledFloorScore(_Drag([2.0, 2.0, 2.0, 2.0], terminate_at=1), FLOOR)
    assert _return(env) == UNSETTLED_SCORE < FLOOR.fraction(FLOOR.uncontrolled)


def test_only_a_reference_whose_transient_the_env_can_outlast_changes_the_score():
    assert settled_reference(EnvCard()) is None
    assert settled_reference(EnvCard(reference=FLOOR)) is None  # episode length is fixed
    assert settled_reference(EnvCard(reference=FLOOR, episode_time=True)) == FLOOR
    no_transient = Reference(metric="Cd", uncontrolled=3.0, floor=2.0)
    assert settled_reference(EnvCard(reference=no_transient)) == no_transient
    assert validation_episode_time(FLOOR, 2.0) == 2.5


def test_the_jet_keeps_the_model_best_on_settled_drag_over_longer_episodes(tmp_path):
    """A short SAC run of the jet cylinder's training case on the test double: its
    validation episodes run the 2 s transient and one training episode more, and the kept
    model's record names the settled fraction of the drag floor as its score, the
    validation with the highest one."""
    from gymprecice.tools.cli import main
    from gymprecice_tutorials.environments import fast_cylinder_floor

    (tmp_path / "sac.yml").write_text(
        "gymprecice/JetCylinderFast-v0:\n  learning_starts: 4\n  batch_size: 8\n  net: [16, 16]\n"
    )
    status = main(
        [
            "train",
            "jet-cylinder-fast",
            "--double",
            "--episode-time",
            "0.25",
            "--algo",
            "sac",
            "--hyperparams",
            str(tmp_path / "sac.yml"),
            "--timesteps",
            "20",
            "--checkpoint-every",
            "10",
            "--vec-env",
            "dummy",
            "--no-progress-bar",
            "--out",
            str(tmp_path / "run"),
        ]
    )
    assert status == 0
    record = json.loads((tmp_path / "run" / "eval" / "best.json").read_text())
    floor = fast_cylinder_floor()
    assert record["score"] == f"settled fraction of the {floor.label}"
    assert record["episode_time"] == pytest.approx(floor.settle_time + 0.25)
    lengths = np.load(tmp_path / "run" / "eval" / "evaluations.npz")["ep_lengths"]
    assert (lengths == round((floor.settle_time + 0.25) / 0.025)).all()
    results = np.load(tmp_path / "run" / "eval" / "evaluations.npz")["results"]
    assert record["mean_return"] == pytest.approx(results.mean(axis=1).max(), abs=1e-5)
    assert -1.0 < record["mean_return"] < 1.5  # a fraction of the floor, not a return


def test_a_run_resumed_under_another_score_does_not_compare_a_return_with_a_fraction(tmp_path):
    """A jet run whose kept model was chosen on the return (9.7), resumed by a gymprecice
    that scores the settled fraction of the floor (about 1 at best), must not keep the
    old model for ever: its validations start afresh. One with the same score resumes its
    best."""
    import math

    from gymprecice_lab.common.registered_env import find_lab_env
    from gymprecice_lab.training.validation import eval_callback

    env = find_lab_env("jet-cylinder-fast")
    kwargs = {"double": True, "episode_time": 0.25, "run_root": str(tmp_path / "envs")}
    (tmp_path / "eval").mkdir()
    best = tmp_path / "eval" / "best.json"
    for score, expected in (
        ("mean validation return", -math.inf),
        ("settled fraction of the drag floor", 9.7),
    ):
        best.write_text(json.dumps({"mean_return": 9.7, "timesteps": 800, "score": score}))
        callback = eval_callback(env, tmp_path, kwargs, 1, 10, None, 0, False)
        try:
            assert callback.best_mean_reward == expected
        finally:
            callback.eval_env.close()
