"""``gymprecice sweep``: the open-loop forcings a learned controller must beat, in one table.

A trained policy is worth something only if it beats what needs no learning: the
uncontrolled flow, the best *constant* actuation and the best *open-loop sinusoid*. This
command runs all of them on the environment's held-out starts (``split="eval"``, the starts
that ``evaluate`` uses; episode k from held-out start k, as ``evaluate --all-starts``) and
writes, under ``--out``:

* ``<label>/``: each controller's rollout (``history.csv``, ``summary.json``), as
  ``baseline`` / ``open-loop`` write them;
* ``sweep.csv`` and ``sweep.json``: per controller the objective on every start, its mean,
  its standard deviation and its spread (max - min) over the starts; the best constant,
  the best sinusoid and, with ``--feedback-gains``, the best classical feedback law
  (:mod:`gymprecice_lab.rollouts.feedback`: a gain x delay grid), or for an env that names
  its own law (the heated plate's PID) the best point of ``--feedback-grid``;
* ``sweep.png``: the objective against the constant action and the sinusoids' grid.

The objective is the environment's (its lab card's ``objective``, lower is better unless
the card says ``maximize``; for the flap the mean tip-displacement magnitude), else the
negated mean reward per action.

``--starts validation`` runs every controller from the env's *validation* starts instead
(:func:`~gymprecice_lab.common.starts.validation_starts`: the starts that choose the model
a training run keeps, disjoint from the held-out ones). That tunes a baseline as a
learned controller is chosen, without seeing the starts it is judged on: take the best
point from ``sweep.json`` and run it on the held-out starts (``gymprecice sweep`` with
that one point, or ``gymprecice feedback --law``). Such a sweep records its starts in
``sweep.json`` and its manifest, and ``gymprecice compare`` refuses it.

Every controller's rollout is independent of the others, so ``--workers N`` spreads them
over N processes, each with its own env (``<out>/envs/env_<k>``) and solver; the table is
the same as from one worker. A controller's rollout counts as finished once its
``summary.json`` is written: a sweep that was stopped (Ctrl-C, SIGTERM, or killed outright:
its workers die with it), or whose worker failed, keeps those when run again with the same
rollouts (env, its settings, starts, seed) and runs only the others.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.plugin.card import FeedbackLaw, load_object
from gymprecice_lab.common.command_runs import die_with_parent
from gymprecice_lab.common.manifest import write_manifest
from gymprecice_lab.common.registered_env import LabEnv, LabEnvError, find_lab_env
from gymprecice_lab.common.requirements import require_solvers
from gymprecice_lab.common.starts import (
    StartsError,
    describe_starts,
    held_out_starts,
    validation_starts,
)
from gymprecice_lab.common.wrapped_env import make_env_checked
from gymprecice_lab.rollouts.command_settings import SweepSettings
from gymprecice_lab.rollouts.controllers import sine_controller, zero_controller
from gymprecice_lab.rollouts.feedback import FeedbackController, own_law_grid
from gymprecice_lab.rollouts.records import episodes_by_start
from gymprecice_lab.rollouts.rollout import rollout

#: ``--episodes``' default on the held-out starts: three (from each of the env's held-out
#: starts in turn, or three seeds where it has none); on the validation starts, each once
HELD_OUT_EPISODES = 3

__all__ = [
    "SweepJob",
    "SweepResult",
    "constant_controller",
    "objective",
    "parse_grid",
    "run_jobs",
    "sweep_command",
    "sweep_jobs",
]


@dataclass
class SweepResult:
    """One controller of the sweep and its objective on each held-out start."""

    label: str
    kind: str  # "uncontrolled" | "constant" | "sinusoid" | "feedback"
    settings: dict[str, float] = field(default_factory=dict)
    objectives: list[float] = field(default_factory=list)

    @property
    def mean(self) -> float:
        return float(np.mean(self.objectives))

    @property
    def std(self) -> float:
        return float(np.std(self.objectives))

    @property
    def spread(self) -> float:
        return float(np.max(self.objectives) - np.min(self.objectives))

    def row(self) -> dict[str, Any]:
        row: dict[str, Any] = {"label": self.label, "kind": self.kind, **self.settings}
        row.update({f"start_{i}": v for i, v in enumerate(self.objectives)})
        row.update({"mean": self.mean, "std": self.std, "spread": self.spread})
        return row


def parse_grid(text: str, name: str) -> list[float]:
    """``"0.25,0.5,1"`` -> ``[0.25, 0.5, 1.0]``; a clear error for anything else."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(
            f"gymprecice sweep: --{name} takes comma-separated numbers, got {text!r}"
        ) from None
    if not values or not all(math.isfinite(v) for v in values):
        raise SystemExit(f"gymprecice sweep: --{name} needs at least one finite number")
    return values


