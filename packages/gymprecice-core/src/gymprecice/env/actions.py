"""Spread one RL action over the preCICE time windows of one env step.

Flow-control papers act every few dozen solver steps and change the actuator smoothly in
between, because a jump in jet velocity is a numerical shock. Each peer re-implements that
by overriding ``step``; here it is one configurable object:

* ``hold``: the new action in every window (a zero-order hold);
* ``ramp``: a straight line from the previous action to the new one, reaching it in the
  last window (Rabault et al. 2019, Gym-preCICE's ``_smooth_step``);
* ``cosine``: the same path eased by a half cosine, so the actuator also starts and ends
  each step at rest: its rate of change never jumps at a step boundary. That matters for
  incompressible flow, whose pressure answers a jump in the actuator's acceleration at
  once (a ``ramp`` of full jet strength moves the lift coefficient by ~3 in one solver
  step);
* ``filter``: a first-order low-pass, ``a_k = a_{k-1} + alpha (action - a_{k-1})`` per
  window, continuing across steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: the schemes, as ``actions.scheme`` of ``gymprecice-config.json`` names them
SCHEMES = ("hold", "ramp", "cosine", "filter")


@dataclass
class ActionSchedule:
    scheme: str = "hold"
    windows: int = 1
    filter_alpha: float = 0.1
    _current: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.scheme not in SCHEMES:
            raise ValueError(
                f"unknown action scheme {self.scheme!r}; use one of {', '.join(SCHEMES)}"
            )
        if self.windows < 1:
            raise ValueError("an action must span at least one time window")
        if not 0.0 < self.filter_alpha <= 1.0:
            raise ValueError("filter_alpha must be in (0, 1]")

    def start(self, initial_action: np.ndarray) -> None:
        """Begin an episode from the actuator state ``initial_action``."""
        self._current = np.array(initial_action, dtype=float, copy=True)

    @property
    def current(self) -> np.ndarray | None:
        """The value applied in the most recent window."""
        return self._current

    def spread(self, action: np.ndarray, windows: int | None = None) -> list[np.ndarray]:
        """Per-window values for ``action`` over ``windows`` windows (default: all)."""
        n = self.windows if windows is None else windows
        target = np.asarray(action, dtype=float)
        previous = self._current if self._current is not None else target
        if n <= 0:
            return []
        if self.scheme == "hold":
            values = [target.copy() for _ in range(n)]
        elif self.scheme in ("ramp", "cosine"):
            fractions = np.arange(1, self.windows + 1)[:n] / self.windows
            if self.scheme == "cosine":
                fractions = (1.0 - np.cos(np.pi * fractions)) / 2.0
            values = [previous + (target - previous) * f for f in fractions]
        else:
            values = []
            value = previous
            for _ in range(n):
                value = value + self.filter_alpha * (target - value)
                values.append(value)
        self._current = values[-1]
        return values
