"""Boundary-patch geometry of an OpenFOAM case, as the OpenFOAM-preCICE adapter sees it.

The controller's vertices must be *exactly* the adapter's, in the same order, or
nearest-neighbour mappings pair the wrong faces. The adapter (``Interface.C``) builds a
preCICE mesh from the patches listed in ``system/preciceDict``:

* ``locations faceCenters`` (default): for each patch in the listed order, the patch's
  face centres (``polyPatch::faceCentres()``, i.e. the mesh's face centres) in patch
  face order; a 2-D preCICE mesh keeps only x and y.
* ``locations faceNodes``: for each patch, its ``localPoints()``: the patch's points in
  order of first appearance in its faces (points shared by two patches appear twice).
* in parallel every rank adds its own part; preCICE numbers them rank by rank, so a
  decomposed case is read ``processor0``, ``processor1``, ... in turn.

Face centres and area vectors replicate ``primitiveMesh::makeFaceCentresAndAreas``
(OpenFOAM v1912 and later ESI releases): triangles directly, other polygons as the
area-weighted centroid of the triangle fan around the vertex average, with the
unsigned triangle areas as weights. Everything is vectorised over faces of equal size.
"""

from __future__ import annotations

import os
import re
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gymprecice.plugin import CaseError, InterfaceGeometry
from gymprecice_openfoam import foamio

#: OpenFOAM's ROOTVSMALL for double precision: faces with less fan area count as zero.
ROOTVSMALL = 1.0e-150

__all__ = [
    "InterfaceSpec",
    "Patch",
    "PatchGeometry",
    "PreciceDict",
    "clear_cache",
    "face_centres_and_areas",
    "interface_geometry",
    "patch_face_nodes",
    "patch_geometry",
    "processor_dirs",
    "read_boundary",
    "read_faces",
    "read_points",
    "read_precice_dict",
]


# --------------------------------------------------------------------------- mesh files


@dataclass(frozen=True)
class Patch:
    """One entry of ``constant/polyMesh/boundary``."""

    name: str
    type: str
    start: int
    size: int

    @property
    def stop(self) -> int:
        return self.start + self.size


def processor_dirs(case_dir: str | os.PathLike[str]) -> list[Path]:
    """``processorN`` directories of a decomposed case, in rank order."""
    found = []
    for child in Path(case_dir).iterdir():
        match = re.fullmatch(r"processor(\d+)", child.name)
        if match and child.is_dir():
            found.append((int(match.group(1)), child))
    return [path for _, path in sorted(found)]


def _mesh_dir(case_dir: Path) -> Path:
    return case_dir / "constant" / "polyMesh"


def read_boundary(mesh_dir: str | os.PathLike[str]) -> list[Patch]:
    """Patches of a ``polyMesh`` directory, in file order."""
    mesh_dir = Path(mesh_dir)
    parsed = foamio.load(mesh_dir / "boundary")
    entries = parsed.get(None) if isinstance(parsed, dict) else None
    if entries is None:
        # A boundary file whose list is empty parses to an empty standalone entry.
        entries = []
    patches = []
    for entry in entries:
        if not (isinstance(entry, tuple) and len(entry) == 2 and isinstance(entry[1], dict)):
            raise CaseError(f"{mesh_dir / 'boundary'}: unexpected entry {entry!r}")
        name, info = entry
        try:
            patches.append(
                Patch(
                    name=str(name),
                    type=str(info.get("type", "patch")),
                    start=int(info["startFace"]),
                    size=int(info["nFaces"]),
                )
            )
        except KeyError as exc:
            raise CaseError(
                f"{mesh_dir / 'boundary'}: patch {name!r} lacks {exc.args[0]!r}"
            ) from None
    return patches


def read_points(mesh_dir: Path, rows: np.ndarray | None = None) -> np.ndarray:
    """Mesh points (all, or the given rows), shape ``(n, 3)``, float64."""
    path, data = foamio.read_bytes(mesh_dir / "points")
    head = foamio.header(path, data)
    if head.format != "binary":
        return foamio.ascii_vectors(path, data, head, rows)
    (points,) = foamio.binary_lists(path, data, head, [head.scalar_dtype()], [3])
    points = points.astype(np.float64, copy=False)
    if rows is not None and len(rows) and rows.max() >= len(points):
        raise CaseError(f"{path}: point {int(rows.max())} requested but there are {len(points)}")
    return points if rows is None else points[rows]


