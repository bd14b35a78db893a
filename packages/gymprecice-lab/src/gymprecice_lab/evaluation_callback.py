"""``gymprecice train --eval-freq``: deterministic evaluation on a separate environment.

SB3's ``EvalCallback`` runs ``--n-eval-episodes`` on an env of its own (index
``n_envs``, so its own run directory, and seeds the training envs never get) and saves
``best_model.zip`` whenever the mean return beats the best so far. Added here: its env
starts every episode from the held-out split, the held-out starts in turn
(:class:`~gymprecice_lab.starts.HeldOutStarts`; ``--n-eval-episodes`` equal to their
number runs each once per evaluation), the best score and ``eval/evaluations.npz``
survive a resume (``eval/best.json``), and with ``--normalize`` the normalisation
statistics are saved beside the best model, which would be unusable without them.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from gymprecice_lab.envs import make_env, vecnormalize_path
from gymprecice_lab.lab_env import LabEnv

__all__ = ["EVAL_SEED_OFFSET", "eval_callback"]

#: evaluation episodes are seeded from ``seed + EVAL_SEED_OFFSET`` on
EVAL_SEED_OFFSET = 10_000


class _SaveBest(BaseCallback):
    """Called by ``EvalCallback`` on a new best: record it and save its statistics."""

    def __init__(self, out: Path, normalize: bool) -> None:
        super().__init__()
        self.out = out
        self.normalize = normalize

    def _on_step(self) -> bool:
        parent = self.parent
        assert isinstance(parent, EvalCallback)
        record = {"mean_return": float(parent.best_mean_reward), "timesteps": self.num_timesteps}
        (self.out / "eval").mkdir(exist_ok=True)
        (self.out / "eval" / "best.json").write_text(json.dumps(record, indent=2) + "\n")
        if self.normalize:
            vec = self.model.get_vec_normalize_env()
            if vec is not None:
                vec.save(str(vecnormalize_path(self.out / "best_model.zip")))
        return True


def eval_callback(
    env: LabEnv,
    out: Path,
    env_kwargs: Mapping[str, Any],
    n_envs: int,
    eval_freq: int,
    n_eval_episodes: int,
    seed: int,
    normalize: bool,
    agents: tuple[str, ...] = (),
) -> EvalCallback:
    """The evaluation callback of a training run into ``out``.

    With ``agents`` (a shared policy) the evaluation env has one slot per agent, as the
    training env does: each of its ``n_eval_episodes`` episodes counts once per agent.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    (out / "eval").mkdir(parents=True, exist_ok=True)
    fn = functools.partial(
        make_env,
        env.env_id,
        n_envs,
        dict(env_kwargs),
        monitor_file=str(out / "eval" / "env"),
        held_out=True,
    )
    eval_env: Any = DummyVecEnv([fn])
    eval_env.seed(seed + EVAL_SEED_OFFSET)
    if agents:
        from gymprecice_lab.shared import shared_vec_env

        eval_env = shared_vec_env(eval_env, agents)
    slots = n_envs * max(1, len(agents))
    if normalize:
        # statistics are copied from the training env before each evaluation
        eval_env = VecNormalize(eval_env, training=False, norm_reward=False)
    callback = EvalCallback(
        eval_env,
        callback_on_new_best=_SaveBest(out, normalize),
        n_eval_episodes=n_eval_episodes * max(1, len(agents)),
        eval_freq=max(1, eval_freq // slots),
        log_path=str(out / "eval"),
        best_model_save_path=str(out),
        deterministic=True,
        verbose=0,
    )
    try:
        previous = json.loads((out / "eval" / "best.json").read_text())
        callback.best_mean_reward = float(previous["mean_return"])
    except (OSError, ValueError, KeyError):
        pass
    _keep_evaluations(callback, out / "eval" / "evaluations.npz")
    return callback


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
