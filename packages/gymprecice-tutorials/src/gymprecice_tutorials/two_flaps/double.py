"""The two flaps' training case on gymprecice's preCICE test double: two scripted flaps.

Testing, training and evaluating TwoFlapsFast (the agents, the watch-point readers, the
gust starts, the slots, parameter sharing) must be possible without preCICE, OpenFOAM or
deal.II, in seconds. The double case couples the controller to two scripted participants
named as the real solids, ``Solid-Upstream`` and ``Solid-Downstream``, one per flap
(:class:`SlotFlap`; ``python -m gymprecice.testing.partner --flow
gymprecice_tutorials.two_flaps.double:SlotFlap --option flap=upstream``), each in its own
explicit coupling scheme with the controller:

* its mesh is its slot's faces in the training case (:func:`slot_faces`, from the case's
  ``blockMeshDict``), the vertices the controller writes the slot velocity to;
* it turns the slot's mean velocity ``v`` into the flap's static tip deflection
  ``x_s = X0 + K v / v_max`` (``v_max`` = 10 m/s): the real training case's figures, a
  mean deflection ``X0`` of 0.017 m (upstream) and 0 m (downstream, in the upstream
  flap's wake) and ``K`` of 0.006 and 0.004 m (blowing pushes harder, suction eases);
* the tip follows a damped oscillator towards ``x_s``, with the real flaps' period of
  1.6 s and a damping ratio of 0.03, integrated exactly over each window; it starts at
  rest, so the first window's load sets it swinging as the impulsive start does;
* it writes its solid's watch-point log ``precice-<participant>-watchpoint-Flap-Tip.log``
  in preCICE's format (the real solid's columns, ``Displacement-Upstream0`` ...), one row
  at time 0, then one per completed window, so the env's code runs unchanged;
* when the env renders, each hands over its flap's ``displacement`` (the flap as a grid
  bent as a cantilever, its tip at the oscillator's ``dx``), and the upstream one also a
  stand-in fluid ``U`` of the whole channel: a 5 m/s inflow slowed behind the flaps,
  faster over their tips, a wake that sways with its flap, and its slot's jet.

It is a test fixture with the shape of the real dynamics (two lightly damped swings that a
gust sets off and a constant slot only re-centres), not a solver: the flaps do not feel
each other.
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
from gymprecice_tutorials.perpendicular_flap.double import ScriptedFlap, scripted_solid, swing
from gymprecice_tutorials.two_flaps.environment import FLAPS, Flap, TwoFlapsEnv
from gymprecice_tutorials.two_flaps.training_case import WINDOW, fast_case_files

__all__ = ["SlotFlap", "double_case_files", "slot_faces", "training_slots"]

#: the flaps' first bending period (s) and damping ratio, as the real case swings
PERIOD = 1.6
DAMPING_RATIO = 0.03
#: slot mean velocity (m/s) at which the static deflection moves by ``K``
V_MAX = 10.0
#: (X0, K) per flap, in metres (module docstring)
STATIC = {"upstream": (0.017, 0.006), "downstream": (0.0, 0.004)}
#: stress (Pa) on the tip per metre of static deflection: the stand-in's tip load
TIP_STRESS = 2000.0
#: the channel (m) the stand-in fluid field covers, and its inflow speed (m/s)
CHANNEL_X = (-3.0, 3.0)
CHANNEL_HEIGHT = 4.0
INFLOW = 5.0
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"
_BLOCK_MESH = "fluid-openfoam/system/blockMeshDict"


def _mesh(flap: Flap) -> str:
    return f"{flap.participant}-Mesh-jet"


def slot_faces(block_mesh: str, flap: Flap) -> InterfaceGeometry:
    """A slot's face centres and areas from the two flaps' ``blockMeshDict`` text."""
    side = "1" if flap.agent == "upstream" else "2"
    values: dict[str, float] = {}
    for name in (f"xJet{side}L", f"xJet{side}R", "zDepth", "nxJet"):
        match = re.search(rf"^\s*{name}\s+([-+0-9.eE]+)\s*;", block_mesh, re.MULTILINE)
        if match is None:
            raise ValueError(f"blockMeshDict: no '{name} <value>;' to place the slot faces")
        values[name] = float(match.group(1))
    edges = np.linspace(values[f"xJet{side}L"], values[f"xJet{side}R"], int(values["nxJet"]) + 1)
    x = 0.5 * (edges[1:] + edges[:-1])
    coordinates = np.column_stack([x, np.zeros_like(x)])
    normals = np.tile([0.0, -1.0, 0.0], (len(x), 1))
    return InterfaceGeometry(coordinates, normals, np.diff(edges) * values["zDepth"], (flap.jet,))


def training_slots() -> dict[str, InterfaceGeometry]:
    """Each slot's faces in the training case, by interface name."""
    block_mesh = fast_case_files(1.0)[_BLOCK_MESH]
    return {flap.jet: slot_faces(block_mesh, flap) for flap in FLAPS}


