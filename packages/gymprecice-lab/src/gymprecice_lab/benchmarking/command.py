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
   are Ray tasks on the cluster too (:mod:`gymprecice_lab.benchmarking.remote_commands`);
   without it they run here, ``--workers`` at once;
2. **evaluate** every policy deterministically from every held-out start (an env without
   held-out starts: from the seeds that stand for them, :mod:`gymprecice_lab.common.starts`)
   (``gymprecice evaluate --all-starts`` into ``<out>/eval/<algo>/seed_<k>``);
3. **baselines** on the same starts (``gymprecice sweep`` into ``<out>/baselines``): the
   uncontrolled flow, the best constant, the best open-loop sinusoid of an amplitude x
   frequency grid and the best classical feedback law of a gain x delay grid
   (:mod:`gymprecice_lab.rollouts.feedback`) or, for an env with a law of its own (the heated
   plate's PID), of that law's grid, each chosen by its mean objective;
4. **aggregate** per controller the mean and the interquartile mean of the objective (and
   of the env's own metrics: its card's ``metrics``, the cylinders' drag and lift over
   every solver step, the fractions of a drag floor), each with a 95 %
   stratified-bootstrap interval (:mod:`gymprecice_lab.benchmarking.stats`), into ``results.md``, ``results.csv`` and
   ``results.json`` (with each seed's restarts while it trained: envs re-created after a
   lost Ray node or a failure, trainings re-run; and its training time and kept model:
   step, validation score, time into training), and draw ``return_wallclock.png`` (training return against wall-clock,
   mean over seeds with a 95 % band) and ``objective_per_start.png``.

Everything that decides the numbers is recorded in ``<out>/benchmark.json``; a rerun with
other settings is refused before anything runs (``--fresh`` starts over). Bad input
(an algorithm that does not fit the action space, a training flag an
algorithm does not have) is refused before anything trains.

The command composes its pieces, each a module of its own: the input's checks and the
command's error (:mod:`~gymprecice_lab.benchmarking.checks`), the sub-commands' command lines
(:mod:`~gymprecice_lab.benchmarking.argv`), ``benchmark.json`` locked across resumes
(:mod:`~gymprecice_lab.benchmarking.settings`), a seed's training with its retries
(:mod:`~gymprecice_lab.benchmarking.seed_training`), Ray or local dispatch
(:mod:`~gymprecice_lab.benchmarking.dispatch`), scores and controller entries
(:mod:`~gymprecice_lab.benchmarking.scores`), the tables
(:mod:`~gymprecice_lab.benchmarking.tables`) and the figures
(:mod:`~gymprecice_lab.benchmarking.plots`).
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

from gymprecice_lab.benchmarking.argv import common_options, sweep_argv, train_argv
from gymprecice_lab.benchmarking.checks import (
    BenchmarkError,
    check_algorithm_fits,
    check_baselines_fit,
    check_grids,
    parse_algorithms,
    parse_train_args,
    resolve_feedback,
)
from gymprecice_lab.benchmarking.command_settings import BenchmarkSettings
from gymprecice_lab.benchmarking.dispatch import run_everywhere, solver_cpus, sweep_cpus
from gymprecice_lab.benchmarking.remote_commands import RemoteCommand
from gymprecice_lab.benchmarking.scores import controller_entry, start_scores
from gymprecice_lab.benchmarking.seed_training import (
    restarts,
    train_seed,
    trained,
    training_record,
    worker_train_seed,
)
from gymprecice_lab.benchmarking.settings import lock_settings, settings_of
from gymprecice_lab.benchmarking.tables import write_tables
from gymprecice_lab.cli.settings import from_argv
from gymprecice_lab.common.command_runs import evaluated, run_in_pool
from gymprecice_lab.common.constructor_kwargs import build_env_kwargs
from gymprecice_lab.common.ray_cluster import check_ray
from gymprecice_lab.common.registered_env import LabEnv, LabEnvError
from gymprecice_lab.common.starts import describe_starts
from gymprecice_lab.training.hyperparams import hyperparameters

__all__ = ["benchmark_command"]


@dataclass(frozen=True)
class _Plan:
    """What the checks settled before anything trains: the settings with the feedback
    baseline's defaults filled in, the env, the algorithms and their extra training flags,
    where it all goes, the held-out starts and one env's CPUs."""

    settings: BenchmarkSettings
    env: LabEnv
    algos: list[str]
    extra: dict[str, list[str]]
    out: Path
    starts: list[str]
    env_cpus: float

    def run(self, kind: str, algo: str, seed: int) -> Path:
        """``<out>/<kind>/<algo>/seed_<k>``: a seed's training or evaluation."""
        return self.out / kind / algo / f"seed_{seed}"


def benchmark_command(settings: BenchmarkSettings) -> int:
    """``gymprecice benchmark ENV --seeds N --algo ppo[,sac] ...``."""
    from gymprecice_lab.common.manifest import write_manifest

    plan = _plan(settings)
    if isinstance(plan, int):
        return plan  # the solvers are missing: the doctor said what
    settings = plan.settings  # the feedback baseline's defaults filled in
    recorded = settings_of(settings, plan.env, plan.algos, plan.extra)
    recorded["held_out_starts"] = list(plan.starts)
    lock_settings(plan.out, recorded, settings.fresh)
    what = (
        f"{', '.join(a.upper() for a in plan.algos)} x {settings.seeds} seed(s), "
        f"{settings.timesteps:,} steps each, evaluated"
        if settings.seeds
        else "the classical baselines alone"
    )
    print(
        f"gymprecice benchmark: {plan.env.name}: {what} from "
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
    _train_seeds(settings, plan)  # 1. every seed (with --ray: at once, its envs on the cluster)
    controllers = _evaluate_seeds(settings, plan)  # 2. from every held-out start
    if not settings.no_baselines:
        controllers += _baselines(settings, plan)  # 3. the classical ones, on the same starts
    _write_results(settings, plan, controllers)  # 4. tables and figures
    write_manifest(
        plan.out, command="benchmark", settings=recorded, seeds={"seeds": recorded["seeds"]}
    )
    return 0


def _plan(settings: BenchmarkSettings) -> _Plan | int:
    """Everything that can be refused, refused before anything trains (an exit status
    where the solvers are missing)."""
    try:
        env = settings.lab_env
    except LabEnvError as exc:
        raise BenchmarkError(str(exc)) from None
    if not settings.seeds and settings.no_baselines:
        raise BenchmarkError(
            "--seeds 0 --no-baselines leaves nothing to run: --seeds 0 runs the classical "
            "baselines alone; give --seeds N to train N seeds"
        )
    if not settings.seeds and settings.train_args:
        raise BenchmarkError("--seeds 0 trains nothing, so --train-args would be ignored")
    algos = parse_algorithms(settings.algo) if settings.seeds else []
    extra = parse_train_args(settings.train_args, algos)
    out = settings.run_dir
    settings = resolve_feedback(settings, env)
    if not settings.double:
        from gymprecice_lab.common.requirements import require_solvers

        status = require_solvers(
            env, "benchmark", verbose=settings.require_solvers, kwargs=settings.env_kwargs
        )
        if status:
            return status
    for algo in algos:  # a flag the algorithm does not take, refused now
        hyperparameters(from_argv(train_argv(settings, algo, 0, out / "check", extra[algo])), env)
    starts, space, env_cpus = _probe(settings, env, out)
    for algo in algos:
        check_algorithm_fits(algo, space)
    if not settings.no_baselines:
        check_baselines_fit(space)
        check_grids(settings, env)
    if settings.ray:
        needs = [("an evaluation", env_cpus)]
        if not settings.no_baselines:
            needs.append(
                (
                    f"the baselines' sweep (--workers {settings.workers})",
                    sweep_cpus(settings.workers, env_cpus),
                )
            )
        check_ray(settings.ray, needs)
    return _Plan(settings, env, algos, extra, out, list(starts), env_cpus)


def _probe(settings: BenchmarkSettings, env: LabEnv, out: Path) -> tuple[Any, gym.Space, float]:
    """The evaluation's env, built (no solver starts before a reset) to read its held-out
    starts (else seeds), its action space and its solvers' CPUs; nothing is left on disk."""
    from gymprecice_lab.common.starts import StartsError, evaluation_starts
    from gymprecice_lab.common.wrapped_env import make_env_checked

    rollout = from_argv(["baseline", settings.env, *common_options(settings, settings.eval_time)])
    try:
        kwargs = build_env_kwargs(rollout, env, out / "check")
        probe = make_env_checked(env.name, env.env_id, 0, kwargs, rescale=False)
        try:
            return evaluation_starts(probe), probe.action_space, solver_cpus(probe)
        except StartsError as exc:
            raise BenchmarkError(str(exc)) from None
        finally:
            probe.close()
    finally:
        shutil.rmtree(out / "check", ignore_errors=True)


def _train_seeds(settings: BenchmarkSettings, plan: _Plan) -> None:
    """Train every seed not trained already (a seed cut short resumes)."""
    jobs: list[tuple[tuple[Any, ...], str]] = []
    for algo in plan.algos:
        for seed in range(settings.seeds):
            run = plan.run("train", algo, seed)
            label = f"{algo} seed {seed}"
            argv = train_argv(settings, algo, seed, run, plan.extra[algo])
            if trained(run, settings.timesteps, from_argv(argv).stop_at):
                print(f"gymprecice benchmark: {label}: trained already, kept", flush=True)
                continue
            if settings.ray:
                argv += ["--ray", settings.ray]
            jobs.append(((argv, str(run), label, settings.retries), label))
    if settings.ray and len(jobs) > 1:
        print(
            f"gymprecice benchmark: training {len(jobs)} seed(s) at once, their envs as Ray "
            f"actors on the cluster at {settings.ray}",
            flush=True,
        )
        run_in_pool(worker_train_seed, jobs, len(jobs))
    else:
        for (argv, run, label, retries), _ in jobs:
            train_seed(argv, Path(run), label, retries)


def _evaluate_seeds(settings: BenchmarkSettings, plan: _Plan) -> list[dict[str, Any]]:
    """Evaluate each seed's kept model (the best of its validations) and, where it is
    another file, its final model, from every held-out start (those not evaluated
    already); per algorithm a controller entry over the seeds for each.

    The kept model is the learnt entry; the final models' entry beside it shows what
    keeping the best on validation bought. A seed trained without validation has no
    kept model: its final model stands in both entries."""
    from gymprecice_lab.common.wrapped_env import find_model

    pending: list[RemoteCommand] = []
    for algo in plan.algos:
        for seed in range(settings.seeds):
            train_dir = plan.run("train", algo, seed)
            seen: set[Path] = set()
            for which, run in _evaluations(plan, algo, seed):
                model, _ = find_model(train_dir, which)
                if run in seen or evaluated(run, model):
                    continue
                seen.add(run)
                pending.append(
                    RemoteCommand(
                        [
                            "evaluate",
                            settings.env,
                            "--all-starts",
                            "--model",
                            which,
                            *common_options(settings, settings.eval_time),
                        ],
                        run,
                        f"evaluating {algo} seed {seed}"
                        + (" (its final model)" if which == "final" else ""),
                        inputs={"--policy": train_dir},
                        cpus=plan.env_cpus,
                    )
                )
    run_everywhere(pending, settings.ray, settings.workers)
    controllers = []
    for algo in plan.algos:
        label = _learned_label(algo, plan.run("train", algo, 0))
        runs = {
            which: [
                start_scores(
                    _summary(dict(_evaluations(plan, algo, seed))[which]),
                    plan.env,
                    len(plan.starts),
                )
                for seed in range(settings.seeds)
            ]
            for which in ("kept", "final")
        }
        controllers.append(
            controller_entry(label, "learned", runs["kept"], settings.bootstrap_reps)
        )
        if runs["final"] != runs["kept"]:
            controllers.append(
                controller_entry(
                    f"{label}, final model",
                    "learned, final",
                    runs["final"],
                    settings.bootstrap_reps,
                )
            )
    return controllers


def _evaluations(plan: _Plan, algo: str, seed: int) -> list[tuple[str, Path]]:
    """``(which, run)`` of a seed's evaluations: its kept model's in ``eval/``, and its
    final model's in ``eval-final/`` where the final model is another file (else the
    kept model's evaluation stands for both)."""
    from gymprecice_lab.common.wrapped_env import find_model

    train_dir = plan.run("train", algo, seed)
    kept = plan.run("eval", algo, seed)
    if find_model(train_dir, "kept")[0] == find_model(train_dir, "final")[0]:
        return [("kept", kept), ("final", kept)]
    return [("kept", kept), ("final", plan.run("eval-final", algo, seed))]


def _learned_label(algo: str, train_dir: Path) -> str:
    """The table's name for an algorithm's seeds: ``SAC``, or ``SAC, shared policy`` where
    they trained one policy for every agent of a joint env (``--shared-policy``), which a
    reader must tell apart from one controller of every actuator."""
    try:
        settings = json.loads((train_dir / "manifest.json").read_text())["settings"]
        shared = bool(settings.get("hyperparams", {}).get("shared_policy"))
    except (OSError, ValueError, KeyError, TypeError):
        shared = False
    return f"{algo.upper()}, shared policy" if shared else algo.upper()


def _baselines(settings: BenchmarkSettings, plan: _Plan) -> list[dict[str, Any]]:
    """Sweep the classical controllers on the same starts (unless swept already); the
    uncontrolled flow and the best of each kind, as controller entries."""
    sweep_dir = plan.out / "baselines"
    if not (sweep_dir / "sweep.json").is_file():
        sweep = RemoteCommand(
            sweep_argv(settings, len(plan.starts), bool(plan.env.feedback_law)),
            sweep_dir,
            "the baselines' sweep",
            cpus=sweep_cpus(settings.workers, plan.env_cpus),
        )
        run_everywhere([sweep], settings.ray, settings.workers, one_at_a_time=True)
    swept = json.loads((sweep_dir / "sweep.json").read_text())
    chosen = [("uncontrolled", "uncontrolled", None)]
    for kind in ("constant", "sinusoid", "feedback"):
        row = swept.get(f"best_{kind}")
        if row:
            chosen.append((f"best {kind}: {row['label']}", kind, row["label"]))
    return [
        controller_entry(
            title,
            kind,
            [
                start_scores(
                    _summary(sweep_dir / (label or "uncontrolled")), plan.env, len(plan.starts)
                )
            ],
            settings.bootstrap_reps,
        )
        for title, kind, label in chosen
    ]


def _summary(run: Path) -> dict[str, Any]:
    return json.loads((run / "summary.json").read_text())


def _write_results(settings: BenchmarkSettings, plan: _Plan, controllers: list[dict]) -> None:
    """``results.md``/``.csv``/``.json`` and the two figures; the table said."""
    from gymprecice_lab.benchmarking.plots import plot_objective_per_start, plot_return_wallclock

    out = plan.out
    runs = {
        f"{algo.upper()} seed {seed}": plan.run("train", algo, seed)
        for algo in plan.algos
        for seed in range(settings.seeds)
    }
    write_tables(
        out,
        plan.env,
        plan.starts,
        controllers,
        {seed: restarts(run) for seed, run in runs.items()},
        {seed: training_record(run) for seed, run in runs.items()},
    )
    if settings.seeds:
        plot_return_wallclock(out, plan.algos, settings.seeds)
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
        + ("return_wallclock.png and " if settings.seeds else "")
        + "objective_per_start.png"
    )
