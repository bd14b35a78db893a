"""The multi-agent env (PettingZoo ParallelEnv) on the preCICE double: API, bad input, semantics.

The env is :class:`gymprecice.testing.two_jets.TwoJetsEnv` on the chaos case (episode
runner, coupling worker, the double, a solver process that fails on request): agent
``upper`` drives jet1, ``lower`` drives jet2. Episodes are 5 steps of 2 windows.
"""

from __future__ import annotations

import functools
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test, parallel_seed_test, seed_test
from pettingzoo.utils.conversions import parallel_to_aec

from gymprecice.env.core import LIBRARY_ENV_VAR
from gymprecice.multiagent import JointEnv, MultiAgentAdapter
from gymprecice.plugin.errors import ConfigError, SolverError
from gymprecice.testing.chaos import inject, pid_alive, write_case
from gymprecice.testing.two_jets import TwoJetsEnv

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="the chaos case's solver runs on Linux"
)

PENALTY = -42.0
STEPS = 5


@pytest.fixture
def case(tmp_path, monkeypatch):
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")
    monkeypatch.delenv(LIBRARY_ENV_VAR, raising=False)
    root = write_case(
        tmp_path / "case",
        tmp_path / "faults",
        end_time=0.1,
        window=0.01,
        windows_per_step=2,
        timeouts={"progress": 4, "reset": 30, "kill_grace": 0.5},
        run_root=tmp_path / "runs",
    )
    _edit(root, lambda c: c["environment"].update(divergence_penalty=PENALTY))
    return root


def _edit(case: Path, edit) -> None:
    path = case / "gymprecice-config.json"
    config = json.loads(path.read_text())
    edit(config)
    path.write_text(json.dumps(config))


def _act(env, value=0.3) -> dict:
    return {agent: np.array([value], dtype=np.float32) for agent in env.agents}


def _processes(env) -> list[int]:
    session = env._gymprecice.run.session
    assert session is not None
    return [session.worker.pid, *(s.pid for s in session.solvers)]


class NoisyJets(TwoJetsEnv):
    """Sensor noise from the env's generator: observations depend on reset(seed=...)."""

    def _get_observations(self, read_data, read_var_list):
        obs = super()._get_observations(read_data, read_var_list)
        return {
            a: o + self.np_random.normal(0, 0.1, o.shape).astype(np.float32) for a, o in obs.items()
        }


# -- the PettingZoo API tests ---------------------------------------------------------------


def test_parallel_api_test_passes_on_the_double(case):
    env = TwoJetsEnv(str(case), 0)
    try:
        parallel_api_test(env, num_cycles=3 * STEPS)
        assert env.possible_agents == ["upper", "lower"]
    finally:
        env.close()


def test_seed_tests_pass_and_the_seed_matters(case, tmp_path):
    made = iter(range(100))

    def make():
        # two identical envs: the same index (it is in the info), each its own run root;
        # no drag from the solver's output file: how far the solver has written it when
        # the controller reads is a race, the coupling data are not
        return NoisyJets(str(case), 0, read_outputs=False, run_root=tmp_path / f"runs-{next(made)}")

    seed_test(lambda: parallel_to_aec(make()), num_cycles=STEPS)
    parallel_seed_test(make, num_cycles=STEPS)
    env = make()
    try:
        first = env.reset(seed=1)[0]["upper"]
        again = env.reset(seed=1)[0]["upper"]
        other = env.reset(seed=2)[0]["upper"]
        assert np.array_equal(first, again) and not np.array_equal(first, other)
    finally:
        env.close()


# -- semantics -------------------------------------------------------------------------------