def read_faces(mesh_dir: Path, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Faces ``start:stop`` as compact arrays: ``offsets`` (m+1,) and vertex ``labels``."""
    path, data = foamio.read_bytes(mesh_dir / "faces")
    head = foamio.header(path, data)
    if head.format != "binary":
        return foamio.ascii_faces(path, data, head, start, stop)
    if head.class_name != "faceCompactList":
        raise CaseError(f"{path}: binary faces must be a faceCompactList, not {head.class_name}")
    ldt = head.label_dtype()
    offsets, labels = foamio.binary_lists(path, data, head, [ldt, ldt], [1, 1])
    count = len(offsets) - 1
    if not 0 <= start <= stop <= count:
        raise CaseError(f"{path}: faces {start}:{stop} requested but the file has {count}")
    lo, hi = int(offsets[start]), int(offsets[stop])
    return offsets[start : stop + 1].astype(np.int64) - lo, labels[lo:hi].astype(np.int64)


# --------------------------------------------------------------------------- geometry


def face_centres_and_areas(
    points: np.ndarray, offsets: np.ndarray, labels: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Face centres and area vectors exactly as OpenFOAM computes them.

    Triangles: vertex average and half the cross product. Other polygons: with ``c`` the
    vertex average, each edge (p, q) forms the triangle (p, q, c) with normal
    ``n = (q - p) x (c - p)``; the centre is ``sum(|n| (p + q + c)) / (3 sum |n|)`` and
    the area vector ``sum(n) / 2``. Faces with fan area below ROOTVSMALL get the vertex
    average and a zero area vector, like OpenFOAM.
    """
    points = np.asarray(points, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.int64)
    labels = np.asarray(labels, dtype=np.int64)
    nfaces = len(offsets) - 1
    sizes = np.diff(offsets)
    centres = np.empty((nfaces, 3))
    areas = np.empty((nfaces, 3))
    for k in np.unique(sizes):
        k = int(k)
        which = np.flatnonzero(sizes == k)
        if k < 3:
            raise ValueError(f"face with {k} vertices (faces {which[:5].tolist()}...)")
        pts = points[labels[offsets[which][:, None] + np.arange(k)]]  # (m, k, 3)
        if k == 3:
            p0, p1, p2 = pts[:, 0], pts[:, 1], pts[:, 2]
            centres[which] = (1.0 / 3.0) * (p0 + p1 + p2)
            areas[which] = 0.5 * _cross(p1 - p0, p2 - p0)
            continue
        fc = pts[:, 0].copy()
        for i in range(1, k):
            fc += pts[:, i]
        fc /= k
        sum_n = np.zeros_like(fc)
        sum_a = np.zeros(len(which))
        sum_ac = np.zeros_like(fc)
        for i in range(k):
            p = pts[:, i]
            q = pts[:, (i + 1) % k]
            c = p + q + fc
            n = _cross(q - p, fc - p)
            a = np.sqrt(n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1] + n[:, 2] * n[:, 2])
            sum_n += n
            sum_a += a
            sum_ac += a[:, None] * c
        tiny = sum_a < ROOTVSMALL
        with np.errstate(invalid="ignore", divide="ignore"):
            ctr = ((1.0 / 3.0) * sum_ac) / sum_a[:, None]
        ctr[tiny] = fc[tiny]
        area = 0.5 * sum_n
        area[tiny] = 0.0
        centres[which] = ctr
        areas[which] = area
    return centres, areas


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


