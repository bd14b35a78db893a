"""A whole case on disk: its files, written, made (un)coupled, and the packaged ones.

A case directory holds::

    <case>/gymprecice-config.json     explicit form (solver "fluid", kind "openfoam")
    <case>/precice-config.xml         preCICE v3: Controller <-> Fluid
    <case>/fluid-openfoam/            OpenFOAM case (pimpleFoam), no mesh, no snapshot
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from gymprecice_tutorials.recipes.coupling import (
    UNCOUPLED_FUNCTION_OBJECT,
    adapter_files,
    adapter_function_object,
    gymprecice_config,
    precice_config,
)
from gymprecice_tutorials.recipes.foam_files import flow_files
from gymprecice_tutorials.recipes.foam_format import BANNER
from gymprecice_tutorials.recipes.mesh import blockmesh_dict
from gymprecice_tutorials.recipes.spec import (
    CASES,
    CASES_DIR,
    FLUID_DIR,
    PRECICE_FO_FILE,
    CaseSpec,
    case_spec,
)


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
    mesh = blockmesh_dict(spec.geometry, spec.resolution, jets=spec.control == "jets")
    return {"system/blockMeshDict": mesh, **flow_files(spec), **adapter_files(spec)}


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
    path.write_text(BANNER + UNCOUPLED_FUNCTION_OBJECT)


def make_coupled(fluid_dir: str | Path) -> None:
    """Put the preCICE adapter back into an OpenFOAM case (undoes :func:`make_uncoupled`)."""
    (Path(fluid_dir) / PRECICE_FO_FILE).write_text(adapter_function_object())


def regenerate(cases_dir: Path = CASES_DIR) -> list[Path]:
    """Rewrite the packaged cases from the recipes."""
    written = []
    for name, spec in CASES.items():
        written.append(write_case(spec, cases_dir / name, overwrite=True))
    return written
