"""Several agents on one coupled simulation: a PettingZoo ``ParallelEnv`` (``gymprecice-core[multiagent]``).

Distributed actuators (two jets, a flap's own inlet segment, a row of slots) can be
separate agents that share one policy. :class:`MultiAgentAdapter` is the multi-agent
counterpart of :class:`~gymprecice.core.Adapter`, over one coupled run:

* an agent is a named group of the controller's write data (:attr:`~MultiAgentAdapter.agent_data`),
  with its own observation space, action space (a Box) and reward;
* all agents act once per step, in one preCICE window schedule (the configuration's
  ``actions`` section applies to every agent's actuator);
* the end time truncates every live agent; a diverging solver terminates every live agent
  with the divergence penalty and ``info["diverged"]``; an agent whose own task ends
  (:meth:`~MultiAgentAdapter._get_terminations`) leaves, its actuator holding its last action;
* seeding, ``reset``, ``close``, solver supervision and the test double are the Adapter's:
  the env runs on the Adapter's episode runner and answers it agent by agent.

:class:`JointEnv` shows all agents as one ``gymnasium.Env`` (stacked arrays), so the
fault-tolerant vector envs run a multi-agent env with their failure budget;
:class:`gymprecice.multiagent.sb3.SharedPolicyVecEnv` turns those back into one slot per
agent for parameter sharing with Stable-Baselines3. :mod:`gymprecice.multiagent.rllib`
registers a multi-agent env for RLlib's multi-agent API, one policy shared by every agent
or one per agent.
"""

from __future__ import annotations

from gymprecice.multiagent.agents import AgentData, resolve_agents
from gymprecice.multiagent.env import MultiAgentAdapter
from gymprecice.multiagent.joint import JointEnv

__all__ = ["AgentData", "JointEnv", "MultiAgentAdapter", "resolve_agents"]
