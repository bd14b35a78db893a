"""The fluid mesh of Turek and Hron's FSI3 channel: ``system/blockMeshDict``.

The geometry is the benchmark's (Turek & Hron 2006): a channel 2.5 x 0.41 m, a rigid
cylinder of radius 0.05 m centred at (0.2, 0.2) and an elastic bar 0.02 m thick fixed
behind it, its tip at x = 0.6 m. The cylinder carries two jets, at 90° and 270°, for
the controller (patches ``jet1`` and ``jet2``).

The topology is an O-grid around the cylinder inside a square box, as the cylinder
recipes' (:mod:`gymprecice_tutorials.recipes.mesh`), with the box's right-hand sector
cut by the bar:

* nine O-grid sectors, counter-clockwise from the bar's upper root: up to the box
  corner at 45°, to the first jet's edge, the jet, to 135°, the left side, to the
  second jet, the jet, to 315°, and down to the bar's lower root. The cylinder arc
  between the roots lies under the bar and carries no fluid;
* Cartesian blocks between the box and the walls, the inlet and the outlet; right of
  the box, blocks above and below the bar up to its tip, and a wake behind the tip
  that also fills the bar's strip.

Every block count derives from one cell size (:class:`Fsi3Resolution`), so a finer
mesh is one number. Cells are graded from ``wall_cell`` at the cylinder to the box's
cell size; the wake grows geometrically towards the outlet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from gymprecice_tutorials.recipes.foam_format import foam_number, foam_vector
from gymprecice_tutorials.recipes.mesh import (
    blockmesh_text,
    count_for_grading,
    geometric_ratio,
    radial_count,
)

__all__ = ["GEOMETRY", "RESOLUTIONS", "Fsi3Geometry", "Fsi3Resolution", "blockmesh_dict"]


@dataclass(frozen=True)
class Fsi3Geometry:
    """The benchmark's channel, cylinder and bar (metres), and the jets (degrees)."""

    length: float = 2.5
    height: float = 0.41
    centre: tuple[float, float] = (0.2, 0.2)
    radius: float = 0.05
    #: the bar's tip (x) and thickness; it is centred on the cylinder's axis
    bar_tip: float = 0.6
    bar_thickness: float = 0.02
    #: extent of the 2-D mesh in z (one cell)
    depth: float = 0.01
    #: half side of the square box that holds the O-grid
    box_half: float = 0.08
    #: angular width of each jet, centred at 90° and 270°
    jet_width: float = 10.0

    @property
    def bar_root(self) -> float:
        """x of the bar's corners on the cylinder."""
        h = self.bar_thickness / 2
        return self.centre[0] + math.sqrt(self.radius**2 - h**2)

    @property
    def diameter(self) -> float:
        return 2 * self.radius


#: Turek and Hron's FSI3 geometry
GEOMETRY = Fsi3Geometry()


@dataclass(frozen=True)
class Fsi3Resolution:
    """The mesh's cell size in the box and behind it, and at the cylinder's wall."""

    #: cell size along the box's sides, the bar and the start of the wake (m)
    cell: float = 0.01
    #: first cell at the cylinder, as a fraction of its diameter
    wall_cell: float = 0.02
    #: last wake cell over the first one (the wake grows towards the outlet)
    wake_grading: float = 8.0


#: the meshes of the mesh study, coarse to fine
RESOLUTIONS: dict[str, Fsi3Resolution] = {
    "coarse": Fsi3Resolution(cell=0.01),
    "medium": Fsi3Resolution(cell=0.007, wall_cell=0.015),
    "fine": Fsi3Resolution(cell=0.005, wall_cell=0.01),
}


@dataclass(frozen=True)
class _Counts:
    side: int  # cells along one full side of the box (left sector)
    arc: int  # box corner to a jet's edge
    jet: int
    root: int  # box corner to the bar, along the box's right side
    radial: int
    radial_grading: float
    left: int
    bottom: int
    top: int
    bar: int  # along the bar, box to tip
    across: int  # across the bar's strip, in the wake
    wake: int


