"""Scripted, deterministic fake physics for the partner participant (``partner.py``).

Real solvers take minutes per episode; tests of the coupling, of the env and of output
readers need a solver that answers in microseconds, reacts to what the controller writes,
and always answers the same way. A *flow* is that: a tiny state machine stepped once per
solver time step, which also says where the participant's mesh vertices are and what it
writes back.

* :class:`NullFlow` writes zeros and ignores what it reads.
* :class:`CylinderFlow` is a jet-controlled cylinder wake: a Stuart-Landau oscillator
  whose amplitude (vortex shedding) is damped by the jets' flow rate; drag and lift follow
  the amplitude and phase; pressure on the cylinder and in the wake follows both. It can
  write OpenFOAM-like ``probes`` and ``forceCoeffs`` files.
* :class:`JetController` is a scripted controller: a synthetic-jet flow rate
  ``Q(t) = amplitude * sin(2 pi frequency t)`` (``jet1`` blows what ``jet2`` sucks).
* :class:`FlapFluid` / :class:`FlapSolid` are a fluid and an elastic flap coupled by a
  contracting fixed-point map, so implicit coupling converges in a few iterations.

Meshes are placed by name: a mesh name containing the dash-separated token ``jet1``/``jet2``
sits on the cylinder's jets, ``cylinder``/``surface`` on its surface, ``flap``/``solid`` on
the flap, ``actuator``/``inlet`` on the inlet; anything else is a short line of vertices.
:func:`fake_cylinder_geometry` gives the jets' coordinates, normals and areas for code
that plays the controller itself.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.fields import Field, grid_points
from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.plugin.solver import InterfaceGeometry

__all__ = [
    "CYLINDER_CENTER",
    "CYLINDER_RADIUS",
    "CylinderFlow",
    "FlapFluid",
    "FlapSolid",
    "Flow",
    "JetController",
    "NullFlow",
    "fake_cylinder_geometry",
    "mesh_vertices",
    "place_jets",
]

CYLINDER_CENTER = np.array([0.0, 0.0])
CYLINDER_RADIUS = 0.05
JET_ANGLES_DEG = {"jet1": 90.0, "jet2": 270.0}
JET_WIDTH_DEG = 10.0
JET_FACES = 8
SURFACE_POINTS = 32
FLAP_HEIGHT = 1.0

Inputs = Mapping[tuple[str, str], np.ndarray]


def _tokens(mesh: str) -> set[str]:
    return {t.lower() for t in mesh.replace("_", "-").split("-")}


def _on_circle(angles_deg: np.ndarray) -> np.ndarray:
    rad = np.radians(angles_deg)
    return CYLINDER_CENTER + CYLINDER_RADIUS * np.stack([np.cos(rad), np.sin(rad)], axis=1)


def _jet_angles(jet: str) -> np.ndarray:
    centre = JET_ANGLES_DEG[jet]
    half = JET_WIDTH_DEG / 2
    edges = np.linspace(centre - half, centre + half, JET_FACES + 1)
    return 0.5 * (edges[1:] + edges[:-1])


def fake_cylinder_geometry() -> dict[str, InterfaceGeometry]:
    """The two jets of the fake cylinder: face centres (2-D), unit normals (3-D), areas.

    The controller side of a test can use these as its interface vertices; the fluid partner
    places its jet meshes at exactly these points.
    """
    out = {}
    for jet in JET_ANGLES_DEG:
        angles = _jet_angles(jet)
        coords = _on_circle(angles)
        normals2 = (coords - CYLINDER_CENTER) / CYLINDER_RADIUS
        normals = np.concatenate([normals2, np.zeros((len(coords), 1))], axis=1)
        arc = math.radians(JET_WIDTH_DEG / JET_FACES) * CYLINDER_RADIUS
        out[jet] = InterfaceGeometry(
            coordinates=coords, normals=normals, areas=np.full(len(coords), arc), patches=(jet,)
        )
    return out


def place_jets(env: Any) -> None:
    """Put a controller env's ``jet1`` and ``jet2`` interfaces at the fake cylinder's jets.

    What every scripted controller of the fake cylinder does first in ``__init__``, after
    ``super().__init__``: an :class:`~gymprecice.env.core.Adapter` or a multi-agent one.
    """
    jets = fake_cylinder_geometry()
    for name in JET_ANGLES_DEG:
        env.set_interface_vertices(name, jets[name].coordinates)


def mesh_vertices(mesh: str, dimensions: int) -> np.ndarray:
    """Deterministic vertex coordinates for a mesh, placed by the tokens of its name."""
    tokens = _tokens(mesh)
    if tokens & set(JET_ANGLES_DEG):
        jet = sorted(tokens & set(JET_ANGLES_DEG))[0]
        coords = _on_circle(_jet_angles(jet))
    elif tokens & {"cylinder", "surface"}:
        coords = _on_circle(np.linspace(0.0, 360.0, SURFACE_POINTS, endpoint=False))
    elif tokens & {"flap", "solid"}:
        n = 11 if "flap" in tokens else 6
        coords = np.stack([np.zeros(n), np.linspace(0.0, FLAP_HEIGHT, n)], axis=1)
    elif tokens & {"actuator", "inlet"}:
        coords = np.stack([np.full(5, -3.0), np.linspace(0.0, 4.0, 5)], axis=1)
    else:
        coords = np.stack([np.linspace(0.0, 1.0, 8), np.zeros(8)], axis=1)
    if dimensions == 3:
        coords = np.concatenate([coords, np.zeros((len(coords), 1))], axis=1)
    return np.ascontiguousarray(coords[:, :dimensions], dtype=float)


class Flow:
    """Base of every scripted flow: the hooks ``partner.py`` calls, with neutral defaults.

    Subclasses keep everything that evolves in ``self.state`` (a dict), so the default
    :meth:`checkpoint`/:meth:`restore` serve implicit coupling without extra code.
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        self.config = config
        self.participant = participant
        self.spec = config.participant(participant)
        self.options = dict(options or {})
        self.meshes: dict[str, np.ndarray] = {}
        self.state: dict[str, Any] = {}

    # -- geometry

    def mesh_coordinates(self, mesh: str) -> np.ndarray:
        """Vertices of a mesh this participant provides (remembered for :meth:`step`)."""
        coords = mesh_vertices(mesh, self.config.mesh(mesh).dimensions)
        self.meshes[mesh] = coords
        return coords

    def register_mesh(self, mesh: str, coordinates: np.ndarray) -> None:
        """Vertices of a received mesh with direct access, known after ``initialize``."""
        self.meshes[mesh] = np.asarray(coordinates, dtype=float)

    def access_region(self, mesh: str) -> np.ndarray:
        """Bounding box for ``set_mesh_access_region``: by default, all of space that matters."""
        dims = self.config.mesh(mesh).dimensions
        return np.array([-1.0e6, 1.0e6] * dims)

    # -- physics

    def step(self, t: float, dt: float, inputs: Inputs) -> None:
        """Advance the state from ``t`` to ``t + dt`` given the data read for this step."""

    def output(self, data: str, mesh: str) -> np.ndarray:
        """Values to write: ``(n,)`` for scalar data, ``(n, dim)`` for vector data."""
        n = len(self.meshes.get(mesh, ()))
        if self.config.data[data].kind == "scalar":
            return np.zeros(n)
        return np.zeros((n, self.config.mesh(mesh).dimensions))

    def checkpoint(self) -> Any:
        return copy.deepcopy(self.state)

    def restore(self, saved: Any) -> None:
        self.state = copy.deepcopy(saved)

    def summary(self) -> dict[str, float]:
        """A few numbers for the partner's per-window log line."""
        return {}

    def write_outputs(self, directory: Path, t: float) -> None:
        """Append rows at time ``t`` to solver output files under ``directory``.

        The partner calls it once per completed window, or once per solver step with
        ``--write-every-step``.
        """

    def field_names(self) -> tuple[str, ...]:
        """The fields :meth:`field` can draw (``env.render()``); none by default."""
        return ()

    def field(self, name: str, t: float) -> Field | None:
        """Field ``name`` of the current state at time ``t``, for core to draw."""
        return None


