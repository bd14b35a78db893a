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

from gymprecice.core import Adapter
from gymprecice.errors import SolverCrashedError
from gymprecice.testing import case_config
from gymprecice.testing.flows import fake_cylinder_geometry

DOUBLE = "gymprecice.testing.fake_precice"


class CylinderEnv(Adapter):
    """The fake cylinder's controller: two jets written, the pressure read."""

    def __init__(self, options, idx=None, **kwargs):
        super().__init__(options, idx, **kwargs)
        geometry = fake_cylinder_geometry()
        for name in ("jet1", "jet2"):
            self.set_interface_vertices(name, geometry[name].coordinates)
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
    from gymprecice.core import _without_label

    label = "solver 'rod' (mysolver) of env 0"
    assert _without_label(f"{label}: adapter not loaded", label) == "adapter not loaded"
    assert _without_label("adapter not loaded", label) == "adapter not loaded"