def _counts(g: Fsi3Geometry, res: Fsi3Resolution) -> _Counts:
    s, h = g.box_half, g.bar_thickness / 2
    cx, cy = g.centre
    cell = res.cell
    delta = s * math.tan(math.radians(g.jet_width / 2))
    extent = s - g.radius
    radial = radial_count(extent, res.wall_cell * g.diameter, cell)
    return _Counts(
        side=max(2, round(2 * s / cell)),
        arc=max(1, round((s - delta) / cell)),
        jet=max(2, round(2 * delta / cell)),
        root=max(2, round((s - h) / cell)),
        radial=radial,
        radial_grading=geometric_ratio(radial, extent, cell),
        left=max(1, round((cx - s) / cell)),
        bottom=max(1, round((cy - s) / cell)),
        top=max(1, round((g.height - cy - s) / cell)),
        bar=max(1, round((g.bar_tip - cx - s) / cell)),
        across=max(2, round(2 * h / cell)),
        wake=count_for_grading(g.length - g.bar_tip, cell, res.wake_grading),
    )


def cell_count(resolution: Fsi3Resolution, geometry: Fsi3Geometry = GEOMETRY) -> int:
    """Cells of the mesh :func:`blockmesh_dict` writes."""
    c = _counts(geometry, resolution)
    wall = 2 * c.root + 2 * (2 * c.arc + c.jet) + c.side
    ny_side = c.bottom + 2 * c.root + c.top
    return (
        wall * c.radial
        + c.left * (c.bottom + c.side + c.top)
        + (2 * c.arc + c.jet) * (c.bottom + c.top)
        + c.bar * ny_side
        + c.wake * (ny_side + c.across)
    )


