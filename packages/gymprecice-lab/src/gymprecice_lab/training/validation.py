"""Validation during ``gymprecice train``: the model a run keeps is its best on validation.

A run's last model is not its best: SAC's and PPO's policies wander between updates, and
on the jet cylinder a run's checkpoints differed by five points of the drag floor from
its final model. So every ``--eval-freq`` env steps (default: at every checkpoint) the
policy is run deterministically from the env's *validation starts*
(:func:`~gymprecice_lab.common.starts.validation_starts`: disjoint from the held-out starts that
judge a controller, and from what training draws), once from each, and the best so far is
kept as ``best_model.zip`` with ``eval/best.json``: its step, its score, its wall-clock
from the typed command, and the starts it was scored on. The score is the mean
validation return, or, for an env whose card declares a physical reference (a drag
floor), the fraction of the floor it reaches once settled, over longer episodes
(:mod:`gymprecice_lab.training.validation_score`): what the benchmark judges. The
held-out starts never choose: judging a model on the starts that chose it would flatter
it.

SB3's ``EvalCallback`` does the running, on an env of its own (index ``n_envs``, its own
run directory). Added here: the validation starts, the record, a last validation of the
final model (so the kept model is never worse on validation than the final one), the
best score and ``eval/evaluations.npz`` that survive a resume, and with ``--normalize``
the normalisation statistics saved beside the kept model, which is unusable without them.
The kept model and its statistics are saved whole or not at all
(:func:`~gymprecice_lab.training.callbacks.save_checkpoint`), and then its record: a run killed
mid-save keeps the kept model before it, with the record that names it.
"""

from __future__ import annotations

import functools
import json
import time
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import (
    BaseCallback,
    EvalCallback,
    StopTrainingOnRewardThreshold,
)
from stable_baselines3.common.vec_env import VecEnvWrapper

from gymprecice_lab.common.kept_model import KEPT_RECORD
from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.common.wrapped_env import make_env, vecnormalize_path
from gymprecice_lab.training.callbacks import save_checkpoint
from gymprecice_lab.training.validation_score import (
    score_name,
    settled_reference,
    validation_episode_time,
)

__all__ = ["EVAL_SEED_OFFSET", "eval_callback", "side_by_side", "validate_final"]

# SB3 warns when the validation env's class differs from the training env's: here it
# does by design (the training envs are fault-tolerant subprocesses, the validation env
# may run in this process), and the wrapper chains that matter are kept alike.
warnings.filterwarnings("ignore", message="Training and eval env are not of the same type")

#: evaluation episodes are seeded from ``seed + EVAL_SEED_OFFSET`` on
EVAL_SEED_OFFSET = 10_000


class _SaveBest(BaseCallback):
    """Called by ``EvalCallback`` on a new best: save it with its statistics, record it."""

    def __init__(
        self,
        out: Path,
        normalize: bool,
        labels: tuple[str, ...],
        started_at: float | None,
        score: str,
        episode_time: float | None,
        trained_before: float = 0.0,
    ) -> None:
        super().__init__()
        self.out = out
        self.normalize = normalize
        self.labels = labels
        self.started_at = started_at
        self.score = score
        self.episode_time = episode_time
        self.trained_before = trained_before

    def _on_step(self) -> bool:
        parent = self.parent
        assert isinstance(parent, EvalCallback)
        now = time.time()
        returns = [float(r) for r in parent.evaluations_results[-1]]
        record = {
            "mean_return": float(parent.best_mean_reward),
            "timesteps": self.num_timesteps,
            "score": self.score,
            "starts": list(self.labels),
            "episode_time": self.episode_time,
            "returns": returns,
            "saved_at": round(now, 3),
            "seconds_from_command": (
                round(now - self.started_at, 1) if self.started_at is not None else None
            ),
            # the same, over a resumed run's segments, the gaps between them left out
            "seconds_of_training": (
                round(self.trained_before + now - self.started_at, 1)
                if self.started_at is not None
                else None
            ),
        }
        kept = self.out / "best_model.zip"
        stats = self.model.get_vec_normalize_env() if self.normalize else None
        save_checkpoint(
            self.model,
            kept,
            stats=stats,
            stats_path=vecnormalize_path(kept) if stats is not None else None,
        )
        (self.out / "eval").mkdir(exist_ok=True)
        tmp = self.out / "eval" / ".best.json.tmp"
        tmp.write_text(json.dumps(record, indent=2) + "\n")
        tmp.replace(self.out / KEPT_RECORD)
        return True


