"""Fault-tolerant parallel environments: a pool that never hangs and never loses work.

Training on 8-60 CFD environments for days breaks with ordinary vector envs: a hung solver
blocks the learner forever (their pipes wait without a timeout), an exception that cannot
be pickled turns into an ``EOFError`` for every env, and one env dying takes the whole run
with it. :class:`EnvPool` is the safety net around the Adapter's own watchdog. One
contract, two backends, one room each:

* :mod:`~gymprecice.vector.pool`: the contract (deadlines per step and reset, respawn of
  a failed env with its episode truncated and the failure in ``info["failure"]``, a
  failure budget, telemetry), independent of where an env lives; its parts are
  :mod:`~gymprecice.vector.jobs` (what each operation does with its answers),
  :mod:`~gymprecice.vector.restarts` (failure handling and the restart policy),
  :mod:`~gymprecice.vector.driver` (a batch of jobs against their deadlines) and
  :mod:`~gymprecice.vector.slots` (the records they share);
* :mod:`~gymprecice.vector.local`: each env in a worker process of this machine
  (``forkserver`` by default), in its own process group;
* :mod:`~gymprecice.vector.ray`: each env in a Ray actor anywhere on a cluster
  (``backend="ray"``; needs ``gymprecice-core[ray]``, imported only when used);
* :mod:`~gymprecice.vector.contract`: what crosses between the pool and a backend (the
  ``Backend`` and ``Host`` protocols, the ``Reply`` of each request), read by both;
* :mod:`~gymprecice.vector.host`: the env side both backends share;
* :mod:`~gymprecice.vector.telemetry`: per-step solver, env and learner time, resets and
  failures, as the pool counts them;
* facades: :class:`ResilientVectorEnv` (Gymnasium 1.x ``VectorEnv``) here, and
  :class:`gymprecice.sb3.ResilientSubprocVecEnv` (Stable-Baselines3 ``VecEnv``).

Autoreset: **same step** (:attr:`gymnasium.vector.AutoresetMode.SAME_STEP`, which is also
what Stable-Baselines3 does). When an episode ends, the step that ended it returns the
first observation of the next episode; the last observation and info of the ended
episode are in ``info["final_obs"]`` and ``info["final_info"]``. The same step resets a
failed env, so the learner never sees a broken env and never waits an extra step for a
reset. Options given to ``reset(options=...)`` stay in force for the env's automatic
resets until the next explicit reset, so an evaluation split
(``reset(options={"split": "eval"})``) is not silently dropped after the first episode.

Env ``i`` writes its stdout and stderr to ``<log_dir>/env_<i>.log``; the learner's process
never blocks on anything but a wait with a deadline.
"""

from __future__ import annotations

from typing import Any

from gymprecice.vector.contract import Backend
from gymprecice.vector.failures import (
    DEFAULT_FATAL_ERRORS,
    EnvFailedError,
    EnvFailure,
    FailureBudgetExceededError,
    describe_exception,
)
from gymprecice.vector.gymnasium import ResilientVectorEnv
from gymprecice.vector.local import LocalBackend
from gymprecice.vector.pool import (
    DEFAULT_CALL_TIMEOUT,
    DEFAULT_CLOSE_TIMEOUT,
    DEFAULT_RESET_TIMEOUT,
    DEFAULT_STEP_TIMEOUT,
    EnvPool,
    StepResult,
)

__all__ = [
    "DEFAULT_CALL_TIMEOUT",
    "DEFAULT_CLOSE_TIMEOUT",
    "DEFAULT_FATAL_ERRORS",
    "DEFAULT_RESET_TIMEOUT",
    "DEFAULT_STEP_TIMEOUT",
    "Backend",
    "EnvFailedError",
    "EnvFailure",
    "EnvPool",
    "FailureBudgetExceededError",
    "LocalBackend",
    "RayBackend",
    "ResilientSubprocVecEnv",
    "ResilientVectorEnv",
    "StepResult",
    "describe_exception",
]

#: names imported on first use: they pull in Stable-Baselines3 or Ray
_LAZY = {
    "ResilientSubprocVecEnv": "gymprecice.learners.sb3",
    "RayBackend": "gymprecice.vector.ray",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
