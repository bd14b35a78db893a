"""Proportional feedback of a measured signal, delayed and scaled, to a bounded actuator.

The textbook first controller for vortex shedding behind a cylinder is proportional
feedback of the lift on the jets (or the spin), with a phase shift that makes the
forcing oppose the shedding. :class:`FeedbackController` is that law for any env with a
bounded ``Box`` action::

    a(t) = clip(centre - gain * half_range * s(t - delay))

with ``s`` one of the env's ``info["metrics"]`` (the cylinders' ``Cl``: the lift the
reward measures over the last action), ``delay`` a whole number of actions (0: the signal
the last action produced; zero until that many actions have been taken), ``gain`` in
fractions of the action's half range per unit of the signal and ``centre`` a fraction of
the box (0.5: its middle). It sees what a policy could see: the signal of actions already
taken, never the coming one.

It lives in core because both sides use it: the lab runs it as a classical baseline
(``gymprecice feedback``, ``sweep``, ``benchmark``), and an env may run it under a
policy's action, so that the policy learns a residual on top of the law (the fast
cylinders' ``base_feedback``).
"""

from __future__ import annotations

from collections import deque
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["FeedbackController"]


class FeedbackController:
    """Proportional feedback of ``signal`` delayed by ``delay`` actions (see the module)."""

    def __init__(
        self,
        space: gym.Space,
        signal: str,
        gain: float,
        delay: int = 0,
        centre: float = 0.5,
    ) -> None:
        if not isinstance(space, gym.spaces.Box) or not (
            np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))
        ):
            raise TypeError(f"feedback needs a bounded Box action space, got {space}")
        if int(delay) != delay or delay < 0:
            raise ValueError(f"delay is a whole number of actions >= 0, got {delay}")
        self.space = space
        self.signal = signal
        self.gain = float(gain)
        self.delay = int(delay)
        self.centre = space.low + float(centre) * (space.high - space.low)
        self.half = (space.high - space.low) / 2.0
        self._past: deque[float] = deque()
        self.reset()

    def settings(self) -> dict[str, Any]:
        return {"signal": self.signal, "gain": self.gain, "delay": self.delay}

    def reset(self) -> None:
        """A new episode: no signal measured yet (zero until the first action's)."""
        self._past = deque([0.0] * (self.delay + 1), maxlen=self.delay + 1)

    def observe(self, info: dict[str, Any]) -> None:
        """Record the signal the last action produced (``info["metrics"][signal]``)."""
        metrics = info.get("metrics", {})
        if self.signal not in metrics:
            raise KeyError(
                f"feedback signal {self.signal!r} is not among this env's metrics "
                f"({', '.join(metrics) or 'none'}); pass --signal with one of them"
            )
        self._past.append(float(metrics[self.signal]))

    def __call__(self, obs: Any, t: float) -> np.ndarray:
        value = self.centre - self.gain * self.half * self._past[0]
        return np.clip(value, self.space.low, self.space.high).astype(self.space.dtype)
