"""RLlib's PPO on a gymprecice env, built inside RLlib's own env runners.

    # a few hundred steps, no solvers
    .venv-rllib/bin/python examples/rllib_ppo.py --double

RLlib builds its environments itself, in its env runners (Ray actors), from an
env creator: :func:`gymprecice.rllib.register_env` registers one for a
gymprecice env, under its Gymnasium id. Each env claims its own run directory
under ``--run-root`` (RLlib's context cannot number envs uniquely), starts its
solvers on the runner's node, and closes them when the algorithm stops. RLlib's
``normalize_actions`` (on by default) maps the policy's output onto the env's
action bounds, so no ``RescaleAction`` is needed.

``ray[rllib]`` pins an older Gymnasium (1.2.2) than the rest of the set-up, so
RLlib lives in an environment of its own: ``bash scripts/setup-rllib.sh`` builds
``.venv-rllib``.

The policy is saved as an RLlib checkpoint (``<out>/checkpoint``), RLlib's own
format, which ``gymprecice evaluate`` does not read:
``Algorithm.from_checkpoint`` restores the whole algorithm to train on, and
:func:`load_policy` below the policy alone to act with.

For a real case: drop ``--double`` (the env then couples to OpenFOAM through
preCICE), or set ``--env-id`` to your own registered env; give ``--run-root`` on
node-local disk, raise ``--total-timesteps`` (the shipped PPO policy's run used
48,000 actions) and ``--num-env-runners`` to the cores you have (one solver per
env), and pass ``--address auto`` on a Ray cluster.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

#: where an algorithm checkpoint keeps its policy (RLlib 2.60's layout)
POLICY_IN_CHECKPOINT = Path(
    "learner_group", "learner", "rl_module", "default_policy"
)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--env-id", default="gymprecice/JetCylinderFast-v0")
    p.add_argument(
        "--double", action="store_true", help="run on gymprecice's test double"
    )
    p.add_argument(
        "--num-env-runners",
        type=int,
        default=2,
        help="Ray actors, one env each",
    )
    p.add_argument(
        "--rollout-length",
        type=int,
        default=40,
        help="steps per runner and update",
    )
    p.add_argument("--total-timesteps", type=int, default=320)
    p.add_argument("--learning-rate", type=float, default=3e-4)
    p.add_argument("--num-epochs", type=int, default=4)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--run-root", type=Path, default=Path("gymprecice-runs"))
    p.add_argument(
        "--address",
        default=None,
        help="a Ray cluster's address (default: local)",
    )
    p.add_argument("--out", type=Path, default=Path("runs/rllib-ppo"))
    return p.parse_args(argv)


def load_policy(checkpoint: Path):
    """A checkpoint's trained policy, as an RLlib module to act with."""
    from ray.rllib.core.rl_module.rl_module import RLModule

    return RLModule.from_checkpoint(
        str(Path(checkpoint).resolve() / POLICY_IN_CHECKPOINT)
    )


def greedy_action(module, obs: np.ndarray) -> np.ndarray:
    """The policy's mean action for one observation, in RLlib's [-1, 1] range.

    RLlib maps it onto the env's bounds (``normalize_actions``) when it steps
    the env; an evaluation of your own does the same: ``low + (a + 1) / 2 *
    (high - low)``, clipped.
    """
    import torch

    batch = {"obs": torch.as_tensor(obs, dtype=torch.float32)[None]}
    with torch.no_grad():
        out = module.forward_inference(batch)
    mean, _log_std = out["action_dist_inputs"][0].chunk(2)
    return mean.numpy()


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    import ray
    from ray.rllib.algorithms.ppo import PPOConfig

    from gymprecice.rllib import register_env

    settings = {"double": True} if args.double else {}
    register_env(args.env_id, run_root=str(args.run_root.resolve()), **settings)
    # Locally, one logical CPU per runner plus the learner's, whatever the
    # machine has: the envs' solvers are processes of their own, outside Ray's
    # accounting.
    if args.address is None:
        ray.init(num_cpus=args.num_env_runners + 1, include_dashboard=False)
    else:
        ray.init(address=args.address)
    batch = args.num_env_runners * args.rollout_length
    config = (
        PPOConfig()
        .environment(args.env_id)
        .env_runners(
            num_env_runners=args.num_env_runners,
            num_envs_per_env_runner=1,
            rollout_fragment_length=args.rollout_length,
            sample_timeout_s=300,
        )
        .training(
            lr=args.learning_rate,
            gamma=0.99,
            lambda_=0.95,
            train_batch_size=batch,
            minibatch_size=max(1, batch // 2),
            num_epochs=args.num_epochs,
        )
        .fault_tolerance(restart_failed_sub_environments=True)
        .debugging(seed=args.seed)
    )
    algo = config.build_algo()
    started = time.monotonic()
    try:
        sampled, iteration = 0, 0
        while sampled < args.total_timesteps:
            result = algo.train()
            iteration += 1
            runners = result["env_runners"]
            sampled = int(runners["num_env_steps_sampled_lifetime"])
            print(
                f"iteration {iteration}: {sampled} steps, episode return "
                f"{runners.get('episode_return_mean', float('nan')):.3g}, "
                f"{time.monotonic() - started:.0f} s"
            )
        args.out.mkdir(parents=True, exist_ok=True)
        checkpoint = Path(
            algo.save_to_path(str((args.out / "checkpoint").resolve()))
        )
    finally:
        algo.stop()  # closes every env and its solvers
        ray.shutdown()
    print(f"trained on {sampled} steps of {args.total_timesteps}")
    print(
        f"saved {checkpoint}: Algorithm.from_checkpoint to train on, "
        "load_policy to act"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
