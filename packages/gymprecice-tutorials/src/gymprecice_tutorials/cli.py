"""``gymprecice train | evaluate | baseline | open-loop | feedback | sweep | compare | benchmark
| time-to-floor | plot | ship-policy | policies``.

Added to the ``gymprecice`` command line by the tutorials plugin. Every command that runs
an environment writes into one output directory (``--out``, default
``runs/<env>/<command>``) its results and a ``manifest.json`` (versions, solver checks,
case file hashes, seeds, command line), so the directory alone says how it was made::

    gymprecice train jet-cylinder --n-envs 4 --timesteps 100000
    gymprecice evaluate jet-cylinder --time 10
    gymprecice baseline jet-cylinder --time 10
    gymprecice open-loop jet-cylinder --amplitude 0.5 --frequency 3
    gymprecice feedback jet-cylinder-fast --gain 2 --delay 3 --all-starts
    gymprecice sweep perpendicular-flap-fast            # uncontrolled, constants, sinusoids
    gymprecice benchmark jet-cylinder-fast --seeds 5 --algo ppo,sac --workers 2
    gymprecice time-to-floor runs/jet-cylinder-fast/train   # when it reached 95 % of the floor
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

This module only builds parsers; the work is imported when a command runs, so listing
``gymprecice --help`` never loads torch or matplotlib.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from gymprecice_tutorials.environments import ENVIRONMENTS
from gymprecice_tutorials.hyperparams import ALGORITHMS
from gymprecice_tutorials.wrapping import parse_wrap_argument

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


def _non_negative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be at least 0, got {value}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {value}")
    return value


def _parser(sub: Any, name: str, help: str, description: str) -> argparse.ArgumentParser:
    """A sub-command whose ``--help`` shows every option's default."""
    return sub.add_parser(
        name,
        help=help,
        description=description,
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )


def _env_options(p: argparse.ArgumentParser, *, rollout: bool) -> None:
    p.add_argument(
        "env",
        metavar="ENV",
        help=f"environment: {', '.join(ENVIRONMENTS)} (or its gymnasium id)",
    )
    p.add_argument(
        "--out", type=Path, default=None, help="output directory (None: runs/<env>/<command>)"
    )
    p.add_argument(
        "--double",
        action="store_true",
        help="run against gymprecice's preCICE test double with a scripted fake flow "
        "(no preCICE, no OpenFOAM; the whole pipeline in minutes, and for tests)",
    )
    p.add_argument(
        "--require-solvers",
        action="store_true",
        help="print `gymprecice doctor`'s whole report when preCICE or a solver this "
        "environment needs is missing (without it: one line)",
    )
    p.add_argument("--case", type=Path, help="a case directory of your own instead of the recipe")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    horizons = ", ".join(
        f"{e.name} {e.rollout_time:g} s" for e in ENVIRONMENTS.values() if e.rollout_time
    )
    p.add_argument(
        "--episode-time",
        type=_positive_float,
        default=None,
        metavar="SECONDS",
        help="simulated seconds per episode of a packaged case (None: "
        + (f"{horizons}; the others the case's" if rollout else "the case's training episode")
        + ")",
    )
    p.set_defaults(rollout=rollout)
    p.add_argument(
        "--wrap",
        action="append",
        type=parse_wrap_argument,
        default=[],
        metavar="NAME:KEY=VALUE,...",
        help="a robustness wrapper between the policy and the env (repeatable): "
        "sensor_noise:std=0.05[,mode=absolute], action_noise:std=0.1, delay:steps=2, "
        "dropout:p=0.1[,fill=0]; train also reads them from the hyperparameter file's "
        "'robustness' key",
    )
    p.add_argument(
        "--env-kwargs",
        type=_json_object,
        default={},
        metavar="JSON",
        help="extra keyword arguments of the environment, e.g. '{\"lift_penalty\": 0.1}'",
    )


def add_commands(sub: Any) -> None:
    """Add the tutorials' sub-commands to ``gymprecice``'s argparse sub-parsers."""
    _train_parser(sub)
    _rollout_parsers(sub)
    _benchmark_parser(sub)
    _time_to_floor_parser(sub)
    _plot_parser(sub)
    _policy_parsers(sub)


