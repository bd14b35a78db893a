"""The training loop of ``gymprecice train``: one segment, from the envs to the saved model.

:func:`train` is the command's work once its options are checked: it builds the envs
(:mod:`gymprecice_lab.training.vector_env`) and the model (:mod:`gymprecice_lab.training.learner`),
learns to a whole number of rollouts with rotating checkpoints, the episodes' metrics,
an optional evaluation and gymprecice's telemetry as callbacks, turns Ctrl-C, SIGTERM
and SIGHUP into a saved model and checkpoint, and returns the summary the manifest
records. A resume is the same call with the checkpoint to continue from.
"""

from __future__ import annotations

import math
import signal
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gymprecice_lab.common.manifest import file_sha256
from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.common.wrapped_env import vecnormalize_path
from gymprecice_lab.training.learner import (
    attach_ensemble,
    build_model,
    learner_threads,
    transition_recorder,
)
from gymprecice_lab.training.logger import merge_progress, segment_logger
from gymprecice_lab.training.shared_policy import shared_vec_env
from gymprecice_lab.training.vector_env import env_fns, make_vec_env, telemetry_callbacks

__all__ = ["rollout_chunk", "train"]


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
    stop_at: float | None = None,
    validation_time: float | None = None,
    n_eval_episodes: int | None = None,
    validate: bool = True,
    started_at: float | None = None,
    trained_before: float = 0.0,
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
    policy learns from every agent's row (:mod:`gymprecice_lab.training.shared_policy`): each env step
    is one learner step per agent, and ``timesteps`` counts those.

    With ``validate`` (the default) the policy is scored from the env's validation starts
    every ``eval_freq`` env steps (default: at every checkpoint) and once more at the end,
    and the best is kept as ``best_model.zip`` (:mod:`gymprecice_lab.training.validation`).
    With ``stop_at`` training ends at the first validation that scores at least that
    (SB3's ``StopTrainingOnRewardThreshold``), and a run whose kept model already does
    trains no further: ``result["stopped_at"]`` records the step and the score.
    """
    from gymprecice_lab.training.callbacks import (
        hold_stop_signals,
        prune_checkpoints,
        record_checkpoint,
        remove_partial_saves,
    )
    from gymprecice_lab.training.validation import eval_callback, validate_final

    algo, normalize = params["algo"], bool(params.get("normalize"))
    checkpoints = out / "checkpoints"
    out.mkdir(parents=True, exist_ok=True)
    remove_partial_saves(out)  # what a save killed mid-way left (SIGKILL after SIGTERM)
    remove_partial_saves(checkpoints, algo)
    fns = env_fns(env, out, env_kwargs, params, n_envs)
    base = make_vec_env(fns, vec_env, out / "workers", ray)
    slots = n_envs * max(1, len(agents))  # learner steps per env step
    learner = shared_vec_env(base, agents) if agents else base
    recorder = transition_recorder(learner, params)
    vec: Any = recorder or learner
    evaluator: Any = None
    try:
        base.seed(seed)
        learner_threads(params)
        model, vec = build_model(params, vec, resume, device=device, seed=seed, verbose=verbose)
        model.set_logger(segment_logger(out, algo, segment, verbose))
        attach_ensemble(model, recorder, params, out)
        done_before = int(model.num_timesteps)
        remaining, target = _steps_to_go(params, slots, timesteps, done_before)
        callbacks = _checkpointing(params, slots, checkpoints, checkpoint_every, keep_checkpoints)
        pending = False  # a validation the resumed checkpoint is owed
        if validate:
            every = eval_freq or checkpoint_every or 10 * rollout_chunk(params, slots)
            evaluator = eval_callback(
                env,
                out,
                env_kwargs,
                n_envs,
                every,
                n_eval_episodes,
                seed,
                normalize,
                agents,
                started_at,
                vec_env="dummy" if ray is not None else vec_env,
                training_vec=model.get_env(),
                trained_before=trained_before,
                stop_at=stop_at,
                validation_time=validation_time,
            )
            callbacks.append(evaluator)
            pending = resume is not None and _unvalidated(evaluator, done_before, every)
            if _reached(evaluator, stop_at):
                print(
                    f"gymprecice train: the kept model already scores "
                    f"{evaluator.best_mean_reward:.4g} >= --stop-at {stop_at:g}; not training on"
                )
                remaining = 0
        callbacks += telemetry_callbacks(base)
        started = time.monotonic()
        # a stop signal outside learning and the last validation waits for the save
        with hold_stop_signals() as held:
            interrupted = None
            if pending and not held:
                # the checkpoint resumed from was saved, but its run was stopped during
                # the validation of that step: validate it now, or it is never a candidate
                evaluator.init_callback(model)
                interrupted = _validate_final(evaluator, validate_final)
                if _reached(evaluator, stop_at):
                    print(
                        f"gymprecice train: the resumed checkpoint scores "
                        f"{evaluator.best_mean_reward:.4g} >= --stop-at {stop_at:g}; "
                        "not training on"
                    )
                    remaining = 0
            if interrupted is None and remaining > 0:
                _announce(env, n_envs, algo, target, out, agents)
                interrupted = _learn(
                    model, remaining, callbacks, out, resume is None, progress_bar, held
                )
            elif interrupted is None and not _reached(evaluator, stop_at):
                print(
                    f"gymprecice train: already trained for {done_before:,} >= {timesteps:,} steps"
                )
            if evaluator is not None and interrupted is None and not held:
                interrupted = _validate_final(evaluator, validate_final)
            final = _save(model, vec, checkpoints, out, algo, normalize)
            record_checkpoint(checkpoints, final, model)
            prune_checkpoints(checkpoints, algo, keep_checkpoints)
        if interrupted is None and held:
            interrupted = signal.Signals(held[0]).name
        kept = _kept(out)
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
            "kept": kept,
            "stopped_at": _stopped_at(kept, stop_at) if _reached(evaluator, stop_at) else None,
        }
    finally:
        merge_progress(out, segment)
        _close(evaluator, vec)


def _validate_final(evaluator: Any, validate_final: Any) -> str | None:
    """Score the final model on the validation starts; the signal that interrupted it.

    The final model is saved whatever happens here; an interrupted or failed last
    validation leaves the kept model the best of the earlier ones.
    """
    from gymprecice_lab.training.callbacks import Interrupted, stop_signals_interrupt

    try:
        with stop_signals_interrupt():
            validate_final(evaluator)
    except Interrupted as exc:
        return str(exc)
    except KeyboardInterrupt:
        return "SIGINT"
    except Exception as exc:  # a solver fault must not lose the final model
        print(
            f"gymprecice train: the last validation did not finish ({exc}); the kept model is "
            "the best of the earlier validations"
        )
    return None


def _unvalidated(evaluator: Any, step: int, every: int) -> bool:
    """Whether ``step`` (the checkpoint a run resumes from) is a validation step whose
    validation is not on record: a stop signal during a validation ends the run after the
    step's checkpoint is saved, and the resumed run would validate only from the next."""
    done = evaluator.evaluations_timesteps
    return step > 0 and every > 0 and step % every == 0 and (not done or done[-1] < step)


def _reached(evaluator: Any, stop_at: float | None) -> bool:
    """Whether a validation has scored ``stop_at`` or more (``--stop-at``)."""
    return stop_at is not None and evaluator is not None and evaluator.best_mean_reward >= stop_at


def _stopped_at(kept: Mapping[str, Any] | None, stop_at: float) -> dict[str, Any]:
    """What the manifest records of a run stopped by ``--stop-at``: the threshold, and the
    step and score of the kept model (``kept``: its record) that reached it."""
    kept = kept or {}
    return {
        "stop_at": stop_at,
        "timesteps": kept.get("timesteps"),
        "score": kept.get("score"),
        "value": kept.get("mean_return"),
    }


def _kept(out: Path) -> dict[str, Any] | None:
    """The kept model's record, with its file's checksum (``None``: none kept)."""
    from gymprecice_lab.common.kept_model import read_kept

    record = read_kept(out)
    if record is None:
        return None
    return {
        **record,
        "model": str(out / "best_model.zip"),
        "model_sha256": file_sha256(out / "best_model.zip"),
    }


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
    from gymprecice_lab.training.callbacks import (
        EpisodeMetricsCallback,
        RotatingCheckpoints,
        StopOnSignal,
    )

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
        StopOnSignal(),
    ]


