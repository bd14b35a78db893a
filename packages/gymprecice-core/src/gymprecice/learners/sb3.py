"""Stable-Baselines3 facades: a fault-tolerant ``SubprocVecEnv`` and a telemetry callback.

Importing this module imports Stable-Baselines3, which gymprecice-core does not depend on
unless installed with its ``sb3`` extra (``pip install 'gymprecice-core[sb3]'``); only users
who train with SB3 import it::

    from gymprecice.learners.sb3 import ResilientSubprocVecEnv, TelemetryCallback

    venv = ResilientSubprocVecEnv([partial(MyEnv, config, idx=i) for i in range(8)],
                                  step_timeout=600, reset_timeout=1200)
    model = PPO("MlpPolicy", venv)
    model.learn(1_000_000, callback=TelemetryCallback())

:class:`ResilientSubprocVecEnv` behaves like SB3's ``SubprocVecEnv`` (auto-reset in the
same step, ``infos[i]["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]``,
reset infos in ``reset_infos``, seeds from :meth:`seed` and options from
:meth:`set_options` applied at the next :meth:`reset`) on top of
:class:`gymprecice.vector.EnvPool`: a hung, crashed or raising env is killed with all its
processes, respawned and reset, and its episode ends with ``done=True``,
``TimeLimit.truncated=True`` (so PPO bootstraps from ``terminal_observation`` instead of
treating the failure as a terminal state) and the failure in ``infos[i]["failure"]``.

One deliberate difference: options set with :meth:`set_options` stay in force for the
automatic resets that follow the next :meth:`reset` (SB3 drops them after one reset), so
an evaluation split does not silently turn back into the training split.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gymprecice.tools.optional import optional_import_error

try:
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env.base_vec_env import (
        VecEnv,
        VecEnvIndices,
        VecEnvObs,
        VecEnvStepReturn,
    )
except ModuleNotFoundError as exc:  # say which extra brings it: gymprecice-core[sb3]
    raise optional_import_error(exc, "gymprecice.sb3") from None

from gymprecice.vector import EnvFailure, EnvPool
from gymprecice.vector.telemetry import Telemetry

__all__ = ["ResilientSubprocVecEnv", "TelemetryCallback"]


class ResilientSubprocVecEnv(VecEnv):
    """SB3 ``VecEnv`` on a fault-tolerant :class:`~gymprecice.vector.EnvPool`.

    ``start_method`` as in SB3 (``"forkserver"`` by default, ``"spawn"``); every other
    keyword argument goes to :class:`~gymprecice.vector.EnvPool` (``step_timeout``,
    ``reset_timeout``, ``max_failures_per_env``, ``failure_window``, ``log_dir``, ...),
    ``backend="ray"`` or a :class:`~gymprecice.vector.ray.RayBackend` included: then the
    envs are Ray actors on a cluster, with the same guarantees.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env]],
        start_method: str | None = None,
        **pool_kwargs: Any,
    ) -> None:
        self.pool = EnvPool(env_fns, start_method=start_method, **pool_kwargs)
        self.waiting = False
        self.closed = False
        super().__init__(len(env_fns), self.pool.observation_space, self.pool.action_space)

    @property
    def telemetry(self) -> Telemetry:
        return self.pool.telemetry

    @property
    def failures(self) -> list[EnvFailure]:
        return self.pool.failures

    def reset(self) -> VecEnvObs:
        options = [dict(o) if o else None for o in self._options]
        results = self.pool.reset(list(self._seeds), options)
        obs = [results[i][0] for i in range(self.num_envs)]
        self.reset_infos = [results[i][1] for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return _stack_obs(obs, self.observation_space)

    def step_async(self, actions: np.ndarray) -> None:
        self.pool.step_async([actions[i] for i in range(self.num_envs)])
        self.waiting = True

    def step_wait(self) -> VecEnvStepReturn:
        results = self.pool.step_wait()
        self.waiting = False
        infos: list[dict[str, Any]] = []
        for i, result in enumerate(results):
            if result.done:
                info = dict(result.final_info or {})
                info["terminal_observation"] = result.final_obs
                info["TimeLimit.truncated"] = result.truncated and not result.terminated
                if result.failure is not None:
                    info["failure"] = result.failure.to_info()
                self.reset_infos[i] = result.info
            else:
                info = dict(result.info)
                info["TimeLimit.truncated"] = False
            infos.append(info)
        obs = _stack_obs([r.obs for r in results], self.observation_space)
        rewards = np.array([r.reward for r in results], dtype=np.float32)
        dones = np.array([r.done for r in results], dtype=bool)
        return obs, rewards, dones, infos

    def close(self) -> None:
        if self.closed:
            return
        self.pool.close()
        self.closed = True

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self.pool.call("get", attr_name, list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self.pool.call("set", (attr_name, value), list(self._get_indices(indices)))

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        return self.pool.call(
            "method", (method_name, method_args, method_kwargs), list(self._get_indices(indices))
        )

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        # By name, not by class: sending SB3's class would make every worker import SB3
        # and PyTorch (seconds and hundreds of MB per env) just to answer this.
        name = (wrapper_class.__module__, wrapper_class.__qualname__)
        return self.pool.call("wrapped", name, list(self._get_indices(indices)))

    def has_attr(self, attr_name: str) -> bool:
        return all(self.pool.call("has", attr_name))

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.render_mode != "rgb_array":
            return [None] * self.num_envs
        return self.env_method("render")


def _stack_obs(obs: Sequence[Any], space: spaces.Space) -> VecEnvObs:
    if isinstance(space, spaces.Dict):
        return {key: np.stack([o[key] for o in obs]) for key in space.spaces}
    if isinstance(space, spaces.Tuple):
        return tuple(np.stack([o[i] for o in obs]) for i in range(len(space.spaces)))
    return np.stack(obs)


def _find_telemetry(env: Any) -> Telemetry | None:
    """Walk down VecEnv wrappers (VecNormalize, VecMonitor, ...) to the telemetry."""
    seen = 0
    while env is not None and seen < 32:
        telemetry = getattr(env, "__dict__", {}).get("pool")
        if telemetry is not None and hasattr(telemetry, "telemetry"):
            return telemetry.telemetry
        env = getattr(env, "venv", None)
        seen += 1
    return None


class TelemetryCallback(BaseCallback):
    """Log the vector env's timings to SB3's logger (and so TensorBoard) every rollout.

    At the end of each rollout the samples since the previous one are aggregated
    (mean, p50, p90, p99, max, count per series; failures; the share of time in solver,
    env, vector env and learner) and recorded under ``<prefix>/...``; SB3 writes them at
    its next log dump. At the end of training :meth:`Telemetry.summary` is printed when
    ``print_summary`` is true. Pass ``telemetry`` explicitly for a vector env that is
    not (a wrapper of) :class:`ResilientSubprocVecEnv`.
    """

    def __init__(
        self,
        prefix: str = "gymprecice",
        print_summary: bool = True,
        telemetry: Telemetry | None = None,
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        self.prefix = prefix
        self.print_summary = print_summary
        self._telemetry = telemetry

    @property
    def telemetry(self) -> Telemetry | None:
        if self._telemetry is None and self.training_env is not None:
            self._telemetry = _find_telemetry(self.training_env)
        return self._telemetry

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        telemetry = self.telemetry
        if telemetry is None:
            return
        for key, value in telemetry.drain().items():
            self.logger.record(f"{self.prefix}/{key}", value)

    def _on_training_end(self) -> None:
        telemetry = self.telemetry
        if telemetry is not None and self.print_summary:
            print(telemetry.summary(), flush=True)
