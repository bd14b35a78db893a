"""``gymprecice train``: PPO, SAC or TD3 (Stable-Baselines3) on N parallel envs of any id.

What a long training run on a shared machine or a cluster needs, and how it is met:

* **parallel simulations that do not take training down**: the envs run in subprocesses
  through :class:`gymprecice.sb3.ResilientSubprocVecEnv` (a crashed or hung solver costs
  one episode, not the run) when it is installed, else SB3's ``SubprocVecEnv``;
* **resumable and preemptible**: checkpoints go to ``<out>/checkpoints`` every
  ``--checkpoint-every`` env steps (the newest ``--keep-checkpoints`` and the best are
  kept); Ctrl-C, SIGTERM (SLURM, ``timeout``) and SIGHUP save the model and a checkpoint
  and exit non-zero; a rerun of the same command continues (``--fresh`` starts over).
  A resume with other hyperparameters is refused: SB3 would keep the saved ones;
* **observable**: a progress bar, TensorBoard in ``<out>/tb`` and ``<out>/progress.csv``
  (SB3's logger, with each episode's mean Cd, Cl and action RMS under ``env/``), per-env
  episodes in ``<out>/monitor/env_<i>.monitor.csv`` (what ``gymprecice plot`` draws);
  ``--eval-freq`` evaluates on a separate env and keeps ``best_model.zip``;
* **traceable**: ``<out>/manifest.json`` with one record per segment (first run and each
  resume), the hyperparameters actually used, the device, the source revision and the
  model's checksum; ``<out>/hyperparams.json`` and a copy of ``--hyperparams``.

Actions are rescaled to ``[-1, 1]`` for the policy (``RescaleAction``): a Gaussian policy
starts with unit standard deviation, which against a ``±2.5e-4`` box would only ever
produce the bounds. :func:`gymprecice_lab.envs.load_policy` rebuilds that env.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym

from gymprecice_lab import hyperparams as hp
from gymprecice_lab.envs import (
    make_env,
    make_env_checked,
    newest_checkpoint,
    vecnormalize_path,
)
from gymprecice_lab.lab_env import LabEnv, LabEnvError, Refused, find_lab_env, names_where
from gymprecice_lab.manifest import file_sha256, read_manifest, write_manifest
from gymprecice_lab.model_based.settings import (
    ENSEMBLE_KEY,
    TRANSITIONS_FILE,
    EnsembleSettings,
)
from gymprecice_lab.requirements import (
    doctor_text,
    missing_requirements,
    require_solvers,
)
from gymprecice_lab.shared import shared_agents, shared_vec_env
from gymprecice_lab.training_log import merge_progress, segment_logger
from gymprecice_lab.wrapping import WrapError, wrap_spec

__all__ = [
    "build_env_kwargs",
    "check_device",
    "default_out",
    "doctor_text",
    "hyperparameters",
    "latest_checkpoint",
    "learner_threads",
    "make_env",
    "missing_requirements",
    "require_solvers",
    "train",
    "train_command",
]

#: kept for callers of the earlier API: the newest checkpoint of a directory
latest_checkpoint = newest_checkpoint


# -- environments --------------------------------------------------------------------------


def build_env_kwargs(args: argparse.Namespace, env: LabEnv, out: Path) -> dict[str, Any]:
    """Constructor keyword arguments of the environment from the command's options."""
    kwargs: dict[str, Any] = {"run_root": str((out / "envs").resolve())}
    episode_time = getattr(args, "episode_time", None)
    if args.double:
        if not env.double:
            raise Refused(
                f"gymprecice: {env.name} declares no test-double variant for --double (lab "
                f"card field 'double': pass card=EnvCard(double=True) to register() when the "
                f"env takes double=True); run it on real solvers (envs with one: "
                f"{names_where('double')})"
            )
        if args.case is not None:
            raise Refused("gymprecice: --double runs a packaged case; drop --case")
        kwargs["double"] = True
    if args.case is not None:
        if episode_time is not None:
            raise Refused(
                "gymprecice: --episode-time shapes a packaged case; with --case set the "
                "coupling's max-time in your precice-config.xml instead"
            )
        kwargs["options"] = str(args.case.resolve())
    elif episode_time is not None:
        if not env.recipe:
            raise Refused(
                f"gymprecice: {env.name} has a fixed case; --episode-time does not apply "
                "(its episode length is the coupling's max-time; an env that takes "
                "episode_time= declares the lab card field 'episode_time')"
            )
        kwargs["episode_time"] = float(episode_time)
    elif getattr(args, "rollout", False) and env.recipe and env.rollout_time:
        kwargs["episode_time"] = float(env.rollout_time)
    kwargs.update(args.env_kwargs or {})
    return kwargs


