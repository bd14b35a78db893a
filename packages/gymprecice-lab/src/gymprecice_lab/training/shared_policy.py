"""One policy for every agent of a joint env: ``gymprecice train --shared-policy``.

A multi-agent env shown as one Gymnasium env (:class:`gymprecice.multiagent.JointEnv`)
stacks its agents: observation ``(n_agents, ...)``, action ``(n_agents, ...)``, one row
per agent, in the order of its card's ``agents``. Parameter sharing trains one policy on
the rows: :class:`~gymprecice.multiagent.sb3.SharedPolicyVecEnv` makes every agent of
every env one slot of the learner's vector env, so one env step gives one sample per
agent. The policy that comes out takes one agent's row; Stable-Baselines3 reads the
joint observation as a batch of rows and returns the joint action, so evaluation, the
baselines' tables and ``--policy shipped`` run it on the joint env as they run any policy.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.training import hyperparams as hp

__all__ = ["per_row", "shared_agents", "shared_vec_env"]


def shared_agents(env: LabEnv, params: Mapping[str, Any]) -> tuple[str, ...]:
    """The agents that share the policy (none without ``shared_policy``); refused with
    one line when the env's card declares fewer than two."""
    if not params.get(hp.SHARED_KEY):
        return ()
    agents = tuple(env.card.agents)
    if len(agents) < 2:
        raise SystemExit(
            f"gymprecice train: --shared-policy trains one policy shared by the agents of a "
            f"joint multi-agent env, and {env.name}'s lab card declares "
            f"{'one agent' if agents else 'none'} (EnvCard(agents=...), one name per row of "
            "its observation and action); drop --shared-policy to train one controller"
        )
    if params.get("model_ensemble") is not None:
        raise SystemExit(
            "gymprecice train: --shared-policy and model_ensemble cannot be combined: the "
            "ensemble learns the joint env's transitions, not one agent's; drop one of them"
        )
    return agents


def shared_vec_env(venv: Any, agents: tuple[str, ...]) -> Any:
    """``venv`` (a vector env of joint envs) with one learner slot per agent."""
    from gymprecice.multiagent.sb3 import SharedPolicyVecEnv

    shared = SharedPolicyVecEnv(venv)
    if shared.n_agents != len(agents):
        shared.close()
        raise SystemExit(
            f"gymprecice train: --shared-policy: the env's observation has "
            f"{shared.n_agents} rows but its lab card names {len(agents)} agents "
            f"({', '.join(agents)}); the card's agents must be the joint env's rows"
        )
    return shared


def per_row(model_shape: tuple[int, ...], env_shape: tuple[int, ...]) -> bool:
    """Whether a policy of shape ``model_shape`` acts on each row of ``env_shape``: a
    shared policy (``(9,)``) on its joint env (``(2, 9)``)."""
    return len(env_shape) == len(model_shape) + 1 and tuple(env_shape[1:]) == tuple(model_shape)
