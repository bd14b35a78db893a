"""``gymprecice benchmark``: every seed trained, every held-out start evaluated, intervals.

One training seed evaluated from one start cannot tell luck from skill, nor a learned
controller from what a simple forcing does. This command runs the protocol of
docs/benchmark.md on one environment, reusing the other commands for each piece:

1. **train** each algorithm (``--algo ppo,sac``) with each seed ``0..N-1``
   (``gymprecice train`` into ``<out>/train/<algo>/seed_<k>``, each with its manifest);
   a seed already trained to ``--timesteps`` is kept, one cut short resumes from its
   newest checkpoint; a seed whose training fails is reported and re-run (``--retries``),
   and if it still fails the benchmark stops without a table: a seed is never silently
   dropped from the aggregate. With ``--ray auto|ADDRESS`` every seed trains at once, each
   from its own process here (its learner) with its envs as Ray actors on the cluster
   (``gymprecice train --ray``, docs/cluster.md), and the evaluations and the sweep below
   are Ray tasks on the cluster too (:mod:`gymprecice_lab.remote_commands`);
   without it they run here, ``--workers`` at once;
2. **evaluate** every policy deterministically from every held-out start (an env without
   held-out starts: from the seeds that stand for them, :mod:`gymprecice_lab.starts`)
   (``gymprecice evaluate --all-starts`` into ``<out>/eval/<algo>/seed_<k>``);
3. **baselines** on the same starts (``gymprecice sweep`` into ``<out>/baselines``): the
   uncontrolled flow, the best constant, the best open-loop sinusoid of an amplitude x
   frequency grid and the best classical feedback law of a gain x delay grid
   (:mod:`gymprecice_lab.feedback`) or, for an env with a law of its own (the heated
   plate's PID), of that law's grid, each chosen by its mean objective;
4. **aggregate** per controller the mean and the interquartile mean of the objective (and
   of the env's own metrics: its card's ``metrics``, the cylinders' drag and lift over
   every solver step, the fractions of a drag floor), each with a 95 %
   stratified-bootstrap interval (:mod:`gymprecice_lab.benchmark_stats`), into ``results.md``, ``results.csv`` and
   ``results.json``, and draw ``return_wallclock.png`` (training return against wall-clock,
   mean over seeds with a 95 % band) and ``objective_per_start.png``.

Everything that decides the numbers is recorded in ``<out>/benchmark.json``; a rerun with
other settings is refused before anything runs (``--fresh`` starts over). Bad input
(an algorithm that does not fit the action space, a training flag an
algorithm does not have) is refused before anything trains.
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice_lab.benchmark_stats import estimate
from gymprecice_lab.command_runs import (
    CommandFailed,
    evaluated,
    exit_status_of,
    parse_command,
    run_commands,
    run_in_pool,
)
from gymprecice_lab.hyperparams import ALGORITHMS
from gymprecice_lab.lab_env import LabEnv, LabEnvError, find_lab_env
from gymprecice_lab.remote_commands import RemoteCommand
from gymprecice_lab.starts import describe_starts

__all__ = [
    "BenchmarkError",
    "benchmark_command",
    "check_algorithm_fits",
    "parse_algorithms",
    "parse_train_args",
    "train_argv",
    "write_tables",
]

SETTINGS_NAME = "benchmark.json"
#: the statistics reported for every metric
STATISTICS = ("mean", "median", "iqm")


class BenchmarkError(CommandFailed):
    """Bad input or a failed seed: one line on stderr, exit status 2 (input) or 1."""

    def __init__(self, message: str, status: int = 2) -> None:
        super().__init__("benchmark", message, status)


# -- parsing and checks ---------------------------------------------------------------------


def parse_algorithms(text: str) -> list[str]:
    """``"ppo,sac"`` -> ``["ppo", "sac"]``; unknown or repeated names are refused."""
    algos = [a.strip().lower() for a in text.split(",") if a.strip()]
    unknown = [a for a in algos if a not in ALGORITHMS]
    if not algos or unknown:
        raise BenchmarkError(
            f"--algo {text!r}: {'unknown ' + ', '.join(unknown) if unknown else 'none given'}; "
            f"choose from {', '.join(ALGORITHMS)} (comma-separated)"
        )
    if len(set(algos)) != len(algos):
        raise BenchmarkError(f"--algo {text!r} names an algorithm twice")
    return algos


def parse_train_args(given: Sequence[str], algos: Sequence[str]) -> dict[str, list[str]]:
    """``--train-args`` values (``"FLAGS"`` for every algorithm, ``"ALGO: FLAGS"`` for one)
    as each algorithm's extra ``gymprecice train`` arguments."""
    out: dict[str, list[str]] = {algo: [] for algo in algos}
    for text in given:
        head, sep, rest = text.partition(":")
        if sep and head.strip().lower() in ALGORITHMS and not head.strip().startswith("-"):
            algo = head.strip().lower()
            if algo not in out:
                raise BenchmarkError(
                    f"--train-args {text!r} is for {algo}, which --algo does not name"
                )
            out[algo] += shlex.split(rest)
        else:
            for algo in algos:
                out[algo] += shlex.split(text)
    owned = {"--algo", "--seed", "--out", "--timesteps", "--n-envs", "--fresh", "--double"}
    for algo, flags in out.items():
        clash = sorted({f.split("=", 1)[0] for f in flags} & owned)
        if clash:
            raise BenchmarkError(
                f"--train-args for {algo} sets {', '.join(clash)}, which the benchmark sets "
                "itself; use the benchmark's own option"
            )
    return out


