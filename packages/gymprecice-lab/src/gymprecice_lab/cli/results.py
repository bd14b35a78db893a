"""``gymprecice plot | ship-policy | policies``: their parsers."""

from __future__ import annotations

import functools
from pathlib import Path

from gymprecice_lab.cli import options as o
from gymprecice_lab.cli.command import Command, run
from gymprecice_lab.cli.options import option, positive_int

__all__ = ["commands"]


def commands() -> list[Command]:
    return [_plot(), *_policies()]


def _plot() -> Command:
    return Command(
        "plot",
        "draw figures: training reward, actions, the objective against the baseline",
        "Draw the return over training, the actions, the objective of the env's lab card "
        "and, for an env with force coefficients (the cylinders), Cd/Cl, of run "
        "directories (train, evaluate, baseline, open-loop, feedback).",
        (
            o.runs_argument("output directories"),
            o.BASELINE.but(metavar=None, help="a baseline run drawn as the reference"),
            o.OUT.but(help="where figures go (None: <first RUN>/plots)"),
            option("--format", choices=("png", "pdf", "svg"), default="png", help="file format"),
            option("--dpi", type=positive_int, default=120, help="resolution of PNGs"),
            option(
                "--labels",
                default=None,
                help="legend names, one per RUN, comma-separated (None: the directory names)",
            ),
            option(
                "--episode",
                type=int,
                default=None,
                help="episode of the rollouts to draw (None: each run's first); titles say which",
            ),
        ),
        functools.partial(run, "plot"),
    )


def _policies() -> list[Command]:
    return [
        Command(
            "ship-policy",
            "copy a training run's kept policy into the package (small: for evaluation)",
            "Copy a `gymprecice train` run's kept model (the best of its validations; "
            "--model final: its model.zip, else its newest checkpoint) into the package's shipped policies as NAME: the model without "
            "the optimizer state (PPO.load still reads it), the VecNormalize statistics and "
            "policy.json (training env and action bound, training command, timesteps, "
            "wall-clock time, source revision, checksums, and the --evaluation result). Then "
            "`gymprecice evaluate ENV --policy NAME` runs it without training.",
            (
                option("train_dir", type=Path, metavar="TRAIN_DIR", help="a training output"),
                option(
                    "--name", default=None, help="the policy's name (None: the training env's name)"
                ),
                option(
                    "--evaluation",
                    type=Path,
                    default=None,
                    metavar="RUN",
                    help="a `gymprecice evaluate` output of this model, whose result is recorded",
                ),
                option(
                    "--into",
                    type=Path,
                    default=None,
                    metavar="DIR",
                    help="ship into DIR (None: $GYMPRECICE_POLICIES_DIR, else the package's "
                    "policies/)",
                ),
                option(
                    "--checkpoint",
                    default=None,
                    metavar="best|STEPS",
                    help="ship a checkpoint instead of the kept model: 'best' (highest mean "
                    "training return, checkpoints/best.json) or a step count",
                ),
                o.MODEL,
                option("--force", action="store_true", help="replace a policy of that name"),
            ),
            functools.partial(run, "ship-policy"),
        ),
        Command(
            "policies",
            "list the trained policies shipped with the package",
            "One line per shipped policy: its training env, steps, action bound "
            "and evaluated objective (its env's; the cylinders: mean Cd). Evaluate one with "
            "`gymprecice "
            "evaluate ENV --policy NAME`.",
            (),
            functools.partial(run, "policies"),
        ),
    ]
