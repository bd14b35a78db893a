"""The mesh of a cylinder case: block cell counts and ``system/blockMeshDict``.

A structured multi-block mesh: an O-grid of eight sectors around the cylinder inside a
square box, and Cartesian blocks between the box and the channel walls, inlet and outlet.
The top and bottom O-grid sectors are split at 90° ± w/2 and 270° ± w/2, so the jet
patches ``jet1`` / ``jet2`` (jet cylinder) cover exactly the angular width ``w``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from gymprecice_tutorials.recipes.foam_format import FOOTER, foam_header, foam_number, foam_vector
from gymprecice_tutorials.recipes.spec import Geometry, Resolution


def geometric_ratio(n: int, length: float, last: float) -> float:
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


def count_for_grading(length: float, first: float, ratio: float) -> int:
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


def radial_count(extent: float, first: float, last: float) -> int:
    """Cells of an O-grid's radial extent graded from ``first`` at the wall to ``last``.

    The growth factor that the two sizes and the extent imply sets the count; cells no
    larger at the wall than at the box are spread evenly instead.
    """
    if last <= first:
        return max(2, round(extent / last))
    growth = (extent - first) / (extent - last)
    return max(2, round(1 + math.log(last / first) / math.log(growth)))


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
    n_radial = radial_count(extent, first, h_box)
    radial_grading = geometric_ratio(n_radial, extent, h_box)
    n_wake = count_for_grading(geometry.length - cx - s, h_box, resolution.wake_grading)
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
            f"simpleGrading ({foam_number(c.radial_grading)} 1 1)"
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
            blocks.append(
                f"hex ({hexa(v)}) ({nx[i]} {ny[j]} 1) simpleGrading ({foam_number(gx)} 1 1)"
            )
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
        edges.append(f"arc {a} {b} {foam_vector(mx, my, z0)}")
        edges.append(f"arc {a + n_front} {b + n_front} {foam_vector(mx, my, z1)}")

    names = ["inlet", "outlet", "walls", "cylinder"] + (["jet1", "jet2"] if jets else [])
    kinds = {"inlet": "patch", "outlet": "patch"}
    patches = [(name, kinds.get(name, "wall"), faces[name]) for name in names]
    info = (
        f"// cells: {c.cells} (wall faces {c.wall_faces}, radial {c.n_radial} with grading "
        f"{c.radial_grading:.3g}, wake {c.n_wake} x-cells, h_box {c.h_box:.4g})"
    )
    return blockmesh_text(info, points, (z0, z1), blocks, edges, patches, quads)


def blockmesh_text(
    info: str,
    points: Sequence[tuple[float, float]],
    z: tuple[float, float],
    blocks: Sequence[str],
    edges: Sequence[str],
    patches: Sequence[tuple[str, str, Sequence[str]]],
    quads: Sequence[Sequence[int]],
) -> str:
    """``system/blockMeshDict`` of a one-cell-deep 2-D mesh.

    ``points`` are the front plane's vertices (at ``z[0]``); the back plane's (at
    ``z[1]``) follow them, numbered on. ``patches`` are ``(name, type, faces)``; the
    ``frontAndBack`` patch (type empty) is made of the blocks' front ``quads``.
    """
    n_front = len(points)
    front = [f"    {foam_vector(x, y, z[0])} // {i}" for i, (x, y) in enumerate(points)]
    back = [f"    {foam_vector(x, y, z[1])} // {i + n_front}" for i, (x, y) in enumerate(points)]
    empty = [f"({' '.join(str(i) for i in reversed(q))})" for q in quads]
    empty += [f"({' '.join(str(i + n_front) for i in q)})" for q in quads]
    boundary = [_patch(name, kind, faces) for name, kind, faces in patches]
    boundary.append(_patch("frontAndBack", "empty", empty))
    return (
        foam_header("dictionary", "system", "blockMeshDict")
        + f"{info}\n\nscale 1;\n\nvertices\n(\n"
        + "\n".join(front + back)
        + "\n);\n\nblocks\n(\n"
        + "\n".join(f"    {b}" for b in blocks)
        + "\n);\n\nedges\n(\n"
        + "\n".join(f"    {e}" for e in edges)
        + "\n);\n\nboundary\n(\n"
        + "\n".join(boundary)
        + "\n);\n\nmergePatchPairs\n(\n);\n"
        + FOOTER
    )


def _patch(name: str, kind: str, faces: Sequence[str]) -> str:
    body = "\n".join(f"            {f}" for f in faces)
    return f"    {name}\n    {{\n        type {kind};\n        faces\n        (\n{body}\n        );\n    }}"
