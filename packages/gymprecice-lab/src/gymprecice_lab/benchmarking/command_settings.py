"""``gymprecice benchmark`` and ``gymprecice time-to-floor``: their options, typed, built
once.

One frozen dataclass per command (why frozen dataclasses, and why one module per family:
:mod:`gymprecice_lab.common.command_settings`). Not to be confused with
:mod:`gymprecice_lab.benchmarking.settings`, the part of these that decides a benchmark's
numbers, written to ``benchmark.json`` and locked across resumes.

The benchmark fills in its feedback baseline's defaults once it knows the env
(:func:`gymprecice_lab.benchmarking.checks.resolve_feedback`): a new settings object
(``dataclasses.replace``), not a changed one.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from gymprecice_lab.common.command_settings import RunsOnEnv

__all__ = ["BenchmarkSettings", "TimeToFloorSettings"]


@dataclass(frozen=True, kw_only=True)
class BenchmarkSettings(RunsOnEnv):
    """``gymprecice benchmark``: the env, the seeds' training, their evaluation, the
    classical baselines, the statistics, and where the pieces run."""

    command: ClassVar[str] = "benchmark"

    # -- the env (every piece: training, evaluations, baselines) -------------------------
    #: ENV as typed
    env: str
    #: ``--out`` (None: ``runs/<env>/benchmark``)
    out: Path | None
    double: bool
    require_solvers: bool
    env_kwargs: Mapping[str, Any]

    # -- the seeds' training -------------------------------------------------------------
    #: ``--seeds N``: seeds 0..N-1 per algorithm
    seeds: int
    #: ``--algo``: the algorithms, comma-separated, as typed
    algo: str
    #: ``--timesteps``: steps per seed
    timesteps: int
    n_envs: int
    #: ``--train-args [ALGO:]FLAGS``: more ``train`` flags, each as typed
    train_args: tuple[str, ...]
    #: ``--episode-time``: simulated seconds per training episode (None: the case's)
    episode_time: float | None
    #: ``--retries``: reruns of a seed whose training fails
    retries: int

    # -- the evaluations -----------------------------------------------------------------
    #: ``--eval-time``: simulated seconds per evaluation episode (None: the rollout horizon)
    eval_time: float | None

    # -- the classical baselines: the sweep's grid, comma-separated as typed ------------
    no_baselines: bool
    constants: int
    amplitudes: str
    frequencies: str
    centre: float
    #: ``--feedback-gains`` (None until :func:`resolve_feedback` fills in the default)
    feedback_gains: str | None
    feedback_delays: str
    feedback_signal: str | None
    #: ``--feedback-grid``: an env's own law's points (None: its documented grid)
    feedback_grid: str | None

    # -- the statistics, and where the pieces run ----------------------------------------
    bootstrap_reps: int
    #: ``--workers``: evaluations and baseline rollouts at once
    workers: int
    #: ``--fresh``: start over, deleting the benchmark's runs
    fresh: bool
    #: ``--ray auto|ADDRESS`` (None: everything runs here)
    ray: str | None


@dataclass(frozen=True, kw_only=True)
class TimeToFloorSettings:
    """``gymprecice time-to-floor``: the training runs, the floor's fractions, and how
    their models are evaluated."""

    # -- the runs and the env they trained on ---------------------------------------------
    #: RUN...: training directories
    runs: tuple[Path, ...]
    #: ``--env`` (None: the first run's, from its manifest)
    env: str | None
    #: ``--model``: kept, final or checkpoints
    model: str

    # -- what is measured ---------------------------------------------------------------
    #: ``--fractions``: fractions of the floor's drop, comma-separated as typed
    fractions: str
    #: ``--eval-time``: simulated seconds per evaluation episode
    eval_time: float

    # -- where and how the evaluations run ----------------------------------------------
    #: ``--out`` (None: ``<first RUN>/time-to-floor``)
    out: Path | None
    double: bool
    workers: int
