"""What core does with a plugin's answers at run time, on the test double.

A crashed solver's error carries its plugin's diagnosis, messages name the solver once,
and a set-up that mixes real preCICE with the test double is reported at reset.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from gymprecice.env.core import Adapter
from gymprecice.plugin.errors import SolverCrashedError
from gymprecice.testing import case_config
from gymprecice.testing.flows import place_jets

DOUBLE = "gymprecice.testing.fake_precice"


class CylinderEnv(Adapter):
    """The fake cylinder's controller: two jets written, the pressure read."""

    def __init__(self, options, idx=None, **kwargs):
        super().__init__(options, idx, **kwargs)
        place_jets(self)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(32,), dtype=np.float32)

    def _get_action(self, action, write_var_list):
        q = float(np.asarray(action).ravel()[0])
        return {
            name: np.tile([0.0, q], (len(self.interface_geometry[name].coordinates), 1))
            for name in ("jet1", "jet2")
        }

    def _get_observation(self, read_data, read_var_list):
        return np.asarray(read_data["cylinder"], dtype=np.float32)

    def _get_reward(self):
        return 0.0


def make_case(root: Path, argv: list[str], *, max_time: float = 0.05) -> Path:
    """A fake-cylinder case whose Fluid is the ``command`` solver ``rod`` running ``argv``."""
    case = root / "case"
    (case / "rod").mkdir(parents=True)
    case_config("fake_cylinder", case, max_time=max_time)
    config = {
        "precice": {"library": DOUBLE},
        "environment": {"run_root": str(root / "runs")},
        "physics_simulation_engine": {
            "solvers": {
                "rod": {
                    "kind": "command",
                    "path": "rod",
                    "participant": "Fluid",
                    "options": {"argv": argv},
                }
            }
        },
        "controller": {
            "write_to": {"jet1": "Velocity", "jet2": "Velocity"},
            "read_from": {"cylinder": "Pressure"},
        },
        "timeouts": {"progress": 60, "reset": 120, "kill_grace": 0.5, "finalize": 5},
    }
    (case / "gymprecice-config.json").write_text(json.dumps(config))
    return case


def partner_argv() -> list[str]:
    return [
        "{python}", "-m", "gymprecice.testing.partner", "--config", "{precice_config}",
        "--participant", "Fluid", "--library", DOUBLE,
    ]  # fmt: skip


def reset_error(case: Path) -> SolverCrashedError:
    env = CylinderEnv(str(case))
    try:
        with pytest.raises(SolverCrashedError) as caught:
            env.reset(seed=0)
    finally:
        env.close()
    return caught.value


def test_a_crashed_solver_carries_its_plugins_diagnosis(tmp_path: Path) -> None:
    """exit 127 alone says nothing; the default plugin's reading of the log says what to fix."""
    error = reset_error(make_case(tmp_path, ["bash", "-c", "gymprecice-no-such-program"]))
    assert error.returncode == 127
    assert "status 127" in error.summary
    assert "diagnosis: a program the solver script calls is not on PATH" in error.summary
    assert "gymprecice-no-such-program: command not found" in error.summary


def test_a_waiting_solvers_problem_names_the_solver_once(tmp_path: Path) -> None:
    argv = ["bash", "-c", "gymprecice-no-such-program; exec sleep 60"]
    error = reset_error(make_case(tmp_path, argv))
    assert error.returncode is None  # still running when the check found the problem
    assert "not on PATH" in error.summary
    assert error.summary.startswith("env 0: solver 'rod' has a problem: a program"), error.summary
    assert error.summary.count("solver 'rod'") == 1, error.summary


def test_a_plugin_message_that_names_the_solver_is_not_named_twice() -> None:
    """Plugins written when the spec's example began with ``solver.describe()`` still read well."""
    from gymprecice.env.guards import without_label

    label = "solver 'rod' (mysolver) of env 0"
    assert without_label(f"{label}: adapter not loaded", label) == "adapter not loaded"
    assert without_label("adapter not loaded", label) == "adapter not loaded"


REAL_BANNER = "---[precice] \x1b[0m This is preCICE version 3.4.1"