def constant_controller(space: gym.Space, fraction: float) -> Callable[[Any, float], Any]:
    """Hold ``low + fraction * (high - low)`` on every dimension of a bounded Box."""
    if not isinstance(space, gym.spaces.Box) or not np.all(np.isfinite(space.low)):
        raise TypeError(f"a constant sweep needs a bounded Box action space, got {space}")
    action = (space.low + fraction * (space.high - space.low)).astype(space.dtype)
    return lambda obs, t: action


def objective(env_info: LabEnv, episode: dict[str, Any]) -> float:
    """An episode's objective, lower is better: the mean of the card's ``objective`` metric
    (negated where the card says ``maximize``), else the negated mean reward per action."""
    if env_info.objective:
        value = float(episode[f"mean_{env_info.objective}"])
        return -value if env_info.maximize else value
    return -float(episode["return"]) / max(1, int(episode["steps"]))


@dataclass(frozen=True)
class SweepJob:
    """One controller to run: what ``sweep.csv`` records of it, and how to build it."""

    label: str
    kind: str  # "uncontrolled" | "constant" | "sinusoid" | "feedback"
    settings: dict[str, float]
    #: the constant's place in the action box (0: low, 1: high); the others ignore it
    fraction: float = 0.5


def sweep_jobs(
    box: tuple[float, float],
    constants: int,
    centre: float,
    amplitudes: Sequence[float],
    frequencies: Sequence[float],
    gains: Sequence[float],
    delays: Sequence[int],
    signal: str | None,
    law: FeedbackLaw | None = None,
    law_points: Sequence[dict[str, float]] = (),
) -> list[SweepJob]:
    """Every controller of the sweep, in the order of its table (``box``: the action's
    low and high on its first dimension, for the constants' labels; ``law_points``: the
    points of the env's own feedback law to run)."""
    low, high = box
    jobs = [SweepJob("uncontrolled", "uncontrolled", {})]
    for k in range(constants):
        fraction = k / (constants - 1) if constants > 1 else 0.5
        value = float(low + fraction * (high - low))
        jobs.append(SweepJob(f"constant-{value:g}", "constant", {"action": value}, fraction))
    for amplitude in amplitudes:
        for frequency in frequencies:
            jobs.append(
                SweepJob(
                    f"sine-c{centre:g}-a{amplitude:g}-f{frequency:g}",
                    "sinusoid",
                    {"centre": centre, "amplitude": amplitude, "frequency": frequency},
                )
            )
    for gain in gains:
        for delay in delays:
            jobs.append(
                SweepJob(
                    f"feedback-{signal}-g{gain:g}-d{delay}",
                    "feedback",
                    {"gain": gain, "delay": delay},
                )
            )
    if law is not None:
        for point in law_points:
            jobs.append(SweepJob(f"feedback-{law.label(point)}", "feedback", dict(point)))
    return jobs


