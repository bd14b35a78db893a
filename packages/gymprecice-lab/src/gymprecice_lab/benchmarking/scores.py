"""An evaluation's scores per start, and a controller's entry with its intervals.

The tables, the figures and ``results.json`` all read one kind of entry: per
controller, for the objective and every metric the env records (the cylinders' drag
and lift over every solver step, the fractions of a drag floor, the card's own
``metrics``), the seed x start scores and each statistic of :data:`STATISTICS` with its
stratified-bootstrap interval (:mod:`gymprecice_lab.benchmarking.stats`). A learned
controller's runs are its seeds; a baseline is run once.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gymprecice_lab.benchmarking.checks import BenchmarkError
from gymprecice_lab.benchmarking.stats import estimate
from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.common.starts import describe_starts

__all__ = ["STATISTICS", "controller_entry", "start_scores"]

#: the statistics reported for every metric
STATISTICS = ("mean", "median", "iqm")


def start_scores(summary: dict[str, Any], env: LabEnv, starts: int) -> dict[str, list[float]]:
    """Per start (in index order) the objective and, where recorded, the env's own metrics:
    the force coefficients over every solver step (the cylinders), the fractions of the
    card's reference and the episode mean of each of the card's ``metrics``."""
    from gymprecice_lab.rollouts.records import episodes_by_start
    from gymprecice_lab.rollouts.sweep import objective

    episodes = episodes_by_start(summary)
    if len(episodes) != starts:
        raise BenchmarkError(
            f"an evaluation has {len(episodes)} episode(s) for "
            f"{describe_starts(starts, env.held_out_starts)}; "
            "rerun with --fresh",
            1,
        )
    out = {"objective": [objective(env, e) for e in episodes]}
    for metric, key in _SERIES_METRICS:
        if all(e.get(key) is not None for e in episodes):
            out[metric] = [float(e[key]) for e in episodes]
    series = "mean_Cd" in out  # the force coefficients over every solver step
    if series and all(e.get("mean_Cl") is not None for e in episodes):
        # a steady side force lowers the drag below the shedding's without suppressing it
        out["side_force"] = [abs(float(e["mean_Cl"])) for e in episodes]
    for name in env.card.metrics:
        key = f"mean_{name}"
        if (series and name in ("Cd", "Cl")) or name == env.objective or key in out:
            continue  # said above: over every solver step, or as the objective
        if all(e.get(key) is not None for e in episodes):
            out[key] = [float(e[key]) for e in episodes]
    return out


#: the per-start metrics besides the objective, from each episode's summary: the mean drag
#: and mean |lift| over every solver step and, where the env knows its drag floor, the
#: fraction of the floor's drop reached over the whole episode and once settled
_SERIES_METRICS = (
    ("mean_Cd", "series_mean_Cd"),
    ("mean_abs_Cl", "series_mean_abs_Cl"),
    ("floor_fraction", "floor_fraction"),
    ("settled_floor_fraction", "settled_floor_fraction"),
)


def controller_entry(label: str, kind: str, runs: list[dict[str, list[float]]], reps: int) -> dict:
    """A controller's entry: per metric its runs x starts scores and every statistic with
    its interval (over the metrics every run recorded; ``reps`` bootstrap resamples)."""
    metrics = [m for m in runs[0] if all(m in r for r in runs)]
    entry: dict[str, Any] = {"label": label, "kind": kind, "runs": len(runs), "metrics": {}}
    for metric in metrics:
        matrix = np.array([r[metric] for r in runs], dtype=float)
        entry["metrics"][metric] = {
            "scores": matrix.tolist(),
            **{s: estimate(matrix, s, reps=reps).as_dict() for s in STATISTICS},
        }
    return entry
