"""The files a rollout writes, and the statistics read from them.

* ``history.csv``: one row per action: ``episode, step, start, time, reward``, the
  step's metrics, ``action_0..`` (``start``/``time``: coupling time at the action's start
  and end; metrics: the named scalars an env reports in ``info["metrics"]``, e.g. the
  cylinders' ``Cd``/``Cl`` averages the reward used, or the flap's tip displacement;
  actions in the env's own units);
* ``coefficients.csv``: every solver step's ``episode, time`` and the force coefficients
  among the env's ``info["metrics"]`` (the cylinders' ``Cd, Cl``, from each step's
  ``info["coefficients"]`` rows); not written for an env whose metrics have neither;
* ``summary.json``: per-episode return and the mean of each metric the env reports,
  the series means over every solver step (:func:`series_means`), the fractions of a
  reference (:func:`floor_metrics`), and over the episodes the mean and standard
  deviation of each (:func:`over_episodes`) and, against a baseline run, the % change
  of each mean (:func:`change_against`).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.card import Reference

__all__ = [
    "COEFFICIENTS",
    "change_against",
    "coefficient_columns",
    "episodes_by_start",
    "floor_metrics",
    "metric_names",
    "nanmean",
    "over_episodes",
    "series_means",
    "write_rollout",
]


_NOT_METRICS = {"episode", "step", "start", "time", "reward"}


def metric_names(rows: list[dict[str, Any]]) -> list[str]:
    """The metrics an episode's rows record, in their order."""
    return list(
        dict.fromkeys(
            name
            for r in rows
            for name in r
            if name not in _NOT_METRICS and not name.startswith("action_")
        )
    )


def write_rollout(
    out: Path,
    history_rows: list[dict[str, Any]],
    coefficient_rows: list[tuple[int, float, float, float]],
    summaries: list[dict[str, Any]],
    columns: list[str],
) -> dict[str, Any]:
    """``history.csv``, ``coefficients.csv`` (only ``columns`` of the coefficients; none
    without any: an earlier run's file is removed, so that plot reads no stale one) and
    ``summary.json``; the summary."""
    _write_csv(out / "history.csv", history_rows)
    _write_coefficients(out / "coefficients.csv", coefficient_rows, columns)
    summary = {
        "episodes": summaries,
        "mean_return": float(np.mean([s["return"] for s in summaries])),
        "over_episodes": over_episodes(summaries),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


#: the columns of ``info["coefficients"]`` rows after their time, in order
COEFFICIENTS = ("Cd", "Cl")


def coefficient_columns(metrics: list[str]) -> list[str]:
    """The force coefficients an env reports among its ``info["metrics"]`` names: the
    columns of its ``coefficients.csv`` (none for an env without force coefficients)."""
    return [name for name in COEFFICIENTS if name in metrics]


def _write_coefficients(
    path: Path, rows: list[tuple[int, float, float, float]], columns: list[str]
) -> None:
    """``episode, time`` and ``columns`` of every solver step's row; no file (and none
    left from an earlier run) when ``columns`` is empty."""
    if not columns:
        path.unlink(missing_ok=True)
        return
    keep = [2 + COEFFICIENTS.index(name) for name in columns]
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["episode", "time", *columns])
        writer.writerows([(row[0], row[1], *(row[k] for k in keep)) for row in rows])


def episodes_by_start(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """A summary's episodes in held-out start order (episode order without starts)."""
    return sorted(summary["episodes"], key=lambda e: int(e.get("start", e["episode"])))


def series_means(coefficients: list[tuple[float, float]]) -> dict[str, float]:
    """Mean Cd and mean |Cl| over an episode's solver steps (none without coefficients)."""
    if not coefficients:
        return {}
    cd, cl = np.asarray(coefficients, dtype=float).T
    return {"series_mean_Cd": float(cd.mean()), "series_mean_abs_Cl": float(np.abs(cl).mean())}


def floor_metrics(
    coefficients: list[tuple[int, float, float, float]],
    t0: float,
    floor: Reference,
    rows: list[dict[str, Any]] | None = None,
) -> dict[str, float]:
    """The settled mean of the reference's metric (from ``t0 + settle_time`` on) and the
    fractions of the floor that the whole episode's and the settled mean reach.

    A cylinder's ``Cd``/``Cl`` is read over every solver step (``coefficients``:
    ``series_settled_mean_Cd``); any other metric, or one without coefficients, from the
    episode's per-action ``rows`` (``settled_mean_<metric>``). None when neither has it."""
    metric = floor.metric
    if metric in ("Cd", "Cl") and coefficients:
        _, time, cd, cl = np.asarray(coefficients, dtype=float).T
        values, key = (cd if metric == "Cd" else cl), f"series_settled_mean_{metric}"
    else:
        pairs = [(r["time"], r[metric]) for r in rows or () if r.get(metric) is not None]
        if not pairs:
            return {}
        time, values = np.asarray(pairs, dtype=float).T
        key = f"settled_mean_{metric}"
    out = {"floor_fraction": floor.fraction(float(values.mean()))}
    settled = values[time >= t0 + floor.settle_time - 1e-9]
    if settled.size:
        out[key] = float(settled.mean())
        out["settled_floor_fraction"] = floor.fraction(float(settled.mean()))
    return out


def over_episodes(episodes: list[dict[str, Any]]) -> dict[str, dict[str, float | int]]:
    """Mean, standard deviation (``ddof=0``) and count over episodes of each scalar."""
    keys = [
        k
        for k in episodes[0]
        if k not in ("episode", "steps", "end_time", "start", "start_label", "video")
    ]
    out: dict[str, dict[str, float | int]] = {}
    for key in keys:
        values = np.array([e[key] for e in episodes if e.get(key) is not None], dtype=float)
        values = values[np.isfinite(values)]
        if values.size:
            out[key] = {
                "mean": float(values.mean()),
                "std": float(values.std()),
                "n": int(values.size),
            }
    return out


def change_against(summary: dict[str, Any], baseline: dict[str, Any]) -> dict[str, float]:
    """% change of each mean over episodes against a baseline summary's (same keys)."""
    ours, theirs = summary["over_episodes"], baseline.get("over_episodes")
    if theirs is None:  # a summary written before over_episodes existed
        theirs = over_episodes(baseline["episodes"])
    out = {}
    for key, stats in ours.items():
        ref = theirs.get(key, {}).get("mean")
        if ref:
            out[key] = 100.0 * (stats["mean"] - ref) / abs(ref)
    return out


def nanmean(values: list[Any]) -> float | None:
    array = np.asarray(values, dtype=float)
    if not array.size or np.all(np.isnan(array)):
        return None
    return float(np.nanmean(array))


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    fields: list[str] = []
    for row in rows:
        fields += [k for k in row if k not in fields]
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields or ["episode"])
        writer.writeheader()
        writer.writerows(rows)
