"""``gymprecice tune ENV``: hyperparameter search, as RL Zoo does it, for any registered env.

Optuna's TPE sampler proposes a trial's hyperparameters (:mod:`gymprecice_lab.training.tune_spaces`);
the trial is an ordinary ``gymprecice train`` run (its own process, its own directory
``<out>/trials/<n>``), whose validations (:mod:`gymprecice_lab.training.validation`) are
reported to Optuna as they are written, so that the median pruner stops a trial whose
validation score lags the others' at the same step. A trial's score is its kept model's:
its best validation score (the mean validation return, or the settled fraction of the
floor for an env with a physical reference, :mod:`.validation_score`). Held-out starts
are never read.

What a long search on a shared machine or a cluster needs, and how it is met:

* **killed at any point, resumed by the same command**: the study lives in SQLite in
  the output directory (``--storage URL``: any Optuna storage, e.g. PostgreSQL for trials
  on several machines); a trial left running by a killed search is failed and queued
  again with its hyperparameters, and its training resumes from its last checkpoint, so
  no finished trial or checkpoint is lost. The training process gets SIGTERM when the
  search dies (it saves a checkpoint), whatever killed the search;
* **a trial whose solver diverges or crashes** is pruned with its reason recorded
  (``optuna`` user attribute ``failure``), and the study goes on;
* **trials side by side**: ``--n-jobs N`` runs N worker processes on the one study;
* the best hyperparameters as a file that ``train --hyperparams`` reads
  (``best_hyperparams.yml``), the study's history and the parameters' importance as
  figures (Optuna's own plots), and a progress bar.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from gymprecice_lab.common.kept_model import RETURN_SCORE
from gymprecice_lab.common.registered_env import LabEnv, LabEnvError
from gymprecice_lab.training.command_settings import TuneSettings
from gymprecice_lab.training.tune_spaces import SPACES, sample, space_names
from gymprecice_lab.training.tune_workers import (
    NODE_VARIABLE,
    SHARE_VARIABLE,
    WORKER_VARIABLE,
    die_with_parent,
    run_workers_here,
    run_workers_on_ray,
    worker_commands,
)

__all__ = ["TuneError", "objective", "open_study", "tune_command"]

#: seconds between a running trial's heartbeats; a trial silent for GRACE_S is stale
HEARTBEAT_S = 20
GRACE_S = 60
#: how often a running trial's validations are read
POLL_S = 2.0
#: the study's attributes that a resumed search must match
STUDY_KEYS = ("env_id", "algo", "timesteps", "n_envs", "double")


class TuneError(Exception):
    """Bad input or a study that cannot be used: one line for the user."""


# -- the study -------------------------------------------------------------------------------


def sampler_seed(seed: int, trials_so_far: int, worker: int) -> int:
    """A sampler seed that differs between workers and between the openings of a study,
    and is the same for the same command on the same study (reproducible)."""
    return (seed * 1_000_003 + trials_so_far * 1_009 + worker) % 2**32


def open_study(
    storage_url: str, name: str, settings: Mapping[str, Any], seed: int, worker: int = 0
) -> Any:
    """The study ``name`` in ``storage_url``, created with ``settings`` or checked against
    them: a study of another env, algorithm or budget is refused, not mixed in.

    Its sampler is seeded from ``seed``, the trials the study already holds and ``worker``
    (the ``--n-jobs`` process it serves): a sampler seeded with ``seed`` alone would make
    every worker, and every resumed search, propose the same first trials again."""
    import optuna
    from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback

    _quiet_experimental_warnings()
    try:
        storage = RDBStorage(
            storage_url,
            heartbeat_interval=HEARTBEAT_S,
            grace_period=GRACE_S,
            heartbeat_stale_trial_callback=RetryHeartbeatStaleTrialCallback(
                max_retry=3, inherit_intermediate_values=True
            ),
        )
    except Exception as exc:  # SQLAlchemy's errors for a URL it cannot open
        raise TuneError(
            f"--storage {storage_url}: cannot open it ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0]})"
        ) from None
    study = optuna.create_study(
        study_name=name,
        storage=storage,
        direction="maximize",
        pruner=optuna.pruners.MedianPruner(n_startup_trials=3, n_warmup_steps=0),
        load_if_exists=True,
    )
    study.sampler = optuna.samplers.TPESampler(
        seed=sampler_seed(seed, len(study.trials), worker), n_startup_trials=5
    )
    recorded = {key: study.user_attrs.get(key) for key in STUDY_KEYS}
    if all(value is None for value in recorded.values()):
        for key in STUDY_KEYS:
            study.set_user_attr(key, settings[key])
    elif recorded != {key: settings[key] for key in STUDY_KEYS}:
        differ = [k for k in STUDY_KEYS if recorded[k] != settings[k]]
        raise TuneError(
            f"study {name!r} in {storage_url} was made for "
            + ", ".join(f"{k}={recorded[k]!r}" for k in differ)
            + ", not "
            + ", ".join(f"{k}={settings[k]!r}" for k in differ)
            + "; give another --study-name or --out"
        )
    return study


def _quiet_experimental_warnings() -> None:
    """Optuna marks its heartbeat, retry and matplotlib plots experimental; a user can do
    nothing about that, so the warnings are not shown."""
    import warnings

    from optuna.exceptions import ExperimentalWarning

    warnings.filterwarnings("ignore", category=ExperimentalWarning)


def _retry_dead_trials(study: Any) -> None:
    """Fail and queue again, now, the running trials of this machine whose search
    process is gone (a killed search): the heartbeat would do it only after its grace."""
    from optuna.storages import RetryHeartbeatStaleTrialCallback
    from optuna.trial import TrialState

    host = socket.gethostname()
    retry = RetryHeartbeatStaleTrialCallback(max_retry=3, inherit_intermediate_values=True)
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        owner = trial.system_attrs.get("gymprecice_owner") or {}
        if owner.get("host") != host or _alive(owner.get("pid"), owner.get("started")):
            continue
        with contextlib.suppress(Exception):  # another process failed it first
            if study._storage.set_trial_state_values(trial._trial_id, state=TrialState.FAIL):
                retry(study, study._storage.get_trial(trial._trial_id))


def _alive(pid: Any, started: Any) -> bool:
    """Whether process ``pid`` runs and is the one that started at ``started``."""
    from gymprecice.env.pidregistry import process_starttime

    try:
        return pid is not None and process_starttime(int(pid)) == started
    except (OSError, ValueError):
        return False


def _score(trial: Any) -> str:
    """What a finished trial's value is (its kept model's record says)."""
    return str(trial.user_attrs.get("score") or RETURN_SCORE)


# -- one trial -------------------------------------------------------------------------------


def objective(trial: Any, settings: TuneSettings, env: LabEnv, out: Path) -> float:
    """Train one trial's hyperparameters; its kept model's validation score."""
    import optuna
    import yaml

    from gymprecice_lab.common.kept_model import read_kept

    storage, trial_id = trial.storage, trial._trial_id
    storage.set_trial_system_attr(
        trial_id,
        "gymprecice_owner",
        {"host": socket.gethostname(), "pid": os.getpid(), "started": _own_start()},
    )
    original = storage.get_trial_system_attrs(trial_id).get("failed_trial", trial.number)
    run = out / "trials" / str(original)  # a retried trial resumes its first attempt's run
    run.mkdir(parents=True, exist_ok=True)
    names = list(settings.params) if settings.params else None
    params = sample(
        trial, settings.algo, settings.timesteps, settings.n_envs, _fixed(settings, env), names
    )
    (run / "hyperparams.yml").write_text(yaml.safe_dump({env.env_id: params}, sort_keys=True))
    trial.set_user_attr("hyperparams", params)
    trial.set_user_attr("run", str(run))
    if os.environ.get(NODE_VARIABLE):  # a worker on a Ray cluster: where the trial trains
        trial.set_user_attr("ray_node", os.environ[NODE_VARIABLE])
    argv = _train_argv(settings, env, run)
    status, reported, pruned = _watch(trial, argv, run)
    if pruned:
        raise optuna.TrialPruned(f"validation score lags at step {reported}")
    kept = read_kept(run / "train")
    if status != 0 or kept is None:
        reason = _failure(run, status)
        trial.set_user_attr("failure", reason)
        print(f"gymprecice tune: trial {trial.number} pruned: {reason}", file=sys.stderr)
        raise optuna.TrialPruned(reason)
    trial.set_user_attr("kept_step", kept["timesteps"])
    trial.set_user_attr("score", kept.get("score", RETURN_SCORE))
    return float(kept["mean_return"])


def _own_start() -> Any:
    from gymprecice.env.pidregistry import process_starttime

    return process_starttime(os.getpid())


def _fixed(settings: TuneSettings, env: LabEnv) -> dict[str, Any]:
    """``--hyperparams``: settings every trial keeps (the search does not vary them)."""
    if settings.hyperparams is None:
        return {}
    from gymprecice_lab.training.hyperparams import load_hyperparams_file

    return load_hyperparams_file(settings.hyperparams, settings.algo, (env.env_id, env.name))


def _train_argv(settings: TuneSettings, env: LabEnv, run: Path) -> list[str]:
    """A trial's ``gymprecice train`` command line, into ``run``."""
    argv = [
        sys.executable,
        "-m",
        "gymprecice",
        "train",
        env.env_id,
        "--algo",
        settings.algo,
        "--hyperparams",
        str(run / "hyperparams.yml"),
        "--timesteps",
        str(settings.timesteps),
        "--n-envs",
        str(settings.n_envs),
        "--checkpoint-every",
        str(settings.validate_every),
        "--seed",
        str(settings.seed),
        "--no-progress-bar",
        "--out",
        str(run / "train"),
    ]
    if settings.double:
        argv.append("--double")
    if settings.episode_time is not None:
        argv += ["--episode-time", repr(settings.episode_time)]
    if settings.env_kwargs:
        argv += ["--env-kwargs", json.dumps(settings.env_kwargs)]
    return argv


