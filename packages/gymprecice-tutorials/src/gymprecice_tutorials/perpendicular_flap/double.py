"""The flap's training case on gymprecice's preCICE test double: a scripted flap.

Training, evaluating and testing PerpendicularFlapFast-v0 end to end (the watch-point
reader, the gust starts, the jet, PPO, the commands) must be possible on a machine
without preCICE, OpenFOAM or deal.II, in seconds. The double case couples the controller
to one scripted participant, :class:`FlapOscillator`, that stands in for fluid and solid
together (``python -m gymprecice.testing.partner --flow
gymprecice_tutorials.perpendicular_flap.double:FlapOscillator``):

* its inlet mesh is the training case's inlet faces (:func:`training_inlet`, from the
  case's ``blockMeshDict``), the vertices the controller writes the jet to;
* it reads the controller's inlet ``Velocity`` and turns it into a load on the flap: the
  momentum flux ``u²`` of each face weighted by ``exp(-y / 1 m)`` (the flow that meets the
  flap, 1 m tall, pushes it; the flow above its tip much less);
* the tip follows a damped oscillator driven by that load::

      x'' + 2 zeta omega x' + omega² x = omega² x_s(load)

  with the real case's figures: a natural frequency of 0.62 Hz, a damping ratio of 0.02,
  and a static deflection ``x_s`` of 0.07 m with the jet on the flap (centre 1 m), which
  the load's weighting takes to about 0.01 m with the jet at the top (centre 3 m). Each
  step is integrated exactly for the load read at its end, so the swing neither gains nor
  loses energy to the integrator;
* it writes the solid's watch-point log ``precice-Solid-watchpoint-Flap-Tip.log`` (in the
  solver directory ``solid-dealii``) in preCICE's format: one row at time 0, then one per
  completed window, so the env's observation and reward code runs unchanged. The tip sinks
  as it bends (``dy = -0.6 dx²``, a cantilever's shortening) and the force is the load's
  static force on the tip.

It is a test fixture with the shape of the real dynamics (a lightly damped swing that a
gust sets off and a constant jet only re-centres), not a solver.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.fields import Field, grid_points
from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.plugin.solver import InterfaceGeometry
from gymprecice.plugin.watchpoints import watch_point_file_name
from gymprecice.testing import partner
from gymprecice.testing.flows import Flow
from gymprecice_tutorials.perpendicular_flap.environment import PerpendicularFlapEnv, jet_profile
from gymprecice_tutorials.perpendicular_flap.training_case import WINDOW, fast_case_files

__all__ = [
    "DAMPING_RATIO",
    "NATURAL_FREQUENCY",
    "STATIC_TIP_ON_FLAP",
    "FlapOscillator",
    "ScriptedFlap",
    "double_case_files",
    "inlet_faces",
    "scripted_solid",
    "swing",
    "training_inlet",
]

#: the flap's first bending mode (Hz) and its damping ratio, as the real case swings
NATURAL_FREQUENCY = 0.62
DAMPING_RATIO = 0.02
#: static tip deflection (m) with the reference jet (2 m tall, 10 m/s peak) centred on the
#: flap (1 m); the load's weighting takes it to about 0.01 m with the jet at the top (3 m)
STATIC_TIP_ON_FLAP = 0.07
#: height (m) over which the load weighting decays: the flap's own height
LOAD_DECAY = 1.0
#: force (N) on the tip per metre of static deflection: the stand-in's tip stiffness
TIP_STIFFNESS = 10.0
#: the participant, its solver directory and its inlet mesh in the double case
PARTICIPANT = "Solid"
SOLVER_DIR = "solid-dealii"
MESH = "Solid-Mesh-inlet"
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"
_BLOCK_MESH = "fluid-openfoam/system/blockMeshDict"


def inlet_faces(block_mesh: str) -> InterfaceGeometry:
    """The inlet's face centres and areas from the flap's ``blockMeshDict`` text.

    The inlet (``x = xIn``) is the edge of two blocks: ``nyFlap`` even cells up to the
    flap's tip and ``nyAbove`` even cells above it (no grading in ``y``).
    """
    values: dict[str, float] = {}
    for name in ("xIn", "yTip", "yTop", "zDepth", "nyFlap", "nyAbove"):
        match = re.search(rf"^\s*{name}\s+([-+0-9.eE]+)\s*;", block_mesh, re.MULTILINE)
        if match is None:
            raise ValueError(f"blockMeshDict: no '{name} <value>;' to place the inlet faces")
        values[name] = float(match.group(1))
    edges = np.concatenate(
        [
            np.linspace(0.0, values["yTip"], int(values["nyFlap"]) + 1),
            np.linspace(values["yTip"], values["yTop"], int(values["nyAbove"]) + 1)[1:],
        ]
    )
    y = 0.5 * (edges[1:] + edges[:-1])
    coordinates = np.column_stack([np.full_like(y, values["xIn"]), y])
    normals = np.tile([-1.0, 0.0, 0.0], (len(y), 1))
    areas = np.diff(edges) * values["zDepth"]
    return InterfaceGeometry(coordinates, normals, areas, ("inlet",))


def training_inlet() -> InterfaceGeometry:
    """The training case's inlet faces (the mesh PerpendicularFlapFast-v0's fluid has)."""
    return inlet_faces(fast_case_files(1.0)[_BLOCK_MESH])


def swing(state: dict[str, float], omega: float, zeta: float, dt: float) -> None:
    """Advance a damped oscillator's ``state`` (``x``, ``v``, ``static``) by ``dt``.

    Exact over the step with the load held: the deviation from the static deflection
    swings freely at ``omega``, decaying at ``zeta * omega``. Both flap doubles use it.
    """
    w, z = omega, zeta
    wd = w * math.sqrt(1.0 - z * z)
    decay = math.exp(-z * w * dt)
    cos, sin = math.cos(wd * dt), math.sin(wd * dt)
    e0, v0 = state["x"] - state["static"], state["v"]
    state["x"] = state["static"] + decay * (e0 * cos + (v0 + z * w * e0) / wd * sin)
    state["v"] = decay * (v0 * cos - (w * w * e0 + z * w * v0) / wd * sin)


class ScriptedFlap(Flow):
    """What both scripted flaps share: the controller's faces as their one mesh, a
    ``(x, v, static)`` state, and a watch-point log they append a row to each window.

    A subclass sets ``faces_mesh`` and ``faces`` (the controller's interface) and
    defines ``_start_log`` and ``_row``.
    """

    faces_mesh: str
    faces: InterfaceGeometry
    state: dict[str, float]

    def mesh_coordinates(self, mesh: str) -> np.ndarray:
        if mesh != self.faces_mesh:
            return super().mesh_coordinates(mesh)
        coords = np.ascontiguousarray(self.faces.coordinates, dtype=float)
        self.meshes[mesh] = coords
        return coords

    def summary(self) -> dict[str, float]:
        return {"dx": self.state["x"], "static": self.state["static"]}

    def _start_log(self, directory: Path) -> Path:
        raise NotImplementedError

    def _row(self, t: float) -> str:
        raise NotImplementedError

    def write_outputs(self, directory: Path, t: float) -> None:
        log = self._start_log(Path(directory))
        with log.open("a") as handle:
            handle.write(self._row(t))


class FlapOscillator(ScriptedFlap):
    """The flap as a damped oscillator driven by the inlet jet (see the module docstring).

    Partner options (``--option KEY=VALUE``): ``natural_frequency`` (Hz),
    ``damping_ratio``, ``static_tip`` (m, with the jet centred on the flap) and ``outputs``
    (directory whose watch-point log is started afresh when the flow is made; the
    partner's ``--write-outputs``).
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        opt = self.options
        self.omega = 2.0 * math.pi * float(opt.get("natural_frequency", NATURAL_FREQUENCY))
        self.zeta = float(opt.get("damping_ratio", DAMPING_RATIO))
        self.inlet = training_inlet()
        self.faces_mesh, self.faces = MESH, self.inlet
        y = self.inlet.coordinates[:, 1]
        self._weights = np.asarray(self.inlet.areas) * np.exp(-y / LOAD_DECAY)
        self._weights /= float(np.sum(self.inlet.areas))
        reference = jet_profile(y, 1.0, 2.0, mean_velocity=2.0 / 3.0 * 10.0)
        self._gain = float(opt.get("static_tip", STATIC_TIP_ON_FLAP)) / self._load(reference)
        self.state = {"x": 0.0, "v": 0.0, "static": 0.0}
        self._log: Path | None = None
        if opt.get("outputs"):
            # Start the episode's log now, before the coupling is initialised: the env
            # waits for its time-0 row during reset and must never read last episode's.
            self._start_log(Path(str(opt["outputs"])))

    def _load(self, velocity_x: np.ndarray) -> float:
        return float(np.sum(self._weights * np.asarray(velocity_x, dtype=float) ** 2))

    # -- dynamics
    def step(self, t: float, dt: float, inputs: Mapping[tuple[str, str], np.ndarray]) -> None:
        s = self.state
        for (_data, mesh), values in inputs.items():
            if mesh == MESH:
                velocity = np.asarray(values, dtype=float).reshape(len(self.inlet.coordinates), -1)
                s["static"] = self._gain * self._load(velocity[:, 0])
        swing(s, self.omega, self.zeta, dt)

    def tip(self) -> tuple[float, float, float, float]:
        """``(dx, dy, fx, fy)`` of the tip now."""
        dx = self.state["x"]
        return dx, -0.6 * dx * dx, TIP_STIFFNESS * self.state["static"], 0.0

    # -- fields for env.render(): the fluid's speed and the bent flap
    def field_names(self) -> tuple[str, ...]:
        return ("U", "displacement")

    def field(self, name: str, t: float) -> Field | None:
        if name == "displacement":
            points, triangles = grid_points([-0.05, 0.05], np.linspace(0.0, 1.0, 21))
            bend = (points[:, 1] / 1.0) ** 2
            dx = self.state["x"] * bend
            disp = np.column_stack([dx, -0.6 * dx * dx])
            return Field(
                name, t, points, disp, triangles=triangles, displacement=disp, label="|d| [m]"
            )
        if name == "U":
            points, triangles = grid_points(np.linspace(-3.0, 3.0, 61), np.linspace(0.0, 4.0, 41))
            x, y = points[:, 0], points[:, 1]
            blocked = np.exp(-((x / 0.4) ** 2) - 4.0 * np.maximum(y - 1.0, 0.0) ** 2) * (y < 1.2)
            values = (1.0 + 5.0 * self.state["static"]) * (1.0 - 0.8 * blocked)
            values *= 1.0 + 0.5 * self.state["x"] * np.exp(-(x**2)) + 0.2 * np.tanh(y)
            return Field(name, t, points, values, triangles=triangles, label="|U| (test double)")
        return None

    # -- preCICE's watch-point log (gymprecice.watchpoints describes the format)
    def _start_log(self, directory: Path) -> Path:
        if self._log is None:
            directory.mkdir(parents=True, exist_ok=True)
            self._log = directory / watch_point_file_name(
                PARTICIPANT, PerpendicularFlapEnv.WATCH_POINT
            )
            columns = ["Time", "Coordinate0", "Coordinate1", "Displacement0", "Displacement1"]
            columns += ["Force0", "Force1"]
            self._log.write_text("".join(f"  {c}" for c in columns) + self._row(0.0))
        return self._log

    def _row(self, t: float) -> str:
        # preCICE writes the newline before each row, so the last row is unterminated
        return "\n" + "  ".join(f"{v:>15.8e}" for v in (t, 0.0, 1.0, *self.tip()))


# -- the test-double case ------------------------------------------------------------------


def precice_config(end_time: float, window: float) -> str:
    """Controller and the scripted flap, coupled as the real case couples the controller."""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<!--
  The flap's training case on the test double: the controller writes the inlet velocity
  to one scripted participant that stands in for fluid and solid (named Solid: it writes
  the solid's watch-point log itself, so no watch point is declared here).
-->
<precice-configuration>
  <data:vector name="Velocity" />

  <mesh name="Controller-Mesh-inlet" dimensions="2">
    <use-data name="Velocity" />
  </mesh>

  <mesh name="{MESH}" dimensions="2">
    <use-data name="Velocity" />
  </mesh>

  <participant name="Controller">
    <provide-mesh name="Controller-Mesh-inlet" />
    <write-data name="Velocity" mesh="Controller-Mesh-inlet" />
  </participant>

  <participant name="{PARTICIPANT}">
    <provide-mesh name="{MESH}" />
    <receive-mesh name="Controller-Mesh-inlet" from="Controller" />
    <read-data name="Velocity" mesh="{MESH}" />
    <mapping:nearest-neighbor direction="read" from="Controller-Mesh-inlet" to="{MESH}" constraint="consistent" />
  </participant>

  <m2n:sockets acceptor="{PARTICIPANT}" connector="Controller" exchange-directory=".." />

  <coupling-scheme:parallel-explicit>
    <participants first="Controller" second="{PARTICIPANT}" />
    <max-time value="{end_time:.10g}" />
    <time-window-size value="{window:.10g}" />
    <exchange data="Velocity" mesh="Controller-Mesh-inlet" from="Controller" to="{PARTICIPANT}" initialize="true" />
  </coupling-scheme:parallel-explicit>
</precice-configuration>
"""


def scripted_solid(
    path: str, participant: str, flow: str, library: str, options: Mapping[str, Any]
) -> dict[str, Any]:
    """The solver entry of a scripted flap: the ``flow`` partner in ``path`` as ``participant``.

    It writes its solid's watch-point log itself, which the deal.II plugin's reader opens
    (``"outputs": "dealii"``); both flap doubles' cases use it.
    """
    argv = partner.command(
        "{precice_config}",  # the env's own copy, substituted by the "command" kind
        participant,
        flow=flow,
        library=library,
        options=dict(options),
        python="{python}",
        write_outputs=".",
    )
    return {
        "kind": "command",
        "path": path,
        "participant": participant,
        "options": {
            "argv": argv,
            "log_name": "partner.log",
            "outputs": "dealii",
            # the partner needs no plugins: skip loading them (faster start)
            "env": {"GYMPRECICE_DISABLE_PLUGINS": "1"},
        },
    }


def double_case_files(
    end_time: float,
    *,
    flow_options: Mapping[str, Any] | None = None,
    library: str = DOUBLE_LIBRARY,
) -> dict[str, str]:
    """Files of the training case on the test double, its run ending at ``end_time``.

    The controller's side (``actions``, the ``inlet`` it writes) is the training case's
    own; the solver ``solid`` is the scripted :class:`FlapOscillator`, whose watch-point
    log the deal.II plugin's reader opens (``"outputs": "dealii"``).
    """
    config: dict[str, Any] = json.loads(fast_case_files(end_time)["gymprecice-config.json"])
    solid = scripted_solid(
        SOLVER_DIR,
        PARTICIPANT,
        "gymprecice_tutorials.perpendicular_flap.double:FlapOscillator",
        library,
        {"outputs": ".", **dict(flow_options or {})},
    )
    config["environment"] = {"name": "perpendicular_flap_fast-double"}
    config["precice"] = {"config_file": "precice-config.xml", "library": library}
    config["physics_simulation_engine"] = {"solvers": {PerpendicularFlapEnv.SOLID: solid}}
    config["timeouts"] = {"reset": 120, "progress": 60, "finalize": 10, "kill_grace": 1}
    return {
        "precice-config.xml": precice_config(end_time, WINDOW),
        "gymprecice-config.json": json.dumps(config, indent=2) + "\n",
        f"{SOLVER_DIR}/README": (
            "The scripted flap (gymprecice_tutorials.perpendicular_flap.double) runs here and "
            "writes the solid's watch-point log.\n"
        ),
    }