def test_the_end_time_truncates_every_agent(case):
    env = TwoJetsEnv(str(case), 0)
    try:
        obs, infos = env.reset(seed=0)
        assert set(obs) == set(infos) == {"upper", "lower"}
        for step in range(STEPS):
            obs, rewards, terms, truncs, infos = env.step(_act(env))
            last = step == STEPS - 1
            assert terms == {"upper": False, "lower": False}
            assert truncs == {"upper": last, "lower": last}
            assert rewards["upper"] == rewards["lower"] <= 0  # minus the drag, 0 before a row
            assert infos["upper"]["time"] == pytest.approx(0.02 * (step + 1))
        assert env.agents == []
        with pytest.raises(Exception, match="reset"):
            env.step({})
    finally:
        env.close()


def test_one_agents_termination_leaves_the_other_going_and_holds_its_actuator(case):
    class EarlyUpper(TwoJetsEnv):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.written: list[tuple[str, float]] = []

        def _get_agent_action(self, agent, action, write_var_list):
            self.written.append((agent, float(action[0])))
            return super()._get_agent_action(agent, action, write_var_list)

        def _get_terminations(self):
            return {"upper": self.time >= 0.04 - 1e-9}

    env = EarlyUpper(str(case), 0)
    try:
        env.reset(seed=0)
        env.step({"upper": np.array([0.5]), "lower": np.array([0.1])})
        _, rewards, terms, truncs, _ = env.step(
            {"upper": np.array([0.7]), "lower": np.array([0.1])}
        )
        assert terms == {"upper": True, "lower": False} and not any(truncs.values())
        assert env.agents == ["lower"]
        env.written.clear()
        _, rewards, terms, truncs, _ = env.step({"lower": np.array([-0.2])})
        assert set(rewards) == {"lower"} and terms == {"lower": False}
        # the terminated agent's actuator holds its last action in every window
        assert [v for a, v in env.written if a == "upper"] == [pytest.approx(0.7)] * 2
        assert [v for a, v in env.written if a == "lower"] == [pytest.approx(-0.2)] * 2
        with pytest.raises(ValueError, match=r"action\(s\) for agent\(s\) \['upper'\], done"):
            env.step({"upper": np.array([0.0]), "lower": np.array([0.0])})
        while env.agents:
            _, _, terms, truncs, _ = env.step({"lower": np.array([0.0])})
        assert truncs == {"lower": True} and terms == {"lower": False}
    finally:
        env.close()


def test_when_every_agent_has_terminated_the_simulation_stops(case):
    class Both(TwoJetsEnv):
        def _get_terminations(self):
            return {"upper": self.time >= 0.02 - 1e-9, "lower": self.time >= 0.06 - 1e-9}

    env = Both(str(case), 0)
    try:
        env.reset(seed=0)
        pids = _processes(env)
        assert env.step(_act(env))[2] == {"upper": True, "lower": False}
        assert env.step(_act(env))[2] == {"lower": False}
        _, _, terms, truncs, _ = env.step(_act(env))
        assert terms == {"lower": True} and truncs == {"lower": False} and env.agents == []
        assert env._gymprecice.run.session is None and not any(pid_alive(p) for p in pids)
    finally:
        env.close()


def test_divergence_terminates_every_agent_with_the_penalty(case, tmp_path):
    inject(tmp_path / "faults", 0, "run", "diverge", window=3)
    env = TwoJetsEnv(str(case), 0)
    try:
        first, _ = env.reset(seed=0)
        env.step(_act(env))
        obs, rewards, terms, truncs, infos = env.step(_act(env))
        assert rewards == {"upper": PENALTY, "lower": PENALTY}
        assert terms == {"upper": True, "lower": True}
        assert truncs == {"upper": False, "lower": False}
        assert infos["upper"]["diverged"]["solver"] == "fluid"
        assert obs["lower"].shape == first["lower"].shape and env.agents == []
        env.reset()
        steps = 0
        while env.agents:
            _, _, terms, _, infos = env.step(_act(env))
            assert not any(terms.values()) and "diverged" not in infos["upper"]
            steps += 1
        assert steps == STEPS
    finally:
        env.close()