def _watch(trial: Any, argv: list[str], run: Path) -> tuple[int, int, bool]:
    """Run a trial's training, report each validation to Optuna as it is written, and
    stop the training (SIGTERM: it saves) once the pruner says so.

    Returns the exit status, the last step reported and whether it was pruned."""
    import numpy as np

    npz = run / "train" / "eval" / "evaluations.npz"
    reported, pruned = -1, False
    with (run / "train.log").open("a") as log, _child(argv, log) as child:
        while True:
            status = child.poll()
            try:
                with np.load(npz) as data:
                    steps, results = list(data["timesteps"]), data["results"]
            except (OSError, ValueError, KeyError, EOFError):
                steps, results = [], None
            for k, step in enumerate(steps):
                if int(step) > reported:
                    reported = int(step)
                    trial.report(float(np.mean(results[k])), reported)
                    if trial.should_prune() and status is None:
                        pruned = True
                        child.send_signal(signal.SIGTERM)
            if status is not None:
                return status, reported, pruned
            time.sleep(POLL_S)


@contextlib.contextmanager
def _child(argv: list[str], log: Any) -> Iterator[subprocess.Popen[bytes]]:
    """The training process: SIGTERM when this process dies whatever killed it
    (``PR_SET_PDEATHSIG``), so that it saves a checkpoint and stops its solvers; and
    SIGTERM, then SIGKILL, when the search stops here (an exception, Ctrl-C)."""
    child = subprocess.Popen(
        argv,
        stdout=log,
        stderr=subprocess.STDOUT,
        preexec_fn=die_with_parent,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},  # no buffer copied into its forks
    )
    try:
        yield child
    finally:
        if child.poll() is None:
            child.send_signal(signal.SIGTERM)
            try:
                child.wait(60)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()


