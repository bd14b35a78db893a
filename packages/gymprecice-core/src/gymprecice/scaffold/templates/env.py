"""The new package's ``env.py``: the environment class (a ``gymprecice.core.Adapter``)
with its spaces, the four user methods, its episode and the metrics its lab card names,
and the packaged case's configuration (with its test-double variant).
"""

from __future__ import annotations

__all__ = ["ENV"]

ENV = '''\
"""{{class_name}}-v0: {{description}}.

Task
----
{{task}}

* **Action** ``{{action_shape}}``: {{action_text}}
* **Observation** ``({{n_sensors}},)``: each sensed value minus the setpoint, divided by
  ``SENSOR_SCALE``.
* **Reward**: ``-|mean sensed - setpoint| / SENSOR_SCALE``.
* **Episode**: {{end_time}} s of simulated time, {{steps}} actions of {{action_time}} s
  ({{windows}} preCICE time window(s) each), truncated at its end; no terminal state.
* ``info["metrics"]``: ``tracking_error`` (``|mean sensed - setpoint|``), ``sensed``
  (the mean sensed value), ``actuation`` (the mean actuator level, in [-1, 1]).

The case
--------
``case/`` couples the controller (participant ``Controller``) to one solver of kind
``{{kind}}``, participant ``{{participant}}``. {{solver_text}} ``double=True`` couples
{{double_what}} through gymprecice's preCICE test double instead: no preCICE and no
solver needed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymprecice.core import Adapter

__all__ = ["CASE_DIR", "{{class_name}}", "packaged_config"]

CASE_DIR = Path(__file__).resolve().parent / "case"
#: the module gymprecice couples through on the test double (``double=True``)
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"
#: the solver of the case (its name in gymprecice-config.json)
SOLVER = "{{solver_name}}"
#: what replaces it on the test double: the stand-in (None: the solver itself)
STAND_IN: dict[str, Any] | None = {{stand_in_entry}}
#: the controller's vertices (x, y): where it writes (interface "actuator") and where
#: it reads (interface "sensor"); the solver maps between them and its own mesh
ACTUATORS = {{actuators}}
SENSORS = {{sensors}}
#: an actuator at level a (in [-1, 1]) writes REFERENCE + ACTUATION_SCALE * a ({{write_unit}})
REFERENCE = {{reference}}
ACTUATION_SCALE = {{actuation_scale}}
#: whether the actuators write vector data ({{write}}), along x
VECTOR_ACTUATION = {{vector_actuation}}
#: the setpoints an episode draws from (the sensed {{read}}, {{read_unit}})
SETPOINTS = {{setpoints}}
#: the sensed value's scale in observations and rewards
SENSOR_SCALE = {{sensor_scale}}
#: whether the action is discrete: per actuator, index 0, 1, 2 is level -1, 0, 1
DISCRETE = {{discrete}}


def packaged_config(double: bool = False) -> dict[str, Any]:
    """The packaged case's configuration; ``double``: on the test double."""
    config = json.loads((CASE_DIR / "gymprecice-config.json").read_text())
    if double:
        config["environment"]["name"] += "-double"
        config["precice"]["library"] = DOUBLE_LIBRARY
        if STAND_IN is not None:
            config["physics_simulation_engine"]["solvers"][SOLVER] = STAND_IN
    return config


class {{class_name}}(Adapter):
    """Hold the sensed {{read}} at a setpoint (see the module docstring)."""

    def __init__(
        self,
        options: Mapping[str, Any] | str | Path | None = None,
        idx: int | None = None,
        *,
        double: bool = False,
        uncontrolled: bool = False,
        run_root: str | Path | None = None,
    ) -> None:
        if options is not None and double:
            raise ValueError(
                "double=True runs the packaged case on the test double; with a case of "
                "your own (options) set its precice.library instead"
            )
        case_dir = CASE_DIR if options is None else None
        if options is None:
            options = packaged_config(double)
        super().__init__(options, idx, run_root=run_root, case_dir=case_dir)
        # set by hand, so the env sees the same vertices on every solver and the double
        self.set_interface_vertices("actuator", ACTUATORS)
        self.set_interface_vertices("sensor", SENSORS)
        self.uncontrolled = bool(uncontrolled)
        n = len(ACTUATORS)
        if DISCRETE:
            self.action_space = (
                gym.spaces.Discrete(3) if n == 1 else gym.spaces.MultiDiscrete([3] * n)
            )
        else:
            self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(len(SENSORS),), dtype=np.float32
        )
        self.setpoint = float(np.mean(SETPOINTS))
        self._level = np.zeros(n)
        self._sensed = np.zeros(len(SENSORS))

    # -- the four user methods -------------------------------------------------------
    def _get_action(self, action: Any, write_var_list: list) -> dict[str, np.ndarray]:
        n = len(ACTUATORS)
        level = np.asarray(action, dtype=float).reshape(n)
        if DISCRETE:
            level = level - 1.0  # index 0, 1, 2 -> level -1, 0, 1
        self._level = np.zeros(n) if self.uncontrolled else np.clip(level, -1.0, 1.0)
        values = REFERENCE + ACTUATION_SCALE * self._level
        if VECTOR_ACTUATION:  # one (x, y) vector per vertex, along x
            values = np.column_stack([values, np.zeros(n)])
        return {"actuator": values}

    def _get_observation(self, read_data: Any, read_var_list: list) -> np.ndarray:
        # zeros at reset(): the case's exchanges are not initialized
        sensed = np.asarray(read_data["sensor"], dtype=float)
        self._sensed = sensed[:, 0] if sensed.ndim > 1 else sensed  # vectors: x
        return ((self._sensed - self.setpoint) / SENSOR_SCALE).astype(np.float32)

    def _get_reward(self) -> float:
        return -self._error() / SENSOR_SCALE

    def _close_external_resources(self) -> None:
        pass  # the env opens no file of its own

    # -- the episode -----------------------------------------------------------------
    def _initial_action(self) -> Any:
        """Draw the episode's setpoint (reset has seeded ``np_random``); every actuator
        starts at level 0."""
        self.setpoint = float(self.np_random.uniform(*SETPOINTS))
        n = len(ACTUATORS)
        if DISCRETE:
            return 1 if n == 1 else np.ones(n, dtype=np.int64)
        return np.zeros(n, dtype=np.float32)

    def _error(self) -> float:
        return abs(float(self._sensed.mean()) - self.setpoint)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Core's step, with the metrics the lab card names in ``info["metrics"]``."""
        obs, reward, terminated, truncated, info = super().step(action)
        info["metrics"] = {
            "tracking_error": self._error(),
            "sensed": float(self._sensed.mean()),
            "actuation": float(self._level.mean()),
        }
        return obs, reward, terminated, truncated, info
'''
