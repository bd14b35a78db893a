"""A scripted stand-in for the cylinder flow, and the test-double cases that run it.

Training and testing the tutorial environments end to end (probe and force readers, the
actuators, the coupling, PPO, plots) must be possible on a machine without preCICE and
without minutes of CFD per episode. :class:`CylinderWake` is a flow for gymprecice's
scripted partner participant (``python -m gymprecice.testing.partner --flow
gymprecice_tutorials.fake_flow:CylinderWake``) that:

* places its coupling meshes on the recipe's jet or cylinder faces (exactly the vertices
  the environment uses, :mod:`gymprecice_tutorials.cylinder_geometry`);
* reads the controller's jet velocities (their flow rate ``Q``) or wall velocities (the
  angular velocity ``omega``) and drives a model of the wake with them;
* writes ``postProcessing/probes/0/p`` (the 151 probes of the recipe) and
  ``postProcessing/forceCoeffs/0/coefficient.dat`` in OpenFOAM v1912's format, one row per
  solver step (``flow.dt`` of the recipe; the partner subcycles in a window that is longer,
  as with ``coupling="action"``, see :func:`double_case_files`), so the environment's real
  readers run.

The wake model is a Stuart-Landau oscillator ``z`` (complex amplitude of the vortex
shedding), the normal form of the Hopf bifurcation that a cylinder wake goes through near
Re = 47::

    dz/dt = (sigma + i omega0) z - sigma |z|^2 z + beta u

with ``u = Q / Q_ref`` (jets) or ``u = omega / omega_ref`` (rotation). Without control
``|z|`` settles at 1 and the flow sheds at ``omega0 = 2 pi / 0.335 s``. Drag and lift::

    Cd = cd0 + kd |z|^2 + kd2 Re(z^2) + ka u^2        (mean 3.205 uncontrolled)
    Cl = Re(z) + k_magnus u_rotation

so a controller that feeds the shedding back out of phase quiets the wake and lowers the
drag, at a price for blowing; constant rotation buys a steady lift (the Magnus effect) that
the reward's lift penalty sees. Probe pressures are a steady field plus a wave convected
downstream with the shedding, plus a local response to the jets. All of it is deterministic
and costs microseconds per step: it is a test fixture with the right shape of dynamics,
not a flow solver.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.fields import Field
from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.testing import partner
from gymprecice.testing.flows import Flow
from gymprecice_tutorials import recipes
from gymprecice_tutorials.cylinder_geometry import patch_geometry
from gymprecice_tutorials.recipes import CaseSpec, Geometry, Resolution
from gymprecice_tutorials.recipes import Flow as FlowParameters

__all__ = [
    "FLOW_FILE",
    "FLOW_RATE_SCALE",
    "OMEGA_SCALE",
    "CylinderWake",
    "double_case_files",
    "spec_from_json",
    "spec_to_json",
]

#: Flow rate (m³/s) at which the fake wake's forcing has unit strength (the env's Qmax).
FLOW_RATE_SCALE = 2.5e-4
#: Angular velocity (rad/s) at which the fake wake's forcing has unit strength.
OMEGA_SCALE = 5.0
#: The case description the fake flow reads (in the double case's solver directory).
FLOW_FILE = "fake-flow.json"
#: The partner's solver directory inside a double case.
SOLVER_DIR = "fluid-fake"
DOUBLE_LIBRARY = "gymprecice.testing.fake_precice"


# -- the case description the flow reads ----------------------------------------------------


def spec_to_json(spec: CaseSpec) -> str:
    """The recipe spec as JSON (what the partner's flow needs to rebuild the geometry)."""
    return json.dumps(asdict(spec), indent=2) + "\n"


def spec_from_json(text: str) -> CaseSpec:
    data = json.loads(text)
    geometry = dict(data.pop("geometry"))
    geometry["centre"] = tuple(geometry["centre"])
    if "snapshots" in data:
        data["snapshots"] = tuple(data["snapshots"])
    return CaseSpec(
        geometry=Geometry(**geometry),
        resolution=Resolution(**data.pop("resolution")),
        flow=FlowParameters(**data.pop("flow")),
        **data,
    )


# -- the flow ------------------------------------------------------------------------------


def _tokens(mesh: str) -> set[str]:
    return {t.lower() for t in mesh.replace("_", "-").split("-")}


class CylinderWake(Flow):
    """The recipe's cylinder as a Stuart-Landau wake (see the module docstring).

    Partner options (``--option KEY=VALUE``): ``case`` (the JSON case description, default
    ``fake-flow.json`` in the working directory), ``outputs`` (directory whose output files
    are started afresh when the flow is made; the partner's ``--write-outputs``), ``sigma`` (growth rate, 1/s, default 4),
    ``beta`` (control authority, 1/s, default 6), ``phase`` (initial shedding phase, rad),
    ``cd0``, ``kd``, ``kd2``, ``ka``, ``k_magnus``.
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        opt = self.options
        self.case = spec_from_json(Path(str(opt.get("case", FLOW_FILE))).read_text())
        g = self.case.geometry
        self.sigma = float(opt.get("sigma", 4.0))
        self.beta = float(opt.get("beta", 6.0))
        self.omega0 = 2.0 * math.pi / 0.335
        self.cd0 = float(opt.get("cd0", 3.05))
        self.kd = float(opt.get("kd", 0.155))
        self.kd2 = float(opt.get("kd2", 0.03))
        self.ka = float(opt.get("ka", 0.2))
        self.k_magnus = float(opt.get("k_magnus", 0.5))
        self.centre = np.array(g.centre, dtype=float)
        self.geometry: dict[str, Any] = {}
        probes = np.array(recipes.probe_locations(g))
        self.probe_points = probes
        rel = (probes[:, :2] - self.centre) / g.diameter
        x, y = rel[:, 0], rel[:, 1]
        r = np.hypot(x, y)
        theta = np.arctan2(y, x)
        # steady part: potential flow around the cylinder, plus a low-pressure wake
        radius = 0.5
        self._steady = (
            2.0 * (radius / r) ** 2 * np.cos(2 * theta)
            - (radius / r) ** 4
            - 0.3 * np.exp(-(y**2)) * (x > 0)
        )
        # shedding: antisymmetric wave convected downstream (wavelength ~ 2.85 D)
        self._wave_amp = 0.4 * np.exp(-0.15 * np.maximum(x, 0.0)) * (np.tanh(2.0 * y) + 0.3)
        self._wave_k = 2.0 * math.pi / 2.85
        self._x = x
        # jets: a local pressure response near each jet (90°: +, 270°: -)
        d1 = np.hypot(x, y - 0.5)
        d2 = np.hypot(x, y + 0.5)
        self._jet_response = 0.5 * (np.exp(-4.0 * d1**2) - np.exp(-4.0 * d2**2))
        phase = float(opt.get("phase", 0.0))
        self.state = {"z": [math.cos(phase), math.sin(phase)], "u_jet": 0.0, "u_rot": 0.0}
        self._files: dict[str, Path] = {}
        if opt.get("outputs"):
            # Start the episode's output files now, before the coupling is initialised: the
            # env reads them as soon as its reset returns, and must never see rows left
            # over from the previous episode.
            self._open_files(Path(str(opt["outputs"])))

    # -- geometry: the recipe's patches
    def mesh_coordinates(self, mesh: str) -> np.ndarray:
        tokens = _tokens(mesh)
        patch = next((p for p in ("jet1", "jet2", "cylinder") if p in tokens), None)
        if patch is None:
            return super().mesh_coordinates(mesh)
        geometry = patch_geometry(self.case, patch)
        self.geometry[mesh] = (patch, geometry)
        coords = np.ascontiguousarray(geometry.coordinates[:, : self.config.mesh(mesh).dimensions])
        self.meshes[mesh] = coords
        return coords

    # -- control inputs
    def _controls(self, inputs: Mapping[tuple[str, str], np.ndarray]) -> tuple[float, float]:
        rates: dict[str, float] = {}
        omegas: list[float] = []
        for (_data, mesh), values in inputs.items():
            if mesh not in self.geometry:
                continue
            patch, geometry = self.geometry[mesh]
            u = np.asarray(values, dtype=float).reshape(len(geometry.coordinates), -1)[:, :2]
            rel = geometry.coordinates[:, :2] - self.centre
            dist = np.linalg.norm(rel, axis=1)
            radial = rel / dist[:, None]
            if patch in ("jet1", "jet2"):
                # flow rate out of the cylinder: radial velocity times face area
                rates[patch] = float(np.sum(np.sum(u * radial, axis=1) * geometry.areas))
            else:
                # rigid rotation: (r x u)_z / |r|^2, area-weighted
                spin = (rel[:, 0] * u[:, 1] - rel[:, 1] * u[:, 0]) / dist**2
                omegas.append(float(np.average(spin, weights=geometry.areas)))
        q = 0.5 * (rates.get("jet1", 0.0) - rates.get("jet2", 0.0))
        omega = float(np.mean(omegas)) if omegas else 0.0
        return q / FLOW_RATE_SCALE, omega / OMEGA_SCALE

    # -- dynamics
    def step(self, t: float, dt: float, inputs: Mapping[tuple[str, str], np.ndarray]) -> None:
        u_jet, u_rot = self._controls(inputs)
        s = self.state
        z = complex(*s["z"])
        u = u_jet + u_rot
        # exact rotation by omega0 dt, then the slow amplitude dynamics (semi-implicit)
        z *= complex(math.cos(self.omega0 * dt), math.sin(self.omega0 * dt))
        z += dt * (self.sigma * z * (1.0 - abs(z) ** 2) + self.beta * u)
        s["z"] = [z.real, z.imag]
        s["u_jet"], s["u_rot"] = u_jet, u_rot

    @property
    def z(self) -> complex:
        return complex(*self.state["z"])

    @property
    def drag(self) -> float:
        s, z = self.state, self.z
        u2 = s["u_jet"] ** 2 + s["u_rot"] ** 2
        return self.cd0 + self.kd * abs(z) ** 2 + self.kd2 * (z * z).real + self.ka * u2

    @property
    def lift(self) -> float:
        return self.z.real + self.k_magnus * self.state["u_rot"]

    def pressure(self) -> np.ndarray:
        """The 151 probe pressures of the current state."""
        z = self.z
        wave = (z * np.exp(-1j * self._wave_k * self._x)).real
        return self._steady + self._wave_amp * wave + self._jet_response * self.state["u_jet"]

    def summary(self) -> dict[str, float]:
        return {"Cd": self.drag, "Cl": self.lift, "u": self.state["u_jet"] + self.state["u_rot"]}

    # -- fields for env.render(): the names the real fluid's plugin answers
    def field_names(self) -> tuple[str, ...]:
        return ("U", "p")

    def _grid(self) -> np.ndarray:
        """Points of the channel outside the cylinder (made once)."""
        if not hasattr(self, "_points"):
            g = self.case.geometry
            x, y = np.meshgrid(np.linspace(0.0, g.length, 133), np.linspace(0.0, g.height, 27))
            points = np.stack([x.ravel(), y.ravel()], axis=1)
            keep = np.linalg.norm(points - self.centre, axis=1) > g.radius * 1.05
            self._points = points[keep]
        return self._points

    def field(self, name: str, t: float) -> Field | None:
        """A wake that sways with the shedding amplitude ``z`` (``U``: speed, ``p``)."""
        if name not in self.field_names():
            return None
        g = self.case.geometry
        points = self._grid()
        x = (points[:, 0] - self.centre[0]) / g.diameter
        y = (points[:, 1] - self.centre[1]) / g.diameter
        inflow = 6.0 * points[:, 1] * (g.height - points[:, 1]) / g.height**2
        behind = x > 0
        sway = 0.6 * (self.z * np.exp(-1j * self._wave_k * x)).real * np.tanh(x) * behind
        width = 0.5 + 0.08 * np.maximum(x, 0.0)
        deficit = np.exp(-(((y - sway) / width) ** 2)) * np.exp(-0.05 * np.maximum(x, 0.0))
        deficit *= behind + (1 - behind) * np.exp(-4.0 * x**2)
        if name == "U":
            values = inflow * (1.0 - 0.9 * deficit)
            return Field("U", t, points, values, label="|U| [m/s] (test double)")
        values = 0.5 * inflow**2 * (1.0 - deficit) - 0.3 * deficit * np.cos(self._wave_k * x)
        return Field("p", t, points, values, label="p (test double)")

    # -- OpenFOAM-format output
    def _open_files(self, directory: Path) -> tuple[Path, Path]:
        key = str(directory.resolve())
        if key not in self._files:
            probes = directory / "postProcessing" / "probes" / "0" / "p"
            coeffs = directory / "postProcessing" / "forceCoeffs" / "0" / "coefficient.dat"
            probes.parent.mkdir(parents=True, exist_ok=True)
            coeffs.parent.mkdir(parents=True, exist_ok=True)
            lines = [
                f"# Probe {i} ({x:.10g} {y:.10g} {zc:.10g})"
                for i, (x, y, zc) in enumerate(self.probe_points)
            ]
            n = len(self.probe_points)
            lines.append("#" + "Probe".rjust(15) + "".join(f"{i:>18}" for i in range(n)))
            lines.append("#" + "Time".rjust(15))
            probes.write_text("\n".join(lines) + "\n")
            names = ["Cd", "Cs", "Cl", "CmRoll", "CmPitch", "CmYaw"]
            names += ["Cd(f)", "Cd(r)", "Cs(f)", "Cs(r)", "Cl(f)", "Cl(r)"]
            coeffs.write_text(
                "# Force coefficients\n"
                "# dragDir         : (1 0 0)\n"
                "# liftDir         : (0 1 0)\n"
                "#\n"
                "# Time            \t" + "\t".join(f"{name:<18}" for name in names) + "\n"
            )
            self._files[key] = directory
        base = self._files[key] / "postProcessing"
        return base / "probes" / "0" / "p", base / "forceCoeffs" / "0" / "coefficient.dat"

    def write_outputs(self, directory: Path, t: float) -> None:
        probes, coeffs = self._open_files(Path(directory))
        stamp = f"{t:.10g}"
        with probes.open("a") as handle:
            handle.write(f"{stamp:>16}" + "".join(f"{v:>18.10g}" for v in self.pressure()) + "\n")
        cd, cl = self.drag, self.lift
        row = [cd, 0.0, cl, 0.0, 0.0, 0.0, cd / 2, cd / 2, 0.0, 0.0, cl / 2, cl / 2]
        with coeffs.open("a") as handle:
            handle.write(f"{stamp:<16}\t" + "\t".join(f"{v:.10e}" for v in row) + "\n")


# -- the test-double case ------------------------------------------------------------------


def double_case_files(
    spec: CaseSpec,
    *,
    step_sleep: float = 0.0,
    flow_options: Mapping[str, Any] | None = None,
    timeouts: Mapping[str, float] | None = None,
    library: str = DOUBLE_LIBRARY,
) -> dict[str, str]:
    """Files of a case that runs ``spec``'s coupling against the test double.

    The preCICE configuration and the controller's side are the recipe's own; the fluid is
    gymprecice's scripted partner with :class:`CylinderWake`, and preCICE is gymprecice's
    test double (``gymprecice.testing.fake_precice``). ``step_sleep`` slows each solver
    step down (seconds), to exercise timeouts and parallel envs. The partner steps with the
    recipe's solver time step (``spec.flow.dt``) and writes one probe and force row per
    step. With ``coupling="action"`` it subcycles in the action's window and writes every
    row before the step's ``advance``, as OpenFOAM's function objects listed before the
    preCICE adapter do: in that serial-explicit scheme the fluid's window-end ``advance``
    waits for the controller's next action, so a row written after it would never reach the
    controller that waits for it. With ``coupling="step"`` (one window per step,
    parallel-explicit) it writes each row once its window's exchange is done, so the
    controller never sees a row of the next step yet and runs are reproducible.
    ``library="precice"``
    couples the same two participants through real preCICE instead (both sides must use
    the same library).
    """
    argv = partner.command(
        "{precice_config}",  # the env's own copy, substituted by the "command" kind
        "Fluid",
        flow="gymprecice_tutorials.fake_flow:CylinderWake",
        library=library,
        options={"case": FLOW_FILE, "outputs": ".", **dict(flow_options or {})},
        python="{python}",
        write_outputs=".",
        write_every_step=spec.coupling == "action",
        dt=repr(float(spec.flow.dt)),
        step_sleep=f"{float(step_sleep):g}" if step_sleep else None,
    )
    config: dict[str, Any] = recipes.gymprecice_config(spec)
    config["environment"] = {"name": f"{spec.name}-double"}
    config["precice"] = {"config_file": "precice-config.xml", "library": library}
    config["physics_simulation_engine"] = {
        "solvers": {
            "fluid": {
                "kind": "command",
                "path": SOLVER_DIR,
                "participant": "Fluid",
                "options": {
                    "argv": argv,
                    "log_name": "partner.log",
                    # its probe and force files are OpenFOAM-format: read them with the
                    # OpenFOAM plugin's readers
                    "outputs": "openfoam",
                    # the partner needs no plugins: skip loading them (faster start)
                    "env": {"GYMPRECICE_DISABLE_PLUGINS": "1"},
                },
            }
        }
    }
    config["timeouts"] = {"reset": 120, "progress": 60, "finalize": 10, "kill_grace": 1}
    config["timeouts"].update(dict(timeouts or {}))
    return {
        "precice-config.xml": recipes.precice_config(spec),
        "gymprecice-config.json": json.dumps(config, indent=2) + "\n",
        f"{SOLVER_DIR}/{FLOW_FILE}": spec_to_json(spec),
    }
