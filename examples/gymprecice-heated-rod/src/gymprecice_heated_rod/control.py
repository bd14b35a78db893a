"""The rod's classical controller: a PI law on the mean temperature, as a lab feedback law.

Every heater gets the same heat::

    heat = 24 K/s - kp e - I,    I <- clip(I + ki e dt)

with ``e`` the mean sensed temperature minus the setpoint (the mean of the observation),
``dt`` the action time (0.05 s) and the integral clipped so the heat stays within
``[0, 50]`` K/s (no wind-up). :data:`PI_LAW` is the family ``gymprecice sweep`` and
``gymprecice benchmark`` tune (the env's lab card names it), over its grid of gains or
``--feedback-grid "kp=100,300;ki=0,1500"``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from gymprecice.card import FeedbackLaw

__all__ = ["PI_LAW", "PIController"]

ACTION_TIME = 0.05
HEAT_RANGE = (0.0, 50.0)
REFERENCE_HEAT = 24.0


class PIController:
    """``heat = 24 - kp e - I`` on every heater (see the module docstring)."""

    def __init__(self, kp: float, ki: float) -> None:
        self.kp, self.ki = float(kp), float(ki)
        self.integral = 0.0

    def reset(self) -> None:
        self.integral = 0.0

    def __call__(self, obs: np.ndarray, t: float | None = None) -> np.ndarray:
        error = float(np.mean(obs))
        low, high = (REFERENCE_HEAT - h for h in reversed(HEAT_RANGE))
        self.integral = float(
            np.clip(self.integral + self.ki * error * ACTION_TIME, low, high)
        )
        heat = np.clip(
            REFERENCE_HEAT - self.kp * error - self.integral, *HEAT_RANGE
        )
        return np.full(3, heat, dtype=np.float32)


def _build(space: Any, settings: Mapping[str, float]) -> PIController:
    return PIController(settings["kp"], settings["ki"])


#: the rod's feedback law for the lab: two gains a side, four controllers to sweep
PI_LAW = FeedbackLaw(
    name="pi",
    summary="heat = 24 K/s - kp e - I, I <- clip(I + ki e dt), e the mean temperature error",
    grid=(("kp", (100.0, 300.0)), ("ki", (0.0, 1500.0))),
    build=_build,
)
