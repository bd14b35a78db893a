"""RLlib's multi-agent API trains a gymprecice multi-agent env through RLlib's env runners.

``ray[rllib]`` 2.60 pins ``gymnasium==1.2.2``, so this runs in ``.venv-rllib`` (built by
``scripts/setup-rllib.sh``, with PettingZoo) and skips where ``ray.rllib`` is missing. The
env is the two flaps' training case on the preCICE test double (``TwoFlapsFastEnv(
double=True)``: a MultiAgentAdapter, its coupling worker, two scripted flaps), with short
episodes: one action of gust, then two actions (0.2 s) of the agents'.
"""

from __future__ import annotations

import sys

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
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode  # noqa: E402

from gymprecice.multiagent.rllib import (  # noqa: E402
    MultiAgentEnvCreator,
    RLlibMultiAgentEnv,
    policy_per_agent,
    register_multiagent_env,
    shared_policy,
)
from gymprecice.testing.chaos import CylinderEnv, ProcessWatcher, write_case  # noqa: E402
from gymprecice_tutorials.two_flaps.fast import TwoFlapsFastEnv  # noqa: E402
from tests.test_rllib import processes_under, wait_gone  # noqa: E402

AGENTS = ["upstream", "downstream"]
#: one action of gust before each episode, then two actions of the agents
SHORT = {"episode_time": 0.2, "settle_time": 0.1}
STEPS_PER_EPISODE = 2
RUNNERS = 2


def test_episode_ends_truncated_for_every_agent_in_rllib(tmp_path):
    """The wrapper's end of an episode, read by RLlib's own ``MultiAgentEpisode``: every
    agent's episode ends truncated, not terminated (the end time is no terminal state).

    Cost: one env of the two flaps' double, two episodes of three actions: about 8 s.
    """
    runs = (tmp_path / "runs").resolve()
    creator = MultiAgentEnvCreator(TwoFlapsFastEnv, double=True, run_root=str(runs))
    watcher = ProcessWatcher(lambda: processes_under(runs), interval=0.1)
    env = creator(SHORT)
    try:
        assert isinstance(env, RLlibMultiAgentEnv)
        assert env.possible_agents == AGENTS
        assert set(env.observation_spaces) == set(env.action_spaces) == set(AGENTS)
        for seed in range(2):  # a second reset: a new episode, new solvers, same env
            episode = MultiAgentEpisode(
                observation_space=env.observation_spaces, action_space=env.action_spaces
            )
            obs, infos = env.reset(seed=seed)
            episode.add_env_reset(observations=obs, infos=infos)
            steps = 0
            while not episode.is_done:
                actions = {agent: env.action_spaces[agent].sample() for agent in obs}
                obs, rewards, terminateds, truncateds, infos = env.step(actions)
                episode.add_env_step(
                    observations=obs,
                    actions=actions,
                    rewards=rewards,
                    infos=infos,
                    terminateds=terminateds,
                    truncateds=truncateds,
                )
                steps += 1
            assert steps == STEPS_PER_EPISODE
            assert terminateds == {"upstream": False, "downstream": False, "__all__": False}
            assert truncateds == {"__all__": True}
            assert episode.is_truncated and not episode.is_terminated
            for agent in AGENTS:
                single = episode.agent_episodes[agent]
                assert single.is_truncated and not single.is_terminated, agent
                assert len(single) == STEPS_PER_EPISODE
            assert env.agents == []
    finally:
        env.close()
    seen = watcher.stop()
    assert seen, "no process of the env was seen"
    assert not wait_gone(seen), "processes of the env outlived its close()"


def test_shared_and_per_agent_policies_and_what_the_creator_refuses(tmp_path):
    """One policy for both flaps, or one each: the RLModules RLlib builds for either.

    Cost: no episode runs (two envs built and closed): under a second.
    """
    env = MultiAgentEnvCreator(TwoFlapsFastEnv, double=True, run_root=str(tmp_path / "runs"))({})
    try:
        for setting, modules in (
            (shared_policy(), ["shared"]),
            (policy_per_agent(TwoFlapsFastEnv.agent_data), AGENTS),
        ):
            spec = PPOConfig().multi_agent(**setting).get_multi_rl_module_spec(env=env)
            assert sorted(spec.rl_module_specs) == sorted(modules)
            for module in spec.rl_module_specs.values():
                assert module.observation_space == env.observation_spaces["upstream"]
                assert module.action_space == env.action_spaces["upstream"]
    finally:
        env.close()
    shared = shared_policy("p")
    assert {shared["policy_mapping_fn"](agent, None) for agent in AGENTS} == {"p"}
    own = policy_per_agent(TwoFlapsFastEnv.agent_data)
    assert [own["policy_mapping_fn"](agent, None, worker=None) for agent in AGENTS] == AGENTS
    with pytest.raises(ValueError, match="agents"):
        policy_per_agent([])

    with pytest.raises(TypeError, match="register_env"):
        MultiAgentEnvCreator("gymprecice/TwoFlapsFast-v0")
    with pytest.raises(ValueError, match="run directory"):
        MultiAgentEnvCreator(TwoFlapsFastEnv, idx=0)
    with pytest.raises(TypeError, match="name"):
        register_multiagent_env(TwoFlapsFastEnv, "")
    # a single-agent env is refused, and closed: the index it claimed is free again
    case = write_case(tmp_path / "case", tmp_path / "faults")
    settings = {"options": str(case), "run_root": str((tmp_path / "runs").resolve())}
    with pytest.raises(TypeError, match="register_env"):
        MultiAgentEnvCreator(CylinderEnv, **settings)({})
    env = CylinderEnv(idx=None, **settings)
    try:
        assert env.env_index == 0
    finally:
        env.close()


