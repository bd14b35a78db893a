"""Spot an OpenFOAM solver that will never couple, and report what the machine lacks.

OpenFOAM treats a function object it cannot load as a *warning* and carries on, so a
missing or broken preCICE adapter does not stop the solver: it runs uncoupled to its end
time while the controller waits in preCICE's initialisation for a partner that never
comes. OpenFOAM v1912 prints, for the adapter's library::

    --> FOAM Warning :
        From function void* Foam::dlLibraryTable::openLibrary(const Foam::fileName&, bool)
        ...
        Could not load "libpreciceAdapterFunctionObject.so"
    libpreciceAdapterFunctionObject.so: cannot open shared object file: No such file or directory
    --> FOAM Warning :
        ...
        Could not open library "libpreciceAdapterFunctionObject.so"
    --> FOAM Warning :
    Unknown function type preciceAdapterFunctionObject
    ...
    --> while loading function object 'preCICE_Adapter'

(later releases and OpenFOAM.org print the same "Could not load" / "Unknown function
type" lines). The adapter's own failures read "Error in the preCICE adapter:" (fatal) or
"Error (deferred - will exit later) in the preCICE adapter:".
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from gymprecice.errors import CaseError
from gymprecice.solver import DoctorCheck, SolverContext
from gymprecice_openfoam import control
from gymprecice_openfoam.installation import ADAPTER_LIBRARY, find_openfoam

_LOAD_FAILURE = re.compile(
    r"Could not (?:load|open library)\s+\"?[^\"\n]*preciceAdapterFunctionObject[^\n]*"
    r"|Unknown function type preciceAdapterFunctionObject"
    r"|preciceAdapterFunctionObject[^\n]*cannot open shared object file[^\n]*"
    r"|lib[^\s]*precice[^\s]*: cannot open shared object file[^\n]*"
)
_ADAPTER_ERROR = re.compile(r"Error (?:\(deferred[^)]*\) )?in the preCICE adapter:\s*\S*")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")

#: How much of the start of the log to read: the warnings come before the first step.
_HEAD_BYTES = 256 * 1024


def _log_text(log_file: Path | None, tail: str) -> str:
    head = ""
    if log_file is not None and log_file.is_file():
        with log_file.open("rb") as handle:
            head = handle.read(_HEAD_BYTES).decode("utf-8", "replace")
    return _ANSI.sub("", head + "\n" + (tail or ""))


def check_log(run_dir: Path, log_file: Path | None, log_text: str) -> str | None:
    """Say why the solver cannot couple, or ``None`` when nothing points to that.

    Looks at the controlDict (is the adapter listed at all?) and at the log (did the
    library load, did the adapter report an error?). Messages name the file and the fix.
    """
    text = _log_text(log_file, log_text)
    where = str(log_file) if log_file is not None else "the solver log"
    failures = sorted({m.group(0).strip() for m in _LOAD_FAILURE.finditer(text)})
    if failures:
        quoted = "\n".join(f"    {line}" for line in failures[:6])
        return (
            f"{where}: OpenFOAM could not load the preCICE adapter ({ADAPTER_LIBRARY}) and "
            "only warned, so the solver runs UNCOUPLED and the controller would wait for it "
            f"forever. OpenFOAM said:\n{quoted}\n"
            "Fix: build and install the OpenFOAM-preCICE adapter for this OpenFOAM version "
            f"(it installs {ADAPTER_LIBRARY} into $FOAM_USER_LIBBIN), make sure libprecice "
            "is on LD_LIBRARY_PATH, and check with `gymprecice doctor`."
        )
    errors = sorted({m.group(0).strip() for m in _ADAPTER_ERROR.finditer(text)})
    if errors:
        index = text.find(errors[0])
        excerpt = "\n".join("    " + line for line in text[index:].splitlines()[:6])
        return (
            f"{where}: the preCICE adapter reported an error:\n{excerpt}\n"
            f"Fix the adapter configuration ({run_dir / 'system' / 'preciceDict'}) or the "
            "preCICE configuration it names."
        )
    try:
        coupled = control.has_adapter(run_dir)
    except CaseError as exc:
        return str(exc)
    if not coupled:
        return (
            f"{control.control_dict_path(run_dir)}: no preCICE adapter function object, so "
            "the solver runs uncoupled and the controller would wait for it forever. Fix: "
            f"add to system/controlDict: {control.ADAPTER_SNIPPET}"
        )
    return None


def check_solver(solver: SolverContext, log_text: str, log_name: str | None) -> str | None:
    run_dir = Path(solver.run_dir)
    log_file = run_dir / log_name if log_name else None
    return check_log(run_dir, log_file, log_text)


def doctor_checks() -> list[DoctorCheck]:
    """What an OpenFOAM environment needs, found or not."""
    checks: list[DoctorCheck] = []
    try:
        inst = find_openfoam()
    except CaseError as exc:
        checks.append(
            DoctorCheck(
                "OpenFOAM",
                False,
                detail=str(exc).split(". Fix:")[0],
                advice="install OpenFOAM or source its etc/bashrc",
            )
        )
        return checks
    version = f" {inst.version}" if inst.version else ""
    checks.append(
        DoctorCheck(
            "OpenFOAM",
            True,
            detail=f"OpenFOAM{version} at {inst.project_dir} ({inst.layout} layout)",
        )
    )
    for tool, why in (
        ("blockMesh", "generates meshes from system/blockMeshDict"),
        ("decomposePar", "splits a case for parallel runs"),
        ("mpirun", "runs decomposed cases"),
        ("gmshToFoam", "converts gmsh meshes"),
    ):
        path = inst.which(tool)
        checks.append(
            DoctorCheck(
                tool,
                path is not None,
                detail=path or "not found",
                advice="" if path else f"needed only if a case uses it ({why})",
            )
        )
    gmsh = shutil.which("gmsh")
    checks.append(
        DoctorCheck(
            "gmsh",
            gmsh is not None,
            detail=gmsh or "not found",
            advice="" if gmsh else "needed only for cases that ship a .geo instead of a mesh",
        )
    )
    library = inst.find_library()
    checks.append(
        DoctorCheck(
            "OpenFOAM-preCICE adapter",
            library is not None,
            detail=str(library) if library else f"{ADAPTER_LIBRARY} not found",
            advice=""
            if library
            else "build it (github.com/precice/openfoam-adapter) for this OpenFOAM; without "
            "it OpenFOAM runs uncoupled",
        )
    )
    return checks
