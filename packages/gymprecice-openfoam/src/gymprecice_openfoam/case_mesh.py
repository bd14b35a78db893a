"""Make a case runnable: generate its mesh when missing and decompose it for a parallel run.

Prepare's steps 2 and 3 (see :mod:`gymprecice_openfoam.case`): blockMesh, gmsh +
gmshToFoam or gmshToFoam from a recipe the case ships, and decomposePar for ``np``
processes. They need only the installation and the run directory, not the prepared
state, and the case sketch (:mod:`.sketch`) uses :func:`ensure_mesh` on its own.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from gymprecice.plugin import CaseError, ConfigError
from gymprecice_openfoam import foamio
from gymprecice_openfoam.installation import OpenFOAMInstallation, run_tool
from gymprecice_openfoam.mesh import processor_dirs


def ensure_mesh(run_dir: Path, inst: OpenFOAMInstallation, options: dict[str, Any]) -> str:
    """Generate ``constant/polyMesh`` when missing; return what was done ("" if nothing)."""
    mesh_dir = run_dir / "constant" / "polyMesh"
    if foamio.existing(mesh_dir / "faces") is not None:
        return ""
    if any(foamio.existing(p / "constant" / "polyMesh" / "faces") for p in processor_dirs(run_dir)):
        return ""  # shipped already decomposed
    if (run_dir / "system" / "blockMeshDict").is_file() or (mesh_dir / "blockMeshDict").is_file():
        run_tool(["blockMesh"], run_dir, "log.blockMesh", inst)
        return "blockMesh"
    geo = options.get("geo") or next(iter(sorted(run_dir.glob("*.geo"))), None)
    msh = options.get("msh") or next(iter(sorted(run_dir.glob("*.msh"))), None)
    if geo is not None and msh is None:
        gmsh = shutil.which("gmsh")
        if gmsh is None:
            raise CaseError(
                f"{run_dir / Path(geo).name}: a gmsh geometry but no mesh, and gmsh is not "
                "on PATH; install gmsh or ship constant/polyMesh"
            )
        msh = Path(geo).with_suffix(".msh").name
        run_tool(
            [gmsh, "-3", str(Path(geo).name), "-format", "msh2", "-o", msh],
            run_dir,
            "log.gmsh",
            inst,
        )
    if msh is not None:
        run_tool(["gmshToFoam", str(Path(msh).name)], run_dir, "log.gmshToFoam", inst)
        return "gmshToFoam"
    raise CaseError(
        f"{mesh_dir}: no mesh and no recipe (system/blockMeshDict, *.geo or *.msh); ship "
        "the mesh or a recipe to build it"
    )


def subdomains(run_dir: Path) -> int:
    """``numberOfSubdomains`` of ``system/decomposeParDict`` (1 without the file)."""
    path = run_dir / "system" / "decomposeParDict"
    if not path.is_file():
        return 1
    value = foamio.load(path).get("numberOfSubdomains", 1)
    try:
        return int(value)
    except (TypeError, ValueError):
        raise CaseError(f"{path}: numberOfSubdomains {value!r} is not an integer") from None


def decide_np(run_dir: Path, options: dict[str, Any]) -> int:
    """Processes for the run: option ``np`` (1 = serial), else decomposeParDict's count."""
    wanted = options.get("np")
    have = subdomains(run_dir)
    if wanted is None:
        return max(1, have)
    wanted = int(wanted)
    if wanted < 1:
        raise ConfigError(f"solver option np={wanted}: must be 1 (serial) or more")
    if wanted > 1 and wanted != have:
        path = run_dir / "system" / "decomposeParDict"
        raise CaseError(
            f"{path}: numberOfSubdomains is {have} but the solver option np={wanted}; "
            "make them agree (or drop np to use the dictionary's count)"
        )
    return wanted


def decompose(run_dir: Path, inst: OpenFOAMInstallation, np_: int) -> None:
    """Run decomposePar unless every processor directory already has a mesh."""
    procs = processor_dirs(run_dir)
    if len(procs) == np_ and all(
        foamio.existing(p / "constant" / "polyMesh" / "faces") for p in procs
    ):
        return
    run_tool(["decomposePar", "-force"], run_dir, "log.decomposePar", inst)