def _failure(run: Path, status: int) -> str:
    """Why a trial's training gave no kept model: its exit status and last log line."""
    try:
        lines = [ln for ln in (run / "train.log").read_text(errors="replace").splitlines() if ln]
    except OSError:
        lines = []
    last = lines[-1][:300] if lines else "no output"
    return f"the training exited with status {status}: {last}"


# -- the command -----------------------------------------------------------------------------


def tune_command(settings: TuneSettings) -> int:
    """``gymprecice tune ENV``."""
    try:
        return _tune(settings)
    except (TuneError, LabEnvError) as exc:
        print(f"gymprecice tune: {exc}", file=sys.stderr)
        return 2


def _tune(settings: TuneSettings) -> int:
    import optuna

    env = settings.lab_env
    algo = settings.algo
    if algo not in SPACES:
        raise TuneError(f"--algo {algo}: choose {', '.join(SPACES)}")
    if settings.params:
        unknown = sorted(set(settings.params) - set(space_names(algo)))
        if unknown:
            raise TuneError(
                f"--params {','.join(unknown)}: {algo.upper()}'s search space has no "
                f"such parameter; choose from {', '.join(space_names(algo))}"
            )
    if settings.ray:
        _check_ray(settings.ray, settings.n_envs)
    if not settings.double:
        from gymprecice_lab.common.requirements import require_solvers

        status = require_solvers(env, "tune", verbose=False)
        if status:
            return status
    out = settings.run_dir
    storage = settings.storage_url
    name = settings.study
    study_settings = {
        "env_id": env.env_id,
        "algo": algo,
        "timesteps": settings.timesteps,
        "n_envs": settings.n_envs,
        "double": bool(settings.double),
    }
    _fixed(settings, env)  # a bad --hyperparams file is refused before anything is written
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        study = open_study(
            storage, name, study_settings, settings.seed, int(os.environ.get(WORKER_VARIABLE, "0"))
        )
    except TuneError:
        if created:
            with contextlib.suppress(OSError):
                (out / "study.db").unlink(missing_ok=True)
                out.rmdir()
        raise
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    _retry_dead_trials(study)
    done = _counted(study)
    todo = max(0, settings.trials - done)
    if WORKER_VARIABLE in os.environ:  # an --n-jobs worker: its parent speaks and reports
        todo = min(todo, int(os.environ.get(SHARE_VARIABLE, todo)))
        if todo:
            _optimize(study, settings, env, out, todo)
        return 0
    print(
        f"gymprecice tune: {env.name}, {algo.upper()}, study {name!r} in {storage}: "
        f"{done} trial(s) finished, {todo} to run ({settings.n_jobs} at once"
        f"{f' on the Ray cluster at {settings.ray}' if settings.ray else ''}), each "
        f"{settings.timesteps:,} steps on {settings.n_envs} env(s) validated every "
        f"{settings.validate_every:,}; trials in {out / 'trials'}",
        flush=True,
    )
    if todo and (settings.n_jobs > 1 or settings.ray):
        commands = worker_commands(
            sys.argv[1:], settings.trials, settings.n_jobs, storage, name, todo
        )
        if settings.ray:
            for line in run_workers_on_ray(commands, settings.ray, settings.n_envs):
                print(f"gymprecice tune: {line}", flush=True)
        else:
            run_workers_here(commands)
    elif todo:
        _optimize(study, settings, env, out, todo)
    return _report(study, settings, env, out, name)


