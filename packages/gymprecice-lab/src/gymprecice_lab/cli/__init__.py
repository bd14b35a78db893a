"""``gymprecice train | tune | evaluate | baseline | open-loop | feedback | sweep | compare
| benchmark | time-to-floor | plot | ship-policy | policies``.

Added to the ``gymprecice`` command line by the lab's plugin. ENV is any environment id
that an installed package registers (or the short name its lab card gives it,
:mod:`gymprecice.card`); what a command needs beyond the Gymnasium API it reads from that
card. Every command that runs
an environment writes into one output directory (``--out``, default
``runs/<env>/<command>``) its results and a ``manifest.json`` (versions, solver checks,
case file hashes, seeds, command line), so the directory alone says how it was made::

    gymprecice train jet-cylinder --n-envs 4 --timesteps 100000
    gymprecice tune jet-cylinder-fast --algo sac --trials 12     # Optuna, resumable
    gymprecice evaluate jet-cylinder --episode-time 10
    gymprecice baseline jet-cylinder --episode-time 10
    gymprecice open-loop jet-cylinder --amplitude 0.5 --frequency 3
    gymprecice feedback jet-cylinder-fast --gain 2 --delay 3 --all-starts
    gymprecice sweep perpendicular-flap-fast            # uncontrolled, constants, sinusoids
    gymprecice benchmark jet-cylinder-fast --seeds 5 --algo ppo,sac --workers 2
    gymprecice time-to-floor runs/jet-cylinder-fast/train   # its kept model's share of the floor
    gymprecice compare runs/perpendicular-flap-fast/sweep runs/perpendicular-flap-fast/evaluate
    gymprecice plot runs/jet-cylinder/train runs/jet-cylinder/evaluate \\
        --baseline runs/jet-cylinder/baseline
    gymprecice ship-policy runs/jet-cylinder/train --name jet-cylinder \\
        --evaluation runs/jet-cylinder/evaluate
    gymprecice evaluate jet-cylinder --policy shipped     # no training needed

``--double`` runs any of them against gymprecice's preCICE test double with a scripted
fake flow (seconds, no solver needed). Without it a command stops at once, in one line,
when ``gymprecice doctor`` does not find what the environment needs
(``--require-solvers``: with the doctor's whole report).

This module only composes the parsers, from the option families of
:mod:`gymprecice_lab.cli.options`; the work is imported when a command runs, so listing
``gymprecice --help`` never loads torch or matplotlib.
"""

from __future__ import annotations

import argparse
import functools
import importlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

from gymprecice_lab.cli import options as o
from gymprecice_lab.cli.options import Option, option, positive_float, positive_int
from gymprecice_lab.common.registered_env import lab_envs
from gymprecice_lab.training.hyperparams import ALGORITHMS

__all__ = ["add_commands"]


class Command(NamedTuple):
    """One sub-command: its one-line help, its description, its options in the order
    ``--help`` shows them, and what runs it."""

    name: str
    help: str
    description: str
    options: Sequence[Option]
    run: Callable[[argparse.Namespace], int]


def add_commands(sub: Any) -> None:
    """Add the lab's sub-commands to ``gymprecice``'s argparse sub-parsers."""
    for command in _commands():
        parser = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description,
            formatter_class=argparse.ArgumentDefaultsHelpFormatter,  # every default shown
        )
        for each in command.options:
            each.add_to(parser)
        parser.set_defaults(func=command.run)


def _commands() -> list[Command]:
    return [
        _train(),
        _tune(),
        *_rollouts(),
        _sweep(),
        _compare(),
        _benchmark(),
        _time_to_floor(),
        _plot(),
        *_policies(),
    ]


# -- tune --------------------------------------------------------------------------------------


def _tune() -> Command:
    return Command(
        "tune",
        "search hyperparameters (Optuna: TPE sampler, median pruner on validation scores)",
        "Search the hyperparameters of PPO, SAC or TD3 on a registered environment, as RL "
        "Zoo does: each trial is a `gymprecice train` run in <out>/trials/N, scored by its "
        "kept model (the best mean return on the env's validation starts; held-out starts "
        "are never read), and pruned when its validations lag the others'. A trial whose "
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
            option("--no-progress-bar", action="store_true", help="no progress bar"),
        ),
        functools.partial(_run, "tune"),
    )