def check_algorithm_fits(algo: str, space: gym.Space) -> None:
    """Refuse an algorithm that cannot act in ``space`` (before anything trains)."""
    box = isinstance(space, gym.spaces.Box)
    if algo in ("sac", "td3"):
        if not box:
            raise BenchmarkError(
                f"--algo {algo}: {algo.upper()} acts only in a continuous Box action space; "
                f"this env's is {space}; use --algo ppo"
            )
        if not (np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))):
            raise BenchmarkError(
                f"--algo {algo}: {algo.upper()} squashes its actions into the action bounds, "
                f"and this env's Box is unbounded ({space}); bound the action space or use "
                "--algo ppo"
            )
    elif not isinstance(
        space,
        (gym.spaces.Box, gym.spaces.Discrete, gym.spaces.MultiDiscrete, gym.spaces.MultiBinary),
    ):
        raise BenchmarkError(
            f"--algo {algo}: {algo.upper()} cannot act in this env's action space {space}"
        )


def _check_baselines_fit(space: gym.Space) -> None:
    if not (
        isinstance(space, gym.spaces.Box)
        and np.all(np.isfinite(space.low))
        and np.all(np.isfinite(space.high))
    ):
        raise BenchmarkError(
            f"the classical baselines (constants, sinusoids, feedback) need a bounded Box "
            f"action space, this env's is {space}; add --no-baselines"
        )


#: the lift feedback's gains where ``--feedback-gains`` is not given (an env whose
#: classical feedback is a signal fed back, as the cylinders' lift)
DEFAULT_FEEDBACK_GAINS = "-2,-1,1,2"


def _resolve_feedback(args: argparse.Namespace, env: LabEnv) -> None:
    """Fill in the feedback baseline's defaults in ``args``: the lift's gains for an env
    fed back a signal; the grid of the env's own law (``--feedback-grid``, its documented
    grid unless given, written out so that ``benchmark.json`` records every point) for one
    that names a law. The other kind's options are refused rather than ignored."""
    from gymprecice_lab.feedback import own_law_grid

    try:
        law, grid = own_law_grid(
            env.name, env.feedback_law, args.feedback_gains, args.feedback_grid
        )
    except ValueError as exc:
        raise BenchmarkError(str(exc)) from None
    if law is None:
        if args.feedback_gains is None:
            # no signal to feed back (card field 'feedback_signal'): no feedback baseline
            has_signal = args.feedback_signal or env.feedback_signal
            args.feedback_gains = DEFAULT_FEEDBACK_GAINS if has_signal else ""
        return
    args.feedback_gains = ""
    args.feedback_grid = law.grid_text(grid) if grid is not None else ""


