"""A solver's case as data: what a plugin hands core so that core can sketch the case.

``gymprecice sketch ENV`` draws an environment's case (its domain, boundary patches,
coupling interfaces, actuators and sensors) from the case files themselves. Each solver
plugin answers ``gymprecice_sketch_case(solver)`` (:mod:`gymprecice.hookspecs`) with a
:class:`SolverSketch`, read from its solver's case: the boundary patches as line
segments in the x-y plane, each with the kind its boundary conditions give it and the
preCICE meshes placed on it; the closed loops that bound the domain; the solver's own
sensors (probes); and the vertices of its preCICE meshes. Plugins read; core decides what
the controller does on each patch (from the preCICE configuration) and draws
(:mod:`gymprecice.case_sketch`, :mod:`gymprecice.sketch_drawing`), as with fields.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["FORMATS", "PATCH_KINDS", "SketchPatch", "SketchPoints", "SolverSketch"]

#: the file types ``gymprecice sketch`` writes, by suffix
FORMATS = (".png", ".svg")

#: What a solver's own boundary conditions make of a patch (core adds ``interface`` and
#: ``actuator`` from the coupling): ``patch`` is any other boundary.
PATCH_KINDS = ("inlet", "outlet", "wall", "symmetry", "patch")


def _xy(array: object, what: str, shape: tuple[int, ...]) -> np.ndarray:
    """``array`` as floats with its last axis cut to x, y; ``shape`` without that axis."""
    values = np.asarray(array, dtype=float)
    if values.ndim != len(shape) + 1 or values.shape[-1] not in (2, 3):
        raise ValueError(f"{what}: expected shape {(*shape, 2)} (or 3 columns), got {values.shape}")
    if any(want not in (-1, got) for want, got in zip(shape, values.shape)):
        raise ValueError(f"{what}: expected shape {(*shape, 2)}, got {values.shape}")
    return np.ascontiguousarray(values[..., :2])


@dataclass(frozen=True, eq=False)
class SketchPatch:
    """One boundary patch of a solver's case.

    ``segments``
        ``(m, 2, 2)``: each of the patch's faces as a segment in the x-y plane (a 2-D
        case's faces are one cell deep).
    ``kind``
        One of :data:`PATCH_KINDS`, from the solver's boundary conditions.
    ``meshes``
        The preCICE meshes of the solver's participant that sit on this patch: core
        reads from the preCICE configuration who couples there (the controller, another
        solver).
    """

    name: str
    kind: str
    segments: np.ndarray
    meshes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in PATCH_KINDS:
            raise ValueError(f"patch {self.name!r}: kind {self.kind!r} is not one of {PATCH_KINDS}")
        segments = _xy(self.segments, f"patch {self.name!r} segments", (-1, 2))
        object.__setattr__(self, "segments", segments)
        object.__setattr__(self, "meshes", tuple(self.meshes))


@dataclass(frozen=True, eq=False)
class SketchPoints:
    """Points a solver samples for the controller (OpenFOAM probes): ``(n, 2)``.

    ``label`` says what they are in the legend (``"probes (p)"``).
    """

    name: str
    points: np.ndarray
    label: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "points", _xy(self.points, f"points {self.name!r}", (-1,)))


@dataclass(frozen=True, eq=False)
class SolverSketch:
    """A solver's case as its plugin reads it, for ``gymprecice sketch``.

    ``loops`` are the closed boundary loops of the domain (``(k, 2)`` each, outer and
    holes alike; core fills the region they enclose). ``vertices`` maps each preCICE mesh
    of the solver's participant to its vertices ``(n, 2)``, as the adapter defines them:
    where a controller couples to that mesh, its vertices are these. ``notes`` are lines
    the sketch prints under its title (how the mesh was read or made).
    """

    patches: tuple[SketchPatch, ...]
    loops: tuple[np.ndarray, ...] = ()
    points: tuple[SketchPoints, ...] = ()
    vertices: Mapping[str, np.ndarray] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        loops = tuple(_xy(loop, "loop", (-1,)) for loop in self.loops)
        vertices = {str(k): _xy(v, f"vertices of {k!r}", (-1,)) for k, v in self.vertices.items()}
        object.__setattr__(self, "patches", tuple(self.patches))
        object.__setattr__(self, "loops", loops)
        object.__setattr__(self, "points", tuple(self.points))
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "notes", tuple(self.notes))
