"""``gymprecice ship-policy``: its options, typed, built once.

A frozen dataclass (why frozen dataclasses, and why one module per family:
:mod:`gymprecice_lab.common.command_settings`). ``gymprecice policies`` takes no option,
so it has none.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

__all__ = ["ShipSettings"]


@dataclass(frozen=True, kw_only=True)
class ShipSettings:
    """``gymprecice ship-policy``: which model of which training run, shipped where."""

    # -- what is shipped --------------------------------------------------------------
    #: TRAIN_DIR: a training output
    train_dir: Path
    #: ``--model``: kept or final
    model: str
    #: ``--checkpoint best|STEPS``: a checkpoint instead of the kept model
    checkpoint: str | None
    #: ``--evaluation RUN``: an evaluation of the model, whose result is recorded
    evaluation: Path | None

    # -- as what, and where ------------------------------------------------------------
    #: ``--name`` (None: the training env's name)
    name: str | None
    #: ``--into DIR`` (None: $GYMPRECICE_POLICIES_DIR, else the package's policies/)
    into: Path | None
    #: ``--force``: replace a policy of that name
    force: bool
