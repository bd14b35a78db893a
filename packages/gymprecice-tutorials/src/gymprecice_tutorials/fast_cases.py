"""JetCylinderFast-v0 and RotatingCylinderFast-v0: the cylinders set up to learn in hours.

The paper's jet cylinder (Rabault et al. 2019; Gym-preCICE) needs about a thousand 2 s
episodes on its 9,795-cell PIMPLE mesh: two days on two cores. These environments train
the same controllers on the recipe ``*_fast`` (:data:`gymprecice_tutorials.recipes.FAST_TRAINING`):

* **the training case**: the coarse mesh (3,580 cells), PISO on one rank, Δt = 1e-3 s,
  one preCICE time window per action (0.025 s, the solver subcycles in it) and 1 s
  episodes (40 actions, about three shedding periods) that start from a library of eight
  developed-flow snapshots over one shedding period; every fourth is held out for
  ``evaluate`` / ``baseline`` / ``open-loop``, so training never sees the evaluation's start;
* **Rabault's reward**: ``reward_offset - <Cd> - lift_penalty |<Cl>|`` with the means over
  the last action (0.025 s), not over a shedding period: a lift that the action swings
  within a period then costs what it costs, and the reward answers the action that caused
  it; the offset is this case's own uncontrolled mean Cd, so "no control" scores about 0;
* **Rabault's actuation**: the jets' flow-rate bound is :data:`MAX_FLOW_RATE_FAST`
  (jet speed up to about 0.3 Umean, where the Gym-preCICE bound of 2.5e-4 m³/s gives jets
  three times faster than the mean flow); the rotating cylinder's spin is bounded to a
  wall speed of 0.1 Umean. Large actuators let an untrained policy shake the cylinder with
  lift swings ten times the shedding's and make the bang-bang answer the easiest to find.

``base_feedback={"gain": G, "delay": D}`` puts the classical law under the agent: the
lift fed back to the actuator (:class:`gymprecice.learners.feedback.FeedbackController`,
what ``gymprecice feedback --gain G --delay D`` runs) plus the agent's action, clipped to
the action space. A policy then learns a residual on top of the textbook controller and
starts from it (an action of 0 is the law); the best law of the training case's sweep is
``{"gain": -1, "delay": 6}`` (docs/benchmark.md). ``info["base_action"]`` is the law's
part of each action. Default ``None``: the action alone.

Everything else (observation, actuators, keyword arguments) is the parent environment's.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from gymprecice.learners.feedback import FeedbackController
from gymprecice_tutorials.jet_cylinder.environment import JetCylinderEnv
from gymprecice_tutorials.rotating_cylinder.environment import RotatingCylinderEnv

__all__ = [
    "FAST_REWARD_OFFSET",
    "MAX_FLOW_RATE_FAST",
    "MAX_OMEGA_FAST",
    "JetCylinderFastEnv",
    "RotatingCylinderFastEnv",
]

#: Jet flow-rate bound (m³/s): 2.5e-5 over the 10° jet's 8.7e-5 m² opening is 0.29 m/s,
#: 0.29 Umean (Rabault et al.'s own bound is 0.11 Umean).
MAX_FLOW_RATE_FAST = 2.5e-5
#: Spin bound (rad/s): a wall speed omega * R of 0.1 Umean.
MAX_OMEGA_FAST = 2.0
#: The training case's uncontrolled mean Cd (10 s from a held-out snapshot, docs/training.md).
FAST_REWARD_OFFSET = 3.2195
#: The reward's averaging window: one action (25 steps of 1e-3 s).
ACTION_WINDOW = 0.025


def _fast_defaults(kwargs: dict[str, Any]) -> dict[str, Any]:
    kwargs.setdefault("reward_offset", FAST_REWARD_OFFSET)
    kwargs.setdefault("averaging_window", ACTION_WINDOW)
    return kwargs


def _checked_base_feedback(base_feedback: Mapping[str, Any] | None) -> tuple[float, int] | None:
    """``base_feedback`` (``{"gain": G, "delay": D}``) as ``(gain, delay)``, checked before
    anything is written: a wrong setting is refused naming the keyword."""
    if base_feedback is None:
        return None
    if not isinstance(base_feedback, Mapping) or set(base_feedback) - {"gain", "delay"}:
        raise ValueError(
            'base_feedback is {"gain": G, "delay": D} (the lift fed back, as gymprecice '
            f"feedback --gain G --delay D), got {base_feedback!r}"
        )
    gain, delay = base_feedback.get("gain"), base_feedback.get("delay", 0)
    if isinstance(gain, bool) or not isinstance(gain, (int, float)) or not np.isfinite(gain):
        raise ValueError(f"base_feedback gain must be a finite number, got {gain!r}")
    if isinstance(delay, bool) or not isinstance(delay, int) or delay < 0:
        raise ValueError(f"base_feedback delay is a whole number of actions >= 0, got {delay!r}")
    return float(gain), delay


class _ResidualOnLiftFeedback:
    """The agent's action on top of the lift-feedback law (``base_feedback``; the module)."""

    #: the law under the agent's action (``None``: the action alone)
    base_law: FeedbackController | None = None

    def _set_base_law(self, setting: tuple[float, int] | None) -> None:
        if setting is not None:
            gain, delay = setting
            space = self.action_space  # type: ignore[attr-defined]
            self.base_law = FeedbackController(space, "Cl", gain, delay, centre=0.5)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        if self.base_law is not None:
            self.base_law.reset()
        return super().reset(seed=seed, options=options)  # type: ignore[misc]

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self.base_law is None:
            return super().step(action)  # type: ignore[misc]
        base = self.base_law(None, self.time)  # type: ignore[attr-defined]
        total = self._clip(base + self._clip(action)).astype(np.float32)  # type: ignore[attr-defined]
        obs, reward, terminated, truncated, info = super().step(total)  # type: ignore[misc]
        if "metrics" in info:  # not a step that ended in divergence
            self.base_law.observe(info)
        info["base_action"] = np.asarray(base, dtype=float).reshape(-1).tolist()
        return obs, reward, terminated, truncated, info


class JetCylinderFastEnv(_ResidualOnLiftFeedback, JetCylinderEnv):
    """:class:`JetCylinderEnv` on the training case, with Rabault's reward and jet bound."""

    recipe: ClassVar[str] = "jet_cylinder_fast"

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        max_flow_rate: float = MAX_FLOW_RATE_FAST,
        base_feedback: Mapping[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        setting = _checked_base_feedback(base_feedback)  # before any file is written
        super().__init__(options, idx, max_flow_rate=max_flow_rate, **_fast_defaults(kwargs))
        self._set_base_law(setting)


class RotatingCylinderFastEnv(_ResidualOnLiftFeedback, RotatingCylinderEnv):
    """:class:`RotatingCylinderEnv` on the training case, with Rabault's reward."""

    recipe: ClassVar[str] = "rotating_cylinder_fast"

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int = 0,
        *,
        max_omega: float = MAX_OMEGA_FAST,
        base_feedback: Mapping[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        setting = _checked_base_feedback(base_feedback)  # before any file is written
        super().__init__(options, idx, max_omega=max_omega, **_fast_defaults(kwargs))
        self._set_base_law(setting)
