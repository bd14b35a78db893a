"""A subclass of the Adapter shares its namespace: it finds the user methods and the documented
API there, and nothing of core's machinery that one of its own names could clash with."""

from __future__ import annotations

import gc
import os
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.core import Adapter

STUBS = Path(__file__).parent / "stubs"
TICKER = "import time\nfor i in range(100000):\n    print('step', i, flush=True); time.sleep(0.05)"

#: what a subclass overrides (the Gym-preCICE paper's methods, the render overlay)
USER_METHODS = {
    "_get_action",
    "_get_observation",
    "_get_reward",
    "_get_terminated",
    "_initial_action",
    "_close_external_resources",
    "_render_overlay",
}
#: the documented API beyond gymnasium.Env's (``_set_precice_vectices``: the paper's spelling)
DOCUMENTED = {
    "divergence_penalty",
    "render_fields",
    "render_size",
    "env_dir",
    "run_dir",
    "solver_dirs",
    "write_var_list",
    "read_var_list",
    "interface_geometry",
    "set_interface_vertices",
    "_set_precice_vectices",
    "open_output",
}
#: what an instance holds beyond gymnasium.Env's: documented state, and core's one handle
INSTANCE = {
    "config",
    "env_index",
    "time",
    "time_window",
    "dt",
    "end_time",
    "last_action",
    "render_mode",
    "_gymprecice",
}


@pytest.fixture(autouse=True)
def stub_precice(monkeypatch, tmp_path):
    monkeypatch.setenv("PYTHONPATH", f"{STUBS}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    monkeypatch.setenv("GYMPRECICE_PRECICE_LIBRARY", "stub_precice")
    monkeypatch.setenv("STUB_PRECICE_LOG", str(tmp_path / "writes.log"))


class JetEnv(Adapter):
    def __init__(self, options, idx=None, **kwargs):
        super().__init__(options, idx, **kwargs)
        self.set_interface_vertices("jet1", [[0.0, 1.0], [0.0, 2.0]])
        self.set_interface_vertices("jet2", [[1.0, 1.0]])
        self.set_interface_vertices("probe", [[5.0, 0.0], [6.0, 0.0], [7.0, 0.0]])
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(3,), dtype=np.float32)

    def _get_action(self, action, write_var_list):
        a = float(np.asarray(action).ravel()[0])
        return {"Velocity-jet1": np.full((2, 2), a), "jet2": [[a, -a]]}

    def _get_observation(self, read_data, read_var_list):
        return np.asarray(read_data["probe"], dtype=np.float32)

    def _get_reward(self):
        return -self.time


def _case(make_case, base_config, tmp_path):
    config = base_config()
    config["physics_simulation_engine"]["solvers"]["fluid"]["options"]["argv"] = [
        "{python}",
        "-c",
        TICKER,
    ]
    config["timeouts"] = {"progress": 3, "kill_grace": 0.5, "finalize": 2}
    return make_case(tmp_path / "case", config)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_the_class_holds_the_user_methods_and_the_documented_api_only():
    shared = set(dir(Adapter)) - set(dir(gym.Env))
    assert shared - USER_METHODS - DOCUMENTED == set(), "core machinery in a subclass's namespace"
    assert shared >= USER_METHODS | DOCUMENTED


def test_an_env_holds_its_documented_state_and_core_s_one_handle(make_case, base_config, tmp_path):
    env = JetEnv(_case(make_case, base_config, tmp_path), 0, run_root=tmp_path / "runs")
    try:
        env.reset(seed=0)
        env.step(np.array([0.5], dtype=np.float32))
        gym_own = {"_np_random", "_np_random_seed", "action_space", "observation_space"}
        assert set(vars(env)) - gym_own == INSTANCE
    finally:
        env.close()


def test_a_subclass_s_own_names_do_not_break_core(make_case, base_config, tmp_path):
    """Names core once used for itself are the env's to use."""

    class Busy(JetEnv):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self._session, self._steps, self._schedule, self._info = "mine", -1, [], {}

        def _observed(self):  # once a method of core's
            raise AssertionError("core called the env's own _observed")

    env = Busy(_case(make_case, base_config, tmp_path), 0, run_root=tmp_path / "runs")
    try:
        env.reset(seed=0)
        *_, info = env.step(np.array([0.5], dtype=np.float32))
        assert info["time_window"] == 1 and env._session == "mine" and env._steps == -1
    finally:
        env.close()


def test_dropping_an_env_ends_its_episode_and_frees_its_index(make_case, base_config, tmp_path):
    case = _case(make_case, base_config, tmp_path)
    env = JetEnv(case, run_root=tmp_path / "runs")
    assert env.env_index == 0
    env.reset(seed=0)
    session = env._gymprecice.run.session
    pids = [p.pid for p in session.solvers] + [session.worker.pid]
    assert all(_alive(pid) for pid in pids)
    del env, session
    gc.collect()
    assert not any(_alive(pid) for pid in pids)
    again = JetEnv(case, run_root=tmp_path / "runs")
    try:
        assert again.env_index == 0  # the dropped env's claim was released
    finally:
        again.close()
