"""The Adapter coupled to a real partner process, through the test double and real preCICE.

The same scenarios run against ``gymprecice.testing.fake_precice`` everywhere and against
real pyprecice where it is installed (marker ``precice``; skipped with the reason
elsewhere), so the double's faithfulness is checked whenever the real library is present.
"""

from __future__ import annotations

import importlib.util
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.core import Adapter
from gymprecice.plugin.errors import SolverCrashedError, SolverTimeoutError
from gymprecice.testing import case_config
from gymprecice.testing.flows import place_jets

DOUBLE = "gymprecice.testing.fake_precice"


def _real_precice_importable() -> bool:
    if importlib.util.find_spec("precice") is None:
        return False
    # pyprecice imports the preCICE C++ library: check in a child so a broken install
    # (library not found) skips instead of crashing the test process.
    probe = subprocess.run([sys.executable, "-c", "import precice"], capture_output=True)
    return probe.returncode == 0


LIBRARIES = [
    pytest.param(DOUBLE, id="double"),
    pytest.param(
        "precice",
        id="real-precice",
        marks=[
            pytest.mark.precice,
            pytest.mark.skipif(
                not _real_precice_importable(),
                reason="pyprecice / the preCICE library is not installed",
            ),
        ],
    ),
]


class FakeCylinderEnv(Adapter):
    """Two jets write velocities; the cylinder's pressure is read by direct mesh access."""

    def __init__(self, options, idx=0, **kwargs):
        super().__init__(options, idx, **kwargs)
        place_jets(self)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(32,), dtype=np.float32)

    def _get_action(self, action, write_var_list):
        q = float(np.asarray(action).ravel()[0])
        jets = {}
        for name, sign in (("jet1", 1.0), ("jet2", -1.0)):
            n = len(self.interface_geometry[name].coordinates)
            jets[name] = np.tile([0.0, sign * q], (n, 1))
        return jets

    def _get_observation(self, read_data, read_var_list):
        self._read = read_data  # what the reward reads too
        return np.asarray(read_data["cylinder"], dtype=np.float32)

    def _get_reward(self):
        return -float(np.abs(self._read["cylinder"]).mean())


def _case(tmp_path: Path, library: str, *, max_time: float = 0.1, variant=None, **partner) -> Path:
    case = tmp_path / "case"
    (case / "fluid").mkdir(parents=True, exist_ok=True)
    case_config("fake_cylinder", case, max_time=max_time, variant=variant)
    argv = ["{python}", "-m", "gymprecice.testing.partner", "--config", "{precice_config}"]
    argv += ["--participant", "Fluid", "--library", library]
    for flag, value in partner.items():
        argv += [f"--{flag.replace('_', '-')}", str(value)]
    config = {
        "precice": {"library": library},
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "command",
                    "participant": "Fluid",
                    # the partner needs no plugin: skip their scan, most of its start-up
                    "options": {"argv": argv, "env": {"GYMPRECICE_DISABLE_PLUGINS": "1"}},
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {"jet1": "Velocity", "jet2": "Velocity"},
            "read_from": {"cylinder": "Pressure"},
        },
        "timeouts": {"progress": 4, "reset": 60, "kill_grace": 0.5, "finalize": 5},
    }
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    return case


def _run_episode(env: Adapter, action: float) -> tuple[list[np.ndarray], dict]:
    obs, info = env.reset(seed=0)
    observations, truncated = [obs], False
    while not truncated:
        obs, _, terminated, truncated, info = env.step(np.array([action], dtype=np.float32))
        assert not terminated
        observations.append(obs)
    return observations, info


@pytest.mark.parametrize("library", LIBRARIES)
def test_explicit_episode_with_direct_access_reads(tmp_path, library):
    """Cost: about 2 s per library (a 10-window episode; real preCICE adds its start-up)."""
    env = FakeCylinderEnv(_case(tmp_path, library), 0, run_root=tmp_path / "runs")
    observations, info = _run_episode(env, 0.5)
    assert len(observations) == 11  # reset + 10 windows of 0.01 up to max-time 0.1
    assert info["time"] == pytest.approx(0.1) and info["time_window"] == 10
    assert observations[0].shape == (32,)
    assert not np.allclose(observations[-1], observations[1])  # the flow responds
    assert env.interface_geometry["cylinder"].coordinates.shape == (32, 2)
    # a second episode in the same env reproduces the first exactly (deterministic flow)
    again, _ = _run_episode(env, 0.5)
    assert all(np.array_equal(a, b) for a, b in zip(observations, again))
    env.close()


