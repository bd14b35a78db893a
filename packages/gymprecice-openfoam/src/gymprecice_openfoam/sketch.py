"""An OpenFOAM case as ``gymprecice sketch`` draws it: read from the case's own files.

* the mesh: ``constant/polyMesh`` when the case has one (or its ``processor*`` meshes);
  otherwise the case's ``system`` and ``constant`` are copied into a temporary directory
  and meshed there the way preparation meshes a case (:func:`.case.ensure_mesh`:
  blockMesh, gmshToFoam), then removed: the pristine case is never written;
* the patches: ``constant/polyMesh/boundary`` with each face a segment in the x-y plane
  (a 2-D case is one cell deep: a boundary face's two points nearer the front plane);
  ``empty``, ``wedge``, ``cyclic`` and ``processor`` patches are not in that plane and are
  left out. A patch's kind comes from its boundary conditions in ``0/`` and its type: a
  fixed pressure makes an outlet (also of a patch typed ``wall``), then the types
  ``wall`` and ``symmetry``, then a fixed or inlet velocity makes an inlet, else the name
  decides (``inlet``, ``outlet``);
* the domain's loops: the boundary segments chained through their shared mesh points;
* ``system/preciceDict``: the preCICE meshes on each patch and their vertices (as the
  adapter builds them, :func:`.mesh.interface_geometry`);
* the probes of ``controlDict``'s function objects (:mod:`.function_objects`).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import CaseError, SketchPatch, SketchPoints, SolverContext, SolverSketch
from gymprecice_openfoam import foamio, mesh
from gymprecice_openfoam.function_objects import probe_sets

__all__ = ["case_sketch", "meshed_case"]

#: patch types that are not boundaries in the x-y plane of a 2-D case
_OFF_PLANE = ("empty", "wedge", "processor", "processorCyclic", "cyclic", "cyclicAMI")
#: pressure conditions of an outlet, velocity conditions of an inlet
_FIXED_PRESSURE = ("fixedValue", "totalPressure", "prghPressure", "prghTotalPressure", "fixedMean")
_INLET_VELOCITY = (
    "fixedValue",
    "fixedProfile",
    "flowRateInletVelocity",
    "uniformFixedValue",
    "timeVaryingMappedFixedValue",
    "codedFixedValue",
    "surfaceNormalFixedValue",
)
#: what is copied to mesh a case elsewhere: the dictionaries and a gmsh input
_MESH_INPUTS = ("system", "constant")


def _mesh_dirs(case_dir: Path) -> list[Path]:
    """The polyMesh directories holding the case's mesh (empty: it has none)."""
    own = case_dir / "constant" / "polyMesh"
    if foamio.existing(own / "faces") is not None:
        return [own]
    ranks = [p / "constant" / "polyMesh" for p in mesh.processor_dirs(case_dir)]
    return [r for r in ranks if foamio.existing(r / "faces") is not None]


@contextmanager
def meshed_case(case_dir: Path, options: dict[str, Any]) -> Iterator[tuple[Path, str]]:
    """``(directory with the mesh, how it was had)``: the case, or a temporary meshed copy."""
    if _mesh_dirs(case_dir):
        yield case_dir, "the case's mesh"
        return
    from gymprecice_openfoam.case import ensure_mesh
    from gymprecice_openfoam.installation import find_openfoam

    try:
        inst = find_openfoam(bashrc=options.get("openfoam_bashrc"))
    except CaseError as exc:
        raise CaseError(
            f"{case_dir}: the case has no mesh (constant/polyMesh) and OpenFOAM, which would "
            f"build it, is not available: {exc}"
        ) from None
    with tempfile.TemporaryDirectory(prefix="gymprecice-sketch-") as tmp:
        copy = Path(tmp) / case_dir.name
        copy.mkdir()
        for child in case_dir.iterdir():
            if child.name in _MESH_INPUTS and child.is_dir():
                shutil.copytree(child, copy / child.name, symlinks=True)
            elif child.suffix in (".geo", ".msh") and child.is_file():
                shutil.copy2(child, copy / child.name)
        how = ensure_mesh(copy, inst, options)
        yield copy, f"mesh built by {how} in a temporary directory"


def _conditions(case_dir: Path, field_name: str) -> dict[str, str]:
    """Each patch's boundary-condition type in ``0/<field>`` (empty when unreadable)."""
    for time in ("0", "0.orig"):
        path = case_dir / time / field_name
        if foamio.existing(path) is None:
            continue
        try:
            boundary = foamio.load(path).get("boundaryField", {})
        except CaseError:
            return {}
        return {
            str(name): str(entry.get("type", ""))
            for name, entry in boundary.items()
            if isinstance(entry, dict)
        }
    return {}


def _kinds(case_dir: Path, patches: list[mesh.Patch]) -> dict[str, str]:
    pressure = _conditions(case_dir, "p_rgh") or _conditions(case_dir, "p")
    velocity = _conditions(case_dir, "U")
    kinds = {}
    for patch in patches:
        # the conditions first: a case may declare its outlet a wall (preCICE's heated plate)
        if patch.type.startswith("symmetry"):
            kind = "symmetry"
        elif pressure.get(patch.name) in _FIXED_PRESSURE:
            kind = "outlet"
        elif patch.type == "wall":
            kind = "wall"
        elif velocity.get(patch.name, "").lower().find("inlet") >= 0 or (
            velocity.get(patch.name) in _INLET_VELOCITY
        ):
            kind = "inlet"
        elif velocity.get(patch.name) in ("noSlip", "slip"):
            kind = "wall"
        elif "outlet" in patch.name.lower():
            kind = "outlet"
        elif "inlet" in patch.name.lower():
            kind = "inlet"
        else:
            kind = "patch"
        kinds[patch.name] = kind
    return kinds


