"""``gymprecice train`` and ``gymprecice tune``: their parsers."""

from __future__ import annotations

import functools
from pathlib import Path

from gymprecice_lab.cli import options as o
from gymprecice_lab.cli.command import Command, run
from gymprecice_lab.cli.options import option, positive_float, positive_int

__all__ = ["commands"]


def commands() -> list[Command]:
    return [_train(), _tune()]


def _tune() -> Command:
    return Command(
        "tune",
        "search hyperparameters (Optuna: TPE sampler, median pruner on validation scores)",
        "Search the hyperparameters of PPO, SAC, TD3 or TQC on a registered environment, as RL "
        "Zoo does: each trial is a `gymprecice train` run in <out>/trials/N, scored by its "
        "kept model (the best on the env's validation starts: the mean return, or the "
        "settled fraction of the floor for an env with a physical reference; held-out "
        "starts are never read), and pruned when its validations lag the others'. A trial whose "
        "solver fails is pruned with its reason recorded. The study is kept in SQLite in "
        "--out (or --storage): the same command resumes a search killed at any point. "
        "Writes best_hyperparams.yml (for train --hyperparams), tune.json, history.png and "
        "importance.png.",
        (
            o.env_argument(),
            o.OUT.but(help="output directory (None: runs/<env>/tune)"),
            o.DOUBLE.but(help="tune on the test double (no solvers; tests and dry runs)"),
            o.SEED,
            o.EPISODE_TIME,
            o.ENV_KWARGS,
            o.ALGO.but(default="sac"),
            option("--trials", type=positive_int, default=20, help="trials in the study"),
            option(
                "--timesteps",
                type=positive_int,
                default=2_000,
                help="env steps per trial (each trial trains from scratch)",
            ),
            option(
                "--n-envs", type=positive_int, default=1, help="parallel environments per trial"
            ),
            option(
                "--validate-every",
                type=positive_int,
                default=400,
                metavar="STEPS",
                help="validate (and report to the pruner) every this many env steps",
            ),
            option(
                "--params",
                type=lambda text: [p.strip() for p in text.split(",") if p.strip()],
                default=None,
                metavar="NAME,...",
                help="search only these parameters of the algorithm's space; the others keep "
                "their defaults (None: all of them)",
            ),
            option(
                "--hyperparams",
                type=Path,
                default=None,
                metavar="FILE.yaml",
                help="hyperparameters every trial keeps (the search does not vary them)",
            ),
            option(
                "--storage",
                default=None,
                metavar="URL",
                help="an Optuna storage URL shared by searches on several machines, e.g. "
                "postgresql://user@host/db (None: sqlite:///<out>/study.db)",
            ),
            option("--study-name", default=None, help="the study's name (None: <env>-<algo>)"),
            option(
                "--n-jobs",
                type=positive_int,
                default=1,
                help="trials at once, each in its own process on the same study",
            ),
            o.RAY.but(
                help="run the --n-jobs workers as Ray tasks on a Ray cluster (auto: the "
                "one this machine joined), each with --n-envs CPUs on one node; the study "
                "must be in a --storage every node reaches (see docs/cluster.md)"
            ),
            option("--no-progress-bar", action="store_true", help="no progress bar"),
        ),
        functools.partial(run, "tune"),
    )


#: ``gymprecice train``'s own options: how it learns, keeps and shows its progress
_TRAINING = (
    option(
        "--hyperparams",
        type=Path,
        default=None,
        metavar="FILE.yaml",
        help="hyperparameters (RL Zoo style: flat, or under the env id); flags override "
        "them; copied into --out. Besides the algorithm's own: net, normalize, robustness, "
        "torch_threads (the learner's CPU threads), noise_type/noise_std and "
        "overlap_updates (SAC, TD3: gradient steps while the solvers compute, "
        "scripts/sac-overlap.yml) and model_ensemble (PPO: model-ensemble PPO, "
        "scripts/ppo-model-ensemble.yml)",
    ),
    o.N_ENVS,
    o.TIMESTEPS,
    option(
        "--n-steps",
        type=positive_int,
        default=None,
        help="PPO: actions per env per update (80: one jet-cylinder episode)",
    ),
    option(
        "--batch-size",
        type=positive_int,
        default=None,
        help="mini-batch size (PPO: at most n_steps x n_envs)",
    ),
    option("--n-epochs", type=positive_int, default=None, help="PPO: epochs per update"),
    option("--learning-rate", type=positive_float, default=None, help="learning rate"),
    option("--gamma", type=float, default=None, help="discount factor"),
    option("--net", default=None, help="hidden layer sizes of policy and value nets, e.g. 64,64"),
    option(
        "--normalize",
        action="store_true",
        help="normalise observations and rewards (VecNormalize); the statistics are "
        "saved beside every model and used by evaluate",
    ),
    option(
        "--shared-policy",
        action="store_true",
        help="a joint multi-agent env (its card's agents): one policy that every agent "
        "shares, trained on each agent's row; --timesteps counts a step per agent",
    ),
)