def _vec_env(
    fns: Sequence[Callable[[], gym.Env]], kind: str, log_dir: Path, ray: str | None = None
) -> Any:
    """The vector env of kind ``kind`` (see ``gymprecice train --vec-env``).

    The resilient env gets no reset deadline of its own: an env's first reset includes
    the case's pre-run (minutes to hours of CFD), which has its own timeout in the
    solver plugin, and the Adapter's ``timeouts`` already catch hung couplings. With
    ``ray`` (``--ray auto|ADDRESS``) its envs are Ray actors on that cluster.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    if ray is not None:
        from gymprecice.sb3 import ResilientSubprocVecEnv
        from gymprecice.vector.ray import RayBackend

        backend = RayBackend(ray)
        return ResilientSubprocVecEnv(
            list(fns), reset_timeout=None, log_dir=str(log_dir), backend=backend
        )

    if kind == "dummy":
        return DummyVecEnv(list(fns))
    if kind in ("auto", "resilient"):
        try:
            from gymprecice.sb3 import ResilientSubprocVecEnv
        except ImportError:
            if kind == "resilient":
                raise SystemExit(
                    "gymprecice: --vec-env resilient needs gymprecice.sb3, which this "
                    "installation of gymprecice-core does not have"
                ) from None
        else:
            return ResilientSubprocVecEnv(list(fns), reset_timeout=None, log_dir=str(log_dir))
    return SubprocVecEnv(list(fns))


def _telemetry_callbacks(vec: Any) -> list[Any]:
    """gymprecice's telemetry callback (time in solvers vs env vs learner, failures) in
    TensorBoard, for the resilient vector env that measures it."""
    try:
        from gymprecice.sb3 import ResilientSubprocVecEnv, TelemetryCallback
    except ImportError:
        return []
    return [TelemetryCallback()] if isinstance(vec, ResilientSubprocVecEnv) else []


# -- training ------------------------------------------------------------------------------


def rollout_chunk(params: Mapping[str, Any], n_envs: int) -> int:
    """Env steps the algorithm takes between two checks of ``total_timesteps``.

    PPO collects whole rollouts of ``n_steps`` per env; SAC/TD3 ``train_freq`` steps per
    env (one by default). Training always ends on such a boundary.
    """
    if params["algo"] == "ppo":
        return int(params["n_steps"]) * n_envs
    freq = params.get("train_freq", 1)
    steps = freq[0] if isinstance(freq, (list, tuple)) else freq
    unit = freq[1] if isinstance(freq, (list, tuple)) and len(freq) > 1 else "step"
    return int(steps) * n_envs if unit == "step" else n_envs


def train(
    env: LabEnv,
    out: Path,
    env_kwargs: Mapping[str, Any],
    params: Mapping[str, Any],
    *,
    n_envs: int = 1,
    timesteps: int = 100_000,
    checkpoint_every: int | None = None,
    keep_checkpoints: int = 5,
    eval_freq: int | None = None,
    n_eval_episodes: int = 5,
    resume: Path | None = None,
    vec_env: str = "auto",
    ray: str | None = None,
    progress_bar: bool = True,
    device: str = "cpu",
    seed: int = 0,
    verbose: int = 0,
    segment: int = 1,
    agents: tuple[str, ...] = (),
) -> dict[str, Any]:
    """Train (or resume ``resume``) to ``timesteps`` env steps and return a summary.

    ``params`` are resolved hyperparameters (:func:`hyperparams.resolve`). Interruption by
    Ctrl-C, SIGTERM or SIGHUP is caught: the model and a checkpoint are saved and
    ``result["interrupted"]`` names the signal. With ``agents`` (``--shared-policy``) one
    policy learns from every agent's row (:mod:`gymprecice_lab.shared`): each env step
    is one learner step per agent, and ``timesteps`` counts those.
    """
    from gymprecice_lab.callbacks import prune_checkpoints, record_checkpoint
    from gymprecice_lab.evaluation_callback import eval_callback

    algo, normalize = params["algo"], bool(params.get("normalize"))
    checkpoints = out / "checkpoints"
    out.mkdir(parents=True, exist_ok=True)
    fns = _env_fns(env, out, env_kwargs, params, n_envs)
    base = _vec_env(fns, vec_env, out / "workers", ray)
    slots = n_envs * max(1, len(agents))  # learner steps per env step
    learner = shared_vec_env(base, agents) if agents else base
    recorder = _transition_recorder(learner, params)
    vec: Any = recorder or learner
    evaluator: Any = None
    try:
        base.seed(seed)
        learner_threads(params)
        model, vec = _model(params, vec, resume, device=device, seed=seed, verbose=verbose)
        model.set_logger(segment_logger(out, algo, segment, verbose))
        _attach_ensemble(model, recorder, params, out)
        done_before = int(model.num_timesteps)
        remaining, target = _steps_to_go(params, slots, timesteps, done_before)
        callbacks = _checkpointing(params, slots, checkpoints, checkpoint_every, keep_checkpoints)
        if eval_freq:
            evaluator = eval_callback(
                env, out, env_kwargs, n_envs, eval_freq, n_eval_episodes, seed, normalize, agents
            )
            callbacks.append(evaluator)
        callbacks += _telemetry_callbacks(base)
        started = time.monotonic()
        if remaining > 0:
            _announce(env, n_envs, algo, target, out, agents)
            interrupted = _learn(model, remaining, callbacks, out, resume is None, progress_bar)
        else:
            interrupted = None
            print(f"gymprecice train: already trained for {done_before:,} >= {timesteps:,} steps")
        final = _save(model, vec, checkpoints, out, algo, normalize)
        record_checkpoint(checkpoints, final, model)
        prune_checkpoints(checkpoints, algo, keep_checkpoints)
        return {
            "timesteps": int(model.num_timesteps),
            "timesteps_requested": timesteps,
            "timesteps_target": target,
            "resumed_from": str(resume) if resume else None,
            "steps_this_run": int(model.num_timesteps) - done_before,
            "seconds": round(time.monotonic() - started, 3),
            "model": str(out / "model.zip"),
            "model_sha256": file_sha256(out / "model.zip"),
            "checkpoint": str(final),
            "device": str(model.device),
            "interrupted": interrupted,
        }
    finally:
        merge_progress(out, segment)
        _close(evaluator, vec)


def _announce(
    env: LabEnv, n_envs: int, algo: str, target: int, out: Path, agents: tuple[str, ...]
) -> None:
    shared = (
        f", one policy shared by {len(agents)} agents ({', '.join(agents)}: "
        f"{len(agents)} steps per env step)"
        if agents
        else ""
    )
    print(
        f"gymprecice train: {env.name}, {n_envs} env(s){shared}, {algo.upper()} to "
        f"{target:,} steps; output in {out} (env logs: {out / 'workers'}). The first "
        "reset prepares each case (for OpenFOAM a pre-run to a developed flow, cached "
        "for later runs): minutes on real solvers.",
        flush=True,
    )


def _close(evaluator: Any, vec: Any) -> None:
    """Close the evaluation env and the training envs, whatever state their workers are in."""
    try:
        if evaluator is not None:
            evaluator.eval_env.close()
        vec.close()
    except (EOFError, BrokenPipeError, OSError):
        pass  # workers already gone (killed with the job): nothing left to close


def _env_fns(
    env: LabEnv, out: Path, env_kwargs: Mapping[str, Any], params: Mapping[str, Any], n: int
) -> list[Callable[[], gym.Env]]:
    """The ``n`` training envs' constructors, each with its monitor file in ``<out>/monitor``."""
    monitor = out / "monitor"
    monitor.mkdir(exist_ok=True)
    return [
        functools.partial(
            make_env,
            env.env_id,
            i,
            dict(env_kwargs),
            monitor_file=str(monitor / f"env_{i}"),
            robustness=params.get("robustness"),
        )
        for i in range(n)
    ]


