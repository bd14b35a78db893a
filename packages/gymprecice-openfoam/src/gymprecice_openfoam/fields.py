"""Fields of an OpenFOAM run for ``env.render()``: written only when the env renders.

Writing: when ``solver.fields`` is set, reset adds a ``writeObjects`` function object to
``system/controlDict`` that writes exactly those fields (``U``, ``p``, ``T``...) every
``solver.field_interval`` seconds of simulated time (one action). On a moving mesh (a
``dynamicMotionSolverFvMesh``, as the flap's fluid) a second one, listed before it, writes
the mesh's point positions (``<time>/polyMesh/points``), so that the fluid is drawn where
the mesh is at that time.

Where they go in ``functions`` (:func:`after_adapter`): in an implicit coupling (fluid and
flap) the preCICE adapter rewrites the *whole* state of a time directory that exists when
a time window converges (the converged values over the first iterate's), so a frame's
files written before the adapter's function object would make the case write everything
at every action; listed after it, they hold the converged window and nothing else. But a
solver writing after the adapter's advance writes a frame only once that advance
returns, and in a serial scheme whose *second* participant it is, the advance at the end
of a window waits for the first one's next window: the controller's next action, which
waits for the frame. So they go after the adapter only where the participant couples
implicitly and is second in no serial scheme (the flap's fluid: an implicit multi
coupling with the solid, a parallel-explicit one with the controller), and first
otherwise (the cylinders' fluid, second of a serial-explicit scheme, never checkpoints).

The last frame after the adapter: ``writeControl runTime`` writes when ``(t - start +
deltaT/2) / writeInterval``, rounded down, grows (OpenFOAM's ``timeControl``); after the
adapter's function object at the coupling's last step, ``deltaT`` is 0 (preCICE has no
time left, and the adapter ends the run there). The end time (a sum of time steps) over
the interval can fall a hair under a whole number (``0.3 / 0.1 = 2.9999999999999996``):
never written, ``render()`` after the episode's last step would have no frame. So after the
adapter the interval is a hair shorter (:data:`UNDER`, relative): every frame's time,
however rounded, starts a new interval, and the step before it does not (for runs of
fewer than about 10^7 time steps).

Without fields the entries are removed: an env that does not render writes nothing more
than before. The case's own ``writeInterval`` is left alone.

Reading: the newest time directory at or before the asked coupling time (plus the
episode's start time) that holds the field, in the case or in every ``processor*``
directory of a decomposed run (their cells in rank order). Values sit at the cell
centres, computed from the mesh (the area-weighted mean of each cell's face centres):
the faces once per mesh from ``constant/polyMesh``, the points of the time directory
when a moving mesh wrote them there (else those of ``constant``). Core triangulates the
undeformed centres once and draws each frame at the moved ones (the field's
``displacement``). A vector field (``U``) is drawn as its magnitude.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import ConfigError, Field, SolverContext
from gymprecice_openfoam import control, foamio, mesh

__all__ = ["after_adapter", "cell_centres", "moving_mesh", "read_field", "set_field_writes"]

#: the function objects' names in controlDict, between two marker comments
FUNCTION = "gymprecice_render"
POINTS_FUNCTION = "gymprecice_render_points"
_BEGIN = "// gymprecice: fields for env.render() (begin)"
_END = "// gymprecice: fields for env.render() (end)"
_BLOCK = re.compile(r"[ \t]*" + re.escape(_BEGIN) + r".*?" + re.escape(_END) + r"\n?", re.S)
_FUNCTIONS = re.compile(r"^\s*functions\s*\{", re.M)
#: where a moving mesh's points of time directory ``t`` are: ``t/polyMesh/points``
POINTS = "polyMesh/points"
#: how much shorter than one action the frame's ``writeInterval`` is after the adapter
#: (relative): above the rounding of a sum of up to ~10^7 time steps (~1e-16 each),
#: below one time step in 10^7 (module docstring)
UNDER = 1e-8
#: labels of the fields the tutorials draw
LABELS = {"U": "|U| [m/s]", "p": "p [m²/s²]", "T": "T [K]"}


def moving_mesh(run_dir: Path) -> bool:
    """Whether the case moves its mesh points with a motion solver (the flap's fluid).

    ``constant/dynamicMeshDict`` with ``dynamicFvMesh dynamicMotionSolver...`` (OpenFOAM
    v1806 and newer, 6 to 8) or a ``mover`` of type ``motionSolver`` (OpenFOAM 9 and
    newer). Such a mesh moves at every time step and keeps its faces, so its points are
    all a frame needs. Any other dynamic mesh (refinement, topology changes) is drawn on
    its undeformed mesh: its points need not have moved by the first frame, and
    ``writeObjects`` would then write them over ``constant/polyMesh/points``.
    """
    path = Path(run_dir) / "constant" / "dynamicMeshDict"
    if not path.is_file():
        return False
    parsed = foamio.load(path)
    if not isinstance(parsed, dict):
        return False
    kind = str(parsed.get("dynamicFvMesh", ""))
    mover = parsed.get("mover")
    if isinstance(mover, dict):
        kind = str(mover.get("type", ""))
    return kind.startswith(("dynamicMotionSolver", "motionSolver"))


def after_adapter(solver: SolverContext) -> bool:
    """Whether the frame's function objects go after the preCICE adapter's (module docstring).

    After: the solver's participant couples implicitly (the adapter then rewrites a time
    directory's whole state) and is the second participant of no serial scheme (so its
    advance never waits for the controller's next action). Before, otherwise.
    """
    config, me = solver.precice, solver.participant
    if config is None or me is None:
        return False
    mine = [scheme for scheme in config.coupling_schemes if me in scheme.participants]
    implicit = any("implicit" in s.kind or s.kind == "multi" for s in mine)
    waits = any(s.kind.startswith("serial") and s.second == me for s in mine)
    return implicit and not waits


def _write_objects(name: str, objects: tuple[str, ...], interval: float, comment: str) -> str:
    return (
        f"    {name}\n    {{\n        type            writeObjects;\n"
        '        libs            ("libutilityFunctionObjects.so");\n'
        f"        objects         ({' '.join(objects)});\n"
        "        writeControl    runTime;\n"
        f"        writeInterval   {float(f'{interval:.12g}')!r};{comment}\n    }}\n"
    )


def _closing_brace(text: str, start: int) -> int:
    """Index of the ``}`` closing the dictionary whose body starts at ``start``."""
    depth = 1
    index = start
    while index < len(text):
        if text.startswith("//", index):
            index = text.find("\n", index)
            index = len(text) if index < 0 else index
        elif text.startswith("/*", index):
            index = text.find("*/", index + 2)
            index = len(text) if index < 0 else index + 2
            continue
        elif text[index] == '"':
            index = text.find('"', index + 1)
            index = len(text) if index < 0 else index
        elif text[index] == "{":
            depth += 1
        elif text[index] == "}":
            depth -= 1
            if depth == 0:
                return index
        index += 1
    raise ValueError("functions is not closed")


def set_field_writes(
    run_dir: Path,
    fields: tuple[str, ...],
    interval: float | None,
    *,
    after_adapter: bool = False,
) -> bool:
    """Make the case write ``fields`` every ``interval`` s, or nothing extra (``()``).

    The function objects are listed first in ``functions``, or last with
    ``after_adapter`` (see :func:`after_adapter`), their interval then a hair shorter
    (:data:`UNDER`; module docstring). Returns whether controlDict changed.
    """
    path = control.control_dict_path(run_dir)
    text = path.read_text()
    plain = _BLOCK.sub("", text)
    wanted = plain
    if fields and interval:
        comment = ""
        if after_adapter:  # the last frame's time need not reach its multiple (module doc)
            comment = f"  // one action ({interval:.12g} s) less a hair: the last one is written"
            interval *= 1.0 - UNDER
        body = ""
        if moving_mesh(run_dir):  # before the fields: complete once a field is
            body += _write_objects(POINTS_FUNCTION, ("points",), interval, comment)
        body += _write_objects(FUNCTION, fields, interval, comment)
        block = f"{_BEGIN}\n{body}{_END}\n"
        match = _FUNCTIONS.search(plain)
        try:
            end = None if match is None else _closing_brace(plain, match.end())
        except ValueError:
            end = None
        if match is None or end is None:
            wanted = plain.rstrip("\n") + "\n\nfunctions\n{\n" + block + "}\n"
        elif not after_adapter:
            start = match.end() + (plain[match.end() : match.end() + 1] == "\n")
            wanted = plain[:start] + block + plain[start:]
        else:
            line = plain.rfind("\n", 0, end) + 1
            before = plain[:line] if plain[line:end].strip() == "" else plain[:end] + "\n"
            wanted = before + block + plain[end:]
    if wanted == text:
        return False
    path.write_text(wanted)
    return True


def _read_labels(path: Path) -> np.ndarray:
    from foamlib import FoamFile  # imported when used: see foamio.loads

    parsed = FoamFile(path)[None]
    return np.asarray(parsed, dtype=np.int64).ravel()


@dataclass
class _Cells:
    """A mesh's faces and cells (fixed), to place its cell centres at any points."""

    owner: np.ndarray
    neighbour: np.ndarray
    offsets: np.ndarray
    labels: np.ndarray
    #: the centres on ``constant/polyMesh/points``: the undeformed mesh
    centres: np.ndarray

    @classmethod
    def read(cls, root: Path) -> _Cells:
        mesh_dir = root / "constant" / "polyMesh"
        owner = _read_labels(mesh_dir / "owner")
        neighbour = _read_labels(mesh_dir / "neighbour")
        offsets, labels = mesh.read_faces(mesh_dir, 0, len(owner))
        cells = cls(owner, neighbour, offsets, labels, np.empty((0, 3)))
        cells.centres = cells.at(mesh.read_points(mesh_dir))
        return cells

    def at(self, points: np.ndarray) -> np.ndarray:
        """Cell centres ``(n, 3)`` with the mesh's points at ``points``."""
        centres, areas = mesh.face_centres_and_areas(points, self.offsets, self.labels)
        weight = np.linalg.norm(areas, axis=1)
        n_cells = int(self.owner.max()) + 1
        total = np.zeros((n_cells, 3))
        mass = np.zeros(n_cells)
        inner = slice(0, len(self.neighbour))
        for cells, faces in ((self.owner, slice(None)), (self.neighbour, inner)):
            np.add.at(total, cells, centres[faces] * weight[faces, None])
            np.add.at(mass, cells, weight[faces])
        return total / np.maximum(mass, 1e-300)[:, None]