def _check_grids(args: argparse.Namespace, env: LabEnv) -> None:
    """The sweep's grids, checked now rather than after every seed has trained."""
    from gymprecice_lab.sweep import parse_grid

    parse_grid(args.amplitudes, "amplitudes")
    if not 0.0 <= args.centre <= 1.0:
        raise BenchmarkError(f"--centre is a fraction of the action box, 0 to 1; got {args.centre}")
    if any(f <= 0 for f in parse_grid(args.frequencies, "frequencies")):
        raise BenchmarkError("--frequencies must be positive (Hz)")
    if args.feedback_gains:
        parse_grid(args.feedback_gains, "feedback-gains")
        delays = parse_grid(args.feedback_delays, "feedback-delays")
        if any(d < 0 or d != int(d) for d in delays):
            raise BenchmarkError("--feedback-delays are whole numbers of actions >= 0")
        if not (args.feedback_signal or env.feedback_signal):
            raise BenchmarkError(
                f"{env.name} has no default feedback signal; pass --feedback-signal NAME "
                "(one of the metrics in its steps' info['metrics']) or --feedback-gains '' "
                "(no feedback baseline)"
            )


# -- the sub-commands, through their own parsers ----------------------------------------------


def _common(args: argparse.Namespace, episode_time: float | None) -> list[str]:
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
        *_common(args, args.episode_time),
        *extra,
    ]


# -- the run ---------------------------------------------------------------------------------


def _settings(args: argparse.Namespace, env: LabEnv, algos: list[str], extra: dict) -> dict:
    """Everything that decides the benchmark's numbers (compared on a resume)."""
    return {
        "env": env.name,
        "env_id": env.env_id,
        "algos": algos,
        "seeds": list(range(args.seeds)),
        "timesteps": args.timesteps,
        "n_envs": args.n_envs,
        "train_args": extra,
        "episode_time": args.episode_time,
        "eval_time": args.eval_time,
        "env_kwargs": args.env_kwargs or {},
        "double": bool(args.double),
        "baselines": None
        if args.no_baselines
        else {
            "constants": args.constants,
            "amplitudes": args.amplitudes,
            "frequencies": args.frequencies,
            "centre": args.centre,
            "feedback_gains": args.feedback_gains,
            "feedback_delays": args.feedback_delays,
            "feedback_signal": args.feedback_signal,
            # only where the env has a law: a benchmark.json written before resumes
            **({"feedback_grid": args.feedback_grid} if env.feedback_law else {}),
        },
        "bootstrap_reps": args.bootstrap_reps,
    }


def _lock_settings(out: Path, settings: dict[str, Any], fresh: bool) -> None:
    """Write ``benchmark.json``, or refuse a rerun whose settings differ from it."""
    path = out / SETTINGS_NAME
    if fresh and out.exists():
        for name in ("train", "eval", "baselines"):
            shutil.rmtree(out / name, ignore_errors=True)
        path.unlink(missing_ok=True)
    if path.is_file():
        original = _with_defaults(json.loads(path.read_text()))
        saved = _with_added_algorithms(original, settings)
        changed = [
            f"{key} is {json.dumps(settings.get(key))} now but {json.dumps(saved.get(key))} "
            f"in the benchmark being resumed"
            for key in sorted(set(saved) | set(settings))
            if json.dumps(saved.get(key), sort_keys=True)
            != json.dumps(settings.get(key), sort_keys=True)
        ]
        if changed:
            raise BenchmarkError(
                f"cannot resume {out} with other settings: {'; '.join(changed)}. Rerun with "
                f"the settings in {path}, choose another --out, or add --fresh to start over"
            )
        if saved is not original:
            added = [a for a in settings["algos"] if a not in original["algos"]]
            print(
                f"gymprecice benchmark: adding {', '.join(a.upper() for a in added)}; what "
                f"{', '.join(a.upper() for a in original['algos'])} finished is kept",
                flush=True,
            )
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(settings, indent=2) + "\n")


def _with_defaults(saved: dict[str, Any]) -> dict[str, Any]:
    """``saved`` with the settings that a benchmark written before they existed ran with."""
    baselines = saved.get("baselines")
    if isinstance(baselines, dict) and "centre" not in baselines:
        saved = {**saved, "baselines": {**baselines, "centre": 0.5}}
    return saved