def _transition_recorder(base: Any, params: Mapping[str, Any]) -> Any:
    """A recorder of the CFD transitions over ``base`` for model-ensemble PPO, else None."""
    if params.get(ENSEMBLE_KEY) is None:
        return None
    from gymprecice_lab.model_based.recorder import TransitionRecorder

    return TransitionRecorder(base)


def _model(
    params: Mapping[str, Any],
    vec: Any,
    resume: Path | None,
    *,
    device: str,
    seed: int,
    verbose: int,
) -> tuple[Any, Any]:
    """The algorithm's model, new or loaded from the checkpoint ``resume`` (its replay
    buffer and normalisation statistics too), and the vector env it steps: ``vec``, under
    ``VecNormalize`` where the hyperparameters normalise."""
    from stable_baselines3.common.vec_env import VecNormalize

    algo = params["algo"]
    cls = hp.algorithm_class(algo, params)
    if params.get("normalize"):
        if resume is not None:
            vec = VecNormalize.load(str(vecnormalize_path(resume)), vec)
        else:
            vec = VecNormalize(vec, gamma=float(params["gamma"]))
    learn_env = _overlapped(vec, params)
    if resume is not None:
        model = cls.load(resume, env=learn_env, device=device, seed=seed)
        steps = resume.name[len(algo) + 1 : -len("_steps.zip")]
        buffer = resume.with_name(f"{algo}_replay_buffer_{steps}_steps.pkl")
        if algo != "ppo" and buffer.is_file():
            model.load_replay_buffer(buffer)
        print(f"gymprecice train: resuming from {resume} ({model.num_timesteps} steps)")
    else:
        model = cls(
            "MlpPolicy",
            learn_env,
            seed=seed,
            device=device,
            verbose=verbose,
            **hp.model_kwargs(params, action_dim=math.prod(vec.action_space.shape)),
        )
    if learn_env is not vec:
        model.overlap_with(learn_env)
        print(
            f"gymprecice train: {hp.OVERLAP_KEY}: each update runs while the solvers compute "
            "the next step, so the telemetry below counts it in the batch step, not the "
            "learner's share"
        )
    return model, vec


