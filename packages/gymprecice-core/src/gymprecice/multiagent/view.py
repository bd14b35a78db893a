"""What the episode runner sees of a multi-agent env: one env, whose action joins the agents'.

An :class:`~gymprecice.episode.EpisodeRunner` runs one env's episodes: it calls the env's
user methods (``_get_action``, ``_get_observation``, ``_get_reward``, ...) and keeps its
documented attributes (``time``, ``dt``, ``last_action``) up to date. A
:class:`~gymprecice.multiagent.MultiAgentAdapter` cannot be that env itself: it is a
PettingZoo env (its ``action_space`` is a method of the agent) and its user methods are
per agent. So it hands the runner a :class:`JointView`, which has what the runner reads
and nothing else: its user methods split the joint action per agent, ask the multi-agent
env's own methods (handed over explicitly, as :class:`AgentMethods`), check their answers
(:mod:`gymprecice.multiagent.answers`) and join them, keeping what the multi-agent env
reports per agent (:attr:`JointView.rewards`, :attr:`JointView.terminations`).

The multi-agent env owns its view, and the view its runner; the view holds the env only
weakly (its public attributes through a weak reference, its user methods as weak
methods), so dropping the env ends its episode at once, as dropping an Adapter does.
"""

from __future__ import annotations

import inspect
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding

from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.episode import EpisodeRunner
from gymprecice.env.values import DataDict, DataRef
from gymprecice.multiagent.answers import (
    AgentAction,
    agent_writes,
    check_observations,
    checked_rewards,
    ended,
)
from gymprecice.multiagent.layout import AgentLayout
from gymprecice.plugin.fields import Overlay
from gymprecice.plugin.solver import InterfaceGeometry, OutputReader

__all__ = ["AgentMethods", "JointView", "ViewedEnv", "weakly"]


class ViewedEnv(Protocol):
    """What a view reads of its multi-agent env: public attributes only."""

    agents: list[str]
    render_fields: Mapping[str, str | Sequence[str]]
    render_size: tuple[int, int | None]


def weakly(method: Callable[..., Any]) -> Callable[..., Any]:
    """``method`` (a bound method) without keeping its object alive.

    Calling it once the object is gone raises ``ReferenceError``. Anything but a bound
    method is returned as it is.
    """
    if not inspect.ismethod(method):
        return method
    ref = weakref.WeakMethod(method)
    name = method.__name__

    def call(*args: Any, **kwargs: Any) -> Any:
        bound = ref()
        if bound is None:
            raise ReferenceError(f"the multi-agent env of {name}() is gone")
        return bound(*args, **kwargs)

    return call


@dataclass
class AgentMethods:
    """The multi-agent env's user methods that its view asks (see :class:`JointView`).

    Taken when the env is built (:meth:`held_weakly`), each as the env's bound method.
    """

    agent_action: AgentAction
    observations: Callable[[DataDict, list[DataRef]], Any]
    rewards: Callable[[], Any]
    terminations: Callable[[], Mapping[str, bool]]
    initial_actions: Callable[[], Mapping[str, Any]]
    close_external_resources: Callable[[], None]
    render_overlay: Callable[[], Overlay | None]

    @classmethod
    def held_weakly(cls, **methods: Callable[..., Any]) -> AgentMethods:
        """The methods, none keeping the env alive (see :func:`weakly`)."""
        return cls(**{name: weakly(method) for name, method in methods.items()})


