"""The command lines the benchmark gives its sub-commands.

Each piece of the benchmark is another ``gymprecice`` command (train, evaluate, sweep),
run through that command's own parser, so that a seed trained by the benchmark is the
seed ``gymprecice train`` would have trained. The options every piece shares (the
double, the episode length, the env's keyword arguments) are written once, here.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["common_options", "sweep_argv", "train_argv"]


def common_options(args: argparse.Namespace, episode_time: float | None) -> list[str]:
    """The options every sub-command shares: the double, the solvers' check, the episode
    length (``episode_time``: the training's or the evaluations'), the env's arguments."""
    argv = []
    if args.double:
        argv.append("--double")
    if args.require_solvers:
        argv.append("--require-solvers")
    if episode_time is not None:
        argv += ["--episode-time", repr(float(episode_time))]
    if args.env_kwargs:
        argv += ["--env-kwargs", json.dumps(args.env_kwargs)]
    return argv


def train_argv(
    args: argparse.Namespace, algo: str, seed: int, out: Path, extra: list[str]
) -> list[str]:
    """``gymprecice train`` of one seed of ``algo`` into ``out`` (``extra``: the
    algorithm's ``--train-args``)."""
    return [
        "train",
        args.env,
        "--algo",
        algo,
        "--seed",
        str(seed),
        "--timesteps",
        str(args.timesteps),
        "--n-envs",
        str(args.n_envs),
        "--out",
        str(out),
        "--no-progress-bar",
        *common_options(args, args.episode_time),
        *extra,
    ]


def sweep_argv(args: argparse.Namespace, starts: int, own_law: bool) -> list[str]:
    """``gymprecice sweep`` of the baselines: the benchmark's grids on its ``starts``
    held-out starts (``own_law``: the env has a feedback law of its own, swept over
    ``--feedback-grid``)."""
    argv = [
        "sweep",
        args.env,
        "--episodes",
        str(starts),
        "--constants",
        str(args.constants),
        # NAME=VALUE: a grid may start with a minus sign
        f"--amplitudes={args.amplitudes}",
        f"--frequencies={args.frequencies}",
        f"--centre={args.centre!r}",
        f"--feedback-gains={args.feedback_gains}",
        f"--feedback-delays={args.feedback_delays}",
        "--workers",
        str(args.workers),
        *common_options(args, args.eval_time),
    ]
    if args.feedback_signal:
        argv.append(f"--feedback-signal={args.feedback_signal}")
    if own_law:
        argv.append(f"--feedback-grid={args.feedback_grid}")
    return argv
