"""``gymprecice train``'s manifest: one record per segment, the first run and each resume.

A run resumed after preemption is several processes; ``<out>/manifest.json`` keeps each
one's command line, start, settings, seeds and result (``segments``), so the time it took
(``time-to-floor``, ``ship-policy``) and what made it can be read back. The record is
written when a segment starts (its result ``None``) and again when it ends; a segment
starts when the user typed the command (:func:`command_started_at`).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice_lab.common.manifest import read_manifest, write_manifest
from gymprecice_lab.training.command_settings import TrainSettings

__all__ = ["command_started_at", "previous_segments", "record_segment", "run_settings"]


def command_started_at() -> float:
    """When the command started (epoch seconds): now, or the typed command's start that a
    wrapper which sets up first passes in ``GYMPRECICE_STARTED_AT`` (scripts/train.sh),
    so that "how long did it take" counts from what the user typed."""
    given = os.environ.get("GYMPRECICE_STARTED_AT", "")
    try:
        started = float(given)
    except ValueError:
        return time.time()
    return started if 0 < started <= time.time() else time.time()


def run_settings(
    settings: TrainSettings, used: dict[str, Any], adjusted: list[str]
) -> dict[str, Any]:
    """What the manifest records of the run's settings (``used``: the hyperparameters
    resolved, ``adjusted``: what was changed in them, and why)."""
    return {
        "n_envs": settings.n_envs,
        "timesteps": settings.timesteps,
        "checkpoint_every": settings.checkpoint_every,
        "keep_checkpoints": settings.keep_checkpoints,
        "eval_freq": settings.eval_freq,
        "stop_at": settings.stop_at,
        "n_eval_episodes": settings.n_eval_episodes,
        "validation": not settings.no_validation,
        "fresh": settings.fresh,
        "vec_env": settings.vec_env,
        "device": settings.device,
        "double": settings.double,
        "hyperparams_file": str(settings.hyperparams) if settings.hyperparams else None,
        "hyperparams": used,
        "adjusted": adjusted,
        "env_id": settings.lab_env.env_id,
        "env_kwargs": settings.constructor_kwargs,
    }


def record_segment(
    out: Path,
    settings: dict[str, Any],
    seeds: dict[str, Any],
    segments: list[dict[str, Any]],
    case_dir: Path | None,
    solvers: Any,
    started_at: float,
    result: Mapping[str, Any] | None,
) -> None:
    """Write the manifest: the earlier segments and this one, with its ``result`` (None
    while it runs)."""
    segment = {
        "argv": list(sys.argv),
        "started_at": started_at,
        # when it ended: a resumed run's training time leaves out the gaps between
        # segments (gymprecice_lab.common.training_clock)
        "finished_at": None if result is None else round(time.time(), 3),
        "settings": settings,
        "seeds": seeds,
        "result": result,
    }
    write_manifest(
        out,
        command="train",
        case_dir=case_dir,
        seeds=seeds,
        settings=settings,
        solvers=solvers,
        extra={"result": result, "segments": [*segments, segment]},
    )


def previous_segments(out: Path) -> list[dict[str, Any]]:
    """The manifest records of the segments before this one (a resume keeps them all)."""
    try:
        manifest = read_manifest(out)
    except (OSError, ValueError):
        return []
    if "segments" in manifest:
        return list(manifest["segments"])
    keys = ("argv", "settings", "seeds", "result")
    return [{k: manifest.get(k) for k in keys}]
