"""Fields of a deal.II solid for ``env.render()``: written only when the env renders.

The deal.II-preCICE adapter's ``elasticity`` writes ``<Output folder>/solution-NNN.vtk``
(legacy ASCII VTK) at the start and then at the end of every time window whose step
number is a multiple of ``Output interval``, ``NNN`` being that step number divided by the
interval. Each file holds the mesh on the *deformed* geometry (higher-order Lagrange
quadrilaterals, one patch of nodes per cell), the ``displacement`` vector and the
``strain_xx`` ... components at its points.

Writing: when ``solver.fields`` is set, reset sets ``Output interval`` to the number of the
solid's time steps in one action (``solver.field_interval``), so the solid writes one
snapshot per action and no more; without fields it puts back the interval the case was
prepared with, so an env that does not render writes nothing more than before.

Reading: the newest snapshot at or before the asked coupling time, its time being
``NNN x interval x time step`` (the adapter's own naming; the file holds no time). The
points are handed over *undeformed*, with the displacement as :attr:`Field.displacement`,
so that core reuses the triangles of the reference mesh and draws them where the solid
is. Each cell's tensor grid of nodes is split into two triangles per sub-square.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import ConfigError, Field, SolverContext

__all__ = ["VtkSnapshot", "read_field", "read_vtk", "render_output_interval"]

#: labels of the fields the adapter writes
LABELS = {"displacement": "|u| [m]"}
#: VTK cell types of 2-D meshes this reader splits into triangles
VTK_TRIANGLE, VTK_QUAD, VTK_LAGRANGE_QUADRILATERAL = 5, 9, 70
_SNAPSHOT = re.compile(r"^solution-(\d+)\.vtk$")


class VtkFormatError(ValueError):
    """A VTK file this reader cannot use: incomplete (being written) or of another kind."""


@dataclass(frozen=True)
class VtkSnapshot:
    """One legacy VTK unstructured grid: points, triangles, and the point data by name."""

    points: np.ndarray
    triangles: np.ndarray
    point_data: dict[str, np.ndarray]


def render_output_interval(solver: SolverContext, time_step: float) -> int | None:
    """The ``Output interval`` (time steps) that writes one snapshot per action.

    ``None`` when the env does not render. The action must last a whole number of the
    solid's time steps (it does when the time step is the preCICE window, which the
    adapter requires).
    """
    if not solver.fields:
        return None
    interval = solver.field_interval
    if not interval:
        return 1
    steps = interval / time_step
    if steps < 0.5 or abs(steps - round(steps)) > 1e-6 * steps:
        raise ConfigError(
            f"{solver.describe()}: one action lasts {interval:g} s of coupling time, which is "
            f"not a whole number of the solid's time steps ({time_step:g} s, 'Time step size' "
            "in its parameter file); the solid can only write a snapshot per action when "
            "the action is a whole number of time windows"
        )
    return round(steps)


# -- VTK ---------------------------------------------------------------------------------------


def _lagrange_quad_order(order: int) -> list[tuple[int, int]]:
    """The ``(i, j)`` node of each entry of a VTK Lagrange quadrilateral of ``order``.

    VTK's ordering: the four corners counter-clockwise, then the inner nodes of the edges
    (0,1), (1,2), (3,2), (0,3), each in the direction of its parameter, then the interior
    nodes row by row.
    """
    n = order
    nodes = [(0, 0), (n, 0), (n, n), (0, n)]
    nodes += [(i, 0) for i in range(1, n)]
    nodes += [(n, j) for j in range(1, n)]
    nodes += [(i, n) for i in range(1, n)]
    nodes += [(0, j) for j in range(1, n)]
    nodes += [(i, j) for j in range(1, n) for i in range(1, n)]
    return nodes


def _cell_triangles(kind: int, ids: np.ndarray, where: str) -> np.ndarray:
    if kind == VTK_TRIANGLE and len(ids) == 3:
        return ids.reshape(1, 3)
    if kind == VTK_QUAD and len(ids) == 4:
        return np.array([[ids[0], ids[1], ids[2]], [ids[0], ids[2], ids[3]]])
    if kind == VTK_LAGRANGE_QUADRILATERAL:
        order = math.isqrt(len(ids)) - 1
        if order < 1 or (order + 1) ** 2 != len(ids):
            raise VtkFormatError(f"{where}: a Lagrange quadrilateral of {len(ids)} nodes")
        grid = np.empty((order + 1, order + 1), dtype=np.int64)
        for node, (i, j) in zip(ids, _lagrange_quad_order(order), strict=True):
            grid[j, i] = node
        a, b = grid[:-1, :-1].ravel(), grid[:-1, 1:].ravel()
        c, d = grid[1:, :-1].ravel(), grid[1:, 1:].ravel()
        return np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    raise ConfigError(
        f"{where}: VTK cell type {kind} with {len(ids)} nodes cannot be drawn; the deal.II "
        "plugin draws 2-D meshes of triangles and quadrilaterals (the adapter's 2-D solids)"
    )


def read_vtk(path: Path) -> VtkSnapshot:
    """Read a legacy ASCII VTK unstructured grid as deal.II's ``write_vtk`` writes it.

    Raises :class:`VtkFormatError` for a file that is not complete yet (the solver writes
    it while the env reads: every block must hold all its numbers and the file must end
    with a line break) or that is not an ASCII unstructured grid.
    """
    text = path.read_text()
    where = str(path)
    if not text.endswith("\n"):
        raise VtkFormatError(f"{where}: incomplete")
    lines = text.split("\n")
    if len(lines) < 4 or lines[2].strip() != "ASCII" or "UNSTRUCTURED_GRID" not in lines[3]:
        raise VtkFormatError(f"{where}: not an ASCII VTK unstructured grid")
    tokens = " ".join(lines[4:]).split()
    at = 0

    def numbers(count: int, dtype: Any) -> np.ndarray:
        nonlocal at
        if at + count > len(tokens):
            raise VtkFormatError(f"{where}: incomplete")
        block = np.asarray(tokens[at : at + count], dtype=dtype)
        at += count
        return block

    points = cells = types = None
    data: dict[str, np.ndarray] = {}
    n_points = 0
    while at < len(tokens):
        word = tokens[at].upper()
        if word == "POINTS":
            n_points = int(tokens[at + 1])
            at += 3
            points = numbers(3 * n_points, float).reshape(n_points, 3)
        elif word == "CELLS":
            size = int(tokens[at + 2])
            at += 3
            cells = numbers(size, np.int64)
        elif word == "CELL_TYPES":
            count = int(tokens[at + 1])
            at += 2
            types = numbers(count, np.int64)
        elif word == "POINT_DATA":
            at += 2
        elif word == "VECTORS":
            name = tokens[at + 1]
            at += 3
            data[name] = numbers(3 * n_points, float).reshape(n_points, 3)
        elif word == "SCALARS":
            name = tokens[at + 1]
            width = 1
            at += 3
            if at < len(tokens) and tokens[at].isdigit():
                width = int(tokens[at])
                at += 1
            if at < len(tokens) and tokens[at].upper() == "LOOKUP_TABLE":
                at += 2
            values = numbers(width * n_points, float)
            data[name] = values if width == 1 else values.reshape(n_points, width)
        elif word in ("CELL_DATA", "FIELD", "METADATA"):
            break  # past what a frame needs
        else:
            raise VtkFormatError(f"{where}: unexpected {tokens[at]!r}")
    if points is None or cells is None or types is None:
        raise VtkFormatError(f"{where}: incomplete")
    triangles = []
    at = 0
    for kind in types:
        count = int(cells[at])
        triangles.append(_cell_triangles(int(kind), cells[at + 1 : at + 1 + count], where))
        at += 1 + count
    return VtkSnapshot(points, np.concatenate(triangles), data)


# -- the hook ----------------------------------------------------------------------------------


def _snapshots(folder: Path) -> dict[int, Path]:
    if not folder.is_dir():
        return {}
    found = {}
    for path in folder.iterdir():
        match = _SNAPSHOT.match(path.name)
        if match:
            found[int(match.group(1))] = path
    return found


def read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    """The newest snapshot of ``name`` at or before coupling time ``time`` (``None``: none yet)."""
    if name not in solver.fields:
        raise ConfigError(
            f"{solver.describe()}: field {name!r} is not written for rendering (the env asked "
            f"for {list(solver.fields)} at reset); add it to the env's render_fields"
        )
    interval = solver.state.get("render_output_interval")
    time_step = solver.state.get("time_step")
    if not interval or not time_step:
        return None  # not reset for rendering yet
    period = interval * time_step
    newest = int(np.floor((time + 1e-6 * period) / period))
    folder = Path(solver.run_dir) / str(solver.state.get("output_folder", ""))
    found = {k: p for k, p in _snapshots(folder).items() if k <= newest}
    if not found:
        return None
    index = max(found)
    try:
        snapshot = read_vtk(found[index])
    except (OSError, VtkFormatError):
        return None  # being written: core asks again
    if name not in snapshot.point_data:
        raise ConfigError(
            f"{solver.describe()}: {found[index]} holds no field {name!r}; the deal.II-preCICE "
            f"adapter writes {sorted(snapshot.point_data)}"
        )
    values = snapshot.point_data[name]
    points = snapshot.points[:, :2]
    displacement = snapshot.point_data.get("displacement")
    if displacement is not None:
        displacement = displacement[:, :2]
        points = points - displacement  # the file's points are the deformed ones
        if values.ndim == 2:
            values = values[:, :2]
    return Field(
        name,
        index * period,
        points,
        values,
        triangles=snapshot.triangles,
        displacement=displacement,
        label=LABELS.get(name, name),
    )