def blockmesh_dict(resolution: Fsi3Resolution, geometry: Fsi3Geometry = GEOMETRY) -> str:
    """``system/blockMeshDict`` of the FSI3 channel at ``resolution``."""
    g, c = geometry, _counts(geometry, resolution)
    cx, cy = g.centre
    r, s, h = g.radius, g.box_half, g.bar_thickness / 2
    hw = g.jet_width / 2
    z0, z1 = -g.depth / 2, g.depth / 2
    delta = s * math.tan(math.radians(hw))
    root_angle = math.degrees(math.asin(h / r))

    points: list[tuple[float, float]] = []

    def add(x: float, y: float) -> int:
        points.append((x, y))
        return len(points) - 1

    # O-grid rays, counter-clockwise from the bar's upper root to its lower root
    angles = [root_angle, 45.0, 90 - hw, 90 + hw, 135.0, 225.0, 270 - hw, 270 + hw, 315.0]
    angles.append(360.0 - root_angle)
    cyl, box = [], []
    for a in angles:
        t = math.radians(a)
        cyl.append(add(cx + r * math.cos(t), cy + r * math.sin(t)))
        if a in (angles[0], angles[-1]):  # the bar's surfaces run straight to the box
            box.append(add(cx + s, cy + math.copysign(h, math.sin(t))))
        else:
            m = max(abs(math.cos(t)), abs(math.sin(t)))
            box.append(add(cx + s * math.cos(t) / m, cy + s * math.sin(t) / m))
    # Cartesian grid lines; points already made (box corners, jet rays) are reused
    xs = [0.0, cx - s, cx - delta, cx + delta, cx + s, g.bar_tip, g.length]
    ys = [0.0, cy - s, cy - h, cy + h, cy + s, g.height]
    grid: dict[tuple[int, int], int] = {}
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            if i <= 3 and j in (2, 3):  # the bar's grid lines end at the box: no block here
                continue
            hit = next((k for k in box if _same(points[k][0], x) and _same(points[k][1], y)), None)
            grid[(i, j)] = hit if hit is not None else add(x, y)
    n_front = len(points)

    blocks: list[str] = []
    quads: list[tuple[int, int, int, int]] = []
    faces: dict[str, list[str]] = {
        name: [] for name in ("inlet", "outlet", "walls", "cylinder", "jet1", "jet2", "flap")
    }

    def block(v: tuple[int, int, int, int], nx: int, ny: int, gx: float = 1.0) -> None:
        quads.append(v)
        hexa = " ".join(str(i) for i in v) + " " + " ".join(str(i + n_front) for i in v)
        blocks.append(f"hex ({hexa}) ({nx} {ny} 1) simpleGrading ({foam_number(gx)} 1 1)")

    def face(patch: str, a: int, b: int) -> None:
        # swept from the front edge a -> b, taken clockwise around its block, so that
        # the face's normal points out of the block
        faces[patch].append(f"({a} {a + n_front} {b + n_front} {b})")

    tangential = [c.root, c.arc, c.jet, c.arc, c.side, c.arc, c.jet, c.arc, c.root]
    wall = ["cylinder", "cylinder", "jet1", "cylinder", "cylinder"]
    wall += ["cylinder", "jet2", "cylinder", "cylinder"]
    for k in range(9):  # O-grid sectors: local x radial (wall -> box), y counter-clockwise
        v = (cyl[k], box[k], box[k + 1], cyl[k + 1])
        block(v, c.radial, tangential[k], c.radial_grading)
        face(wall[k], cyl[k], cyl[k + 1])
    face("flap", box[0], cyl[0])  # the bar's upper and lower surfaces inside the box
    face("flap", cyl[-1], box[-1])

    def cartesian(i: int, j: int, j_top: int, nx: int, ny: int, gx: float = 1.0) -> None:
        v = (grid[(i, j)], grid[(i + 1, j)], grid[(i + 1, j_top)], grid[(i, j_top)])
        block(v, nx, ny, gx)
        if i == 0:
            face("inlet", v[0], v[3])
        if i == len(xs) - 2:
            face("outlet", v[2], v[1])
        if j == 0:
            face("walls", v[1], v[0])
        if j_top == len(ys) - 1:
            face("walls", v[3], v[2])

    cartesian(0, 0, 1, c.left, c.bottom)  # left of the box: its side is one block face
    cartesian(0, 1, 4, c.left, c.side)
    cartesian(0, 4, 5, c.left, c.top)
    for i, nx in ((1, c.arc), (2, c.jet), (3, c.arc)):  # below and above the box
        cartesian(i, 0, 1, nx, c.bottom)
        cartesian(i, 4, 5, nx, c.top)
    rows = ((0, 1, c.bottom), (1, 2, c.root), (3, 4, c.root), (4, 5, c.top))
    for j, j_top, ny in rows:  # beside the bar, up to its tip
        cartesian(4, j, j_top, c.bar, ny)
    face("flap", grid[(4, 2)], grid[(5, 2)])  # the bar's lower and upper surfaces
    face("flap", grid[(5, 3)], grid[(4, 3)])
    for j, j_top, ny in (*rows[:2], (2, 3, c.across), *rows[2:]):  # the wake
        cartesian(5, j, j_top, c.wake, ny, resolution.wake_grading)
    face("flap", grid[(5, 2)], grid[(5, 3)])  # the bar's tip

    edges: list[str] = []
    for k in range(9):
        mid = math.radians((angles[k] + angles[k + 1]) / 2)
        mx, my = cx + r * math.cos(mid), cy + r * math.sin(mid)
        edges.append(f"arc {cyl[k]} {cyl[k + 1]} {foam_vector(mx, my, z0)}")
        edges.append(f"arc {cyl[k] + n_front} {cyl[k + 1] + n_front} {foam_vector(mx, my, z1)}")

    kinds = {"inlet": "patch", "outlet": "patch"}
    patches = [(name, kinds.get(name, "wall"), fs) for name, fs in faces.items()]
    info = (
        f"// Turek-Hron FSI3 channel, cell {resolution.cell:g} m: "
        f"{cell_count(resolution, geometry)} cells (radial {c.radial}, wake {c.wake})"
    )
    return blockmesh_text(info, points, (z0, z1), blocks, edges, patches, quads)


def _same(a: float, b: float) -> bool:
    return abs(a - b) < 1e-12