def cell_centres(root: Path) -> np.ndarray:
    """Approximate cell centres ``(n, 3)`` of the mesh under ``root`` (a case or processor)."""
    return _Cells.read(root).centres


def _roots(run_dir: Path) -> list[Path]:
    processors = mesh.processor_dirs(run_dir)
    return processors if processors else [run_dir]


def _times(root: Path, name: str, upto: float) -> dict[str, float]:
    out = {}
    for child in root.iterdir():
        try:
            value = float(child.name)
        except ValueError:
            continue
        if value <= upto and (child / name).is_file():
            out[child.name] = value
    return out


#: OpenFOAM ends every file it writes with this divider: a file without it is being written
_END_DIVIDER = b"// ****"


def _written(path: Path) -> bool:
    """Whether OpenFOAM has finished writing ``path`` (its end divider is there).

    A reader never hands foamlib a file cut short: its parser can take minutes on one.
    """
    with path.open("rb") as handle:
        handle.seek(0, 2)
        handle.seek(max(0, handle.tell() - 256))
        return _END_DIVIDER in handle.read()


def _values(path: Path, n: int) -> np.ndarray:
    if not _written(path):
        raise ValueError(f"{path} is being written")
    from foamlib import FoamFieldFile  # imported when used: see foamio.loads

    internal = FoamFieldFile(path).internal_field
    values = np.asarray(internal, dtype=float)
    if values.ndim == 0 or (values.ndim == 1 and len(values) in (2, 3) and n not in (2, 3)):
        values = np.broadcast_to(values, (n, *values.shape)).copy()  # uniform
    return values


