"""Stable-Baselines3's PPO on gymprecice's fault-tolerant SB3 vector env.

    # a few hundred steps, no solvers
    python examples/sb3_ppo.py --double
    gymprecice evaluate jet-cylinder-fast --double --policy runs/sb3-ppo

The same pieces ``gymprecice train`` uses, in a script of your own:
:class:`gymprecice.sb3.ResilientSubprocVecEnv` runs each env in its own worker,
and a solver that crashes or hangs ends that env's episode as truncated
(``info["failure"]``) instead of stopping the run;
:class:`gymprecice.sb3.TelemetryCallback` records where the time went (solver,
env code, learner) and prints a summary at the end. The model is saved as
``<out>/model.zip``, which ``gymprecice evaluate --policy`` loads.

For a real case: drop ``--double`` (the env then couples to OpenFOAM through
preCICE), or set ``--env-id`` to your own registered env; raise
``--total-timesteps`` (the shipped PPO policy's run used 48,000 actions) and
``--num-envs`` to the cores you have (one solver per env).
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path

import gymnasium as gym
from stable_baselines3 import PPO

from gymprecice.sb3 import ResilientSubprocVecEnv, TelemetryCallback


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env-id", default="gymprecice/JetCylinderFast-v0")
    p.add_argument(
        "--double", action="store_true", help="run on gymprecice's test double"
    )
    p.add_argument("--num-envs", type=int, default=2)
    p.add_argument(
        "--n-steps", type=int, default=40, help="rollout length per env"
    )
    p.add_argument("--total-timesteps", type=int, default=320)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("runs/sb3-ppo"))
    return p.parse_args(argv)


def make_env(env_id: str, idx: int, double: bool) -> gym.Env:
    """One env, actions rescaled to [-1, 1] as ``gymprecice evaluate`` does."""
    # registers the gymprecice/... ids in the worker
    import gymprecice  # noqa: F401

    kwargs = {"double": True} if double else {}
    env = gym.make(env_id, idx=idx, **kwargs)
    return gym.wrappers.RescaleAction(env, -1.0, 1.0)


def train(args: argparse.Namespace) -> Path:
    venv = ResilientSubprocVecEnv(
        [
            functools.partial(make_env, args.env_id, i, args.double)
            for i in range(args.num_envs)
        ],
        step_timeout=900,
        max_failures_per_env=5,
    )
    try:
        model = PPO(
            "MlpPolicy",
            venv,
            n_steps=args.n_steps,
            batch_size=args.n_steps,
            seed=args.seed,
        )
        model.learn(args.total_timesteps, callback=TelemetryCallback())
        path = args.out / "model.zip"
        path.parent.mkdir(parents=True, exist_ok=True)
        model.save(path)
    finally:
        venv.close()
    print(
        f"trained {model.num_timesteps} steps; saved {path}: "
        f"gymprecice evaluate ENV --policy {args.out}"
    )
    return path


# the vector env's workers start with forkserver: guard the entry
if __name__ == "__main__":
    train(parse_args())