def record_episode_end(*, episode, metrics_logger, **_) -> None:
    singles = list(episode.agent_episodes.values())
    metrics_logger.log_value("ma_truncated", int(episode.is_truncated), reduce="sum")
    metrics_logger.log_value("ma_terminated", int(episode.is_terminated), reduce="sum")
    metrics_logger.log_value(
        "agents_terminated", sum(int(s.is_terminated) for s in singles), reduce="sum"
    )
    metrics_logger.log_value(
        "agents_truncated", sum(int(s.is_truncated) for s in singles), reduce="sum"
    )
    metrics_logger.log_value("ma_episode_steps", len(episode), reduce="max")


@pytest.fixture
def local_ray():
    ray.init(address="local", num_cpus=RUNNERS, include_dashboard=False)
    yield
    ray.shutdown()


def test_ppo_shared_policy_trains_both_flaps_through_rllib_env_runners(local_ray, tmp_path):
    """RLlib's PPO, one policy mapped to both agents, one iteration on two env runners.

    Each runner builds its own two flaps' double (its own env index and run directory);
    the test checks that both agents' steps were sampled and trained, that every episode
    ended by truncation for every agent, and that no process of the envs outlives
    ``algo.stop()``.

    Cost: Ray's start (13-20 s), two runners built, each with RLlib's env check (a reset
    and a step: 25-45 s), then two episodes of three actions per runner, side by side
    (about 10 s): 50 to 90 s measured on 2 busy cores.
    """
    runs = (tmp_path / "runs").resolve()
    name = register_multiagent_env(
        TwoFlapsFastEnv, "gymprecice-test/two-flaps-double", double=True, run_root=str(runs)
    )
    # two episodes per runner, counted in env steps (each a step of both agents)
    batch = RUNNERS * STEPS_PER_EPISODE * 2
    config = (
        PPOConfig()
        .environment(name, env_config=SHORT)
        .env_runners(
            num_env_runners=RUNNERS,
            num_envs_per_env_runner=1,
            num_cpus_per_env_runner=0.5,
            sample_timeout_s=120,
        )
        .multi_agent(**shared_policy())
        .training(train_batch_size=batch, minibatch_size=batch, num_epochs=1)
        .callbacks(on_episode_end=record_episode_end)
        .debugging(seed=0)
    )
    watcher = ProcessWatcher(lambda: processes_under(runs), interval=0.1)
    algo = config.build_algo()
    try:
        result = algo.train()
    finally:
        algo.stop()
    seen = watcher.stop()

    runners = result["env_runners"]
    assert runners["num_env_steps_sampled_lifetime"] >= batch
    sampled = runners["num_agent_steps_sampled_lifetime"]
    assert set(sampled) == set(AGENTS) and all(sampled[a] >= batch for a in AGENTS)
    # every episode ended by truncation, for the env and for every agent
    episodes = runners["num_episodes"]
    assert episodes >= RUNNERS
    assert runners["ma_truncated"] == episodes and runners["ma_terminated"] == 0
    assert runners["agents_truncated"] == len(AGENTS) * episodes
    assert runners["agents_terminated"] == 0
    assert runners["ma_episode_steps"] == STEPS_PER_EPISODE
    learner = result["learners"]["shared"]
    assert learner["num_module_steps_trained"] > 0

    env_dirs = sorted(p.name for p in runs.glob("env_*") if p.is_dir())
    assert env_dirs == [f"env_{i}" for i in range(RUNNERS)]
    assert seen, "no process of the envs was seen while training"
    assert not wait_gone(seen), "processes of the envs outlived algo.stop()"