def _with_added_algorithms(saved: dict[str, Any], settings: dict[str, Any]) -> dict[str, Any]:
    """``saved`` as if it had named the algorithms that ``settings`` adds, with their
    training flags: adding an algorithm to a benchmark keeps every finished seed,
    evaluation and baseline of the others, whose settings must still match."""
    algos, old = settings.get("algos") or [], saved.get("algos") or []
    added = [a for a in algos if a not in old]
    if not added or algos[: len(old)] != old:
        return saved
    train_args = {**saved.get("train_args", {})}
    train_args.update({a: settings.get("train_args", {}).get(a) for a in added})
    return {**saved, "algos": algos, "train_args": train_args}


def _trained(run: Path, timesteps: int) -> bool:
    """Whether ``run`` holds a finished training of at least ``timesteps`` steps."""
    try:
        result = json.loads((run / "manifest.json").read_text()).get("result") or {}
    except (OSError, ValueError):
        return False
    return (
        (run / "model.zip").is_file()
        and not result.get("interrupted")
        and int(result.get("timesteps") or 0) >= timesteps
    )


def _train_once(argv: list[str]) -> int:
    """One ``gymprecice train`` (its exit status); an exception is a failed training."""
    ns = parse_command(argv)
    return int(ns.func(ns) or 0)


def _train_seed(argv: list[str], run: Path, label: str, retries: int) -> None:
    """Train one seed, re-running a failed attempt up to ``retries`` times (a rerun
    resumes from the attempt's newest checkpoint)."""
    failures: list[str] = []
    for attempt in range(retries + 1):
        try:
            status = _train_once(argv)
        except Exception as exc:  # a crashed training: report, then run it again
            status, reason = 1, f"{type(exc).__name__}: {exc}"
        else:
            reason = f"exit status {status}"
        if status == 0:
            return
        if status > 128:  # stopped by a signal (Ctrl-C, SIGTERM): the user's, not a failure
            raise BenchmarkError(
                f"{label}: training stopped by a signal ({reason}); run the same command "
                "again to resume",
                status,
            )
        failures.append(f"attempt {attempt + 1}: {reason}")
        print(
            f"gymprecice benchmark: {label}: training failed ({reason})"
            + ("; running it again" if attempt < retries else ""),
            file=sys.stderr,
            flush=True,
        )
    run.mkdir(parents=True, exist_ok=True)
    (run / "benchmark-failures.json").write_text(json.dumps(failures, indent=2) + "\n")
    raise BenchmarkError(
        f"{label}: training failed {len(failures)} time(s) ({'; '.join(failures)}); no table "
        f"is written without it (see {run}); fix the cause and run the same command again "
        "(finished seeds are kept)",
        1,
    )


def _worker_train_seed(argv: list[str], run: str, label: str, retries: int) -> int:
    """:func:`_train_seed` in a pool's worker (0: trained)."""
    return exit_status_of(_train_seed, argv, Path(run), label, retries)


def _solver_cpus(env: gym.Env) -> float:
    """CPUs the solvers of one env use (:attr:`GymPreciceConfig.solver_cpus`; 1 for an env
    without a configuration, such as a test double)."""
    config = getattr(env.unwrapped, "config", None)
    return float(getattr(config, "solver_cpus", 0) or 1)


def _sweep_cpus(args: argparse.Namespace, env_cpus: float) -> float:
    """The sweep's ``--workers`` envs at once, on one node."""
    return max(1, args.workers) * env_cpus


def _run_everywhere(
    commands: list[RemoteCommand], args: argparse.Namespace, one_at_a_time: bool = False
) -> None:
    """Run ``commands`` on the cluster with ``--ray`` (Ray tasks that ship their inputs and
    bring their outputs back), else here, ``--workers`` at once (``one_at_a_time``: a
    command that spreads its own work over ``--workers``)."""
    if args.ray:
        from gymprecice_lab.remote_commands import RemoteCommandError
        from gymprecice_lab.remote_commands import run_commands as run_remote_commands

        try:
            run_remote_commands(commands, args.ray)
        except RemoteCommandError as exc:
            raise BenchmarkError(str(exc), 1) from None
        return
    local = [([*c.argv, *_input_options(c), "--out", str(c.out)], c.what) for c in commands]
    run_commands(local, 1 if one_at_a_time else args.workers)


def _input_options(command: RemoteCommand) -> list[str]:
    return [item for option, path in command.inputs.items() for item in (option, str(path))]


