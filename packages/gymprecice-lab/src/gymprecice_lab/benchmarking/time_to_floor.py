"""``gymprecice time-to-floor``: how far and how soon a training run controlled the flow.

An env's physical reference (its lab card's ``reference``, :class:`gymprecice.card.Reference`:
a cylinder's *drag floor*) says how far control can take its metric, from the uncontrolled
value to the floor; a run has *controlled the flow* once a policy takes most of that drop. This module finds, for a training run, the first
checkpoint whose deterministic evaluation from **every** held-out start reaches a given
fraction of the floor once settled (the mean over the starts), and the wall-clock from
the start of the training command to that checkpoint's save (over a resumed run's
segments, the gaps between them left out: :mod:`gymprecice_lab.common.training_clock`).

The checkpoints are evaluated in the order they were saved, ``--workers`` at a time, and
the scan stops at the first that reaches the highest fraction asked for: the answer is
the same as evaluating every checkpoint, at a fraction of the cost. Each evaluation is an
ordinary ``gymprecice evaluate --all-starts`` run under ``<out>/<steps>``, kept, so a scan
resumes and its numbers can be traced. A short evaluation (``--eval-time``, 4 s: 2 s of
transient, then 2 s, six shedding periods, of settled flow) keeps the scan cheap; the
benchmark's table evaluates the final models over 10 s.

By default (``--model kept``) the model scanned is the one the run keeps, the best of its
validations (:mod:`gymprecice_lab.common.kept_model`), at the wall-clock of its save: the model a
user is left with, judged on the held-out starts that never chose it. ``--model final``
takes the final model; ``--model checkpoints`` scans every checkpoint as above.

Over several runs (the seeds of one recipe) it reports the median time with a 95 %
bootstrap interval over the runs; a run that never reached a fraction counts as slower
than every run that did, and the interval is then left open.
"""

from __future__ import annotations

import csv
import json
import math
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.card import Reference
from gymprecice_lab.benchmarking.command_settings import TimeToFloorSettings
from gymprecice_lab.common.command_runs import CommandFailed, evaluated, run_commands
from gymprecice_lab.common.durations import duration_text
from gymprecice_lab.common.registered_env import LabEnv, LabEnvError, find_lab_env
from gymprecice_lab.common.training_clock import training_seconds
from gymprecice_lab.rollouts.records import episodes_by_start

__all__ = [
    "Checkpoint",
    "RunScan",
    "candidates",
    "checkpoints",
    "run_clock",
    "run_started",
    "scan_run",
    "time_to_floor_command",
]

_STEPS = re.compile(r"_(\d+)_steps\.zip$")


@dataclass(frozen=True)
class Checkpoint:
    """A saved model of a run: its steps, its file and when it was saved."""

    steps: int
    model: Path
    #: seconds from the start of the training command to the save
    seconds: float


@dataclass
class RunScan:
    """The scan of one run: the settled fraction of every checkpoint evaluated."""

    run: Path
    fractions: tuple[float, ...]
    rows: list[dict[str, Any]] = field(default_factory=list)
    #: the training's own length (steps, seconds to the last checkpoint)
    last_steps: int = 0
    last_seconds: float = 0.0
    #: the models scanned: ``kept``, ``final`` or ``checkpoints``
    which: str = "checkpoints"

    def first_reaching(self, fraction: float) -> dict[str, Any] | None:
        """The first checkpoint whose evaluation reaches ``fraction`` of the floor."""
        return next((r for r in self.rows if r["settled_floor_fraction"] >= fraction), None)

    def as_dict(self) -> dict[str, Any]:
        reached = {}
        for fraction in self.fractions:
            row = self.first_reaching(fraction)
            reached[f"{fraction:g}"] = (
                {"steps": row["steps"], "seconds": row["seconds"]} if row else None
            )
        return {
            "run": str(self.run),
            "last_steps": self.last_steps,
            "last_seconds": self.last_seconds,
            "reached": reached,
            "checkpoints": self.rows,
        }


