"""RLlib's multi-agent API on a gymprecice multi-agent env, built in RLlib's own env runners.

RLlib's new API stack samples multi-agent envs in its ``MultiAgentEnvRunner`` actors, each
of which builds its envs from the creator registered under the env's name (a runner
calls it once per ``num_envs_per_env_runner``). :func:`register_multiagent_env` registers
a :class:`MultiAgentEnvCreator` for a :class:`~gymprecice.multiagent.MultiAgentAdapter`
subclass or factory: every env it builds claims its own index, so its own run directory,
as :class:`gymprecice.rllib.EnvCreator` does for one agent, and is shown to RLlib as a
:class:`RLlibMultiAgentEnv`. ``algo.stop()`` closes every runner's envs, and their solvers
end with them. One policy shared by every agent, or one policy per agent::

    from ray.rllib.algorithms.ppo import PPOConfig
    from gymprecice.multiagent.rllib import register_multiagent_env, shared_policy

    register_multiagent_env(TwoJets, name="two-jets", options="case", run_root=runs)
    config = (
        PPOConfig()
        .environment("two-jets")
        .env_runners(num_env_runners=4)
        .multi_agent(**shared_policy())  # or **policy_per_agent(TwoJets.agent_data)
    )
    algo = config.build_algo()
    algo.train()
    algo.stop()

Why not RLlib's ``ParallelPettingZooEnv``: it resets the env when it is built, which for
a gymprecice env starts the solvers of an episode that nobody samples (the spaces are known
without it), and it marks the env's end only when every agent that reported in the last
step ended *the same way*, so an agent whose own task ends in the step that reaches the
end time would leave the episode running with no agent to act.

How the end of an episode is reported: RLlib 2.60's ``MultiAgentEpisode`` counts an episode
in which every agent reports ``truncated`` as *terminated* as well, and its PPO then does
not bootstrap from the last state's value, which would make the end time a terminal
state. :class:`RLlibMultiAgentEnv` therefore reports the end time through
``truncateds["__all__"]`` alone; each agent's own flag stays out of the dict (RLlib
reads the ``__all__`` flag for every agent), so the agents' episodes end truncated, not
terminated. Terminations (an agent's own task, a diverging solver) are reported per agent.

Needs ``gymprecice-core[rllib,multiagent]``: ``ray[rllib]`` 2.60 pins ``gymnasium==1.2.2``,
which gymprecice supports.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

try:
    from ray.rllib.env.multi_agent_env import MultiAgentEnv
except ImportError as exc:  # ray without its rllib extra fails on one of its own imports
    raise ModuleNotFoundError(
        f"{__name__} needs RLlib ({exc}): pip install 'gymprecice-core[rllib]'",
        name=getattr(exc, "name", None) or "ray",
    ) from None

from gymprecice.tools.optional import optional_import_error

try:
    from pettingzoo import ParallelEnv
except ModuleNotFoundError as exc:  # say which extra brings it: gymprecice-core[multiagent]
    raise optional_import_error(exc, __name__) from None

from gymprecice.learners.rllib import EnvCreator

__all__ = [
    "MultiAgentEnvCreator",
    "RLlibMultiAgentEnv",
    "policy_per_agent",
    "register_multiagent_env",
    "shared_policy",
]


class RLlibMultiAgentEnv(MultiAgentEnv):
    """A PettingZoo ``ParallelEnv`` (a :class:`~gymprecice.multiagent.MultiAgentAdapter`)
    as RLlib's ``MultiAgentEnv``; the env's end is reported as the module docstring says.

    The agents and their spaces are read when it is built, without a reset: a
    :class:`~gymprecice.multiagent.MultiAgentAdapter` knows them after ``__init__``. It
    owns ``env``: :meth:`close` closes it.
    """

    def __init__(self, env: ParallelEnv) -> None:
        super().__init__()
        if not isinstance(env, ParallelEnv):
            close = getattr(env, "close", None)
            if callable(close):  # it may own solvers already: leave nothing running
                close()
            raise TypeError(
                f"RLlibMultiAgentEnv wraps a PettingZoo ParallelEnv (a gymprecice "
                f"MultiAgentAdapter), got {type(env).__name__}; register a single-agent "
                "env (a gymnasium.Env, a JointEnv) with gymprecice.rllib.register_env"
            )
        agents = list(env.possible_agents)
        if not agents:
            env.close()
            raise ValueError(
                f"{type(env).__name__}.possible_agents is empty after __init__; RLlib needs "
                "the agents and their spaces before the first reset (a MultiAgentAdapter "
                "subclass sets agent_data and its spaces in __init__)"
            )
        self.env = env
        self.possible_agents = agents
        self.agents = list(agents)
        self.observation_spaces = {agent: env.observation_space(agent) for agent in agents}
        self.action_spaces = {agent: env.action_space(agent) for agent in agents}
        self.metadata = dict(getattr(env, "metadata", None) or {"render_modes": []})
        self.render_mode = getattr(env, "render_mode", None)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return obs, infos or {}

    def step(
        self, action_dict: Mapping[str, Any]
    ) -> tuple[dict[str, Any], dict[str, Any], dict[str, bool], dict[str, bool], dict[str, Any]]:
        obs, rewards, terminated, truncated, infos = self.env.step(action_dict)
        self.agents = list(self.env.agents)
        ended = not self.agents
        terminateds = {agent: bool(flag) for agent, flag in terminated.items()}
        # every agent of the step terminated: the env terminated; else its end is a
        # truncation of the agents still in it (the end time), said once, by "__all__"
        terminateds["__all__"] = ended and all(terminateds.values())
        truncateds = {
            agent: bool(flag)
            for agent, flag in truncated.items()
            if not (ended and flag)  # RLlib would count every agent's flag as terminated
        }
        truncateds["__all__"] = ended and not terminateds["__all__"]
        return obs, rewards, terminateds, truncateds, infos

    def render(self) -> Any:
        return self.env.render()

    def close(self) -> None:
        """Close the env: every process of its episode ends."""
        self.env.close()

    def __repr__(self) -> str:
        return f"RLlibMultiAgentEnv({self.env!r})"


class MultiAgentEnvCreator(EnvCreator):
    """An RLlib env creator for a gymprecice multi-agent env (see the module docstring).

    ``env`` is a :class:`~gymprecice.multiagent.MultiAgentAdapter` subclass or a callable
    taking ``idx`` and keyword arguments that returns one. ``kwargs`` are its settings; the
    ``env_config`` RLlib passes at creation overrides them. Each env is made with
    ``idx=None`` and claims a free index under its ``run_root``, as
    :class:`gymprecice.rllib.EnvCreator` explains; ``idx`` is refused as a setting.
    Picklable: RLlib ships it to its runners.
    """

    def __init__(self, env: Callable[..., ParallelEnv], /, **kwargs: Any) -> None:
        if isinstance(env, str) or not callable(env):
            raise TypeError(
                f"a multi-agent env is registered as a MultiAgentAdapter subclass or a "
                f"callable that makes one, got {env!r} (a Gymnasium id is a single-agent "
                "env: gymprecice.rllib.register_env)"
            )
        super().__init__(env, **kwargs)

    def __call__(self, config: Mapping[str, Any] | None = None) -> RLlibMultiAgentEnv:
        settings = self.settings(config)
        return RLlibMultiAgentEnv(self.env(idx=None, **settings))

    def __repr__(self) -> str:
        return f"MultiAgentEnvCreator({self.env!r}, **{self.kwargs!r})"


def register_multiagent_env(env: Callable[..., ParallelEnv], /, name: str, **kwargs: Any) -> str:
    """Register the multi-agent ``env`` with Ray Tune's registry as ``name``; return ``name``.

    ``PPOConfig().environment(name)`` then builds it in every env runner through a
    :class:`MultiAgentEnvCreator`; ``kwargs`` go to every env (``env_config`` entries
    override them).
    """
    from ray.tune.registry import register_env as tune_register_env

    if not isinstance(name, str) or not name:
        raise TypeError(f"register_multiagent_env needs a name to register it under, got {name!r}")
    tune_register_env(name, MultiAgentEnvCreator(env, **kwargs))
    return name


class _SharedPolicy:
    """The policy mapping that sends every agent to one policy: a class, so that it pickles
    by reference to this module and prints the policy it maps to."""

    def __init__(self, policy_id: str) -> None:
        self.policy_id = policy_id

    def __call__(self, agent_id: Any, episode: Any = None, **kwargs: Any) -> str:
        return self.policy_id

    def __repr__(self) -> str:
        return f"_SharedPolicy({self.policy_id!r})"


def _own_policy(agent_id: Any, episode: Any = None, **kwargs: Any) -> str:
    """The policy mapping that sends each agent to the policy named after it."""
    return str(agent_id)


def shared_policy(policy_id: str = "shared") -> dict[str, Any]:
    """``config.multi_agent(**shared_policy())``: one policy that every agent maps to.

    Parameter sharing: the policy (one RLModule, ``policy_id``) learns from every agent's
    steps and acts for each agent from its own observation. The agents need one observation
    space and one action space.
    """
    return {"policies": {policy_id}, "policy_mapping_fn": _SharedPolicy(policy_id)}


def policy_per_agent(agents: Iterable[str]) -> dict[str, Any]:
    """``config.multi_agent(**policy_per_agent(MyEnv.agent_data))``: a policy per agent.

    ``agents`` are the env's agent names (iterating the class's ``agent_data`` gives them);
    each policy is named after its agent and learns from that agent's steps alone.
    """
    names = [str(agent) for agent in agents]
    if not names:
        raise ValueError("policy_per_agent needs the env's agents, got none")
    return {"policies": set(names), "policy_mapping_fn": _own_policy}
