"""The benchmark's two figures.

* ``return_wallclock.png``: the training return against wall-clock time, per algorithm
  the mean over seeds with a 95 % bootstrap band (seeds resampled at each time). Each
  seed's curve at time ``t`` is the mean return of its last ``n_envs`` episodes finished
  by ``t`` (SB3's monitor files, whose clock runs from the seed's first start and so
  includes pauses between resumed segments); the curves stop where the shortest seed
  stops, so every point averages every seed.
* ``objective_per_start.png``: the objective from each held-out start for every
  controller: each seed of a learned controller as a dot, its IQM as a diamond; each
  baseline as a line across the starts.
"""

from __future__ import annotations

import csv
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_lab.benchmarking.stats import iqm

__all__ = ["plot_objective_per_start", "plot_return_wallclock", "seed_curve"]

#: points on the common wall-clock axis
GRID = 200
BAND_REPS = 1000


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def seed_curve(run: Path) -> tuple[np.ndarray, np.ndarray]:
    """(wall-clock seconds, return) of every episode of a training run, in time order."""
    times: list[float] = []
    returns: list[float] = []
    for path in sorted((run / "monitor").glob("*.monitor.csv")):
        with path.open(newline="") as handle:
            rows = csv.DictReader(line for line in handle if not line.startswith("#"))
            for row in rows:
                times.append(float(row["t"]))
                returns.append(float(row["r"]))
    order = np.argsort(times)
    return np.asarray(times)[order], np.asarray(returns)[order]


def _on_grid(times: np.ndarray, returns: np.ndarray, grid: np.ndarray, window: int) -> np.ndarray:
    """The mean of the last ``window`` episodes finished by each grid time (NaN before)."""
    done = np.searchsorted(times, grid, side="right")
    cumulative = np.concatenate([[0.0], np.cumsum(returns)])
    first = np.maximum(done - window, 0)
    count = done - first
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (cumulative[done] - cumulative[first]) / count, np.nan)


def plot_return_wallclock(out: Path, algos: Sequence[str], seeds: int) -> Path:
    """``<out>/return_wallclock.png`` from ``<out>/train/<algo>/seed_<k>``'s monitors."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    rng = np.random.default_rng(0)
    for algo in algos:
        curves = [seed_curve(out / "train" / algo / f"seed_{k}") for k in range(seeds)]
        curves = [c for c in curves if len(c[0])]
        if not curves:
            continue
        window = max(1, len(list((out / "train" / algo / "seed_0" / "monitor").glob("*.csv"))))
        end = min(float(t[-1]) for t, _ in curves)
        start = max(float(t[0]) for t, _ in curves)
        grid = np.linspace(start, max(end, start), GRID)
        values = np.array([_on_grid(t, r, grid, window) for t, r in curves])
        mean = np.nanmean(values, axis=0)
        ax.plot(
            grid / 60.0,
            mean,
            marker="." if end <= start else None,
            label=f"{algo.upper()} ({len(curves)} seeds)",
        )
        if len(curves) > 1:
            picks = rng.integers(len(curves), size=(BAND_REPS, len(curves)))
            resampled = np.nanmean(values[picks], axis=1)
            low, high = np.nanpercentile(resampled, [2.5, 97.5], axis=0)
            ax.fill_between(grid / 60.0, low, high, alpha=0.25)
    ax.set_xlabel("wall-clock since the seed's start (min)")
    ax.set_ylabel("training return")
    ax.set_title("Training return: mean over seeds, 95 % bootstrap band")
    if ax.get_legend_handles_labels()[0]:
        ax.legend()
    path = out / "return_wallclock.png"
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_objective_per_start(
    path: Path,
    starts: Sequence[str],
    controllers: Sequence[dict[str, Any]],
    objective_label: str,
    *,
    held_out: bool = True,
    description: str = "",
) -> Path:
    """The objective from each start for every controller (lower is better), its axis
    named ``objective_label`` (the card's objective: ``LabEnv.objective_label``); the
    starts are held-out ones, or (``held_out`` False) seeds; ``description`` (the card's)
    heads the figure."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(starts) + 3), 4))
    x = np.arange(len(starts))
    learned = [c for c in controllers if c["runs"] > 1 or c["kind"] == "learned"]
    width = 0.8 / max(1, len(learned))
    for i, c in enumerate(learned):
        scores = np.asarray(c["metrics"]["objective"]["scores"], dtype=float)
        offset = (i - (len(learned) - 1) / 2) * width
        # an open diamond, so that the seeds' dots stay visible inside it
        (line,) = ax.plot(
            x + offset,
            iqm(scores, axis=0),
            "D",
            markersize=10,
            fillstyle="none",
            markeredgewidth=1.5,
            label=f"{c['label']} (IQM)",
        )
        for row in scores:
            ax.plot(x + offset, row, "o", color=line.get_color(), markersize=4, alpha=0.7)
    for c in controllers:
        if c in learned:
            continue
        scores = np.asarray(c["metrics"]["objective"]["scores"], dtype=float)[0]
        ax.plot(x, scores, marker="s", linestyle="--", label=c["label"])
    # start labels are sentences ("setpoint 305.25 K, inflow -> 0.045 m/s at 0.5 s"):
    # wrapped, so that neighbours do not overprint each other
    ax.set_xticks(x, [textwrap.fill(str(s), 24) for s in starts])
    ax.set_xlim(-0.5, len(starts) - 0.5)
    kind = "held-out start" if held_out else "start (drawn by its reset seed)"
    ax.set_xlabel(kind)
    ax.set_ylabel(objective_label)
    title = f"Objective per {kind.split(' (')[0]} (dots: training seeds)"
    ax.set_title(f"{textwrap.fill(description, 64)}\n{title}" if description else title)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
