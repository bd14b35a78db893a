"""Gradient steps that run while the solvers compute: the ``overlap_updates`` key.

SB3's SAC and TD3 alternate: the envs step (the solvers compute, the learner waits), then
the learner takes its gradient steps (the solvers wait). On the fast cylinders those
gradient steps are about a quarter of the wall-clock. With ``overlap_updates: true`` in a
SAC or TD3 hyperparameter file, the gradient steps SB3 asks for after one env step run
during the next one: its actions are sent to the envs first, and the update runs while
the solvers compute them.

The price is one env step of lag: the action sent at step ``t`` comes from the policy as it
was before the update asked for at step ``t - 1`` (the update itself sees the same replay
buffer as SB3's order would, less the one transition still being computed). Every update
SB3 asks for runs; the last one runs when ``learn`` ends. An update that raises raises from
the env step, as SB3's own would from ``train``.

What it pays depends on the cores: the update shares them with the solvers. On 2 cores
with two solvers it took 2 to 21 % off SAC's wall-clock with one learner thread
(``torch_threads: 1``), and with torch's default of a thread per core it slowed the solvers
by more than it saved (docs/benchmark.md, "The levers").
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

__all__ = ["OverlappedUpdates", "overlapping"]


class OverlappedUpdates(VecEnvWrapper):
    """A vector env that runs the update left with it after sending each step's actions."""

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self._pending: Callable[[], None] | None = None

    def defer(self, update: Callable[[], None]) -> None:
        """Run ``update`` during the next step (after the one pending, if any, ran)."""
        self.flush()
        self._pending = update

    def flush(self) -> None:
        """Run the pending update now (nothing when there is none)."""
        update, self._pending = self._pending, None
        if update is not None:
            update()

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(actions)
        self.flush()  # the envs compute the actions while the learner updates

    def step_wait(self) -> Any:
        return self.venv.step_wait()

    def reset(self) -> Any:
        return self.venv.reset()


class _Overlapping:
    """The mixin of :func:`overlapping`: ``train`` is deferred to the next env step."""

    _overlap: OverlappedUpdates | None = None

    def overlap_with(self, env: OverlappedUpdates) -> None:
        """Defer every update to ``env``'s next step (``env`` must be the model's env)."""
        self._overlap = env

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        update = functools.partial(super().train, gradient_steps, batch_size)  # type: ignore[misc]
        if self._overlap is None:
            update()
        else:
            self._overlap.defer(update)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_overlap"]  # type: ignore[misc]

    def learn(self, *args: Any, **kwargs: Any) -> Any:
        result = super().learn(*args, **kwargs)  # type: ignore[misc]
        if self._overlap is not None:
            self._overlap.flush()  # the update asked for after the last step
        return result


@functools.cache
def overlapping(cls: type) -> type:
    """``cls`` (SAC or TD3) with its updates deferred to the next env step once
    :meth:`~_Overlapping.overlap_with` names the env. Saved models are ``cls``'s."""
    return type(f"Overlapping{cls.__name__}", (_Overlapping, cls), {})
