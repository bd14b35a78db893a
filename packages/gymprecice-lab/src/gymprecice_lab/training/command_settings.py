"""``gymprecice train`` and ``gymprecice tune``: their options, typed, built once.

One frozen dataclass per command (why frozen dataclasses, and why one module per family:
:mod:`gymprecice_lab.common.command_settings`). ``train``'s is also what ``benchmark``
checks a seed's training flags with (the same parser, the same defaults); ``tune``'s
trials are ``train`` command lines written from it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

from gymprecice_lab.common.command_settings import EnvSettings, RunsOnEnv

__all__ = ["TrainSettings", "TuneSettings"]


@dataclass(frozen=True, kw_only=True)
class TrainSettings(EnvSettings):
    """``gymprecice train``: the environment family (:class:`EnvSettings`), then how it
    learns, then how the run is kept and shown."""

    # -- the learner: the algorithm, its hyperparameter file, its budget ------------------
    #: ``--algo``: ppo, sac, td3 or tqc
    algo: str
    #: ``--hyperparams FILE.yaml`` (RL Zoo style), copied into the run
    hyperparams: Path | None
    #: ``--n-envs``: parallel environments
    n_envs: int
    #: ``--timesteps``: total actions, rounded up to whole rollouts
    timesteps: int

    # -- hyperparameter flags: None (False) leaves the file's value, else the default ----
    n_steps: int | None
    batch_size: int | None
    n_epochs: int | None
    learning_rate: float | None
    gamma: float | None
    #: ``--net 64,64``, as typed (checked when the hyperparameters are resolved)
    net: str | None
    normalize: bool
    shared_policy: bool

    # -- keeping the run: checkpoints, validation, resume --------------------------------
    checkpoint_every: int | None
    keep_checkpoints: int
    eval_freq: int | None
    #: ``--stop-at SCORE``: stop at the first validation scoring at least this
    stop_at: float | None
    #: ``--validation-time SECONDS``: each validation episode's length (None: the default)
    validation_time: float | None
    n_eval_episodes: int | None
    no_validation: bool
    #: ``--fresh``: start over even where ``--out`` has checkpoints
    fresh: bool

    # -- where it runs and how it shows itself -------------------------------------------
    #: ``--vec-env``: auto, resilient, subproc or dummy
    vec_env: str
    #: ``--ray auto|ADDRESS`` (None: the envs run on this machine)
    ray: str | None
    no_progress_bar: bool
    verbose: int
    #: ``--device``: the torch device
    device: str


@dataclass(frozen=True, kw_only=True)
class TuneSettings(RunsOnEnv):
    """``gymprecice tune``: the env its trials train on, the search, the study's storage."""

    command: ClassVar[str] = "tune"

    # -- the env every trial trains on (passed on to each trial's ``train``) -------------
    #: ENV as typed
    env: str
    #: ``--out`` (None: ``runs/<env>/tune``)
    out: Path | None
    double: bool
    #: ``--seed``: the sampler's and every trial's
    seed: int
    episode_time: float | None
    env_kwargs: Mapping[str, Any]

    # -- the search ----------------------------------------------------------------------
    #: ``--algo``: ppo, sac, td3 or tqc
    algo: str
    #: ``--trials``: trials in the study
    trials: int
    #: ``--timesteps``: env steps per trial
    timesteps: int
    n_envs: int
    #: ``--validate-every``: steps between a trial's validations (its pruner reports)
    validate_every: int
    #: ``--params``: the parameters searched (None: the algorithm's whole space)
    params: tuple[str, ...] | None
    #: ``--hyperparams``: what every trial keeps
    hyperparams: Path | None

    # -- the study: where it is kept, how many trials at once ----------------------------
    #: ``--storage URL`` (None: SQLite in the output directory)
    storage: str | None
    #: ``--study-name`` (None: ``<env>-<algo>``)
    study_name: str | None
    n_jobs: int
    #: ``--ray auto|ADDRESS``: the ``--n-jobs`` workers run as Ray tasks there
    ray: str | None
    no_progress_bar: bool

    @cached_property
    def storage_url(self) -> str:
        """The study's storage: ``--storage``, else ``sqlite:///<out>/study.db``."""
        return self.storage or f"sqlite:///{self.run_dir / 'study.db'}"

    @cached_property
    def study(self) -> str:
        """The study's name: ``--study-name``, else ``<env>-<algo>``."""
        return self.study_name or f"{self.lab_env.name}-{self.algo}"
