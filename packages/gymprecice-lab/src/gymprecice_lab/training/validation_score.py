"""What a validation scores: the fraction of the floor once settled, where an env has one.

A training run keeps the model best on its validation starts
(:mod:`gymprecice_lab.training.validation`). By default the score is the mean return of a
training-length episode. For an env whose lab card declares a physical ``reference`` (a
cylinder's drag floor) that is the wrong question: the benchmark and ``time-to-floor``
judge a controller by the reference's metric *once settled*, after the card's
``settle_time`` of transient, and the reward is not that metric (Rabault's reward charges
the lift too, and a 2 s training episode is mostly transient). On the jet cylinder, two
runs' checkpoints at 2,400 actions took 99.5 and 100.5 % of the drag floor once settled,
their final models 87 and 89 %: the last actions traded drag for less lift, as the
reward asks (docs/benchmark.md).

So for such an env every validation episode runs the transient and then one training
episode more (:func:`validation_episode_time`), and :class:`SettledFloorScore` makes the
episode's return the fraction of the floor that the settled mean of the metric reaches,
the same number ``time-to-floor`` reports, computed the same way
(:func:`gymprecice_lab.rollouts.records.floor_metrics` reads the metric of each action from
``info["metrics"]`` and keeps the actions that end after the transient). SB3's
``EvalCallback`` then keeps the model best on that, unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.card import EnvCard, Reference

__all__ = ["SettledFloorScore", "score_name", "settled_reference", "validation_episode_time"]

#: the score of an episode that ended before any settled action (a diverged solver):
#: worse than no control at all, which scores 0
UNSETTLED_SCORE = -1.0


def settled_reference(card: EnvCard) -> Reference | None:
    """The card's reference when validation can score it: declared, and either with no
    transient or on an env whose episode length can be set (``episode_time``)."""
    reference = card.reference
    if reference is None or (reference.settle_time > 0 and not card.episode_time):
        return None
    return reference


def validation_episode_time(reference: Reference, episode_time: float) -> float:
    """The transient the reference leaves out, then one training episode of settled flow."""
    return reference.settle_time + episode_time


def score_name(reference: Reference | None) -> str:
    """How the kept model's record names its score."""
    if reference is None:
        return "mean validation return"
    return f"settled fraction of the {reference.label}"


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
