"""The model ``gymprecice train`` learns with, and what it learns alongside.

:func:`build_model` makes the algorithm's model new or resumes it from a checkpoint (its
replay buffer and ``VecNormalize`` statistics too), under
:class:`~gymprecice_lab.training.overlap.OverlappedUpdates` when the hyperparameters overlap the
updates with the solvers; :func:`transition_recorder` and :func:`attach_ensemble` give
model-ensemble PPO (:mod:`gymprecice_lab.model_based`) the CFD transitions it learns its
models from; :func:`learner_threads` caps the learner's CPU threads, which it shares with
the solvers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice_lab.common.wrapped_env import vecnormalize_path
from gymprecice_lab.model_based.settings import (
    ENSEMBLE_KEY,
    TRANSITIONS_FILE,
    EnsembleSettings,
)
from gymprecice_lab.training import hyperparams as hp

__all__ = ["attach_ensemble", "build_model", "learner_threads", "transition_recorder"]


def build_model(
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


def _overlapped(vec: Any, params: Mapping[str, Any]) -> Any:
    """``vec`` under :class:`~gymprecice_lab.training.overlap.OverlappedUpdates` when the
    hyperparameters overlap the updates with the solvers, else ``vec`` itself."""
    if not params.get(hp.OVERLAP_KEY):
        return vec
    from gymprecice_lab.training.overlap import OverlappedUpdates

    return OverlappedUpdates(vec)


def transition_recorder(base: Any, params: Mapping[str, Any]) -> Any:
    """A recorder of the CFD transitions over ``base`` for model-ensemble PPO, else None."""
    if params.get(ENSEMBLE_KEY) is None:
        return None
    from gymprecice_lab.model_based.recorder import TransitionRecorder

    return TransitionRecorder(base)


def attach_ensemble(model: Any, recorder: Any, params: Mapping[str, Any], out: Path) -> None:
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


def learner_threads(params: Mapping[str, Any]) -> int:
    """Cap the learner's CPU threads at ``torch_threads`` when the hyperparameters set it;
    return how many it has. They share the cores with the solvers: fewer can be faster."""
    import torch

    if params.get(hp.THREADS_KEY):
        torch.set_num_threads(int(params[hp.THREADS_KEY]))
    return torch.get_num_threads()
