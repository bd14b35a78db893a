"""RLlib's PPO trains a gymprecice env through RLlib's own env runners.

``ray[rllib]`` 2.60 pins ``gymnasium==1.2.2``, so this runs in the second environment
that ``scripts/setup-rllib.sh`` builds (``.venv-rllib``) and skips where ``ray.rllib`` is
missing. The env is the tutorials' Quickstart-v0 on the preCICE test double (Adapter,
coupling worker, the double, a scripted-flow solver process), registered with
:func:`gymprecice.rllib.register_env` under its Gymnasium id: two env runners (Ray
actors) with two envs each build it, train PPO for two iterations, and the test checks
that

* timesteps were sampled and episodes ran to the env's truncation (its end time);
* the four envs ran in four different run directories (each claimed its own index);
* no process of any env (coupling worker, solver) is left once the algorithm stops.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

pytest.importorskip(
    "ray.rllib",
    reason="RLlib is not installed: ray[rllib] pins gymnasium 1.2.2, so its tests run in "
    ".venv-rllib (bash scripts/setup-rllib.sh)",
    exc_type=ImportError,
)
pytest.importorskip("torch", reason="RLlib's PPO needs torch")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process checks read /proc"),
]

import ray  # noqa: E402
from ray.rllib.algorithms.ppo import PPOConfig  # noqa: E402

from gymprecice.learners.rllib import EnvCreator, register_env  # noqa: E402
from gymprecice.testing.chaos import (  # noqa: E402
    CylinderEnv,
    ProcessWatcher,
    pid_alive,
    process_table,
    write_case,
)

ENV_ID = "gymprecice/Quickstart-v0"
EPISODE_TIME = 0.1  # 4 actions of 0.025 s
STEPS_PER_EPISODE = 4
RUNNERS, ENVS_PER_RUNNER = 2, 2
#: how long the envs' processes may take to go after the algorithm stops (a bound)
GONE_WITHIN_S = 30.0


def processes_under(root: Path) -> set[int]:
    """Live processes working in ``root`` or below (the envs' workers and solvers)."""
    found = set()
    for pid in process_table():
        try:
            cwd = Path(f"/proc/{pid}/cwd").resolve()
        except OSError:
            continue
        if cwd == root or root in cwd.parents:
            found.add(pid)
    return found


def wait_gone(pids: set[int]) -> set[int]:
    deadline = time.monotonic() + GONE_WITHIN_S
    while time.monotonic() < deadline and any(pid_alive(p) for p in pids):
        time.sleep(0.2)
    return {p for p in pids if pid_alive(p)}


def record_episode_end(*, episode, metrics_logger, **_) -> None:
    metrics_logger.log_value("gymprecice_truncated", int(episode.is_truncated), reduce="sum")
    metrics_logger.log_value("gymprecice_terminated", int(episode.is_terminated), reduce="sum")
    metrics_logger.log_value("gymprecice_episode_steps", len(episode), reduce="max")


@pytest.fixture
def local_ray():
    ray.init(address="local", num_cpus=RUNNERS, include_dashboard=False)
    yield
    ray.shutdown()


def test_creator_settings_and_idx(tmp_path):
    creator = EnvCreator(ENV_ID, double=True, episode_time=1.0)
    context = {"episode_time": EPISODE_TIME, "num_envs": 2}
    assert creator.settings(context) == {"double": True, "episode_time": EPISODE_TIME}
    with pytest.raises(ValueError, match="run directory"):
        creator({"idx": 3})
    with pytest.raises(TypeError, match="name="):
        register_env(CylinderEnv)
    # an Adapter subclass: envs built from one context claim different indices
    case = write_case(tmp_path / "case", tmp_path / "faults")
    creator = EnvCreator(CylinderEnv, options=str(case), run_root=str(tmp_path / "runs"))
    envs = [creator({}) for _ in range(2)]
    try:
        assert sorted(env.unwrapped.env_index for env in envs) == [0, 1]
    finally:
        for env in envs:
            env.close()


def test_ppo_trains_through_rllib_env_runners(local_ray, tmp_path):
    runs = (tmp_path / "runs").resolve()
    name = register_env(ENV_ID, double=True, run_root=str(runs))
    assert name == ENV_ID
    batch = RUNNERS * ENVS_PER_RUNNER * STEPS_PER_EPISODE * 2
    config = (
        PPOConfig()
        .environment(ENV_ID, env_config={"episode_time": EPISODE_TIME})
        .env_runners(
            num_env_runners=RUNNERS,
            num_envs_per_env_runner=ENVS_PER_RUNNER,
            num_cpus_per_env_runner=0.5,
            sample_timeout_s=120,
        )
        .training(train_batch_size=batch, minibatch_size=batch // 2, num_epochs=1)
        .callbacks(on_episode_end=record_episode_end)
        .debugging(seed=0)
    )
    watcher = ProcessWatcher(lambda: processes_under(runs), interval=0.1)
    algo = config.build_algo()
    try:
        for _ in range(2):
            result = algo.train()
    finally:
        algo.stop()
    seen = watcher.stop()

    runners = result["env_runners"]
    assert runners["num_env_steps_sampled_lifetime"] >= 2 * batch
    # every episode of the iteration, on every env, ended by the env's truncation
    assert runners["num_episodes"] >= RUNNERS * ENVS_PER_RUNNER
    assert runners["gymprecice_truncated"] == runners["num_episodes"]
    assert runners["gymprecice_terminated"] == 0
    assert runners["gymprecice_episode_steps"] == runners["episode_len_min"] == STEPS_PER_EPISODE
    assert result["learners"]["default_policy"]["num_module_steps_trained"] > 0

    env_dirs = sorted(p.name for p in runs.glob("env_*") if p.is_dir())
    assert env_dirs == [f"env_{i}" for i in range(RUNNERS * ENVS_PER_RUNNER)]
    assert seen, "no process of the envs was seen while training"
    assert not wait_gone(seen), "processes of the envs outlived algo.stop()"


# -- the RLlib guide (docs/guides/rllib.md): examples/rllib_ppo.py, run as the page shows it

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load_guide():
    import importlib.util

    spec = importlib.util.spec_from_file_location("rllib_ppo", EXAMPLES / "rllib_ppo.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.timeout(600)
def test_rllib_guide_trains_on_the_double_and_saves_a_policy_that_acts(tmp_path):
    import subprocess

    import gymnasium as gym
    import numpy as np

    runs, out = (tmp_path / "runs").resolve(), tmp_path / "policy"
    argv = ["--double", "--run-root", str(runs), "--out", str(out)]
    watcher = ProcessWatcher(lambda: processes_under(runs), interval=0.1)
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / "rllib_ppo.py"), *argv],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=540,
    )
    seen = watcher.stop()
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    trained = [line for line in proc.stdout.splitlines() if line.startswith("trained on ")]
    assert trained, proc.stdout[-3000:]
    assert int(trained[0].split()[2]) >= 320  # the few hundred steps it was asked for
    assert seen, "no process of the envs was seen while training"
    assert not wait_gone(seen), "processes of the envs outlived the script"

    guide = _load_guide()
    policy = guide.load_policy(out / "checkpoint")
    env = gym.make("gymprecice/JetCylinderFast-v0", double=True, idx=0, run_root=str(runs))
    try:
        obs, _ = env.reset(seed=0)
        action = guide.greedy_action(policy, obs)
        assert action.shape == env.action_space.shape and np.isfinite(action).all()
    finally:
        env.close()