def _check_ray(address: str, needs: Sequence[tuple[str, float]]) -> None:
    """Refuse ``--ray`` before anything trains when Ray is missing, no cluster answers, or
    no node has the CPUs one of ``needs`` (what, CPUs on one node) asks for."""
    try:
        import ray
    except ImportError:
        raise BenchmarkError(
            "--ray needs Ray on this machine and every node: pip install "
            "'gymprecice-core[ray]' (see docs/cluster.md)"
        ) from None
    host, _, port = address.rpartition(":")
    try:
        if host and port.isdigit():  # a head's address: ray.init would retry it for minutes
            import socket

            socket.create_connection((host, int(port)), timeout=5).close()
        ray.init(address=address, log_to_driver=False)
    except (OSError, RuntimeError, ValueError) as exc:  # ConnectionError is an OSError
        raise BenchmarkError(
            f"--ray {address}: no Ray cluster answers there "
            f"({getattr(exc, 'strerror', None) or exc}); start one (ray start --head, see "
            "docs/cluster.md) or pass its head's address"
        ) from None
    else:
        from gymprecice_lab.remote_commands import (
            RemoteCommandError,
            check_fits,
            largest_node_cpus,
        )

        try:
            check_fits(needs, largest_node_cpus())
        except RemoteCommandError as exc:
            raise BenchmarkError(f"--ray {address}: {exc}") from None
    finally:
        if ray.is_initialized():
            ray.shutdown()


# -- reading results -----------------------------------------------------------------------


def _scores(summary: dict[str, Any], env: LabEnv, starts: int) -> dict[str, list[float]]:
    """Per start (in index order) the objective and, where recorded, the env's own metrics:
    the force coefficients over every solver step (the cylinders), the fractions of the
    card's reference and the episode mean of each of the card's ``metrics``."""
    from gymprecice_lab.evaluate import episodes_by_start
    from gymprecice_lab.sweep import objective

    episodes = episodes_by_start(summary)
    if len(episodes) != starts:
        raise BenchmarkError(
            f"an evaluation has {len(episodes)} episode(s) for "
            f"{describe_starts(starts, env.held_out_starts)}; "
            "rerun with --fresh",
            1,
        )
    out = {"objective": [objective(env, e) for e in episodes]}
    for metric, key in _SERIES_METRICS:
        if all(e.get(key) is not None for e in episodes):
            out[metric] = [float(e[key]) for e in episodes]
    series = "mean_Cd" in out  # the force coefficients over every solver step
    if series and all(e.get("mean_Cl") is not None for e in episodes):
        # a steady side force lowers the drag below the shedding's without suppressing it
        out["side_force"] = [abs(float(e["mean_Cl"])) for e in episodes]
    for name in env.card.metrics:
        key = f"mean_{name}"
        if (series and name in ("Cd", "Cl")) or name == env.objective or key in out:
            continue  # said above: over every solver step, or as the objective
        if all(e.get(key) is not None for e in episodes):
            out[key] = [float(e[key]) for e in episodes]
    return out


#: the per-start metrics besides the objective, from each episode's summary: the mean drag
#: and mean |lift| over every solver step and, where the env knows its drag floor, the
#: fraction of the floor's drop reached over the whole episode and once settled
_SERIES_METRICS = (
    ("mean_Cd", "series_mean_Cd"),
    ("mean_abs_Cl", "series_mean_abs_Cl"),
    ("floor_fraction", "floor_fraction"),
    ("settled_floor_fraction", "settled_floor_fraction"),
)


def _controller(label: str, kind: str, runs: list[dict[str, list[float]]], reps: int) -> dict:
    metrics = [m for m in runs[0] if all(m in r for r in runs)]
    entry: dict[str, Any] = {"label": label, "kind": kind, "runs": len(runs), "metrics": {}}
    for metric in metrics:
        matrix = np.array([r[metric] for r in runs], dtype=float)
        entry["metrics"][metric] = {
            "scores": matrix.tolist(),
            **{s: estimate(matrix, s, reps=reps).as_dict() for s in STATISTICS},
        }
    return entry


_METRIC_TITLES = {
    "objective": "{objective} (lower is better)",
    "mean_Cd": "mean drag coefficient over every solver step (lower is better)",
    "floor_fraction": "fraction of the drag floor's drop, over the whole episode (higher is "
    "better; 1: the steady symmetric flow's drag)",
    "settled_floor_fraction": "fraction of the drag floor's drop once settled, after the "
    "first seconds' transient (higher is better)",
    "mean_abs_Cl": "mean |lift coefficient| over every solver step (the shedding's swing)",
    "side_force": "|mean lift coefficient|: the steady side force (0 for a symmetric flow)",
}