class NullFlow(Flow):
    """Writes zeros, ignores its input: the smallest participant that couples."""


def _normal_rate(values: np.ndarray, coords: np.ndarray) -> float:
    """Mean outward-normal velocity on a cylinder patch (a scalar stands for itself)."""
    if values.ndim == 1 or len(coords) == 0:
        return float(np.mean(values)) if values.size else 0.0
    rel = coords[:, :2] - CYLINDER_CENTER
    norms = np.linalg.norm(rel, axis=1, keepdims=True)
    normals = np.divide(rel, norms, out=np.zeros_like(rel), where=norms > 0)
    return float(np.mean(np.sum(values[:, :2] * normals, axis=1)))


class CylinderFlow(Flow):
    """A jet-controlled cylinder wake (Stuart-Landau oscillator), for drag-reduction tests.

    The shedding amplitude ``r`` obeys ``dr/dt = (sigma - gamma a^2) r - r^3`` (solved
    exactly per step, so any ``dt`` is stable), the phase turns at ``omega``; ``a`` is the
    jets' mean normal velocity magnitude. ``Cd = cd0 + kd r^2 + ka a^2`` and
    ``Cl = r cos(phase) + kl (q_jet1 - q_jet2)``: blowing hard enough quiets the wake and
    lowers the drag, at a price. Options: ``sigma``, ``gamma``, ``omega``, ``cd0``, ``kd``,
    ``ka``, ``kl``, ``r0``, ``probes`` (number of wake probes, default 151).
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        opt = self.options
        self.sigma = float(opt.get("sigma", 1.0))
        self.gamma = float(opt.get("gamma", 1.0))
        self.omega = float(opt.get("omega", 2 * math.pi * 3.0))
        self.cd0 = float(opt.get("cd0", 3.0))
        self.kd = float(opt.get("kd", 0.2))
        self.ka = float(opt.get("ka", 0.02))
        self.kl = float(opt.get("kl", 0.5))
        n_probes = int(opt.get("probes", 151))
        x = np.linspace(0.1, 0.6, n_probes)
        y = 0.08 * np.sin(np.arange(n_probes) * 0.7)
        self.probes = np.stack([x, y], axis=1)
        self.state = {"r": float(opt.get("r0", 1.0)), "phase": 0.0, "q1": 0.0, "q2": 0.0}
        self._headers_written: set[Path] = set()

    @property
    def actuation(self) -> float:
        return math.sqrt(0.5 * (self.state["q1"] ** 2 + self.state["q2"] ** 2))

    @property
    def drag(self) -> float:
        return self.cd0 + self.kd * self.state["r"] ** 2 + self.ka * self.actuation**2

    @property
    def lift(self) -> float:
        s = self.state
        return s["r"] * math.cos(s["phase"]) + self.kl * (s["q1"] - s["q2"])

    def step(self, t: float, dt: float, inputs: Inputs) -> None:
        rates: dict[str, list[float]] = {"jet1": [], "jet2": []}
        for (_data, mesh), values in inputs.items():
            jets = _tokens(mesh) & set(rates)
            if jets:
                coords = self.meshes.get(mesh, np.zeros((0, 2)))
                rates[sorted(jets)[0]].append(_normal_rate(np.asarray(values), coords))
        s = self.state
        s["q1"] = float(np.mean(rates["jet1"])) if rates["jet1"] else 0.0
        s["q2"] = float(np.mean(rates["jet2"])) if rates["jet2"] else 0.0
        lam = self.sigma - self.gamma * self.actuation**2
        r2 = s["r"] ** 2
        if abs(lam) < 1e-12:
            r2 = r2 / (1.0 + 2.0 * r2 * dt)
        else:
            growth = math.exp(2.0 * lam * dt)
            r2 = lam * r2 * growth / (lam + r2 * (growth - 1.0))
        s["r"] = math.sqrt(max(r2, 0.0))
        s["phase"] = (s["phase"] + self.omega * dt) % (2 * math.pi)

    def pressure(self, coords: np.ndarray) -> np.ndarray:
        """Pressure at points: a steady part plus a wave that the shedding drives."""
        rel = coords[:, :2] - CYLINDER_CENTER
        angle = np.arctan2(rel[:, 1], rel[:, 0])
        dist = np.linalg.norm(rel, axis=1)
        s = self.state
        steady = 1.0 - 2.0 * np.sin(angle) ** 2 * np.exp(-(dist - CYLINDER_RADIUS) * 4.0)
        wave = s["r"] * np.cos(s["phase"] - 12.0 * rel[:, 0]) * np.sin(angle)
        return steady + wave + self.ka * self.actuation * np.cos(angle)

    def output(self, data: str, mesh: str) -> np.ndarray:
        coords = self.meshes.get(mesh, np.zeros((0, 2)))
        if self.config.data[data].kind == "scalar":
            return self.pressure(coords)
        n = len(coords)
        dims = self.config.mesh(mesh).dimensions
        out = np.zeros((n, dims))
        if n:
            out[:, 0] = self.drag / n
            out[:, 1] = self.lift / n
        return out

    def summary(self) -> dict[str, float]:
        return {"Cd": self.drag, "Cl": self.lift, "q": self.actuation}

    def field_names(self) -> tuple[str, ...]:
        return ("p",)

    def field(self, name: str, t: float) -> Field | None:
        """The pressure of :meth:`pressure` on a grid around the cylinder and its wake."""
        if name != "p":
            return None
        points, _ = grid_points(np.linspace(-0.2, 0.8, 61), np.linspace(-0.2, 0.2, 25))
        outside = np.linalg.norm(points - CYLINDER_CENTER, axis=1) > CYLINDER_RADIUS
        points = points[outside]
        return Field("p", t, points, self.pressure(points), label="p (fake)")

    def write_outputs(self, directory: Path, t: float) -> None:
        probes = Path(directory) / "postProcessing" / "probes" / "0" / "p"
        coeffs = Path(directory) / "postProcessing" / "forceCoeffs" / "0" / "coefficient.dat"
        if probes not in self._headers_written:
            probes.parent.mkdir(parents=True, exist_ok=True)
            lines = [f"# Probe {i} ({x:g} {y:g} 0)" for i, (x, y) in enumerate(self.probes)]
            lines.append(
                "#" + "Probe".rjust(15) + "".join(f"{i:>15}" for i in range(len(self.probes)))
            )
            lines.append("#" + "Time".rjust(15))
            probes.write_text("\n".join(lines) + "\n")
            self._headers_written.add(probes)
        if coeffs not in self._headers_written:
            coeffs.parent.mkdir(parents=True, exist_ok=True)
            names = ["Cd", "Cs", "Cl", "CmRoll", "CmPitch", "CmYaw"]
            names += ["Cd(f)", "Cd(r)", "Cs(f)", "Cs(r)", "Cl(f)", "Cl(r)"]
            header = [
                "# Force coefficients",
                "# dragDir       : (1.00000000e+00 0.00000000e+00 0.00000000e+00)",
                "# liftDir       : (0.00000000e+00 1.00000000e+00 0.00000000e+00)",
                "#",
                "# Time          \t" + "\t".join(f"{n:<16}" for n in names).rstrip(),
            ]
            coeffs.write_text("\n".join(header) + "\n")
            self._headers_written.add(coeffs)
        stamp = f"{t:.10g}"
        p = self.pressure(self.probes)
        with probes.open("a") as fh:
            fh.write(f"{stamp:>16}" + "".join(f"{v:>15.6g}" for v in p) + "\n")
        cd, cl = self.drag, self.lift
        row = [cd, 0.0, cl, 0.0, 0.0, 0.0, cd / 2, cd / 2, 0.0, 0.0, cl / 2, cl / 2]
        with coeffs.open("a") as fh:
            fh.write(f"{stamp:<16}\t" + "\t".join(f"{v:.8e}" for v in row) + "\n")


class JetController(Flow):
    """A scripted controller: synthetic jets with ``Q(t) = amplitude sin(2 pi frequency t)``.

    Writes normal velocity ``+Q`` on ``jet1`` meshes and ``-Q`` on ``jet2`` meshes (any other
    vector data gets ``+Q`` along x); remembers the mean of everything it reads. Options:
    ``amplitude`` (default 1.0), ``frequency`` (default 1.0; 0 gives a constant jet).
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        self.amplitude = float(self.options.get("amplitude", 1.0))
        self.frequency = float(self.options.get("frequency", 1.0))
        self.state = {"t": 0.0, "read": {}}

    def rate(self, t: float) -> float:
        if self.frequency == 0:
            return self.amplitude
        return self.amplitude * math.sin(2 * math.pi * self.frequency * t)

    def step(self, t: float, dt: float, inputs: Inputs) -> None:
        self.state["t"] = t + dt
        self.state["read"] = {
            f"{d}@{m}": float(np.mean(v)) if np.size(v) else 0.0 for (d, m), v in inputs.items()
        }

    def output(self, data: str, mesh: str) -> np.ndarray:
        coords = self.meshes.get(mesh, np.zeros((0, 2)))
        q = self.rate(self.state["t"])
        if self.config.data[data].kind == "scalar":
            return np.full(len(coords), q)
        dims = self.config.mesh(mesh).dimensions
        tokens = _tokens(mesh)
        out = np.zeros((len(coords), dims))
        if tokens & set(JET_ANGLES_DEG):
            sign = -1.0 if "jet2" in tokens else 1.0
            rel = coords[:, :2] - CYLINDER_CENTER
            normals = rel / np.linalg.norm(rel, axis=1, keepdims=True)
            out[:, :2] = sign * q * normals
        else:
            out[:, 0] = q
        return out

    def summary(self) -> dict[str, float]:
        return {"Q": self.rate(self.state["t"]), **self.state["read"]}


