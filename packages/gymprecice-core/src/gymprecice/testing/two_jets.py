"""A two-agent env on the chaos case: each jet of the fake cylinder is one agent.

Tests of :mod:`gymprecice.multiagent` (and its overhead benchmark) need a complete
multi-agent environment over the same coupled run as the single-agent
:class:`~gymprecice.testing.chaos.CylinderEnv`: the case of :func:`~gymprecice.testing.chaos.write_case`
(the episode runner, coupling worker, the preCICE double, a solver process that fails on
request through :func:`~gymprecice.testing.chaos.inject`). Agent ``upper`` drives ``jet1``,
agent ``lower`` drives ``jet2``; both observe the 3 probe pressures and the latest drag
coefficient, and both are rewarded with minus the drag. Needs PettingZoo
(``gymprecice-core[multiagent]``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.multiagent import MultiAgentAdapter
from gymprecice.testing.chaos import PROBES
from gymprecice.testing.chaos_solver import COEFFICIENTS
from gymprecice.testing.flows import place_jets

__all__ = ["TwoJetsEnv"]


class TwoJetsEnv(MultiAgentAdapter):
    """Two jets, two agents (see the module docstring).

    Action of each agent: its jet's flow rate in [-1, 1] (``upper`` blows outward for a
    positive value, ``lower`` sucks, as the single-agent env's one action does for both).
    Set ``read_outputs=False`` to skip the drag file (benchmarks of the bare coupling).
    """

    agent_data = {"upper": ["Velocity-jet1"], "lower": ["jet2"]}

    def __init__(
        self, options: Any = None, idx: int | None = 0, *, read_outputs: bool = True, **kwargs: Any
    ) -> None:
        super().__init__(options, idx, **kwargs)
        place_jets(self)
        self.set_interface_vertices("probe", PROBES)
        self.action_spaces = {
            agent: gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
            for agent in self.possible_agents
        }
        self.observation_spaces = {
            agent: gym.spaces.Box(-np.inf, np.inf, shape=(4,), dtype=np.float32)
            for agent in self.possible_agents
        }
        self.read_outputs = read_outputs
        self._drag = 0.0
        self._signs = {"upper": 1.0, "lower": -1.0}

    def _get_agent_action(self, agent: str, action: np.ndarray, write_var_list: list) -> dict:
        (ref,) = write_var_list
        n = len(self.interface_geometry[ref.interface].coordinates)
        return {ref: np.tile([0.0, self._signs[agent] * float(action[0])], (n, 1))}

    def _get_observations(self, read_data: Any, read_var_list: Any) -> dict[str, np.ndarray]:
        self._drag = self._read_drag() if self.read_outputs else 0.0
        pressure = np.asarray(read_data["probe"], dtype=float).ravel()
        obs = np.array([*pressure, self._drag], dtype=np.float32)
        return {agent: obs.copy() for agent in self.agents}

    def _get_rewards(self) -> dict[str, float]:
        return dict.fromkeys(self.agents, -self._drag)

    def _read_drag(self) -> float:
        try:
            text = (self.solver_dirs["fluid"] / COEFFICIENTS).read_text()
        except FileNotFoundError:
            return 0.0
        rows = [line for line in text.splitlines() if line and not line.startswith("#")]
        return float(rows[-1].split()[1]) if rows else 0.0