class SlotFlap(ScriptedFlap):
    """One flap as a damped oscillator driven by its slot (see the module docstring).

    Partner options (``--option KEY=VALUE``): ``flap`` (``upstream`` or ``downstream``),
    ``period`` (s), ``damping_ratio`` and ``outputs`` (the directory whose watch-point
    log is started afresh when the flow is made; the partner's ``--write-outputs``).
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        opt = self.options
        name = str(opt.get("flap", ""))
        flaps = {flap.agent: flap for flap in FLAPS}
        if name not in flaps:
            raise ValueError(f"SlotFlap: option flap={name!r}; use one of {sorted(flaps)}")
        self.flap = flaps[name]
        self.omega = 2.0 * math.pi / float(opt.get("period", PERIOD))
        self.zeta = float(opt.get("damping_ratio", DAMPING_RATIO))
        self.slot = training_slots()[self.flap.jet]
        self.faces_mesh, self.faces = _mesh(self.flap), self.slot
        self.x0, self.gain = STATIC[name]
        self.state = {"x": 0.0, "v": 0.0, "static": self.x0, "slot": 0.0}
        self._log: Path | None = None
        if opt.get("outputs"):
            # Start the episode's log now, before the coupling is initialised: the env
            # waits for its time-0 row during reset and must never read last episode's.
            self._start_log(Path(str(opt["outputs"])))

    # -- dynamics
    def step(self, t: float, dt: float, inputs: Mapping[tuple[str, str], np.ndarray]) -> None:
        s = self.state
        for (_data, mesh), values in inputs.items():
            if mesh == _mesh(self.flap):
                velocity = np.asarray(values, dtype=float).reshape(len(self.slot.coordinates), -1)
                areas = np.asarray(self.slot.areas, dtype=float)
                mean = float(velocity[:, 1] @ areas / areas.sum())
                s["slot"] = mean
                s["static"] = self.x0 + self.gain * mean / V_MAX
        swing(s, self.omega, self.zeta, dt)

    def tip(self) -> tuple[float, float, float, float]:
        """``(dx, dy, sx, sy)`` of the tip now (a cantilever's tip sinks as it bends)."""
        dx = self.state["x"]
        return dx, -0.6 * dx * dx, TIP_STRESS * self.state["static"], 0.0

    # -- fields for env.render(): the bent flap, and the upstream one's stand-in fluid
    def field_names(self) -> tuple[str, ...]:
        if self.flap is FLAPS[0]:
            return ("U", "displacement")
        return ("displacement",)

    def field(self, name: str, t: float) -> Field | None:
        if name == "displacement":
            x = self.flap.x
            points, triangles = grid_points([x - 0.05, x + 0.05], np.linspace(0.0, 1.0, 21))
            dx = self.state["x"] * points[:, 1] ** 2  # a cantilever's shape, tip at dx
            disp = np.column_stack([dx, -0.6 * dx * dx])
            return Field(
                name, t, points, disp, triangles=triangles, displacement=disp, label="|d| [m]"
            )
        if name == "U" and "U" in self.field_names():
            return self._fluid(t)
        return None

    def _fluid(self, t: float) -> Field:
        """The stand-in fluid: the shape of the real flow, driven by this flap's state."""
        points, triangles = grid_points(
            np.linspace(*CHANNEL_X, 91), np.linspace(0.0, CHANNEL_HEIGHT, 61)
        )
        x, y = points[:, 0], points[:, 1]
        u = INFLOW * np.tanh(y / 0.3)  # the floor's boundary layer
        w = np.zeros_like(u)
        below_tip = 1.0 / (1.0 + np.exp((y - 1.05) / 0.08))
        sway = self.omega * t
        for flap in FLAPS:
            behind = np.clip((x - flap.x) / 0.3, 0.0, 1.0) * np.exp(-np.maximum(x - flap.x, 0) / 2)
            behind /= 1.0 + np.exp((y - 1.4) / 0.2)  # the wake: below the tips' height
            slowed = 0.8 * below_tip * np.exp(-(((x - flap.x) / 0.25) ** 2)) + 0.6 * behind
            u *= np.clip(1.0 - slowed, 0.05, None)
            u += 3.0 * np.exp(-(((x - flap.x) / 0.5) ** 2) - ((y - 1.25) / 0.25) ** 2)
            wake = np.sin(2.0 * np.pi * (x - flap.x) / 1.5 - sway) * behind
            w += (1.0 + 20.0 * abs(self.state["x"])) * wake * np.exp(-(((y - 1.0) / 0.3) ** 2))
        jet = self.flap.jet_x
        w += self.state["slot"] * np.exp(-(((x - jet) / 0.15) ** 2) - y / 0.4)
        values = np.column_stack([u, w])
        return Field("U", t, points, values, triangles=triangles, label="|U| (test double)")

    # -- preCICE's watch-point log (gymprecice.watchpoints describes the format)
    def _start_log(self, directory: Path) -> Path:
        if self._log is None:
            directory.mkdir(parents=True, exist_ok=True)
            flap = self.flap
            self._log = directory / watch_point_file_name(flap.participant, TwoFlapsEnv.WATCH_POINT)
            columns = ["Time", "Coordinate0", "Coordinate1"]
            columns += [f"{flap.displacement}{i}" for i in range(2)]
            columns += [f"{flap.stress}{i}" for i in range(2)]
            self._log.write_text("".join(f"  {c}" for c in columns) + self._row(0.0))
        return self._log

    def _row(self, t: float) -> str:
        # preCICE writes the newline before each row, so the last row is unterminated
        corner = (self.flap.x - 0.05, 1.0)
        return "\n" + "  ".join(f"{v:>15.8e}" for v in (t, *corner, *self.tip()))


# -- the test-double case ------------------------------------------------------------------


def precice_config(end_time: float, window: float) -> str:
    """Controller and the two scripted flaps, each in an explicit scheme with it."""
    meshes, participants, schemes = [], [], []
    for flap in FLAPS:
        mine = _mesh(flap)
        controller = f"Controller-Mesh-{flap.jet}"
        meshes.append(
            f'  <mesh name="{controller}" dimensions="2">\n    <use-data name="Velocity" />\n'
            f'  </mesh>\n  <mesh name="{mine}" dimensions="2">\n'
            '    <use-data name="Velocity" />\n  </mesh>'
        )
        participants.append(
            f'  <participant name="{flap.participant}">\n'
            f'    <provide-mesh name="{mine}" />\n'
            f'    <receive-mesh name="{controller}" from="Controller" />\n'
            f'    <read-data name="Velocity" mesh="{mine}" />\n'
            f'    <mapping:nearest-neighbor direction="read" from="{controller}" to="{mine}" '
            'constraint="consistent" />\n  </participant>\n'
            f'  <m2n:sockets acceptor="{flap.participant}" connector="Controller" '
            'exchange-directory=".." />'
        )
        schemes.append(
            "  <coupling-scheme:parallel-explicit>\n"
            f'    <participants first="Controller" second="{flap.participant}" />\n'
            f'    <max-time value="{end_time:.10g}" />\n'
            f'    <time-window-size value="{window:.10g}" />\n'
            f'    <exchange data="Velocity" mesh="{controller}" from="Controller" '
            f'to="{flap.participant}" initialize="true" />\n'
            "  </coupling-scheme:parallel-explicit>"
        )
    controller_meshes = "\n".join(
        f'    <provide-mesh name="Controller-Mesh-{flap.jet}" />\n'
        f'    <write-data name="Velocity" mesh="Controller-Mesh-{flap.jet}" />'
        for flap in FLAPS
    )
    nl = "\n"
    return f"""<?xml version="1.0" encoding="UTF-8" ?>
<!--
  The two flaps' training case on the test double: the controller writes each slot's
  velocity to one scripted participant per flap, named as the real solid (each writes
  its solid's watch-point log itself, so no watch point is declared here).
-->
<precice-configuration>
  <data:vector name="Velocity" />

{nl.join(meshes)}

  <participant name="Controller">
{controller_meshes}
  </participant>

{nl.join(participants)}

{nl.join(schemes)}
</precice-configuration>
"""


def double_case_files(
    end_time: float,
    *,
    flow_options: Mapping[str, Any] | None = None,
    library: str = DOUBLE_LIBRARY,
) -> dict[str, str]:
    """Files of the training case on the test double, its run ending at ``end_time``.

    The controller's side (``actions``, the slots it writes) is the training case's own;
    the solvers ``upstream`` and ``downstream`` are scripted :class:`SlotFlap`\\ s, whose
    watch-point logs the deal.II plugin's reader opens (``"outputs": "dealii"``).
    """
    config: dict[str, Any] = json.loads(fast_case_files(end_time)["gymprecice-config.json"])
    solvers = {}
    files = {}
    for flap in FLAPS:
        directory = f"solid-{flap.agent}-dealii"
        solvers[flap.solver] = scripted_solid(
            directory,
            flap.participant,
            "gymprecice_tutorials.two_flaps.double:SlotFlap",
            library,
            {"flap": flap.agent, "outputs": ".", **dict(flow_options or {})},
        )
        files[f"{directory}/README"] = (
            f"The scripted {flap.agent} flap (gymprecice_tutorials.two_flaps.double) runs "
            "here and writes its solid's watch-point log.\n"
        )
    config["environment"] = {"name": "two_flaps_fast-double"}
    config["precice"] = {"config_file": "precice-config.xml", "library": library}
    config["physics_simulation_engine"] = {"solvers": solvers}
    config["timeouts"] = {"reset": 120, "progress": 60, "finalize": 10, "kill_grace": 1}
    return {
        "precice-config.xml": precice_config(end_time, WINDOW),
        "gymprecice-config.json": json.dumps(config, indent=2) + "\n",
        **files,
    }
