"""The ``model_ensemble`` hyperparameter: what model-ensemble PPO's models are and do.

Kept apart from the torch code so that reading and checking a hyperparameter file does not
load torch.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = ["ENSEMBLE_KEY", "TRANSITIONS_FILE", "EnsembleSettings"]

#: The hyperparameter-file key that turns PPO into model-ensemble PPO.
ENSEMBLE_KEY = "model_ensemble"
#: Where a run keeps its CFD transitions (under its output directory), for a resume.
TRANSITIONS_FILE = Path("model_ensemble") / "transitions.npz"


@dataclass(frozen=True)
class EnsembleSettings:
    """Model-ensemble PPO's settings; every field has a default, so ``{}`` is valid.

    Up to ``updates`` model-based PPO updates follow each CFD update, each on
    ``trajectories`` predicted trajectories per member as long as a CFD rollout
    (``n_steps``), from the same recorded starts within one CFD update's turn (so that two
    turns differ by the policy, not by where they began); they stop early, as in drlFoam,
    once fewer than a ``quorum`` share of the members predict a higher mean reward than in
    the previous model-based rollout (0: never early). The networks read the last
    ``history`` observations and actions and predict the change of the observation and the
    reward; each fit continues from the previous weights for at most ``epochs`` epochs and
    stops when the held-out ``validation`` share has not improved for ``patience`` epochs.
    """

    members: int = 5
    updates: int = 4
    trajectories: int = 2
    history: int = 2
    hidden: tuple[int, ...] = (128, 128)
    epochs: int = 30
    patience: int = 5
    learning_rate: float = 1e-3
    batch_size: int = 128
    validation: float = 0.2
    quorum: float = 0.5
    #: CFD rollouts before the first model-based update (the ensemble needs data first)
    warmup_rollouts: int = 1

    @classmethod
    def from_value(cls, value: Any, where: str) -> EnsembleSettings:
        """The settings of a file's ``model_ensemble`` value (a mapping, or ``true``).

        Raises ``SystemExit`` naming ``where`` (the file) and the fix on an unknown key or
        a value out of range.
        """
        if value is True:
            value = {}
        if not isinstance(value, Mapping):
            raise SystemExit(
                f"{where}: {ENSEMBLE_KEY} must be true or a mapping of its settings "
                f"({', '.join(f.name for f in dataclasses.fields(cls))})"
            )
        names = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise SystemExit(
                f"{where}: {ENSEMBLE_KEY} has no setting {unknown[0]!r}; choose from "
                f"{', '.join(names)}"
            )
        kwargs: dict[str, Any] = {}
        for key, raw in value.items():
            default = getattr(cls, key) if key != "hidden" else cls().hidden
            try:
                kwargs[key] = _coerce(raw, default)
            except (TypeError, ValueError):
                raise SystemExit(
                    f"{where}: {ENSEMBLE_KEY}.{key} must be like {_show(default)}, got {raw!r}"
                ) from None
        settings = cls(**kwargs)
        problem = settings.problem()
        if problem:
            raise SystemExit(f"{where}: {ENSEMBLE_KEY}.{problem}")
        return settings

    def problem(self) -> str | None:
        """The first setting out of range, as ``name must ...``; ``None`` if all are fine."""
        for name in ("members", "trajectories", "history", "epochs", "patience", "batch_size"):
            if getattr(self, name) < 1:
                return f"{name} must be at least 1, got {getattr(self, name)}"
        for name in ("updates", "warmup_rollouts"):
            if getattr(self, name) < 0:
                return f"{name} must be at least 0, got {getattr(self, name)}"
        if not self.hidden or any(width < 1 for width in self.hidden):
            return f"hidden must be one or more layer widths >= 1, got {list(self.hidden)}"
        if not 0.0 <= self.quorum <= 1.0:
            return f"quorum must be a share between 0 and 1, got {self.quorum}"
        if not 0.0 < self.validation < 1.0:
            return f"validation must be a share between 0 and 1, got {self.validation}"
        if self.learning_rate <= 0:
            return f"learning_rate must be positive, got {self.learning_rate}"
        return None

    def to_json(self) -> dict[str, Any]:
        """The settings as ``hyperparams.json`` records them (and a resume compares)."""
        data = dataclasses.asdict(self)
        data["hidden"] = list(self.hidden)
        return data


def _coerce(raw: Any, default: Any) -> Any:
    if isinstance(default, tuple):
        if isinstance(raw, str):
            raw = [part for part in raw.split(",") if part.strip()]
        return tuple(int(_strict_number(v, int)) for v in raw)
    return _strict_number(raw, type(default))


def _strict_number(raw: Any, kind: type) -> Any:
    if isinstance(raw, bool):
        raise TypeError("a boolean is not a number")
    if kind is int:
        if isinstance(raw, float) and not raw.is_integer():
            raise ValueError("not a whole number")
        return int(raw)
    return float(raw)


def _show(default: Any) -> str:
    return ",".join(str(v) for v in default) if isinstance(default, tuple) else str(default)
