"""Which write data each agent drives: ``agent_data`` resolved against the configuration.

An agent is a named group of the controller's write data. The groups are declared in code
(the env's ``agent_data``), because the env's own methods are written against the agent
names; the data they name must be what ``gymprecice-config.json`` and ``precice-config.xml``
make the controller write. Everything is checked once, at construction, so a typo fails
with both files named instead of writing the wrong actuator for a whole training run:

* a name the controller does not write (with what it does write, and which file to fix);
* a data claimed by two agents (an actuator has one owner);
* a write data no agent claims (nobody would ever set it).

This module needs no PettingZoo: it is plain configuration logic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.core import DataRef
from gymprecice.plugin.errors import ConfigError

__all__ = ["AgentData", "resolve_agents"]

#: agent name -> the write data it drives: ``"Data-interface"`` keys, interface names (all
#: the data the controller writes on that interface) or :class:`~gymprecice.core.DataRef`\ s
AgentData = Mapping[str, "str | DataRef | Sequence[str | DataRef]"]


def resolve_agents(
    agent_data: AgentData,
    config: GymPreciceConfig,
    write_refs: Sequence[DataRef],
    owner: str,
) -> dict[str, tuple[DataRef, ...]]:
    """Each agent's write data, in the configuration's order; ``ConfigError`` when wrong.

    ``owner`` names where ``agent_data`` was declared (``"my_env.TwoJets.agent_data"``),
    for the messages.
    """
    if not isinstance(agent_data, Mapping) or not agent_data:
        raise ConfigError(
            f"{owner} declares no agent: set it to {{agent name: [write data, ...]}}, e.g. "
            f"{{'upper': ['{_example(write_refs)}']}}, with every data the controller writes "
            f"({_names(write_refs)}) claimed by one agent"
        )
    claimed_by: dict[DataRef, str] = {}
    agents: dict[str, tuple[DataRef, ...]] = {}
    for agent, claims in agent_data.items():
        if not isinstance(agent, str) or not agent:
            raise ConfigError(f"{owner}: agent names are non-empty strings, got {agent!r}")
        listed = [claims] if isinstance(claims, (str, DataRef)) else list(claims)
        if not listed:
            raise ConfigError(
                f"{owner}[{agent!r}] claims no write data; give it one of {_names(write_refs)}"
            )
        refs: list[DataRef] = []
        for claim in listed:
            matched = _match(claim, write_refs)
            if not matched:
                raise ConfigError(_not_written(owner, agent, claim, config, write_refs))
            for ref in matched:
                other = claimed_by.get(ref)
                if other is not None and other != agent:
                    raise ConfigError(
                        f"{owner}: agents {other!r} and {agent!r} both claim {str(ref)!r} "
                        f"(data {ref.data!r} on interface {ref.interface!r}); a write data is "
                        f"driven by one agent: remove it from one of them"
                    )
                if ref not in refs:
                    claimed_by[ref] = agent
                    refs.append(ref)
        agents[agent] = tuple(sorted(refs, key=write_refs.index))
    unclaimed = [str(ref) for ref in write_refs if ref not in claimed_by]
    if unclaimed:
        raise ConfigError(
            f"{owner}: the controller writes {unclaimed} ({config.where()}, controller.write_to) "
            "but no agent claims it, so nothing would ever set it: add it to an agent, or "
            "remove it from controller.write_to"
        )
    return agents


def _match(claim: object, write_refs: Sequence[DataRef]) -> list[DataRef]:
    if isinstance(claim, DataRef):
        return [claim] if claim in write_refs else []
    if not isinstance(claim, str):
        return []
    exact = [ref for ref in write_refs if str(ref) == claim]
    return exact or [ref for ref in write_refs if ref.interface == claim]


def _not_written(
    owner: str,
    agent: str,
    claim: object,
    config: GymPreciceConfig,
    write_refs: Sequence[DataRef],
) -> str:
    participant = config.participant
    in_xml = config.precice.participant(participant).write_data
    in_json = {(ref.data, ref.mesh) for ref in write_refs}
    only_xml = [
        f"{data!r} on mesh {mesh!r}" for data, mesh in in_xml if (data, mesh) not in in_json
    ]
    message = (
        f"{owner}[{agent!r}] claims {claim!r}, which the controller does not write. It writes "
        f"{_names(write_refs)} ({config.where()}: controller.write_to, cross-checked with "
        f"{config.precice_file}, participant {participant!r}): name one of those, as "
        "'Data-interface' or as an interface name"
    )
    if only_xml:
        message += (
            f"; {config.precice_file.name} also lets {participant!r} write "
            f"{', '.join(only_xml)}: to drive it, add its interface to controller.write_to"
        )
    else:
        message += (
            f", or make the controller write it: a <write-data name=... mesh=.../> of "
            f"participant {participant!r} in {config.precice_file}, and its interface in "
            "controller.write_to"
        )
    return message


def _names(write_refs: Sequence[DataRef]) -> list[str]:
    return [str(ref) for ref in write_refs]


def _example(write_refs: Sequence[DataRef]) -> str:
    return str(write_refs[0]) if write_refs else "Data-interface"
