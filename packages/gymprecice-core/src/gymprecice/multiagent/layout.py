"""Where each agent's action sits in the joint action: the one vector the runner spreads.

The episode runner spreads one action over a step's time windows (hold, ramp, cosine,
filter), which only numbers can be, so a multi-agent env hands it one vector: every
agent's Box action, flattened and laid end to end in the order of ``possible_agents``.
:class:`AgentLayout` is that order, made at each ``reset()`` from the agents' spaces. It
joins an action dict into the vector (refusing a dict that is not one action per live
agent, before anything reaches the solvers) and splits a window's value back per agent.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.env.values import DataRef
from gymprecice.plugin.errors import ConfigError

__all__ = ["AgentLayout", "Slot", "agent_space"]


@dataclass(frozen=True)
class Slot:
    """Where one agent's action sits in the joint vector, and the data it drives."""

    start: int
    stop: int
    space: gym.spaces.Box
    refs: tuple[DataRef, ...]

    @property
    def shape(self) -> tuple[int, ...]:
        return self.space.shape


def agent_space(
    spaces: Mapping[str, gym.Space], attr: str, agent: str, agents: Sequence[str], who: str
) -> gym.Space:
    """``spaces[agent]``; an unknown agent and a space the env never set are named apart.

    ``attr`` is the env's attribute (``"action_spaces"``), ``agents`` the env's agents and
    ``who`` its class, for the messages.
    """
    try:
        return spaces[agent]
    except KeyError:
        if agent not in agents:
            raise KeyError(f"{who}: no agent {agent!r}; the agents are {list(agents)}") from None
        raise ConfigError(
            f"{who} sets no {attr}[{agent!r}]: fill self.{attr} for every agent "
            f"({list(agents)}) in __init__, after super().__init__()"
        ) from None


