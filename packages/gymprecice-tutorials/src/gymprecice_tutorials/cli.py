"""``gymprecice train | evaluate | baseline | open-loop | plot``: the tutorials' commands.

Added to the ``gymprecice`` command line by the tutorials plugin. Every command that runs
an environment writes into one output directory (``--out``, default
``runs/<env>/<command>``) its results and a ``manifest.json`` (versions, solver checks,
case file hashes, seeds, command line), so the directory alone says how it was made::

    gymprecice train jet-cylinder --require-solvers --n-envs 4 --timesteps 100000
    gymprecice evaluate jet-cylinder --time 10
    gymprecice baseline jet-cylinder --time 10
    gymprecice open-loop jet-cylinder --amplitude 0.5 --frequency 3
    gymprecice plot runs/jet-cylinder/train runs/jet-cylinder/evaluate \\
        --baseline runs/jet-cylinder/baseline

``--double`` runs any of them against gymprecice's preCICE test double with a scripted
fake flow (seconds, no solver needed); ``--require-solvers`` refuses to start unless
``gymprecice doctor`` finds what the environment needs.

This module only builds parsers; the work is imported when a command runs, so listing
``gymprecice --help`` never loads torch or matplotlib.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from gymprecice_tutorials.plugin import ENVIRONMENTS

__all__ = ["add_commands"]


def _json_object(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError("must be a JSON object, e.g. '{\"lift_penalty\": 0.1}'")
    return value


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


def _env_options(p: argparse.ArgumentParser, *, horizon: float | None) -> None:
    p.add_argument(
        "env",
        metavar="ENV",
        help=f"environment: {', '.join(ENVIRONMENTS)} (or its gymnasium id)",
    )
    p.add_argument("--out", type=Path, help="output directory (default: runs/<env>/<command>)")
    p.add_argument(
        "--double",
        action="store_true",
        help="run against gymprecice's preCICE test double with a scripted fake flow "
        "(no preCICE, no OpenFOAM; for trying the pipeline and for tests)",
    )
    p.add_argument(
        "--require-solvers",
        action="store_true",
        help="stop at once, with `gymprecice doctor`'s explanation, unless preCICE and the "
        "solvers this environment needs are installed",
    )
    p.add_argument("--case", type=Path, help="a case directory of your own instead of the recipe")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--episode-time",
        type=_positive_float,
        default=None,
        metavar="SECONDS",
        help="simulated seconds per episode of a packaged case"
        + (f" (default {horizon:g})" if horizon else " (default: the case's)"),
    )
    p.set_defaults(default_episode_time=horizon)
    p.add_argument(
        "--env-kwargs",
        type=_json_object,
        default={},
        metavar="JSON",
        help="extra keyword arguments of the environment, e.g. '{\"lift_penalty\": 0.1}'",
    )


def add_commands(sub: Any) -> None:
    """Add the tutorials' sub-commands to ``gymprecice``'s argparse sub-parsers."""
    p = sub.add_parser(
        "train",
        help="train a PPO controller (Stable-Baselines3) on N parallel environments",
        description="Train PPO on a tutorial environment. Resumes from the newest "
        "checkpoint in --out unless --fresh is given.",
    )
    _env_options(p, horizon=None)
    p.add_argument("--n-envs", type=_positive_int, default=1, help="parallel environments")
    p.add_argument(
        "--timesteps", type=_positive_int, default=100_000, help="total actions (env steps)"
    )
    p.add_argument(
        "--n-steps",
        type=_positive_int,
        default=80,
        help="actions per env per PPO update (default 80: one jet-cylinder episode)",
    )
    p.add_argument(
        "--batch-size",
        type=_positive_int,
        default=80,
        help="PPO mini-batch size (default 80: divides every n_steps x n_envs buffer of 80s)",
    )
    p.add_argument("--n-epochs", type=_positive_int, default=10)
    p.add_argument("--learning-rate", type=_positive_float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--net", default="512,512", help="hidden layer sizes of policy and value nets")
    p.add_argument(
        "--checkpoint-every",
        type=_positive_int,
        default=None,
        metavar="STEPS",
        help="save a checkpoint every this many env steps (default: every 10 updates)",
    )
    p.add_argument("--fresh", action="store_true", help="start over even if --out has checkpoints")
    p.add_argument(
        "--vec-env",
        choices=("auto", "resilient", "subproc", "dummy"),
        default="auto",
        help="vector env: fault-tolerant subprocesses (auto, when available), plain SB3 "
        "subprocesses, or all in this process (debugging)",
    )
    p.add_argument("--no-progress-bar", action="store_true", help="no progress bar")
    p.add_argument("--device", default="cpu", help="torch device (default cpu)")
    p.set_defaults(func=_run("train"))

    p = sub.add_parser(
        "evaluate",
        help="run a trained policy deterministically over a long horizon",
    )
    _env_options(p, horizon=10.0)
    p.add_argument(
        "--model",
        type=Path,
        help="model .zip or a training directory (default: runs/<env>/train)",
    )
    p.add_argument("--episodes", type=_positive_int, default=1)
    p.add_argument("--stochastic", action="store_true", help="sample actions instead")
    p.set_defaults(func=_run("evaluate"))

    p = sub.add_parser("baseline", help="run the uncontrolled flow (zero action)")
    _env_options(p, horizon=10.0)
    p.add_argument("--episodes", type=_positive_int, default=1)
    p.set_defaults(func=_run("baseline"))

    p = sub.add_parser("open-loop", help="run a sinusoidal open-loop controller")
    _env_options(p, horizon=10.0)
    p.add_argument(
        "--amplitude",
        type=float,
        default=0.5,
        help="amplitude as a fraction of the action bound (default 0.5)",
    )
    p.add_argument(
        "--frequency",
        type=_positive_float,
        default=None,
        help="frequency in Hz (default: 3 for the cylinders, 0.5 for the flap)",
    )
    p.add_argument("--phase", type=float, default=0.0, help="phase in radians")
    p.add_argument("--episodes", type=_positive_int, default=1)
    p.set_defaults(func=_run("open-loop"))

    p = sub.add_parser(
        "plot",
        help="draw PNGs: training reward, action history, Cd/Cl against the baseline",
    )
    p.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="output directories")
    p.add_argument("--baseline", type=Path, help="a baseline run to compare Cd/Cl with")
    p.add_argument("--out", type=Path, help="where PNGs go (default: <first RUN>/plots)")
    p.set_defaults(func=_plot)


def _run(command: str) -> Any:
    def handler(args: argparse.Namespace) -> int:
        if command == "train":
            from gymprecice_tutorials.train import train_command

            return train_command(args)
        from gymprecice_tutorials.evaluate import rollout_command

        return rollout_command(command, args)

    return handler


def _plot(args: argparse.Namespace) -> int:
    from gymprecice_tutorials.plots import plot_command

    return plot_command(args)
