"""Robustness wrappers: seeded, with the semantics their names promise."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.learners.robustness import (
    ActuationDelay,
    ObservationDropout,
    SensorNoise,
    parse_wrap_option,
    wrap,
)
from gymprecice.plugin.errors import ConfigError


class Echo(gym.Env):
    """Observation: the constant ``[1, -2, 4]``; ``info["applied"]``: the action received."""

    observation_space = gym.spaces.Box(-10, 10, shape=(3,), dtype=np.float64)
    action_space = gym.spaces.Box(-1, 1, shape=(1,), dtype=np.float32)
    BASE = np.array([1.0, -2.0, 4.0])

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return self.BASE.copy(), {}

    def step(self, action):
        return self.BASE.copy(), 0.0, False, False, {"applied": np.asarray(action).copy()}


def _run(env, seed, steps=5, actions=None):
    obs, _ = env.reset(seed=seed)
    seen, applied = [obs], []
    for i in range(steps):
        action = np.array([0.1 * (i + 1)], dtype=np.float32) if actions is None else actions[i]
        obs, _, _, _, info = env.step(action)
        seen.append(obs)
        applied.append(info["applied"])
    return np.array(seen), np.array(applied)


SPEC = {
    "sensor_noise": {"std": 0.1},
    "action_noise": {"std": 0.05},
    "dropout": {"p": 0.3},
    "delay": {"steps": 1},
}


def test_the_same_seed_gives_the_same_noise_and_another_seed_other_noise():
    a = _run(wrap(Echo(), SPEC), seed=3)
    b = _run(wrap(Echo(), SPEC), seed=3)
    c = _run(wrap(Echo(), SPEC), seed=4)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])
    # reseeding the same wrapper replays its noise
    env = wrap(Echo(), SPEC)
    first, second = _run(env, seed=7), _run(env, seed=7)
    np.testing.assert_array_equal(first[0], second[0])


def test_relative_sensor_noise_scales_with_the_value_and_absolute_does_not():
    env = SensorNoise(Echo(), 0.1, "relative", seed=0)
    samples = np.array([env.observation(Echo.BASE) for _ in range(4000)])
    np.testing.assert_allclose(samples.mean(axis=0), Echo.BASE, atol=0.02)
    np.testing.assert_allclose(samples.std(axis=0), 0.1 * np.abs(Echo.BASE), rtol=0.1)
    env = SensorNoise(Echo(), 0.1, "absolute", seed=0)
    samples = np.array([env.observation(Echo.BASE) for _ in range(4000)])
    np.testing.assert_allclose(samples.std(axis=0), [0.1, 0.1, 0.1], rtol=0.1)


def test_the_delay_hands_the_env_the_action_of_k_steps_ago():
    actions = [np.array([v], dtype=np.float32) for v in (0.1, 0.2, 0.3, 0.4)]
    _, applied = _run(ActuationDelay(Echo(), 2), seed=0, steps=4, actions=actions)
    np.testing.assert_allclose(applied.ravel(), [0.0, 0.0, 0.1, 0.2])
    env = ActuationDelay(Echo(), 2)
    _run(env, seed=0, steps=4, actions=actions)
    _, applied = _run(env, seed=0, steps=1, actions=actions)  # a reset forgets the queue
    np.testing.assert_allclose(applied.ravel(), [0.0])
    _, applied = _run(ActuationDelay(Echo(), 0), seed=0, steps=2, actions=actions)
    np.testing.assert_allclose(applied.ravel(), [0.1, 0.2])


def test_action_noise_stays_within_the_action_space():
    env = wrap(Echo(), {"action_noise": {"std": 5.0}}, seed=1)
    _, applied = _run(env, seed=1, steps=50, actions=[np.array([0.9], np.float32)] * 50)
    assert applied.min() >= -1 and applied.max() <= 1 and len(np.unique(applied)) > 2


def test_dropout_holds_the_last_delivered_value_or_fills_a_constant():
    env = ObservationDropout(Echo(), 1.0, "hold", seed=0)
    first, _ = env.reset(seed=0)
    np.testing.assert_array_equal(first, Echo.BASE)  # nothing to hold yet
    np.testing.assert_array_equal(env.observation(Echo.BASE * 2), Echo.BASE)
    env = ObservationDropout(Echo(), 1.0, 0.0, seed=0)
    np.testing.assert_array_equal(env.reset()[0], [0.0, 0.0, 0.0])
    env = ObservationDropout(Echo(), 0.5, -9.0, seed=0)
    lost = np.array([env.observation(Echo.BASE) == -9.0 for _ in range(2000)])
    assert lost.mean() == pytest.approx(0.5, abs=0.05)


def test_wrappers_compose_with_a_vector_env():
    venv = gym.vector.SyncVectorEnv([lambda: wrap(Echo(), SPEC, seed=0) for _ in range(2)])
    obs, _ = venv.reset(seed=5)
    obs, *_ = venv.step(np.zeros((2, 1), dtype=np.float32))
    assert obs.shape == (2, 3) and not np.array_equal(obs[0], obs[1])  # seeds 5 and 6
    venv.close()


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        (
            {"sensor_nosie": {"std": 0.1}},
            "unknown robustness wrapper 'sensor_nosie' .*sensor_noise",
        ),
        ({"sensor_noise": {"sdt": 0.1}}, r"unknown option sensor_noise.sdt \(did you mean 'std'"),
        ({"sensor_noise": {"std": -1}}, "sensor_noise.std is -1; it must be >= 0"),
        ({"sensor_noise": {"std": 0.1, "mode": "percent"}}, "mode is 'percent'; use 'relative'"),
        ({"dropout": {"p": 1.5}}, r"dropout.p is 1.5; it must be in \[0, 1\]"),
        ({"delay": {"steps": 0.5}}, "delay.steps is 0.5; give a whole number"),
        ({"action_noise": {"std": float("nan")}}, "action_noise.std is nan; give a finite"),
    ],
)
def test_bad_options_are_refused_with_the_key_and_the_fix(spec, message):
    with pytest.raises(ConfigError, match=message):
        wrap(Echo(), spec)


def test_the_command_line_form():
    assert parse_wrap_option("sensor_noise:std=0.05,mode=absolute") == {
        "sensor_noise": {"std": 0.05, "mode": "absolute"}
    }
    assert parse_wrap_option("delay:steps=2") == {"delay": {"steps": 2}}
    with pytest.raises(ConfigError, match="is not KEY=VALUE"):
        parse_wrap_option("delay:2")
    with pytest.raises(ConfigError, match="did you mean 'dropout'"):
        parse_wrap_option("dropuot:p=0.1")
