"""The Gymnasium facade: a 1.x ``VectorEnv`` on an :class:`~gymprecice.vector.EnvPool`."""

from __future__ import annotations

import copy as _copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array, iterate

from gymprecice.vector.failures import EnvFailure
from gymprecice.vector.pool import EnvPool
from gymprecice.vector.telemetry import Telemetry

__all__ = ["ResilientVectorEnv"]


class ResilientVectorEnv(VectorEnv):
    """A Gymnasium 1.x ``VectorEnv`` on an :class:`EnvPool`; autoreset mode SAME_STEP.

    Follows :class:`gymnasium.vector.AsyncVectorEnv`'s conventions: ``reset(seed=s)`` seeds
    env ``i`` with ``s + i`` (a list gives one seed per env); ``options`` (one dict for all
    envs, or a list with one per env) reach every env's ``reset``, and
    ``options["reset_mask"]`` (a bool array) resets only some envs. Infos are batched
    with ``_key`` masks; when env ``i``'s episode ended in a step, ``infos["final_obs"][i]``
    and ``infos["final_info"]`` hold the ended episode's last observation and info, and
    the returned observation is the new episode's first. An episode cut short by an env
    failure has ``truncations[i] = True``, reward 0, and ``infos["failure"]`` (also in
    ``final_info``) describing it (:meth:`EnvFailure.to_info`). Options persist for the
    automatic resets of each env until the next explicit :meth:`reset`.

    Keyword arguments are those of :class:`EnvPool` (timeouts, failure budget, start
    method, log directory, ``backend="ray"`` for envs on a Ray cluster). ``telemetry`` (:class:`gymprecice.telemetry.Telemetry`)
    holds the timings; ``telemetry.summary()`` reports them.
    """

    def __init__(
        self, env_fns: Sequence[Callable[[], gym.Env]], *, copy: bool = True, **pool_kwargs: Any
    ) -> None:
        self.pool = EnvPool(env_fns, **pool_kwargs)
        self.copy = copy
        self.num_envs = self.pool.num_envs
        self.single_observation_space = self.pool.observation_space
        self.single_action_space = self.pool.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = dict(self.pool.metadata)
        # as Gymnasium's own vector envs: in the metadata and as an attribute (TorchRL's
        # GymWrapper reads the attribute to handle the same-step autoreset)
        self.autoreset_mode = AutoresetMode.SAME_STEP
        self.metadata["autoreset_mode"] = self.autoreset_mode
        self.render_mode = self.pool.render_mode
        self._observations = create_empty_array(self.single_observation_space, self.num_envs)

    @property
    def telemetry(self) -> Telemetry:
        return self.pool.telemetry

    @property
    def failures(self) -> list[EnvFailure]:
        return self.pool.failures

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        seeds = _per_env_seeds(seed, self.num_envs)
        per_env, mask = _per_env_options(options, self.num_envs)
        indices = [i for i in range(self.num_envs) if mask is None or mask[i]]
        results = self.pool.reset(seeds, per_env, indices)
        items, infos = [], {}
        for i in range(self.num_envs):
            if i in results:
                obs, info = results[i]
                infos = self._add_info(infos, info, i)
            else:
                obs = self.pool._slots[i].last_obs
            items.append(obs)
        self._observations = concatenate(self.single_observation_space, items, self._observations)
        return self._output(self._observations), infos

    def step_async(self, actions: Any) -> None:
        self.pool.step_async(list(iterate(self.action_space, actions)))

    def step_wait(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        results = self.pool.step_wait()
        infos: dict[str, Any] = {}
        for i, result in enumerate(results):
            info = dict(result.info)
            if result.done:
                info["final_obs"] = result.final_obs
                info["final_info"] = result.final_info or {}
            infos = self._add_info(infos, info, i)
        self._observations = concatenate(
            self.single_observation_space, [r.obs for r in results], self._observations
        )
        return (
            self._output(self._observations),
            np.array([r.reward for r in results], dtype=np.float64),
            np.array([r.terminated for r in results], dtype=np.bool_),
            np.array([r.truncated for r in results], dtype=np.bool_),
            infos,
        )

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        self.step_async(actions)
        return self.step_wait()

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call method ``name`` (or read attribute ``name``) of every env."""
        return tuple(self.pool.call("call", (name, args, kwargs)))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        return tuple(self.pool.call("get", name))

    def set_attr(self, name: str, values: Any) -> None:
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(
                f"values must be one value or {self.num_envs} (one per env), got {len(values)}"
            )
        for i, value in enumerate(values):
            self.pool.call("set", (name, value), [i])

    def render(self) -> tuple[Any, ...] | None:
        return self.call("render")

    def close_extras(self, **kwargs: Any) -> None:
        pool = self.__dict__.get("pool")
        if pool is not None:
            pool.close(**kwargs)

    def _output(self, observations: Any) -> Any:
        return _copy.deepcopy(observations) if self.copy else observations


def _per_env_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)):
        return [int(seed) + i for i in range(n)]
    seeds = list(seed)
    if len(seeds) != n:
        raise ValueError(f"expected one seed or {n} seeds, got {len(seeds)}")
    return seeds


def _per_env_options(
    options: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None, n: int
) -> tuple[list[dict[str, Any] | None], np.ndarray | None]:
    """Split Gymnasium's reset options into one dict per env, and the reset mask."""
    if options is None:
        return [None] * n, None
    if isinstance(options, Mapping):
        common = dict(options)
        mask = common.pop("reset_mask", None)
        if mask is not None:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(
                    f"options['reset_mask'] must be a bool array of shape ({n},) with at "
                    "least one True value"
                )
        return [dict(common) for _ in range(n)], mask
    per_env = [dict(o) if o is not None else None for o in options]
    if len(per_env) != n:
        raise ValueError(f"expected one options dict or {n} (one per env), got {len(per_env)}")
    return per_env, None