def test_a_solver_killed_mid_episode_is_reported_and_reset_recovers(case, tmp_path):
    inject(tmp_path / "faults", 0, "run", "kill", window=3)
    env = TwoJetsEnv(str(case), 0)
    try:
        env.reset(seed=0)
        pids = _processes(env)
        env.step(_act(env))
        with pytest.raises(SolverError, match="fluid"):
            env.step(_act(env))
        assert env.agents == []
        assert not any(pid_alive(p) for p in pids), "the killed episode left processes running"
        env.reset()
        pids = _processes(env)
        steps = 0
        while env.agents:
            env.step(_act(env))
            steps += 1
        assert steps == STEPS
    finally:
        env.close()
    assert not any(pid_alive(p) for p in pids)


@pytest.mark.slow  # worker processes (forkserver), or torch and PPO
def test_a_solver_killed_in_a_vector_env_costs_one_failure_and_the_run_goes_on(case, tmp_path):
    pytest.importorskip("stable_baselines3")
    from gymprecice.learners.sb3 import ResilientSubprocVecEnv
    from gymprecice.multiagent.sb3 import SharedPolicyVecEnv

    inject(tmp_path / "faults", 1, "run", "kill", window=3)
    fns = [functools.partial(_joint, str(case), i) for i in range(2)]
    venv = SharedPolicyVecEnv(
        ResilientSubprocVecEnv(fns, step_timeout=20, reset_timeout=60, close_timeout=10)
    )
    try:
        assert venv.num_envs == 4 and venv.observation_space.shape == (4,)
        obs = venv.reset()
        assert obs.shape == (4, 4)
        venv.step(np.full((4, 1), 0.3, dtype=np.float32))
        obs, rewards, dones, infos = venv.step(np.full((4, 1), 0.3, dtype=np.float32))
        assert dones.tolist() == [False, False, True, True]  # both agents of env 1
        assert all(infos[k]["TimeLimit.truncated"] and "failure" in infos[k] for k in (2, 3))
        assert rewards[2] == rewards[3] == 0.0 and rewards[0] == rewards[1] <= 0
        assert infos[2]["terminal_observation"].shape == (4,)
        assert [f.env_index for f in venv.venv.failures] == [1]
        for _ in range(STEPS):
            obs, rewards, dones, infos = venv.step(np.zeros((4, 1), dtype=np.float32))
        assert len(venv.venv.failures) == 1 and dones.any()
    finally:
        venv.close()


