"""The benchmark's results: ``results.json``, ``results.csv`` and ``results.md``.

Three views of the same controller entries (:mod:`gymprecice_lab.benchmarking.scores`):
every score for a program, one row per controller for a spreadsheet, and a table per
metric, each statistic with its interval, for a reader, headed by what the env and its
held-out starts are and followed by each seed's restarts while it trained.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gymprecice_lab.benchmarking.scores import STATISTICS
from gymprecice_lab.common.durations import duration_text
from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.common.starts import describe_starts

__all__ = ["write_tables"]


_METRIC_TITLES = {
    "objective": "{objective} (lower is better)",
    "mean_Cd": "mean drag coefficient over every solver step (lower is better)",
    "floor_fraction": "fraction of the drag floor's drop, over the whole episode (higher is "
    "better; 1: the steady symmetric flow's drag)",
    "settled_floor_fraction": "fraction of the drag floor's drop once settled, after the "
    "first seconds' transient (higher is better)",
    "mean_abs_Cl": "mean |lift coefficient| over every solver step (the shedding's swing)",
    "side_force": "|mean lift coefficient|: the steady side force (0 for a symmetric flow)",
}


def _metric_title(metric: str) -> str:
    """A table's heading: the metric's own, or that of an episode mean of a card metric."""
    if metric in _METRIC_TITLES:
        return _METRIC_TITLES[metric]
    name = metric.removeprefix("mean_")
    return f"the episode mean of {name} (info['metrics'], a metric of the env's lab card)"


def _fmt(e: dict[str, Any]) -> str:
    """A table's cell: the value, with its interval where there is one."""
    if e["runs"] < 2:
        return f"{e['value']:.4g}"
    return f"{e['value']:.4g} [{e['low']:.4g}, {e['high']:.4g}]"


def _restarts_note(restarts: Mapping[str, Mapping[str, int]]) -> str:
    """The line under the tables: each seed's restarts while it trained."""
    seeds = []
    for seed, counts in restarts.items():
        parts = [
            f"{n} {what}{'s' if n != 1 else ''}"
            for what, n in (
                ("env restart", counts.get("env_restarts", 0)),
                ("training re-run", counts.get("training_reruns", 0)),
            )
            if n
        ]
        seeds.append(f"{seed}: {', '.join(parts) or 'none'}")
    return (
        "Restarts while training, per seed (an env re-created after a lost Ray node or a "
        "failure; a training re-run from its newest checkpoint after a failure): "
        + "; ".join(seeds)
        + "."
    )


def _training_note(training: Mapping[str, Mapping[str, Any]]) -> str:
    """The line under the tables: each seed's training time and the model it kept."""
    seeds = []
    for seed, record in training.items():
        steps = record.get("timesteps")
        text = f"{seed}: {steps:,} steps" if steps is not None else f"{seed}:"
        text += f" in {duration_text(record.get('training_seconds'), to_the_minute=True)}"
        kept = record.get("kept")
        if kept:
            value = kept.get("value")
            text += (
                f", kept the model of step {int(kept['timesteps']):,} "
                f"({str(kept['score']).replace('validation ', '')} {value:.4g} on validation), "
                f"{duration_text(kept.get('training_seconds'), to_the_minute=True)} into training"
                if value is not None
                else ""
            )
        seeds.append(text)
    return (
        "Training per seed (wall-clock summed over a resumed run's segments, the gaps "
        "between them left out): " + "; ".join(seeds) + "."
    )


def write_tables(
    out: Path,
    env: LabEnv,
    starts: Sequence[str],
    controllers: list[dict],
    restarts: Mapping[str, Mapping[str, int]] | None = None,
    training: Mapping[str, Mapping[str, Any]] | None = None,
) -> None:
    """``results.json`` (every score), ``results.csv`` and ``results.md``; ``restarts``:
    per seed (``"PPO seed 0"``), its env restarts and training re-runs
    (:func:`~gymprecice_lab.benchmarking.seed_training.restarts`), in the JSON and under the
    tables; ``training``: per seed, its training time and kept model
    (:func:`~gymprecice_lab.benchmarking.seed_training.training_record`), the same."""
    metrics = list(dict.fromkeys(m for c in controllers for m in c["metrics"]))
    results: dict[str, Any] = {
        "env": env.env_id,
        "held_out_starts": list(starts),
        "controllers": controllers,
    }
    if restarts is not None:
        results["restarts"] = {seed: dict(counts) for seed, counts in restarts.items()}
    if training is not None:
        results["training"] = {seed: dict(record) for seed, record in training.items()}
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    fields = ["controller", "kind", "runs", "starts"]
    for m in metrics:
        for s in STATISTICS:
            fields += [f"{m}_{s}", f"{m}_{s}_low", f"{m}_{s}_high"]
    with (out / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for c in controllers:
            row: dict[str, Any] = {
                "controller": c["label"],
                "kind": c["kind"],
                "runs": c["runs"],
                "starts": len(starts),
            }
            for m, stats in c["metrics"].items():
                for s in STATISTICS:
                    row[f"{m}_{s}"] = stats[s]["value"]
                    row[f"{m}_{s}_low"] = stats[s]["low"]
                    row[f"{m}_{s}_high"] = stats[s]["high"]
            writer.writerow(row)
    objective = env.objective or "negated mean reward per action"
    if env.objective and env.maximize:
        objective += ", negated"
    lines = [
        f"# Benchmark: {env.env_id}",
        "",
        *([env.card.description, ""] if env.card.description else []),
        f"From each of the {describe_starts(len(starts), env.held_out_starts)} "
        f"({'; '.join(starts)}): the mean, "
        "median and interquartile mean (IQM) over every seed x start score, each with a "
        "95 % stratified-bootstrap interval over seeds (strata: the starts); a controller "
        "run once (runs = 1) has no interval.",
    ]
    for m in metrics:
        lines += ["", f"## {m}: {_metric_title(m).format(objective=objective)}", ""]
        lines += [
            "| controller | kind | runs | " + " | ".join(STATISTICS) + " |",
            "| --- | --- | --- | " + " | ".join("---" for _ in STATISTICS) + " |",
        ]
        for c in controllers:
            if m not in c["metrics"]:
                continue
            cells = [_fmt(c["metrics"][m][s]) for s in STATISTICS]
            lines.append(
                f"| {c['label']} | {c['kind']} | {c['runs']} | " + " | ".join(cells) + " |"
            )
    if restarts:
        lines += ["", _restarts_note(restarts)]
    if training:
        lines += ["", _training_note(training)]
    (out / "results.md").write_text("\n".join(lines) + "\n")
