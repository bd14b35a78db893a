"""The two flaps' classical feedback: each slot set from its own flap's tip.

A slot eases the push on its flap when it sucks and adds to it when it blows
(:mod:`gymprecice_tutorials.two_flaps.environment`). The textbook controller of a swinging
structure with such an actuator is proportional feedback of the structure's own state:

    slot_i = clip(-(kx dx_i + kv vx_i), -1, 1)

with ``dx_i`` the tip's streamwise displacement (m) and ``vx_i`` its velocity (m/s) over
the last time window, each slot fed by its own flap only. ``kx`` (1/m) sucks while the
flap is bent downstream, lowering its mean bend; ``kv`` (s/m) sucks while it moves
downstream and blows while it swings back: a force against the motion, damping. Negative
gains do the opposite; the grid holds both signs, so that the sweep, not a guess about
the sign of the slot's effect, finds the law's best point.

:data:`TIP_LAW` is that family as the two flaps' ``feedback_law`` (their lab card), run by
``gymprecice sweep`` and ``gymprecice benchmark`` like the plate's PID. Its grid: the
displacement gain at 0 and ±50 /m (the slot's whole range at a 2 cm bend, about the
flaps' mean), the velocity gain at 0, ±10 and ±30 s/m (the whole range at 10 and 3 cm/s;
the swing's peak speed is about 10 cm/s).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from gymprecice.plugin.card import FeedbackLaw

__all__ = ["TIP_LAW", "TipFeedback"]

#: where a flap's row of the joint env's observation holds its tip's dx and vx
#: (``(dx, dy, vx, vy, sx, sy, the other's dx, the other's vx, flag)``)
DX, VX = 0, 2


@dataclass
class TipFeedback:
    """Each slot from its own flap's tip: ``clip(-(kx dx + kv vx))`` (see the module)."""

    kx: float
    kv: float

    def __call__(self, obs: np.ndarray, t: float | None = None) -> np.ndarray:
        """Both slots, one row per flap as the joint env's observation (``t`` unused)."""
        rows = np.asarray(obs, dtype=np.float64).reshape(-1, 9)
        slots = -(self.kx * rows[:, DX] + self.kv * rows[:, VX])
        return np.clip(slots, -1.0, 1.0).reshape(-1, 1).astype(np.float32)


def _tip_feedback_for(space: Any, settings: Mapping[str, float]) -> TipFeedback:
    """One point of the law, for the joint env's ``(2, 1)`` action box of slots in [-1, 1]."""
    low, high = float(np.min(space.low)), float(np.max(space.high))
    if tuple(space.shape) != (2, 1) or (low, high) != (-1.0, 1.0):
        raise ValueError(
            f"the tip feedback drives the two flaps' slots, an action box (2, 1) in [-1, 1]; "
            f"the env's is {space}: run it on TwoFlapsFast-v0"
        )
    return TipFeedback(settings["kx"], settings["kv"])


#: the two flaps' classical baseline for ``gymprecice sweep`` and ``benchmark``
TIP_LAW = FeedbackLaw(
    "tip",
    "slot_i = clip(-(kx dx_i + kv vx_i)), each flap's own tip",
    (("kx", (-50, 0, 50)), ("kv", (-30, -10, 0, 10, 30))),
    _tip_feedback_for,
)
