"""The Adapter's own logic against a partner-less preCICE stub and real solver processes."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.core import Adapter
from gymprecice.plugin.errors import ConfigError, SolverCrashedError, SolverTimeoutError

STUBS = Path(__file__).parent / "stubs"
TICKER = "import time\nfor i in range(100000):\n    print('step', i, flush=True); time.sleep(0.05)"


@pytest.fixture(autouse=True)
def stub_precice(monkeypatch, tmp_path):
    monkeypatch.setenv("PYTHONPATH", f"{STUBS}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    monkeypatch.setenv("GYMPRECICE_PRECICE_LIBRARY", "stub_precice")
    monkeypatch.setenv("STUB_PRECICE_LOG", str(tmp_path / "writes.log"))


class JetEnv(Adapter):
    def __init__(self, options, idx=0, **kwargs):
        super().__init__(options, idx, **kwargs)
        self.set_interface_vertices("jet1", [[0.0, 1.0], [0.0, 2.0]])
        self.set_interface_vertices("jet2", [[1.0, 1.0]])
        self.set_interface_vertices("probe", [[5.0, 0.0], [6.0, 0.0], [7.0, 0.0]])
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(3,), dtype=np.float32)
        self.closed_resources = 0

    def _get_action(self, action, write_var_list):
        a = float(np.asarray(action).ravel()[0])
        return {"Velocity-jet1": np.full((2, 2), a), "jet2": [[a, -a]]}

    def _get_observation(self, read_data, read_var_list):
        return np.asarray(read_data["probe"], dtype=np.float32)

    def _get_reward(self):
        return -self.time

    def _close_external_resources(self):
        self.closed_resources += 1


def _case(make_case, base_config, tmp_path, argv=None, **overrides):
    config = base_config(**overrides)
    config["physics_simulation_engine"]["solvers"]["fluid"]["options"]["argv"] = argv or [
        "{python}",
        "-c",
        TICKER,
    ]
    config.setdefault("timeouts", {}).update({"progress": 3, "kill_grace": 0.5, "finalize": 2})
    return make_case(tmp_path / "case", config)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_episode_runs_to_max_time_and_truncates(make_case, base_config, tmp_path):
    case = _case(make_case, base_config, tmp_path, actions={"windows": 3, "scheme": "ramp"})
    env = JetEnv(case, 0, run_root=tmp_path / "runs")
    obs, info = env.reset(seed=1)
    assert obs.shape == (3,) and info["time"] == 0.0
    rewards, truncated, steps = [], False, 0
    while not truncated:
        obs, reward, terminated, truncated, info = env.step(np.array([0.9]))
        assert terminated is False
        steps += 1
        rewards.append(reward)
    # max-time 0.01 with 0.001 windows, 3 windows per step: 3 + 3 + 3 + 1 windows
    assert steps == 4
    assert info["time"] == pytest.approx(0.01) and info["time_window"] == 10
    assert np.allclose(obs, 0.01)
    assert set(info["timing"]) >= {"precice_s", "wait_s", "env_s", "step_s"}
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.array([0.0]))
    env.close()
    writes = (tmp_path / "writes.log").read_text().splitlines()
    jet2 = [line for line in writes if "Controller-Mesh-jet2" in line]
    # initial data (zeros) then a ramp 0.3, 0.6, 0.9, 0.9, ...
    assert jet2[0].endswith("[0.0, -0.0]")
    assert jet2[1].split(" ", 3)[3] == str([0.3, -0.3]) or np.allclose(
        eval(jet2[1].split(" ", 3)[3]), [0.3, -0.3]
    )


def test_reset_mid_episode_and_close_leave_nothing_running(make_case, base_config, tmp_path):
    case = _case(make_case, base_config, tmp_path)
    env = JetEnv(case, 0, run_root=tmp_path / "runs")
    env.reset(seed=0)
    session = env._gymprecice.run.session
    first = [p.pid for p in session.solvers] + [session.worker.pid]
    env.step(env.action_space.sample())
    env.reset()
    session = env._gymprecice.run.session
    second = [p.pid for p in session.solvers] + [session.worker.pid]
    assert not any(_alive(pid) for pid in first)
    env.close()
    env.close()  # idempotent
    assert not any(_alive(pid) for pid in second)
    assert env.closed_resources >= 2
    assert (env.run_dir / ".gymprecice" / "pids").read_text().strip() == ""


def test_solver_exiting_1_mid_episode_is_reported_with_log_tail(
    make_case, base_config, tmp_path, monkeypatch
):
    monkeypatch.setenv("STUB_PRECICE_BLOCK_AT", "1")
    go = tmp_path / "go"
    crash = (
        "import os, sys, time\n"
        f"while not os.path.exists({str(go)!r}): time.sleep(0.01)\n"
        "print('solver says: divergence detected', flush=True)\nsys.exit(1)"
    )
    case = _case(make_case, base_config, tmp_path, argv=["{python}", "-c", crash])
    env = JetEnv(case, 3, run_root=tmp_path / "runs")
    env.reset()
    env.step(np.array([0.1]))
    go.touch()  # the solver dies mid-episode, while the next advance blocks
    started = time.monotonic()
    with pytest.raises(SolverCrashedError) as info:
        env.step(np.array([0.1]))
    assert time.monotonic() - started < 5
    err = info.value
    assert err.env_index == 3 and err.solver == "fluid" and err.returncode == 1
    assert "divergence detected" in err.log_tail and "divergence detected" in str(err)
    assert not env._gymprecice.active
    monkeypatch.setenv("STUB_PRECICE_BLOCK_AT", "-1")
    go.unlink()
    env.reset()  # the next reset starts clean
    env.step(np.array([0.1]))
    env.close()


def test_hung_solver_is_killed_after_the_progress_timeout(
    make_case, base_config, tmp_path, monkeypatch
):
    monkeypatch.setenv("STUB_PRECICE_BLOCK_AT", "1")
    silent = "import time\ntime.sleep(1000)"
    case = _case(make_case, base_config, tmp_path, argv=["{python}", "-c", silent])
    env = JetEnv(case, 0, run_root=tmp_path / "runs")
    env.reset()
    env.step(np.array([0.0]))
    session = env._gymprecice.run.session
    pids = [p.pid for p in session.solvers] + [session.worker.pid]
    started = time.monotonic()
    with pytest.raises(SolverTimeoutError, match="no progress for 3 s"):
        env.step(np.array([0.0]))
    assert 2.5 < time.monotonic() - started < 20
    assert not any(_alive(pid) for pid in pids)
    env.close()


def test_solver_exiting_at_start_fails_the_reset(make_case, base_config, tmp_path, monkeypatch):
    monkeypatch.setenv("STUB_PRECICE_BLOCK_AT", "init")
    case = _case(
        make_case,
        base_config,
        tmp_path,
        argv=["{python}", "-c", "import sys; sys.exit('no mesh found')"],
    )
    env = JetEnv(case, 0, run_root=tmp_path / "runs")
    with pytest.raises(SolverCrashedError, match="exited with status 1") as info:
        env.reset()
    assert "no mesh found" in info.value.log_tail
    env.close()


def test_wrong_action_shape_is_a_clear_error(make_case, base_config, tmp_path):
    case = _case(make_case, base_config, tmp_path)

    class Bad(JetEnv):
        def _get_action(self, action, write_var_list):
            return {"jet1": np.zeros(5), "jet2": np.zeros((1, 2))}

    env = Bad(case, 0, run_root=tmp_path / "runs")
    with pytest.raises(ValueError, match=r"Velocity-jet1 with shape \(5,\); expected \(2, 2\)"):
        env.reset()
    env.close()


def test_interfaces_without_vertices_say_how_to_set_them(make_case, base_config, tmp_path):
    case = _case(make_case, base_config, tmp_path)

    class NoGeometry(JetEnv):
        def __init__(self, options, idx=0, **kwargs):
            Adapter.__init__(self, options, idx, **kwargs)
            self.closed_resources = 0
            self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    env = NoGeometry(case, 0, run_root=tmp_path / "runs")
    with pytest.raises(ConfigError, match=r"set_interface_vertices\('jet1'"):
        env.reset()
    env.close()


def test_missing_pyprecice_says_what_to_install(make_case, base_config, tmp_path, monkeypatch):
    from gymprecice.plugin.errors import PreciceNotInstalledError

    monkeypatch.setenv("GYMPRECICE_PRECICE_LIBRARY", "precice_that_is_not_installed")
    case = _case(make_case, base_config, tmp_path)
    env = JetEnv(case, 0, run_root=tmp_path / "runs")
    with pytest.raises(PreciceNotInstalledError, match=r"gymprecice-core\[precice\]"):
        env.reset()
    env.close()


def test_seeding_is_reproducible(make_case, base_config, tmp_path):
    case = _case(make_case, base_config, tmp_path)
    env = JetEnv(case, 0, run_root=tmp_path / "runs")
    env.reset(seed=42)
    a = env.np_random.random()
    env.reset(seed=42)
    assert env.np_random.random() == a
    env.close()
    assert sys.executable


def test_open_output_gives_one_reader_per_episode_and_closes_it(make_case, base_config, tmp_path):
    from gymprecice.plugin.hookspecs import hookimpl
    from gymprecice.plugin.manager import temporary_plugin

    class Reader:
        closed = False

        def read_new(self):
            return []

        def close(self):
            self.closed = True

    class Outputs:
        @hookimpl
        def gymprecice_open_output(self, solver, name, options):
            return Reader() if name == "probes" else None

    case = _case(make_case, base_config, tmp_path)
    with temporary_plugin(Outputs(), "outputs"):
        env = JetEnv(case, 0, run_root=tmp_path / "runs")
        env.reset()
        first = env.open_output("fluid", "probes", field="p")
        assert env.open_output("fluid", "probes", field="p") is first
        assert env.open_output("fluid", "probes", field="U") is not first
        with pytest.raises(ConfigError, match="no installed plugin opens output 'forces'"):
            env.open_output("fluid", "forces")
        env.reset()
        assert first.closed
        assert env.open_output("fluid", "probes", field="p") is not first
        env.close()


def test_waiting_for_solver_output_is_timed_as_solver_time() -> None:
    """Readers from open_output report their waits, which steps count as wait_s."""
    import time as _time

    from gymprecice.env.timed_reader import TimedReader

    class Reader:
        start_time = 8.0

        def wait_until(self, t: float, timeout: float) -> str:
            _time.sleep(0.05)
            return f"rows to {t}"

        def read_new(self) -> str:
            return "new"

    clock = [0.0]
    reader = TimedReader(Reader(), clock)
    assert reader.wait_until(1.0, timeout=2.0) == "rows to 1.0"
    assert reader.read_new() == "new" and reader.start_time == 8.0
    assert clock[0] >= 0.05
    before = clock[0]
    reader.read_new()
    assert clock[0] == before  # only waiting counts


def test_a_solver_that_dies_while_its_output_is_awaited_ends_the_wait_at_once() -> None:
    """A watch-point wait looks at the solvers between slices: a dead solver's error comes
    within a slice, not after the reader's whole timeout; with every solver alive, the
    reader's own timeout error comes at its timeout."""
    import time as _time

    from gymprecice.env.timed_reader import OUTPUT_WAIT_SLICE_S, TimedReader
    from gymprecice.plugin.errors import SolverCrashedError

    class NeverReady:
        def wait_until(self, t: float, timeout: float) -> str:
            _time.sleep(timeout)
            raise TimeoutError(f"no row for time {t} within {timeout} s")

    looks = []

    def dies_on_second_look() -> None:
        looks.append(_time.monotonic())
        if len(looks) == 2:
            raise SolverCrashedError("env 0: solver 'solid' was killed by SIGKILL")

    started = _time.monotonic()
    reader = TimedReader(NeverReady(), [0.0], dies_on_second_look)
    with pytest.raises(SolverCrashedError, match="'solid' was killed"):
        reader.wait_until(1.0, timeout=120.0)
    assert _time.monotonic() - started < 4 * OUTPUT_WAIT_SLICE_S

    reader = TimedReader(NeverReady(), [0.0], lambda: None)
    started = _time.monotonic()
    with pytest.raises(TimeoutError, match=r"no row for time 1\.0"):
        reader.wait_until(1.0, timeout=1.2)
    assert 1.1 < _time.monotonic() - started < 2.0