def _attach_ensemble(model: Any, recorder: Any, params: Mapping[str, Any], out: Path) -> None:
    """Model-ensemble PPO: give the model its recorder and the transitions kept so far."""
    if recorder is None:
        return
    try:
        restored = model.attach(
            EnsembleSettings.from_value(params[ENSEMBLE_KEY], "hyperparams"),
            recorder,
            out / TRANSITIONS_FILE,
        )
    except ValueError as exc:
        raise SystemExit(f"gymprecice train: {exc}") from None
    if restored:
        print(f"gymprecice train: model ensemble: {restored:,} CFD transitions kept")


def _steps_to_go(
    params: Mapping[str, Any], n_envs: int, timesteps: int, done_before: int
) -> tuple[int, int]:
    """Steps to train now and the step count it ends at: ``timesteps`` rounded up to whole
    rollouts from ``done_before`` (said when it differs)."""
    chunk = rollout_chunk(params, n_envs)
    remaining = math.ceil(max(0, timesteps - done_before) / chunk) * chunk
    target = done_before + remaining
    if remaining and target != timesteps:
        print(
            f"gymprecice train: --timesteps {timesteps:,} is not a whole number of "
            f"{params['algo'].upper()} rollouts of {chunk} steps from {done_before:,}; "
            f"training to {target:,}"
        )
    return remaining, target


