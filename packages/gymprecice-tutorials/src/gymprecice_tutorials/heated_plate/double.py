"""HeatedPlate-v0 on gymprecice's preCICE test double: a scripted, lumped plate.

The environment's code (the heater and inflow it writes, the interface temperature it
reads, the starts, the reward) must be testable on a machine without preCICE, OpenFOAM or
FEniCS, in seconds. The double case couples the controller to one scripted participant,
:class:`LumpedPlate` (``python -m gymprecice.testing.partner --flow
gymprecice_tutorials.heated_plate.double:LumpedPlate``), standing in for fluid and plate
together. It provides the three meshes the controller is coupled to (the inlet, the
heater, the fluid side of the plate) and follows two temperatures:

* the interface temperature ``T`` relaxes within ``PLATE_TIME`` towards a mix of the
  heater's and the near-wall fluid's temperature, the fluid's share growing with the
  inflow velocity ``u``: ``T_eq = (T_heater + g(u) T_fluid) / (1 + g(u))``,
  ``g(u) = SHARE (u / 0.1 m/s)^SPEED_EXPONENT``;
* the near-wall fluid warms towards ``T`` within ``FLUID_TIME`` and is cooled by the
  inflow: ``T_fluid' = (T - T_fluid) / FLUID_TIME - COOLING (u / 0.1 m/s)^SPEED_EXPONENT
  (T_fluid - 300 K)``.

The constants are fitted to HeatedPlate-v0 itself (the OpenFOAM plate, held-out start 1:
0.3 s of settling, then 2 s with the inflow stepping from 0.1 to 0.255 m/s after 1.1 s):
its uncontrolled interface temperature (302.65 -> 304.63 K) and its answer to the heater
stepped to 330 K (+1.7 K after one action, +3.7 K after two, +8.9 K after twenty). The
double follows them within 0.13 K (uncontrolled) and 0.28 K (the step) after every
action: a policy trained on the real case meets the same gain and the same two time
scales here. The real plate hardly feels the inflow (a tenfold change
moves it by 0.4 K), hence the small exponent.

It is a test fixture with the shape of the real case's response (a fast heater, a slow
warming drift, a faster flow cooling the plate), not a solver.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from gymprecice.plugin.fields import Field, grid_points
from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.testing import partner
from gymprecice.testing.flows import Flow
from gymprecice_tutorials.heated_plate.packaged_case import WINDOW, case_files

__all__ = ["LumpedPlate", "double_case_files"]

PARTICIPANT = "Fluid"
SOLVER_DIR = "fluid-double"
PLATE_MESH = "Fluid-Mesh"
INLET_MESH = "Fluid-Mesh-inlet"
HEATER_MESH = "Solid-Mesh-heater"
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"
INFLOW_TEMPERATURE = 300.0
#: fitted to HeatedPlate-v0 (module docstring): the plate's and the near-wall fluid's
#: time scales (s), the inflow's cooling (1/s) and the fluid's share of the interface
PLATE_TIME = 0.034
FLUID_TIME = 0.21
COOLING = 1.06
SHARE = 6.3
SPEED_EXPONENT = 0.02


class LumpedPlate(Flow):
    """Fluid and plate as two lumped temperatures (see the module docstring)."""

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        self.state = {"T": 305.0, "fluid": INFLOW_TEMPERATURE, "heater": 310.0, "u": 0.1}

    def step(self, t: float, dt: float, inputs: Mapping[tuple[str, str], np.ndarray]) -> None:
        s = self.state
        for (_data, mesh), values in inputs.items():
            values = np.asarray(values, dtype=float)
            if mesh == HEATER_MESH:
                s["heater"] = float(np.mean(values))
            elif mesh == INLET_MESH:
                s["u"] = float(np.mean(values.reshape(len(values), -1)[:, 0]))
        speed = (max(s["u"], 1e-6) / 0.1) ** SPEED_EXPONENT
        share = SHARE * speed
        target = (s["heater"] + share * s["fluid"]) / (1.0 + share)
        s["T"] = target + (s["T"] - target) * math.exp(-dt / PLATE_TIME)
        cooling = COOLING * speed * (s["fluid"] - INFLOW_TEMPERATURE)
        s["fluid"] += dt * ((s["T"] - s["fluid"]) / FLUID_TIME - cooling)

    def output(self, data: str, mesh: str) -> np.ndarray:
        if mesh == PLATE_MESH and data == "Temperature":
            return np.full(len(self.meshes.get(mesh, ())), self.state["T"])
        return super().output(data, mesh)

    def summary(self) -> dict[str, float]:
        return {"T": self.state["T"], "heater": self.state["heater"]}

    # -- fields for env.render(): the fluid's and the plate's temperature
    def field_names(self) -> tuple[str, ...]:
        return ("T-fluid", "T")

    def field(self, name: str, t: float) -> Field | None:
        s = self.state
        if name == "T":  # the plate, x in [0, 1], y in [-0.25, 0]: heater below
            points, triangles = grid_points(np.linspace(0.0, 1.0, 21), np.linspace(-0.25, 0.0, 6))
            depth = -points[:, 1] / 0.25
            values = s["T"] + (s["heater"] - s["T"]) * depth
            return Field(name, t, points, values, triangles=triangles, label="plate T [K]")
        if name == "T-fluid":  # the channel above it, warmed along the plate
            points, triangles = grid_points(np.linspace(0.0, 3.0, 46), np.linspace(0.0, 0.5, 11))
            x, y = points[:, 0], points[:, 1]
            layer = np.exp(-y / (0.05 + 0.05 * np.clip(x, 0.0, 3.0)))
            warm = (s["T"] - INFLOW_TEMPERATURE) * layer * np.clip(x, 0.0, 1.0)
            values = INFLOW_TEMPERATURE + warm + (s["fluid"] - INFLOW_TEMPERATURE) * layer
            return Field(name, t, points, values, triangles=triangles, label="fluid T [K]")
        return None


def precice_config(end_time: float, window: float) -> str:
    """Controller and the lumped plate, coupled as the real case couples the controller."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<!--
  HeatedPlate-v0 on the test double: the controller writes the inflow velocity and the
  heater temperature to one scripted participant that stands in for fluid and plate, and
  reads the interface temperature from it.