def eval_callback(
    env: LabEnv,
    out: Path,
    env_kwargs: Mapping[str, Any],
    n_envs: int,
    eval_freq: int,
    n_eval_episodes: int | None,
    seed: int,
    normalize: bool,
    agents: tuple[str, ...] = (),
    started_at: float | None = None,
    vec_env: str = "dummy",
    training_vec: Any = None,
    trained_before: float = 0.0,
    stop_at: float | None = None,
    validation_time: float | None = None,
) -> EvalCallback:
    """The validation callback of a training run into ``out``.

    ``n_eval_episodes`` ``None`` runs each validation start once per validation. With
    ``agents`` (a shared policy) the validation env has one slot per agent, as the
    training env does: each of its episodes counts once per agent. ``started_at``
    (epoch seconds) is when the command was typed, for the kept model's wall-clock;
    ``trained_before``, the seconds a resumed run trained in its earlier segments.
    Validation envs run side by side, one per training env at most
    (:func:`side_by_side`), in a vector env of kind ``vec_env`` (``--vec-env``): while
    they run, the training envs wait, so their cores are free. ``stop_at`` stops training
    after the first validation whose score reaches it (the kept model is saved first).
    ``validation_time`` (simulated seconds) sets the validation episodes' length, for an
    env that takes ``episode_time`` (default: where the score is a settled one, the
    card's settle time and a training episode, else a training episode); a resumed run
    validated over episodes of another length starts its validations afresh.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from gymprecice_lab.common.starts import validation_starts

    (out / "eval").mkdir(parents=True, exist_ok=True)
    probe = make_env(env.env_id, n_envs, dict(env_kwargs), rescale=False)
    try:
        labels = validation_starts(probe)
        episode_time = env_kwargs.get(
            "episode_time", getattr(probe.unwrapped, "episode_time", None)
        )
    finally:
        probe.close()
    reference = settled_reference(env.card)
    if reference is not None and reference.settle_time > 0 and episode_time is None:
        reference = None  # the card says it takes one, but the env does not tell
    if validation_time is not None and episode_time is not None:
        episode_time = float(validation_time)
        env_kwargs = {**env_kwargs, "episode_time": episode_time}
    elif reference is not None and reference.settle_time > 0:
        episode_time = validation_episode_time(reference, float(episode_time))
        env_kwargs = {**env_kwargs, "episode_time": episode_time}
    parts = side_by_side(len(labels), n_envs)
    fns = [
        functools.partial(
            make_env,
            env.env_id,
            n_envs + part,
            dict(env_kwargs),
            monitor_file=str(out / "eval" / (f"env_{part}" if parts > 1 else "env")),
            validation=(part, parts),
            score=reference,
        )
        for part in range(parts)
    ]
    if parts > 1:
        from gymprecice_lab.training.vector_env import make_vec_env

        eval_env: Any = make_vec_env(fns, vec_env, out / "eval" / "workers")
    else:
        eval_env = DummyVecEnv(fns)
    if n_eval_episodes is None:
        n_eval_episodes = len(labels)
    eval_env.seed(seed + EVAL_SEED_OFFSET)
    if agents:
        from gymprecice_lab.training.shared_policy import shared_vec_env

        eval_env = shared_vec_env(eval_env, agents)
    slots = n_envs * max(1, len(agents))
    if normalize:
        # statistics are copied from the training env before each evaluation, by SB3's
        # walk down both wrapper chains in step: give this one as many layers
        eval_env = _layered(
            VecNormalize(eval_env, training=False, norm_reward=False),
            _layers_above_normalization(training_vec),
        )
    callback = EvalCallback(
        eval_env,
        callback_on_new_best=_SaveBest(
            out,
            normalize,
            labels,
            started_at,
            score_name(reference),
            float(episode_time) if episode_time is not None else None,
            trained_before,
        ),
        n_eval_episodes=n_eval_episodes * max(1, len(agents)),
        eval_freq=max(1, eval_freq // slots),
        log_path=str(out / "eval"),
        best_model_save_path=None,  # _SaveBest saves it whole
        callback_after_eval=(
            StopTrainingOnRewardThreshold(reward_threshold=stop_at) if stop_at is not None else None
        ),
        deterministic=True,
        verbose=0,
    )
    try:
        previous = json.loads((out / "eval" / "best.json").read_text())
    except (OSError, ValueError):
        previous = {}
    # a run resumed by a gymprecice that scores otherwise, or over episodes of another
    # length, starts its validations afresh: a return and a fraction of a floor do not
    # compare, nor a drag settled over 2 s and one over 8 s
    same_episodes = previous.get("episode_time", episode_time) == (
        float(episode_time) if episode_time is not None else None
    )
    if previous.get("score", score_name(None)) == score_name(reference) and same_episodes:
        try:
            callback.best_mean_reward = float(previous["mean_return"])
        except (KeyError, TypeError, ValueError):
            pass
        _keep_evaluations(callback, out / "eval" / "evaluations.npz")
    return callback


def _layers_above_normalization(vec: Any) -> int:
    """How many vector-env wrappers the model's env has above its ``VecNormalize`` (the
    overlapped learner's, :mod:`gymprecice_lab.training.overlap`): SB3's sync walks both chains
    in step from the top, so the validation env needs as many."""
    from stable_baselines3.common.vec_env import VecNormalize

    count, inner = 0, vec
    while isinstance(inner, VecEnvWrapper) and not isinstance(inner, VecNormalize):
        count, inner = count + 1, inner.venv
    return count if isinstance(inner, VecNormalize) else 0


def _layered(vec: Any, layers: int) -> Any:
    """``vec`` inside ``layers`` pass-through wrappers."""
    for _ in range(layers):
        vec = _PassThrough(vec)
    return vec


class _PassThrough(VecEnvWrapper):
    """A layer that changes nothing: keeps the validation env's wrapper chain as deep as
    the training env's, which SB3's normalisation sync walks in step."""

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> Any:
        return self.venv.step_wait()


def side_by_side(starts: int, n_envs: int) -> int:
    """How many validation envs run at once: the most, up to ``n_envs`` (the cores the
    training envs leave idle while validation runs), that divides the ``starts`` evenly
    (each env then takes the same starts in every validation)."""
    return max(k for k in range(1, max(1, min(starts, n_envs)) + 1) if starts % k == 0)


def validate_final(callback: EvalCallback) -> None:
    """Validate the model once more unless the last validation was of this very step: the
    final model is a candidate too."""
    model = callback.model
    done = callback.evaluations_timesteps
    if callback.eval_freq <= 0 or (done and done[-1] == model.num_timesteps):
        return
    callback.n_calls = callback.eval_freq * max(1, callback.n_calls // callback.eval_freq + 1)
    callback.num_timesteps = model.num_timesteps
    callback._on_step()


def _keep_evaluations(callback: EvalCallback, path: Path) -> None:
    """Start from the evaluations a previous segment wrote: SB3 rewrites the file from
    its own lists at every evaluation, which a resumed run would start empty."""
    import numpy as np

    if not path.is_file():
        return
    try:
        with np.load(path) as data:
            callback.evaluations_timesteps = [int(t) for t in data["timesteps"]]
            callback.evaluations_results = [list(r) for r in data["results"]]
            callback.evaluations_length = [list(n) for n in data["ep_lengths"]]
    except (OSError, ValueError, KeyError):
        return  # unreadable: SB3 writes a new one