@dataclass
class PatchGeometry:
    """Face data of one patch (in one mesh: the whole case or one processor).

    ``offsets``/``labels`` are the patch's faces in compact form; ``labels`` index
    ``points``, which holds only the points the patch uses (``mesh_points`` gives their
    labels in the mesh). Arrays are shared with a cache and read-only.
    """

    name: str
    centres: np.ndarray  # (n, 3)
    area_vectors: np.ndarray  # (n, 3), pointing out of the domain
    offsets: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(1, np.int64))
    labels: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0, np.int64))
    points: np.ndarray | None = field(repr=False, default=None)
    mesh_points: np.ndarray | None = field(repr=False, default=None)

    @property
    def areas(self) -> np.ndarray:
        """Face areas ``|Sf|`` (OpenFOAM's ``magSf``)."""
        a = self.area_vectors
        return np.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2])

    @property
    def normals(self) -> np.ndarray:
        """Unit outward normals ``Sf / |Sf|`` (zero for zero-area faces)."""
        mag = self.areas
        out = np.zeros_like(self.area_vectors)
        nz = mag > 0
        out[nz] = self.area_vectors[nz] / mag[nz, None]
        return out

    def local_points(self) -> np.ndarray:
        """The patch's points in order of first appearance (``localPoints()``)."""
        if self.points is None:
            raise ValueError("points were not kept for this patch")
        return self.points[_first_appearance(self.labels)]


def _first_appearance(labels: np.ndarray) -> np.ndarray:
    """Unique labels ordered by where each first occurs (PrimitivePatch::meshPoints)."""
    if len(labels) == 0:
        return labels
    unique, first = np.unique(labels, return_index=True)
    return unique[np.argsort(first, kind="stable")]


class _GeometryCache:
    """Patch geometry per mesh directory and patch, reused while the mesh files are unchanged.

    Every env of a vector env and every reset asks for the same patches; reading even
    the few lines they need costs milliseconds, a dictionary lookup microseconds.
    """

    def __init__(self, size: int = 256) -> None:
        self.size = size
        self.entries: OrderedDict[tuple, PatchGeometry] = OrderedDict()
        self.boundaries: OrderedDict[tuple, list[Patch]] = OrderedDict()

    @staticmethod
    def key(mesh_dir: Path) -> tuple:
        parts: list[object] = [str(mesh_dir.resolve())]
        for name in ("points", "faces", "boundary"):
            found = foamio.existing(mesh_dir / name)
            if found is None:
                parts.append(None)
            else:
                st = found.stat()
                parts.append((found.name, st.st_size, st.st_mtime_ns, st.st_ino))
        return tuple(parts)

    def _boundary(self, key: tuple, mesh_dir: Path) -> list[Patch]:
        patches = self.boundaries.get(key)
        if patches is None:
            if foamio.existing(mesh_dir / "faces") is None:
                raise CaseError(
                    f"{mesh_dir}: no mesh (constant/polyMesh/faces missing); generate it first "
                    "(blockMesh, gmshToFoam, ...) or let the plugin's prepare step do it"
                )
            patches = read_boundary(mesh_dir)
            self.boundaries[key] = patches
            while len(self.boundaries) > self.size:
                self.boundaries.popitem(last=False)
        return patches

    def get(self, mesh_dir: Path, names: list[str], what: str) -> list[PatchGeometry]:
        key = self.key(mesh_dir)
        patches = self._boundary(key, mesh_dir)
        by_name = {p.name: p for p in patches}
        for name in names:
            if name not in by_name:
                source = f"{what} names patch" if what else "patch"
                raise CaseError(
                    f"{source} {name!r}, but the mesh {mesh_dir} has no such patch; "
                    f"available patches: {', '.join(_patch_names(patches)) or '(none)'}. "
                    "Fix the patch name (or regenerate the mesh)."
                )
        todo = [by_name[n] for n in dict.fromkeys(names) if (key, n) not in self.entries]
        if todo:
            for geometry in _compute(mesh_dir, todo):
                self.entries[(key, geometry.name)] = geometry
            while len(self.entries) > self.size:
                self.entries.popitem(last=False)
        for name in names:
            self.entries.move_to_end((key, name))
        return [self.entries[(key, n)] for n in names]

    def clear(self) -> None:
        self.entries.clear()
        self.boundaries.clear()