def _learn(
    model: Any,
    steps: int,
    callbacks: list[Any],
    out: Path,
    fresh: bool,
    progress_bar: bool,
    held: Sequence[int] = (),
) -> str | None:
    """Learn for ``steps`` env steps; the signal that interrupted it (None: it finished).

    ``held``: the stop signals that arrived just before, while they were held
    (:func:`~gymprecice_lab.training.callbacks.hold_stop_signals`); learning then does not start.
    """
    from stable_baselines3.common.callbacks import CallbackList

    from gymprecice_lab.training.callbacks import Interrupted, stop_signals_interrupt
    from gymprecice_lab.training.prerun_progress import PrerunProgress

    try:
        with stop_signals_interrupt(), PrerunProgress(out / "envs"):
            if held:
                raise Interrupted(held[0])
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


def _save(model: Any, vec: Any, checkpoints: Path, out: Path, prefix: str, normalize: bool) -> Path:
    """Save the final checkpoint (with its replay buffer), then ``model.zip``, each with
    its normalisation statistics, each whole or not at all
    (:func:`~gymprecice_lab.training.callbacks.save_checkpoint`): a SIGKILL mid-save leaves the
    previous checkpoint the newest whole one."""
    from gymprecice_lab.training.callbacks import save_checkpoint

    final = checkpoints / f"{prefix}_{model.num_timesteps}_steps.zip"
    stats = vec if normalize else None
    save_checkpoint(
        model,
        final,
        replay_buffer=checkpoints / f"{prefix}_replay_buffer_{model.num_timesteps}_steps.pkl",
        stats=stats,
        stats_path=vecnormalize_path(final),
    )
    model_zip = out / "model.zip"
    save_checkpoint(model, model_zip, stats=stats, stats_path=vecnormalize_path(model_zip))
    return final


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