def test_double_and_real_precice_agree(tmp_path):
    if not _real_precice_importable():
        pytest.skip("pyprecice / the preCICE library is not installed")
    results = []
    for library in (DOUBLE, "precice"):
        env = FakeCylinderEnv(
            _case(tmp_path / library, library), 0, run_root=tmp_path / library / "runs"
        )
        results.append(_run_episode(env, -0.3)[0])
        env.close()
    for double, real in zip(*results):
        np.testing.assert_allclose(double, real, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("library", LIBRARIES)
def test_implicit_coupling_honours_checkpoints(tmp_path, library):
    """Cost: about 2 s per library (a 5-window implicit episode)."""
    case = _case(tmp_path, library, max_time=0.05, variant="implicit")
    env = FakeCylinderEnv(case, 0, run_root=tmp_path / "runs")
    observations, info = _run_episode(env, 0.2)
    assert info["time"] == pytest.approx(0.05)
    assert len(observations) == 6
    env.close()


@pytest.mark.parametrize("library", LIBRARIES)
def test_partner_killed_mid_episode_is_reported_not_hung(tmp_path, library):
    """Cost: about 1 s per library (three windows, then the partner dies)."""
    case = _case(tmp_path, library, crash_at_window=3)
    env = FakeCylinderEnv(case, 2, run_root=tmp_path / "runs")
    env.reset()
    started = time.monotonic()
    with pytest.raises(SolverCrashedError) as info:
        for _ in range(10):
            env.step(np.array([0.1], dtype=np.float32))
    assert time.monotonic() - started < 15
    assert info.value.env_index == 2 and "SIGKILL" in str(info.value)
    env.close()


@pytest.mark.parametrize("library", LIBRARIES)
def test_partner_hanging_mid_episode_times_out(tmp_path, library):
    """Cost: about 7 s per library, nearly all of it the progress timeout it checks."""
    case = _case(tmp_path, library, hang_at_window=2)
    env = FakeCylinderEnv(case, 0, run_root=tmp_path / "runs")
    env.reset()
    with pytest.raises(SolverTimeoutError, match="no progress"):
        for _ in range(10):
            env.step(np.array([0.1], dtype=np.float32))
    # the env is usable again after the failure
    case_file = case / "gymprecice-config.json"
    config = json.loads(case_file.read_text())
    config["physics_simulation_engine"]["solvers"]["fluid"]["options"]["argv"] = config[
        "physics_simulation_engine"
    ]["solvers"]["fluid"]["options"]["argv"][:-2]
    case_file.write_text(json.dumps(config))
    env.close()
    fresh = FakeCylinderEnv(case, 0, run_root=tmp_path / "runs")
    _run_episode(fresh, 0.0)
    fresh.close()


def test_env_passes_gymnasium_check_env_on_the_double(tmp_path):
    from gymnasium.utils.env_checker import check_env

    env = FakeCylinderEnv(_case(tmp_path, DOUBLE, max_time=0.05), 0, run_root=tmp_path / "runs")
    check_env(env, skip_render_check=True)
    env.close()


def _script_with_live_episode(tmp_path: Path, then: str) -> str:
    """Python source: reset an env, print its solver and worker pids, then run ``then``."""
    case = _case(tmp_path, DOUBLE, max_time=10.0)
    return f"""
import sys, time
sys.path.insert(0, {str(Path(__file__).parent)!r})
from test_adapter_coupled import FakeCylinderEnv
env = FakeCylinderEnv({str(case)!r}, 0, run_root={str(tmp_path / "runs")!r})
env.reset()
print(" ".join(str(p.pid) for p in env._gymprecice.run.session.solvers), env._gymprecice.run.session.worker.pid, flush=True)
{then}
"""


def _assert_all_gone(pids: list[int]) -> None:
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(pid) for pid in pids):
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in pids)


def test_forgotten_close_leaves_no_process_behind(tmp_path):
    script = _script_with_live_episode(tmp_path, "raise SystemExit(3)  # without env.close()")
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 3, done.stderr
    _assert_all_gone([int(p) for p in done.stdout.split()])


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_termination_signal_leaves_no_process_behind(tmp_path, signum):
    """A scheduler's SIGTERM (or a closed terminal's SIGHUP) skips atexit; core cleans up."""
    # A plain process: default dispositions, whatever this test runner inherited (nohup).
    default = "import signal; signal.signal(signal.SIGTERM, signal.SIG_DFL); "
    default += "signal.signal(signal.SIGHUP, signal.SIG_DFL)\n"
    script = default + _script_with_live_episode(tmp_path, "time.sleep(120)")
    proc = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        line = proc.stdout.readline()
        pids = [int(p) for p in line.split()]
        assert pids, proc.stderr.read()
        proc.send_signal(signum)
        assert proc.wait(timeout=60) == -signum  # it still dies of the signal
    finally:
        proc.kill()
        proc.wait()
    _assert_all_gone(pids)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False
