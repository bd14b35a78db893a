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

import difflib
import re
import shutil
from pathlib import Path

from gymprecice.plugin import CaseError, DoctorCheck, SolverContext
from gymprecice_openfoam import control, foamio
from gymprecice_openfoam.installation import ADAPTER_LIBRARY, find_openfoam
from gymprecice_openfoam.mesh import PreciceDict, processor_dirs, read_boundary, read_precice_dict

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


def _written_libraries(run_dir: Path) -> list[str]:
    """The adapter library names controlDict loads, exactly as written there."""
    try:
        return control.adapter_libraries(run_dir)
    except CaseError:
        return []


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
        written = _written_libraries(run_dir)
        named = ", ".join(repr(lib) for lib in written) or repr(ADAPTER_LIBRARY)
        odd = [lib for lib in written if lib != ADAPTER_LIBRARY]
        spelling = (
            f"controlDict ({control.control_dict_path(run_dir)}) loads {named}, but the "
            f"adapter's library is named {ADAPTER_LIBRARY!r}: fix 'libs' there, or "
            if odd
            else ""
        )
        return (
            f"{where}: OpenFOAM could not load the preCICE adapter ({named}, as written in "
            "controlDict) and only warned, so the solver runs UNCOUPLED and the controller "
            f"would wait for it forever. OpenFOAM said:\n{quoted}\n"
            f"Fix: {spelling}build and install the OpenFOAM-preCICE adapter for this OpenFOAM "
            f"version (it installs {ADAPTER_LIBRARY} into $FOAM_USER_LIBBIN), make sure "
            "libprecice is on LD_LIBRARY_PATH, and check with `gymprecice doctor`."
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


def validate_case(solver: SolverContext) -> list[str]:
    """Problems of a pristine OpenFOAM case that would only show once it runs.

    Each names the file at fault and the fix: the adapter missing from or disabled in
    controlDict, a preciceDict whose participant, meshes, data or preCICE file disagree
    with the preCICE configuration, and interface patches the mesh does not have.
    """
    case_dir = Path(solver.run_dir)
    problems: list[str] = []
    try:
        problems += _control_dict_problems(case_dir)
    except CaseError as exc:
        return [str(exc)]
    if not (case_dir / "system" / "preciceDict").is_file() and not problems:
        return [
            f"{case_dir / 'system' / 'preciceDict'}: missing; the OpenFOAM-preCICE adapter "
            "reads its participant, preCICE file and interfaces from it"
        ]
    try:
        pdict = read_precice_dict(case_dir)
    except CaseError as exc:
        return [*problems, str(exc)]
    problems += _precice_dict_problems(solver, pdict)
    problems += _patch_problems(case_dir, pdict)
    return problems


def _control_dict_problems(case_dir: Path) -> list[str]:
    path = control.control_dict_path(case_dir)
    if not control.has_adapter(case_dir):
        return [
            f"{path}: no preCICE adapter function object, so the solver would run "
            "uncoupled and the controller would wait for it forever; add to "
            f"system/controlDict: {control.ADAPTER_SNIPPET}"
        ]
    return [
        f"{path}: the preCICE adapter entry {name!r} has 'enabled false;', so OpenFOAM "
        "skips it and the solver would run uncoupled; delete that line (or set "
        "'enabled true;')"
        for name in control.disabled_adapter_entries(case_dir)
    ]


def _precice_dict_problems(solver: SolverContext, pdict: PreciceDict) -> list[str]:
    precice = solver.precice
    if precice is None:
        return []
    xml = solver.precice_config_file or precice.path
    problems = []
    wanted = solver.participant
    if pdict.participant is None:
        return [f"{pdict.path}: no 'participant' entry; add 'participant {wanted or '...'};'"]
    if pdict.participant not in precice.participants:
        problems.append(
            f"{pdict.path}: participant {pdict.participant!r} is not a participant of {xml} "
            f"(those are {sorted(precice.participants)}); set 'participant "
            f"{wanted or '<one of them>'};' there"
        )
        return problems
    if wanted and pdict.participant != wanted:
        problems.append(
            f"{pdict.path}: participant {pdict.participant!r}, but the gymprecice "
            f"configuration says this solver plays {wanted!r}; set 'participant {wanted};' "
            "there (or fix the solver's participant in gymprecice-config.json)"
        )
    if pdict.config and solver.precice_config_file is not None:
        named = (Path(solver.run_dir) / pdict.config).resolve()
        if named != Path(solver.precice_config_file).resolve():
            problems.append(
                f"{pdict.path}: preciceConfig {pdict.config!r} is {named}, not the preCICE "
                f"configuration of this case ({solver.precice_config_file}); set preciceConfig "
                "to that file, relative to the OpenFOAM case"
            )
    me = precice.participants[pdict.participant]
    for interface in pdict.interfaces:
        if interface.mesh not in me.provided_meshes:
            what = (
                f"which {xml} does not define"
                if interface.mesh not in precice.meshes
                else f"which participant {pdict.participant!r} does not <provide-mesh> in {xml}"
            )
            problems.append(
                f"{pdict.path}: interface {interface.name!r} uses mesh {interface.mesh!r}, "
                f"{what}; the meshes {pdict.participant!r} provides there are "
                f"{me.provided_meshes}. Set 'mesh' to one of them (or fix the XML)."
            )
            continue
        for data in (*interface.read_data, *interface.write_data):
            if data not in precice.data:
                problems.append(
                    f"{pdict.path}: interface {interface.name!r} exchanges data {data!r}, "
                    f"which {xml} does not define (its data are {sorted(precice.data)}); fix "
                    "readData/writeData"
                )
                continue
            module = adapter_module(data)
            if pdict.modules and module is not None and module not in pdict.modules:
                problems.append(
                    f"{pdict.path}: interface {interface.name!r} exchanges {data!r}, which the "
                    f"OpenFOAM-preCICE adapter's {module} module handles, but 'modules' is "
                    f"({' '.join(pdict.modules)}); add it: 'modules "
                    f"({' '.join([*pdict.modules, module])});'"
                )
    return problems


#: the OpenFOAM-preCICE adapter (1.x) hands a data name to the module whose prefixes it
#: starts with (``CHT.C``, ``FF.C``, ``FSI.C``); longer prefixes first, as the adapter tests
_MODULE_DATA = (
    ("CHT", ("Sink-Temperature", "Temperature", "Heat-Flux", "Heat-Transfer-Coefficient")),
    (
        "FF",
        (
            "VelocityGradient",
            "Velocity",
            "PressureGradient",
            "Pressure",
            "FlowTemperatureGradient",
            "FlowTemperature",
            "AlphaGradient",
            "Alpha",
            "Phi",
        ),
    ),
    ("FSI", ("Force", "DisplacementDelta", "Displacement", "Stress")),
)


def adapter_module(data: str) -> str | None:
    """The adapter module that reads or writes ``data`` (``None``: none of them)."""
    for module, prefixes in _MODULE_DATA:
        if data.startswith(prefixes):
            return module
    return None


def patch_problems(case_dir: Path) -> list[str]:
    """Interface patches of ``system/preciceDict`` that the case's mesh lacks.

    The one check behind both ``gymprecice check`` (on the pristine case, where the mesh
    may exist only as a ``blockMeshDict``) and the preparation of an env's case (right
    after its mesh is built), so both report the same problem the same way.
    """
    if not (case_dir / "system" / "preciceDict").is_file():
        return []
    try:
        pdict = read_precice_dict(case_dir)
    except CaseError as exc:
        return [str(exc)]
    return _patch_problems(case_dir, pdict)


def _mesh_patch_names(case_dir: Path) -> tuple[Path, list[str]] | None:
    """The patches of the built mesh, or else of the blockMeshDict that will build it."""
    boundary = case_dir / "constant" / "polyMesh" / "boundary"
    if not boundary.is_file():
        processors = processor_dirs(case_dir)
        boundary = processors[0] / "constant" / "polyMesh" / "boundary" if processors else boundary
    if boundary.is_file():
        return boundary, [patch.name for patch in read_boundary(boundary.parent)]
    for recipe in (
        case_dir / "system" / "blockMeshDict",
        case_dir / "constant" / "polyMesh" / "blockMeshDict",
    ):
        if recipe.is_file():
            names = block_mesh_patch_names(foamio.read_bytes(recipe)[1])
            if names is None:
                return None  # an old-style or #include'd boundary: blockMesh will tell
            return recipe, names
    return None  # a gmsh recipe: the mesh is known once it is converted


_COMMENTS = re.compile(rb"/\*.*?\*/|//[^\n]*", re.S)
_TOKENS = re.compile(rb"[(){};]|[^\s(){};]+")


def block_mesh_patch_names(data: bytes) -> list[str] | None:
    """The patch names of a blockMeshDict's ``boundary`` list, read from its tokens.

    Parsing the whole file with foamlib takes seconds to minutes (its ``blocks`` and
    face lists), and every env's construction checks its patches; the names need only
    the nesting of brackets. ``None`` without a top-level ``boundary`` list, or where it
    holds a directive (``#include``, ...) that only blockMesh expands.
    """
    tokens = _TOKENS.findall(_COMMENTS.sub(b" ", data))
    depth = 0
    for i, token in enumerate(tokens[:-1]):
        if token in (b"(", b"{"):
            depth += 1
        elif token in (b")", b"}"):
            depth -= 1
        elif depth == 0 and token == b"boundary" and tokens[i + 1] == b"(":
            return _patch_names(tokens, i + 2)
    return None


def _patch_names(tokens: list[bytes], start: int) -> list[str] | None:
    """The names of the ``name { ... }`` entries of the list that opens before ``start``."""
    names: list[str] = []
    depth = 1
    for i in range(start, len(tokens)):
        token = tokens[i]
        if token.startswith((b"#", b"$")):
            return None
        if token in (b"(", b"{"):
            depth += 1
        elif token in (b")", b"}"):
            depth -= 1
            if depth == 0:
                return names
        elif depth == 1 and i + 1 < len(tokens) and tokens[i + 1] == b"{":
            names.append(token.decode())
    return None  # unbalanced: blockMesh will tell


def _patch_problems(case_dir: Path, pdict: PreciceDict) -> list[str]:
    """Interface patches the case's mesh (or its blockMeshDict) lacks."""
    try:
        found = _mesh_patch_names(case_dir)
    except (CaseError, ValueError) as exc:
        return [str(exc)]
    if found is None:
        return []
    boundary, names = found
    problems = []
    for interface in pdict.interfaces:
        for patch in interface.patches:
            if patch not in names:
                close = difflib.get_close_matches(patch, names, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                problems.append(
                    f"{pdict.path}: interface {interface.name!r} names patch {patch!r}, which "
                    f"{boundary} does not have{hint}; its patches are {names}"
                )
    return problems


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
                advice="install OpenFOAM (Debian/Ubuntu: `sudo apt-get install openfoam`) or "
                "source its etc/bashrc; then `gymprecice install openfoam-adapter`",
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
            else "build it for this OpenFOAM with `gymprecice install openfoam-adapter`; "
            "without it OpenFOAM runs uncoupled",
        )
    )
    return checks
