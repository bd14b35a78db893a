"""A classical feedback law: a measured signal fed back, delayed and scaled, to the actuator.

The textbook first controller for vortex shedding behind a cylinder is proportional
feedback of the lift on the jets (or the spin), with a phase shift that makes the
forcing oppose the shedding. :class:`FeedbackController` is that law for any env with a
bounded ``Box`` action::

    a(t) = clip(centre - gain * half_range * s(t - delay))

with ``s`` one of the env's ``info["metrics"]`` (the cylinders' ``Cl``: the lift the
reward measures over the last action), ``delay`` a whole number of actions (0: the signal
the last action produced; the phase shift ``2 pi f delay * action_time`` at the shedding
frequency ``f``; zero until that many actions have been taken), ``gain`` in
fractions of the action's half range per unit of the signal and ``centre`` a fraction of
the box (0.5: its middle, zero for the cylinders). It sees what a policy could see: the
signal of actions already taken, never the coming one.

``gymprecice feedback ENV --gain G --delay D`` runs one law; ``gymprecice sweep ENV
--feedback-gains ... --feedback-delays ...`` tunes it on the held-out starts beside the
open-loop forcings.

Not every task's textbook controller is the lift fed back. An env names its own family
of classical controllers as a :class:`gymprecice.card.FeedbackLaw` (its lab card's
``feedback_law``: the heated plate's PID heater in the tutorials), with the grid of its
documented tuning; ``gymprecice sweep`` and ``benchmark`` then tune that family instead,
over ``--feedback-grid "kp=2,3;ki=25,50"`` or the law's own grid.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.plugin.card import FeedbackLaw, Grid, load_object

__all__ = ["FeedbackController", "own_law_grid"]


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


def own_law_grid(
    env_name: str, law_spec: str | None, gains: str | None, grid_text: str | None
) -> tuple[FeedbackLaw | None, Grid | None]:
    """The feedback law an env names (``law_spec``) and its grid to tune, from a command's
    ``--feedback-gains`` and ``--feedback-grid`` (``None``: not given, the law's documented
    grid; ``""``: no feedback baseline, grid ``None``). An env without a law of its own
    gives ``(None, None)``: its feedback is a signal fed back. The other kind's option is
    a ``ValueError`` rather than ignored."""
    if law_spec is None:
        if grid_text:
            raise ValueError(
                f"{env_name} has no feedback law of its own for --feedback-grid; its "
                "classical feedback is a signal fed back: --feedback-gains and "
                "--feedback-delays"
            )
        return None, None
    law = load_object(law_spec, "feedback_law")
    if gains:
        raise ValueError(
            f"{env_name}'s classical feedback is its {law.name} law "
            f"({', '.join(law.parameters)}), not a signal fed back: tune it with "
            f'--feedback-grid "{law.grid_text(law.default_grid())}" instead of '
            "--feedback-gains"
        )
    if grid_text == "":
        return law, None
    return law, law.parse_grid(grid_text or "")