#: checkpoints, evaluation during training, and how the run shows itself
_KEEPING = (
    option(
        "--checkpoint-every",
        type=positive_int,
        default=None,
        metavar="STEPS",
        help="save a checkpoint every this many env steps (None: every 10 rollouts)",
    ),
    option(
        "--keep-checkpoints",
        type=positive_int,
        default=5,
        metavar="N",
        help="keep the newest N checkpoints and the best (highest mean return)",
    ),
    option(
        "--eval-freq",
        type=positive_int,
        default=None,
        metavar="STEPS",
        help="every this many env steps, score the policy deterministically from the "
        "env's validation starts (never its held-out ones) on a separate env, and keep "
        "the best as best_model.zip, the model evaluate, ship-policy, benchmark and "
        "time-to-floor take (None: at every checkpoint, and once more at the end)",
    ),
    option(
        "--stop-at",
        type=float,
        default=None,
        metavar="SCORE",
        help="stop training at the first validation that scores SCORE or more (the score "
        "the kept model is chosen on: the settled fraction of the drag floor where the "
        "env's card declares one, e.g. 0.95, else the mean validation return); that model "
        "is the kept one, and the same command again does not train on (None: train for "
        "--timesteps)",
    ),
    option(
        "--validation-time",
        type=float,
        default=None,
        metavar="SECONDS",
        help="simulated seconds of each validation episode, for an env that takes "
        "episode_time: e.g. 10 on the cylinders, as long as `evaluate`'s episodes, so that "
        "a policy whose drag drifts after a few seconds is not kept for its start (None: "
        "where the card declares a settled score, its settle time and one training "
        "episode, else one training episode)",
    ),
    option(
        "--n-eval-episodes",
        type=positive_int,
        default=None,
        help="episodes per validation (None: one from each validation start)",
    ),
    option(
        "--no-validation",
        action="store_true",
        help="no validation during training: only the final model.zip is left",
    ),
    o.FRESH,
    option(
        "--vec-env",
        choices=("auto", "resilient", "subproc", "dummy"),
        default="auto",
        help="vector env: fault-tolerant subprocesses (auto, when available), plain SB3 "
        "subprocesses, or all in this process (debugging)",
    ),
    o.RAY,
    option("--no-progress-bar", action="store_true", help="no progress bar"),
    option(
        "--verbose",
        type=int,
        choices=(0, 1, 2),
        default=0,
        help="0: progress bar and summary; 1: SB3's table every rollout; 2: SB3's debug output",
    ),
    option("--device", default="cpu", help="torch device (cuda is refused without CUDA)"),
)


def _train() -> Command:
    return Command(
        "train",
        "train a controller (Stable-Baselines3 PPO, SAC, TD3; sb3-contrib TQC) on N parallel "
        "environments",
        "Train PPO, SAC, TD3 or TQC on a registered environment. Resumes from the newest "
        "checkpoint in --out unless --fresh is given; a resume must use the run's "
        "hyperparameters. Ctrl-C, SIGTERM and SIGHUP save the model and a checkpoint. "
        "Hyperparameters shown as None take the algorithm's default (ppo: n_steps 80, "
        "batch_size 80, n_epochs 10, learning_rate 3e-4, gamma 0.99, net 512,512; sac/td3/tqc: "
        "batch_size 256, net 256,256, SB3's others (tqc: sb3-contrib's), td3 with Gaussian action noise of std "
        "0.1), then --hyperparams, then the flag.",
        (*o.env_options(rollout=False), o.ALGO, *_TRAINING, *_KEEPING),
        functools.partial(run, "train"),
    )