class AgentLayout:
    """The agents' places in the joint action, and their observation spaces, for one reset.

    ``who`` names the env's class in every message.
    """

    def __init__(
        self,
        slots: Mapping[str, Slot],
        observation_spaces: Mapping[str, gym.Space],
        who: str,
    ) -> None:
        self.slots = dict(slots)
        self.observation_spaces = dict(observation_spaces)
        #: a Box observation's shape (what is checked of it), ``None`` for other spaces
        self.observation_shapes = {
            agent: space.shape if isinstance(space, gym.spaces.Box) else None
            for agent, space in self.observation_spaces.items()
        }
        self.who = who
        self.size = max((slot.stop for slot in self.slots.values()), default=0)
        lows = [np.broadcast_to(s.space.low, s.shape).ravel() for s in self.slots.values()]
        highs = [np.broadcast_to(s.space.high, s.shape).ravel() for s in self.slots.values()]
        #: the joint action's space: every agent's bounds, end to end
        self.action_space = gym.spaces.Box(
            np.concatenate([np.zeros(0), *lows]).astype(float),
            np.concatenate([np.zeros(0), *highs]).astype(float),
            dtype=float,
        )

    @classmethod
    def of(
        cls,
        agents: Sequence[str],
        agent_refs: Mapping[str, tuple[DataRef, ...]],
        action_space: Callable[[str], gym.Space],
        observation_space: Callable[[str], gym.Space],
        who: str,
    ) -> AgentLayout:
        """The layout of ``agents``, in this order, from the env's spaces and ``agent_refs``.

        Every agent needs both spaces, and its action space must be a Box: an action is
        spread over the step's windows as numbers.
        """
        slots: dict[str, Slot] = {}
        observation_spaces: dict[str, gym.Space] = {}
        start = 0
        for agent in agents:
            space = action_space(agent)
            observation_spaces[agent] = observation_space(agent)
            if not isinstance(space, gym.spaces.Box):
                raise ConfigError(
                    f"{who}: action_spaces[{agent!r}] is {space}; a gymprecice agent "
                    "acts through a Box (its actions are spread over the step's time windows "
                    "as numbers): use a Box, and map a discrete choice to values in "
                    "_get_agent_action"
                )
            stop = start + int(np.prod(space.shape, dtype=int))
            slots[agent] = Slot(start, stop, space, agent_refs[agent])
            start = stop
        return cls(slots, observation_spaces, who)

    @property
    def agents(self) -> list[str]:
        """Every agent, in the joint vector's order."""
        return list(self.slots)

    # -- joining and splitting --------------------------------------------------------------
    def joint(self, actions: Any, live: list[str], held: np.ndarray) -> np.ndarray:
        """One vector of the live agents' ``actions``; a done agent's part holds ``held``'s."""
        who = self.who
        if not isinstance(actions, Mapping):
            raise TypeError(
                f"{who}.step() takes a dict {{agent: action}} for every live agent "
                f"({live}), got {type(actions).__name__}"
            )
        if actions.keys() != set(live):
            self._refuse_agents(actions, live)
        joint = np.array(held, dtype=float)
        for agent in live:
            slot = self.slots[agent]
            value = actions[agent]
            if np.shape(value) != slot.shape:
                raise ValueError(
                    f"{who}: the action of agent {agent!r} has shape {np.shape(value)}, but "
                    f"its action space {slot.space} expects shape {slot.shape}"
                )
            try:
                joint[slot.start : slot.stop] = np.ravel(value)
            except (TypeError, ValueError):
                raise ValueError(
                    f"{who}: the action of agent {agent!r} is not numeric ({value!r}); its "
                    f"action space is {slot.space}"
                ) from None
        if not np.isfinite(joint).all():
            bad = [a for a in live if not np.isfinite(self.part(joint, a)).all()]
            raise ValueError(
                f"{who}: the action of agent(s) {bad} is not finite (NaN or infinity); "
                "check the policy's output"
            )
        return joint

    def part(self, joint: np.ndarray, agent: str) -> np.ndarray:
        """``agent``'s action in ``joint``, in the shape of its action space."""
        slot = self.slots[agent]
        return joint[slot.start : slot.stop].reshape(slot.shape)

    def split(self, joint: np.ndarray) -> dict[str, np.ndarray]:
        """Every agent's action in ``joint`` (copies); ``{}`` if ``joint`` is not this size."""
        if not self.slots or len(joint) != self.size:
            return {}
        return {agent: self.part(joint, agent).copy() for agent in self.slots}

    def initial(self, initial: Mapping[str, Any]) -> np.ndarray:
        """The joint vector of ``_initial_actions()``: one entry per agent, of its shape."""
        joint = np.zeros(self.size, dtype=float)
        for agent, slot in self.slots.items():
            if agent not in initial:
                raise KeyError(f"{self.who}._initial_actions() has no entry for agent {agent!r}")
            values = np.asarray(initial[agent], dtype=float)
            if values.shape != slot.shape:
                raise ValueError(
                    f"{self.who}._initial_actions()[{agent!r}] has shape {values.shape}; "
                    f"action_spaces[{agent!r}] expects {slot.shape}"
                )
            joint[slot.start : slot.stop] = values.ravel()
        return joint

    def _refuse_agents(self, actions: Mapping[str, Any], live: list[str]) -> None:
        missing = [agent for agent in live if agent not in actions]
        unknown = [agent for agent in actions if agent not in self.slots]
        done = [agent for agent in actions if agent in self.slots and agent not in live]
        problems = []
        if missing:
            problems.append(f"no action for agent(s) {missing}")
        if unknown:
            problems.append(f"action(s) for unknown agent(s) {unknown}")
        if done:
            problems.append(f"action(s) for agent(s) {done}, done in this episode")
        raise ValueError(
            f"{self.who}.step(): {'; '.join(problems)}. Give exactly one action per live "
            f"agent, env.agents = {live} (the agents are {self.agents})"
        )