class JointView:
    """The env an :class:`~gymprecice.episode.EpisodeRunner` serves for a multi-agent env.

    ``env`` is the multi-agent env (held weakly), ``methods`` its user methods, ``config``
    its checked configuration; ``idx`` and ``run_root`` are the Adapter's arguments. The
    view makes the runner (:attr:`runner`), with the penalty of ``env``'s class.
    """

    def __init__(
        self,
        env: ViewedEnv,
        methods: AgentMethods,
        config: GymPreciceConfig,
        idx: int | None,
        run_root: str | Path | None,
        *,
        render_mode: str | None,
    ) -> None:
        self._env = weakref.ref(env)
        #: the env's user methods, which the user methods below ask
        self.methods = methods
        #: the env's class, which every message names
        self.who = type(env).__qualname__
        self.config = config
        self.render_mode = render_mode
        self._np_random: np.random.Generator | None = None
        #: the coupled run's machinery (``env._gymprecice``, as an Adapter's)
        self.runner = EpisodeRunner(self, idx, run_root, cls=type(env))
        self.env_index: int = self.runner.run.env_index
        self.time = 0.0
        self.time_window = 0
        self.dt: float | None = config.time_window_size
        self.end_time: float | None = config.end_time
        #: the last joint action the runner took (its schedule's start after reset)
        self.last_action: Any = None
        #: each agent's write data, resolved from ``agent_data`` (set once resolved)
        self.agent_refs: dict[str, tuple[DataRef, ...]] = {}
        #: this episode's agents in the joint action (set at each reset)
        self.layout: AgentLayout | None = None
        #: the joint action the episode started from, and the one the actuators hold
        self.start = np.zeros(0)
        self.held = np.zeros(0)
        #: the last step's rewards of the live agents, and the live agents its task ended
        self.rewards: dict[str, float] = {}
        self.terminations: set[str] = set()

    # -- what the runner reads -------------------------------------------------------------
    @property
    def action_space(self) -> gym.spaces.Box:
        """The joint action's Box (what the runner checks and clips an action against)."""
        return self._laid_out().action_space

    @property
    def np_random(self) -> np.random.Generator:
        """The env's random generator, made unseeded on first use as Gymnasium's is."""
        if self._np_random is None:
            self._np_random, _ = seeding.np_random()
        return self._np_random

    def seed(self, seed: int | None) -> None:
        """``reset(seed=...)``: a generator from ``seed``; ``None`` keeps the one there is."""
        if seed is not None:
            self._np_random, _ = seeding.np_random(seed)

    @property
    def render_fields(self) -> Mapping[str, str | Sequence[str]]:
        return self._owner().render_fields

    @property
    def render_size(self) -> tuple[int, int | None]:
        return self._owner().render_size

    # -- the Adapter's documented API, over the runner (as the Adapter has it) -------------
    @property
    def env_dir(self) -> Path:
        return self.runner.run.env_dir

    @property
    def run_dir(self) -> Path:
        return self.runner.run.prepare().root

    @property
    def solver_dirs(self) -> dict[str, Path]:
        run = self.runner.run
        run.prepare()
        return {name: ctx.run_dir for name, ctx in run.solvers.items()}

    @property
    def write_var_list(self) -> list[DataRef]:
        return list(self.runner.write_refs)

    @property
    def read_var_list(self) -> list[DataRef]:
        return list(self.runner.read_refs)

    @property
    def interface_geometry(self) -> dict[str, InterfaceGeometry]:
        return self.runner.vertices.known()

    def set_interface_vertices(self, interface: str, coordinates: Any) -> None:
        self.runner.vertices.set(interface, coordinates)

    def open_output(self, solver: str, name: str, options: dict[str, Any]) -> OutputReader:
        return self.runner.run.open_output(solver, name, options)

    def joint(self, actions: Any, live: list[str]) -> np.ndarray:
        """The step's action dict as one vector (see :meth:`AgentLayout.joint`)."""
        return self._laid_out().joint(actions, live, self.held)

    def last_actions(self) -> dict[str, np.ndarray]:
        """The action each agent's actuator holds (``{}`` before the first reset)."""
        return {} if self.layout is None else self.layout.split(self.held)

    # -- the user methods the runner calls, answered agent by agent ------------------------
    def _get_action(self, action: Any, write_var_list: list[DataRef]) -> Mapping[Any, Any]:
        value = np.asarray(action, dtype=float)
        return agent_writes(value, self._laid_out(), self.methods.agent_action)

    def _get_observation(self, read_data: DataDict, read_var_list: list[DataRef]) -> Any:
        obs = self.methods.observations(read_data, read_var_list)
        check_observations(obs, self._owner().agents, self._laid_out())
        return obs

    def _get_reward(self) -> float:
        answer = self.methods.rewards()
        self.rewards = checked_rewards(
            answer, self._owner().agents, self._laid_out(), self.env_index, self.runner.steps
        )
        return float(sum(self.rewards.values()))

    def _get_terminated(self) -> bool:
        flags = self.methods.terminations()
        live = self._owner().agents
        self.terminations = ended(flags, live, self._laid_out())
        return bool(flags) and len(self.terminations) == len(live)

    def _initial_action(self) -> np.ndarray:
        self.start = self._laid_out().initial(self.methods.initial_actions())
        self.terminations = set()
        return self.start

    def _close_external_resources(self) -> None:
        if self._env() is not None:
            self.methods.close_external_resources()

    def _render_overlay(self) -> Overlay | None:
        return self.methods.render_overlay()

    # -- exit-time cleanup -----------------------------------------------------------------
    def close(self) -> None:
        """End everything the episode started (what exit-time cleanup calls)."""
        self.runner.close(self)

    def _owner(self) -> ViewedEnv:
        env = self._env()
        if env is None:
            raise ReferenceError("the multi-agent env of this view is gone")
        return env

    def _laid_out(self) -> AgentLayout:
        if self.layout is None:
            raise RuntimeError(f"{self.who}: the agents are laid out at reset(); call it first")
        return self.layout