def _front(points: np.ndarray, labels: np.ndarray, offsets: np.ndarray, mid: float):
    """Per face, the two point indices nearest the front plane (z below ``mid``)."""
    pairs = []
    for k in range(len(offsets) - 1):
        face = labels[offsets[k] : offsets[k + 1]]
        front = face[points[face, 2] < mid]
        if len(front) != 2:  # a 3-D face: its two farthest points, projected
            xy = points[face, :2]
            gaps = np.linalg.norm(xy[:, None] - xy[None], axis=2)
            i, j = np.unravel_index(np.argmax(gaps), gaps.shape)
            front = face[[i, j]]
        pairs.append(front)
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


def _loops(edges: list[tuple[int, int]], points: dict[int, np.ndarray]) -> list[np.ndarray]:
    """Chain boundary edges (point labels) into closed loops, the outer one first."""
    neighbours: dict[int, list[int]] = {}
    for a, b in edges:
        if a != b:
            neighbours.setdefault(a, []).append(b)
            neighbours.setdefault(b, []).append(a)
    seen: set[tuple[int, int]] = set()
    loops = []
    for start in list(neighbours):
        for first in neighbours[start]:
            if (start, first) in seen:
                continue
            loop, previous, current = [start], start, first
            seen.update({(start, first), (first, start)})
            while current != start and len(loop) <= len(neighbours):
                loop.append(current)
                options = [n for n in neighbours[current] if (current, n) not in seen]
                if not options:
                    break
                previous, current = current, options[0]
                seen.update({(previous, current), (current, previous)})
            if current == start and len(loop) > 2:
                loops.append(np.array([points[p] for p in loop]))
    area = [abs(_signed_area(loop)) for loop in loops]
    return [loops[i] for i in np.argsort(area)[::-1]]


def _signed_area(loop: np.ndarray) -> float:
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _read(source: Path, mesh_dirs: list[Path]) -> tuple[list[SketchPatch], list[np.ndarray]]:
    """The in-plane patches of every mesh directory (ranks merged) and the domain's loops;
    the kinds from the conditions in ``source``'s ``0/``."""
    boundary = mesh.read_boundary(mesh_dirs[0])
    patches = [p for p in boundary if p.type not in _OFF_PLANE]
    kinds = _kinds(source, patches)
    names = [p.name for p in patches]
    segments: dict[str, list[np.ndarray]] = {name: [] for name in names}
    loops: list[np.ndarray] = []
    for rank, mesh_dir in enumerate(mesh_dirs):
        present = {p.name for p in mesh.read_boundary(mesh_dir)}
        geometries = mesh.patch_geometry(mesh_dir, [n for n in names if n in present])
        every = [g.points for g in geometries if g.points is not None and len(g.points)]
        if not every:
            continue
        z = np.concatenate(every)[:, 2]
        mid = 0.5 * (z.min() + z.max()) if z.max() > z.min() else np.inf
        edges: list[tuple[int, int]] = []
        where: dict[int, np.ndarray] = {}
        for geometry in geometries:
            if geometry.points is None or not len(geometry.labels):
                continue
            pairs = _front(geometry.points, geometry.labels, geometry.offsets, mid)
            segments[geometry.name].append(geometry.points[pairs][:, :, :2])
            labels = geometry.mesh_points[pairs]
            edges.extend(map(tuple, labels.tolist()))
            for local, label in zip(pairs.ravel(), labels.ravel()):
                where[int(label)] = geometry.points[local, :2]
        if rank == 0 and len(mesh_dirs) == 1:
            loops = _loops(edges, where)
    drawn = [
        SketchPatch(name, kinds[name], np.concatenate(segments[name]))
        for name in names
        if segments[name]
    ]
    return drawn, loops


def case_sketch(solver: SolverContext) -> SolverSketch:
    """The solver's case as a :class:`~gymprecice.sketch.SolverSketch` (see the module)."""
    source = Path(solver.run_dir)
    with meshed_case(source, dict(solver.options)) as (case_dir, how):
        mesh_dirs = _mesh_dirs(case_dir)
        if not mesh_dirs:
            raise CaseError(f"{case_dir}: no mesh after meshing; check the case's mesh recipe")
        patches, loops = _read(source, mesh_dirs)
        meshes_on: dict[str, list[str]] = {}
        vertices: dict[str, np.ndarray] = {}
        if (case_dir / "system" / "preciceDict").is_file():
            for interface in mesh.read_precice_dict(case_dir).interfaces:
                for name in interface.patches:
                    meshes_on.setdefault(name, []).append(interface.mesh)
                if interface.location_kind in ("faceCenters", "faceNodes"):
                    geometry = mesh.interface_geometry(case_dir, interface.mesh, dimensions=2)
                    vertices[interface.mesh] = geometry.coordinates
        patches = [
            SketchPatch(p.name, p.kind, p.segments, tuple(meshes_on.get(p.name, ())))
            for p in patches
        ]
        probes = [
            SketchPoints(s.name, s.locations, s.label)
            for s in probe_sets(source)
            if len(s.locations)
        ]
    return SolverSketch(
        patches=tuple(patches),
        loops=tuple(loops),
        points=tuple(probes),
        vertices=vertices,
        notes=(how,),
    )
