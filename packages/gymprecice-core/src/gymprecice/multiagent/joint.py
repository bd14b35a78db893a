"""All agents of a multi-agent env as one Gymnasium env, stacked along a first axis.

:class:`JointEnv` is what the fault-tolerant vector envs run: a ``gymnasium.Env``, so
:class:`~gymprecice.vector.ResilientVectorEnv` and
:class:`~gymprecice.sb3.ResilientSubprocVecEnv` host it with their deadlines, respawn and
failure budget unchanged. It serves two routes:

* parameter sharing: :class:`gymprecice.multiagent.sb3.SharedPolicyVecEnv` splits each
  joint env back into one vector slot per agent, so one SB3 policy acts for every agent;
* one controller that sees and drives every actuator: train on the joint env directly
  (its reward is the mean of the agents' rewards).

The agents must be alike: the same Box observation space and the same Box action space
(parameter sharing needs it, and a stacked array needs one shape). An agent that is done
before the episode ends (its own termination) gets zeros as observation and reward until
the episode ends, and its part of the action is ignored (its actuator holds its last
action), as PettingZoo's and SuperSuit's "black death" does.

Rendering is the multi-agent env's: a joint env has the ``render_mode`` its env was made
with, and ``render()`` returns that env's frame (every participant, every agent's
actuator), so Gymnasium's ``RecordVideo`` records it.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.multiagent.env import MultiAgentAdapter

__all__ = ["JointEnv"]


class JointEnv(gym.Env):
    """A :class:`~gymprecice.multiagent.MultiAgentAdapter` as one ``gymnasium.Env``.

    Observation and action: arrays of shape ``(n_agents, *agent_shape)`` in
    ``possible_agents`` order. Reward: the mean of the live agents' rewards (the
    divergence penalty stays the penalty). ``info`` holds ``agent_rewards``,
    ``agent_terminated`` and ``agent_truncated`` (arrays over the agents: what each agent
    got and how it ended) besides the engine's ``time``, ``timing`` and ``diverged``.
    The episode is terminated when every agent terminated, truncated when it ended
    otherwise (the end time, a divergence counts as termination for every agent).
    ``render_mode``, ``metadata`` (``render_fps``) and ``render()`` are ``env``'s.
    """

    #: what a subclass that builds its env from keywords (``render_mode`` among them)
    #: supports, for ``gymnasium.make``; an instance's metadata is its env's
    metadata: dict[str, Any] = dict(MultiAgentAdapter.metadata)

    def __init__(self, env: MultiAgentAdapter) -> None:
        super().__init__()
        self.env = env
        self.agents = list(env.possible_agents)
        obs = [env.observation_space(a) for a in self.agents]
        act = [env.action_space(a) for a in self.agents]
        for kind, spaces in (("observation", obs), ("action", act)):
            if not all(isinstance(s, gym.spaces.Box) for s in spaces) or any(
                s != spaces[0] for s in spaces
            ):
                raise ValueError(
                    f"JointEnv stacks alike agents: every agent of {type(env).__qualname__} "
                    f"needs the same Box {kind} space, got "
                    f"{dict(zip(self.agents, spaces, strict=True))}; pad or map them to one "
                    "space in the env"
                )
        self.observation_space = _stacked(obs[0], len(self.agents))
        self.action_space = _stacked(act[0], len(self.agents))
        self.metadata = dict(env.metadata)
        self.render_mode = env.render_mode
        self._zero_obs = np.zeros(obs[0].shape, dtype=obs[0].dtype)
        self._ended: dict[str, str] = {}

    @property
    def n_agents(self) -> int:
        return len(self.agents)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs, infos = self.env.reset(seed=seed, options=options)
        self._ended = {}
        info = dict(infos[self.agents[0]])
        return self._stack(obs), info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action = np.asarray(action)
        if action.shape != self.action_space.shape:
            raise ValueError(
                f"JointEnv: the action has shape {action.shape}; expected "
                f"{self.action_space.shape} (one row per agent, {self.agents})"
            )
        live = self.env.agents
        actions = {a: action[i] for i, a in enumerate(self.agents) if a in live}
        obs, rewards, terms, truncs, infos = self.env.step(actions)
        for agent in live:
            if terms[agent]:
                self._ended[agent] = "terminated"
            elif truncs[agent]:
                self._ended[agent] = "truncated"
        info = dict(infos[live[0]])
        info["agent_rewards"] = np.array([rewards.get(a, 0.0) for a in self.agents])
        info["agent_terminated"] = np.array(
            [self._ended.get(a) == "terminated" for a in self.agents]
        )
        info["agent_truncated"] = np.array([self._ended.get(a) == "truncated" for a in self.agents])
        over = not self.env.agents
        terminated = over and all(state == "terminated" for state in self._ended.values())
        reward = float(np.mean([rewards[a] for a in live]))
        return self._stack(obs), reward, terminated, over and not terminated, info

    @property
    def render_size(self) -> tuple[int, int]:
        """The multi-agent env's frame size ``(width, height)``."""
        return self.env.render_size

    def render(self) -> np.ndarray | None:
        """The multi-agent env's frame (``None`` with a warning without ``render_mode``)."""
        return self.env.render()

    def close(self) -> None:
        self.env.close()

    def _stack(self, obs: dict[str, Any]) -> np.ndarray:
        return np.stack([np.asarray(obs[a]) if a in obs else self._zero_obs for a in self.agents])


def _stacked(space: gym.spaces.Box, n: int) -> gym.spaces.Box:
    low = np.broadcast_to(space.low, space.shape)
    high = np.broadcast_to(space.high, space.shape)
    return gym.spaces.Box(np.stack([low] * n), np.stack([high] * n), dtype=space.dtype)