def run_started(run: Path) -> float:
    """When the training command of ``run`` started (epoch seconds).

    ``gymprecice train`` records it in the manifest's first segment; a run trained
    before it did gives the time its hyperparameters were written, the command's first
    write (after its set-up check).
    """
    try:
        manifest = json.loads((run / "manifest.json").read_text())
    except (OSError, ValueError):
        manifest = {}
    segments = manifest.get("segments") or [{}]
    started = segments[0].get("started_at")
    if started is not None:
        return float(started)
    for name in ("hyperparams.json", "manifest.json"):
        if (run / name).is_file():
            return (run / name).stat().st_mtime
    raise FileNotFoundError(f"{run} is not a training run of `gymprecice train` (no manifest)")


def run_clock(run: Path) -> Callable[[float], float]:
    """Seconds of training of ``run`` at an epoch time: summed over its manifest's
    segments, or, for a run trained before they were recorded, from :func:`run_started`."""
    try:
        segments = json.loads((run / "manifest.json").read_text()).get("segments") or []
    except (OSError, ValueError, AttributeError):
        segments = []
    if any(s.get("started_at") is not None for s in segments):
        return lambda at: float(training_seconds(segments, at) or 0.0)
    started = run_started(run)
    return lambda at: at - started


def candidates(run: Path, which: str) -> list[Checkpoint]:
    """The models of ``run`` to scan: its kept model, its final one, or its checkpoints
    (``which``: ``kept``, ``final`` or ``checkpoints``)."""
    from gymprecice_lab.common.kept_model import KEPT_MODEL, read_kept

    if which == "checkpoints":
        return checkpoints(run)
    clock = run_clock(run)
    if which == "kept":
        record = read_kept(run)
        if record is None:
            raise FileNotFoundError(
                f"no kept model in {run} (best_model.zip and eval/best.json): it trained "
                "without validation; pass --model final or --model checkpoints"
            )
        saved = float(record.get("saved_at") or (run / KEPT_MODEL).stat().st_mtime)
        return [Checkpoint(int(record["timesteps"]), run / KEPT_MODEL, clock(saved))]
    final = run / "model.zip"
    if not final.is_file():
        raise FileNotFoundError(f"no final model.zip in {run}")
    steps = max((c.steps for c in checkpoints(run)), default=0)
    return [Checkpoint(steps, final, clock(final.stat().st_mtime))]


def checkpoints(run: Path) -> list[Checkpoint]:
    """The run's checkpoints (``checkpoints/*_<steps>_steps.zip``), oldest first."""
    clock = run_clock(run)
    found = []
    for path in (run / "checkpoints").glob("*_steps.zip"):
        match = _STEPS.search(path.name)
        if match:
            found.append(Checkpoint(int(match[1]), path, clock(path.stat().st_mtime)))
    return sorted(found, key=lambda c: c.steps)


def _evaluation(
    env: LabEnv, checkpoint: Checkpoint, out: Path, eval_time: float, double: bool
) -> tuple[list[str], str]:
    argv = [
        "evaluate",
        env.name,
        "--policy",
        str(checkpoint.model),
        "--all-starts",
        "--episode-time",
        repr(float(eval_time)),
        "--out",
        str(out),
    ]
    if double:
        argv.append("--double")
    return argv, f"evaluating {checkpoint.model.name}"


def _settled(summary: dict[str, Any], floor: Reference) -> list[float]:
    """The settled fraction of the floor from each held-out start, in start order."""
    episodes = episodes_by_start(summary)
    values = [e.get("settled_floor_fraction") for e in episodes]
    if any(v is None for v in values):
        raise ValueError(
            f"an evaluation has no settled {floor.metric}: its episodes are shorter than the "
            f"{floor.settle_time:g} s of transient; raise --eval-time"
        )
    return [float(v) for v in values]