def _checkpointing(
    params: Mapping[str, Any],
    n_envs: int,
    checkpoints: Path,
    every: int | None,
    keep: int,
) -> list[Any]:
    """The callbacks every run has: rotating checkpoints (every 10 rollouts unless
    ``every`` steps) and the episodes' metrics in the log."""
    from gymprecice_lab.callbacks import EpisodeMetricsCallback, RotatingCheckpoints

    algo = params["algo"]
    every = every or 10 * rollout_chunk(params, n_envs)
    return [
        RotatingCheckpoints(
            save_freq=max(1, every // n_envs),
            save_path=str(checkpoints),
            name_prefix=algo,
            save_vecnormalize=bool(params.get("normalize")),
            save_replay_buffer=algo != "ppo",
            keep=keep,
        ),
        EpisodeMetricsCallback(),
    ]


def _learn(
    model: Any, steps: int, callbacks: list[Any], out: Path, fresh: bool, progress_bar: bool
) -> str | None:
    """Learn for ``steps`` env steps; the signal that interrupted it (None: it finished)."""
    from stable_baselines3.common.callbacks import CallbackList

    from gymprecice_lab.callbacks import Interrupted, stop_signals_interrupt
    from gymprecice_lab.prerun_progress import PrerunProgress

    try:
        with stop_signals_interrupt(), PrerunProgress(out / "envs"):
            model.learn(
                total_timesteps=steps,
                callback=CallbackList(callbacks),
                reset_num_timesteps=fresh,
                progress_bar=progress_bar,
            )
    except Interrupted as exc:
        return str(exc)
    except KeyboardInterrupt:
        # Ctrl-C: keep what was learnt (the policy lives in this process); the
        # same command resumes from the checkpoint written below.
        return "SIGINT"
    return None


def learner_threads(params: Mapping[str, Any]) -> int:
    """Cap the learner's CPU threads at ``torch_threads`` when the hyperparameters set it;
    return how many it has. They share the cores with the solvers: fewer can be faster."""
    import torch

    if params.get(hp.THREADS_KEY):
        torch.set_num_threads(int(params[hp.THREADS_KEY]))
    return torch.get_num_threads()


def _overlapped(vec: Any, params: Mapping[str, Any]) -> Any:
    """``vec`` under :class:`~gymprecice_lab.overlap.OverlappedUpdates` when the
    hyperparameters overlap the updates with the solvers, else ``vec`` itself."""
    if not params.get(hp.OVERLAP_KEY):
        return vec
    from gymprecice_lab.overlap import OverlappedUpdates

    return OverlappedUpdates(vec)


def _save(model: Any, vec: Any, checkpoints: Path, out: Path, prefix: str, normalize: bool) -> Path:
    """Save the final checkpoint, ``model.zip`` and their normalisation statistics."""
    checkpoints.mkdir(parents=True, exist_ok=True)
    final = checkpoints / f"{prefix}_{model.num_timesteps}_steps.zip"
    model.save(final)
    model.save(out / "model.zip")
    if normalize:
        vec.save(str(vecnormalize_path(final)))
        vec.save(str(vecnormalize_path(out / "model.zip")))
    if getattr(model, "replay_buffer", None) is not None:
        model.save_replay_buffer(
            checkpoints / f"{prefix}_replay_buffer_{model.num_timesteps}_steps.pkl"
        )
    return final


def _net(text: str) -> list[int]:
    try:
        sizes = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 1:
        raise SystemExit(f"gymprecice train: --net must be sizes like 512,512, got {text!r}")
    return sizes


def default_out(env: LabEnv, command: str) -> Path:
    """``runs/<env name>/<command>``: where a command writes without ``--out``."""
    return Path("runs") / env.name / command


def check_device(device: str) -> None:
    """Refuse a torch device this machine does not have (SB3 would fall back silently)."""
    import torch

    try:
        kind = torch.device(device).type
    except (RuntimeError, TypeError) as exc:
        raise SystemExit(f"gymprecice train: --device {device}: {exc}") from None
    if kind == "cuda" and not torch.cuda.is_available():
        raise SystemExit(
            f"gymprecice train: --device {device}: this torch ({torch.__version__}) sees no "
            f"CUDA device; use --device cpu (or install a CUDA build of torch)"
        )
    if kind == "mps" and not torch.backends.mps.is_available():
        raise SystemExit(
            f"gymprecice train: --device {device}: MPS is not available; use --device cpu"
        )


def hyperparameters(args: argparse.Namespace, env: LabEnv, out: Path) -> dict[str, Any]:
    """The run's resolved hyperparameters; copies ``--hyperparams`` into ``out``."""
    from_file: dict[str, Any] = {}
    if args.hyperparams is not None:
        keys = tuple(dict.fromkeys((env.env_id, env.name, env.env_id.split("/", 1)[-1])))
        from_file = hp.load_hyperparams_file(args.hyperparams, args.algo, keys)
    flags = {
        "n_steps": args.n_steps,
        "batch_size": args.batch_size,
        "n_epochs": args.n_epochs,
        "learning_rate": args.learning_rate,
        "gamma": args.gamma,
        "net": _net(args.net) if args.net is not None else None,
        "normalize": True if args.normalize else None,
        hp.SHARED_KEY: True if getattr(args, "shared_policy", False) else None,
    }
    return hp.resolve(args.algo, from_file, flags)


def _refuse_changed_resume(out: Path, params: Mapping[str, Any]) -> None:
    saved_path = out / hp.HYPERPARAMS_NAME
    if not saved_path.is_file():
        return
    changed = hp.changed_on_resume(json.loads(saved_path.read_text()), params)
    if changed:
        raise SystemExit(
            f"gymprecice train: cannot resume {out} with other hyperparameters: "
            f"{'; '.join(changed)} (SB3 would keep the saved values); rerun with the run's "
            f"values (see {saved_path.name}) or add --fresh to start over"
        )


def _adjust_batch_size(params: dict[str, Any], slots: int) -> list[str]:
    """PPO's mini-batch cannot exceed its rollout buffer: clamp it, say so, record it.

    ``slots`` is the learner's steps per env step: ``--n-envs``, times the agents with
    ``--shared-policy``."""
    if params["algo"] != "ppo":
        return []
    buffer = int(params["n_steps"]) * slots
    if int(params["batch_size"]) <= buffer:
        return []
    note = (
        f"--batch-size {params['batch_size']} is larger than the rollout buffer "
        f"(--n-steps {params['n_steps']} x {slots} learner slots = {buffer}); training "
        f"with batch size {buffer}"
    )
    params["batch_size"] = buffer
    print(f"gymprecice train: warning: {note}", file=sys.stderr)
    return [note]


def _start_fresh(out: Path) -> None:
    """``--fresh``: remove what a previous run left that would be mistaken for this one."""
    for pattern in ("checkpoints", "monitor", "tb", "eval", str(TRANSITIONS_FILE.parent)):
        shutil.rmtree(out / pattern, ignore_errors=True)
    for name in (
        "model.zip",
        "best_model.zip",
        "progress.csv",
        hp.HYPERPARAMS_NAME,
        "manifest.json",
    ):
        (out / name).unlink(missing_ok=True)
    for path in out.glob("*_vecnormalize.pkl"):
        path.unlink()


def _env_probe(env: LabEnv, kwargs: Mapping[str, Any]) -> Path | None:
    """The case the envs will run (materialised now, once, for all of them).

    Building one env here (no solver starts before ``reset``) writes the recipe's case, so
    the N env processes find it ready, gives its directory for the manifest, and turns a
    wrong ``--env-kwargs`` into one line instead of N crashed workers.
    """
    probe = make_env_checked(env.name, env.env_id, 0, kwargs, rescale=False)
    try:
        config = getattr(probe.unwrapped, "config", None)
        return Path(config.case_dir) if config is not None else None
    finally:
        probe.close()


def command_started_at() -> float:
    """When the command started (epoch seconds): now, or the typed command's start that a
    wrapper which sets up first passes in ``GYMPRECICE_STARTED_AT`` (scripts/train.sh),
    so that "how long did it take" counts from what the user typed."""
    given = os.environ.get("GYMPRECICE_STARTED_AT", "")
    try:
        started = float(given)
    except ValueError:
        return time.time()
    return started if 0 < started <= time.time() else time.time()


def train_command(args: argparse.Namespace) -> int:
    """``gymprecice train``."""
    from gymprecice_lab.manifest import solver_versions

    started_at = command_started_at()
    try:
        env = find_lab_env(args.env)
    except LabEnvError as exc:
        print(f"gymprecice train: {exc}", file=sys.stderr)
        return 2
    out = (args.out or default_out(env, "train")).resolve()
    kwargs = build_env_kwargs(args, env, out)  # usage errors first: they cost nothing to find
    check_device(args.device)
    solvers = solver_versions()
    if not args.double:
        status = require_solvers(
            env,
            "train",
            None if args.require_solvers else solvers,
            verbose=args.require_solvers,
            kwargs=kwargs,
        )
        if status:
            return status
    try:
        params = _with_robustness(hyperparameters(args, env, out), args)
    except WrapError as exc:
        print(f"gymprecice train: {exc} (in --wrap or the hyperparameter file)", file=sys.stderr)
        return 2
    resume = None if args.fresh else newest_checkpoint(out / "checkpoints")
    if resume is not None:
        _refuse_changed_resume(out, params)
    if args.fresh:
        _start_fresh(out)
    kwargs = build_env_kwargs(args, env, out)
    case_dir = _env_probe(env, kwargs)
    _keep_hyperparameters(args, out, params, resumed=resume is not None)
    used = dict(params)
    agents = shared_agents(env, used)
    slots = args.n_envs * max(1, len(agents))
    settings = _settings(args, env, used, _adjust_batch_size(used, slots), kwargs)
    seeds = {"seed": args.seed, "env_seeds": [args.seed + i for i in range(args.n_envs)]}
    segments = _previous_segments(out) if resume is not None else []
    record = functools.partial(
        _record_segment, out, settings, seeds, segments, case_dir, solvers, started_at
    )
    record(None)
    result = train(
        env,
        out,
        kwargs,
        used,
        n_envs=args.n_envs,
        timesteps=args.timesteps,
        checkpoint_every=args.checkpoint_every,
        keep_checkpoints=args.keep_checkpoints,
        eval_freq=args.eval_freq,
        n_eval_episodes=args.n_eval_episodes,
        resume=resume[0] if resume else None,
        vec_env=args.vec_env,
        ray=getattr(args, "ray", None),
        progress_bar=not args.no_progress_bar,
        device=args.device,
        seed=args.seed,
        verbose=args.verbose,
        segment=len(segments) + 1,
        agents=agents,
    )
    record(result)
    return _report(result, out)


def _with_robustness(params: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    """``params`` with the robustness wrappers of the file and ``--wrap`` together (a
    ``WrapError`` for a malformed one), none left where there are none."""
    robustness = wrap_spec(params.get("robustness"), getattr(args, "wrap", []))
    if robustness:
        params["robustness"] = robustness
    else:
        params.pop("robustness", None)
    return params


def _keep_hyperparameters(
    args: argparse.Namespace, out: Path, params: Mapping[str, Any], *, resumed: bool
) -> None:
    """Write the run's hyperparameters (a resume keeps the first run's) and a copy of
    ``--hyperparams`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    if not resumed:
        (out / hp.HYPERPARAMS_NAME).write_text(json.dumps(params, indent=2) + "\n")
    if args.hyperparams is not None and args.hyperparams.resolve() != (out / "hyperparams.yaml"):
        shutil.copyfile(args.hyperparams, out / "hyperparams.yaml")


def _settings(
    args: argparse.Namespace,
    env: LabEnv,
    used: dict[str, Any],
    adjusted: list[str],
    kwargs: dict[str, Any],
) -> dict[str, Any]:
    """What the manifest records of the run's settings."""
    return {
        "n_envs": args.n_envs,
        "timesteps": args.timesteps,
        "checkpoint_every": args.checkpoint_every,
        "keep_checkpoints": args.keep_checkpoints,
        "eval_freq": args.eval_freq,
        "n_eval_episodes": args.n_eval_episodes,
        "fresh": args.fresh,
        "vec_env": args.vec_env,
        "device": args.device,
        "double": args.double,
        "hyperparams_file": str(args.hyperparams) if args.hyperparams else None,
        "hyperparams": used,
        "adjusted": adjusted,
        "env_id": env.env_id,
        "env_kwargs": kwargs,
    }


def _record_segment(
    out: Path,
    settings: dict[str, Any],
    seeds: dict[str, Any],
    segments: list[dict[str, Any]],
    case_dir: Path | None,
    solvers: Any,
    started_at: float,
    result: Mapping[str, Any] | None,
) -> None:
    """Write the manifest: the earlier segments and this one, with its ``result`` (None
    while it runs)."""
    segment = {
        "argv": list(sys.argv),
        "started_at": started_at,
        "settings": settings,
        "seeds": seeds,
        "result": result,
    }
    write_manifest(
        out,
        command="train",
        case_dir=case_dir,
        seeds=seeds,
        settings=settings,
        solvers=solvers,
        extra={"result": result, "segments": [*segments, segment]},
    )


def _report(result: Mapping[str, Any], out: Path) -> int:
    """Say how the run ended; its exit status (128 + the signal that interrupted it)."""
    if result["interrupted"]:
        print(
            f"gymprecice train: interrupted ({result['interrupted']}) after "
            f"{result['timesteps']:,} steps; saved {result['model']} and a checkpoint; run the "
            f"same command again to resume",
            file=sys.stderr,
        )
        return _exit_status(result["interrupted"])
    print(
        f"gymprecice train: {result['timesteps']:,} steps; model {result['model']}; "
        f"TensorBoard: tensorboard --logdir {out / 'tb'}"
    )
    return 0


def _exit_status(signal_name: str) -> int:
    """128 + the signal's number, as a shell reports a process the signal ended."""
    import signal

    return 128 + int(getattr(signal, signal_name, signal.SIGINT))


def _previous_segments(out: Path) -> list[dict[str, Any]]:
    """The manifest records of the segments before this one (a resume keeps them all)."""
    try:
        manifest = read_manifest(out)
    except (OSError, ValueError):
        return []
    if "segments" in manifest:
        return list(manifest["segments"])
    keys = ("argv", "settings", "seeds", "result")
    return [{k: manifest.get(k) for k in keys}]
