"""An episode's return as the fraction of a reference's floor it reaches once settled.

:class:`SettledFloorScore` wraps an env so that an episode's return is the number
``time-to-floor`` and the benchmark judge a cylinder by: the fraction of its drag floor
(:class:`gymprecice.card.Reference`) that the mean of the reference's metric over the
settled actions reaches, computed as
:func:`gymprecice_lab.rollouts.records.floor_metrics` computes it. The model a training
run keeps is chosen on it (:mod:`gymprecice_lab.training.validation_score`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.plugin.card import Reference

__all__ = ["UNSETTLED_SCORE", "SettledFloorScore"]

#: the score of an episode that ended before any settled action (a diverged solver):
#: worse than no control at all, which scores 0
UNSETTLED_SCORE = -1.0


class SettledFloorScore(gym.Wrapper):
    """Rewards 0 on every step but the last, which gets the episode's score: the fraction
    of the reference's floor that the mean of its metric over the settled actions (those
    ending ``settle_time`` or more after the reset) reaches. The episode's return is then
    that fraction, which SB3's ``EvalCallback`` averages over the validation starts."""

    def __init__(self, env: gym.Env, reference: Reference) -> None:
        super().__init__(env)
        self.reference = reference
        self._t0 = 0.0
        self._settled: list[float] = []

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._t0 = float(info.get("time", 0.0))
        self._settled = []
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, _, terminated, truncated, info = self.env.step(action)
        value = _metric(info, self.reference.metric)
        time = float(info.get("time", 0.0))
        if value is not None and time >= self._t0 + self.reference.settle_time - 1e-9:
            self._settled.append(value)
        reward = 0.0
        if terminated or truncated:
            reward = (
                self.reference.fraction(float(np.mean(self._settled)))
                if self._settled
                else UNSETTLED_SCORE
            )
        return obs, reward, terminated, truncated, info


def _metric(info: Mapping[str, Any], name: str) -> float | None:
    value = info.get("metrics", {}).get(name)
    if value is None:
        return None
    value = float(value)
    return value if np.isfinite(value) else None
