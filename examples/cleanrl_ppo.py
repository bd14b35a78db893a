"""CleanRL-style PPO in one file, on gymprecice's fault-tolerant vector env.

    # a few hundred steps, no solvers
    python examples/cleanrl_ppo.py --double
    gymprecice evaluate jet-cylinder-fast --double --policy runs/cleanrl-ppo

The algorithm is CleanRL's ``ppo_continuous_action.py`` (Huang et al., 2022),
written out in full so every line can be read and changed: a Gaussian policy and
a value function, rollouts of ``--num-steps`` per env, generalised advantage
estimates, clipped surrogate updates. What gymprecice adds is the vector env:
:class:`gymprecice.vector.ResilientVectorEnv` runs each environment in its own
worker, and a solver that crashes or hangs ends that env's episode as truncated
(``infos["failure"]``) instead of stopping the run.

The policy's network is Stable-Baselines3's ``MlpPolicy`` layer for layer (64 x
64, tanh, a state-independent log standard deviation), so the trained weights
are saved as an SB3 PPO model (``<out>/model.zip``) that ``gymprecice evaluate``
and ``gymprecice_lab.common.wrapped_env.load_policy`` load like one
``gymprecice train`` made.

For a real case: drop ``--double`` (the env then couples to OpenFOAM through
preCICE), or set ``--env-id`` to your own registered env; raise
``--total-timesteps`` (the shipped PPO policy's run used 48,000 actions) and
``--num-envs`` to the cores you have (one solver per env).
"""

from __future__ import annotations

import argparse
import functools
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from torch import nn
from torch.distributions import Normal

from gymprecice.vector import ResilientVectorEnv


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env-id", default="gymprecice/JetCylinderFast-v0")
    p.add_argument(
        "--double", action="store_true", help="run on gymprecice's test double"
    )
    p.add_argument("--num-envs", type=int, default=2)
    p.add_argument(
        "--num-steps", type=int, default=40, help="rollout length per env"
    )
    p.add_argument("--total-timesteps", type=int, default=320)
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--num-minibatches", type=int, default=2)
    p.add_argument("--update-epochs", type=int, default=4)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--ent-coef", type=float, default=0.0)
    p.add_argument("--vf-coef", type=float, default=0.5)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("runs/cleanrl-ppo"))
    return p.parse_args(argv)


def make_env(env_id: str, idx: int, double: bool) -> gym.Env:
    """One env, actions rescaled to [-1, 1] as ``gymprecice evaluate`` does."""
    # registers the gymprecice/... ids in the worker
    import gymprecice  # noqa: F401

    kwargs = {"double": True} if double else {}
    env = gym.make(env_id, idx=idx, **kwargs)
    return gym.wrappers.RescaleAction(env, -1.0, 1.0)


class MlpExtractor(nn.Module):
    """Two separate 64 x 64 tanh networks, named as in SB3 for SB3 to load."""

    def __init__(self, obs_dim: int) -> None:
        super().__init__()

        def body() -> nn.Sequential:
            return nn.Sequential(
                nn.Linear(obs_dim, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh()
            )

        self.policy_net = body()
        self.value_net = body()


class Agent(nn.Module):
    def __init__(self, obs_dim: int, act_dim: int) -> None:
        super().__init__()
        self.mlp_extractor = MlpExtractor(obs_dim)
        self.action_net = nn.Linear(64, act_dim)
        self.value_net = nn.Linear(64, 1)
        self.log_std = nn.Parameter(torch.zeros(act_dim))

    def get_value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.value_net(self.mlp_extractor.value_net(obs)).squeeze(-1)

    def get_action_and_value(
        self, obs: torch.Tensor, action: torch.Tensor | None = None
    ):
        mean = self.action_net(self.mlp_extractor.policy_net(obs))
        dist = Normal(mean, self.log_std.exp().expand_as(mean))
        if action is None:
            action = dist.sample()
        return (
            action,
            dist.log_prob(action).sum(-1),
            dist.entropy().sum(-1),
            self.get_value(obs),
        )


def save_as_sb3(agent: Agent, env: gym.vector.VectorEnv, path: Path) -> None:
    """The agent as an SB3 PPO model, for ``gymprecice evaluate --policy``."""
    from stable_baselines3 import PPO

    # SB3 builds its policy from an env's spaces; never stepped
    class Spaces(gym.Env):
        observation_space = env.single_observation_space
        action_space = env.single_action_space

    model = PPO("MlpPolicy", Spaces(), device="cpu")
    model.policy.load_state_dict(agent.state_dict())
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)