def _train_parser(sub: Any) -> None:
    p = _parser(
        sub,
        "train",
        help="train a controller (Stable-Baselines3 PPO, SAC or TD3) on N parallel environments",
        description="Train PPO, SAC or TD3 on a tutorial environment. Resumes from the newest "
        "checkpoint in --out unless --fresh is given; a resume must use the run's "
        "hyperparameters. Ctrl-C, SIGTERM and SIGHUP save the model and a checkpoint. "
        "Hyperparameters shown as None take the algorithm's default (ppo: n_steps 80, "
        "batch_size 80, n_epochs 10, learning_rate 3e-4, gamma 0.99, net 512,512; sac/td3: "
        "batch_size 256, net 256,256, SB3's others, td3 with Gaussian action noise of std "
        "0.1), then --hyperparams, then the flag.",
    )
    _env_options(p, rollout=False)
    p.add_argument("--algo", choices=ALGORITHMS, default="ppo", help="learning algorithm")
    p.add_argument(
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
    )
    p.add_argument("--n-envs", type=_positive_int, default=1, help="parallel environments")
    p.add_argument(
        "--timesteps",
        type=_positive_int,
        default=100_000,
        help="total actions (env steps), rounded up to whole rollouts; 100,000 is about "
        "21 hours on the real jet cylinder on 2 cores",
    )
    p.add_argument(
        "--n-steps",
        type=_positive_int,
        default=None,
        help="PPO: actions per env per update (80: one jet-cylinder episode)",
    )
    p.add_argument(
        "--batch-size",
        type=_positive_int,
        default=None,
        help="mini-batch size (PPO: at most n_steps x n_envs)",
    )
    p.add_argument("--n-epochs", type=_positive_int, default=None, help="PPO: epochs per update")
    p.add_argument("--learning-rate", type=_positive_float, default=None, help="learning rate")
    p.add_argument("--gamma", type=float, default=None, help="discount factor")
    p.add_argument(
        "--net", default=None, help="hidden layer sizes of policy and value nets, e.g. 64,64"
    )
    p.add_argument(
        "--normalize",
        action="store_true",
        help="normalise observations and rewards (VecNormalize); the statistics are "
        "saved beside every model and used by evaluate",
    )
    p.add_argument(
        "--checkpoint-every",
        type=_positive_int,
        default=None,
        metavar="STEPS",
        help="save a checkpoint every this many env steps (None: every 10 rollouts)",
    )
    p.add_argument(
        "--keep-checkpoints",
        type=_positive_int,
        default=5,
        metavar="N",
        help="keep the newest N checkpoints and the best (highest mean return)",
    )
    p.add_argument(
        "--eval-freq",
        type=_positive_int,
        default=None,
        metavar="STEPS",
        help="every this many env steps, evaluate deterministically on a separate env "
        "(from the held-out starts, in turn) and keep best_model.zip (None: no evaluation "
        "during training)",
    )
    p.add_argument(
        "--n-eval-episodes", type=_positive_int, default=2, help="episodes per evaluation"
    )
    p.add_argument("--fresh", action="store_true", help="start over even if --out has checkpoints")
    p.add_argument(
        "--vec-env",
        choices=("auto", "resilient", "subproc", "dummy"),
        default="auto",
        help="vector env: fault-tolerant subprocesses (auto, when available), plain SB3 "
        "subprocesses, or all in this process (debugging)",
    )
    p.add_argument(
        "--ray",
        metavar="auto|ADDRESS",
        default=None,
        help="run the envs as Ray actors on a Ray cluster (auto: the one this machine "
        "joined); needs gymprecice-core[ray], see docs/cluster.md",
    )
    p.add_argument("--no-progress-bar", action="store_true", help="no progress bar")
    p.add_argument(
        "--verbose",
        type=int,
        choices=(0, 1, 2),
        default=0,
        help="0: progress bar and summary; 1: SB3's table every rollout; 2: SB3's debug output",
    )
    p.add_argument("--device", default="cpu", help="torch device (cuda is refused without CUDA)")
    p.set_defaults(func=_run("train"))


