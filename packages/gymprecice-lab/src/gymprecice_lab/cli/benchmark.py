"""``gymprecice benchmark`` and ``gymprecice time-to-floor``: their parsers."""

from __future__ import annotations

import functools

from gymprecice_lab.cli import options as o
from gymprecice_lab.cli.command import Command, run
from gymprecice_lab.cli.options import option, positive_float, positive_int
from gymprecice_lab.common.registered_env import lab_envs
from gymprecice_lab.training.hyperparams import ALGORITHMS

__all__ = ["commands"]


def commands() -> list[Command]:
    return [_benchmark(), _time_to_floor()]


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
                type=o.non_negative_int,
                default=5,
                help="training seeds per algorithm (0..N-1; 0: the classical baselines "
                "alone, nothing trained)",
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
        functools.partial(run, "benchmark"),
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
        functools.partial(run, "time-to-floor"),
    )


def _reference_listing() -> str:
    """Each installed env's reference, as its card declares it (for --help)."""
    found = [
        f"{e.name} ({e.reference.label} of {e.reference.metric})" for e in lab_envs() if e.reference
    ]
    return f"Envs with one: {', '.join(found)}." if found else "No installed env declares one."
