"""An episode's start among saved states, the same way in every solver plugin.

A coupled case that starts its episodes from saved states (an OpenFOAM plugin's snapshot
time directories, a FEniCS script's saved solid state, ...) keeps them in a train, an
eval and optionally a validation split. At every reset each solver picks one from the
env's reset options (``env.reset(options={"split": "eval", "start": k})``) with
:func:`choose_start`. Core seeds every solver's ``solver.rng`` with the episode's seed, so
two solvers given their starts in the same order pick the same one, index for index and
draw for draw: a fluid's snapshot and the solid's state saved with it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from gymprecice.plugin.errors import ConfigError


def choose_start(
    pools: Mapping[str, Sequence[str]],
    everything: Sequence[str],
    rng: np.random.Generator | None,
    split: str | None,
    start: int | None = None,
    *,
    what: str = "snapshot",
    validation_hint: str = "give the solver a 'validation' list of starts",
    order: Callable[[str], Any] | None = None,
) -> str:
    """The episode's start: one of the split's saved states.

    ``pools`` maps ``"train"``, ``"eval"`` and ``"validation"`` to their starts;
    ``everything`` is every start (the ``"all"`` split, and the train or eval split when
    ``pools`` has none). ``split`` (reset option ``"split"``): ``None`` or ``"train"``,
    ``"eval"``, ``"validation"`` (refused when there is none; ``validation_hint`` says how
    to get one) or ``"all"``. ``start`` (reset option ``"start"``) takes the split's start
    of that index, in the order given (or sorted by ``order``, a sort key: the OpenFOAM
    plugin's time order), so that an evaluation can run every held-out start once;
    without it the start is drawn with ``rng``: ``pool[rng.integers(len(pool))]``, in the
    order given. ``what`` names a start in the errors (``"snapshot"``, ``"start"``).

    Raises :class:`ConfigError` for an unknown split, a missing validation split, a start
    that is not an integer or out of range, and a split with nothing in it.
    """
    if split in (None, "train", "eval"):
        pool = list(pools.get(split or "train") or everything)
    elif split == "validation":
        pool = list(pools.get("validation") or [])
        if not pool:
            raise ConfigError(
                f"reset option split='validation': the case keeps no validation {what}s; "
                f"{validation_hint}"
            )
    elif split == "all":
        pool = list(everything)
    else:
        raise ConfigError(
            f"reset option split={split!r}: use 'train' (default), 'eval', 'validation' or 'all'"
        )
    if not pool:
        raise ConfigError(
            f"reset option split={split or 'train'!r}: there is no {what} to start from"
        )
    if start is not None:
        if isinstance(start, bool) or not isinstance(start, (int, np.integer)):
            raise ConfigError(f"reset option start={start!r}: must be an integer index")
        if not 0 <= int(start) < len(pool):
            raise ConfigError(
                f"reset option start={start}: split {split or 'train'!r} has {len(pool)} "
                f"{what}(s) ({', '.join(pool)}); use 0 to {len(pool) - 1}"
            )
        ordered = pool if order is None else sorted(pool, key=order)
        return ordered[int(start)]
    generator = rng if rng is not None else np.random.default_rng()
    return pool[int(generator.integers(len(pool)))]
