"""Robustness wrappers: how well does a policy hold up when the world is less clean?

A controller trained on exact probes and instant jets meets noisy sensors, sloppy valves
and lag on a real rig. These seeded Gymnasium wrappers put such imperfections between
the agent and any env (a gymprecice :class:`~gymprecice.core.Adapter` or another), for
training under them or for testing a trained policy without retraining:

``sensor_noise``  ``{"std": 0.05, "mode": "relative" | "absolute"}``: Gaussian noise on
                  every observation value (relative: ``std`` times the value's magnitude)
``action_noise``  ``{"std": 0.1}``: Gaussian noise on the action the env receives,
                  clipped to the action space
``delay``         ``{"steps": 2}``: the env receives the action of ``steps`` steps ago
                  (the env's initial actuator state, zeros, until then)
``dropout``       ``{"p": 0.1, "fill": "hold" | number}``: each observation value is lost
                  with probability ``p``, replaced by its last delivered value (``hold``)
                  or a constant

:func:`wrap` applies a specification such as ``{"sensor_noise": {"std": 0.05}}`` in a
fixed order (action-side first, then observation-side) and refuses misspelt names, keys
and out-of-range values with the key and the fix. Each wrapper draws from its own
generator, seeded by the ``seed`` given to ``reset`` (or at construction): the same seed
gives the same noise, so a robustness study is reproducible. Wrap each env inside the
vector env's factory (``lambda: wrap(make_env(), spec)``) so each env has its own.
"""

from __future__ import annotations

import difflib
import math
import zlib
from collections import deque
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.plugin.errors import ConfigError

__all__ = [
    "WRAPPERS",
    "ActionNoise",
    "ActuationDelay",
    "ObservationDropout",
    "SensorNoise",
    "checked_spec",
    "parse_wrap_option",
    "wrap",
]


class _Seeded:
    """A generator per wrapper, reseeded by ``reset(seed=...)`` (salted by the wrapper)."""

    _salt = ""

    def _init_rng(self, seed: int | None) -> None:
        self.rng = np.random.default_rng(self._seed_for(seed))

    def _seed_for(self, seed: int | None) -> Any:
        if seed is None:
            return None
        return [int(seed), zlib.crc32(self._salt.encode())]

    def _reseed(self, seed: int | None) -> None:
        if seed is not None:
            self.rng = np.random.default_rng(self._seed_for(seed))


def _finite(value: Any, key: str, *, low: float = 0.0, high: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"robustness wrapper option {key} is {value!r}; give a finite number")
    if not low <= value <= high:
        bound = f"in [{low:g}, {high:g}]" if math.isfinite(high) else f">= {low:g}"
        raise ConfigError(f"robustness wrapper option {key} is {value!r}; it must be {bound}")
    return float(value)


class SensorNoise(_Seeded, gym.ObservationWrapper):
    """Gaussian noise on every observation value, relative to its magnitude or absolute."""

    _salt = "sensor_noise"

    def __init__(
        self, env: gym.Env, std: float, mode: str = "relative", seed: int | None = None
    ) -> None:
        super().__init__(env)
        self.std = _finite(std, "sensor_noise.std")
        if mode not in ("relative", "absolute"):
            raise ConfigError(
                f"robustness wrapper option sensor_noise.mode is {mode!r}; use 'relative' "
                "(std times each value's magnitude) or 'absolute'"
            )
        self.mode = mode
        self._init_rng(seed)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._reseed(seed)
        return super().reset(seed=seed, options=options)

    def observation(self, observation: Any) -> Any:
        values = np.asarray(observation)
        noise = self.rng.normal(0.0, self.std, size=values.shape)
        if self.mode == "relative":
            noise = noise * np.abs(values)
        return (values + noise).astype(values.dtype, copy=False)


class ActionNoise(_Seeded, gym.ActionWrapper):
    """Gaussian noise on the action the env receives, clipped to the action space."""

    _salt = "action_noise"

    def __init__(self, env: gym.Env, std: float, seed: int | None = None) -> None:
        super().__init__(env)
        self.std = _finite(std, "action_noise.std")
        self._init_rng(seed)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._reseed(seed)
        return super().reset(seed=seed, options=options)

    def action(self, action: Any) -> Any:
        values = np.asarray(action, dtype=float)
        noisy = values + self.rng.normal(0.0, self.std, size=values.shape)
        space = self.action_space
        if isinstance(space, gym.spaces.Box):
            return np.clip(noisy, space.low, space.high).astype(space.dtype)
        return noisy