def _moved_centres(root: Path, cells: _Cells, upto: float) -> np.ndarray | None:
    """The cell centres at the newest points at or before ``upto`` (``None``: undeformed).

    As OpenFOAM finds a mesh's points: in the newest time directory that holds
    ``polyMesh/points``, else in ``constant``.
    """
    found = _times(root, POINTS, upto)
    if not found:
        return None
    path = root / max(found, key=found.__getitem__) / POINTS
    if not _written(path):
        raise ValueError(f"{path} is being written")
    return cells.at(mesh.read_points(path.parent))


def _stamp(path: Path) -> tuple[str, int, int]:
    stat = path.stat()
    return str(path), stat.st_mtime_ns, stat.st_size


def read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    """The newest snapshot of ``name`` at or before coupling time ``time`` (``None``: none yet)."""
    if name not in solver.fields:
        raise ConfigError(
            f"{solver.describe()}: field {name!r} is not written for rendering (the env asked "
            f"for {list(solver.fields)} at reset); add it to the env's render_fields"
        )
    run_dir = Path(solver.run_dir)
    start = float(solver.state.get("initial_time", 0.0))
    tolerance = 1e-6 * max(1.0, abs(start + time))
    roots = _roots(run_dir)
    common: dict[str, float] | None = None
    for root in roots:
        found = _times(root, name, start + time + tolerance)
        common = found if common is None else {k: v for k, v in common.items() if k in found}
    if not common:
        if not any(_times(root, name, float("inf")) for root in roots):
            raise ConfigError(
                f"{solver.describe()}: the case writes no field {name!r} (no time directory "
                f"under {run_dir} holds it); OpenFOAM writes the fields its solver "
                "registers, e.g. U and p (pimpleFoam), T (buoyant and laplacianFoam)"
            )
        return None
    chosen = max(common, key=common.__getitem__)
    # While core waits for a newer snapshot it asks again: the same files are not parsed
    # twice (a rewritten file has a new stamp).
    last: dict[str, Any] = solver.state.setdefault("render_last", {})
    try:
        stamps = tuple(_stamp(root / chosen / name) for root in roots)
    except OSError:
        return None
    if name in last and last[name][0] == stamps:
        return last[name][1]
    cache: dict[str, Any] = solver.state.setdefault("render_cells", {})
    points, moved, values = [], [], []
    try:
        for root in roots:
            key = str(root)
            if not isinstance(cache.get(key), _Cells):
                cache[key] = _Cells.read(root)
            cells = cache[key]
            points.append(cells.centres)
            # the points are written before the field: complete when the field is
            values.append(_values(root / chosen / name, len(cells.centres)))
            at = _moved_centres(root, cells, common[chosen])
            moved.append(cells.centres if at is None else at)
    except (OSError, ValueError, KeyError):
        return None  # written just now, not complete yet: core asks again
    reference = np.concatenate(points)
    displacement = np.concatenate(moved) - reference
    field = Field(
        name,
        common[chosen] - start,
        reference[:, :2],
        np.concatenate(values),
        displacement=displacement[:, :2] if displacement.any() else None,
        label=LABELS.get(name, name),
    )
    last[name] = (stamps, field)
    return field
