"""``gymprecice evaluate | baseline | open-loop | feedback | sweep | compare``: their
parsers."""

from __future__ import annotations

import functools
from pathlib import Path

from gymprecice_lab.cli import options as o
from gymprecice_lab.cli.command import Command, run
from gymprecice_lab.common.registered_env import lab_envs

__all__ = ["commands"]


def commands() -> list[Command]:
    return [*_rollouts(), _sweep(), _compare()]


def _rollouts() -> list[Command]:
    env = o.env_options(rollout=True)
    return [
        Command(
            "evaluate",
            "run a trained policy deterministically over a long horizon",
            "Run a trained policy (deterministic: its mean action) for whole "
            "episodes and write history.csv, coefficients.csv and summary.json (mean and std "
            "over the episodes; the % change against --baseline when given).",
            (
                *env,
                o.POLICY,
                o.MODEL,
                o.EPISODES,
                o.ALL_STARTS,
                o.VALIDATION_STARTS,
                o.VIDEO,
                o.STOCHASTIC,
                o.BASELINE,
            ),
            functools.partial(run, "evaluate"),
        ),
        Command(
            "baseline",
            "run the env uncontrolled (the zero action clipped into the action box)",
            "Run the env uncontrolled: the zero action clipped into the action box, in "
            "the env's own units (the cylinders: jets closed, cylinder at rest), with the "
            "env keywords of its lab card's 'uncontrolled' where it declares them: what a "
            "controller is judged against; same files as evaluate.",
            (*env, o.EPISODES, o.ALL_STARTS, o.VALIDATION_STARTS, o.VIDEO),
            functools.partial(run, "baseline"),
        ),
        Command(
            "open-loop",
            "run a sinusoidal open-loop controller",
            "Force the env with a sinusoid on every action dimension, the classic "
            "open-loop control a learned controller should beat (at --frequency, else its "
            "lab card's open_loop_frequency, else a tenth of its action rate); same files "
            "as evaluate.",
            (
                *env,
                *o.OPEN_LOOP,
                o.EPISODES,
                o.ALL_STARTS,
                o.VALIDATION_STARTS,
                o.VIDEO,
                o.BASELINE,
            ),
            functools.partial(run, "open-loop"),
        ),
        Command(
            "feedback",
            "run the env's classical feedback: its own law, or a metric fed back",
            "Run the env's classical feedback controller, the textbook first one a learned "
            "controller should beat; same files as evaluate. An env whose lab card names a "
            "feedback law of its own (feedback_law) runs one point of it: --law NAME=V;... "
            "with one value per parameter. Otherwise one of the env's step metrics (--signal, "
            "else its card's feedback_signal) is fed back to the actuator: a = clip(centre - "
            "gain * half_range * signal(t - delay actions)). `gymprecice sweep` tunes either "
            f"(--feedback-grid, --feedback-gains/--feedback-delays). {_feedback_listing()}",
            (*env, *o.FEEDBACK, o.EPISODES, o.ALL_STARTS, o.VALIDATION_STARTS, o.VIDEO, o.BASELINE),
            functools.partial(run, "feedback"),
        ),
    ]


def _sweep() -> Command:
    return Command(
        "sweep",
        "run the open-loop forcings a learned controller must beat",
        "Run the env uncontrolled, N constant actions across the action box, "
        "a grid of sinusoids (amplitude x frequency) and, with --feedback-gains or "
        "--feedback-grid, its classical feedback, on its held-out starts (else seeds); "
        "write sweep.csv, sweep.json (best constant, best sinusoid) and sweep.png. "
        "--starts validation runs them on the env's validation starts instead: a baseline "
        "tuned there, as a trained model is chosen, never sees the held-out starts; run "
        "its best point on those afterwards.",
        (
            *o.env_options(rollout=True),
            *o.SWEEP_GRID,
            o.EPISODES.but(
                default=None,
                help="starts per controller (default: 3 on the held-out starts; with "
                "--starts validation, each validation start once)",
            ),
            o.option(
                "--starts",
                choices=("held-out", "validation"),
                default="held-out",
                help="the starts every controller runs from: the held-out ones (what compare "
                "and benchmark read), or the validation ones (those that choose a trained "
                "model: tune a baseline there, then run its best point on the held-out starts)",
            ),
            o.workers_option("controllers run at once, each with its own env and core"),
        ),
        functools.partial(run, "sweep"),
    )


def _compare() -> Command:
    return Command(
        "compare",
        "compare evaluated controllers with the uncontrolled env and the best open loop",
        "Read gymprecice sweep outputs (the open-loop candidates) and evaluate / "
        "baseline / open-loop outputs (the controllers to judge), all on the same held-out "
        "starts, and write compare.md and compare.json: the objective per start, and each "
        "controller's margin over the uncontrolled env, the best constant and the best "
        "sinusoid, per start and as mean and spread. Runs nothing.",
        (
            o.runs_argument("output directories"),
            o.OUT.but(help="where to write (None: beside RUN)"),
            o.VIDEO.but(
                nargs=None,
                const=None,
                type=Path,
                help="also put the uncontrolled env (a baseline RUN made with --video) and each "
                "controlled one (evaluate RUNs made with --video) side by side, from the same "
                "start, in FILE.mp4 or FILE.gif (several starts: FILE-start-K.mp4)",
            ),
        ),
        functools.partial(run, "compare"),
    )


def _feedback_listing() -> str:
    """Each installed env's classical feedback, as its card declares it (for --help)."""
    envs = lab_envs()
    laws = [e.name for e in envs if e.feedback_law]
    signals: dict[str, list[str]] = {}
    for env in envs:
        if env.feedback_signal and not env.feedback_law:
            signals.setdefault(env.feedback_signal, []).append(env.name)
    parts = [f"{', '.join(names)}: {signal} fed back" for signal, names in signals.items()]
    if laws:
        parts.append(f"{', '.join(laws)}: a law of its own")
    return f"Installed: {'; '.join(parts)}." if parts else ""