def _rollout_parsers(sub: Any) -> None:
    p = _parser(
        sub,
        "evaluate",
        help="run a trained policy deterministically over a long horizon",
        description="Run a trained policy (deterministic: its mean action) for whole "
        "episodes and write history.csv, coefficients.csv and summary.json (mean and std "
        "over the episodes; the %% change against --baseline when given).",
    )
    _env_options(p, rollout=True)
    p.add_argument(
        "--policy",
        "--model",
        dest="policy",
        metavar="NAME|PATH",
        default=None,
        help="the policy: a model .zip, a training directory (its model.zip, else its "
        "newest checkpoint), the name of a policy shipped with the package (`gymprecice "
        "policies` lists them; ./NAME for a directory of that name) or `shipped` (the one "
        "shipped for ENV). On another env than its training env a policy keeps its "
        "training action bound (None: runs/<env>/train)",
    )
    p.add_argument("--episodes", type=_positive_int, default=1, help="episodes to run")
    _all_starts_option(p)
    p.add_argument("--stochastic", action="store_true", help="sample actions instead")
    _baseline_option(p)
    p.set_defaults(func=_run("evaluate"))

    p = _parser(
        sub,
        "baseline",
        help="run the uncontrolled flow (zero action)",
        description="Run the uncontrolled flow (zero action: jets closed, cylinder at rest) "
        "that a controller is judged against; same files as evaluate.",
    )
    _env_options(p, rollout=True)
    p.add_argument("--episodes", type=_positive_int, default=1, help="episodes to run")
    _all_starts_option(p)
    p.set_defaults(func=_run("baseline"))

    p = _parser(
        sub,
        "open-loop",
        help="run a sinusoidal open-loop controller",
        description="Force the flow with a sinusoid on every action dimension, the classic "
        "open-loop control a learned controller should beat; same files as evaluate.",
    )
    _env_options(p, rollout=True)
    p.add_argument(
        "--amplitude",
        type=float,
        default=0.5,
        help="amplitude as a fraction of the action bound",
    )
    p.add_argument(
        "--frequency",
        type=_positive_float,
        default=None,
        help="frequency in Hz (None: 3 for the cylinders, 0.5 for the flap)",
    )
    p.add_argument("--phase", type=float, default=0.0, help="phase in radians")
    p.add_argument("--episodes", type=_positive_int, default=1, help="episodes to run")
    _all_starts_option(p)
    _baseline_option(p)
    p.set_defaults(func=_run("open-loop"))

    p = _parser(
        sub,
        "feedback",
        help="run a classical feedback law (the lift fed back on the jets)",
        description="Feed one of the env's step metrics (the cylinders' lift Cl) back to "
        "the actuator: a = clip(centre - gain * half_range * signal(t - delay actions)), "
        "the textbook first controller a learned one should beat; same files as evaluate. "
        "`gymprecice sweep --feedback-gains ... --feedback-delays ...` tunes it. An env "
        "with a feedback law of its own (the heated plate's PID heater) runs one point of "
        "it instead: --law 'kp=3;ki=50;kd=1'.",
    )
    _env_options(p, rollout=True)
    p.add_argument(
        "--gain",
        type=float,
        default=1.0,
        help="fraction of the action's half range per unit of the signal",
    )
    p.add_argument(
        "--delay",
        type=_non_negative_int,
        default=0,
        help="whole actions between the signal and the action it sets (the phase shift)",
    )
    p.add_argument(
        "--signal",
        default=None,
        help="the info['metrics'] entry fed back (None: Cl for the cylinders)",
    )
    p.add_argument(
        "--centre",
        type=float,
        default=0.5,
        help="the action without signal as a fraction of the action box (0.5: its middle)",
    )
    p.add_argument(
        "--law",
        default=None,
        metavar="NAME=V;...",
        help="for an env with a feedback law of its own (the heated plate's PID), one value "
        "of each of its parameters, e.g. 'kp=3;ki=50;kd=1' (instead of --signal, --gain, "
        "--delay)",
    )
    p.add_argument("--episodes", type=_positive_int, default=1, help="episodes to run")
    _all_starts_option(p)
    _baseline_option(p)
    p.set_defaults(func=_run("feedback"))

    p = _parser(
        sub,
        "sweep",
        help="run the open-loop forcings a learned controller must beat",
        description="Run the uncontrolled flow, N constant actions across the action box and "
        "a grid of sinusoids (amplitude x frequency) on the held-out starts; write "
        "sweep.csv, sweep.json (best constant, best sinusoid) and sweep.png.",
    )
    _env_options(p, rollout=True)
    p.add_argument(
        "--constants",
        type=_non_negative_int,
        default=9,
        help="constant actions, evenly from low to high (0: none)",
    )
    p.add_argument(
        "--centre",
        type=float,
        default=0.5,
        help="the sinusoids' centre as a fraction of the action box (0.5: its middle)",
    )
    p.add_argument(
        "--amplitudes",
        default="0.25,0.5,1",
        help="sinusoid amplitudes, fractions of the half range, comma-separated",
    )
    p.add_argument(
        "--frequencies",
        default="0.3,0.6,1.2,2.4",
        help="sinusoid frequencies (Hz), comma-separated",
    )
    p.add_argument(
        "--feedback-gains",
        default="",
        help="gains of the classical feedback law to sweep, comma-separated (empty: none; "
        "see `gymprecice feedback`), e.g. -2,-1,-0.5,0.5,1,2",
    )
    p.add_argument(
        "--feedback-delays",
        default="0",
        help="its delays in whole actions, comma-separated",
    )
    p.add_argument(
        "--feedback-signal",
        default=None,
        help="the info['metrics'] entry fed back (None: Cl for the cylinders)",
    )
    _feedback_grid_option(p)
    p.add_argument(
        "--episodes", type=_positive_int, default=3, help="held-out starts per controller"
    )
    _workers_option(p, "controllers run at once, each with its own env and core")
    p.set_defaults(func=_sweep)

    p = _parser(
        sub,
        "compare",
        help="compare evaluated controllers with the uncontrolled flow and the best open loop",
        description="Read gymprecice sweep outputs (the open-loop candidates) and evaluate / "
        "baseline / open-loop outputs (the controllers to judge), all on the same held-out "
        "starts, and write compare.md and compare.json: the objective per start, and each "
        "controller's margin over the uncontrolled flow, the best constant and the best "
        "sinusoid, per start and as mean and spread. Runs nothing.",
    )
    p.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="output directories")
    p.add_argument("--out", type=Path, default=None, help="where to write (None: beside RUN)")
    p.set_defaults(func=_compare)