def _compute(mesh_dir: Path, patches: list[Patch]) -> list[PatchGeometry]:
    """Read the faces spanning ``patches`` and the points they use; build each geometry."""
    real = [p for p in patches if p.size]
    first = min((p.start for p in real), default=0)
    last = max((p.stop for p in real), default=0)
    offsets, labels = read_faces(mesh_dir, first, max(first, last))
    out = []
    for patch in patches:
        lo, hi = patch.start - first, patch.stop - first
        if patch.size == 0:
            p_off, p_lab = np.zeros(1, np.int64), np.zeros(0, np.int64)
        else:
            p_off = offsets[lo : hi + 1] - offsets[lo]
            p_lab = labels[offsets[lo] : offsets[hi]]
        out.append((patch, p_off, p_lab))
    used = np.unique(np.concatenate([lab for _, _, lab in out])) if out else np.zeros(0, int)
    points = read_points(mesh_dir, used) if len(used) else np.zeros((0, 3))
    result = []
    for patch, p_off, p_lab in out:
        mine = np.unique(p_lab)
        local = np.searchsorted(mine, p_lab)
        p_points = points[np.searchsorted(used, mine)]
        centres, area_vectors = face_centres_and_areas(p_points, p_off, local)
        geometry = PatchGeometry(patch.name, centres, area_vectors, p_off, local, p_points, mine)
        for array in (centres, area_vectors, p_off, local, p_points, mine):
            array.flags.writeable = False
        result.append(geometry)
    return result


_CACHE = _GeometryCache()


def clear_cache() -> None:
    """Forget cached meshes (tests and benchmarks measure cold reads with this)."""
    _CACHE.clear()


def _patch_names(patches: Sequence[Patch]) -> list[str]:
    return [p.name for p in patches if p.type != "processor"]


def patch_geometry(
    mesh_dir: str | os.PathLike[str], names: Iterable[str], *, what: str = ""
) -> list[PatchGeometry]:
    """Geometry of the named patches of one ``polyMesh`` directory, in the given order.

    ``what`` names the file that asked for the patches, for the error message when one
    is missing (e.g. ``system/preciceDict``).
    """
    return _CACHE.get(Path(mesh_dir), list(names), what)


def patch_face_nodes(mesh_dir: str | os.PathLike[str], names: Iterable[str]) -> np.ndarray:
    """``localPoints()`` of each named patch, concatenated in the given order."""
    parts = [g.local_points() for g in patch_geometry(mesh_dir, names)]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


# --------------------------------------------------------------------------- preciceDict


@dataclass(frozen=True)
class InterfaceSpec:
    """One interface of ``system/preciceDict``."""

    name: str
    mesh: str
    patches: tuple[str, ...]
    locations: str = "faceCenters"
    read_data: tuple[str, ...] = ()
    write_data: tuple[str, ...] = ()
    cell_sets: tuple[str, ...] = ()
    connectivity: bool = False

    @property
    def location_kind(self) -> str:
        """``"faceCenters"``, ``"faceNodes"`` or ``"volumeCenters"`` (British spellings too)."""
        return self.locations.replace("Centres", "Centers")


@dataclass(frozen=True)
class PreciceDict:
    """The parts of ``system/preciceDict`` that decide the coupling meshes."""

    path: Path
    participant: str | None
    config: str | None
    modules: tuple[str, ...]
    interfaces: tuple[InterfaceSpec, ...]

    def interface_for_mesh(self, mesh: str) -> InterfaceSpec | None:
        for interface in self.interfaces:
            if interface.mesh == mesh:
                return interface
        return None


def _words(value: object) -> tuple[str, ...]:
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,)
    if isinstance(value, (list, tuple)):
        return tuple(str(v) for v in value)
    return (str(value),)


