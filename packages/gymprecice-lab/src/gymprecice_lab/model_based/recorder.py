"""Every CFD transition of a training run, raw, for the environment models to learn from.

The recorder wraps the vector env *below* ``VecNormalize``: it sees the observations and
rewards the solvers produced and the (clipped) actions the envs received, not the running
normalisation of the moment, which drifts while the run learns. Transitions are kept per
episode so that a model reading a history of steps never reads across a reset.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

__all__ = ["Segment", "TransitionRecorder"]


@dataclass
class Segment:
    """One episode's contiguous steps: ``obs`` has one more row than ``actions``."""

    obs: list[np.ndarray] = field(default_factory=list)
    actions: list[np.ndarray] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.actions)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(obs [T+1, d], actions [T, a], rewards [T])``."""
        return (
            np.asarray(self.obs, dtype=np.float32),
            np.asarray(self.actions, dtype=np.float32).reshape(len(self.actions), -1),
            np.asarray(self.rewards, dtype=np.float32),
        )


class TransitionRecorder(VecEnvWrapper):
    """Keeps each env's transitions; :meth:`segments` hands them out, :meth:`save` keeps them.

    A step whose env failed (``info["failure"]``, from the resilient vector env) closes the
    episode without that step: its reward and final observation are not the flow's.
    """

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self._closed: list[Segment] = []
        self._open: list[Segment | None] = [None] * venv.num_envs
        self._actions: np.ndarray | None = None

    # -- the vector-env interface --------------------------------------------------------

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        for i in range(self.num_envs):
            self._close(i)
            self._open[i] = Segment(obs=[np.array(obs[i], dtype=np.float32)])  # type: ignore[index]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.array(actions, dtype=np.float32, copy=True)
        self.venv.step_async(actions)

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        assert self._actions is not None, "step_wait before step_async"
        for i in range(self.num_envs):
            segment = self._open[i]
            failed = bool(dones[i]) and infos[i].get("failure") is not None
            if segment is not None and not failed:
                following = infos[i]["terminal_observation"] if dones[i] else obs[i]  # type: ignore[index]
                segment.actions.append(self._actions[i])
                segment.rewards.append(float(rewards[i]))
                segment.obs.append(np.array(following, dtype=np.float32))
            if dones[i]:
                self._close(i)
                self._open[i] = Segment(obs=[np.array(obs[i], dtype=np.float32)])  # type: ignore[index]
        return obs, rewards, dones, infos

    # -- the data ------------------------------------------------------------------------

    @property
    def transitions(self) -> int:
        """Transitions kept so far, finished episodes and those under way."""
        return sum(len(s) for s in self.segments())

    def segments(self) -> list[Segment]:
        """Every episode with at least one transition, the ones under way included."""
        return [s for s in [*self._closed, *self._open] if s is not None and len(s)]

    def save(self, path: Path) -> None:
        """Write every transition to ``path`` (``.npz``), atomically."""
        segments = self.segments()
        if not segments:
            return
        parts = [s.arrays() for s in segments]
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(path.name + ".partial")
        with partial.open("wb") as handle:
            np.savez(
                handle,
                obs=np.concatenate([p[0] for p in parts]),
                actions=np.concatenate([p[1] for p in parts]),
                rewards=np.concatenate([p[2] for p in parts]),
                lengths=np.array([len(s) for s in segments], dtype=np.int64),
            )
        partial.replace(path)

    def load(self, path: Path) -> int:
        """Take back the transitions of an earlier segment of the run; how many."""
        if not path.is_file():
            return 0
        with np.load(path) as data:
            obs, actions, rewards = data["obs"], data["actions"], data["rewards"]
            lengths = [int(n) for n in data["lengths"]]
        o = a = 0
        for n in lengths:
            self._closed.append(
                Segment(
                    obs=list(obs[o : o + n + 1]),
                    actions=list(actions[a : a + n]),
                    rewards=[float(r) for r in rewards[a : a + n]],
                )
            )
            o += n + 1
            a += n
        return a

    def _close(self, i: int) -> None:
        segment = self._open[i]
        if segment is not None and len(segment):
            self._closed.append(segment)
        self._open[i] = None