def _controller_of(
    job: SweepJob, space: gym.Space, signal: str | None, law: FeedbackLaw | None = None
) -> Any:
    if job.kind == "uncontrolled":
        return zero_controller(space)
    if job.kind == "constant":
        return constant_controller(space, job.fraction)
    if job.kind == "sinusoid":
        s = job.settings
        return sine_controller(space, s["amplitude"], s["frequency"], centre=s["centre"])
    if law is not None:
        return law.build(space, job.settings)
    return FeedbackController(space, str(signal), job.settings["gain"], int(job.settings["delay"]))


def run_jobs(spec: dict[str, Any], jobs: Sequence[SweepJob], index: int) -> None:
    """Run ``jobs`` one after the other on env ``index`` (its own run directory), each
    into ``<out>/<label>``. Module-level, so that a worker process can run its share."""
    env_info = find_lab_env(spec["env"])
    law = load_object(spec["law"], "feedback_law") if spec.get("law") else None
    out = Path(spec["out"])
    env: gym.Env | None = None
    env_uncontrolled: bool | None = None
    try:
        for job in jobs:
            uncontrolled = job.kind == "uncontrolled"
            if env is None or env_uncontrolled != uncontrolled:
                if env is not None:  # one env per index at a time: they share its directory
                    env.close()
                    env = None
                kwargs = dict(spec["kwargs"])
                if uncontrolled:  # where the action cannot say "uncontrolled", a kwarg does
                    kwargs.update(dict(env_info.baseline_kwargs))
                env = make_env_checked(env_info.name, env_info.env_id, index, kwargs, rescale=False)
                env_uncontrolled = uncontrolled
            controller = _controller_of(job, env.action_space, spec["signal"], law)
            summary = rollout(
                env,
                controller,
                out / job.label,
                episodes=spec["episodes"],
                seed=spec["seed"],
                every_start=True,
                starts=spec.get("starts") or "held-out",
                reference=env_info.reference,
            )
            values = ", ".join(f"{objective(env_info, e):.4g}" for e in summary["episodes"])
            print(f"gymprecice sweep: ran {job.label} ({values})", flush=True)
    finally:
        if env is not None:
            env.close()


def _run_share(parent: int, spec: dict[str, Any], jobs: Sequence[SweepJob], index: int) -> None:
    """:func:`run_jobs` in a worker process that dies with the sweep (``parent``)."""
    die_with_parent(parent)
    run_jobs(spec, jobs, index)