# -- train -------------------------------------------------------------------------------------

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
        "train a controller (Stable-Baselines3 PPO, SAC or TD3) on N parallel environments",
        "Train PPO, SAC or TD3 on a registered environment. Resumes from the newest "
        "checkpoint in --out unless --fresh is given; a resume must use the run's "
        "hyperparameters. Ctrl-C, SIGTERM and SIGHUP save the model and a checkpoint. "
        "Hyperparameters shown as None take the algorithm's default (ppo: n_steps 80, "
        "batch_size 80, n_epochs 10, learning_rate 3e-4, gamma 0.99, net 512,512; sac/td3: "
        "batch_size 256, net 256,256, SB3's others, td3 with Gaussian action noise of std "
        "0.1), then --hyperparams, then the flag.",
        (*o.env_options(rollout=False), o.ALGO, *_TRAINING, *_KEEPING),
        functools.partial(_run, "train"),
    )


# -- evaluate, baseline, open-loop, feedback ---------------------------------------------------


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
                o.VIDEO,
                o.STOCHASTIC,
                o.BASELINE,
            ),
            functools.partial(_run, "evaluate"),
        ),
        Command(
            "baseline",
            "run the env uncontrolled (the zero action clipped into the action box)",
            "Run the env uncontrolled: the zero action clipped into the action box, in "
            "the env's own units (the cylinders: jets closed, cylinder at rest), with the "
            "env keywords of its lab card's 'uncontrolled' where it declares them: what a "
            "controller is judged against; same files as evaluate.",
            (*env, o.EPISODES, o.ALL_STARTS, o.VIDEO),
            functools.partial(_run, "baseline"),
        ),
        Command(
            "open-loop",
            "run a sinusoidal open-loop controller",
            "Force the env with a sinusoid on every action dimension, the classic "
            "open-loop control a learned controller should beat (at --frequency, else its "
            "lab card's open_loop_frequency, else a tenth of its action rate); same files "
            "as evaluate.",
            (*env, *o.OPEN_LOOP, o.EPISODES, o.ALL_STARTS, o.VIDEO, o.BASELINE),
            functools.partial(_run, "open-loop"),
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
            (*env, *o.FEEDBACK, o.EPISODES, o.ALL_STARTS, o.VIDEO, o.BASELINE),
            functools.partial(_run, "feedback"),
        ),
    ]


# -- sweep, compare ----------------------------------------------------------------------------


def _sweep() -> Command:
    return Command(
        "sweep",
        "run the open-loop forcings a learned controller must beat",
        "Run the env uncontrolled, N constant actions across the action box, "
        "a grid of sinusoids (amplitude x frequency) and, with --feedback-gains or "
        "--feedback-grid, its classical feedback, on its held-out starts (else seeds); "
        "write sweep.csv, sweep.json (best constant, best sinusoid) and sweep.png.",
        (
            *o.env_options(rollout=True),
            *o.SWEEP_GRID,
            o.EPISODES.but(default=3, help="held-out starts per controller"),
            o.workers_option("controllers run at once, each with its own env and core"),
        ),
        functools.partial(_run, "sweep"),
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
        functools.partial(_run, "compare"),
    )


# -- benchmark, time-to-floor ------------------------------------------------------------------

#: ``benchmark``'s classical baselines: the sweep's grid, smaller (its default frequencies
#: are about the cylinders' shedding frequency), and feedback gains only where the env feeds
#: back a signal
_BASELINE_GRID = o.adapted(
    o.SWEEP_GRID,
    constants={"default": 3, "help": "constant actions in the sweep"},
    amplitudes={"help": "open-loop sinusoid amplitudes (fractions of the half range)"},
    frequencies={"default": "1.5,3,6", "help": "open-loop sinusoid frequencies (Hz)"},
    centre={
        "help": "the sinusoids' centre as a fraction of the action box (0.5: its middle; the "
        "flap's best open loop swings about 0.875)"
    },
    feedback_gains={
        "default": None,
        "help": "feedback gains to sweep (default: -2,-1,1,2 where the feedback is a signal "
        "fed back, none for an env with a feedback law of its own; empty: no feedback "
        "baseline)",
    },
    feedback_delays={
        "default": "0,2,4,6",
        "help": "feedback delays (whole actions; with both signs of gain they span a shedding "
        "period of the cylinders)",
    },
)

