"""gymprecice hooks for solver kind ``"openfoam"``: any OpenFOAM case with the preCICE adapter.

Solver options (``physics_simulation_engine.solvers.<name>.options``):

``application``      solver to run (default: controlDict's ``application``)
``np``               processes; 1 = serial, >1 must match ``system/decomposeParDict``
                     (default: the dictionary's ``numberOfSubdomains``, 1 without it)
``prerun_end_time``  pre-run uncoupled to this time once; episodes start there
``prerun_cache``     share pre-runs between envs and runs (default true: the user cache,
                     see :mod:`.prerun_cache`; false: never; or a directory)
``initial_time``     start episodes from this existing time directory instead
``snapshots``        times (or ``{"train": [...], "eval": [...], "validation": [...]}``) to
                     draw episode starts from; ``eval_fraction`` (default 0.25) sets the
                     fixed split, ``validation_fraction`` (default 0: none) a third set
``end_time``         controlDict ``endTime`` to use (default: long enough for the coupling)
``geo``, ``msh``       the gmsh geometry or mesh to convert when the case ships no mesh
``max_courant``      end the episode as diverged once the log's Courant number max passes
                     this (a positive number; default: no guard). A floating-point
                     exception or ``Maximum number of iterations exceeded`` is divergence
                     anyway (see :mod:`.divergence`)
``solver_args``, ``mpirun_args``, ``prerun_args``, ``prerun_timeout``, ``openfoam_bashrc``

Any other option key is refused when the case is prepared, naming the closest known one.

Outputs (``env.open_output(solver, name, **options)``): ``"probes"`` (option ``field``),
``"forces"`` (``which="force"|"moment"``), ``"forceCoeffs"``, or any function-object name
under ``postProcessing`` with ``type`` one of those; ``object`` overrides the directory
name and ``start_time`` the first start-time directory read (default: the episode's).
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice.plugin import (
    CaseError,
    ConfigError,
    DoctorCheck,
    Field,
    InstallStep,
    InterfaceGeometry,
    LaunchSpec,
    OutputReader,
    ParticipantSpec,
    SolverContext,
    SolverSketch,
    for_kind,
    hookimpl,
)
from gymprecice_openfoam import case, checks, divergence, outputs
from gymprecice_openfoam import fields as render_fields
from gymprecice_openfoam import mesh as meshes  # the geometry hook's argument is named mesh

KIND = "openfoam"


@hookimpl
def gymprecice_solver_kinds() -> Mapping[str, str]:
    return {KIND: "OpenFOAM case coupled through the OpenFOAM-preCICE adapter"}


#: the solver options this plugin reads (see the module docstring)
OPTIONS = (
    "application",
    "np",
    "prerun_end_time",
    "prerun_cache",
    "initial_time",
    "snapshots",
    "eval_fraction",
    "validation_fraction",
    "end_time",
    "geo",
    "msh",
    "solver_args",
    "mpirun_args",
    "prerun_args",
    "prerun_timeout",
    "openfoam_bashrc",
    divergence.COURANT_OPTION,
)


@hookimpl
@for_kind(KIND)
def gymprecice_validate_case(solver: SolverContext) -> list[str] | None:
    """``gymprecice check`` and env construction: the case against the preCICE XML."""
    try:
        _check_options(solver)
    except ConfigError as exc:
        return [str(exc), *checks.validate_case(solver)]
    return checks.validate_case(solver)


@hookimpl
@for_kind(KIND)
def gymprecice_prepare_case(solver: SolverContext) -> bool | None:
    _check_options(solver)
    case.prepare_case(solver)
    return True


def _check_options(solver: SolverContext) -> None:
    """A misspelt option must not be ignored (``prerun_end_tme`` would skip the pre-run)."""
    unknown = sorted(set(solver.options) - set(OPTIONS))
    if not unknown:
        divergence.courant_limit(solver)
        return
    hints = []
    for key in unknown:
        close = difflib.get_close_matches(key, OPTIONS, n=1)
        hints.append(f"{key!r} (did you mean {close[0]!r}?)" if close else repr(key))
    where = str(solver.config_file) if solver.config_file else "the gymprecice configuration"
    raise ConfigError(
        f"{where}: {solver.describe()}: unknown option(s) {', '.join(hints)} in "
        f"physics_simulation_engine.solvers.{solver.name}.options; the OpenFOAM plugin "
        f"knows {list(OPTIONS)}"
    )


@hookimpl
@for_kind(KIND)
def gymprecice_reset_case(solver: SolverContext) -> bool | None:
    case.reset_case(solver)
    # what env.render() draws, written every action; nothing extra when it does not render
    render_fields.set_field_writes(
        Path(solver.run_dir),
        solver.fields,
        solver.field_interval,
        after_adapter=render_fields.after_adapter(solver),
    )
    return True


@hookimpl
@for_kind(KIND)
def gymprecice_read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    return render_fields.read_field(solver, name, time)


@hookimpl
@for_kind(KIND)
def gymprecice_sketch_case(solver: SolverContext) -> SolverSketch | None:
    from gymprecice_openfoam.sketch import case_sketch  # only `gymprecice sketch` needs it

    return case_sketch(solver)


@hookimpl
@for_kind(KIND)
def gymprecice_launch_solver(solver: SolverContext) -> LaunchSpec | None:
    return case.launch_spec(solver)


def _log_name(solver: SolverContext) -> str | None:
    state = solver.state.get("openfoam")
    if isinstance(state, case.PreparedCase):
        return case.log_name(state.application)
    loaded = case.PreparedCase.load(Path(solver.run_dir))
    return case.log_name(loaded.application) if loaded else None


@hookimpl
@for_kind(KIND)
def gymprecice_check_solver(solver: SolverContext, log_text: str) -> str | None:
    return checks.check_solver(solver, log_text, _log_name(solver))


@hookimpl
@for_kind(KIND)
def gymprecice_detect_divergence(
    solver: SolverContext, log_text: str, returncode: int | None
) -> str | None:
    return divergence.detect(solver, log_text, returncode)


def _parallel(solver: SolverContext) -> bool | None:
    state = solver.state.get("openfoam")
    if not isinstance(state, case.PreparedCase):
        state = case.PreparedCase.load(Path(solver.run_dir))
    return None if state is None else state.np > 1


@hookimpl
@for_kind(KIND)
def gymprecice_interface_geometry(
    solver: SolverContext, interface: str, mesh: str
) -> InterfaceGeometry | None:
    run_dir = Path(solver.run_dir)
    if not (run_dir / "system" / "preciceDict").is_file():
        return None
    pdict = meshes.read_precice_dict(run_dir)
    if pdict.interface_for_mesh(mesh) is None:
        _refuse_unknown_mesh(solver, pdict, mesh)
        return None
    dimensions = 3
    if solver.precice is not None and mesh in solver.precice.meshes:
        dimensions = solver.precice.meshes[mesh].dimensions
    return meshes.interface_geometry(
        run_dir, mesh, dimensions=dimensions, parallel=_parallel(solver)
    )


def _refuse_unknown_mesh(solver: SolverContext, pdict: meshes.PreciceDict, mesh: str) -> None:
    """The XML gives ``mesh`` to this case's participant, yet preciceDict does not use it.

    Only then is the mismatch this case's fault; a mesh of another participant is simply
    not ours to describe.
    """
    precice = solver.precice
    if precice is None or pdict.participant is None:
        return
    if mesh not in precice.participants.get(pdict.participant, _NOBODY).provided_meshes:
        return
    used = [i.mesh for i in pdict.interfaces]
    raise CaseError(
        f"{pdict.path}: participant {pdict.participant!r} provides mesh {mesh!r} in "
        f"{solver.precice_config_file or precice.path}, but no interface of preciceDict uses "
        f"it (preciceDict's meshes: {used}); set that interface's 'mesh' to {mesh!r}"
    )


_NOBODY = ParticipantSpec(name="")

_TYPES = {"probes": "probes", "forces": "forces", "forceCoeffs": "forceCoeffs"}


def open_reader(
    run_dir: Path, name: str, options: Mapping[str, Any], start_time: float | None
) -> outputs.TableReader:
    """Build the reader for output ``name`` of a case (see the module docstring)."""
    opts = dict(options)
    kind = opts.pop("type", None) or _TYPES.get(name)
    directory = run_dir / "postProcessing" / str(opts.pop("object", name))
    start = opts.pop("start_time", start_time)
    if kind is None:
        kind = _guess_type(directory)
    if kind == "probes":
        field = opts.pop("field", None) or _single_field(directory)
        reader: outputs.TableReader = outputs.ProbesReader(directory, field, start_time=start)
    elif kind == "forces":
        reader = outputs.ForcesReader(
            directory, which=str(opts.pop("which", "force")), start_time=start
        )
    elif kind == "forceCoeffs":
        reader = outputs.ForceCoeffsReader(directory, start_time=start)
    else:
        raise ConfigError(
            f"output {name!r}: unknown type {kind!r}; use 'probes', 'forces' or 'forceCoeffs' "
            "(option type=...)"
        )
    if opts:
        raise ConfigError(f"output {name!r}: unknown options {sorted(opts)}")
    return reader


def _guess_type(directory: Path) -> str | None:
    for _, path in outputs.time_dirs(directory):
        names = {p.name for p in path.iterdir()}
        if names & {"force.dat", "forces.dat", "moment.dat"}:
            return "forces"
        if names & {"coefficient.dat", "forceCoeffs.dat"}:
            return "forceCoeffs"
        if names:
            return "probes"
    raise CaseError(
        f"{directory}: no output yet to tell its type; pass type='probes'|'forces'|"
        "'forceCoeffs' when opening it"
    )


def _single_field(directory: Path) -> str:
    fields = sorted({p.name for _, d in outputs.time_dirs(directory) for p in d.iterdir()})
    if len(fields) == 1:
        return fields[0]
    raise ConfigError(
        f"{directory}: say which probed field to read (field=...); found {fields or 'none yet'}"
    )


@hookimpl(trylast=True)
def gymprecice_open_output(
    solver: SolverContext, name: str, options: Mapping[str, Any]
) -> OutputReader | None:
    # The readers are about a file format, not a solver: a solver of another kind that
    # writes OpenFOAM-format function-object output (a test double's partner, a wrapper
    # script) opts in with options {"outputs": "openfoam"}.
    if solver.kind != KIND and solver.options.get("outputs") != "openfoam":
        return None
    start = solver.state.get("initial_time")
    return open_reader(Path(solver.run_dir), name, options, start)


@hookimpl
def gymprecice_doctor_checks() -> list[DoctorCheck]:
    return checks.doctor_checks()


@hookimpl
def gymprecice_install_steps() -> list[InstallStep]:
    from gymprecice_openfoam.adapter_install import openfoam_adapter_step

    return [openfoam_adapter_step()]
