"""Train gymprecice environments with RLlib, each env built inside RLlib's own env runners.

RLlib builds its environments in its env runners (Ray actors), from an *env creator* it
calls with an :class:`~ray.rllib.env.env_context.EnvContext` (the ``env_config`` dict plus
``worker_index``, ``num_workers``, ...). A gymprecice env needs one thing more than a plain
Gymnasium env: its own index, which names its run directory ``<run_root>/env_<idx>``.
Two envs with one index would share a run directory, and the second would kill the
first's solvers when it replaces it. RLlib's context cannot give a unique index: its new
API stack builds every env of a runner (``num_envs_per_env_runner``) from the same
context (``vector_index`` is always 0), evaluation runners count ``worker_index`` from 1
like the training runners, and two trials on one node share the run root. So the creator
passes ``idx=None`` and each env *claims* the lowest index no live env holds under its
run root (a lock file, held until the env closes, across processes).

::

    from ray.rllib.algorithms.ppo import PPOConfig
    from gymprecice.learners.rllib import register_env

    register_env("gymprecice/JetCylinder-v0", run_root="/local/scratch/runs")
    config = (
        PPOConfig()
        .environment("gymprecice/JetCylinder-v0", env_config={"episode_time": 2.0})
        .env_runners(num_env_runners=8, num_envs_per_env_runner=2)
    )
    algo = config.build_algo()
    algo.train()
    algo.stop()  # closes every env: their solvers end with them

Keyword arguments given to :func:`register_env` (or :class:`EnvCreator`) go to every env;
``env_config`` entries override them. Actions need no rescaling: RLlib's
``normalize_actions`` (on by default) maps the policy's output onto the env's ``Box``
bounds, however small (the jets' flow rates are of order 1e-4 m³/s).

A multi-agent env (:class:`~gymprecice.multiagent.MultiAgentAdapter`) is registered for
RLlib's multi-agent API by :mod:`gymprecice.multiagent.rllib`, through the same creator.

Needs ``gymprecice-core[rllib]``; ``ray[rllib]`` 2.60 pins ``gymnasium==1.2.2``, which
gymprecice supports.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium

__all__ = ["RLLIB_KEYS", "EnvCreator", "register_env"]

#: keys RLlib adds to the env config on its own (``num_envs`` for vector entry points);
#: they are not the env's settings
RLLIB_KEYS = frozenset({"num_envs"})


class EnvCreator:
    """An RLlib env creator for one gymprecice env: a Gymnasium id or a callable.

    ``env`` is a registered id (``"gymprecice/Quickstart-v0"``; ``import gymprecice``
    registers the plugins' ids in the env runner) or a callable taking ``idx`` and keyword
    arguments (an :class:`~gymprecice.core.Adapter` subclass). ``kwargs`` are the env's
    settings; the ``env_config`` RLlib passes at creation overrides them. The env is made
    with ``idx=None`` so that it claims a free run directory (see the module docstring);
    ``idx`` is therefore refused as a setting. Picklable: RLlib ships it to its runners.
    """

    def __init__(self, env: str | Callable[..., gymnasium.Env], /, **kwargs: Any) -> None:
        if not (isinstance(env, str) or callable(env)):
            raise TypeError(f"env must be a Gymnasium id or a callable, got {env!r}")
        self.env = env
        self.kwargs = dict(kwargs)
        self._check(self.kwargs)

    def settings(self, config: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The env's keyword arguments: the creator's, overridden by ``config``'s."""
        given = {k: v for k, v in dict(config or {}).items() if k not in RLLIB_KEYS}
        self._check(given)
        return {**self.kwargs, **given}

    def __call__(self, config: Mapping[str, Any] | None = None) -> gymnasium.Env:
        settings = self.settings(config)
        if isinstance(self.env, str):
            import gymprecice  # noqa: F401  (registers the plugins' ids in this process)

            return gymnasium.make(self.env, idx=None, **settings)
        return self.env(idx=None, **settings)

    def __repr__(self) -> str:
        return f"EnvCreator({self.env!r}, **{self.kwargs!r})"

    @staticmethod
    def _check(settings: Mapping[str, Any]) -> None:
        if "idx" in settings:
            raise ValueError(
                "idx is not a setting of an env built by RLlib: every env runner would "
                "build its envs with the same index and share one run directory; each env "
                "claims a free index under its run_root instead"
            )


def register_env(
    env: str | Callable[..., gymnasium.Env], /, name: str | None = None, **kwargs: Any
) -> str:
    """Register ``env`` with Ray Tune's registry for RLlib; return the name to use.

    ``name`` defaults to ``env`` when it is a Gymnasium id, so that
    ``PPOConfig().environment("gymprecice/Quickstart-v0")`` builds it through the creator
    (RLlib looks a string up in Tune's registry before Gymnasium's); a callable needs a
    ``name``. ``kwargs`` go to every env (see :class:`EnvCreator`).
    """
    from ray.tune.registry import register_env as tune_register_env

    if name is None:
        if not isinstance(env, str):
            raise TypeError("register_env(callable) needs a name= to register it under")
        name = env
    tune_register_env(name, EnvCreator(env, **kwargs))
    return name
