"""``gymprecice train``: PPO, SAC, TD3 (Stable-Baselines3) or TQC (sb3-contrib) on N envs.

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
* **the model worth keeping**: at every checkpoint (``--eval-freq``) the policy is scored
  from the env's validation starts, never its held-out ones, and the best is kept as
  ``best_model.zip`` beside the final ``model.zip``, with its step, score and wall-clock
  (:mod:`gymprecice_lab.training.validation`); evaluate, ship-policy, benchmark and
  time-to-floor take it by default;
* **traceable**: ``<out>/manifest.json`` with one record per segment (first run and each
  resume), the hyperparameters actually used, the device, the source revision and the
  model's checksum; ``<out>/hyperparams.json`` and a copy of ``--hyperparams``.

Actions are rescaled to ``[-1, 1]`` for the policy (``RescaleAction``): a Gaussian policy
starts with unit standard deviation, which against a ``±2.5e-4`` box would only ever
produce the bounds. :func:`gymprecice_lab.common.wrapped_env.load_policy` rebuilds that env.

This module is the command: given its settings
(:class:`~gymprecice_lab.training.command_settings.TrainSettings`: the env and its
constructor arguments are derived there, once), it checks the device and the solvers,
resolves the hyperparameters (:mod:`gymprecice_lab.training.hyperparams`), finds the
checkpoint to resume from, records each segment (:mod:`gymprecice_lab.training.segments`) and reports how the
run ended; the training itself is :func:`gymprecice_lab.training.loop.train`.
"""

from __future__ import annotations

import functools
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice_lab.common.kept_model import kept_summary
from gymprecice_lab.common.registered_env import LabEnvError
from gymprecice_lab.common.requirements import require_solvers
from gymprecice_lab.common.training_clock import training_seconds
from gymprecice_lab.common.wrapped_env import newest_checkpoint
from gymprecice_lab.common.wrapping import WrapError
from gymprecice_lab.model_based.settings import TRANSITIONS_FILE
from gymprecice_lab.training import hyperparams as hp
from gymprecice_lab.training.command_settings import TrainSettings
from gymprecice_lab.training.loop import train
from gymprecice_lab.training.segments import (
    command_started_at,
    previous_segments,
    record_segment,
    run_settings,
)
from gymprecice_lab.training.shared_policy import shared_agents
from gymprecice_lab.training.vector_env import probe_case

__all__ = ["check_device", "train_command"]


def train_command(settings: TrainSettings) -> int:
    """``gymprecice train``."""
    from gymprecice_lab.common.manifest import solver_versions

    started_at = command_started_at()
    try:
        env = settings.lab_env
    except LabEnvError as exc:
        print(f"gymprecice train: {exc}", file=sys.stderr)
        return 2
    out = settings.run_dir
    if settings.stop_at is not None and settings.no_validation:
        print(
            "gymprecice train: --stop-at stops at a validation's score, and --no-validation "
            "runs none: drop one of them",
            file=sys.stderr,
        )
        return 2
    kwargs = settings.constructor_kwargs  # usage errors first: they cost nothing to find
    check_device(settings.device)
    solvers = solver_versions()
    if not settings.double:
        status = require_solvers(
            env,
            "train",
            None if settings.require_solvers else solvers,
            verbose=settings.require_solvers,
            kwargs=kwargs,
        )
        if status:
            return status
    try:
        params = hp.with_robustness(hp.hyperparameters(settings, env), settings.wrap)
    except WrapError as exc:
        print(f"gymprecice train: {exc} (in --wrap or the hyperparameter file)", file=sys.stderr)
        return 2
    resume = None if settings.fresh else newest_checkpoint(out / "checkpoints")
    if resume is not None:
        hp.refuse_changed_resume(out, params)
    if settings.fresh:
        _start_fresh(out)
    case_dir = probe_case(env, kwargs)
    hp.keep_hyperparameters(settings.hyperparams, out, params, resumed=resume is not None)
    used = dict(params)
    agents = shared_agents(env, used)
    slots = settings.n_envs * max(1, len(agents))
    run = run_settings(settings, used, hp.adjust_batch_size(used, slots))
    seeds = {
        "seed": settings.seed,
        "env_seeds": [settings.seed + i for i in range(settings.n_envs)],
    }
    segments = previous_segments(out) if resume is not None else []
    record = functools.partial(
        record_segment, out, run, seeds, segments, case_dir, solvers, started_at
    )
    record(None)
    result = train(
        env,
        out,
        kwargs,
        used,
        n_envs=settings.n_envs,
        timesteps=settings.timesteps,
        checkpoint_every=settings.checkpoint_every,
        keep_checkpoints=settings.keep_checkpoints,
        eval_freq=settings.eval_freq,
        stop_at=settings.stop_at,
        validation_time=settings.validation_time,
        n_eval_episodes=settings.n_eval_episodes,
        validate=not settings.no_validation,
        started_at=started_at,
        trained_before=training_seconds([*segments, {"started_at": started_at}], started_at) or 0.0,
        resume=resume[0] if resume else None,
        vec_env=settings.vec_env,
        ray=settings.ray,
        progress_bar=not settings.no_progress_bar,
        device=settings.device,
        seed=settings.seed,
        verbose=settings.verbose,
        segment=len(segments) + 1,
        agents=agents,
    )
    record(result)
    return _report(result, out)


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
    stopped = result.get("stopped_at")
    if stopped:
        print(
            f"gymprecice train: stopped: the validation at step {stopped['timesteps']:,} "
            f"scored {stopped['value']:.4g} >= --stop-at {stopped['stop_at']:g}"
        )
    kept = result.get("kept")
    if kept:
        print(f"gymprecice train: kept model {kept['model']}: {kept_summary(kept)}")
    return 0


def _exit_status(signal_name: str) -> int:
    """128 + the signal's number, as a shell reports a process the signal ended."""
    import signal

    return 128 + int(getattr(signal, signal_name, signal.SIGINT))
