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
  (:mod:`gymprecice_tutorials.feedback`: a gain x delay grid);
* ``sweep.png``: the objective against the constant action and the sinusoids' grid.

The objective is the environment's (``TutorialEnv.objective``, lower is better; for the flap
the mean tip-displacement magnitude), else the negated mean reward per action.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice_tutorials.environments import TutorialEnv, find_environment
from gymprecice_tutorials.envs import make_env_checked
from gymprecice_tutorials.evaluate import rollout, sine_controller, zero_controller
from gymprecice_tutorials.feedback import FeedbackController
from gymprecice_tutorials.manifest import write_manifest
from gymprecice_tutorials.requirements import require_solvers
from gymprecice_tutorials.train import build_env_kwargs, default_out

__all__ = ["SweepResult", "constant_controller", "objective", "parse_grid", "sweep_command"]


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


def objective(env_info: TutorialEnv, episode: dict[str, Any]) -> float:
    """An episode's objective (lower is better): the env's, else the negated mean reward."""
    if env_info.objective:
        return float(episode[f"mean_{env_info.objective}"])
    return -float(episode["return"]) / max(1, int(episode["steps"]))


def _run(
    env: gym.Env, controller: Any, out: Path, env_info: TutorialEnv, args: argparse.Namespace
) -> list[float]:
    # every controller meets the same starts: episode k runs held-out start k
    summary = rollout(
        env, controller, out, episodes=args.episodes, seed=args.seed, every_start=True
    )
    return [objective(env_info, episode) for episode in summary["episodes"]]


def sweep_command(args: argparse.Namespace) -> int:
    """``gymprecice sweep ENV``: uncontrolled, constants and sinusoids on the held-out starts."""
    try:
        env_info = find_environment(args.env)
    except KeyError as exc:
        print(f"gymprecice sweep: {exc.args[0]}", file=sys.stderr)
        return 2
    if not 0.0 <= args.centre <= 1.0:
        raise SystemExit(
            f"gymprecice sweep: --centre is a fraction of the action box, 0 to 1; got {args.centre}"
        )
    amplitudes = parse_grid(args.amplitudes, "amplitudes")
    frequencies = parse_grid(args.frequencies, "frequencies")
    if any(f <= 0 for f in frequencies):
        raise SystemExit("gymprecice sweep: --frequencies must be positive (Hz)")
    gains = parse_grid(args.feedback_gains, "feedback-gains") if args.feedback_gains else []
    delays = [int(d) for d in parse_grid(args.feedback_delays, "feedback-delays")]
    if any(d < 0 for d in delays):
        raise SystemExit("gymprecice sweep: --feedback-delays are whole numbers of actions >= 0")
    signal = args.feedback_signal or env_info.feedback_signal
    if gains and signal is None:
        raise SystemExit(
            f"gymprecice sweep: {env_info.name} has no default feedback signal; pass "
            "--feedback-signal NAME (one of the metrics in its steps' info['metrics'])"
        )
    out = (args.out or default_out(env_info, "sweep")).resolve()
    kwargs = build_env_kwargs(args, env_info, out)
    if not args.double:
        status = require_solvers(env_info, "sweep", verbose=args.require_solvers)
        if status:
            return status
    results: list[SweepResult] = []

    def report(result: SweepResult) -> None:
        results.append(result)
        values = ", ".join(f"{v:.4g}" for v in result.objectives)
        print(
            f"gymprecice sweep: {result.label:<24} {result.mean:.4g} ± {result.std:.2g} ({values})"
        )

    write_manifest(
        out,
        command="sweep",
        case_dir=None,
        seeds={"seed": args.seed},
        settings={
            "env_id": env_info.env_id,
            "env_kwargs": kwargs,
            "episodes": args.episodes,
            "constants": args.constants,
            "centre": args.centre,
            "amplitudes": amplitudes,
            "frequencies": frequencies,
            "feedback_signal": signal if gains else None,
            "feedback_gains": gains,
            "feedback_delays": delays if gains else [],
        },
    )
    uncontrolled = make_env_checked(
        env_info.name,
        env_info.env_id,
        0,
        {**kwargs, **dict(env_info.baseline_kwargs)},
        rescale=False,
    )
    try:
        result = SweepResult("uncontrolled", "uncontrolled")
        result.objectives = _run(
            uncontrolled,
            zero_controller(uncontrolled.action_space),
            out / "uncontrolled",
            env_info,
            args,
        )
        report(result)
    finally:
        uncontrolled.close()
    env = make_env_checked(env_info.name, env_info.env_id, 0, kwargs, rescale=False)
    try:
        space = env.action_space
        for k in range(args.constants):
            fraction = k / (args.constants - 1) if args.constants > 1 else 0.5
            value = float(
                np.asarray(space.low + fraction * (space.high - space.low)).reshape(-1)[0]
            )
            label = f"constant-{value:g}"
            result = SweepResult(label, "constant", {"action": value})
            result.objectives = _run(
                env, constant_controller(space, fraction), out / label, env_info, args
            )
            report(result)
        for amplitude in amplitudes:
            for frequency in frequencies:
                label = f"sine-c{args.centre:g}-a{amplitude:g}-f{frequency:g}"
                settings = {"centre": args.centre, "amplitude": amplitude, "frequency": frequency}
                result = SweepResult(label, "sinusoid", settings)
                controller = sine_controller(space, amplitude, frequency, centre=args.centre)
                result.objectives = _run(env, controller, out / label, env_info, args)
                report(result)
        for gain in gains:
            for delay in delays:
                label = f"feedback-{signal}-g{gain:g}-d{delay}"
                result = SweepResult(label, "feedback", {"gain": gain, "delay": delay})
                law = FeedbackController(space, str(signal), gain, delay)
                result.objectives = _run(env, law, out / label, env_info, args)
                report(result)
    finally:
        env.close()
    _write(out, results)
    return 0


def best(results: Sequence[SweepResult], kind: str) -> SweepResult | None:
    """The controller of ``kind`` with the lowest mean objective."""
    of_kind = [r for r in results if r.kind == kind]
    return min(of_kind, key=lambda r: r.mean) if of_kind else None


def _write(out: Path, results: list[SweepResult]) -> None:
    rows = [r.row() for r in results]
    names = list(dict.fromkeys(name for row in rows for name in row))
    with (out / "sweep.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=names)
        writer.writeheader()
        writer.writerows(rows)
    summary = {
        "controllers": rows,
        "best_constant": best(results, "constant").row() if best(results, "constant") else None,
        "best_sinusoid": best(results, "sinusoid").row() if best(results, "sinusoid") else None,
        "best_feedback": best(results, "feedback").row() if best(results, "feedback") else None,
    }
    (out / "sweep.json").write_text(json.dumps(summary, indent=2) + "\n")
    for kind in ("constant", "sinusoid", "feedback"):
        chosen = best(results, kind)
        if chosen is not None:
            print(
                f"gymprecice sweep: best {kind}: {chosen.label} ({chosen.mean:.4g} ± {chosen.std:.2g})"
            )
    _figure(out / "sweep.png", results)
    print(f"gymprecice sweep: wrote {out / 'sweep.csv'}, sweep.json and sweep.png")


def _figure(path: Path, results: list[SweepResult]) -> None:
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
    left.set_xlabel("constant action")
    left.set_ylabel("objective (mean over starts)")
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
        fig.colorbar(image, ax=right, label="objective")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
