"""TorchRL's PPO on a gymprecice vector env, through its Gymnasium wrapper.

    # a few hundred steps, no solvers
    python examples/torchrl_ppo.py --double
    gymprecice evaluate jet-cylinder-fast --double --policy runs/torchrl-ppo

TorchRL wraps Gymnasium environments with ``GymWrapper``; wrapped around
:class:`gymprecice.vector.ResilientVectorEnv` (Gymnasium's same-step autoreset),
each gymprecice env runs in its own worker, a failed solver truncates only its
env's episode, and TorchRL sees one batched environment. The rest is TorchRL's
own PPO: a ``Collector`` gathers ``--frames-per-batch`` steps, ``GAE`` estimates
advantages, ``ClipPPOLoss`` updates a Gaussian policy and a value network.

The networks are Stable-Baselines3's ``MlpPolicy`` layer for layer (64 x 64,
tanh, a state-independent log standard deviation), so the trained weights are
saved as an SB3 PPO model (``<out>/model.zip``) that ``gymprecice evaluate``
loads like one ``gymprecice train`` made, beside the TorchRL state dict
(``<out>/torchrl_policy.pt``).

For a real case: drop ``--double`` (the env then couples to OpenFOAM through
preCICE), or set ``--env-id`` to your own registered env; raise
``--total-frames`` (the shipped PPO policy's run used 48,000 actions) and
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
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.envs import GymWrapper
from torchrl.modules import IndependentNormal, ProbabilisticActor, ValueOperator
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from gymprecice.vector import ResilientVectorEnv


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env-id", default="gymprecice/JetCylinderFast-v0")
    p.add_argument(
        "--double", action="store_true", help="run on gymprecice's test double"
    )
    p.add_argument("--num-envs", type=int, default=2)
    p.add_argument(
        "--frames-per-batch",
        type=int,
        default=80,
        help="steps per update, all envs",
    )
    p.add_argument("--total-frames", type=int, default=320)
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--gamma", type=float, default=0.99)
    p.add_argument("--gae-lambda", type=float, default=0.95)
    p.add_argument("--minibatch-size", type=int, default=40)
    p.add_argument("--update-epochs", type=int, default=4)
    p.add_argument("--clip-coef", type=float, default=0.2)
    p.add_argument("--max-grad-norm", type=float, default=0.5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("runs/torchrl-ppo"))
    return p.parse_args(argv)


def make_env(env_id: str, idx: int, double: bool) -> gym.Env:
    """One env, actions rescaled to [-1, 1] as ``gymprecice evaluate`` does."""
    # registers the gymprecice/... ids in the worker
    import gymprecice  # noqa: F401

    kwargs = {"double": True} if double else {}
    env = gym.make(env_id, idx=idx, **kwargs)
    return gym.wrappers.RescaleAction(env, -1.0, 1.0)


class TorchRLInfos(gym.vector.VectorWrapper):
    """Hand TorchRL only the infos it reads: the ended episodes' last obs.

    TorchRL turns every info entry into a tensor, and gymprecice's infos also
    hold text and nested timings. A failed env's description
    (``infos["failure"]``) is printed instead.
    """

    def __init__(self, env: gym.vector.VectorEnv) -> None:
        super().__init__(env)
        self.autoreset_mode = env.autoreset_mode

    def reset(self, **kwargs):
        obs, _ = self.env.reset(**kwargs)
        return obs, {}

    def step(self, actions):
        obs, reward, terminated, truncated, infos = self.env.step(actions)
        for i in np.flatnonzero(infos.get("_failure", ())):
            print(f"env {i} failed and was replaced: {infos['failure'][i]}")
        kept = {
            key: infos[key]
            for key in ("final_obs", "_final_obs")
            if key in infos
        }
        return obs, reward, terminated, truncated, kept


class Networks(nn.Module):
    """The policy and value networks, named as SB3's ``ActorCriticPolicy``."""

    def __init__(self, obs_dim: int, act_dim: int) -> None:
        super().__init__()

        def body() -> nn.Sequential:
            return nn.Sequential(
                nn.Linear(obs_dim, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh()
            )

        self.mlp_extractor = nn.Module()
        self.mlp_extractor.policy_net = body()
        self.mlp_extractor.value_net = body()
        self.action_net = nn.Linear(64, act_dim)
        self.value_net = nn.Linear(64, 1)
        self.log_std = nn.Parameter(torch.zeros(act_dim))


class GaussianHead(nn.Module):
    """Observation -> (loc, scale) of the policy's Gaussian."""

    def __init__(self, nets: Networks) -> None:
        super().__init__()
        self.nets = nets

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        loc = self.nets.action_net(self.nets.mlp_extractor.policy_net(obs))
        return loc, self.nets.log_std.exp().expand_as(loc)


class ValueHead(nn.Module):
    def __init__(self, nets: Networks) -> None:
        super().__init__()
        self.nets = nets

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.nets.value_net(self.nets.mlp_extractor.value_net(obs))


def save_as_sb3(
    nets: Networks, vec_env: gym.vector.VectorEnv, path: Path
) -> None:
    """The networks as an SB3 PPO model for ``gymprecice evaluate --policy``."""
    from stable_baselines3 import PPO

    # SB3 builds its policy from an env's spaces; never stepped
    class Spaces(gym.Env):
        observation_space = vec_env.single_observation_space
        action_space = vec_env.single_action_space

    model = PPO("MlpPolicy", Spaces(), device="cpu")
    model.policy.load_state_dict(nets.state_dict())
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)