def train(args: argparse.Namespace) -> Path:
    torch.manual_seed(args.seed)
    envs = ResilientVectorEnv(
        [
            functools.partial(make_env, args.env_id, i, args.double)
            for i in range(args.num_envs)
        ]
    )
    obs_dim = int(np.prod(envs.single_observation_space.shape))
    act_dim = int(np.prod(envs.single_action_space.shape))
    agent = Agent(obs_dim, act_dim)
    optimizer = torch.optim.Adam(
        agent.parameters(), lr=args.learning_rate, eps=1e-5
    )
    shape = (args.num_steps, args.num_envs)
    obs_buf = torch.zeros((*shape, obs_dim))
    act_buf = torch.zeros((*shape, act_dim))
    logp_buf, rew_buf, done_buf, val_buf = (
        torch.zeros(shape) for _ in range(4)
    )
    batch_size = args.num_envs * args.num_steps
    minibatch = batch_size // args.num_minibatches
    updates = max(1, args.total_timesteps // batch_size)
    started = time.monotonic()
    try:
        next_obs = torch.as_tensor(
            envs.reset(seed=args.seed)[0], dtype=torch.float32
        )
        next_done = torch.zeros(args.num_envs)
        returns, episode_return = [], np.zeros(args.num_envs)
        for update in range(1, updates + 1):
            for step in range(args.num_steps):
                obs_buf[step], done_buf[step] = next_obs, next_done
                with torch.no_grad():
                    action, logp, _, value = agent.get_action_and_value(
                        next_obs
                    )
                act_buf[step], logp_buf[step], val_buf[step] = (
                    action,
                    logp,
                    value,
                )
                # the env clips to its Box, as SB3 does with a Gaussian policy's
                # samples
                obs, reward, terminated, truncated, infos = envs.step(
                    np.clip(action.numpy(), -1.0, 1.0)
                )
                reward = np.asarray(reward, dtype=np.float64)
                episode_return += reward
                # the same-step autoreset returns the next episode's first obs;
                # an episode cut at the coupling's end time (truncated) still
                # had a future: bootstrap
                for i in np.flatnonzero(truncated & ~terminated):
                    if (
                        "final_obs" in infos
                        and infos["_final_obs"][i]
                        and "failure" not in infos
                    ):
                        final = torch.as_tensor(
                            infos["final_obs"][i], dtype=torch.float32
                        )
                        with torch.no_grad():
                            reward[i] += args.gamma * float(
                                agent.get_value(final)
                            )
                for i in np.flatnonzero(terminated | truncated):
                    returns.append(episode_return[i])
                    episode_return[i] = 0.0
                rew_buf[step] = torch.as_tensor(reward, dtype=torch.float32)
                next_obs = torch.as_tensor(obs, dtype=torch.float32)
                next_done = torch.as_tensor(
                    terminated | truncated, dtype=torch.float32
                )
            with torch.no_grad():  # generalised advantage estimation
                next_value = agent.get_value(next_obs)
                advantages = torch.zeros(shape)
                gae = torch.zeros(args.num_envs)
                for t in reversed(range(args.num_steps)):
                    not_done = 1.0 - (
                        next_done
                        if t == args.num_steps - 1
                        else done_buf[t + 1]
                    )
                    following = (
                        next_value
                        if t == args.num_steps - 1
                        else val_buf[t + 1]
                    )
                    delta = (
                        rew_buf[t]
                        + args.gamma * following * not_done
                        - val_buf[t]
                    )
                    gae = delta + args.gamma * args.gae_lambda * not_done * gae
                    advantages[t] = gae
                value_targets = advantages + val_buf
            b_obs, b_act = (
                obs_buf.reshape(-1, obs_dim),
                act_buf.reshape(-1, act_dim),
            )
            b_logp, b_adv = logp_buf.reshape(-1), advantages.reshape(-1)
            b_ret = value_targets.reshape(-1)
            for _ in range(args.update_epochs):
                for idx in torch.randperm(batch_size).split(minibatch):
                    _, logp, entropy, value = agent.get_action_and_value(
                        b_obs[idx], b_act[idx]
                    )
                    ratio = (logp - b_logp[idx]).exp()
                    adv = (b_adv[idx] - b_adv[idx].mean()) / (
                        b_adv[idx].std() + 1e-8
                    )
                    clipped = ratio.clamp(
                        1 - args.clip_coef, 1 + args.clip_coef
                    )
                    pg_loss = torch.max(-adv * ratio, -adv * clipped).mean()
                    v_loss = 0.5 * ((value - b_ret[idx]) ** 2).mean()
                    loss = (
                        pg_loss
                        - args.ent_coef * entropy.mean()
                        + args.vf_coef * v_loss
                    )
                    optimizer.zero_grad()
                    loss.backward()
                    nn.utils.clip_grad_norm_(
                        agent.parameters(), args.max_grad_norm
                    )
                    optimizer.step()
            recent = f"{np.mean(returns[-10:]):.3f}" if returns else "n/a"
            print(
                f"update {update}/{updates}: {update * batch_size} steps, "
                f"mean return of the last episodes {recent}, "
                f"{time.monotonic() - started:.0f} s"
            )
        path = args.out / "model.zip"
        save_as_sb3(agent, envs, path)
    finally:
        envs.close()
    print(f"saved {path}: gymprecice evaluate ENV --policy {args.out}")
    return path


# the vector env's workers start with forkserver: guard the entry
if __name__ == "__main__":
    train(parse_args())