class FlapFluid(Flow):
    """Fluid side of a fake FSI: the force on the flap eases as the flap bends away.

    ``F = f0 (1 + u_in) - k_fb d``, with ``u_in`` the mean inlet velocity written by a
    controller and ``d`` the mean flap displacement read from the solid. Written as an
    x-force spread over the flap vertices. Options: ``f0`` (default 1.0), ``k_fb`` (0.5).
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        self.f0 = float(self.options.get("f0", 1.0))
        self.k_fb = float(self.options.get("k_fb", 0.5))
        self.state = {"force": self.f0, "u_in": 0.0, "d": 0.0}

    def step(self, t: float, dt: float, inputs: Inputs) -> None:
        s = self.state
        for (data, _mesh), values in inputs.items():
            v = np.asarray(values)
            first = v[:, 0] if v.ndim == 2 else v
            if data == "Displacement":
                s["d"] = float(np.mean(first)) if first.size else 0.0
            elif data == "Velocity":
                s["u_in"] = float(np.mean(first)) if first.size else 0.0
        s["force"] = self.f0 * (1.0 + s["u_in"]) - self.k_fb * s["d"]

    def output(self, data: str, mesh: str) -> np.ndarray:
        out = super().output(data, mesh)
        n = len(out)
        if n and data == "Force":
            if out.ndim == 2:
                out[:, 0] = self.state["force"] / n
            else:
                out[:] = self.state["force"] / n
        return out

    def summary(self) -> dict[str, float]:
        return {"F": self.state["force"], "d": self.state["d"], "u_in": self.state["u_in"]}

    def field_names(self) -> tuple[str, ...]:
        return ("p",)

    def field(self, name: str, t: float) -> Field | None:
        """A pressure that the force raises in front of the flap (x < 0)."""
        if name != "p":
            return None
        points, triangles = grid_points(np.linspace(-1.5, 1.5, 31), np.linspace(0.0, 2.0, 21))
        x, y = points[:, 0], points[:, 1]
        bump = np.exp(-(x**2) - 0.5 * (y - 0.5 * FLAP_HEIGHT) ** 2)
        values = self.state["force"] * np.tanh(-4.0 * x) * bump + 0.1 * self.state["u_in"]
        return Field("p", t, points, values, triangles=triangles, label="p (fake)")


class FlapSolid(Flow):
    """Solid side of a fake FSI: a linear spring, ``d = F_total / stiffness``.

    The tip moves most: the displacement grows linearly with height. Option:
    ``stiffness`` (default 1.0).
    """

    def __init__(
        self,
        config: PreciceConfig,
        participant: str,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(config, participant, options)
        self.stiffness = float(self.options.get("stiffness", 1.0))
        self.state = {"d": 0.0, "force": 0.0}

    def step(self, t: float, dt: float, inputs: Inputs) -> None:
        total = 0.0
        for (data, _mesh), values in inputs.items():
            if data == "Force":
                v = np.asarray(values)
                total += float(np.sum(v[:, 0] if v.ndim == 2 else v))
        self.state["force"] = total
        self.state["d"] = total / self.stiffness

    def output(self, data: str, mesh: str) -> np.ndarray:
        out = super().output(data, mesh)
        coords = self.meshes.get(mesh)
        if data == "Displacement" and coords is not None and len(coords):
            shape = coords[:, 1] / FLAP_HEIGHT
            if out.ndim == 2:
                out[:, 0] = self.state["d"] * 2.0 * shape
            else:
                out[:] = self.state["d"] * 2.0 * shape
        return out

    def summary(self) -> dict[str, float]:
        return {"d": self.state["d"], "F": self.state["force"]}

    def field_names(self) -> tuple[str, ...]:
        return ("displacement",)

    def field(self, name: str, t: float) -> Field | None:
        """The flap (0.1 wide) bent by the spring's displacement, growing with height."""
        if name != "displacement":
            return None
        points, triangles = grid_points([-0.05, 0.05], np.linspace(0.0, FLAP_HEIGHT, 11))
        disp = np.zeros_like(points)
        disp[:, 0] = self.state["d"] * 2.0 * points[:, 1] / FLAP_HEIGHT
        return Field(
            "displacement", t, points, disp, triangles=triangles, displacement=disp, label="|d|"
        )


class ClockFlow(Flow):
    """Writes the end time of the last step it computed, everywhere: data that names its window.

    A controller that reads it can tell whether an observation was computed for the step
    it just took, or is left over from an earlier one (stale-data tests).
    """

    def step(self, t: float, dt: float, inputs: Inputs) -> None:
        self.state["t"] = t + dt

    def output(self, data: str, mesh: str) -> np.ndarray:
        return super().output(data, mesh) + self.state.get("t", 0.0)