def scan_run(
    run: Path,
    env: LabEnv,
    out: Path,
    *,
    fractions: Sequence[float] = (0.9, 0.95),
    eval_time: float = 4.0,
    workers: int = 1,
    double: bool = False,
    which: str = "checkpoints",
) -> RunScan:
    """Evaluate ``run``'s models (``which``: :func:`candidates`) in order until one
    reaches ``max(fractions)``."""
    floor = env.require("reference", "time-to-floor")
    found = candidates(run, which)
    if not found:
        raise FileNotFoundError(
            f"no checkpoints in {run / 'checkpoints'}: train with --checkpoint-every"
        )
    scan = RunScan(run, tuple(fractions), last_steps=found[-1].steps, which=which)
    scan.last_seconds = found[-1].seconds
    goal = max(fractions)
    for first in range(0, len(found), max(1, workers)):
        batch = found[first : first + max(1, workers)]
        where = {c.steps: out / (which if which != "checkpoints" else str(c.steps)) for c in batch}
        pending = [
            _evaluation(env, c, where[c.steps], eval_time, double)
            for c in batch
            if not evaluated(where[c.steps], c.model)
        ]
        run_commands(pending, workers, "time-to-floor")
        for c in batch:
            summary = json.loads((where[c.steps] / "summary.json").read_text())
            per_start = _settled(summary, floor)
            scan.rows.append(
                {
                    "steps": c.steps,
                    "seconds": round(c.seconds, 1),
                    "settled_floor_fraction": float(np.mean(per_start)),
                    "per_start": per_start,
                }
            )
        if any(r["settled_floor_fraction"] >= goal for r in scan.rows):
            break
    return scan


def median_time(seconds: Sequence[float], reps: int = 2000) -> dict[str, Any]:
    """The median over runs with its 95 % bootstrap interval; ``inf`` marks a run that
    never reached the fraction (then the interval's upper end is open: ``inf``)."""
    values = np.asarray(seconds, dtype=float)
    median = float(np.median(values))
    if values.size < 2:
        return {"median": median, "low": median, "high": median, "runs": int(values.size)}
    if np.all(np.isfinite(values)):
        from gymprecice_lab.benchmarking.stats import estimate

        e = estimate(values.reshape(-1, 1), "median", reps=reps)
        return {"median": e.value, "low": e.low, "high": e.high, "runs": e.runs}
    # censored runs: resample with the never-reached ones as slower than all others
    rng = np.random.default_rng(0)
    finite_max = float(np.max(values[np.isfinite(values)])) if np.isfinite(values).any() else 0.0
    ranked = np.where(np.isfinite(values), values, finite_max + 1.0)
    medians = np.median(rng.choice(ranked, size=(reps, values.size), replace=True), axis=1)
    low, high = np.percentile(medians, [2.5, 97.5])
    return {
        "median": median,
        "low": float(low) if low <= finite_max else math.inf,
        "high": float(high) if high <= finite_max else math.inf,
        "runs": int(values.size),
        "not_reached": int(np.sum(~np.isfinite(values))),
    }


def summarise(scans: Sequence[RunScan], fractions: Sequence[float]) -> dict[str, Any]:
    """Per fraction: each run's seconds and steps, and the median with its interval."""
    out: dict[str, Any] = {}
    for fraction in fractions:
        times, steps = [], []
        for scan in scans:
            row = scan.first_reaching(fraction)
            times.append(row["seconds"] if row else math.inf)
            steps.append(row["steps"] if row else None)
        out[f"{fraction:g}"] = {"seconds": times, "steps": steps, **median_time(times)}
    return out


