"""A vector env whose steps are the ensemble's predictions instead of the CFD's.

Env ``i`` follows member ``i mod members`` of the ensemble (``trajectories`` envs per
member). Each episode starts from a stretch of a
recorded CFD episode (the last ``history`` observations and the actions between them), so
predicted trajectories begin in flows the solvers produced, and lasts ``horizon`` steps; its
end is a truncation (``TimeLimit.truncated``), as the CFD episode's is, so PPO bootstraps it.
Predictions are kept within the recorded range widened by ``margin`` of its span on each
side: a member that drifts cannot feed the policy flows far outside what the data holds.
:meth:`ModelVecEnv.use` draws each env's start once: every :meth:`~ModelVecEnv.reset`
until the next ``use`` begins there again, so successive rollouts compare policies, not
starts.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvStepReturn

from gymprecice_lab.model_based.ensemble import EnvironmentEnsemble
from gymprecice_lab.model_based.recorder import Segment

__all__ = ["ModelVecEnv"]


class ModelVecEnv(VecEnv):
    """``trajectories`` envs per ensemble member, each stepping its member's predictions."""

    def __init__(
        self,
        ensemble: EnvironmentEnsemble,
        observation_space: spaces.Box,
        action_space: spaces.Box,
        horizon: int,
        seed: int,
        trajectories: int = 1,
        margin: float = 0.1,
    ) -> None:
        self.ensemble = ensemble
        self.horizon = horizon
        self.margin = margin
        self._rng = np.random.default_rng(seed)
        self._members = np.tile(np.arange(ensemble.members), trajectories)
        self._starts: list[tuple[np.ndarray, np.ndarray]] = []
        self._drawn: np.ndarray = np.zeros(len(self._members), np.int64)
        self._bounds = (np.full(1, -np.inf), np.full(1, np.inf))
        self._reward_bounds = (-np.inf, np.inf)
        n, h = len(self._members), ensemble.settings.history
        self._obs = np.zeros((n, h, ensemble.obs_dim), np.float32)
        self._act = np.zeros((n, h, ensemble.act_dim), np.float32)
        self._t = np.zeros(n, np.int64)
        self._pending: np.ndarray | None = None
        super().__init__(n, observation_space, action_space)

    def use(self, segments: Sequence[Segment]) -> None:
        """Take the recorded episodes to start from, and the range to keep predictions in."""
        h = self.ensemble.settings.history
        self._starts = []
        lows, highs, rewards = [], [], []
        for segment in segments:
            obs, actions, reward = segment.arrays()
            lows.append(obs.min(0))
            highs.append(obs.max(0))
            rewards.append(reward)
            # a start at step t needs observations t-h+1..t and the h-1 actions before t
            for t in range(h - 1, len(obs)):
                self._starts.append((obs[t - h + 1 : t + 1], actions[t - h + 1 : t]))
        if not self._starts:
            raise ValueError(f"no recorded episode has the {h} steps a start needs")
        low, high = np.min(lows, 0), np.max(highs, 0)
        span = high - low
        self._bounds = (low - self.margin * span, high + self.margin * span)
        self._drawn = self._rng.integers(len(self._starts), size=self.num_envs)
        reward = np.concatenate(rewards)
        r_span = float(reward.max() - reward.min())
        self._reward_bounds = (
            float(reward.min()) - self.margin * r_span,
            float(reward.max()) + self.margin * r_span,
        )

    # -- the vector-env interface --------------------------------------------------------

    def reset(self) -> np.ndarray:
        """Every env back to the start :meth:`use` drew for it."""
        for i in range(self.num_envs):
            self._start(i, int(self._drawn[i]))
        return self._obs[:, -1, :].copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._pending = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)

    def step_wait(self) -> VecEnvStepReturn:
        assert self._pending is not None, "step_wait before step_async"
        self._act[:, -1, :] = self._pending
        next_obs, rewards = self.ensemble.predict(self._members, self._obs, self._act)
        next_obs = np.clip(next_obs, *self._bounds).astype(np.float32)
        rewards = np.clip(rewards, *self._reward_bounds).astype(np.float32)
        self._obs = np.roll(self._obs, -1, axis=1)
        self._obs[:, -1, :] = next_obs
        self._act = np.roll(self._act, -1, axis=1)
        self._t += 1
        dones = self._t >= self.horizon
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": False} for _ in range(self.num_envs)]
        obs = next_obs.copy()
        for i in np.flatnonzero(dones):
            infos[i] = {"TimeLimit.truncated": True, "terminal_observation": next_obs[i].copy()}
            self._start(i)
            obs[i] = self._obs[i, -1, :]
        self._pending = None
        return obs, rewards, dones, infos

    def _start(self, i: int, index: int | None = None) -> None:
        """Env ``i`` from recorded start ``index`` (``None``: one drawn at random)."""
        if not self._starts:
            raise RuntimeError("ModelVecEnv.use(segments) must come before reset()")
        if index is None:
            index = int(self._rng.integers(len(self._starts)))
        obs, actions = self._starts[index]
        self._obs[i] = obs
        self._act[i, :-1, :] = actions
        self._act[i, -1, :] = 0.0
        self._t[i] = 0

    def close(self) -> None:
        pass

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        if attr_name == "render_mode":
            return [None] * len(self._indices(indices))
        raise AttributeError(f"ModelVecEnv has no attribute {attr_name!r}")

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise AttributeError(f"ModelVecEnv has no attribute {attr_name!r} to set")

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **kwargs: Any
    ) -> list[Any]:
        raise AttributeError(f"ModelVecEnv has no method {method_name!r}")

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)