def test_of_two_dead_solvers_the_cause_is_named_not_the_partner_precice_aborted() -> None:
    """A solid killed from outside makes preCICE abort the fluid a moment later; when the
    env looks at both dead, the solid is the culprit."""
    import signal

    from gymprecice.env.coupling import PARTNER_LOST, _culprit_first

    class Dead:
        def __init__(self, name: str, status: int, log: str) -> None:
            self.name, self._status, self._log = name, status, log

        def poll(self) -> int:
            return self._status

        def log_tail(self, lines: int = 30) -> str:
            return self._log

    aborted = Dead("fluid", -signal.SIGABRT, f"ERROR: Receiving data failed. {PARTNER_LOST}")
    killed = Dead("solid", -signal.SIGKILL, "")
    crashed = Dead("solid", 1, "FOAM FATAL ERROR")
    assert [s.name for s in _culprit_first([aborted, killed])] == ["solid", "fluid"]
    assert [s.name for s in _culprit_first([aborted, crashed])] == ["solid", "fluid"]
    assert [s.name for s in _culprit_first([crashed, aborted])] == ["solid", "fluid"]


def test_info_time_is_shown_to_the_time_window_s_precision() -> None:
    """info["time"] shows 2.0, not 2.0000000000000013 (adding windows leaves noise)."""
    from gymprecice.env.episode import shown_time

    noisy = sum([0.01] * 200)
    assert noisy != 2.0 and shown_time(noisy, 0.01) == 2.0
    assert shown_time(sum([0.1] * 3), 0.1) == 0.3
    # a millionth of the window is kept: distinct windows never merge
    assert shown_time(1e-9 * 3, 1e-9) == pytest.approx(3e-9, rel=1e-6) and shown_time(
        1e-9 * 3, 1e-9
    ) != shown_time(1e-9 * 4, 1e-9)
    assert shown_time(1.0 / 3.0, 1.0 / 3.0) == pytest.approx(1.0 / 3.0, abs=1e-6)
    assert shown_time(0.5, None) == 0.5