@pytest.mark.slow  # worker processes (forkserver), or torch and PPO
def test_a_shared_policy_trains_with_ppo(case):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from gymprecice.multiagent.sb3 import SharedPolicyVecEnv

    venv = SharedPolicyVecEnv(DummyVecEnv([functools.partial(_joint, str(case), 0)]))
    try:
        model = PPO("MlpPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, seed=0, device="cpu")
        model.learn(16)
        assert model.num_timesteps == 16  # 8 steps of 2 agents
        action, _ = model.predict(venv.reset(), deterministic=True)
        assert action.shape == (2, 1)
        # beneath the slots, as beneath a VecEnvWrapper: the vector env of joint envs
        assert isinstance(venv.unwrapped, DummyVecEnv)
        assert isinstance(venv.unwrapped.envs[0], JointEnv)
    finally:
        venv.close()


def _joint(case: str, idx: int) -> JointEnv:
    return JointEnv(TwoJetsEnv(case, idx))


def test_joint_env_stacks_the_agents(case):
    env = _joint(str(case), 0)
    try:
        obs, info = env.reset(seed=0)
        assert obs.shape == (2, 4) and env.action_space.shape == (2, 1)
        obs, reward, terminated, truncated, info = env.step(np.array([[0.3], [0.3]]))
        assert not (terminated or truncated) and obs.shape == (2, 4)
        assert reward == pytest.approx(info["agent_rewards"].mean())
        assert info["agent_terminated"].tolist() == [False, False]
    finally:
        env.close()


# -- bad input ---------------------------------------------------------------------------------


def _env_with(case, agent_data, **attrs):
    cls = type("Custom", (TwoJetsEnv,), {"agent_data": agent_data, **attrs})
    return cls(str(case), 0)


def test_an_agent_claiming_data_the_controller_does_not_write(case):
    with pytest.raises(ConfigError) as err:
        _env_with(case, {"upper": ["Heat-jet1"], "lower": ["jet2"]})
    message = str(err.value)
    assert "Custom.agent_data['upper'] claims 'Heat-jet1'" in message
    assert str(case / "gymprecice-config.json") in message
    assert str(case / "precice-config.xml") in message and "<write-data" in message
    assert "['Velocity-jet1', 'Velocity-jet2']" in message


def test_an_agent_claiming_data_the_xml_allows_but_the_json_does_not_name(case):
    _edit(case, lambda c: c["controller"].update(write_to={"jet1": "Velocity"}))
    with pytest.raises(ConfigError) as err:
        _env_with(case, {"upper": ["jet1"], "lower": ["Velocity-jet2"]})
    message = str(err.value)
    assert "claims 'Velocity-jet2', which the controller does not write" in message
    assert "'Velocity' on mesh 'Controller-Mesh-jet2'" in message
    assert "add its interface to controller.write_to" in message


def test_two_agents_claiming_the_same_data(case):
    with pytest.raises(ConfigError, match=r"agents 'upper' and 'lower' both claim 'Velocity-jet1'"):
        _env_with(case, {"upper": ["jet1", "jet2"], "lower": ["Velocity-jet1"]})


def test_write_data_no_agent_claims(case):
    with pytest.raises(ConfigError, match=r"writes \['Velocity-jet2'\].*no agent claims it"):
        _env_with(case, {"upper": ["jet1"]})


def test_no_agents(case):
    with pytest.raises(ConfigError, match="declares no agent"):
        _env_with(case, {})


@pytest.mark.parametrize(
    ("actions", "expected"),
    [
        ({"upper": [0.1]}, r"no action for agent\(s\) \['lower'\]"),
        ({"upper": [0.1], "lower": [0.1], "middle": [0.1]}, r"unknown agent\(s\) \['middle'\]"),
        ({"upper": [0.1], "lower": [0.1, 0.2]}, r"agent 'lower' has shape \(2,\)"),
        ({"upper": [np.nan], "lower": [0.1]}, r"agent\(s\) \['upper'\] is not finite"),
        ([0.1, 0.1], "takes a dict"),
    ],
)
def test_a_bad_action_dict_is_refused_and_the_episode_goes_on(case, actions, expected):
    env = TwoJetsEnv(str(case), 0)
    try:
        env.reset(seed=0)
        with pytest.raises((ValueError, TypeError), match=expected):
            env.step(actions)
        assert env.agents == ["upper", "lower"]
        env.step(_act(env))  # nothing was sent to the solvers
    finally:
        env.close()


def test_an_observation_that_does_not_fit_its_space_is_refused_and_nothing_runs(case):
    class Short(TwoJetsEnv):
        def _get_observations(self, read_data, read_var_list):
            return {
                a: o[:3] for a, o in super()._get_observations(read_data, read_var_list).items()
            }

    env = Short(str(case), 0)
    try:
        with pytest.raises(ValueError) as err:
            env.reset(seed=0)
        assert "agent 'upper' an observation of shape (3,)" in str(err.value)
        assert "observation_spaces['upper']" in str(err.value)
        assert env._gymprecice.run.session is None and env.agents == []
    finally:
        env.close()


def test_rewards_missing_an_agent_end_the_episode(case):
    class Selfish(TwoJetsEnv):
        def _get_rewards(self):
            return {"upper": -1.0, "middle": 0.0}

    env = Selfish(str(case), 0)
    try:
        env.reset(seed=0)
        pids = _processes(env)
        with pytest.raises(KeyError, match=r"none for live agent\(s\) \['lower'\]; unknown"):
            env.step(_act(env))
        assert env.agents == [] and not any(pid_alive(p) for p in pids)
    finally:
        env.close()


def test_an_agent_writing_another_agents_data(case):
    class Meddling(TwoJetsEnv):
        def _get_agent_action(self, agent, action, write_var_list):
            out = dict(super()._get_agent_action(agent, action, write_var_list))
            if agent == "upper":
                out["Velocity-jet2"] = np.zeros((8, 2))
            return out

    env = Meddling(str(case), 0)
    try:
        with pytest.raises(KeyError, match=r"returned 'Velocity-jet2', which is agent 'lower'"):
            env.reset(seed=0)
    finally:
        env.close()


def test_missing_or_non_box_spaces(case):
    import gymnasium as gym

    class NoSpaces(TwoJetsEnv):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            del self.action_spaces["lower"]

    env = NoSpaces(str(case), 0)
    try:
        with pytest.raises(ConfigError, match=r"sets no action_spaces\['lower'\]"):
            env.reset(seed=0)
        env.action_spaces["lower"] = gym.spaces.Discrete(3)
        with pytest.raises(ConfigError, match=r"acts through a Box"):
            env.reset(seed=0)
    finally:
        env.close()


def test_the_divergence_penalty_is_the_env_classs_without_a_configured_one(case):
    _edit(case, lambda c: c["environment"].pop("divergence_penalty"))
    env = _env_with(case, TwoJetsEnv.agent_data, divergence_penalty=-7.0)
    try:
        assert env._gymprecice.guards.penalty == -7.0
    finally:
        env.close()


def test_dropping_the_env_ends_its_episode_and_frees_its_index(case):
    """The env's view holds the env weakly: nothing keeps a dropped env (and its solvers)."""
    env = TwoJetsEnv(str(case), None)
    assert env.env_index == 0
    env.reset(seed=0)
    pids = _processes(env)
    assert all(pid_alive(p) for p in pids)
    del env
    assert not any(pid_alive(p) for p in pids)
    again = TwoJetsEnv(str(case), None)
    try:
        assert again.env_index == 0  # the dropped env's claim was released
    finally:
        again.close()


def test_a_subclass_s_own_names_do_not_break_core(case):
    """Names the multi-agent env once used for itself are the subclass's to use."""

    class Busy(TwoJetsEnv):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self._engine, self._slots, self._held, self._agent_refs = "mine", {}, None, ()

        def _joint(self, *args):  # once methods of the env's machinery
            raise AssertionError("core called the env's own _joint")

        _layout = _who = _check_observations = _checked_rewards = _agent_writes = _joint

    env = Busy(str(case), 0)
    try:
        env.reset(seed=0)
        *_, infos = env.step(_act(env))
        assert infos["upper"]["time_window"] == 2 and env._engine == "mine"
    finally:
        env.close()


def test_without_pettingzoo_the_error_names_the_extra():
    code = (
        "import sys; sys.modules['pettingzoo'] = None\n"
        "try:\n    import gymprecice.multiagent\n"
        "except ModuleNotFoundError as exc:\n    print(exc)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    message = proc.stdout.strip().splitlines()[-1]
    assert message.startswith("gymprecice.multiagent needs pettingzoo, which is not installed")
    assert "pip install '" in message
    # the extra that brings it, which the message names once the package's metadata has it
    pyproject = (Path(__file__).parents[1] / "pyproject.toml").read_text()
    assert re.search(r'^multiagent = \["pettingzoo>=', pyproject, re.M)


def test_it_is_a_parallel_env():
    from pettingzoo import ParallelEnv

    assert issubclass(MultiAgentAdapter, ParallelEnv)