class ActuationDelay(gym.ActionWrapper):
    """The env receives the action of ``steps`` steps ago (a lagging actuator)."""

    def __init__(self, env: gym.Env, steps: int) -> None:
        super().__init__(env)
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 0:
            raise ConfigError(
                f"robustness wrapper option delay.steps is {steps!r}; give a whole number of "
                "steps >= 0"
            )
        self.steps = steps
        self._pending: deque[Any] = deque()

    def _initial(self) -> Any:
        shape = getattr(self.action_space, "shape", None) or ()
        dtype = getattr(self.action_space, "dtype", None) or float
        return np.zeros(shape, dtype=dtype)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._pending = deque([self._initial()] * self.steps)
        return super().reset(seed=seed, options=options)

    def action(self, action: Any) -> Any:
        self._pending.append(action)
        return self._pending.popleft()


class ObservationDropout(_Seeded, gym.ObservationWrapper):
    """Each observation value is lost with probability ``p`` (held or filled)."""

    _salt = "dropout"

    def __init__(
        self, env: gym.Env, p: float, fill: str | float = "hold", seed: int | None = None
    ) -> None:
        super().__init__(env)
        self.p = _finite(p, "dropout.p", high=1.0)
        if fill != "hold":
            fill = _finite(fill, "dropout.fill", low=-math.inf)
        self.fill = fill
        self._last: np.ndarray | None = None
        self._init_rng(seed)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._reseed(seed)
        self._last = None
        return super().reset(seed=seed, options=options)

    def observation(self, observation: Any) -> Any:
        values = np.array(observation, copy=True)
        lost = self.rng.random(values.shape) < self.p
        if self.fill == "hold":
            # the first observation of an episode has nothing to hold: it is delivered whole
            if self._last is not None:
                values[lost] = self._last[lost]
        else:
            values[lost] = self.fill
        self._last = values.copy()
        return values


#: name -> (wrapper class, its options); :func:`wrap` applies them in this order
WRAPPERS: dict[str, tuple[type[gym.Wrapper], tuple[str, ...]]] = {
    "delay": (ActuationDelay, ("steps",)),
    "action_noise": (ActionNoise, ("std",)),
    "sensor_noise": (SensorNoise, ("std", "mode")),
    "dropout": (ObservationDropout, ("p", "fill")),
}
_SEEDED = {"action_noise", "sensor_noise", "dropout"}


def wrap(env: gym.Env, spec: Mapping[str, Mapping[str, Any]] | None, seed: int | None = None):
    """``env`` inside the wrappers ``spec`` names (see the module docstring)."""
    for name, options in checked_spec(spec).items():
        cls, _ = WRAPPERS[name]
        kwargs = dict(options)
        if name in _SEEDED:
            kwargs["seed"] = seed
        env = cls(env, **kwargs)
    return env


def checked_spec(spec: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    """``spec`` checked and in the order :func:`wrap` applies it (a ConfigError if bad)."""
    if not spec:
        return {}
    if not isinstance(spec, Mapping):
        raise ConfigError(
            f"robustness wrappers must be a mapping such as "
            f'{{"sensor_noise": {{"std": 0.05}}}}, got {spec!r}'
        )
    out: dict[str, dict[str, Any]] = {}
    for name in spec:
        if name not in WRAPPERS:
            close = difflib.get_close_matches(str(name), list(WRAPPERS), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(
                f"unknown robustness wrapper {name!r}{hint}; the wrappers are {list(WRAPPERS)}"
            )
        options = spec[name]
        if not isinstance(options, Mapping):
            raise ConfigError(
                f"robustness wrapper {name!r} takes options as a mapping, got {options!r}"
            )
        known = WRAPPERS[name][1]
        for key in options:
            if key not in known:
                close = difflib.get_close_matches(str(key), known, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ConfigError(f"unknown option {name}.{key}{hint}; {name} takes {list(known)}")
    for name in WRAPPERS:  # the fixed order: action side first
        if name in spec:
            out[name] = dict(spec[name])
    return out


def parse_wrap_option(text: str) -> dict[str, dict[str, Any]]:
    """``"sensor_noise:std=0.05,mode=absolute"`` (a ``--wrap`` argument) as a spec entry."""
    name, _, rest = text.partition(":")
    options: dict[str, Any] = {}
    for pair in filter(None, rest.split(",")):
        key, sep, value = pair.partition("=")
        if not sep:
            raise ConfigError(
                f"--wrap {text!r}: {pair!r} is not KEY=VALUE; e.g. --wrap sensor_noise:std=0.05"
            )
        options[key.strip()] = _value(value.strip())
    spec = {name.strip(): options}
    checked_spec(spec)
    return spec


def _value(text: str) -> Any:
    for convert in (int, float):
        try:
            return convert(text)
        except ValueError:
            pass
    return text