#: the evaluation episode's length: benchmark's (its rollout horizon), time-to-floor's
_EVAL_TIME = option(
    "--eval-time",
    type=positive_float,
    default=None,
    metavar="SECONDS",
    help="simulated seconds per evaluation episode (None: the env's rollout horizon)",
)


def _benchmark() -> Command:
    return Command(
        "benchmark",
        "train N seeds per algorithm, evaluate every held-out start, baselines, intervals",
        "Train each algorithm with seeds 0..N-1 (resumably: a manifest per seed), "
        "evaluate every policy deterministically from every held-out start, run the "
        "classical baselines on the same starts (uncontrolled, best constant, best "
        "open-loop sinusoid, best point of the env's classical feedback) and write "
        "results.md/.csv/.json (mean and interquartile mean with 95 % stratified-bootstrap "
        "intervals) and two figures. Settings are recorded in benchmark.json; a rerun "
        "with other settings is refused (--fresh starts over). See docs/benchmark.md.",
        (
            o.env_argument("; evaluated from its held-out starts, else from seeds"),
            option(
                "--seeds",
                type=positive_int,
                default=5,
                help="training seeds per algorithm (0..N-1)",
            ),
            o.ALGO.but(choices=None, help=f"algorithms, comma-separated ({', '.join(ALGORITHMS)})"),
            o.TIMESTEPS.but(
                help="steps per training seed, as train counts them (with --shared-policy in --train-args: a step per agent)"
            ),
            o.N_ENVS.but(help="parallel envs per seed"),
            option(
                "--train-args",
                action="append",
                default=[],
                metavar="[ALGO:]FLAGS",
                help="more `gymprecice train` flags, for every algorithm or (ALGO: prefix) one, "
                "e.g. 'ppo: --n-steps 40 --net 64,64' (repeatable)",
            ),
            o.EPISODE_TIME.but(help="simulated seconds per training episode (None: the case's)"),
            _EVAL_TIME,
            o.ENV_KWARGS.but(
                help="extra keyword arguments of the environment (training and evaluation)"
            ),
            o.OUT.but(help="output (None: runs/<env>/benchmark)"),
            o.DOUBLE.but(help="run on the test double (for tests)"),
            o.REQUIRE_SOLVERS.but(help="the doctor's whole report when missing"),
            option(
                "--retries",
                type=o.non_negative_int,
                default=1,
                help="times a seed whose training fails is run again before the benchmark stops",
            ),
            option(
                "--no-baselines", action="store_true", help="learned controllers only (no sweep)"
            ),
            *_BASELINE_GRID,
            option("--bootstrap-reps", type=positive_int, default=2000, help="bootstrap resamples"),
            o.workers_option("evaluations and baseline rollouts run at once, each on its own core"),
            o.FRESH.but(help="start over, deleting the benchmark's runs"),
            o.RAY.but(
                help="train every seed at once, its envs as Ray actors on this Ray cluster "
                "(auto: the one this machine joined), and run the evaluations and the sweep as "
                "Ray tasks there; needs gymprecice-core[ray], see docs/cluster.md"
            ),
        ),
        functools.partial(_run, "benchmark"),
    )