def _metric_title(metric: str) -> str:
    """A table's heading: the metric's own, or that of an episode mean of a card metric."""
    if metric in _METRIC_TITLES:
        return _METRIC_TITLES[metric]
    name = metric.removeprefix("mean_")
    return f"the episode mean of {name} (info['metrics'], a metric of the env's lab card)"


def _fmt(e: dict[str, Any]) -> str:
    if e["runs"] < 2:
        return f"{e['value']:.4g}"
    return f"{e['value']:.4g} [{e['low']:.4g}, {e['high']:.4g}]"


def write_tables(out: Path, env: LabEnv, starts: Sequence[str], controllers: list[dict]) -> None:
    """``results.json`` (every score), ``results.csv`` and ``results.md``."""
    metrics = list(dict.fromkeys(m for c in controllers for m in c["metrics"]))
    (out / "results.json").write_text(
        json.dumps(
            {"env": env.env_id, "held_out_starts": list(starts), "controllers": controllers},
            indent=2,
        )
        + "\n"
    )
    fields = ["controller", "kind", "runs", "starts"]
    for m in metrics:
        for s in STATISTICS:
            fields += [f"{m}_{s}", f"{m}_{s}_low", f"{m}_{s}_high"]
    with (out / "results.csv").open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        for c in controllers:
            row: dict[str, Any] = {
                "controller": c["label"],
                "kind": c["kind"],
                "runs": c["runs"],
                "starts": len(starts),
            }
            for m, stats in c["metrics"].items():
                for s in STATISTICS:
                    row[f"{m}_{s}"] = stats[s]["value"]
                    row[f"{m}_{s}_low"] = stats[s]["low"]
                    row[f"{m}_{s}_high"] = stats[s]["high"]
            writer.writerow(row)
    objective = env.objective or "negated mean reward per action"
    if env.objective and env.maximize:
        objective += ", negated"
    lines = [
        f"# Benchmark: {env.env_id}",
        "",
        *([env.card.description, ""] if env.card.description else []),
        f"From each of the {describe_starts(len(starts), env.held_out_starts)} "
        f"({'; '.join(starts)}): the mean, "
        "median and interquartile mean (IQM) over every seed x start score, each with a "
        "95 % stratified-bootstrap interval over seeds (strata: the starts); a controller "
        "run once (runs = 1) has no interval.",
    ]
    for m in metrics:
        lines += ["", f"## {m}: {_metric_title(m).format(objective=objective)}", ""]
        lines += [
            "| controller | kind | runs | " + " | ".join(STATISTICS) + " |",
            "| --- | --- | --- | " + " | ".join("---" for _ in STATISTICS) + " |",
        ]
        for c in controllers:
            if m not in c["metrics"]:
                continue
            cells = [_fmt(c["metrics"][m][s]) for s in STATISTICS]
            lines.append(
                f"| {c['label']} | {c['kind']} | {c['runs']} | " + " | ".join(cells) + " |"
            )
    (out / "results.md").write_text("\n".join(lines) + "\n")


# -- the command -----------------------------------------------------------------------------


@dataclass(frozen=True)
class _Plan:
    """What the checks settled before anything trains: the env, the algorithms and their
    extra training flags, where it all goes, the held-out starts and one env's CPUs."""

    env: LabEnv
    algos: list[str]
    extra: dict[str, list[str]]
    out: Path
    starts: list[str]
    env_cpus: float

    def run(self, kind: str, algo: str, seed: int) -> Path:
        """``<out>/<kind>/<algo>/seed_<k>``: a seed's training or evaluation."""
        return self.out / kind / algo / f"seed_{seed}"