def _time_to_floor_parser(sub: Any) -> None:
    p = _parser(
        sub,
        "time-to-floor",
        help="how soon training runs reached 90 / 95 %% of the drag floor",
        description="Evaluate each training run's checkpoints in order, deterministically "
        "from every held-out start, until one reaches the highest --fractions of the drag "
        "floor once settled; print the wall-clock from the training command's start to the "
        "first checkpoint reaching each fraction and, over several runs (seeds), the median "
        "with a 95 % bootstrap interval. Writes time_to_floor.json and .csv. See "
        "docs/benchmark.md.",
    )
    p.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="training directories")
    p.add_argument(
        "--env",
        default="jet-cylinder-fast",
        help="the environment the runs trained on (one with a measured drag floor)",
    )
    p.add_argument("--fractions", default="0.9,0.95", help="fractions of the floor's drop")
    p.add_argument(
        "--eval-time",
        type=float,
        default=4.0,
        help="simulated seconds per evaluation episode (the first 2 s are the transient)",
    )
    p.add_argument(
        "--out", type=Path, default=None, help="output (None: <first RUN>/time-to-floor)"
    )
    p.add_argument("--double", action="store_true", help="evaluate on the test double (tests)")
    _workers_option(p, "checkpoints evaluated at once, each on its own core")
    p.set_defaults(func=_time_to_floor)


def _time_to_floor(args: argparse.Namespace) -> int:
    from gymprecice_tutorials.time_to_floor import time_to_floor_command

    return time_to_floor_command(args)


def _workers_option(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--workers",
        type=_positive_int,
        default=1,
        help=f"{what} (a solver runs on one core: at most the machine's cores)",
    )


def _feedback_grid_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--feedback-grid",
        default=None,
        metavar="NAME=V1,V2;...",
        help="for an env with a feedback law of its own (the heated plate's PID: kp, ki, kd), "
        "the values of its parameters to tune, e.g. 'kp=2,3;ki=25,50;kd=0' (unnamed "
        "parameters keep the law's documented grid; default: that grid; empty: none)",
    )