def _check_ray(address: str, cpus: int) -> None:
    """Refuse ``--ray`` before anything is written when Ray is missing, no cluster
    answers, or no node has the CPUs of one trial (one line, exit status 2)."""
    from gymprecice_lab.common.ray_cluster import check_ray

    check_ray(address, [("a trial (--n-envs)", float(cpus))], "tune")


def _counted(study: Any) -> int:
    """Trials that count toward ``--trials``: finished, pruned or failed for good."""
    from optuna.trial import TrialState

    return len(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED)))


def _optimize(study: Any, settings: TuneSettings, env: LabEnv, out: Path, n: int) -> None:
    from optuna.trial import TrialState

    def stop_when_counted(study: Any, trial: Any) -> None:
        if _counted(study) >= settings.trials:
            study.stop()

    study.optimize(
        lambda trial: objective(trial, settings, env, out),
        n_trials=n + len(study.get_trials(deepcopy=False, states=(TrialState.WAITING,))),
        callbacks=[stop_when_counted],
        catch=(),
        show_progress_bar=not settings.no_progress_bar,
        gc_after_trial=True,
    )


def _report(study: Any, settings: TuneSettings, env: LabEnv, out: Path, name: str) -> int:
    """Write the best hyperparameters and the figures; say the best trial."""
    import yaml
    from optuna.trial import TrialState

    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    pruned = study.get_trials(deepcopy=False, states=(TrialState.PRUNED,))
    failed = [t for t in pruned if t.user_attrs.get("failure")]
    if not complete:
        print(
            f"gymprecice tune: no trial finished yet ({len(pruned)} pruned, {len(failed)} of "
            "them failed: see `failure` in the study); run the same command to go on",
            file=sys.stderr,
        )
        return 1
    best = study.best_trial
    params = dict(best.user_attrs.get("hyperparams") or {})
    best_file = out / "best_hyperparams.yml"
    best_file.write_text(
        f"# gymprecice tune {env.name}: study {name!r}, trial {best.number} of "
        f"{len(complete) + len(pruned)}, {_score(best)} {best.value:.6g}\n"
        + yaml.safe_dump({env.env_id: params}, sort_keys=True)
    )
    summary = {
        "env_id": env.env_id,
        "algo": settings.algo,
        "study": name,
        "best_trial": best.number,
        "best_value": best.value,
        "best_hyperparams": params,
        "trials": {"complete": len(complete), "pruned": len(pruned), "failed": len(failed)},
        "failures": {str(t.number): t.user_attrs["failure"] for t in failed},
        # what the search cost: each trial's wall-clock, finished or not
        "trial_seconds": {str(t.number): _seconds(t) for t in study.get_trials(deepcopy=False)},
    }
    (out / "tune.json").write_text(json.dumps(summary, indent=2) + "\n")
    figures = _figures(study, out)
    print(
        f"gymprecice tune: best trial {best.number}: {_score(best)} {best.value:.4g} "
        f"({len(complete)} finished, {len(pruned)} pruned, {len(failed)} of them failed); "
        f"wrote {best_file} (`gymprecice train {env.name} --algo {settings.algo} "
        f"--hyperparams {best_file}`), tune.json{figures}"
    )
    return 0


def _seconds(trial: Any) -> float | None:
    """A trial's wall-clock (s) from its start to its end; ``None`` for one still running
    or waiting (a killed trial ends when the next opening of the study finds it dead)."""
    if trial.datetime_start is None or trial.datetime_complete is None:
        return None
    return round((trial.datetime_complete - trial.datetime_start).total_seconds(), 1)


def _figures(study: Any, out: Path) -> str:
    """Optuna's history and parameter-importance plots, as PNGs; what was written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from optuna.importance import PedAnovaImportanceEvaluator
    from optuna.visualization import matplotlib as plots

    written = []
    for filename, draw in (
        ("history.png", lambda: plots.plot_optimization_history(study)),
        (
            "importance.png",
            lambda: plots.plot_param_importances(study, evaluator=PedAnovaImportanceEvaluator()),
        ),
    ):
        try:
            ax = draw()
        except (ValueError, RuntimeError):
            continue  # too few finished trials for this plot yet
        ax.figure.tight_layout()
        ax.figure.savefig(out / filename, dpi=120)
        plt.close(ax.figure)
        written.append(filename)
    return "".join(f", {name}" for name in written)
