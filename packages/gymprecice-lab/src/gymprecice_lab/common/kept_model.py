"""Which model of a training run a command takes: the kept one, or the final one.

A ``gymprecice train`` run leaves two models: ``model.zip``, the policy when training
stopped, and ``best_model.zip``, the *kept model*, the best of the run's validations
(:mod:`gymprecice_lab.training.validation`) with its record in ``eval/best.json``. The
final model of an off-policy run can sit several points below the run's best, so every
command that takes a training run (evaluate, ship-policy, benchmark, time-to-floor)
takes the kept model unless ``--model final`` says otherwise, and says which it took.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice_lab.common.durations import duration_text

__all__ = [
    "FINAL",
    "KEPT",
    "KEPT_MODEL",
    "KEPT_RECORD",
    "MODEL_CHOICES",
    "RETURN_SCORE",
    "choose_model",
    "kept_summary",
    "read_kept",
]

KEPT, FINAL = "kept", "final"
#: the values of ``--model``: which model of a training run to take
MODEL_CHOICES = (KEPT, FINAL)
#: the kept model and its record, in a training run's directory
KEPT_MODEL = Path("best_model.zip")
KEPT_RECORD = Path("eval") / "best.json"
#: the kept model's score where its record names none (runs made before it did), and
#: the score of an env without a physical reference
RETURN_SCORE = "mean validation return"


def read_kept(run: Path) -> dict[str, Any] | None:
    """The kept model's record of training run ``run`` (``None``: it keeps none)."""
    try:
        record = json.loads((run / KEPT_RECORD).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or not (run / KEPT_MODEL).is_file():
        return None
    return record


def kept_summary(record: Mapping[str, Any]) -> str:
    """One line on a kept model: its step, score, starts and wall-clock."""
    seconds = record.get("seconds_from_command")
    trained = record.get("seconds_of_training")
    if seconds is None:
        clock = ""
    elif trained is not None and abs(float(trained) - float(seconds)) > 1:
        clock = (
            f", after {duration_text(float(trained))} of training over the run's segments "
            f"({duration_text(float(seconds))} after the resuming command)"
        )
    else:
        clock = f", {duration_text(float(seconds))} after the command was typed"
    starts = record.get("starts") or []
    on = f"{len(starts)} validation start(s)" if starts else "validation"
    score = str(record.get("score") or RETURN_SCORE).replace("validation ", "")
    return (
        f"best on {on} ({score} {float(record['mean_return']):.4g}) at step "
        f"{int(record['timesteps']):,}{clock}"
    )


def choose_model(run: Path, which: str = KEPT) -> tuple[Path, str] | None:
    """The model file ``which`` of training directory ``run`` and the line that says so;
    ``None`` when ``run`` has no ``model.zip`` to fall back on and no kept model."""
    if which not in MODEL_CHOICES:
        raise ValueError(f"--model takes {' or '.join(MODEL_CHOICES)}, got {which!r}")
    final = run / "model.zip"
    if which == KEPT:
        record = read_kept(run)
        if record is not None:
            return run / KEPT_MODEL, (
                f"the kept model {run / KEPT_MODEL} ({kept_summary(record)}); "
                "--model final for the last one"
            )
        if final.is_file():
            looks_trained = (run / "manifest.json").is_file() or (run / "checkpoints").is_dir()
            why = (
                "no kept model (trained without validation)"
                if looks_trained
                else "a policy directory"
            )
            return final, f"{final}: {why}, its final model"
        return None
    if final.is_file():
        return final, f"the final model {final} (--model final)"
    return None
