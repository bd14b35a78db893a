"""Fields of an OpenFOAM run for ``env.render()``: written only when the env renders.

Writing: when ``solver.fields`` is set, reset adds a ``writeObjects`` function object to
``system/controlDict`` that writes exactly those fields (``U``, ``p``, ``T``...) every
``solver.field_interval`` seconds of simulated time (one action), listed *first* in
``functions`` so it writes before the preCICE adapter's function object advances the
coupling (the controller then never waits for a frame's files). Without fields the entry
is removed: an env that does not render writes nothing more than before. The case's own
``writeInterval`` is left alone.

Reading: the newest time directory at or before the asked coupling time (plus the
episode's start time) that holds the field, in the case or in every ``processor*``
directory of a decomposed run (their cells in rank order). Values sit at the cell
centres, computed once per mesh from ``constant/polyMesh`` (the area-weighted mean of each
cell's face centres); core triangulates them. A vector field (``U``) is drawn as its
magnitude.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFieldFile, FoamFile

from gymprecice.errors import ConfigError
from gymprecice.fields import Field
from gymprecice.solver import SolverContext
from gymprecice_openfoam import control, mesh

__all__ = ["cell_centres", "read_field", "set_field_writes"]

#: the function object's name in controlDict, between two marker comments
FUNCTION = "gymprecice_render"
_BEGIN = "// gymprecice: fields for env.render() (begin)"
_END = "// gymprecice: fields for env.render() (end)"
_BLOCK = re.compile(re.escape(_BEGIN) + r".*?" + re.escape(_END) + r"\n?", re.S)
_FUNCTIONS = re.compile(r"^\s*functions\s*\{", re.M)
#: labels of the fields the tutorials draw
LABELS = {"U": "|U| [m/s]", "p": "p [m²/s²]", "T": "T [K]"}


def set_field_writes(run_dir: Path, fields: tuple[str, ...], interval: float | None) -> bool:
    """Make the case write ``fields`` every ``interval`` s, or nothing extra (``()``).

    Returns whether controlDict changed.
    """
    path = control.control_dict_path(run_dir)
    text = path.read_text()
    plain = _BLOCK.sub("", text)
    wanted = plain
    if fields and interval:
        block = (
            f"{_BEGIN}\n    {FUNCTION}\n    {{\n        type            writeObjects;\n"
            '        libs            ("libutilityFunctionObjects.so");\n'
            f"        objects         ({' '.join(fields)});\n"
            "        writeControl    runTime;\n"
            f"        writeInterval   {float(f'{interval:.12g}')!r};\n    }}\n{_END}\n"
        )
        match = _FUNCTIONS.search(plain)
        if match is None:
            wanted = plain.rstrip("\n") + "\n\nfunctions\n{\n" + block + "}\n"
        else:
            wanted = plain[: match.end()] + "\n" + block + plain[match.end() :]
    if wanted == text:
        return False
    path.write_text(wanted)
    return True


def _read_labels(path: Path) -> np.ndarray:
    parsed = FoamFile(path)[None]
    return np.asarray(parsed, dtype=np.int64).ravel()


def cell_centres(root: Path) -> np.ndarray:
    """Approximate cell centres ``(n, 3)`` of the mesh under ``root`` (a case or processor)."""
    mesh_dir = root / "constant" / "polyMesh"
    points = mesh.read_points(mesh_dir)
    owner = _read_labels(mesh_dir / "owner")
    neighbour = _read_labels(mesh_dir / "neighbour")
    offsets, labels = mesh.read_faces(mesh_dir, 0, len(owner))
    centres, areas = mesh.face_centres_and_areas(points, offsets, labels)
    weight = np.linalg.norm(areas, axis=1)
    n_cells = int(owner.max()) + 1
    total = np.zeros((n_cells, 3))
    mass = np.zeros(n_cells)
    for cells, faces in ((owner, slice(None)), (neighbour, slice(0, len(neighbour)))):
        np.add.at(total, cells, centres[faces] * weight[faces, None])
        np.add.at(mass, cells, weight[faces])
    return total / np.maximum(mass, 1e-300)[:, None]


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
    internal = FoamFieldFile(path).internal_field
    values = np.asarray(internal, dtype=float)
    if values.ndim == 0 or (values.ndim == 1 and len(values) in (2, 3) and n not in (2, 3)):
        values = np.broadcast_to(values, (n, *values.shape)).copy()  # uniform
    return values


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
    cache: dict[str, Any] = solver.state.setdefault("render_cells", {})
    points, values = [], []
    try:
        for root in roots:
            key = str(root)
            if key not in cache:
                cache[key] = cell_centres(root)
            centres = cache[key]
            points.append(centres)
            values.append(_values(root / chosen / name, len(centres)))
    except (OSError, ValueError, KeyError):
        return None  # written just now, not complete yet: core asks again
    return Field(
        name,
        common[chosen] - start,
        np.concatenate(points)[:, :2],
        np.concatenate(values),
        label=LABELS.get(name, name),
    )