def test_a_solver_on_real_precice_next_to_the_double_is_reported_at_reset(tmp_path: Path) -> None:
    """A mixed set-up waits forever; the banner in the solver's log shows it at once.

    The solver stands in for a real-preCICE participant: it prints real preCICE's first
    log line and waits, as real preCICE waits for a partner that never comes. The
    progress timeout is 60 s, so an error here is the library check, not a timeout.
    """
    script = (
        f"echo \"$GYMPRECICE_PRECICE_LIBRARY\" > library.txt; echo '{REAL_BANNER}'; exec sleep 60"
    )
    case = make_case(tmp_path, ["bash", "-c", script])
    error = reset_error(case)
    assert error.returncode is None
    assert "runs real preCICE 3.4.1" in error.summary
    assert f"the env's coupling uses the preCICE test double ({DOUBLE!r})" in error.summary
    assert "set precice.library in gymprecice-config.json" in error.summary
    # core told the solver which library the env uses
    library = tmp_path / "runs" / "env_0" / "rod" / "library.txt"
    assert library.read_text().strip() == DOUBLE


def test_a_solver_on_the_double_next_to_real_precice_is_named_too() -> None:
    from gymprecice.env.precice_library import library_in_log, mixed_library_problem

    double_log = "---[precice]  This is preCICE version 3.4.1 (gymprecice fake_precice)\n"
    assert library_in_log(double_log).double
    assert not library_in_log(REAL_BANNER).double
    assert library_in_log("Time = 0.1\n") is None
    problem = mixed_library_problem("precice", double_log)
    assert problem is not None
    assert "it runs the preCICE test double (gymprecice.testing.fake_precice)" in problem
    assert "the env's coupling uses real preCICE (module 'precice')" in problem
    assert mixed_library_problem("precice", REAL_BANNER) is None
    assert mixed_library_problem(DOUBLE, double_log) is None


def test_the_context_carries_the_envs_library(tmp_path: Path, monkeypatch) -> None:
    """``SolverContext.precice_library``: the configuration's, or the variable's override."""
    case = make_case(tmp_path, partner_argv())
    monkeypatch.delenv("GYMPRECICE_PRECICE_LIBRARY", raising=False)
    env = CylinderEnv(str(case))
    try:
        env._gymprecice.run.prepare()
        ctx = env._gymprecice.run.solvers["rod"]
        assert ctx.precice_library == DOUBLE and ctx.uses_test_double
        env.reset(seed=0)  # both sides on the double: the library check stays quiet
        env.step(np.zeros(1, np.float32))
    finally:
        env.close()
    monkeypatch.setenv("GYMPRECICE_PRECICE_LIBRARY", "precice")
    env = CylinderEnv(str(case))
    try:
        env._gymprecice.run.prepare()
        assert env._gymprecice.run.solvers["rod"].precice_library == "precice"
    finally:
        env.close()


def test_the_last_steps_wait_for_the_solvers_to_exit_counts_as_waiting(tmp_path: Path) -> None:
    """On the last step core finalizes and waits for the solvers: that is ``wait_s``.

    The solver lingers 1 s after its coupling ended, so the last step waits at least that
    long for it, while preCICE itself is done in milliseconds.
    """
    argv = ["bash", "-c", " ".join(partner_argv()) + "; sleep 1"]
    env = CylinderEnv(str(make_case(tmp_path, argv, max_time=0.02)))
    try:
        env.reset(seed=0)
        truncated, info = False, {}
        while not truncated:
            _, _, _, truncated, info = env.step(np.zeros(1, np.float32))
        timing = info["timing"]
        assert timing["wait_s"] >= 1.0, dict(timing)
        assert timing["wait_s"] + timing["env_s"] <= timing["step_s"]
    finally:
        env.close()


def test_readers_follow_the_conventions_or_say_which_is_missing(tmp_path: Path) -> None:
    from gymprecice.env.timed_reader import TimedReader
    from gymprecice.plugin.solver import OutputReader, WaitableOutputReader
    from gymprecice.plugin.watchpoints import WatchPointLog

    log = WatchPointLog(tmp_path / "precice-Solid-watchpoint-Tip.log")
    assert isinstance(log, WaitableOutputReader) and log.start_time == 0.0

    class Plain:
        def read_new(self):
            return []

        def close(self):
            pass

    assert isinstance(Plain(), OutputReader) and not isinstance(Plain(), WaitableOutputReader)
    with pytest.raises(AttributeError, match=r"Plain has no wait_until.*WaitableOutputReader"):
        TimedReader(Plain(), [0.0]).wait_until(1.0, 5)
