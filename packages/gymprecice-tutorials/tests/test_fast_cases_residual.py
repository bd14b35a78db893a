"""The fast cylinders' ``base_feedback``: the lift-feedback law under the agent's action.

On the test double: with an agent that does nothing, an env with the law underneath runs
exactly what the lab's feedback baseline runs on the plain env, and an agent's action is
added to the law's, clipped to the actuator's bound.
"""

from __future__ import annotations

import numpy as np
import pytest

from gymprecice.learners.feedback import FeedbackController
from gymprecice_tutorials.fast_cases import JetCylinderFastEnv, RotatingCylinderFastEnv

LAW = {"gain": -1.0, "delay": 2}
EPISODE = 0.2  # 8 actions: the law acts from the third


@pytest.fixture(autouse=True)
def _light_subprocesses(monkeypatch):
    """The coupling worker and the partner need no plugins (see test_envs.py)."""
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")


def _episode(env, actions) -> list[dict]:
    """One episode from the first held-out start; each step's info."""
    try:
        env.reset(seed=0, options={"split": "eval", "start": 0})
        infos, truncated = [], False
        while not truncated:
            *_, truncated, info = env.step(actions(infos))
            infos.append(info)
        return infos
    finally:
        env.close()


@pytest.mark.parametrize("cls", [JetCylinderFastEnv, RotatingCylinderFastEnv])
def test_an_agent_doing_nothing_on_the_law_is_the_lab_s_feedback_baseline(cls, tmp_path):
    plain = cls(double=True, episode_time=EPISODE, run_root=tmp_path / "plain")
    law = FeedbackController(plain.action_space, "Cl", LAW["gain"], LAW["delay"])
    law.reset()

    def feedback(infos):
        if infos:
            law.observe(infos[-1])
        return law(None, 0.0)

    baseline = _episode(plain, feedback)
    residual = _episode(
        cls(double=True, episode_time=EPISODE, base_feedback=LAW, run_root=tmp_path / "law"),
        lambda infos: np.zeros(1, np.float32),
    )

    def column(infos, key):
        return [info[key][0] if isinstance(info[key], list) else info[key] for info in infos]

    assert column(residual, "action") == pytest.approx(column(baseline, "action"))
    assert column(residual, "Cd") == pytest.approx(column(baseline, "Cd"))
    assert column(residual, "base_action") == pytest.approx(column(baseline, "action"))
    # the law acts: zero until its delay has passed, then the lift fed back
    assert residual[0]["base_action"] == [0.0] and any(column(residual, "base_action"))


def test_the_agent_s_action_adds_to_the_law_s_within_the_bound(tmp_path):
    env = JetCylinderFastEnv(
        double=True, episode_time=EPISODE, base_feedback=LAW, run_root=tmp_path / "runs"
    )
    bound = float(env.action_space.high[0])
    pushes = [0.25 * bound] * 4 + [bound] * 4
    infos = _episode(env, lambda infos: np.array([pushes[len(infos)]], np.float32))
    assert infos[0]["action"][0] == pytest.approx(0.25 * bound, rel=1e-5)  # before the law acts
    for push, info in zip(pushes, infos, strict=True):
        wanted = np.clip(info["base_action"][0] + push, -bound, bound)  # the sum, clipped
        assert info["action"][0] == pytest.approx(wanted, rel=1e-5)
    assert any(info["action"][0] == pytest.approx(bound) for info in infos[4:])  # clipped


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ({"gain": -1, "delay": 1.5}, "delay is a whole number"),
        ({"gain": "big"}, "gain must be a finite number"),
        ({"gain": -1, "dealy": 6}, 'base_feedback is {"gain"'),
        ([-1, 6], 'base_feedback is {"gain"'),
    ],
)
def test_a_wrong_law_is_refused_before_any_case_is_written(setting, message, tmp_path):
    with pytest.raises(ValueError, match=message):
        JetCylinderFastEnv(double=True, base_feedback=setting, run_root=tmp_path / "runs")
    assert not (tmp_path / "runs").exists()