def benchmark_command(args: argparse.Namespace) -> int:
    """``gymprecice benchmark ENV --seeds N --algo ppo[,sac] ...``."""
    from gymprecice_lab.manifest import write_manifest

    plan = _plan(args)
    if isinstance(plan, int):
        return plan  # the solvers are missing: the doctor said what
    settings = _settings(args, plan.env, plan.algos, plan.extra)
    settings["held_out_starts"] = list(plan.starts)
    _lock_settings(plan.out, settings, args.fresh)
    print(
        f"gymprecice benchmark: {plan.env.name}: {', '.join(a.upper() for a in plan.algos)} x "
        f"{args.seeds} seed(s), {args.timesteps:,} steps each, evaluated from "
        f"{describe_starts(len(plan.starts), plan.env.held_out_starts)}; output in {plan.out}",
        flush=True,
    )
    if plan.env.card.training_case:
        case = plan.env.card.training_case
        print(
            f"gymprecice benchmark: note: {plan.env.name}'s lab card names {case} as its "
            f"training case, a cheaper case of the same task: `gymprecice benchmark {case}` "
            "runs this protocol there at a fraction of the cost",
            flush=True,
        )
    _train_seeds(args, plan)  # 1. every seed (with --ray: at once, its envs on the cluster)
    controllers = _evaluate_seeds(args, plan)  # 2. from every held-out start
    if not args.no_baselines:
        controllers += _baselines(args, plan)  # 3. the classical ones, on the same starts
    _write_results(args, plan, controllers)  # 4. tables and figures
    write_manifest(
        plan.out, command="benchmark", settings=settings, seeds={"seeds": settings["seeds"]}
    )
    return 0


def _plan(args: argparse.Namespace) -> _Plan | int:
    """Everything that can be refused, refused before anything trains (an exit status
    where the solvers are missing)."""
    from gymprecice_lab.train import default_out, hyperparameters

    try:
        env = find_lab_env(args.env)
    except LabEnvError as exc:
        raise BenchmarkError(str(exc)) from None
    algos = parse_algorithms(args.algo)
    extra = parse_train_args(args.train_args, algos)
    out = (args.out or default_out(env, "benchmark")).resolve()
    _resolve_feedback(args, env)
    if not args.double:
        from gymprecice_lab.requirements import require_solvers

        status = require_solvers(
            env, "benchmark", verbose=args.require_solvers, kwargs=args.env_kwargs
        )
        if status:
            return status
    for algo in algos:
        hyperparameters(
            parse_command(train_argv(args, algo, 0, out / "check", extra[algo])), env, out
        )
    starts, space, env_cpus = _probe(args, env, out)
    for algo in algos:
        check_algorithm_fits(algo, space)
    if not args.no_baselines:
        _check_baselines_fit(space)
        _check_grids(args, env)
    if args.ray:
        needs = [("an evaluation", env_cpus)]
        if not args.no_baselines:
            needs.append(
                (f"the baselines' sweep (--workers {args.workers})", _sweep_cpus(args, env_cpus))
            )
        _check_ray(args.ray, needs)
    return _Plan(env, algos, extra, out, list(starts), env_cpus)


def _probe(args: argparse.Namespace, env: LabEnv, out: Path) -> tuple[Any, gym.Space, float]:
    """The evaluation's env, built (no solver starts before a reset) to read its held-out
    starts (else seeds), its action space and its solvers' CPUs; nothing is left on disk."""
    from gymprecice_lab.envs import make_env_checked
    from gymprecice_lab.starts import StartsError, evaluation_starts
    from gymprecice_lab.train import build_env_kwargs

    rollout = parse_command(["baseline", args.env, *_common(args, args.eval_time)])
    try:
        kwargs = build_env_kwargs(rollout, env, out / "check")
        probe = make_env_checked(env.name, env.env_id, 0, kwargs, rescale=False)
        try:
            return evaluation_starts(probe), probe.action_space, _solver_cpus(probe)
        except StartsError as exc:
            raise BenchmarkError(str(exc)) from None
        finally:
            probe.close()
    finally:
        shutil.rmtree(out / "check", ignore_errors=True)


def _train_seeds(args: argparse.Namespace, plan: _Plan) -> None:
    """Train every seed not trained already (a seed cut short resumes)."""
    jobs: list[tuple[tuple[Any, ...], str]] = []
    for algo in plan.algos:
        for seed in range(args.seeds):
            run = plan.run("train", algo, seed)
            label = f"{algo} seed {seed}"
            if _trained(run, args.timesteps):
                print(f"gymprecice benchmark: {label}: trained already, kept", flush=True)
                continue
            argv = train_argv(args, algo, seed, run, plan.extra[algo])
            if args.ray:
                argv += ["--ray", args.ray]
            jobs.append(((argv, str(run), label, args.retries), label))
    if args.ray and len(jobs) > 1:
        print(
            f"gymprecice benchmark: training {len(jobs)} seed(s) at once, their envs as Ray "
            f"actors on the cluster at {args.ray}",
            flush=True,
        )
        run_in_pool(_worker_train_seed, jobs, len(jobs))
    else:
        for (argv, run, label, retries), _ in jobs:
            _train_seed(argv, Path(run), label, retries)