def _write(out: Path, scans: Sequence[RunScan], summary: dict[str, Any], settings: dict) -> None:
    out.mkdir(parents=True, exist_ok=True)
    payload = {"settings": settings, "summary": summary, "runs": [s.as_dict() for s in scans]}
    (out / "time_to_floor.json").write_text(
        json.dumps(payload, indent=2, default=lambda v: None) + "\n"
    )
    with (out / "time_to_floor.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["run", "steps", "seconds", "settled_floor_fraction", "per_start"])
        for scan in scans:
            for row in scan.rows:
                writer.writerow(
                    [
                        scan.run.name,
                        row["steps"],
                        row["seconds"],
                        f"{row['settled_floor_fraction']:.4f}",
                        " ".join(f"{v:.4f}" for v in row["per_start"]),
                    ]
                )


def _trained_env(run: Path) -> str:
    """The env id a training run recorded in its manifest."""
    try:
        return str(json.loads((run / "manifest.json").read_text())["settings"]["env_id"])
    except (OSError, ValueError, KeyError, TypeError):
        raise LabEnvError(
            f"{run} is not a training run of `gymprecice train` (no readable manifest.json "
            "recording its env); give a training directory, or pass --env"
        ) from None


def time_to_floor_command(settings: TimeToFloorSettings) -> int:
    """``gymprecice time-to-floor RUN [RUN ...] [--env ENV]``."""
    from gymprecice_lab.rollouts.sweep import parse_grid

    try:
        env = find_lab_env(settings.env or _trained_env(settings.runs[0]))
        floor = env.require("reference", "time-to-floor")
    except LabEnvError as exc:
        print(f"gymprecice time-to-floor: {exc}", file=sys.stderr)
        return 2
    fractions = parse_grid(settings.fractions, "fractions")
    if not all(0 < f <= 1.5 for f in fractions):
        print(
            "gymprecice time-to-floor: --fractions are fractions of the floor, e.g. 0.9,0.95",
            file=sys.stderr,
        )
        return 2
    if settings.eval_time <= floor.settle_time:
        print(
            f"gymprecice time-to-floor: --eval-time {settings.eval_time:g} leaves no settled flow "
            f"after {floor.settle_time:g} s of transient; give more",
            file=sys.stderr,
        )
        return 2
    if not settings.double:
        from gymprecice_lab.common.requirements import require_solvers

        status = require_solvers(env, "time-to-floor", verbose=False)
        if status:
            return status
    out = (settings.out or (settings.runs[0] / "time-to-floor")).resolve()
    scans = []
    for i, run in enumerate(settings.runs):
        run = run.resolve()
        # each run's evaluations under its own name: a later scan of more runs reuses them
        unique = len({r.resolve().name for r in settings.runs}) == len(settings.runs)
        where = out / (run.name if unique else f"run_{i}")
        try:
            scan = scan_run(
                run,
                env,
                where,
                fractions=fractions,
                eval_time=settings.eval_time,
                workers=settings.workers,
                double=settings.double,
                which=settings.model,
            )
        except CommandFailed as exc:  # an evaluation failed; it said why
            return int(exc.code or 1)
        except (FileNotFoundError, ValueError) as exc:
            print(f"gymprecice time-to-floor: {run}: {exc}", file=sys.stderr)
            return 2
        scans.append(scan)
        if settings.model != "checkpoints":
            _say_model(run, scan, settings.model)
        _say_first(run, scan, fractions)
    summary = summarise(scans, fractions)
    _write(
        out,
        scans,
        summary,
        {
            "env": env.name,
            "fractions": fractions,
            "eval_time": settings.eval_time,
            "model": settings.model,
            "floor": asdict(floor),
        },
    )
    if len(scans) > 1:
        _say_medians(summary, fractions)
    print(f"gymprecice time-to-floor: wrote {out / 'time_to_floor.json'} and time_to_floor.csv")
    return 0


def _say_model(run: Path, scan: RunScan, which: str) -> None:
    """The model scanned and its settled fraction of the floor from each held-out start."""
    row = scan.rows[0]
    starts = ", ".join(f"{v:.1%}" for v in row["per_start"])
    print(
        f"gymprecice time-to-floor: {run.name}: the {which} model ({row['steps']:,} steps, saved "
        f"{duration_text(row['seconds'])} after the training command started): "
        f"{row['settled_floor_fraction']:.1%} of the floor once settled, the mean over "
        f"{len(row['per_start'])} held-out start(s) ({starts})"
    )


def _say_first(run: Path, scan: RunScan, fractions: list[float]) -> None:
    """One line per fraction: the run's first model scanned that reached it, or none."""
    for fraction in fractions:
        row = scan.first_reaching(fraction)
        model = "checkpoint" if scan.which == "checkpoints" else f"the {scan.which} model,"
        where = (
            f"{model} {row['steps']:,} steps, {duration_text(row['seconds'])} after the "
            "training command started"
            if row
            else f"not within its {scan.last_steps:,} steps ({duration_text(scan.last_seconds)})"
        )
        print(f"gymprecice time-to-floor: {run.name}: {fraction:.0%} of the floor: {where}")


def _say_medians(summary: dict[str, Any], fractions: list[float]) -> None:
    """One line per fraction: the median time over the runs and its interval."""
    for fraction in fractions:
        s = summary[f"{fraction:g}"]
        print(
            f"gymprecice time-to-floor: {fraction:.0%} of the floor: median "
            f"{duration_text(s['median'])} [{duration_text(s['low'])}, {duration_text(s['high'])}] over "
            f"{s['runs']} runs"
        )
