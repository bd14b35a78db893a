"""Fields as data: what a plugin hands core so that core can draw a solver's physics.

A solver plugin answers ``gymprecice_read_field(solver, name, time)``
(:mod:`gymprecice.hookspecs`) with a :class:`Field`: where the values sit (points or cell
centres), the values, the connectivity where the solver has it, and the displacement of
a moving geometry (FSI). Core draws it (:mod:`gymprecice.rendering`); plugins never
draw, as they never start a process.

The env adds what only it knows, the state of its actuators, as an :class:`Overlay`.

A program driven by core's ``"command"`` kind (the test double's scripted partner, a
Python solver of one's own) hands fields over through files: core sets
``GYMPRECICE_FIELDS`` (comma-separated names) in its environment when the env renders,
and the program writes ``gymprecice-fields/<name>.npz`` in its working directory with
:func:`write_field_file` at every coupling time window it completes. Without the
variable it writes nothing, so an env that does not render costs nothing.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "FIELDS_DIR",
    "FIELDS_ENV_VAR",
    "Field",
    "Overlay",
    "field_file",
    "grid_points",
    "read_field_file",
    "requested_fields",
    "write_field_file",
]

#: Environment variable core sets for a ``"command"`` solver: the fields to write.
FIELDS_ENV_VAR = "GYMPRECICE_FIELDS"
#: Directory (in the solver's working directory) of a ``"command"`` solver's field files.
FIELDS_DIR = "gymprecice-fields"


@dataclass(frozen=True, eq=False)
class Field:
    """One field of one solver at one coupling time, as core draws it.

    ``points``
        ``(n, 2)`` (or ``(n, 3)``, z dropped) coordinates where the values sit: mesh
        vertices or cell centres.
    ``values``
        ``(n,)`` scalar values, or ``(n, k)`` vectors (drawn as their magnitude).
    ``time``
        The coupling time (seconds since the episode's start) the values belong to.
    ``triangles``
        ``(m, 3)`` vertex indices into ``points`` where the solver knows its
        connectivity; ``None``: core triangulates the points (Delaunay, without the
        triangles that bridge a hole such as a cylinder).
    ``displacement``
        ``(n, 2)`` displacement of each point (FSI): drawn at ``points + displacement``.
    ``label``
        What the colour bar says, e.g. ``"|U| [m/s]"`` (default: the name).
    """

    name: str
    time: float
    points: np.ndarray
    values: np.ndarray
    triangles: np.ndarray | None = None
    displacement: np.ndarray | None = None
    label: str = ""

    def __post_init__(self) -> None:
        points = np.asarray(self.points, dtype=float)
        if points.ndim != 2 or points.shape[1] not in (2, 3) or len(points) < 3:
            raise ValueError(
                f"field {self.name!r}: points must be an (n, 2) or (n, 3) array of at least 3 "
                f"points, got shape {points.shape}"
            )
        points = np.ascontiguousarray(points[:, :2])
        values = np.asarray(self.values, dtype=float)
        if values.shape[:1] != (len(points),) or values.ndim > 2:
            raise ValueError(
                f"field {self.name!r}: values must have one row per point ({len(points)}), "
                f"got shape {values.shape}"
            )
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "values", values)
        if self.triangles is not None:
            tri = np.asarray(self.triangles, dtype=np.int64)
            if tri.ndim != 2 or tri.shape[1] != 3 or (tri.size and tri.max() >= len(points)):
                raise ValueError(
                    f"field {self.name!r}: triangles must be (m, 3) indices below {len(points)}"
                )
            object.__setattr__(self, "triangles", tri)
        if self.displacement is not None:
            disp = np.asarray(self.displacement, dtype=float)
            if disp.ndim != 2 or len(disp) != len(points):
                raise ValueError(
                    f"field {self.name!r}: displacement must be (n, 2) with n = {len(points)}, "
                    f"got shape {disp.shape}"
                )
            object.__setattr__(self, "displacement", np.ascontiguousarray(disp[:, :2]))

    @property
    def scalar(self) -> np.ndarray:
        """The values drawn: scalars as they are, vectors as their magnitude."""
        if self.values.ndim == 1:
            return self.values
        return np.linalg.norm(self.values, axis=1)

    @property
    def positions(self) -> np.ndarray:
        """Where the values are drawn: ``points`` moved by ``displacement``."""
        if self.displacement is None:
            return self.points
        return self.points + self.displacement


@dataclass(frozen=True)
class Overlay:
    """The actuators' state that an env draws over its fields (``Adapter._render_overlay``).

    ``text``: lines in the frame's corner (``"jet Q = 1.2e-05 m³/s"``). ``arrows``:
    ``(x, y, dx, dy)`` in the fields' coordinates (a jet's direction and strength, the
    inflow). ``markers``: ``(x, y)`` points (probes, watch points).
    """

    text: Sequence[str] = ()
    arrows: Sequence[tuple[float, float, float, float]] = field(default_factory=tuple)
    markers: Sequence[tuple[float, float]] = field(default_factory=tuple)


def requested_fields(environ: os._Environ[str] | dict[str, str] | None = None) -> list[str]:
    """The field names core asks a ``"command"`` solver for (``[]``: write none)."""
    raw = (os.environ if environ is None else environ).get(FIELDS_ENV_VAR, "")
    return [name.strip() for name in raw.split(",") if name.strip()]


def field_file(directory: str | os.PathLike[str], name: str) -> Path:
    """Where a ``"command"`` solver in ``directory`` writes field ``name``."""
    return Path(directory) / FIELDS_DIR / f"{name}.npz"


def write_field_file(directory: str | os.PathLike[str], value: Field) -> Path:
    """Write ``value`` for core to read, atomically (a reader never sees half a file)."""
    path = field_file(directory, value.name)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {
        "time": np.array(float(value.time)),
        "points": value.points,
        "values": value.values,
        "label": np.array(value.label),
    }
    if value.triangles is not None:
        arrays["triangles"] = value.triangles
    if value.displacement is not None:
        arrays["displacement"] = value.displacement
    handle, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{value.name}.", suffix=".npz")
    try:
        with os.fdopen(handle, "wb") as out:
            np.savez(out, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_field_file(path: str | os.PathLike[str], name: str | None = None) -> Field:
    """Read a field written by :func:`write_field_file`."""
    path = Path(path)
    with np.load(path, allow_pickle=False) as data:
        return Field(
            name=name or path.stem,
            time=float(data["time"]),
            points=data["points"],
            values=data["values"],
            triangles=data.get("triangles"),
            displacement=data.get("displacement"),
            label=str(data["label"]) if "label" in data else "",
        )


def grid_points(
    x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Points of a structured ``len(x) x len(y)`` grid and its triangles (two per cell).

    For solvers (and test flows) whose field lives on a rectangle: the triangles are
    known, so core skips the Delaunay triangulation.
    """
    xs, ys = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    points = np.stack([gx.ravel(), gy.ravel()], axis=1)
    nx, ny = len(xs), len(ys)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    a = (j * nx + i).ravel()
    b, c, d = a + 1, a + nx, a + nx + 1
    triangles = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return points, triangles