def _time_to_floor() -> Command:
    return Command(
        "time-to-floor",
        "how far and how soon training runs reached 90 / 95 %% of their env's reference floor",
        "Evaluate each training run's kept model (--model: or its final model, or its "
        "checkpoints in order until one reaches the highest --fractions), deterministically "
        "from every held-out start, against the floor of the env's reference (its lab "
        "card's 'reference': the drop of a metric from its uncontrolled value to the best "
        "it can reach) once settled; print the fraction reached and the wall-clock from the "
        "training command's start to the model's save and, over several runs (seeds), the "
        "median with a 95 % bootstrap interval. Writes time_to_floor.json and .csv. "
        f"{_reference_listing()} See docs/benchmark.md.",
        (
            o.runs_argument("training directories"),
            option(
                "--env",
                default=None,
                help="the environment the runs trained on, one whose lab card declares a "
                "'reference' (None: the first run's, from its manifest)",
            ),
            option("--fractions", default="0.9,0.95", help="fractions of the floor's drop"),
            _EVAL_TIME.but(
                type=float,
                default=4.0,
                metavar=None,
                help="simulated seconds per evaluation episode (the reference's settle_time "
                "at its start is left out as the transient)",
            ),
            o.OUT.but(help="output (None: <first RUN>/time-to-floor)"),
            o.DOUBLE.but(help="evaluate on the test double (tests)"),
            o.workers_option("checkpoints evaluated at once, each on its own core"),
            option(
                "--model",
                choices=("kept", "final", "checkpoints"),
                default="kept",
                help="the model of each run: the kept one (the best of its validations), the "
                "final one, or every checkpoint in order until one reaches the highest fraction",
            ),
        ),
        functools.partial(_run, "time-to-floor"),
    )


# -- plot, ship-policy, policies ---------------------------------------------------------------


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
        functools.partial(_run, "plot"),
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
            functools.partial(_run, "ship-policy"),
        ),
        Command(
            "policies",
            "list the trained policies shipped with the package",
            "One line per shipped policy: its training env, steps, action bound "
            "and evaluated objective (its env's; the cylinders: mean Cd). Evaluate one with "
            "`gymprecice "
            "evaluate ENV --policy NAME`.",
            (),
            functools.partial(_run, "policies"),
        ),
    ]


# -- what the installed envs' cards say, for the help texts ---------------------------------


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


def _reference_listing() -> str:
    """Each installed env's reference, as its card declares it (for --help)."""
    found = [
        f"{e.name} ({e.reference.label} of {e.reference.metric})" for e in lab_envs() if e.reference
    ]
    return f"Envs with one: {', '.join(found)}." if found else "No installed env declares one."


# -- running a command -------------------------------------------------------------------------

#: The optional modules a command imports while it runs. They are imported before it
#: writes anything: in an environment where one is missing, gymprecice's command line says
#: in one line what to install, and no output directory is left behind.
_IMPORTS_FIRST: dict[str, tuple[str, ...]] = {
    "train": ("yaml", "stable_baselines3", "torch"),
    "tune": ("yaml", "optuna"),
    "evaluate": ("stable_baselines3",),
    "benchmark": ("yaml", "stable_baselines3", "torch"),
}


def _run(command: str, args: argparse.Namespace) -> int:
    """Run ``command``: its optional modules first, then its work, imported now."""
    for module in _IMPORTS_FIRST.get(command, ()):
        importlib.import_module(module)
    if command == "train":
        from gymprecice_lab.training.train import train_command

        return train_command(args)
    if command == "tune":
        from gymprecice_lab.training.tune import tune_command

        return tune_command(args)
    if command in ("evaluate", "baseline", "open-loop", "feedback"):
        from gymprecice_lab.rollouts.evaluate import rollout_command

        return rollout_command(command, args)
    if command == "sweep":
        from gymprecice_lab.rollouts.sweep import sweep_command

        return sweep_command(args)
    if command == "compare":
        from gymprecice_lab.rollouts.compare import compare_command

        return compare_command(args)
    if command == "benchmark":
        from gymprecice_lab.benchmarking.command import benchmark_command

        return benchmark_command(args)
    if command == "time-to-floor":
        from gymprecice_lab.rollouts.time_to_floor import time_to_floor_command

        return time_to_floor_command(args)
    if command == "plot":
        from gymprecice_lab.rollouts.plots import plot_command

        return plot_command(args)
    if command == "ship-policy":
        from gymprecice_lab.policies.ship import ship_command

        return ship_command(args)
    from gymprecice_lab.policies.shipped import list_command

    return list_command(args)