def _evaluate_seeds(args: argparse.Namespace, plan: _Plan) -> list[dict[str, Any]]:
    """Evaluate each seed's final model from every held-out start (those not evaluated
    already); per algorithm its controller entry over the seeds."""
    pending: list[RemoteCommand] = []
    for algo in plan.algos:
        for seed in range(args.seeds):
            train_dir, run = plan.run("train", algo, seed), plan.run("eval", algo, seed)
            if not evaluated(run, train_dir / "model.zip"):
                pending.append(
                    RemoteCommand(
                        ["evaluate", args.env, "--all-starts", *_common(args, args.eval_time)],
                        run,
                        f"evaluating {algo} seed {seed}",
                        inputs={"--policy": train_dir},
                        cpus=plan.env_cpus,
                    )
                )
    _run_everywhere(pending, args)
    controllers = []
    for algo in plan.algos:
        runs = [
            _scores(_summary(plan.run("eval", algo, seed)), plan.env, len(plan.starts))
            for seed in range(args.seeds)
        ]
        controllers.append(_controller(algo.upper(), "learned", runs, args.bootstrap_reps))
    return controllers


def _baselines(args: argparse.Namespace, plan: _Plan) -> list[dict[str, Any]]:
    """Sweep the classical controllers on the same starts (unless swept already); the
    uncontrolled flow and the best of each kind, as controller entries."""
    sweep_dir = plan.out / "baselines"
    if not (sweep_dir / "sweep.json").is_file():
        sweep = RemoteCommand(
            _sweep_argv(args, plan),
            sweep_dir,
            "the baselines' sweep",
            cpus=_sweep_cpus(args, plan.env_cpus),
        )
        _run_everywhere([sweep], args, one_at_a_time=True)
    swept = json.loads((sweep_dir / "sweep.json").read_text())
    chosen = [("uncontrolled", "uncontrolled", None)]
    for kind in ("constant", "sinusoid", "feedback"):
        row = swept.get(f"best_{kind}")
        if row:
            chosen.append((f"best {kind}: {row['label']}", kind, row["label"]))
    return [
        _controller(
            title,
            kind,
            [_scores(_summary(sweep_dir / (label or "uncontrolled")), plan.env, len(plan.starts))],
            args.bootstrap_reps,
        )
        for title, kind, label in chosen
    ]


def _sweep_argv(args: argparse.Namespace, plan: _Plan) -> list[str]:
    """``gymprecice sweep`` of the baselines: the benchmark's grids on its starts."""
    argv = [
        "sweep",
        args.env,
        "--episodes",
        str(len(plan.starts)),
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
        *_common(args, args.eval_time),
    ]
    if args.feedback_signal:
        argv.append(f"--feedback-signal={args.feedback_signal}")
    if plan.env.feedback_law:
        argv.append(f"--feedback-grid={args.feedback_grid}")
    return argv


def _summary(run: Path) -> dict[str, Any]:
    return json.loads((run / "summary.json").read_text())


def _write_results(args: argparse.Namespace, plan: _Plan, controllers: list[dict]) -> None:
    """``results.md``/``.csv``/``.json`` and the two figures; the table said."""
    from gymprecice_lab.benchmark_plots import plot_objective_per_start, plot_return_wallclock

    out = plan.out
    write_tables(out, plan.env, plan.starts, controllers)
    plot_return_wallclock(out, plan.algos, args.seeds)
    plot_objective_per_start(
        out / "objective_per_start.png",
        plan.starts,
        controllers,
        plan.env.objective_label,
        held_out=plan.env.held_out_starts,
        description=plan.env.description,
    )
    print((out / "results.md").read_text())
    print(
        f"gymprecice benchmark: wrote {out / 'results.md'}, results.csv, results.json, "
        "return_wallclock.png and objective_per_start.png"
    )