def _benchmark_parser(sub: Any) -> None:
    p = _parser(
        sub,
        "benchmark",
        help="train N seeds per algorithm, evaluate every held-out start, baselines, intervals",
        description="Train each algorithm with seeds 0..N-1 (resumably: a manifest per seed), "
        "evaluate every policy deterministically from every held-out start, run the "
        "classical baselines on the same starts (uncontrolled, best constant, best "
        "open-loop sinusoid, best feedback law of a documented sweep) and write "
        "results.md/.csv/.json (mean and interquartile mean with 95 % stratified-bootstrap "
        "intervals) and two figures. Settings are recorded in benchmark.json; a rerun "
        "with other settings is refused (--fresh starts over). See docs/benchmark.md.",
    )
    p.add_argument(
        "env",
        metavar="ENV",
        help="environment with held-out starts: "
        + ", ".join(e.name for e in ENVIRONMENTS.values() if e.held_out_starts)
        + " (or its id)",
    )
    p.add_argument(
        "--seeds", type=_positive_int, default=5, help="training seeds per algorithm (0..N-1)"
    )
    p.add_argument(
        "--algo", default="ppo", help=f"algorithms, comma-separated ({', '.join(ALGORITHMS)})"
    )
    p.add_argument(
        "--timesteps", type=_positive_int, default=100_000, help="actions per training seed"
    )
    p.add_argument("--n-envs", type=_positive_int, default=1, help="parallel envs per seed")
    p.add_argument(
        "--train-args",
        action="append",
        default=[],
        metavar="[ALGO:]FLAGS",
        help="more `gymprecice train` flags, for every algorithm or (ALGO: prefix) one, "
        "e.g. 'ppo: --n-steps 40 --net 64,64' (repeatable)",
    )
    p.add_argument(
        "--episode-time",
        type=_positive_float,
        default=None,
        metavar="SECONDS",
        help="simulated seconds per training episode (None: the case's)",
    )
    p.add_argument(
        "--eval-time",
        type=_positive_float,
        default=None,
        metavar="SECONDS",
        help="simulated seconds per evaluation episode (None: the env's rollout horizon)",
    )
    p.add_argument(
        "--env-kwargs",
        type=_json_object,
        default={},
        metavar="JSON",
        help="extra keyword arguments of the environment (training and evaluation)",
    )
    p.add_argument("--out", type=Path, default=None, help="output (None: runs/<env>/benchmark)")
    p.add_argument("--double", action="store_true", help="run on the test double (for tests)")
    p.add_argument(
        "--require-solvers", action="store_true", help="the doctor's whole report when missing"
    )
    p.add_argument(
        "--retries",
        type=_non_negative_int,
        default=1,
        help="times a seed whose training fails is run again before the benchmark stops",
    )
    p.add_argument(
        "--no-baselines", action="store_true", help="learned controllers only (no sweep)"
    )
    p.add_argument(
        "--constants", type=_non_negative_int, default=3, help="constant actions in the sweep"
    )
    p.add_argument(
        "--amplitudes",
        default="0.25,0.5,1",
        help="open-loop sinusoid amplitudes (fractions of the half range)",
    )
    p.add_argument("--frequencies", default="1.5,3,6", help="open-loop sinusoid frequencies (Hz)")
    p.add_argument(
        "--centre",
        type=float,
        default=0.5,
        help="the sinusoids' centre as a fraction of the action box (0.5: its middle; the "
        "flap's best open loop swings about 0.875)",
    )
    p.add_argument(
        "--feedback-gains",
        default=None,
        help="feedback gains to sweep (default: -2,-1,1,2 where the feedback is a signal fed "
        "back, none for an env with a feedback law of its own; empty: no feedback baseline)",
    )
    p.add_argument(
        "--feedback-delays",
        default="0,2,4,6",
        help="feedback delays (whole actions; with both signs of gain they span a shedding period of the cylinders)",
    )
    p.add_argument(
        "--feedback-signal",
        default=None,
        help="the info['metrics'] entry fed back (None: Cl for the cylinders)",
    )
    _feedback_grid_option(p)
    p.add_argument("--bootstrap-reps", type=_positive_int, default=2000, help="bootstrap resamples")
    _workers_option(p, "evaluations and baseline rollouts run at once, each on its own core")
    p.add_argument("--fresh", action="store_true", help="start over, deleting the benchmark's runs")
    p.add_argument(
        "--ray",
        metavar="auto|ADDRESS",
        default=None,
        help="train every seed at once, its envs as Ray actors on this Ray cluster (auto: "
        "the one this machine joined), and run the evaluations and the sweep as Ray tasks "
        "there; needs gymprecice-core[ray], see docs/cluster.md",
    )
    p.set_defaults(func=_benchmark)


