"""gymprecice plugin for FEniCS participants coupled through fenicsprecice.

Solver kind ``"fenics"``: a Python script that solves with legacy FEniCS (dolfin) and couples
through ``fenicsprecice.Adapter``, configured by a ``precice-adapter-config.json`` in the
solver directory, like the preCICE tutorials' ``solid-fenics`` participants. Options
(``physics_simulation_engine.solvers.<name>.options``)::

    {"script": "solid.py",                             # the participant script
     "adapter_config": "precice-adapter-config.json",  # fenicsprecice's configuration
     "python": null,          # interpreter; default: the FEniCS solver environment
     "threads": 1,            # OMP_NUM_THREADS for the script
     "output_folder": "output",  # what the script writes, removed at every reset
     "starts": null,          # saved states to start episodes from (below)
     "start_file": "start-state.npz"}  # where reset puts the episode's start state

``starts`` (``{"train": [FILE, ...], "eval": [...], "validation": [...]}``, validation
optional; files relative to the solver directory or absolute) is for a solid that
restarts from a saved state matching the fluid's: an episode that starts from a fluid
snapshot of a swinging run (the OpenFOAM plugin's ``snapshots``) needs the solid's
displacement and velocity of that moment. At every reset the start the env's reset
options choose (``env.reset(options={"split": "eval", "start": k})``) is copied to
``<run dir>/<start_file>``, replacing the last episode's, for the script to read (the
FSI3 bar's ``solid.py`` restarts from ``solid.json``'s ``start_state``). The choice is
the OpenFOAM plugin's (:func:`gymprecice.plugin.choose_start`, with the seed core gives
every solver): ``start`` k takes the split's k-th file *in the order given*, and the
OpenFOAM plugin takes its k-th snapshot in time order, so give the files in time order,
the state of each snapshot at the same place; without ``start`` both draw the same index.
(Split ``"all"`` is train's files, then eval's, then validation's: the same draws as the
OpenFOAM plugin's explicit ``snapshots`` split, but its ``start`` k counts in that order,
where the OpenFOAM plugin counts all snapshots in time order.) Without ``starts`` reset
writes no start file.

The script runs in the FEniCS solver environment's interpreter (see
:mod:`gymprecice_fenics.solver_env`), never in gymprecice's own: Debian's dolfin needs the
system Python and numpy 1.x.

What the hooks do:

* validate (pristine case, writes nothing): options, the script, adapter file and start
  files exist,
  and the adapter file's participant, mesh and data names agree with the preCICE XML,
  including that what the script reads is what its partner sends (a controller writing
  ``Heat-Flux`` where the script reads ``Temperature`` is named with both files).
* prepare: the solver environment is probed (no interpreter, dolfin or fenicsprecice
  missing, numpy 2: each with the fix); the env's copy of the adapter file is pointed at the
  env's preCICE configuration; and the script is *dry-run* up to ``Adapter.initialize``
  (:mod:`gymprecice_fenics.dry_run`): a script that fails at import or while building its
  mesh is reported with its own error line before any coupling starts, and the coupling
  vertices it would give preCICE are kept for the interface geometry.
* reset: removes the output folder, ``precice-*.log``, ``precice-profiling/``,
  ``precice-exports/`` and ``gymprecice-fields/`` of the run directory; with ``starts``,
  copies the episode's start state to ``start_file``.
* launch: ``<fenics python> <script>`` in the run directory, unbuffered; when the env
  renders, with ``GYMPRECICE_FIELDS`` and ``GYMPRECICE_FIELD_INTERVAL`` set.
* fields (``env.render()``): the ``gymprecice-fields/<name>.npz`` files the script writes
  when asked (see :mod:`gymprecice_fenics.fields`).
* check: a Python traceback in the log is turned into what failed and the fix (an import,
  numpy 2, a form that fails to compile).
* divergence: a script that died with a PETSc ``DIVERGED_*`` reason or a Newton solver
  that did not converge diverged.
* interface geometry: the dry run's vertices, for a controller mesh mapped to the
  script's coupling mesh or to a second mesh the script sets through the adapter's
  participant (fenicsprecice 2.x couples one mesh; a heater on another boundary needs a
  second).
* install: ``gymprecice install fenics`` builds the solver environment.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
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
    SolverContext,
    choose_start,
    command_output,
    first_match,
    for_kind,
    hookimpl,
    solver_environment,
)
from gymprecice_fenics import fields as render_fields
from gymprecice_fenics import solver_env
from gymprecice_fenics.adapter_config import AdapterConfig, check_against_precice

KIND = "fenics"
DEFAULT_SCRIPT = "solid.py"
DEFAULT_ADAPTER_CONFIG = "precice-adapter-config.json"
DEFAULT_OUTPUT = "output"
DEFAULT_START_FILE = "start-state.npz"
OPTIONS = (
    "script",
    "adapter_config",
    "python",
    "threads",
    "output_folder",
    "starts",
    "start_file",
)
#: The splits of ``starts``; train and eval are needed, validation is optional.
START_SPLITS = ("train", "eval", "validation")
VALIDATION_HINT = (
    "give the FEniCS solver option starts a 'validation' list "
    "({'train': [...], 'eval': [...], 'validation': [...]})"
)
DRY_RUN = Path(__file__).with_name("dry_run.py")
DRY_RUN_TIMEOUT = 300.0  # the first run of a script compiles its forms

_DIVERGENCE = (
    re.compile(r"DIVERGED_[A-Z_]+"),
    re.compile(r"Newton solver did not converge"),
)

# Exception lines of a failed script, and what they mean.
_TRACEBACK_HINTS = (
    (
        re.compile(r"No module named '(dolfin|fenics|ufl|ffc)"),
        "the interpreter {python} has no FEniCS; " + solver_env.INSTALL_ADVICE,
    ),
    (
        re.compile(r"No module named '(fenicsprecice|precice)'"),
        "the interpreter {python} lacks the preCICE side; run `gymprecice install fenics`",
    ),
    (
        re.compile(r"NumPy 1\.x cannot be run in|numpy\.core\.multiarray failed|_ARRAY_API"),
        "numpy 2 in the solver environment; fenicsprecice and Debian's dolfin need numpy<2: "
        "`gymprecice install fenics --force` rebuilds the environment on Debian's numpy",
    ),
    (
        re.compile(r"(ffc|ufl|dijitso|UFL|FFC)\w*[.:]|Unable to compile|UFLException"),
        "a form in {script} failed to compile (FFC/UFL); fix the variational form named in the "
        "traceback",
    ),
)


# -- hooks -----------------------------------------------------------------------------------


@hookimpl
def gymprecice_solver_kinds() -> dict[str, str]:
    return {KIND: "FEniCS (dolfin) participant script coupled through fenicsprecice"}


@hookimpl
@for_kind(KIND)
def gymprecice_validate_case(solver: SolverContext) -> list[str] | None:
    """Check the pristine case against the preCICE XML; writes nothing."""
    try:
        _check_options(solver)
        _script(solver)
        adapter = _adapter_config(solver)
        _starts(solver)
    except (CaseError, ConfigError) as exc:
        return [str(exc)]
    if solver.precice is None:
        return []
    return check_against_precice(adapter, solver.precice, solver.participant, _where(solver))


@hookimpl
@for_kind(KIND)
def gymprecice_prepare_case(solver: SolverContext) -> bool | None:
    _check_options(solver)
    script = _script(solver)
    _starts(solver)
    python = _checked_python(solver)
    adapter = _adapter_config(solver)
    if solver.precice_config_file is not None:
        adapter.point_at(Path(solver.precice_config_file))
    if solver.precice is not None:
        problems = check_against_precice(
            adapter, solver.precice, solver.participant, _where(solver)
        )
        if problems:
            raise CaseError("\n".join(problems))
    solver.state["participant"] = adapter.participant
    # A script that restarts reads its start file before it couples: the dry run gets
    # the first training start, and every reset puts the episode's own in its place.
    _place_start(solver, solver.run_dir.resolve(), first=True)
    solver.state["meshes"] = dry_run(solver, python, script)["meshes"]
    return True


@hookimpl
@for_kind(KIND)
def gymprecice_reset_case(solver: SolverContext) -> bool | None:
    run_dir = solver.run_dir.resolve()
    output = str(solver.options.get("output_folder") or DEFAULT_OUTPUT)
    for folder in (output, "precice-profiling", "precice-exports"):
        path = (run_dir / folder).resolve()
        # Only ever delete inside the env's run directory, whatever the options say.
        if path != run_dir and path.is_relative_to(run_dir) and path.is_dir():
            shutil.rmtree(path)
    for log in run_dir.glob("precice-*.log"):
        log.unlink(missing_ok=True)
    render_fields.clear_fields(run_dir)
    _place_start(solver, run_dir)
    return True


@hookimpl
@for_kind(KIND)
def gymprecice_launch_solver(solver: SolverContext) -> LaunchSpec | None:
    _check_options(solver)
    script = _script(solver)
    python = _checked_python(solver)
    env = {**_env(solver), **render_fields.field_env(solver)}
    return LaunchSpec(argv=[python, "-u", script.name], cwd=solver.run_dir, env=env)


@hookimpl
@for_kind(KIND)
def gymprecice_read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    return render_fields.read_field(solver, name, time)


@hookimpl
@for_kind(KIND)
def gymprecice_check_solver(solver: SolverContext, log_text: str) -> str | None:
    if "Traceback (most recent call last)" not in log_text:
        return None
    return _explain_traceback(solver, log_text)


@hookimpl
@for_kind(KIND)
def gymprecice_detect_divergence(
    solver: SolverContext, log_text: str, returncode: int | None
) -> str | None:
    if returncode is None or returncode == 0:
        return None
    return first_match(log_text, _DIVERGENCE)


@hookimpl
@for_kind(KIND)
def gymprecice_interface_geometry(
    solver: SolverContext, interface: str, mesh: str
) -> InterfaceGeometry | None:
    if "meshes" not in solver.state:
        solver.state["meshes"] = dry_run(solver, _checked_python(solver), _script(solver))["meshes"]
    coordinates = solver.state["meshes"].get(mesh)
    return None if not coordinates else InterfaceGeometry(coordinates)


@hookimpl
def gymprecice_doctor_checks() -> list[DoctorCheck]:
    dolfin = command_output(["dpkg-query", "-W", "-f=${Version}", "python3-dolfin"])
    report = solver_env.probe()
    return [
        DoctorCheck(
            name="FEniCS (Debian python3-dolfin)",
            ok=bool(dolfin),
            detail=f"python3-dolfin {dolfin}" if dolfin else "not installed",
            advice=""
            if dolfin
            else "Debian/Ubuntu: `sudo apt-get install python3-dolfin python3-scipy "
            "python3-venv`, then `gymprecice install fenics`",
        ),
        DoctorCheck(
            name="FEniCS solver environment",
            ok=report.ok,
            detail=report.summary() if report.ok else "; ".join(report.problems),
            advice="" if report.ok else solver_env.INSTALL_ADVICE,
        ),
    ]


@hookimpl
def gymprecice_install_steps() -> list[InstallStep]:
    return [solver_env.fenics_install_step()]


# -- the dry run -----------------------------------------------------------------------------


def dry_run(solver: SolverContext, python: str, script: Path) -> dict[str, Any]:
    """Run ``script`` up to ``Adapter.initialize`` in the run directory (see ``dry_run.py``).

    Returns ``{"participant", "mesh", "coordinates", "meshes"}`` (``meshes``: the vertices of
    every mesh the script set, the adapter's and any it set through the adapter's
    participant); raises :class:`CaseError` with the
    script's own error and the fix when it fails before coupling.
    """
    try:
        proc = subprocess.run(
            [python, str(DRY_RUN), script.name],
            cwd=solver.run_dir,
            capture_output=True,
            text=True,
            timeout=DRY_RUN_TIMEOUT,
            stdin=subprocess.DEVNULL,
            env={**os.environ, **_env(solver)},
            start_new_session=True,
        )
    except subprocess.TimeoutExpired:
        raise CaseError(
            f"{solver.describe()}: {script} did not reach fenicsprecice's Adapter.initialize "
            f"within {DRY_RUN_TIMEOUT:.0f} s when run without coupling; it must build its mesh "
            "and call precice.initialize(...) before solving"
        ) from None
    line = next(
        (ln for ln in proc.stdout.splitlines() if ln.startswith("GYMPRECICE-DRY-RUN ")), None
    )
    if line is not None:
        found = json.loads(line.split(" ", 1)[1])
        found.setdefault("meshes", {found["mesh"]: found["coordinates"]})
        if not found["coordinates"]:
            raise CaseError(
                f"{script}: the coupling subdomain given to Adapter.initialize contains no mesh "
                f"vertex (mesh {found['mesh']!r}); fix the SubDomain's inside()"
            )
        return found
    if proc.returncode == 4:
        raise CaseError(
            f"{script} ended without calling fenicsprecice's Adapter.initialize; a FEniCS "
            "participant must create fenicsprecice.Adapter(...) and call its initialize(...)"
        )
    explained = _explain_traceback(solver, proc.stderr + proc.stdout)
    raise CaseError(
        explained
        or f"{script} failed before coupling (exit status {proc.returncode}): "
        f"{_last_line(proc.stderr + proc.stdout)}"
    )


# -- helpers ---------------------------------------------------------------------------------


def _where(solver: SolverContext) -> str:
    return str(solver.config_file) if solver.config_file else "the gymprecice configuration"


def _check_options(solver: SolverContext) -> None:
    unknown = sorted(set(solver.options) - set(OPTIONS))
    if unknown:
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: unknown option(s) {unknown}; the FEniCS "
            f"plugin knows {list(OPTIONS)}"
        )
    threads = solver.options.get("threads")
    if threads is not None and (
        isinstance(threads, bool) or not isinstance(threads, int) or threads < 1
    ):
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.threads must be a positive "
            f"integer, got {threads!r}"
        )


def _starts(solver: SolverContext) -> dict[str, list[str]] | None:
    """The ``starts`` option checked: each split's files as given (``None``: no option).

    Raises :class:`ConfigError` naming the option, the file and the fix for a malformed
    option, a missing file or a ``start_file`` outside the run directory.
    """
    raw = solver.options.get("starts")
    where = f"{_where(solver)}: {solver.describe()}: options"
    _start_file(solver)
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise ConfigError(
            f"{where}.starts must be {{'train': [FILE, ...], 'eval': [...]}} (and optionally "
            f"'validation'), got {raw!r}"
        )
    unknown = sorted(set(raw) - set(START_SPLITS))
    missing = [key for key in ("train", "eval") if not raw.get(key)]
    if unknown or missing:
        raise ConfigError(
            f"{where}.starts: keys must be 'train' and 'eval', each a non-empty list of files, "
            f"and optionally 'validation'; "
            + (f"unknown {unknown}" if unknown else f"missing or empty {missing}")
        )
    pools: dict[str, list[str]] = {}
    for key in START_SPLITS:
        files = raw.get(key)
        if files is None:
            continue
        if isinstance(files, str) or not isinstance(files, list):
            raise ConfigError(f"{where}.starts[{key!r}] must be a list of files, got {files!r}")
        for index, name in enumerate(files):
            if not isinstance(name, str) or not name:
                raise ConfigError(
                    f"{where}.starts[{key!r}][{index}] must be a file name, got {name!r}"
                )
            path = _start_path(solver, name)
            if not path.is_file():
                raise ConfigError(
                    f"{where}.starts[{key!r}][{index}]: the start file {path} does not exist; "
                    f"put it in the solver directory {solver.source_dir} (names are relative "
                    "to it) or give its absolute path"
                )
        pools[key] = list(files)
    return pools


def _start_path(solver: SolverContext, name: str) -> Path:
    path = Path(name)
    return path if path.is_absolute() else Path(solver.source_dir) / path


def _start_file(solver: SolverContext) -> str:
    """The ``start_file`` option: a relative path inside the run directory."""
    name = solver.options.get("start_file", DEFAULT_START_FILE)
    if (
        not isinstance(name, str)
        or not name
        or Path(name).is_absolute()
        or ".." in Path(name).parts
    ):
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.start_file must be a file name "
            f"relative to the run directory (default {DEFAULT_START_FILE!r}), got {name!r}"
        )
    return name


def _place_start(solver: SolverContext, run_dir: Path, first: bool = False) -> None:
    """Copy the episode's start state to ``start_file`` (nothing without ``starts``).

    The start is chosen as the OpenFOAM plugin chooses its snapshot, from the reset
    options and ``solver.rng``; ``first``: the first training start (the dry run's).
    """
    pools = _starts(solver)
    if pools is None:
        return
    if first:
        chosen = pools["train"][0]
    else:
        everything = list(dict.fromkeys(name for files in pools.values() for name in files))
        chosen = choose_start(
            pools,
            everything,
            solver.rng,
            solver.reset_options.get("split"),
            solver.reset_options.get("start"),
            what="start",
            validation_hint=VALIDATION_HINT,
        )
    target = run_dir / _start_file(solver)
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(target.name + ".partial")
    shutil.copyfile(_start_path(solver, chosen), partial)
    # A rename replaces the last episode's file (or a link left there) without writing
    # through it.
    os.replace(partial, target)


def _script(solver: SolverContext) -> Path:
    name = str(solver.options.get("script") or DEFAULT_SCRIPT)
    path = solver.run_dir / name
    if not path.is_file():
        raise CaseError(
            f"{solver.describe()}: the participant script {path} does not exist; put it in "
            f"the solver directory or set options.script in {_where(solver)}"
        )
    return path


def _adapter_config(solver: SolverContext) -> AdapterConfig:
    name = str(solver.options.get("adapter_config") or DEFAULT_ADAPTER_CONFIG)
    return AdapterConfig.read(solver.run_dir / name)


def _python(solver: SolverContext) -> str:
    explicit = solver.options.get("python")
    if not explicit:
        return solver_env.fenics_python()
    path = Path(str(explicit))
    if os.sep in str(explicit) and not path.is_absolute():
        path = solver.run_dir / path
    elif os.sep not in str(explicit):
        return shutil.which(str(explicit)) or str(explicit)
    return str(path)


def _checked_python(solver: SolverContext) -> str:
    """The interpreter to run the script with; raises with the fix when it cannot."""
    python = _python(solver)
    report = solver_env.probe(python)
    if not report.ok:
        raise CaseError(
            f"{solver.describe()}: the FEniCS solver environment is not usable: "
            + "; ".join(report.problems)
        )
    return python


def _env(solver: SolverContext) -> dict[str, str]:
    threads = solver.options.get("threads") or 1
    return {
        "OMP_NUM_THREADS": str(threads),
        "PYTHONUNBUFFERED": "1",
        # gymprecice's own venv must not leak into the solver environment's interpreter.
        "PYTHONNOUSERSITE": "1",
        "PYTHONPATH": "",
        **solver_environment(),
    }


def _last_line(text: str) -> str:
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else "(no output)"


def _explain_traceback(solver: SolverContext, text: str) -> str | None:
    """What a script's traceback means, naming the script and the fix."""
    if "Traceback (most recent call last)" not in text:
        return None
    script = solver.run_dir / str(solver.options.get("script") or DEFAULT_SCRIPT)
    error = _last_line(text.split("Traceback (most recent call last)")[-1])
    for pattern, advice in _TRACEBACK_HINTS:
        if pattern.search(text):
            fix = advice.format(python=_python(solver), script=script)
            return f"{solver.describe()}: {script} failed: {error}; {fix}"
    return f"{solver.describe()}: {script} failed: {error}; fix the script (see the traceback)"