def read_precice_dict(case_dir: str | os.PathLike[str]) -> PreciceDict:
    """Parse ``system/preciceDict``: participant, config and every interface.

    Accepts the dictionary form ``interfaces { Name { mesh ...; patches (...); } }``
    and the older list form ``interfaces ( { mesh ...; } ... );``.
    """
    path = Path(case_dir) / "system" / "preciceDict"
    if not path.is_file():
        raise CaseError(
            f"{path}: missing; the OpenFOAM-preCICE adapter reads its interfaces from it "
            "(see the adapter's documentation for the format)"
        )
    parsed = foamio.load(path)
    raw = parsed.get("interfaces")
    if isinstance(raw, dict):
        items = list(raw.items())
    elif isinstance(raw, (list, tuple)):
        items = [(f"Interface{i + 1}", d) for i, d in enumerate(raw)]
    else:
        raise CaseError(f"{path}: no 'interfaces' dictionary; add one with mesh and patches")
    interfaces = []
    for name, entry in items:
        if not isinstance(entry, dict):
            raise CaseError(f"{path}: interface {name!r} is not a dictionary")
        if "mesh" not in entry:
            raise CaseError(f"{path}: interface {name!r} has no 'mesh' entry")
        interfaces.append(
            InterfaceSpec(
                name=str(name),
                mesh=str(entry["mesh"]),
                patches=_words(entry.get("patches")),
                locations=str(entry.get("locations", "faceCenters")),
                read_data=_words(entry.get("readData")),
                write_data=_words(entry.get("writeData")),
                cell_sets=_words(entry.get("cellSets")),
                connectivity=bool(entry.get("connectivity", False)),
            )
        )
    config = parsed.get("preciceConfig")
    participant = parsed.get("participant")
    return PreciceDict(
        path=path,
        participant=None if participant is None else str(participant),
        config=None if config is None else str(config).strip('"'),
        modules=_words(parsed.get("modules")),
        interfaces=tuple(interfaces),
    )


def interface_geometry(
    case_dir: str | os.PathLike[str],
    mesh_name: str,
    *,
    dimensions: int = 3,
    parallel: bool | None = None,
) -> InterfaceGeometry:
    """Vertices of the adapter's preCICE mesh ``mesh_name``, in the adapter's order.

    ``dimensions`` is the preCICE mesh's dimension (2 drops z, as the adapter does).
    ``parallel`` reads ``processor*`` meshes rank by rank; ``None`` does so only when the
    case has processor meshes but no undecomposed mesh.
    """
    case_dir = Path(case_dir)
    pdict = read_precice_dict(case_dir)
    spec = pdict.interface_for_mesh(mesh_name)
    if spec is None:
        known = ", ".join(i.mesh for i in pdict.interfaces) or "(none)"
        raise CaseError(
            f"{pdict.path}: no interface uses mesh {mesh_name!r}; its meshes are {known}"
        )
    if not spec.patches:
        raise CaseError(f"{pdict.path}: interface {spec.name!r} lists no patches")
    kind = spec.location_kind
    if kind not in ("faceCenters", "faceNodes"):
        raise CaseError(
            f"{pdict.path}: interface {spec.name!r} uses locations {spec.locations!r}; only "
            "faceCenters and faceNodes have patch geometry (set vertices by hand otherwise)"
        )
    if dimensions not in (2, 3):
        raise ValueError(f"dimensions must be 2 or 3, not {dimensions}")
    if parallel is None:
        parallel = foamio.existing(_mesh_dir(case_dir) / "faces") is None and bool(
            processor_dirs(case_dir)
        )
    meshes = [_mesh_dir(p) for p in processor_dirs(case_dir)] if parallel else [_mesh_dir(case_dir)]
    if not meshes:
        raise CaseError(f"{case_dir}: parallel geometry requested but there are no processor*")
    where = f"{pdict.path} (interface {spec.name!r})"
    coords, normals, areas = [], [], []
    for mesh_dir in meshes:
        geoms = patch_geometry(mesh_dir, spec.patches, what=where)
        for g in geoms:
            if kind == "faceCenters":
                coords.append(g.centres)
                normals.append(g.normals)
                areas.append(g.areas)
            else:
                coords.append(g.local_points())
    coordinates = np.concatenate(coords)[:, :dimensions]
    if kind == "faceNodes":
        return InterfaceGeometry(coordinates=coordinates, patches=spec.patches)
    return InterfaceGeometry(
        coordinates=coordinates,
        normals=np.concatenate(normals),
        areas=np.concatenate(areas),
        patches=spec.patches,
    )