def train(args: argparse.Namespace) -> Path:
    torch.manual_seed(args.seed)
    vec_env = ResilientVectorEnv(
        [
            functools.partial(make_env, args.env_id, i, args.double)
            for i in range(args.num_envs)
        ]
    )
    try:
        env = GymWrapper(TorchRLInfos(vec_env))
        env.set_seed(args.seed)
        obs_dim = int(np.prod(vec_env.single_observation_space.shape))
        act_dim = int(np.prod(vec_env.single_action_space.shape))
        nets = Networks(obs_dim, act_dim)
        actor = ProbabilisticActor(
            TensorDictModule(
                GaussianHead(nets),
                in_keys=["observation"],
                out_keys=["loc", "scale"],
            ),
            in_keys=["loc", "scale"],
            distribution_class=IndependentNormal,
            spec=env.action_spec_unbatched,
            # sampled actions are clipped to the Box, as SB3 clips them
            safe=True,
            return_log_prob=True,
        )
        critic = ValueOperator(ValueHead(nets), in_keys=["observation"])
        advantage = GAE(
            gamma=args.gamma, lmbda=args.gae_lambda, value_network=critic
        )
        loss = ClipPPOLoss(
            actor, critic, clip_epsilon=args.clip_coef, entropy_coeff=0.0
        )
        optimizer = torch.optim.Adam(
            loss.parameters(), lr=args.learning_rate, eps=1e-5
        )
        collector = Collector(
            env,
            actor,
            frames_per_batch=args.frames_per_batch,
            total_frames=args.total_frames,
            # the policy keeps no state between steps
            auto_register_policy_transforms=False,
        )
        started, frames = time.monotonic(), 0
        for batch in collector:
            frames += batch.numel()
            batch = batch.reshape(-1)
            for _ in range(args.update_epochs):
                with torch.no_grad():
                    advantage(batch)
                for idx in torch.randperm(batch.numel()).split(
                    args.minibatch_size
                ):
                    losses = loss(batch[idx])
                    total = losses["loss_objective"] + losses["loss_critic"]
                    total = total + losses.get("loss_entropy", torch.zeros(()))
                    optimizer.zero_grad()
                    total.backward()
                    nn.utils.clip_grad_norm_(
                        loss.parameters(), args.max_grad_norm
                    )
                    optimizer.step()
            collector.update_policy_weights_()
            reward = batch["next", "reward"].mean().item()
            print(
                f"{frames}/{args.total_frames} frames, "
                f"mean step reward {reward:.3f}, "
                f"{time.monotonic() - started:.0f} s"
            )
        collector.shutdown()
        args.out.mkdir(parents=True, exist_ok=True)
        torch.save(nets.state_dict(), args.out / "torchrl_policy.pt")
        path = args.out / "model.zip"
        save_as_sb3(nets, vec_env, path)
    finally:
        vec_env.close()
    print(f"saved {path}: gymprecice evaluate ENV --policy {args.out}")
    return path


# the vector env's workers start with forkserver: guard the entry
if __name__ == "__main__":
    train(parse_args())
