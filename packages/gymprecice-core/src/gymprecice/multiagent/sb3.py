"""Parameter sharing in Stable-Baselines3: every agent of every env is one vector slot.

Importing this module imports Stable-Baselines3, which gymprecice does not depend on.
:class:`SharedPolicyVecEnv` wraps any SB3 ``VecEnv`` of :class:`~gymprecice.multiagent.JointEnv`
(normally :class:`~gymprecice.sb3.ResilientSubprocVecEnv`, which brings deadlines, respawn
and the failure budget) and shows ``n_envs * n_agents`` slots, each one agent's
observation, action, reward and end. One policy trained on it is shared by all agents::

    from functools import partial
    from stable_baselines3 import PPO
    from gymprecice.multiagent import JointEnv
    from gymprecice.multiagent.sb3 import SharedPolicyVecEnv
    from gymprecice.learners.sb3 import ResilientSubprocVecEnv

    def make(i):
        return JointEnv(TwoJets("case", idx=i))

    envs = ResilientSubprocVecEnv([partial(make, i) for i in range(4)])
    venv = SharedPolicyVecEnv(envs)
    PPO("MlpPolicy", venv).learn(100_000)

Why not SuperSuit (checked with SuperSuit 3.11): its ``pettingzoo_env_to_vec_env_v1`` works with
Gymnasium 1.x, but ``concat_vec_envs_v1`` makes its copies by pickling one built env, which a
gymprecice env refuses (it owns running processes, a lock on its env index and a run
directory, which copies would share), and its worker processes have no deadline, respawn
or failure budget: one hung solver would stop training.

A failed env (killed, hung, raising) ends the episode of all its agents' slots with
``done=True``, ``TimeLimit.truncated=True``, reward 0 and the failure in ``info["failure"]``,
as the pool reports it for one agent.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.tools.optional import optional_import_error

try:
    from stable_baselines3.common.vec_env.base_vec_env import (
        VecEnv,
        VecEnvIndices,
        VecEnvObs,
        VecEnvStepReturn,
    )
except ModuleNotFoundError as exc:  # say which extra brings it: gymprecice-core[sb3]
    raise optional_import_error(exc, __name__) from None

__all__ = ["SharedPolicyVecEnv"]

#: per-agent arrays of a JointEnv's info, split over the agents' slots
_PER_AGENT = ("agent_rewards", "agent_terminated", "agent_truncated", "terminal_observation")


class SharedPolicyVecEnv(VecEnv):
    """``venv`` (a ``VecEnv`` of :class:`~gymprecice.multiagent.JointEnv`) with one slot per agent.

    Slot ``k`` is agent ``k % n_agents`` of env ``k // n_agents``.
    """

    def __init__(self, venv: VecEnv) -> None:
        obs_space, act_space = venv.observation_space, venv.action_space
        if not (isinstance(obs_space, gym.spaces.Box) and isinstance(act_space, gym.spaces.Box)):
            raise TypeError(
                "SharedPolicyVecEnv wraps a VecEnv of gymprecice.multiagent.JointEnv (stacked "
                f"Box spaces); got observation space {obs_space} and action space {act_space}"
            )
        self.venv = venv
        self.n_agents = int(obs_space.shape[0])
        super().__init__(venv.num_envs * self.n_agents, _row(obs_space), _row(act_space))

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        self.reset_infos = [
            dict(info) for info in self.venv.reset_infos for _ in range(self.n_agents)
        ]
        return self._slots(obs)

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        self.venv.step_async(actions.reshape(self.venv.num_envs, self.n_agents, *actions.shape[1:]))

    def step_wait(self) -> VecEnvStepReturn:
        obs, _, dones, infos = self.venv.step_wait()
        n = self.n_agents
        rewards = np.zeros((self.venv.num_envs, n), dtype=np.float32)
        slot_infos: list[dict[str, Any]] = []
        for i, info in enumerate(infos):
            if "agent_rewards" in info:  # absent after a failure: the pool gives reward 0
                rewards[i] = info["agent_rewards"]
            shared = {k: v for k, v in info.items() if k not in _PER_AGENT}
            terminated = info.get("agent_terminated")
            for j in range(n):
                slot = dict(shared)
                if "terminal_observation" in info:
                    slot["terminal_observation"] = info["terminal_observation"][j]
                if "TimeLimit.truncated" in info:
                    ended_by_task = terminated is not None and bool(terminated[j])
                    slot["TimeLimit.truncated"] = (
                        bool(info["TimeLimit.truncated"]) and not ended_by_task
                    )
                slot_infos.append(slot)
            if dones[i]:
                reset_info = self.venv.reset_infos[i] if self.venv.reset_infos else {}
                for j in range(n):
                    self.reset_infos[i * n + j] = dict(reset_info)
        return self._slots(obs), rewards.reshape(-1), np.repeat(dones, n), slot_infos

    @property
    def unwrapped(self) -> VecEnv:
        """The vector env of joint envs beneath the slots (its ``envs`` are the joint envs),
        as a ``VecEnvWrapper``'s ``unwrapped`` is the vector env it wraps."""
        return self.venv.unwrapped

    def close(self) -> None:
        self.venv.close()

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        return self.venv.seed(seed)

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        self.venv.set_options(options)

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self._per_slot(indices, lambda envs: self.venv.get_attr(attr_name, envs))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self.venv.set_attr(attr_name, value, self._envs(indices))

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        return self._per_slot(
            indices,
            lambda envs: self.venv.env_method(method_name, *method_args, indices=envs, **kwargs),
        )

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return self._per_slot(indices, lambda envs: self.venv.env_is_wrapped(wrapper_class, envs))

    # -- internals -------------------------------------------------------------------------
    def _slots(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs)
        return obs.reshape(self.num_envs, *obs.shape[2:])

    def _envs(self, indices: VecEnvIndices) -> list[int]:
        return sorted({k // self.n_agents for k in self._get_indices(indices)})

    def _per_slot(self, indices: VecEnvIndices, ask: Any) -> list[Any]:
        slots: Iterable[int] = list(self._get_indices(indices))
        envs = sorted({k // self.n_agents for k in slots})
        answers = dict(zip(envs, ask(envs), strict=True))
        return [answers[k // self.n_agents] for k in slots]


def _row(space: gym.spaces.Box) -> gym.spaces.Box:
    return gym.spaces.Box(space.low[0], space.high[0], dtype=space.dtype)