-->
<precice-configuration>
  <data:scalar name="Temperature" />
  <data:vector name="Velocity" />

  <mesh name="{PLATE_MESH}" dimensions="2">
    <use-data name="Temperature" />
  </mesh>
  <mesh name="{INLET_MESH}" dimensions="2">
    <use-data name="Velocity" />
  </mesh>
  <mesh name="{HEATER_MESH}" dimensions="2">
    <use-data name="Temperature" />
  </mesh>
  <mesh name="Controller-Mesh-inlet" dimensions="2">
    <use-data name="Velocity" />
  </mesh>
  <mesh name="Controller-Mesh-heater" dimensions="2">
    <use-data name="Temperature" />
  </mesh>
  <mesh name="Controller-Mesh-plate" dimensions="2">
    <use-data name="Temperature" />
  </mesh>

  <participant name="Controller">
    <provide-mesh name="Controller-Mesh-inlet" />
    <provide-mesh name="Controller-Mesh-heater" />
    <provide-mesh name="Controller-Mesh-plate" />
    <receive-mesh name="{PLATE_MESH}" from="{PARTICIPANT}" />
    <write-data name="Velocity" mesh="Controller-Mesh-inlet" />
    <write-data name="Temperature" mesh="Controller-Mesh-heater" />
    <read-data name="Temperature" mesh="Controller-Mesh-plate" />
    <mapping:nearest-neighbor direction="read" from="{PLATE_MESH}" to="Controller-Mesh-plate" constraint="consistent" />
  </participant>

  <participant name="{PARTICIPANT}">
    <provide-mesh name="{PLATE_MESH}" />
    <provide-mesh name="{INLET_MESH}" />
    <provide-mesh name="{HEATER_MESH}" />
    <receive-mesh name="Controller-Mesh-inlet" from="Controller" />
    <receive-mesh name="Controller-Mesh-heater" from="Controller" />
    <write-data name="Temperature" mesh="{PLATE_MESH}" />
    <read-data name="Velocity" mesh="{INLET_MESH}" />
    <read-data name="Temperature" mesh="{HEATER_MESH}" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-inlet" to="{INLET_MESH}" constraint="consistent" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-heater" to="{HEATER_MESH}" constraint="consistent" />
  </participant>

  <m2n:sockets acceptor="{PARTICIPANT}" connector="Controller" exchange-directory=".." />

  <coupling-scheme:parallel-explicit>
    <participants first="Controller" second="{PARTICIPANT}" />
    <max-time value="{end_time:.10g}" />
    <time-window-size value="{window:.10g}" />
    <exchange data="Velocity" mesh="Controller-Mesh-inlet" from="Controller" to="{PARTICIPANT}" initialize="true" />
    <exchange data="Temperature" mesh="Controller-Mesh-heater" from="Controller" to="{PARTICIPANT}" initialize="true" />
    <exchange data="Temperature" mesh="{PLATE_MESH}" from="{PARTICIPANT}" to="Controller" />
  </coupling-scheme:parallel-explicit>
</precice-configuration>
"""


def double_case_files(end_time: float, *, library: str = DOUBLE_LIBRARY) -> dict[str, str]:
    """Files of the heated plate on the test double, its run ending at ``end_time``."""
    config: dict[str, Any] = json.loads(case_files("openfoam", end_time)["gymprecice-config.json"])
    argv = partner.command(
        "{precice_config}",  # the env's own copy, substituted by the "command" kind
        PARTICIPANT,
        flow="gymprecice_tutorials.heated_plate.double:LumpedPlate",
        library=library,
        python="{python}",
    )
    config["environment"] = {"name": "heated_plate-double"}
    config["precice"] = {"config_file": "precice-config.xml", "library": library}
    config["physics_simulation_engine"] = {
        "solvers": {
            "plate": {
                "kind": "command",
                "path": SOLVER_DIR,
                "participant": PARTICIPANT,
                "options": {
                    "argv": argv,
                    "log_name": "partner.log",
                    # the partner needs no plugins: skip loading them (faster start)
                    "env": {"GYMPRECICE_DISABLE_PLUGINS": "1"},
                },
            }
        }
    }
    config["timeouts"] = {"reset": 120, "progress": 60, "finalize": 10, "kill_grace": 1}
    return {
        "precice-config.xml": precice_config(end_time, WINDOW),
        "gymprecice-config.json": json.dumps(config, indent=2) + "\n",
        f"{SOLVER_DIR}/README": (
            "The lumped plate (gymprecice_tutorials.heated_plate.double) runs here.\n"
        ),
    }
