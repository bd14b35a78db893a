"""The envs ``gymprecice train`` learns on: N constructors, one vector env, the case first.

The training loop (:mod:`gymprecice_lab.training.loop`) asks for them here:

* :func:`probe_case` builds one env before the N workers start, so the recipe's case is
  written once, its directory is known for the manifest, and a wrong ``--env-kwargs``
  is one line instead of N crashed workers;
* :func:`env_fns` gives each worker's constructor, with its monitor file;
* :func:`make_vec_env` puts them in the vector env ``--vec-env`` / ``--ray`` ask for (a
  crashed or hung solver in the resilient one costs one episode, not the run);
* :func:`telemetry_callbacks` adds gymprecice's telemetry where that env measures it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym

from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.common.wrapped_env import make_env, make_env_checked

__all__ = ["env_fns", "make_vec_env", "probe_case", "telemetry_callbacks"]


def probe_case(env: LabEnv, kwargs: Mapping[str, Any]) -> Path | None:
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


def env_fns(
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


def make_vec_env(
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
        from gymprecice.learners.sb3 import ResilientSubprocVecEnv
        from gymprecice.vector.ray import RayBackend

        backend = RayBackend(ray)
        return ResilientSubprocVecEnv(
            list(fns), reset_timeout=None, log_dir=str(log_dir), backend=backend
        )

    if kind == "dummy":
        return DummyVecEnv(list(fns))
    if kind in ("auto", "resilient"):
        try:
            from gymprecice.learners.sb3 import ResilientSubprocVecEnv
        except ImportError:
            if kind == "resilient":
                raise SystemExit(
                    "gymprecice: --vec-env resilient needs gymprecice.sb3, which this "
                    "installation of gymprecice-core does not have"
                ) from None
        else:
            return ResilientSubprocVecEnv(list(fns), reset_timeout=None, log_dir=str(log_dir))
    return SubprocVecEnv(list(fns))


def telemetry_callbacks(vec: Any) -> list[Any]:
    """gymprecice's telemetry callback (time in solvers vs env vs learner, failures) in
    TensorBoard, for the resilient vector env that measures it."""
    try:
        from gymprecice.learners.sb3 import ResilientSubprocVecEnv, TelemetryCallback
    except ImportError:
        return []
    return [TelemetryCallback()] if isinstance(vec, ResilientSubprocVecEnv) else []
