"""Parametric recipes for the OpenFOAM tutorial cases.

Every file of the packaged cases under ``gymprecice_tutorials/cases/`` is written by this
module; the committed copies are its output for the default parameters (a test checks that
they agree). A case directory holds::

    <case>/gymprecice-config.json     explicit form (solver "fluid", kind "openfoam")
    <case>/precice-config.xml         preCICE v3: Controller <-> Fluid, parallel-explicit
    <case>/fluid-openfoam/            OpenFOAM case (pimpleFoam), no mesh, no snapshot
        0/U 0/p
        constant/transportProperties constant/turbulenceProperties constant/momentumTransport
        system/blockMeshDict system/controlDict system/fvSchemes system/fvSolution
        system/decomposeParDict system/preciceDict
        system/probes system/forceCoeffs          function objects, included by controlDict
        system/preciceAdapterFunctionObject       the preCICE adapter, included by controlDict

The flow is the Schäfer-Turek 2D-2 benchmark (channel 2.2 x 0.41, cylinder D = 0.1 at
(0.2, 0.2), parabolic inflow with Umax = 1.5, nu = 1e-3, Re = Umean D / nu = 100). The mesh
is a structured multi-block mesh: an O-grid of eight sectors around the cylinder inside a
square box, and Cartesian blocks between the box and the channel walls, inlet and outlet.
The top and bottom O-grid sectors are split at 90° ± w/2 and 270° ± w/2, so the jet patches
``jet1`` / ``jet2`` (jet cylinder) cover exactly the angular width ``w``.

Uncoupled runs (pre-run to developed shedding, validation, tests) call
:func:`make_uncoupled`, which empties ``system/preciceAdapterFunctionObject``: controlDict
includes it with a plain ``#include``, so a coupled run never starts without the adapter.

Command line::

    python -m gymprecice_tutorials.recipes write jet_cylinder DIR [--cells-per-jet N ...]
    python -m gymprecice_tutorials.recipes regenerate     # rewrite the packaged cases
    python -m gymprecice_tutorials.recipes info [NAME]    # block counts and cell estimate
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

CASES_DIR = Path(__file__).resolve().parent / "cases"
FLUID_DIR = "fluid-openfoam"
PRECICE_FO_FILE = "system/preciceAdapterFunctionObject"

#: "jets": two jets (patches jet1, jet2) set by the controller; "rotation": the whole
#: cylinder wall (patch cylinder) moves with the velocity the controller sets
Control = Literal["jets", "rotation"]
#: How one action reaches the solver (see :attr:`CaseSpec.coupling`).
Coupling = Literal["step", "action"]


# --------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Geometry:
    """Channel, cylinder and jets (lengths in metres, angles in degrees)."""

    length: float = 2.2
    height: float = 0.41
    diameter: float = 0.1
    centre: tuple[float, float] = (0.2, 0.2)
    #: extent of the 2D mesh in z (one cell); forces are per this depth
    depth: float = 0.01
    #: half side of the square box that holds the O-grid around the cylinder
    box_half: float = 0.1
    #: angular width of each jet; jets are centred at 90° and 270°
    jet_width: float = 10.0

    @property
    def radius(self) -> float:
        return self.diameter / 2

    def check(self) -> None:
        cx, cy = self.centre
        s = self.box_half
        if not self.radius < s:
            raise ValueError("box_half must be larger than the cylinder radius")
        if not (s < cx and s < cy and cy + s < self.height and cx + s < self.length):
            raise ValueError("the box around the cylinder must lie inside the channel")
        if not 0 < self.jet_width < 80:
            raise ValueError("jet_width must lie in (0, 80) degrees")


@dataclass(frozen=True)
class Resolution:
    """Mesh resolution knobs; every block count derives from these three numbers.

    * ``cells_per_jet``: cells across one jet (the jet width). The tangential spacing is
      uniform around the cylinder, so the wall has ``cells_per_jet * 360 / jet_width``
      faces (with or without jets); ``h_box`` is the resulting spacing along the box.
    * ``wall_cell``: height of the first cell at the cylinder wall, as a fraction of D.
      The O-grid cells grow geometrically from it to ``h_box`` at the box; their number
      follows (and the growth is then adjusted so that the last cell is ``h_box``).
    * ``wake_grading``: last/first cell size along x in the wake (first cell = ``h_box``);
      the inlet, top and bottom blocks are uniform with spacing ``h_box``.
    """

    cells_per_jet: int = 3
    wall_cell: float = 0.01
    wake_grading: float = 4.0

    @classmethod
    def coarse(cls) -> Resolution:
        """A few thousand cells: quick start, smoke tests."""
        return cls(cells_per_jet=2, wall_cell=0.02, wake_grading=6.0)

    @classmethod
    def default(cls) -> Resolution:
        """The training cases."""
        return cls()

    @classmethod
    def fine(cls) -> Resolution:
        """The validation against the Schäfer-Turek reference (docs/validation.md)."""
        return cls(cells_per_jet=4, wall_cell=0.0075, wake_grading=4.0)


@dataclass(frozen=True)
class Flow:
    """Inflow, viscosity and time stepping."""

    u_max: float = 1.5
    nu: float = 1e-3
    dt: float = 5e-4
    #: PIMPLE outer iterations per time step. 1 is PISO: cheaper, but its lagged
    #: convective flux over-predicts the lift amplitude by several per cent at dt = 5e-4
    #: (see docs/validation.md); 2 removes most of that error.
    outer_correctors: int = 2

    @property
    def u_mean(self) -> float:
        return 2.0 * self.u_max / 3.0


@dataclass(frozen=True)
class CaseSpec:
    """Everything that makes one tutorial case."""

    name: str
    control: Control
    geometry: Geometry = field(default_factory=Geometry)
    resolution: Resolution = field(default_factory=Resolution)
    flow: Flow = field(default_factory=Flow)
    #: RL episode: number of actions and solver time steps per action
    actions_per_episode: int = 80
    steps_per_action: int = 50
    #: ``"step"``: one preCICE time window per solver step (parallel-explicit); the
    #: controller writes every window and core's ``ramp`` schedule moves the actuator from
    #: the previous action to the new one. ``"action"``: one time window per action
    #: (serial-explicit, the controller first); the solver subcycles inside it, the OpenFOAM
    #: adapter reads the data at the end of each substep and preCICE interpolates the written
    #: action linearly across the window (``waveform-degree="1"``): the same ramp with
    #: ``steps_per_action`` times fewer exchanges.
    coupling: Coupling = "step"
    #: simulated time of the uncoupled pre-run that gives the developed-shedding snapshot
    prerun_end_time: float = 6.0
    #: optional episode starts (simulated times before ``prerun_end_time``) that the
    #: pre-run also writes: a library of developed-flow snapshots at different shedding
    #: phases. The OpenFOAM plugin splits them once into training starts and held-out
    #: evaluation starts (every fourth, ``eval_fraction`` 0.25); training resets draw from
    #: the first, ``gymprecice evaluate`` / ``baseline`` from the second. Empty: every
    #: episode starts from ``prerun_end_time``.
    snapshots: tuple[float, ...] = ()
    n_procs: int = 2
    #: write fields every this many seconds of simulated time (0: only at endTime)
    write_interval: float = 0.0
    #: controlDict endTime; None: prerun_end_time + episode_time (a coupled run restarts
    #: from the pre-run snapshot and preCICE ends it after max-time)
    end_time: float | None = None

    @property
    def episode_time(self) -> float:
        return self.actions_per_episode * self.steps_per_action * self.flow.dt

    @property
    def action_time(self) -> float:
        return self.steps_per_action * self.flow.dt

    @property
    def time_window(self) -> float:
        """The preCICE time window: one solver step, or one action (:attr:`coupling`)."""
        if self.coupling not in ("step", "action"):
            raise ValueError(f"coupling must be 'step' or 'action', got {self.coupling!r}")
        return self.action_time if self.coupling == "action" else self.flow.dt

    @property
    def interfaces(self) -> tuple[str, ...]:
        if self.control == "jets":
            return ("jet1", "jet2")
        return ("cylinder",)


#: The training case of the ``*-fast`` environments: the quick start's coarse mesh (3,580
#: cells) with PISO on one rank at twice the time step, one preCICE time window per action
#: (25 substeps of 1e-3 s), 1 s episodes, and eight start snapshots spread over one
#: shedding period (two held out for evaluation). Half the CPU of the quick start per
#: simulated second; its physics against Schäfer-Turek is in docs/training.md.
FAST_TRAINING = {
    "resolution": Resolution.coarse(),
    "flow": Flow(dt=1e-3, outer_correctors=1),
    "steps_per_action": 25,
    "actions_per_episode": 40,
    "coupling": "action",
    "prerun_end_time": 5.0,
    "snapshots": (4.7, 4.74, 4.78, 4.82, 4.86, 4.9, 4.94, 4.98),
    "n_procs": 1,
}

CASES: dict[str, CaseSpec] = {
    "jet_cylinder": CaseSpec(name="jet_cylinder", control="jets"),
    "rotating_cylinder": CaseSpec(name="rotating_cylinder", control="rotation"),
    "quickstart": CaseSpec(
        name="quickstart",
        control="jets",
        resolution=Resolution.coarse(),
        flow=Flow(outer_correctors=1),
        actions_per_episode=20,
        prerun_end_time=5.0,
        n_procs=1,
    ),
    "jet_cylinder_fast": CaseSpec(name="jet_cylinder_fast", control="jets", **FAST_TRAINING),
    "rotating_cylinder_fast": CaseSpec(
        name="rotating_cylinder_fast", control="rotation", **FAST_TRAINING
    ),
}


def case_spec(name: str, **overrides: object) -> CaseSpec:
    """The packaged spec ``name`` with fields replaced by ``overrides``."""
    try:
        spec = CASES[name]
    except KeyError:
        raise KeyError(f"no case recipe {name!r}; the recipes are {sorted(CASES)}") from None
    return replace(spec, **overrides) if overrides else spec


# --------------------------------------------------------------------------------------
# Mesh
# --------------------------------------------------------------------------------------


def _geometric_ratio(n: int, length: float, last: float) -> float:
    """Expansion ratio (last/first) of ``n`` geometric cells over ``length`` ending in ``last``.

    The cells are ``last * q**-k`` (k = 0 .. n-1, from the far end); their sum decreases
    with the growth factor ``q``, so ``q`` is found by bisection.
    """
    if n <= 1:
        return 1.0

    def total(q: float) -> float:
        return sum(last * q**-k for k in range(n))

    lo, hi = 1e-3, 1e3
    for _ in range(200):
        mid = math.sqrt(lo * hi)
        if total(mid) > length:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi) ** (n - 1)


def _count_for_grading(length: float, first: float, ratio: float) -> int:
    """Number of geometric cells over ``length`` from ``first`` growing to ``ratio * first``."""
    if abs(ratio - 1.0) < 1e-9:
        return max(1, round(length / first))
    # total = first * (q^n - 1) / (q - 1) with q^(n-1) = ratio; solve for n.
    best, best_err = 1, math.inf
    for n in range(1, 100000):
        q = ratio ** (1.0 / (n - 1)) if n > 1 else 1.0
        tot = first * n if n == 1 else first * (q**n - 1) / (q - 1)
        err = abs(tot - length)
        if err < best_err:
            best, best_err = n, err
        if tot > length:
            break
    return best


@dataclass(frozen=True)
class BlockCounts:
    """Cell counts of the blocks (derived from :class:`Resolution`)."""

    n_jet: int
    n_arc: int  # sector between the box diagonal and the jet edge
    n_side: int  # left/right 90° sectors = cells along one box side
    n_radial: int
    radial_grading: float
    n_left: int
    n_bottom: int
    n_top: int
    n_wake: int
    wake_grading: float
    h_box: float

    @property
    def wall_faces(self) -> int:
        return 2 * self.n_side + 2 * (2 * self.n_arc + self.n_jet)

    @property
    def cells(self) -> int:
        ny = self.n_bottom + self.n_side + self.n_top
        nx_mid = 2 * self.n_arc + self.n_jet
        return (
            self.wall_faces * self.n_radial
            + (self.n_left + self.n_wake) * ny
            + nx_mid * (self.n_bottom + self.n_top)
        )


def block_counts(geometry: Geometry, resolution: Resolution) -> BlockCounts:
    geometry.check()
    w = geometry.jet_width
    n_jet = resolution.cells_per_jet
    if n_jet < 1 or not 0 < resolution.wall_cell < 0.5:
        raise ValueError("cells_per_jet must be >= 1 and wall_cell in (0, 0.5)")
    per_degree = n_jet / w
    n_arc = max(1, round((45.0 - w / 2) * per_degree))
    n_side = max(1, round(90.0 * per_degree))
    s = geometry.box_half
    cx, cy = geometry.centre
    h_box = 2 * s / n_side
    # O-grid: geometric cells from wall_cell * D to h_box over the (side) radial extent
    extent = s - geometry.radius
    first = resolution.wall_cell * geometry.diameter
    if h_box <= first:
        n_radial = max(2, round(extent / h_box))
    else:
        growth = (extent - first) / (extent - h_box)
        n_radial = max(2, round(1 + math.log(h_box / first) / math.log(growth)))
    radial_grading = _geometric_ratio(n_radial, extent, h_box)
    n_wake = _count_for_grading(geometry.length - cx - s, h_box, resolution.wake_grading)
    return BlockCounts(
        n_jet=n_jet,
        n_arc=n_arc,
        n_side=n_side,
        n_radial=n_radial,
        radial_grading=radial_grading,
        n_left=max(1, round((cx - s) / h_box)),
        n_bottom=max(1, round((cy - s) / h_box)),
        n_top=max(1, round((geometry.height - cy - s) / h_box)),
        n_wake=n_wake,
        wake_grading=resolution.wake_grading,
        h_box=h_box,
    )


def _fmt(x: float) -> str:
    text = f"{x:.10g}"
    return "0" if text == "-0" else text


def _vec(*xs: float) -> str:
    return "(" + " ".join(_fmt(x) for x in xs) + ")"


def blockmesh_dict(geometry: Geometry, resolution: Resolution, *, jets: bool = True) -> str:
    """``system/blockMeshDict`` for the channel with the cylinder.

    With ``jets`` the wall sectors 90° ± w/2 and 270° ± w/2 are the patches ``jet1`` and
    ``jet2``; without, they belong to ``cylinder`` (the block topology is the same).
    """
    c = block_counts(geometry, resolution)
    cx, cy = geometry.centre
    r, s, L, H = geometry.radius, geometry.box_half, geometry.length, geometry.height
    hw = geometry.jet_width / 2
    z0, z1 = -geometry.depth / 2, geometry.depth / 2
    delta = s * math.tan(math.radians(hw))  # box-edge offset of the jet rays

    points: list[tuple[float, float]] = []
    index: dict[str, int] = {}

    def add(name: str, x: float, y: float) -> int:
        index[name] = len(points)
        points.append((x, y))
        return index[name]

    # O-grid ray angles, counter-clockwise from the lower-right box diagonal
    angles = [-45.0, 45.0, 90 - hw, 90 + hw, 135.0, 225.0, 270 - hw, 270 + hw]
    for k, a in enumerate(angles):
        t = math.radians(a)
        add(f"c{k}", cx + r * math.cos(t), cy + r * math.sin(t))
    for k, a in enumerate(angles):
        t = math.radians(a)
        m = max(abs(math.cos(t)), abs(math.sin(t)))
        add(f"b{k}", cx + s * math.cos(t) / m, cy + s * math.sin(t) / m)
    # Cartesian grid lines; box corners/jet rays are already points b*
    xs = [0.0, cx - s, cx - delta, cx + delta, cx + s, L]
    ys = [0.0, cy - s, cy + s, H]
    box_of = {
        (1, 1): "b5", (2, 1): "b6", (3, 1): "b7", (4, 1): "b0",
        (1, 2): "b4", (2, 2): "b3", (3, 2): "b2", (4, 2): "b1",
    }  # fmt: skip
    grid: dict[tuple[int, int], int] = {}
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            if (i, j) in box_of:
                grid[(i, j)] = index[box_of[(i, j)]]
            else:
                grid[(i, j)] = add(f"g{i}{j}", x, y)
    n_front = len(points)

    def hexa(v: Sequence[int]) -> str:
        return " ".join(str(i) for i in v) + " " + " ".join(str(i + n_front) for i in v)

    blocks: list[str] = []
    quads: list[tuple[int, int, int, int]] = []  # front (z0) vertices of each block, CCW
    faces: dict[str, list[str]] = {
        "inlet": [], "outlet": [], "walls": [], "cylinder": [], "jet1": [], "jet2": [],
    }  # fmt: skip

    def quad(a: int, b: int) -> str:
        # face swept from the front edge a -> b to the back plane; with a -> b clockwise
        # around its block (interior on the right) the face normal points out of the block
        return f"({a} {a + n_front} {b + n_front} {b})"

    # O-grid sectors: local x1 radial (wall -> box), x2 counter-clockwise
    tang = [c.n_side, c.n_arc, c.n_jet, c.n_arc, c.n_side, c.n_arc, c.n_jet, c.n_arc]
    wall_patch = ["cylinder", "cylinder", "jet1", "cylinder"] * 2
    wall_patch[6] = "jet2"
    if not jets:
        wall_patch = ["cylinder"] * 8
    for k in range(8):
        k2 = (k + 1) % 8
        ci, ck = index[f"c{k}"], index[f"c{k2}"]
        bi, bk = index[f"b{k}"], index[f"b{k2}"]
        quads.append((ci, bi, bk, ck))
        blocks.append(
            f"hex ({hexa(quads[-1])}) ({c.n_radial} {tang[k]} 1) "
            f"simpleGrading ({_fmt(c.radial_grading)} 1 1)"
        )
        faces[wall_patch[k]].append(quad(ci, ck))

    # Cartesian blocks (all grid cells except the three that hold the O-grid)
    nx = [c.n_left, c.n_arc, c.n_jet, c.n_arc, c.n_wake]
    ny = [c.n_bottom, c.n_side, c.n_top]
    for j in range(3):
        for i in range(5):
            if j == 1 and i in (1, 2, 3):
                continue
            v = (grid[(i, j)], grid[(i + 1, j)], grid[(i + 1, j + 1)], grid[(i, j + 1)])
            gx = c.wake_grading if i == 4 else 1.0
            quads.append(v)
            blocks.append(f"hex ({hexa(v)}) ({nx[i]} {ny[j]} 1) simpleGrading ({_fmt(gx)} 1 1)")
            if i == 0:
                faces["inlet"].append(quad(v[0], v[3]))
            if i == 4:
                faces["outlet"].append(quad(v[2], v[1]))
            if j == 0:
                faces["walls"].append(quad(v[1], v[0]))
            if j == 2:
                faces["walls"].append(quad(v[3], v[2]))

    edges: list[str] = []
    for k in range(8):
        k2 = (k + 1) % 8
        mid = math.radians(0.5 * (angles[k] + (angles[k2] if k2 else angles[k2] + 360)))
        mx, my = cx + r * math.cos(mid), cy + r * math.sin(mid)
        a, b = index[f"c{k}"], index[f"c{k2}"]
        edges.append(f"arc {a} {b} {_vec(mx, my, z0)}")
        edges.append(f"arc {a + n_front} {b + n_front} {_vec(mx, my, z1)}")

    front = [f"    {_vec(x, y, z0)} // {i}" for i, (x, y) in enumerate(points)]
    back = [f"    {_vec(x, y, z1)} // {i + n_front}" for i, (x, y) in enumerate(points)]

    def patch(name: str, kind: str, fs: list[str]) -> str:
        body = "\n".join(f"            {f}" for f in fs)
        return f"    {name}\n    {{\n        type {kind};\n        faces\n        (\n{body}\n        );\n    }}"

    patches = [
        patch("inlet", "patch", faces["inlet"]),
        patch("outlet", "patch", faces["outlet"]),
        patch("walls", "wall", faces["walls"]),
        patch("cylinder", "wall", faces["cylinder"]),
    ]
    if jets:
        patches += [patch("jet1", "wall", faces["jet1"]), patch("jet2", "wall", faces["jet2"])]
    empty = [f"            ({' '.join(str(i) for i in reversed(q))})" for q in quads]
    empty += [f"            ({' '.join(str(i + n_front) for i in q)})" for q in quads]
    patches.append(
        "    frontAndBack\n    {\n        type empty;\n        faces\n        (\n"
        + "\n".join(empty)
        + "\n        );\n    }"
    )
    info = (
        f"// cells: {c.cells} (wall faces {c.wall_faces}, radial {c.n_radial} with grading "
        f"{c.radial_grading:.3g}, wake {c.n_wake} x-cells, h_box {c.h_box:.4g})"
    )
    return (
        _header("dictionary", "system", "blockMeshDict")
        + f"{info}\n\nscale 1;\n\nvertices\n(\n"
        + "\n".join(front + back)
        + "\n);\n\nblocks\n(\n"
        + "\n".join(f"    {b}" for b in blocks)
        + "\n);\n\nedges\n(\n"
        + "\n".join(f"    {e}" for e in edges)
        + "\n);\n\nboundary\n(\n"
        + "\n".join(patches)
        + "\n);\n\nmergePatchPairs\n(\n);\n"
        + _FOOTER
    )


# --------------------------------------------------------------------------------------
# Probes
# --------------------------------------------------------------------------------------


def probe_locations(geometry: Geometry) -> list[tuple[float, float, float]]:
    """The 151 pressure probes of Rabault et al. (2019), in this geometry's coordinates.

    In units of D around the cylinder centre: a wake grid of 9 x 7 points
    (x = 0.75, 1, 1.5, ..., 4.5; y = -1.5 ... 1.5 step 0.5), 4 x 4 points above and below
    the cylinder (x = -0.25, 0, 0.25, 0.5; y = ±1, ±1.5) and two rings of 36 points
    (every 10°, from 0°) at radii 0.7 D and 1.0 D. Order: wake grid, side grid, rings.
    As in the original layout, three ring points repeat grid points ((0, ±1) and (1, 0)).
    """
    d = geometry.diameter
    cx, cy = geometry.centre
    pts: list[tuple[float, float]] = []
    for x in (0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5):
        for y in (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5):
            pts.append((x, y))
    for x in (-0.25, 0.0, 0.25, 0.5):
        for y in (-1.5, -1.0, 1.0, 1.5):
            pts.append((x, y))
    for radius in (0.7, 1.0):
        for k in range(36):
            t = math.radians(10.0 * k)
            pts.append((radius * math.cos(t), radius * math.sin(t)))
    return [(round(cx + d * x, 12), round(cy + d * y, 12), 0.0) for x, y in pts]


# --------------------------------------------------------------------------------------
# OpenFOAM files
# --------------------------------------------------------------------------------------

_BANNER = """\
/*--------------------------------*- C++ -*----------------------------------*\\
  gymprecice tutorial case, written by gymprecice_tutorials.recipes:
  change the recipe and regenerate rather than editing this file.
\\*---------------------------------------------------------------------------*/
"""
_FOOTER = "\n// ************************************************************************* //\n"


def _header(cls: str, location: str, obj: str) -> str:
    return (
        _BANNER
        + "FoamFile\n{\n    version     2.0;\n    format      ascii;\n"
        + f'    class       {cls};\n    location    "{location}";\n    object      {obj};\n}}\n\n'
    )


def _boundary(entries: dict[str, str]) -> str:
    lines = ["boundaryField", "{"]
    for name, body in entries.items():
        lines.append(f"    {name}")
        lines.append("    {")
        for stmt in body.strip().split("\n"):
            lines.append(f"        {stmt.strip()}")
        lines.append("    }")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _u_file(spec: CaseSpec) -> str:
    g, f = spec.geometry, spec.flow
    # parabolic inflow u(y) = 4 Umax y (H - y) / H^2, as a polynomial in y (fixedProfile)
    a1 = 4 * f.u_max / g.height
    a2 = -4 * f.u_max / g.height**2
    bcs = {
        "inlet": (
            "type            fixedProfile;\n"
            # Polynomial<vector>: (coefficient exponent) pairs, both of the field's type
            f"profile         polynomial ((({_fmt(a1)} 0 0) (1 1 1)) "
            f"(({_fmt(a2)} 0 0) (2 2 2)));\n"
            "direction       (0 1 0);\n"
            "origin          0;"
        ),
        "outlet": "type            inletOutlet;\ninletValue      uniform (0 0 0);\n"
        "value           uniform (0 0 0);",
        "walls": "type            noSlip;",
    }
    if spec.control == "rotation":
        bcs["cylinder"] = (
            "// wall velocity set by the preCICE adapter (rotation omega x r)\n"
            "type            fixedValue;\nvalue           uniform (0 0 0);"
        )
    else:
        bcs["cylinder"] = "type            noSlip;"
    if spec.control == "jets":
        for jet in ("jet1", "jet2"):
            bcs[jet] = (
                "// jet velocity set by the preCICE adapter\n"
                "type            fixedValue;\nvalue           uniform (0 0 0);"
            )
    bcs["frontAndBack"] = "type            empty;"
    return (
        _header("volVectorField", "0", "U")
        + "dimensions      [0 1 -1 0 0 0 0];\n\ninternalField   uniform (0 0 0);\n\n"
        + _boundary(bcs)
        + _FOOTER
    )


def _p_file(spec: CaseSpec) -> str:
    bcs = {
        "inlet": "type            zeroGradient;",
        "outlet": "type            fixedValue;\nvalue           uniform 0;",
        "walls": "type            zeroGradient;",
        "cylinder": "type            zeroGradient;",
    }
    if spec.control == "jets":
        bcs["jet1"] = "type            zeroGradient;"
        bcs["jet2"] = "type            zeroGradient;"
    bcs["frontAndBack"] = "type            empty;"
    return (
        _header("volScalarField", "0", "p")
        + "dimensions      [0 2 -2 0 0 0 0];\n\ninternalField   uniform 0;\n\n"
        + _boundary(bcs)
        + _FOOTER
    )


def _transport(spec: CaseSpec) -> str:
    return (
        _header("dictionary", "constant", "transportProperties")
        + "transportModel  Newtonian;\n\n"
        + f"nu              [0 2 -1 0 0 0 0] {_fmt(spec.flow.nu)};\n"
        + _FOOTER
    )


def _laminar(obj: str) -> str:
    return _header("dictionary", "constant", obj) + "simulationType  laminar;\n" + _FOOTER


def _end_time(spec: CaseSpec) -> float:
    if spec.end_time is not None:
        return spec.end_time
    return round(spec.prerun_end_time + spec.episode_time, 10)


def _control_dict(spec: CaseSpec) -> str:
    end = _end_time(spec)
    interval = spec.write_interval or end
    return (
        _header("dictionary", "system", "controlDict")
        + "application     pimpleFoam;\n\n"
        + "startFrom       latestTime;\nstartTime       0;\n\n"
        + f"stopAt          endTime;\nendTime         {_fmt(end)};\n\n"
        + f"deltaT          {_fmt(spec.flow.dt)};\n\n"
        + f"writeControl    adjustableRunTime;\nwriteInterval   {_fmt(interval)};\n"
        + "purgeWrite      0;\n\n"
        + "writeFormat     ascii;\nwritePrecision  10;\nwriteCompression off;\n\n"
        + "timeFormat      general;\ntimePrecision   8;\n\n"
        + "runTimeModifiable false;\n\nadjustTimeStep  no;\n\n"
        + "functions\n{\n"
        + '    #include "probes"\n'
        + '    #include "forceCoeffs"\n'
        + "    // the preCICE adapter; an uncoupled run empties this file (recipes.make_uncoupled)\n"
        + '    #include "preciceAdapterFunctionObject"\n'
        + "}\n"
        + _FOOTER
    )


def _probes(spec: CaseSpec) -> str:
    locs = "\n".join(f"        {_vec(*p)}" for p in probe_locations(spec.geometry))
    return (
        _BANNER
        + "// Included by controlDict: 151 pressure probes (Rabault et al. 2019 layout)\n\n"
        + 'probes\n{\n    type            probes;\n    libs            ("libsampling.so");\n'
        + "    writeControl    timeStep;\n    writeInterval   1;\n"
        + "    fields          (p);\n"
        + f"    probeLocations\n    (\n{locs}\n    );\n}}\n"
    )


def _force_coeffs(spec: CaseSpec) -> str:
    g, f = spec.geometry, spec.flow
    patches = " ".join(("cylinder", *(("jet1", "jet2") if spec.control == "jets" else ())))
    cx, cy = g.centre
    return (
        _BANNER
        + "// Included by controlDict: drag/lift coefficients on the cylinder wall, with\n"
        + "// Cd = 2 Fx / (rho Umean^2 D depth), Cl likewise (Schäfer-Turek definitions)\n\n"
        + 'forceCoeffs\n{\n    type            forceCoeffs;\n    libs            ("libforces.so");\n'
        + "    writeControl    timeStep;\n    writeInterval   1;\n"
        + f"    patches         ({patches});\n"
        + "    rho             rhoInf;\n    rhoInf          1;\n"
        + f"    CofR            {_vec(cx, cy, 0.0)};\n"
        + "    liftDir         (0 1 0);\n    dragDir         (1 0 0);\n"
        + "    pitchAxis       (0 0 1);\n"
        + f"    magUInf         {_fmt(f.u_mean)};\n"
        + f"    lRef            {_fmt(g.diameter)};\n"
        + f"    Aref            {_fmt(g.diameter * g.depth)};\n}}\n"
    )


PRECICE_FUNCTION_OBJECT = (
    "preCICE_Adapter\n{\n    type            preciceAdapterFunctionObject;\n"
    '    libs            ("libpreciceAdapterFunctionObject.so");\n}\n'
)
UNCOUPLED_FUNCTION_OBJECT = "// uncoupled run: the preCICE adapter function object is dropped\n"


def _precice_fo() -> str:
    return (
        _BANNER
        + "// Included by controlDict: the OpenFOAM-preCICE adapter (coupled runs)\n\n"
        + PRECICE_FUNCTION_OBJECT
    )


def _fv_schemes() -> str:
    return (
        _header("dictionary", "system", "fvSchemes")
        + "ddtSchemes\n{\n    default         backward;\n}\n\n"
        + "gradSchemes\n{\n    default         Gauss linear;\n}\n\n"
        + "divSchemes\n{\n    default         none;\n"
        + "    div(phi,U)      Gauss linearUpwind grad(U);\n"
        + "    div((nuEff*dev2(T(grad(U))))) Gauss linear;\n}\n\n"
        + "laplacianSchemes\n{\n    default         Gauss linear corrected;\n}\n\n"
        + "interpolationSchemes\n{\n    default         linear;\n}\n\n"
        + "snGradSchemes\n{\n    default         corrected;\n}\n"
        + _FOOTER
    )


def _fv_solution(spec: CaseSpec) -> str:
    return (
        _header("dictionary", "system", "fvSolution")
        + "solvers\n{\n"
        + "    p\n    {\n        solver          GAMG;\n        smoother        GaussSeidel;\n"
        + "        tolerance       1e-06;\n        relTol          0.01;\n    }\n\n"
        + "    pFinal\n    {\n        $p;\n        relTol          0;\n    }\n\n"
        + '    "(U|UFinal)"\n    {\n        solver          smoothSolver;\n'
        + "        smoother        symGaussSeidel;\n        tolerance       1e-08;\n"
        + "        relTol          0;\n    }\n}\n\n"
        + "PIMPLE\n{\n    momentumPredictor yes;\n"
        + f"    nOuterCorrectors {spec.flow.outer_correctors};\n"
        + "    nCorrectors     2;\n    nNonOrthogonalCorrectors 0;\n"
        + "    pRefCell        0;\n    pRefValue       0;\n}\n"
        + _FOOTER
    )


def _decompose(spec: CaseSpec) -> str:
    n = max(1, spec.n_procs)
    return (
        _header("dictionary", "system", "decomposeParDict")
        + f"numberOfSubdomains {n};\n\nmethod          simple;\n\n"
        + f"coeffs\n{{\n    n               ({n} 1 1);\n}}\n"
        + _FOOTER
    )


def _mesh_name(participant: str, interface: str) -> str:
    return f"{participant}-Mesh-{interface}"


def _precice_dict(spec: CaseSpec) -> str:
    blocks = []
    for k, name in enumerate(spec.interfaces, start=1):
        blocks.append(
            f"    Interface{k}\n    {{\n        mesh            {_mesh_name('Fluid', name)};\n"
            f"        patches         ({name});\n        locations       faceCenters;\n"
            "        readData        (Velocity);\n        writeData       ();\n    }"
        )
    return (
        _header("dictionary", "system", "preciceDict")
        + 'preciceConfig   "../precice-config.xml";\n\nparticipant     Fluid;\n\n'
        + "modules         (FF);\n\n"
        + "interfaces\n{\n"
        + "\n".join(blocks)
        + "\n}\n\nFF\n{\n    nameU           U;\n    nameP           p;\n}\n"
        + _FOOTER
    )


def precice_config(spec: CaseSpec) -> str:
    """``precice-config.xml`` (preCICE v3): the controller writes Velocity on its meshes."""
    meshes, fluid, controller, exchanges = [], [], [], []
    for name in spec.interfaces:
        cm, fm = _mesh_name("Controller", name), _mesh_name("Fluid", name)
        for m in (cm, fm):
            meshes.append(
                f'  <mesh name="{m}" dimensions="2">\n    <use-data name="Velocity" />\n  </mesh>'
            )
        fluid.append(f'    <provide-mesh name="{fm}" />')
        fluid.append(f'    <receive-mesh name="{cm}" from="Controller" />')
        fluid.append(f'    <read-data name="Velocity" mesh="{fm}" />')
        fluid.append(
            f'    <mapping:nearest-neighbor direction="read" from="{cm}" to="{fm}"'
            ' constraint="consistent" />'
        )
        controller.append(f'    <provide-mesh name="{cm}" />')
        controller.append(f'    <write-data name="Velocity" mesh="{cm}" />')
        exchanges.append(
            f'    <exchange data="Velocity" mesh="{cm}" from="Controller" to="Fluid" />'
        )
    # One window per action: serial-explicit with the controller first, so that the fluid
    # receives the window's action at its end and interpolates it linearly from the
    # previous one while it subcycles (parallel-explicit would apply it one window late).
    scheme = "serial-explicit" if spec.coupling == "action" else "parallel-explicit"
    data = (
        '  <data:vector name="Velocity" waveform-degree="1" />\n\n'
        if spec.coupling == "action"
        else '  <data:vector name="Velocity" />\n\n'
    )
    return (
        '<?xml version="1.0" encoding="UTF-8" ?>\n'
        "<!-- gymprecice tutorial case, written by gymprecice_tutorials.recipes -->\n"
        "<precice-configuration>\n"
        '  <log>\n    <sink filter="%Severity% > debug and %Rank% = 0"'
        ' format="---[precice] %ColorizedSeverity% %Message%" enabled="true" />\n  </log>\n\n'
        + data
        + "\n\n".join(meshes)
        + '\n\n  <participant name="Fluid">\n'
        + "\n".join(fluid)
        + '\n  </participant>\n\n  <participant name="Controller">\n'
        + "\n".join(controller)
        + "\n  </participant>\n\n"
        '  <m2n:sockets acceptor="Controller" connector="Fluid" exchange-directory=".." />\n\n'
        f"  <coupling-scheme:{scheme}>\n"
        '    <participants first="Controller" second="Fluid" />\n'
        f'    <max-time value="{_fmt(spec.episode_time)}" />\n'
        f'    <time-window-size value="{_fmt(spec.time_window)}" />\n'
        + "\n".join(exchanges)
        + f"\n  </coupling-scheme:{scheme}>\n</precice-configuration>\n"
    )


def gymprecice_config(spec: CaseSpec) -> dict[str, object]:
    """``gymprecice-config.json`` in the contract's explicit form."""
    return {
        "environment": {"name": spec.name},
        "precice": {"config_file": "precice-config.xml", "library": "precice"},
        "physics_simulation_engine": {
            "solvers": {
                "fluid": {
                    "kind": "openfoam",
                    "path": FLUID_DIR,
                    "participant": "Fluid",
                    "options": {
                        "prerun_end_time": spec.prerun_end_time,
                        **({"snapshots": list(spec.snapshots)} if spec.snapshots else {}),
                    },
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {name: "Velocity" for name in spec.interfaces},
            "read_from": {},
            "meshes": {name: _mesh_name("Controller", name) for name in spec.interfaces},
        },
        # one window per action: preCICE ramps between the written actions (waveform)
        "actions": (
            {"windows": 1, "scheme": "hold"}
            if spec.coupling == "action"
            else {"windows": spec.steps_per_action, "scheme": "ramp"}
        ),
    }


def case_files(spec: CaseSpec) -> dict[str, str]:
    """Relative path -> text of every file of the case ``spec``."""
    files = {
        "precice-config.xml": precice_config(spec),
        "gymprecice-config.json": json.dumps(gymprecice_config(spec), indent=2) + "\n",
    }
    files.update({f"{FLUID_DIR}/{k}": v for k, v in fluid_files(spec).items()})
    return files


def fluid_files(spec: CaseSpec) -> dict[str, str]:
    """The OpenFOAM case (relative to ``fluid-openfoam/``)."""
    files = {
        "0/U": _u_file(spec),
        "0/p": _p_file(spec),
        "constant/transportProperties": _transport(spec),
        "constant/turbulenceProperties": _laminar("turbulenceProperties"),
        "constant/momentumTransport": _laminar("momentumTransport"),
        "system/blockMeshDict": blockmesh_dict(
            spec.geometry, spec.resolution, jets=spec.control == "jets"
        ),
        "system/controlDict": _control_dict(spec),
        "system/fvSchemes": _fv_schemes(),
        "system/fvSolution": _fv_solution(spec),
        "system/decomposeParDict": _decompose(spec),
        "system/probes": _probes(spec),
        "system/forceCoeffs": _force_coeffs(spec),
        PRECICE_FO_FILE: _precice_fo(),
        "system/preciceDict": _precice_dict(spec),
    }
    return files


def write_case(spec: CaseSpec | str, target: str | Path, *, overwrite: bool = False) -> Path:
    """Write the case ``spec`` (or the packaged spec of that name) into ``target``."""
    if isinstance(spec, str):
        spec = case_spec(spec)
    target = Path(target)
    if target.exists() and any(target.iterdir()):
        if not overwrite:
            raise FileExistsError(f"{target} exists and is not empty (overwrite=False)")
        shutil.rmtree(target)
    for rel, text in case_files(spec).items():
        path = target / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return target


def write_fluid_case(spec: CaseSpec, target: str | Path, *, coupled: bool = False) -> Path:
    """Write only the OpenFOAM case of ``spec`` into ``target`` (uncoupled by default)."""
    target = Path(target)
    for rel, text in fluid_files(spec).items():
        path = target / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    if not coupled:
        make_uncoupled(target)
    return target


def make_uncoupled(fluid_dir: str | Path) -> None:
    """Drop the preCICE adapter from an OpenFOAM case (pre-runs, validation, tests)."""
    path = Path(fluid_dir) / PRECICE_FO_FILE
    if not path.parent.is_dir():
        raise FileNotFoundError(f"{fluid_dir} has no system/ directory")
    path.write_text(_BANNER + UNCOUPLED_FUNCTION_OBJECT)


def make_coupled(fluid_dir: str | Path) -> None:
    """Put the preCICE adapter back into an OpenFOAM case (undoes :func:`make_uncoupled`)."""
    (Path(fluid_dir) / PRECICE_FO_FILE).write_text(_precice_fo())


def regenerate(cases_dir: Path = CASES_DIR) -> list[Path]:
    """Rewrite the packaged cases from the recipes."""
    written = []
    for name, spec in CASES.items():
        written.append(write_case(spec, cases_dir / name, overwrite=True))
    return written


# --------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------


def add_resolution_options(parser: argparse.ArgumentParser) -> None:
    """The :class:`Resolution` knobs as options, for the commands that write a mesh."""
    parser.add_argument("--cells-per-jet", type=int, help="mesh: see recipes.Resolution")
    parser.add_argument("--wall-cell", type=float, help="mesh: see recipes.Resolution")
    parser.add_argument("--wake-grading", type=float, help="mesh: see recipes.Resolution")


def resolution_overrides(args: argparse.Namespace) -> dict[str, float]:
    """The :class:`Resolution` fields given by :func:`add_resolution_options`' options."""
    given = {
        "cells_per_jet": args.cells_per_jet,
        "wall_cell": args.wall_cell,
        "wake_grading": args.wake_grading,
    }
    return {k: v for k, v in given.items() if v is not None}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gymprecice_tutorials.recipes")
    sub = parser.add_subparsers(dest="command", required=True)
    w = sub.add_parser("write", help="write one case into a directory")
    w.add_argument("name", choices=sorted(CASES))
    w.add_argument("target", type=Path)
    add_resolution_options(w)
    w.add_argument("--overwrite", action="store_true")
    sub.add_parser("regenerate", help="rewrite the packaged cases")
    i = sub.add_parser("info", help="print the block counts of the cases")
    i.add_argument("name", nargs="?", choices=sorted(CASES))
    args = parser.parse_args(argv)

    if args.command == "write":
        spec = case_spec(args.name)
        knobs = resolution_overrides(args)
        if knobs:
            spec = replace(spec, resolution=replace(spec.resolution, **knobs))
        print(write_case(spec, args.target, overwrite=args.overwrite))
    elif args.command == "regenerate":
        for path in regenerate():
            print(path)
    else:
        for name in [args.name] if args.name else sorted(CASES):
            spec = CASES[name]
            c = block_counts(spec.geometry, spec.resolution)
            print(f"{name}: ~{c.cells} cells, {c}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
