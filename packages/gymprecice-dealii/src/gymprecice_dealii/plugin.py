"""gymprecice plugin for solid participants run by the deal.II-preCICE adapter.

Solver kind ``"dealii"``: the ``elasticity`` program of the deal.II-preCICE adapter
(https://github.com/precice/dealii-adapter), configured by one ``parameters.prm`` in the
solver directory. Options (``physics_simulation_engine.solvers.<name>.options``)::

    {"parameters": "parameters.prm",   # the adapter's parameter file, in the solver dir
     "program": "elasticity",          # name on PATH, or a path (relative: to the run dir)
     "np": 1,                          # > 1: start through "mpirun -np N"
     "mpirun": "mpirun",               # the MPI launcher used when np > 1
     "threads": null,                  # DEAL_II_NUM_THREADS for the solver
     "output_interval": null,          # override 'Output interval' (time steps per VTU)
     "max_displacement": null}         # diverged past this displacement (see .divergence)

The adapter's solvers are serial finite-element codes (the nonlinear one uses threads),
so ``threads`` is usually what speeds them up; ``np`` exists for adapter builds that
distribute their mesh.

What the hooks do:

* prepare: read ``parameters.prm`` of the env's copy, point ``precice config-file`` at the
  env's own preCICE configuration (relative path, as the adapter opens it from its working
  directory), and check the file against that configuration: participant, mesh, read and
  write data, and the time step, which the adapter requires to equal the time-window size
  (it aborts otherwise). Mismatches are reported naming both files.
* reset: delete the adapter's output folder, ``precice-*.log`` (iterations, convergence,
  watch points) and ``precice-profiling/`` of the run directory only. When the env renders,
  set ``Output interval`` to one snapshot per action; when it does not, keep the
  prepared interval (see :mod:`gymprecice_dealii.fields`).
* launch: ``elasticity parameters.prm`` (or through ``mpirun``).
* outputs: ``self.open_output(solver, "watchpoint", point="Flap-Tip")`` in an env reads
  the preCICE watch-point log the solid participant writes. Core opens it for a solver
  of any kind (see :mod:`gymprecice.watchpoints`); this plugin answers where core steps
  aside: a deal.II solver whose participant only ``parameters.prm`` names, and a solver
  of another kind that writes such a log itself (a scripted stand-in for the solid),
  which opts in with the solver option ``{"outputs": "dealii"}``.
* fields (``env.render()``): ``"displacement"`` (and the strain components) of the
  adapter's VTK snapshots, drawn on the deformed solid.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymprecice.plugin import (
    CaseError,
    ConfigError,
    DoctorCheck,
    Field,
    InstallStep,
    LaunchSpec,
    SolverContext,
    WatchPointLog,
    for_kind,
    hookimpl,
    open_watch_point,
    stack_which,
    watch_point_file_name,
    watch_point_options,
)
from gymprecice_dealii import divergence
from gymprecice_dealii import fields as render_fields
from gymprecice_dealii.prm import ElasticityParameters, PrmError

KIND = "dealii"
DEFAULT_PROGRAM = "elasticity"
DEFAULT_PARAMETERS = "parameters.prm"
OPTIONS = (
    "parameters",
    "program",
    "np",
    "mpirun",
    "threads",
    "output_interval",
    divergence.DISPLACEMENT_OPTION,
)
OUTPUTS = ("watchpoint",)
BUILD_ADVICE = (
    "build the deal.II-preCICE adapter with `gymprecice install dealii-adapter` (needs "
    "deal.II >= 9.2), or put your own `elasticity` program on PATH, or set options.program "
    "to its path"
)

LIBRARY_ADVICE = (
    "deal.II is needed to build the deal.II-preCICE adapter, e.g. `apt install libdeal.ii-dev`"
)

# Log lines of a failed elasticity run, and what they mean.
_LOG_HINTS = (
    (
        "This solver supports only constant time-step sizes",
        "'Time step size' in {prm} differs from the preCICE time-window size; make them equal",
    ),
    (
        "was not found in the path for files of class ParameterHandler",
        "the adapter cannot open its parameter file {prm}",
    ),
    (
        "was declared in the current subsection",
        "{prm} sets a key this adapter version does not know (see the line named above)",
    ),
    (
        "error while loading shared libraries",
        "elasticity cannot load a shared library (deal.II or preCICE); check LD_LIBRARY_PATH "
        "or rebuild the adapter against the installed libraries",
    ),
)


# -- hooks -----------------------------------------------------------------------------------


@hookimpl
def gymprecice_solver_kinds() -> dict[str, str]:
    return {KIND: "solid participant: the deal.II-preCICE adapter's elasticity program"}


@hookimpl
@for_kind(KIND)
def gymprecice_validate_case(solver: SolverContext) -> list[str] | None:
    """Check ``parameters.prm`` of the pristine case against the preCICE XML."""
    try:
        _check_options(solver)
        check_against_precice(solver, _read_parameters(solver))
    except (CaseError, ConfigError) as exc:
        return [str(exc)]
    return []


@hookimpl
@for_kind(KIND)
def gymprecice_prepare_case(solver: SolverContext) -> bool | None:
    _check_options(solver)
    params = _read_parameters(solver)
    if solver.precice_config_file is not None:
        target = os.path.relpath(
            Path(solver.precice_config_file).resolve(), solver.run_dir.resolve()
        )
        if params.precice_config_file != target:
            params.precice_config_file = target
    if solver.options.get("output_interval") is not None:
        params.output_interval = _positive_int(solver, "output_interval")
    check_against_precice(solver, params)
    params.write()
    solver.state["participant"] = params.participant
    solver.state["output_folder"] = params.output_folder
    solver.state["output_interval"] = params.output_interval
    solver.state["time_step"] = params.time_step
    return True


@hookimpl
@for_kind(KIND)
def gymprecice_reset_case(solver: SolverContext) -> bool | None:
    run_dir = solver.run_dir.resolve()
    folder = solver.state.get("output_folder")
    if folder is None:
        folder = _read_parameters(solver).output_folder
    outputs = (run_dir / folder).resolve()
    # Only ever delete inside the env's run directory, whatever the parameter file says.
    if outputs != run_dir and outputs.is_relative_to(run_dir) and outputs.is_dir():
        shutil.rmtree(outputs)
    for log in run_dir.glob("precice-*.log"):
        log.unlink(missing_ok=True)
    profiling = run_dir / "precice-profiling"
    if profiling.is_dir():
        shutil.rmtree(profiling)
    _set_output_interval(solver)
    return True


@hookimpl
@for_kind(KIND)
def gymprecice_read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    return render_fields.read_field(solver, name, time)


@hookimpl
@for_kind(KIND)
def gymprecice_launch_solver(solver: SolverContext) -> LaunchSpec | None:
    _check_options(solver)
    program = _find_program(solver, str(solver.options.get("program") or DEFAULT_PROGRAM))
    argv = [program, _parameters_name(solver)]
    ranks = _positive_int(solver, "np") if solver.options.get("np") is not None else 1
    if ranks > 1:
        launcher = str(solver.options.get("mpirun") or "mpirun")
        if shutil.which(launcher) is None:
            raise CaseError(
                f"{solver.describe()}: options.np is {ranks}, but the MPI launcher {launcher!r} "
                f"is not on PATH; install MPI, set options.mpirun, or drop options.np in "
                f"{_where(solver)}"
            )
        argv = [launcher, "-np", str(ranks), *argv]
    env: dict[str, str] = {}
    if solver.options.get("threads") is not None:
        env["DEAL_II_NUM_THREADS"] = str(_positive_int(solver, "threads"))
    return LaunchSpec(argv=argv, cwd=solver.run_dir, env=env)


@hookimpl
@for_kind(KIND)
def gymprecice_check_solver(solver: SolverContext, log_text: str) -> str | None:
    prm = solver.run_dir / _parameters_name(solver)
    for needle, advice in _LOG_HINTS:
        if needle in log_text:
            return advice.format(prm=prm)
    return None


@hookimpl
@for_kind(KIND)
def gymprecice_detect_divergence(
    solver: SolverContext, log_text: str, returncode: int | None
) -> str | None:
    return divergence.detect(solver, log_text, returncode)


@hookimpl
def gymprecice_open_output(
    solver: SolverContext, name: str, options: Mapping[str, Any]
) -> WatchPointLog | None:
    # Core opens any participant's watch point (preCICE writes it, whatever the solver).
    # It leaves this plugin two cases: a deal.II solver whose participant only
    # parameters.prm names, and a solver of another kind that writes the log itself (a test
    # double's stand-in for the solid), which opts in with options {"outputs": "dealii"}.
    stand_in = solver.kind != KIND and solver.options.get("outputs") == KIND
    if solver.kind != KIND and not stand_in:
        return None
    if name not in OUTPUTS:
        raise ConfigError(
            f"{solver.describe()}: no output {name!r}; the deal.II plugin offers {list(OUTPUTS)}"
        )
    if not stand_in:
        known = solver.state.get("participant") or _read_parameters(solver).participant
        return open_watch_point(solver, options, participant=known)
    # A stand-in declares no watch point (the test double would write the same file too).
    point, participant = watch_point_options(solver, options)
    participant = participant or solver.state.get("participant")
    if participant is None:
        return open_watch_point(solver, options)  # raises, naming the fix
    return WatchPointLog(solver.run_dir / watch_point_file_name(participant, point))


@hookimpl
def gymprecice_doctor_checks() -> list[DoctorCheck]:
    version, source = dealii_version()
    program = stack_which(DEFAULT_PROGRAM)
    return [
        DoctorCheck(
            name="deal.II library",
            ok=version is not None,
            detail=f"deal.II {version} ({source})" if version else "not found",
            advice="" if version else LIBRARY_ADVICE,
        ),
        DoctorCheck(
            name="deal.II-preCICE adapter (elasticity)",
            ok=program is not None,
            detail=program or "elasticity is not on PATH nor built by `gymprecice install`",
            advice="" if program else BUILD_ADVICE,
        ),
    ]


# -- checks against the preCICE configuration ------------------------------------------------


def check_against_precice(solver: SolverContext, params: ElasticityParameters) -> None:
    """Fail with both file names when ``parameters.prm`` disagrees with the preCICE XML.

    preCICE would stop the solid with a less direct message (or, for the time step, the
    adapter aborts after the coupling has started), so the env reports it at preparation.
    """
    cfg = solver.precice
    if cfg is None:
        return
    prm, xml = params.where, cfg.path
    participant = params.participant
    if solver.participant and solver.participant != participant:
        raise CaseError(
            f"{prm}: 'Participant name' is {participant!r}, but {_where(solver)} says solver "
            f"{solver.name!r} is participant {solver.participant!r}; make them equal"
        )
    if participant not in cfg.participants:
        raise CaseError(
            f"{prm}: 'Participant name' is {participant!r}, but {xml} has no such participant; "
            f"its participants are {sorted(cfg.participants)}"
        )
    spec = cfg.participants[participant]
    mesh = params.mesh_name
    if mesh not in spec.provided_meshes:
        raise CaseError(
            f"{prm}: 'Mesh name' is {mesh!r}, but in {xml} participant {participant!r} provides "
            f"{spec.provided_meshes}; make the mesh names agree"
        )
    for label, data, pairs, tag in (
        ("Read data name", params.read_data, spec.read_data, "read-data"),
        ("Write data name", params.write_data, spec.write_data, "write-data"),
    ):
        if (data, mesh) not in pairs:
            on_mesh = [d for d, m in pairs if m == mesh]
            raise CaseError(
                f"{prm}: {label!r} is {data!r}, but in {xml} participant {participant!r} has "
                f"<{tag}> {on_mesh} on mesh {mesh!r}; make the data names agree"
            )
    window = cfg.time_window_size(participant)
    if window is not None and abs(params.time_step - window) > 1e-12 * max(1.0, window):
        raise CaseError(
            f"{prm}: 'Time step size' is {params.time_step!r}, but the time-window size of "
            f"{participant!r} in {xml} is {window!r}; the deal.II-preCICE adapter only runs "
            "with time step = time-window size, so make them equal"
        )


# -- helpers ---------------------------------------------------------------------------------


def _where(solver: SolverContext) -> str:
    return str(solver.config_file) if solver.config_file else "the gymprecice configuration"


def _check_options(solver: SolverContext) -> None:
    unknown = sorted(set(solver.options) - set(OPTIONS))
    if unknown:
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: unknown option(s) {unknown}; the deal.II "
            f"plugin knows {list(OPTIONS)}"
        )
    divergence.displacement_limit(solver)


def _positive_int(solver: SolverContext, key: str) -> int:
    value = solver.options.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.{key} must be a positive integer, "
            f"got {value!r}"
        )
    return value


def _set_output_interval(solver: SolverContext) -> None:
    """One snapshot per action when the env renders; the prepared interval when not."""
    if "time_step" not in solver.state:  # a context this plugin did not prepare
        params = _read_parameters(solver)
        solver.state["time_step"] = params.time_step
        solver.state["output_interval"] = params.output_interval
    wanted = render_fields.render_output_interval(solver, solver.state["time_step"])
    solver.state["render_output_interval"] = wanted
    interval = wanted or solver.state["output_interval"]
    params = _read_parameters(solver)
    if params.output_interval != interval:
        params.output_interval = interval
        params.write()


def _parameters_name(solver: SolverContext) -> str:
    return str(solver.options.get("parameters") or DEFAULT_PARAMETERS)


def _read_parameters(solver: SolverContext) -> ElasticityParameters:
    path = solver.run_dir / _parameters_name(solver)
    if not path.is_file():
        raise CaseError(
            f"{solver.describe()}: {path} does not exist; the elasticity program reads its "
            "settings from it (copy the adapter's parameters.prm into the solver directory, "
            "or set options.parameters)"
        )
    try:
        params = ElasticityParameters.read(path)
    except PrmError as exc:
        raise CaseError(str(exc)) from None
    missing = params.missing()
    if missing:
        raise CaseError(
            f"{path}: the deal.II-preCICE adapter needs {missing}, which this file does not set"
        )
    return params


def _find_program(solver: SolverContext, program: str) -> str:
    if os.sep in program:
        path = Path(program) if os.path.isabs(program) else solver.run_dir / program
        if path.is_file() and os.access(path, os.X_OK):
            return str(path)
    else:
        found = stack_which(program)  # PATH, then what `gymprecice install` built
        if found:
            return found
    raise CaseError(
        f"{solver.describe()}: the deal.II-preCICE adapter program {program!r} is not "
        f"{'an executable file' if os.sep in program else 'on PATH'}; {BUILD_ADVICE} "
        f"(options.program in {_where(solver)})"
    )


_VERSION_DEFINE = re.compile(r'#\s*define\s+DEAL_II_PACKAGE_VERSION\s+"([^"]+)"')


def dealii_version() -> tuple[str | None, str]:
    """Installed deal.II version and where it was found: pkg-config, dpkg, or the header."""
    for argv, source in (
        (["pkg-config", "--modversion", "deal.II"], "pkg-config"),
        (["dpkg-query", "-W", "-f=${Version}", "libdeal.ii-dev"], "dpkg libdeal.ii-dev"),
    ):
        if shutil.which(argv[0]) is None:
            continue
        try:
            done = subprocess.run(argv, capture_output=True, text=True, timeout=10, check=False)
        except (OSError, subprocess.SubprocessError):
            continue
        if done.returncode == 0 and done.stdout.strip():
            return done.stdout.strip(), source
    roots = [os.environ.get("DEAL_II_DIR"), "/usr/local", "/usr", "/opt/deal.II"]
    for root in filter(None, roots):
        header = Path(root) / "include" / "deal.II" / "base" / "config.h"
        try:
            match = _VERSION_DEFINE.search(header.read_text(errors="replace"))
        except OSError:
            continue
        if match:
            return match.group(1), str(header)
    return None, ""


@hookimpl
def gymprecice_install_steps() -> list[InstallStep]:
    from gymprecice_dealii.adapter_install import elasticity_step

    return [elasticity_step()]