def _finished(out: Path, job: SweepJob, episodes: int) -> dict[str, Any] | None:
    """The summary of a controller that this sweep (or an earlier run of it) finished."""
    try:
        summary = json.loads((out / job.label / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    return summary if len(summary.get("episodes", [])) == episodes else None


def _same_rollouts(out: Path, identity: dict[str, Any]) -> bool:
    """Whether ``out`` holds a sweep whose rollouts ran as this one's would."""
    try:
        saved = json.loads((out / "manifest.json").read_text()).get("settings", {})
    except (OSError, ValueError):
        return False
    return all(
        json.dumps(saved.get(k), sort_keys=True) == json.dumps(v, sort_keys=True)
        for k, v in identity.items()
    )


def _run_workers(spec: dict[str, Any], jobs: list[SweepJob], workers: int) -> None:
    """Spread ``jobs`` round robin over ``workers`` processes, each with its own env and
    run directory (one worker: in this process). A worker that fails leaves its
    unfinished controllers to the caller's check; Ctrl-C stops every worker."""
    import multiprocessing

    if workers <= 1:
        run_jobs(spec, jobs, 0)
        return
    context = multiprocessing.get_context("spawn")  # never fork a process holding threads
    processes = [
        context.Process(
            target=_run_share, args=(os.getpid(), spec, jobs[w::workers], w), name=f"sweep-{w}"
        )
        for w in range(workers)
    ]
    from gymprecice_lab.training.callbacks import stop_signals_interrupt

    try:
        with stop_signals_interrupt():  # SIGTERM / SIGHUP: stop the workers, as Ctrl-C does
            for process in processes:
                process.start()
            for process in processes:
                process.join()
    finally:
        for process in processes:
            if process.is_alive():
                process.terminate()
                process.join(30)


@dataclass(frozen=True)
class _Grid:
    """The sweep's controllers as the options give them, checked."""

    amplitudes: list[float]
    frequencies: list[float]
    gains: list[float]
    delays: list[int]
    signal: str | None
    law: FeedbackLaw | None
    law_points: list[dict[str, float]]


def sweep_command(settings: SweepSettings) -> int:
    """``gymprecice sweep ENV``: uncontrolled, constants and sinusoids on the held-out starts."""
    try:
        env_info = settings.lab_env
    except LabEnvError as exc:
        print(f"gymprecice sweep: {exc}", file=sys.stderr)
        return 2
    grid = _grid(settings, env_info)
    starts = settings.starts
    out = settings.run_dir
    kwargs = settings.constructor_kwargs
    if not settings.double:
        status = require_solvers(env_info, "sweep", verbose=settings.require_solvers, kwargs=kwargs)
        if status:
            return status
    box, validation = _action_box(env_info, kwargs, starts)
    if starts == "validation" and settings.episodes is None:
        settings = dataclasses.replace(settings, episodes=validation)
    elif settings.episodes is None:
        settings = dataclasses.replace(settings, episodes=HELD_OUT_EPISODES)
    jobs = sweep_jobs(
        box,
        settings.constants,
        settings.centre,
        grid.amplitudes,
        grid.frequencies,
        grid.gains,
        grid.delays,
        grid.signal,
        grid.law,
        grid.law_points,
    )
    # what every rollout depends on: a rerun that agrees keeps the controllers it finished
    identity = {
        "env_id": env_info.env_id,
        "env_kwargs": kwargs,
        "episodes": settings.episodes,
        "seed": settings.seed,
        "feedback_signal": grid.signal if grid.gains else None,
        "feedback_law": env_info.feedback_law if grid.law_points else None,
        # None: the held-out starts (as sweeps recorded them before --starts existed)
        "starts": None if starts == "held-out" else starts,
    }
    resumable = _same_rollouts(out, identity)
    write_manifest(
        out,
        command="sweep",
        case_dir=None,
        seeds={"seed": settings.seed},
        settings={
            **identity,
            "constants": settings.constants,
            "centre": settings.centre,
            "amplitudes": grid.amplitudes,
            "frequencies": grid.frequencies,
            "feedback_gains": grid.gains,
            "feedback_delays": grid.delays if grid.gains else [],
            "feedback_grid": [dict(p) for p in grid.law_points],
        },
    )
    todo = [j for j in jobs if not (resumable and _finished(out, j, settings.episodes))]
    if len(todo) < len(jobs):
        print(
            f"gymprecice sweep: {len(jobs) - len(todo)} of {len(jobs)} controllers were "
            "finished by an earlier run of this sweep: kept",
            flush=True,
        )
    if todo and not _run_unfinished(settings, env_info, grid, kwargs, out, todo, starts):
        return 1
    _write(out, _results(out, jobs, env_info, settings.episodes), env_info, starts)
    return 0


def _grid(settings: SweepSettings, env_info: LabEnv) -> _Grid:
    """The options' grids, checked (a ``SystemExit`` naming the option otherwise)."""
    if not 0.0 <= settings.centre <= 1.0:
        raise SystemExit(
            f"gymprecice sweep: --centre is a fraction of the action box, 0 to 1; got {settings.centre}"
        )
    # an empty --amplitudes: no sinusoids (a sweep of the feedback law alone)
    amplitudes = (
        parse_grid(settings.amplitudes, "amplitudes") if settings.amplitudes.strip() else []
    )
    frequencies = parse_grid(settings.frequencies, "frequencies")
    if any(f <= 0 for f in frequencies):
        raise SystemExit("gymprecice sweep: --frequencies must be positive (Hz)")
    gains = parse_grid(settings.feedback_gains, "feedback-gains") if settings.feedback_gains else []
    delays = [int(d) for d in parse_grid(settings.feedback_delays, "feedback-delays")]
    if any(d < 0 for d in delays):
        raise SystemExit("gymprecice sweep: --feedback-delays are whole numbers of actions >= 0")
    law, law_points = _law_points(settings, env_info)
    signal = settings.feedback_signal or env_info.feedback_signal
    if gains and signal is None:
        raise SystemExit(
            f"gymprecice sweep: {env_info.name} has no default feedback signal; pass "
            "--feedback-signal NAME (one of the metrics in its steps' info['metrics']), or "
            "declare the lab card field 'feedback_signal' (docs: Lab reference)"
        )
    return _Grid(amplitudes, frequencies, gains, delays, signal, law, law_points)


def _action_box(
    env_info: LabEnv, kwargs: dict[str, Any], starts: str = "held-out"
) -> tuple[tuple[float, float], int]:
    """The action's low and high on its first dimension, read from an env built (no
    solver starts before a reset) and closed, refused unless a bounded Box; and how many
    validation starts the env has (0 unless ``starts`` is "validation")."""
    probe = make_env_checked(env_info.name, env_info.env_id, 0, kwargs, rescale=False)
    validation = 0
    try:
        space = probe.action_space
        held_out_starts(probe)  # a card that declares starts the env does not name
        if starts == "validation":
            validation = len(validation_starts(probe))
    except StartsError as exc:
        raise SystemExit(f"gymprecice sweep: {exc}") from None
    finally:
        probe.close()
    if not isinstance(space, gym.spaces.Box) or not np.all(np.isfinite(space.low)):
        raise SystemExit(
            f"gymprecice sweep: {env_info.name}'s action space {space} is not a bounded Box; "
            "the sweep's constants and sinusoids need one"
        )
    return (float(np.ravel(space.low)[0]), float(np.ravel(space.high)[0])), validation


def _run_unfinished(
    settings: SweepSettings,
    env_info: LabEnv,
    grid: _Grid,
    kwargs: dict[str, Any],
    out: Path,
    todo: list[SweepJob],
    starts: str = "held-out",
) -> bool:
    """Run the controllers ``todo`` on ``--workers`` workers; whether all finished (those
    that did not are named on stderr)."""
    for job in todo:  # a half-written rollout must not pass for a finished one
        (out / job.label / "summary.json").unlink(missing_ok=True)
    workers = min(max(1, settings.workers), len(todo))
    where = (
        f"{settings.episodes} validation start(s)"
        if starts == "validation"
        else describe_starts(settings.episodes, env_info.held_out_starts)
    )
    print(
        f"gymprecice sweep: {len(todo)} controller(s) x {where} on {workers} worker(s)",
        flush=True,
    )
    spec = {
        "env": env_info.env_id,
        "kwargs": kwargs,
        "out": str(out),
        "episodes": settings.episodes,
        "seed": settings.seed,
        "signal": grid.signal,
        "law": env_info.feedback_law if grid.law_points else None,
        "starts": starts,
    }
    _run_workers(spec, todo, workers)
    failed = [j.label for j in todo if not _finished(out, j, settings.episodes)]
    if failed:
        print(
            f"gymprecice sweep: {len(failed)} controller(s) did not finish "
            f"({', '.join(failed)}); see the worker's output above. The finished ones "
            "are kept: run the same command again to complete the sweep",
            file=sys.stderr,
        )
    return not failed


def _results(out: Path, jobs: list[SweepJob], env_info: LabEnv, episodes: int) -> list[SweepResult]:
    """Every controller's objective on each start, read back from its rollout (and said)."""
    results: list[SweepResult] = []
    for job in jobs:
        summary = _finished(out, job, episodes) or {"episodes": []}
        result = SweepResult(job.label, job.kind, dict(job.settings))
        result.objectives = [objective(env_info, e) for e in episodes_by_start(summary)]
        results.append(result)
        values = ", ".join(f"{v:.4g}" for v in result.objectives)
        print(
            f"gymprecice sweep: {result.label:<24} {result.mean:.4g} ± {result.std:.2g} ({values})"
        )
    return results


def _law_points(
    settings: SweepSettings, env_info: LabEnv
) -> tuple[FeedbackLaw | None, list[dict[str, float]]]:
    """The env's own feedback law and the points of it to run (:func:`own_law_grid`)."""
    try:
        law, grid = own_law_grid(
            env_info.name,
            env_info.feedback_law,
            settings.feedback_gains,
            settings.feedback_grid,
        )
    except ValueError as exc:
        raise SystemExit(f"gymprecice sweep: {exc}") from None
    return law, law.points(grid) if law is not None and grid is not None else []


def best(results: Sequence[SweepResult], kind: str) -> SweepResult | None:
    """The controller of ``kind`` with the lowest mean objective."""
    of_kind = [r for r in results if r.kind == kind]
    return min(of_kind, key=lambda r: r.mean) if of_kind else None


def _write(
    out: Path, results: list[SweepResult], env_info: LabEnv, starts: str = "held-out"
) -> None:
    rows = [r.row() for r in results]
    names = list(dict.fromkeys(name for row in rows for name in row))
    with (out / "sweep.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=names)
        writer.writeheader()
        writer.writerows(rows)
    summary = {
        "starts": starts,
        "controllers": rows,
        "best_constant": best(results, "constant").row() if best(results, "constant") else None,
        "best_sinusoid": best(results, "sinusoid").row() if best(results, "sinusoid") else None,
        "best_feedback": best(results, "feedback").row() if best(results, "feedback") else None,
    }
    # whole or not at all: the benchmark takes a sweep.json as a finished sweep
    tmp = out / ".sweep.json.partial"
    tmp.write_text(json.dumps(summary, indent=2) + "\n")
    os.replace(tmp, out / "sweep.json")
    for kind in ("constant", "sinusoid", "feedback"):
        chosen = best(results, kind)
        if chosen is not None:
            print(
                f"gymprecice sweep: best {kind}: {chosen.label} ({chosen.mean:.4g} ± {chosen.std:.2g})"
            )
    _figure(out / "sweep.png", results, env_info)
    print(f"gymprecice sweep: wrote {out / 'sweep.csv'}, sweep.json and sweep.png")


def _figure(path: Path, results: list[SweepResult], env_info: LabEnv) -> None:
    """``sweep.png``: the objective (named from the card) against the constant action
    (in the card's unit) and over the sinusoids' amplitude x frequency grid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    constants = [r for r in results if r.kind == "constant"]
    if constants:
        x = [r.settings["action"] for r in constants]
        left.errorbar(x, [r.mean for r in constants], yerr=[r.std for r in constants], marker="o")
    for r in results:
        if r.kind == "uncontrolled":
            left.axhline(r.mean, color="k", linestyle="--", label="uncontrolled")
    left.set_xlabel(env_info.action_label("constant action"))
    left.set_ylabel(f"{env_info.objective_label}, mean over starts")
    left.legend()
    sines = [r for r in results if r.kind == "sinusoid"]
    if sines:
        amps = sorted({r.settings["amplitude"] for r in sines})
        freqs = sorted({r.settings["frequency"] for r in sines})
        grid = np.full((len(amps), len(freqs)), np.nan)
        for r in sines:
            grid[amps.index(r.settings["amplitude"]), freqs.index(r.settings["frequency"])] = r.mean
        image = right.imshow(grid, origin="lower", aspect="auto")
        right.set_xticks(range(len(freqs)), [f"{f:g}" for f in freqs])
        right.set_yticks(range(len(amps)), [f"{a:g}" for a in amps])
        right.set_xlabel("frequency (Hz)")
        right.set_ylabel("amplitude (fraction of the half range)")
        fig.colorbar(image, ax=right, label=env_info.objective_label)
    fig.suptitle(env_info.description, fontsize="medium")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