def _benchmark(args: argparse.Namespace) -> int:
    from gymprecice_tutorials.benchmark import benchmark_command

    return benchmark_command(args)


def _all_starts_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--all-starts",
        action="store_true",
        help="one episode from every held-out start of the env (overrides --episodes; "
        "refused for an env without held-out starts)",
    )


def _baseline_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="RUN",
        help="a baseline run directory (its summary.json): report the %% change of each mean",
    )


def _plot_parser(sub: Any) -> None:
    p = _parser(
        sub,
        "plot",
        help="draw figures: training reward, action history, Cd/Cl against the baseline",
        description="Draw the return over training, the actions and Cd/Cl of run "
        "directories (train, evaluate, baseline, open-loop).",
    )
    p.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="output directories")
    p.add_argument("--baseline", type=Path, help="a baseline run to compare Cd/Cl with")
    p.add_argument("--out", type=Path, help="where figures go (None: <first RUN>/plots)")
    p.add_argument("--format", choices=("png", "pdf", "svg"), default="png", help="file format")
    p.add_argument("--dpi", type=_positive_int, default=120, help="resolution of PNGs")
    p.add_argument(
        "--labels",
        default=None,
        help="legend names, one per RUN, comma-separated (None: the directory names)",
    )
    p.add_argument(
        "--episode",
        type=int,
        default=None,
        help="episode of the rollouts to draw (None: each run's first); titles say which",
    )
    p.set_defaults(func=_plot)


def _policy_parsers(sub: Any) -> None:
    p = _parser(
        sub,
        "ship-policy",
        help="copy a training run's final policy into the package (small: for evaluation)",
        description="Copy a `gymprecice train` run's final model (its model.zip, else its "
        "newest checkpoint) into the package's shipped policies as NAME: the model without "
        "the optimizer state (PPO.load still reads it), the VecNormalize statistics and "
        "policy.json (training env and action bound, training command, timesteps, "
        "wall-clock time, source revision, checksums, and the --evaluation result). Then "
        "`gymprecice evaluate ENV --policy NAME` runs it without training.",
    )
    p.add_argument("train_dir", type=Path, metavar="TRAIN_DIR", help="a training output")
    p.add_argument("--name", default=None, help="the policy's name (None: the training env's name)")
    p.add_argument(
        "--evaluation",
        type=Path,
        default=None,
        metavar="RUN",
        help="a `gymprecice evaluate` output of this model, whose result is recorded",
    )
    p.add_argument(
        "--into",
        type=Path,
        default=None,
        metavar="DIR",
        help="ship into DIR (None: $GYMPRECICE_POLICIES_DIR, else the package's policies/)",
    )
    p.add_argument(
        "--checkpoint",
        default=None,
        metavar="best|STEPS",
        help="ship a checkpoint instead of the final model: 'best' (highest mean training "
        "return, checkpoints/best.json) or a step count",
    )
    p.add_argument("--force", action="store_true", help="replace a policy of that name")
    p.set_defaults(func=_policies("ship"))

    p = _parser(
        sub,
        "policies",
        help="list the trained policies shipped with the package",
        description="One line per shipped policy: its training env, steps, action bound "
        "and evaluated mean Cd (or the env's objective). Evaluate one with `gymprecice "
        "evaluate ENV --policy NAME`.",
    )
    p.set_defaults(func=_policies("list"))


def _policies(command: str) -> Any:
    def handler(args: argparse.Namespace) -> int:
        from gymprecice_tutorials.shipped_policies import list_command, ship_command

        return ship_command(args) if command == "ship" else list_command(args)

    return handler


def _run(command: str) -> Any:
    def handler(args: argparse.Namespace) -> int:
        if command == "train":
            from gymprecice_tutorials.train import train_command

            return train_command(args)
        from gymprecice_tutorials.evaluate import rollout_command

        return rollout_command(command, args)

    return handler


def _sweep(args: argparse.Namespace) -> int:
    from gymprecice_tutorials.sweep import sweep_command

    return sweep_command(args)


def _compare(args: argparse.Namespace) -> int:
    from gymprecice_tutorials.compare import compare_command

    return compare_command(args)


def _plot(args: argparse.Namespace) -> int:
    from gymprecice_tutorials.plots import plot_command

    return plot_command(args)
