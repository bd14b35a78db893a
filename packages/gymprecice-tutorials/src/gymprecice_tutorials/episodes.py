"""What the tutorials' episodes share: their timing checks and their reset options.

Every tutorial that keeps a few held-out episode starts (gusts, inflow steps) reads its
``split``/``start`` reset options the same way, and the flap tutorials time their
episodes in whole actions, so one function checks each and one error names the fix.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["episode_timing", "read_split"]


def read_split(
    options: Mapping[str, Any] | None, seed: int | None, held_out: int, noun: str
) -> tuple[str, int | None]:
    """The episode's split and the seed (or held-out index) that picks its start.

    ``options["split"]`` is ``"train"`` (the default) or ``"eval"``; ``options["start"]``,
    when given, is an index into the ``held_out`` held-out ``noun`` (e.g. ``"gusts"``) and
    takes the place of ``seed``.
    """
    split = (options or {}).get("split", "train")
    if split not in ("train", "eval"):
        raise ValueError(f"split must be 'train' or 'eval', got {split!r}")
    start = (options or {}).get("start")
    if start is not None and not (
        isinstance(start, int) and not isinstance(start, bool) and 0 <= start < held_out
    ):
        raise ValueError(
            f"reset option start={start!r}: {held_out} held-out {noun}, use 0 to {held_out - 1}"
        )
    return split, seed if start is None else start


def episode_timing(
    action_time: float, episode_time: float, settle_time: float
) -> tuple[float, float]:
    """``(episode_time, settle_time)`` as floats, each checked to be a positive whole
    number of actions (``action_time`` s)."""
    for name, value in (("episode_time", episode_time), ("settle_time", settle_time)):
        steps = value / action_time
        if not math.isfinite(value) or value <= 0 or abs(steps - round(steps)) > 1e-9:
            raise ValueError(
                f"{name} must be a positive multiple of {action_time} s (one action), got {value}"
            )
    return float(episode_time), float(settle_time)
