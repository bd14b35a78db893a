"""What a multi-agent env's user methods return, checked before the episode goes on.

The runner checks one env's answers (a finite observation and reward, the data of every
written interface); a multi-agent env's answers are dicts of agents, and a wrong one
(an agent missing, an unknown or a done one, an observation outside its space, an agent
writing another agent's actuator) would otherwise reach the learner or the solvers as
something else. Each function here takes the user's answer and what it is checked
against (the :class:`~gymprecice.multiagent.layout.AgentLayout` of this episode, the live
agents) and raises with the method and the agent named.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from gymprecice.env.returned_values import find_written, refuse_non_finite
from gymprecice.env.values import DataRef
from gymprecice.multiagent.layout import AgentLayout

__all__ = ["AgentAction", "agent_writes", "check_observations", "checked_rewards", "ended"]

#: The user's ``_get_agent_action(agent, action, write_var_list)``.
AgentAction = Callable[[str, np.ndarray, list[DataRef]], Mapping[Any, Any]]


def agent_writes(
    value: np.ndarray, layout: AgentLayout, agent_action: AgentAction
) -> dict[DataRef, Any]:
    """Every agent's data for one window's joint value, each from ``agent_action``."""
    who = layout.who
    out: dict[DataRef, Any] = {}
    for agent, slot in layout.slots.items():
        refs = slot.refs
        produced = agent_action(agent, layout.part(value, agent), list(refs))
        if not isinstance(produced, Mapping):
            raise TypeError(
                f"{who}._get_agent_action({agent!r}, ...) returned "
                f"{type(produced).__name__}; return a dict keyed by the entries of its "
                f"write_var_list {[str(r) for r in refs]}"
            )
        for ref in refs:
            array = produced.get(ref)
            if array is None:
                array = find_written(produced, ref, list(refs))
            if array is None:
                raise KeyError(
                    f"{who}._get_agent_action({agent!r}, ...) returned no data for {ref} "
                    f"(interface {ref.interface!r}, data {ref.data!r}); return a dict keyed "
                    f"by the entries of its write_var_list {[str(r) for r in refs]}"
                )
            out[ref] = array
        if len(produced) > len(refs):
            _refuse_foreign(layout, agent, produced)
    return out


def _refuse_foreign(layout: AgentLayout, agent: str, produced: Mapping[Any, Any]) -> None:
    """Raise on the first key of ``produced`` that is not ``agent``'s own data."""
    refs = layout.slots[agent].refs
    own = {key for ref in refs for key in (ref, str(ref), ref.interface)}
    for key in produced:
        if key in own:
            continue
        owner = next(
            (a for a, slot in layout.slots.items() for r in slot.refs if key in (r, str(r))),
            None,
        )
        whose = f"agent {owner!r}'s data" if owner else "not a write data of this env"
        raise KeyError(
            f"{layout.who}._get_agent_action({agent!r}, ...) returned {str(key)!r}, which "
            f"is {whose}; an agent writes only its own: {[str(r) for r in refs]} (agent_data)"
        )


def check_observations(obs: Any, live: list[str], layout: AgentLayout) -> None:
    """The observations cover the live agents, and each fits its agent's space."""
    who = layout.who
    if not isinstance(obs, Mapping):
        raise TypeError(
            f"{who}._get_observations() returned {type(obs).__name__}; return a dict "
            f"{{agent: observation}} for the live agents {live}"
        )
    if not all(agent in obs for agent in live) or len(obs) > len(live):
        missing = [agent for agent in live if agent not in obs]
        unknown = [key for key in obs if key not in layout.slots]
        if missing or unknown:
            raise KeyError(
                f"{who}._get_observations() returned observations for {list(obs)}: "
                + _missing_and_unknown(missing, unknown)
                + f". The agents are {layout.agents}"
            )
    for agent in live:
        value = obs[agent]
        shape = layout.observation_shapes[agent]
        space = layout.observation_spaces[agent]
        if shape is not None:  # a Box: its shape (bounds are the learner's business)
            fits = getattr(value, "shape", None) == shape or np.shape(value) == shape
        else:
            fits = space.contains(value)
        if not fits:
            what = f"shape {np.shape(value)}" if shape is not None else repr(value)
            raise ValueError(
                f"{who}._get_observations() returned for agent {agent!r} an observation of "
                f"{what}, which observation_spaces[{agent!r}] = {space} does not hold: make "
                "the space and the method agree"
            )


def checked_rewards(
    rewards: Any, live: list[str], layout: AgentLayout, env_index: int, step: int
) -> dict[str, float]:
    """``{agent: reward}`` of the live agents as floats; refused if not that, or not finite."""
    who = layout.who
    if not isinstance(rewards, Mapping):
        raise TypeError(
            f"{who}._get_rewards() returned {type(rewards).__name__}; return a dict "
            f"{{agent: reward}} for the live agents {live}"
        )
    missing = [agent for agent in live if agent not in rewards]
    unknown = [key for key in rewards if key not in layout.slots]
    if missing or unknown:
        raise KeyError(
            f"{who}._get_rewards() returned rewards for {list(rewards)}: "
            + _missing_and_unknown(missing, unknown)
            + f". The agents are {layout.agents}"
        )
    out = {agent: float(rewards[agent]) for agent in live}
    if not math.isfinite(math.fsum(out.values())):  # one NaN or infinity makes it so
        refuse_non_finite(out, "_get_rewards", env_index, step)
    return out


def ended(flags: Mapping[str, bool], live: list[str], layout: AgentLayout) -> set[str]:
    """The live agents ``_get_terminations()`` ends; an unknown agent in it is refused."""
    if not flags:
        return set()
    unknown = [key for key in flags if key not in layout.slots]
    if unknown:
        raise KeyError(
            f"{layout.who}._get_terminations() names unknown agent(s) {unknown}; the agents "
            f"are {layout.agents}"
        )
    return {agent for agent in live if flags.get(agent)}


def _missing_and_unknown(missing: list[str], unknown: list[Any]) -> str:
    return (
        (f"none for live agent(s) {missing}" if missing else "")
        + ("; " if missing and unknown else "")
        + (f"unknown agent(s) {unknown}" if unknown else "")
    )
