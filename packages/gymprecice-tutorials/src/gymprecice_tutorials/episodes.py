"""What the tutorials' episodes share: their timing checks and their reset options.

Every tutorial that keeps a few held-out episode starts (gusts, inflow steps) reads its
``split``/``start`` reset options the same way, and the flap tutorials time their
episodes in whole actions, so one function checks each and one error names the fix.

Three splits: ``"train"`` draws a start from the seed; ``"eval"`` takes a held-out start,
which judges a controller; ``"validation"`` takes a validation start, which chooses among
models (the model a training run keeps). Held-out and validation starts are fixed lists,
disjoint from each other and off every grid that training draws from, so neither is ever
trained on and the starts that judge a controller never chose it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

__all__ = ["SPLITS", "episode_timing", "fixed_start", "read_split"]

#: the ``split`` reset option's values
SPLITS = ("train", "eval", "validation")

T = TypeVar("T")


def read_split(
    options: Mapping[str, Any] | None,
    seed: int | None,
    held_out: int,
    noun: str,
    validation: int = 0,
) -> tuple[str, int | None]:
    """The episode's split and the seed (or start index) that picks its start.

    ``options["split"]`` is ``"train"`` (the default), ``"eval"`` or ``"validation"``;
    ``options["start"]``, when given, is an index into the split's fixed starts (the
    ``held_out`` held-out or ``validation`` validation ``noun``, e.g. ``"gusts"``) and
    takes the place of ``seed``.
    """
    split = (options or {}).get("split", "train")
    if split not in SPLITS:
        raise ValueError(f"split must be 'train', 'eval' or 'validation', got {split!r}")
    count, kind = (validation, "validation") if split == "validation" else (held_out, "held-out")
    if split == "validation" and not validation:
        raise ValueError(f"reset option split='validation': this env has no validation {noun}")
    start = (options or {}).get("start")
    if start is not None and not (
        isinstance(start, int) and not isinstance(start, bool) and 0 <= start < count
    ):
        raise ValueError(
            f"reset option start={start!r}: {count} {kind} {noun}, use 0 to {count - 1}"
        )
    return split, seed if start is None else start


def fixed_start(
    split: str, index: int | None, held_out: Sequence[T], validation: Sequence[T]
) -> T | None:
    """The fixed start of an ``"eval"`` or ``"validation"`` episode (``index`` modulo their
    number, 0 when ``None``); ``None`` for a training episode, whose start is drawn."""
    if split == "eval":
        return held_out[(index or 0) % len(held_out)]
    if split == "validation":
        return validation[(index or 0) % len(validation)]
    return None


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
