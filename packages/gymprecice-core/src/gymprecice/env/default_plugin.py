"""Core's own plugin: the solver kinds that need no solver-specific knowledge.

``"script"``
    The Gym-preCICE paper's way of driving a solver: three shell scripts in the solver's
    directory. ``prerun_script`` runs once when the env prepares its copy of the case (for
    example mesh generation and an uncoupled run to a developed flow), ``reset_script``
    before every episode, and ``run_script`` is the coupled solver itself. Options (filled
    from ``physics_simulation_engine`` in the paper's configuration form)::

        {"run_script": "run.sh", "reset_script": "reset.sh", "prerun_script": "prerun.sh",
         "interpreter": null, "prepare_timeout": null, "reset_timeout": 600,
         "env": {}, "log_name": "solver.log", "divergence_patterns": []}

    Scripts are executed directly, honouring their ``#!`` line, as the paper's
    ``./run.sh`` did. A script without the executable bit is an error with the fix
    (``chmod +x``) rather than being run through ``bash``: guessing an interpreter would
    run a Python script as shell code. Set ``"interpreter": "bash"`` (any program) to run
    scripts through it instead, e.g. for a case unpacked from an archive that lost the
    bit. An executable text file without a ``#!`` line runs under ``sh``, exactly what the
    paper's ``shell=True`` did.

``"command"``
    Any program given as an argument vector, run as is in the solver's run directory::

        {"argv": ["{python}", "-m", "gymprecice.testing.partner", "--participant",
                  "{participant}", "--config", "{precice_config}"],
         "prepare_argv": [...], "reset_argv": [...],
         "prepare_timeout": null, "reset_timeout": 600, "env": {}, "log_name": "solver.log",
         "divergence_patterns": []}

    ``prepare_argv`` runs once per env, ``reset_argv`` before every episode. Placeholders
    in any argument: ``{python}`` (this interpreter, so the same virtual environment runs
    the partner), ``{run_dir}``, ``{env_dir}``, ``{env_index}``, ``{solver}``,
    ``{participant}``, ``{precice_config}`` (the env's own preCICE configuration). Only
    these exact tokens are replaced, so other braces (JSON arguments) are left alone.

Both kinds take ``"divergence_patterns"``: regular expressions whose first matching log
line (while the solver runs, or after it failed) means the solver diverged under the
agent's actions, e.g. ``["Floating point exception", "Courant Number .* max: [0-9]{3,}"]``;
see :func:`gymprecice.hookspecs.gymprecice_detect_divergence`. None by default: a generic
program's failures are faults unless the case says otherwise.

Outputs: core itself opens a participant's preCICE watch point for a solver of any kind,
these two included (``self.open_output("solid", "watchpoint", point="Flap-Tip")``, see
:func:`gymprecice_open_output`). A solver's other files are read by a plugin's readers:
the option ``"outputs"`` names the plugin (``"openfoam"`` for OpenFOAM-format
function-object output, ``"dealii"`` for a watch-point log the program writes itself).

Both kinds hand core fields to draw (``env.render()``) through files: when the env renders,
the launched program finds ``GYMPRECICE_FIELDS`` (comma-separated field names) in its
environment and writes ``gymprecice-fields/<name>.npz`` in its working directory at every
time window (:func:`gymprecice.fields.write_field_file`); reset removes them. Without the
variable it must write nothing, so an env that does not render costs nothing.

Both kinds export ``GYMPRECICE_ENV_INDEX``, ``GYMPRECICE_ENV_DIR``, ``GYMPRECICE_RUN_DIR``,
``GYMPRECICE_SOLVER``, ``GYMPRECICE_PARTICIPANT``, ``GYMPRECICE_PRECICE_CONFIG`` and, for
reset, ``GYMPRECICE_SEED`` (drawn from the episode's seeded generator, so a reset script
can randomise the initial state reproducibly). Prepare and reset steps run to completion
through :func:`gymprecice.env.short_commands.run_to_completion` (own process group, log
file in the run directory, timeout); the coupled program is described by a
:class:`~gymprecice.solver.LaunchSpec` and core starts it.

This module is loaded on every ``import gymprecice``: it imports nothing heavy at the top.
"""

from __future__ import annotations

import functools
import os
import re
import shlex
import shutil
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from gymprecice.plugin import watchpoints
from gymprecice.plugin.divergence import first_match
from gymprecice.plugin.errors import CaseError, ConfigError
from gymprecice.plugin.fields import FIELDS_DIR, FIELDS_ENV_VAR, Field, field_file, read_field_file
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.options import refuse_unknown_options
from gymprecice.plugin.solver import DoctorCheck, LaunchSpec, OutputReader, SolverContext
from gymprecice.tools.precice_install import core_install_steps
from gymprecice.tools.stack import InstallStep

SCRIPT = "script"
COMMAND = "command"
KINDS = {
    SCRIPT: "solver driven by the Gym-preCICE paper's prerun/reset/run shell scripts",
    COMMAND: "any program given as an argument vector (options.argv), run in the solver directory",
}
#: default seconds a reset script / reset command may take
DEFAULT_RESET_TIMEOUT = 600.0
_SHARED_OPTIONS = ("prepare_timeout", "reset_timeout", "env", "log_name", "divergence_patterns")
#: the options each kind reads (see the module docstring). ``outputs`` is read by other
#: plugins' output readers (``"openfoam"``: OpenFOAM-format function-object output;
#: ``"dealii"``: a preCICE watch-point log the solver writes itself).
OPTIONS = {
    SCRIPT: ("run_script", "reset_script", "prerun_script", "interpreter", *_SHARED_OPTIONS),
    COMMAND: ("argv", "prepare_argv", "reset_argv", *_SHARED_OPTIONS),
}
_FOREIGN_OPTIONS = ("outputs",)

# Log lines that mean the shell could not start something, with what to do about it.
_LOG_HINTS = (
    ("command not found", "a program the solver script calls is not on PATH"),
    ("Permission denied", "a file the solver needs is not executable or not writable"),
    (
        "bad interpreter",
        "a script's #! line names a missing interpreter (or has Windows line endings)",
    ),
)


# -- hooks -----------------------------------------------------------------------------------
# trylast: core's generic kinds are the fallback; a third-party plugin answering for one of
# its own solvers is always consulted first.


@hookimpl(trylast=True)
def gymprecice_solver_kinds() -> dict[str, str]:
    return dict(KINDS)


@hookimpl(trylast=True)
def gymprecice_validate_case(solver: SolverContext) -> list[str] | None:
    if solver.kind not in KINDS:
        return None
    try:
        check_options(solver)
        divergence_patterns(solver)
    except ConfigError as exc:
        return [str(exc)]
    return launch_problems(solver)


def launch_problems(solver: SolverContext) -> list[str]:
    """What preparing, resetting or launching would refuse, found without running anything.

    The very checks of :func:`_script_argv` and :func:`_command_argv` (so ``gymprecice
    check`` and ``reset()`` give the same messages), run on the pristine case: a missing
    or non-executable script, a program in an argv that is not there or not executable,
    and a script that an argv hands to an interpreter but that is not there.
    """
    problems = []
    if solver.kind == SCRIPT:
        roles = _present_script_roles(solver)
        if "run_script" not in roles:
            roles.append("run_script")
        checks = [functools.partial(_script_argv, solver, role) for role in roles]
    else:
        checks = [
            functools.partial(_command_argv, solver, key, required=key == "argv")
            for key in ("prepare_argv", "reset_argv", "argv")
        ]
    for check in checks:
        try:
            check()
        except (CaseError, ConfigError) as exc:
            problems.append(str(exc))
    return problems


@hookimpl(trylast=True)
def gymprecice_prepare_case(solver: SolverContext) -> bool | None:
    if solver.kind in KINDS:
        check_options(solver)
        divergence_patterns(solver)
    if solver.kind == SCRIPT:
        # Check every script now, so a missing run script fails at the first reset rather
        # than after a long prerun.
        scripts = {role: _script_argv(solver, role) for role in _present_script_roles(solver)}
        if "run_script" not in scripts:
            raise ConfigError(
                f"{_where(solver)}: {solver.describe()} has no options.run_script; name the "
                "script that starts the coupled solver (physics_simulation_engine.run_script)"
            )
        if "prerun_script" in scripts:
            _run_step(solver, scripts["prerun_script"], "prerun", "prepare_timeout", None)
        return True
    if solver.kind == COMMAND:
        _command_argv(solver, "argv", required=True)  # validate before any work
        _command_argv(solver, "reset_argv")
        prepare = _command_argv(solver, "prepare_argv")
        if prepare:
            _run_step(solver, prepare, "prepare", "prepare_timeout", None)
        return True
    return None


@hookimpl(trylast=True)
def gymprecice_reset_case(solver: SolverContext) -> bool | None:
    if solver.kind in KINDS:
        # the last episode's fields must never be drawn as this one's
        shutil.rmtree(solver.run_dir / FIELDS_DIR, ignore_errors=True)
    if solver.kind == SCRIPT:
        if solver.options.get("reset_script"):
            argv = _script_argv(solver, "reset_script")
            _run_step(solver, argv, "reset", "reset_timeout", DEFAULT_RESET_TIMEOUT)
        return True
    if solver.kind == COMMAND:
        argv = _command_argv(solver, "reset_argv")
        if argv:
            _run_step(solver, argv, "reset", "reset_timeout", DEFAULT_RESET_TIMEOUT)
        return True
    return None


@hookimpl(trylast=True)
def gymprecice_launch_solver(solver: SolverContext) -> LaunchSpec | None:
    if solver.kind == SCRIPT:
        argv = _script_argv(solver, "run_script")
    elif solver.kind == COMMAND:
        argv = _command_argv(solver, "argv", required=True)
    else:
        return None
    env = _environment(solver)
    if solver.fields:
        env[FIELDS_ENV_VAR] = ",".join(solver.fields)
    return LaunchSpec(
        argv=argv,
        cwd=solver.run_dir,
        env=env,
        log_name=str(solver.options.get("log_name", "solver.log")),
    )


@hookimpl(trylast=True)
def gymprecice_read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    """The program's latest ``gymprecice-fields/<name>.npz``; ``None`` until it exists.

    The program was told which fields to write (``GYMPRECICE_FIELDS``); one that does
    not know a field says so in its log and exits, which fails the reset.
    """
    if solver.kind not in KINDS:
        return None
    if name not in solver.fields:
        raise ConfigError(
            f"{solver.describe()}: field {name!r} was not requested from the program at "
            f"reset (it writes {list(solver.fields)}); add it to the env's render_fields"
        )
    path = field_file(solver.run_dir, name)
    try:
        return read_field_file(path, name)
    except FileNotFoundError:
        return None


@hookimpl(trylast=True)
def gymprecice_check_solver(solver: SolverContext, log_text: str) -> str | None:
    if solver.kind not in KINDS:
        return None
    for line in log_text.splitlines():
        for needle, meaning in _LOG_HINTS:
            if needle in line:
                return (
                    f"{meaning}: {line.strip()!r} "
                    f"(log in {solver.run_dir}); fix the script or the PATH and reset"
                )
    return None


@hookimpl(trylast=True)
def gymprecice_detect_divergence(
    solver: SolverContext, log_text: str, returncode: int | None
) -> str | None:
    if solver.kind not in KINDS:
        return None
    return first_match(log_text, divergence_patterns(solver))


def divergence_patterns(solver: SolverContext) -> list[re.Pattern[str]]:
    """The solver's ``divergence_patterns``, compiled; a bad one is a :class:`ConfigError`."""
    raw = solver.options.get("divergence_patterns") or []
    key = f"physics_simulation_engine.solvers.{solver.name}.options.divergence_patterns"
    if isinstance(raw, str) or not isinstance(raw, list):
        raise ConfigError(
            f"{_where(solver)}: {key} is {raw!r}; give a list of regular expressions, e.g. "
            '["Floating point exception"]'
        )
    compiled = []
    for pattern in raw:
        try:
            compiled.append(re.compile(pattern))
        except (re.error, TypeError) as exc:
            raise ConfigError(
                f"{_where(solver)}: {key} holds {pattern!r}, not a valid regular expression "
                f"({exc}); fix or remove it"
            ) from None
    return compiled


@hookimpl(tryfirst=True)
def gymprecice_open_output(
    solver: SolverContext, name: str, options: Mapping[str, Any]
) -> OutputReader | None:
    """A participant's preCICE watch point, for a solver of any kind (core's own output).

    preCICE writes the log from ``precice-config.xml`` whatever the solver is, so reading
    it needs no solver plugin (:func:`gymprecice.watchpoints.open_watch_point`). Asked
    first, before the solvers' plugins, so a plugin that does not know the name cannot
    refuse it. Core steps aside only where the solver's plugin may know better: a solver
    of a plugin's kind whose participant only its own files name (deal.II's
    ``parameters.prm``), and a solver with ``options.outputs`` whose point preCICE does
    not write (a stand-in that writes the log itself, read by the plugin it names).
    Every other output is the plugins' to open.
    """
    if name != watchpoints.OUTPUT:
        return None
    point, participant = watchpoints.watch_point_options(solver, options)
    if solver.options.get("outputs") and (
        participant is None or watchpoints.undeclared_watch_point(solver, participant, point)
    ):
        return None
    if participant is None and solver.kind not in KINDS:
        return None
    return watchpoints.open_watch_point(solver, options)


@hookimpl(trylast=True)
def gymprecice_install_steps() -> list[InstallStep]:
    return core_install_steps()


@hookimpl(trylast=True)
def gymprecice_doctor_checks() -> list[DoctorCheck]:
    bash = shutil.which("bash")
    advice = "install bash: the paper's solver scripts (kind 'script') use it"
    return [
        DoctorCheck(
            name="bash",
            ok=bash is not None,
            detail=bash or "not on PATH",
            advice="" if bash else advice,
        )
    ]


def check_options(solver: SolverContext) -> None:
    """Refuse an option key the kind does not read: ``reset_timout`` must not be ignored."""
    refuse_unknown_options(solver, (*OPTIONS[solver.kind], *_FOREIGN_OPTIONS))


# -- kind "script" ---------------------------------------------------------------------------

_SCRIPT_ROLES = ("prerun_script", "reset_script", "run_script")


def _present_script_roles(solver: SolverContext) -> list[str]:
    return [role for role in _SCRIPT_ROLES if solver.options.get(role)]


def _script_argv(solver: SolverContext, role: str) -> list[str]:
    """Check one script in the run directory and say how to execute it."""
    name = solver.options.get(role)
    if not isinstance(name, str) or not name:
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.{role} must be a script file name, "
            f"got {name!r}"
        )
    script = solver.run_dir / name
    pristine = solver.source_dir / name
    if not script.is_file():
        raise CaseError(
            f"{solver.describe()}: the {role.replace('_', ' ')} {name!r} does not exist in "
            f"{solver.source_dir} (the env's copy: {solver.run_dir}); add it there or fix "
            f"physics_simulation_engine.{role} in {_where(solver)}"
        )
    head = _head(script)
    if head.startswith(b"#!") and head.split(b"\n", 1)[0].endswith(b"\r"):
        raise CaseError(
            f"{pristine}: the script has Windows line endings (CRLF), so its #! interpreter "
            f"cannot be found; convert it with `dos2unix {pristine}` "
            f"(or `sed -i 's/\\r$//' {pristine}`)"
        )
    interpreter = solver.options.get("interpreter")
    if interpreter:
        return [*_split(interpreter), str(script)]
    if not os.access(script, os.X_OK):
        raise CaseError(
            f"{pristine}: the {role.replace('_', ' ')} is not executable; run "
            f'`chmod +x {pristine}` (or set options.interpreter, e.g. "bash", for '
            f"{solver.describe()})"
        )
    if not head.startswith((b"#!", b"\x7fELF")):
        # What `sh -c ./script` (the paper's shell=True) does on ENOEXEC.
        return ["sh", str(script)]
    return [str(script)]


def _head(path: Path) -> bytes:
    with path.open("rb") as handle:
        return handle.read(256)


# -- kind "command" --------------------------------------------------------------------------


def _command_argv(solver: SolverContext, key: str, *, required: bool = False) -> list[str]:
    raw = solver.options.get(key)
    if raw is None or raw == [] or raw == "":
        if required:
            raise ConfigError(
                f"{_where(solver)}: {solver.describe()} needs options.{key}: the command as "
                'a list of arguments, e.g. ["{python}", "-m", "mysolver", "--case", "."]'
            )
        return []
    if isinstance(raw, str):
        raw = shlex.split(raw)
    if not isinstance(raw, Sequence) or not all(isinstance(a, (str, int, float)) for a in raw):
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.{key} must be a list of "
            f"strings, got {raw!r}"
        )
    argv = [_substitute(str(arg), solver) for arg in raw]
    _check_program(solver, argv[0], key)
    _check_interpreted_script(solver, argv, key)
    return argv


def _substitute(arg: str, solver: SolverContext) -> str:
    values = {
        "{python}": sys.executable,
        "{run_dir}": str(solver.run_dir),
        "{env_dir}": str(solver.env_dir),
        "{env_index}": str(solver.env_index),
        "{solver}": solver.name,
        "{participant}": solver.participant or "",
        "{precice_config}": str(solver.precice_config_file or ""),
    }
    for token, value in values.items():
        arg = arg.replace(token, value)
    return arg


def _check_program(solver: SolverContext, program: str, key: str) -> None:
    if os.sep in program:
        path = Path(program) if os.path.isabs(program) else solver.run_dir / program
        found = path.is_file() and os.access(path, os.X_OK)
        if path.is_file() and not found:
            pristine = path if os.path.isabs(program) else solver.source_dir / program
            raise CaseError(
                f"{pristine}: options.{key} runs this file, but it is not executable; run "
                f"`chmod +x {pristine}` (or start options.{key} with its interpreter, e.g. "
                f'["bash", "{program}"]) for {solver.describe()}'
            )
    else:
        found = shutil.which(program) is not None
    if not found:
        raise CaseError(
            f"{solver.describe()}: options.{key} starts with {program!r}, which is not an "
            f"executable {'file' if os.sep in program else 'program on PATH'}; install it, "
            f"fix PATH, or fix options.{key} in {_where(solver)}"
        )


#: programs that take a script file as their first argument
_INTERPRETERS = re.compile(r"^(python[0-9.]*|bash|sh|dash|zsh|ksh|perl|ruby|node|Rscript)$")


def _check_interpreted_script(solver: SolverContext, argv: list[str], key: str) -> None:
    """``["python", "solver.py"]`` with no ``solver.py``: say so now, not in the log."""
    program = Path(argv[0])
    if not (_INTERPRETERS.match(program.name) or argv[0] == sys.executable) or len(argv) < 2:
        return
    script = argv[1]
    if script.startswith("-") or "{" in script:
        return  # an option (python -m module, bash -c text) or an unfilled placeholder
    path = Path(script) if os.path.isabs(script) else solver.run_dir / script
    if not path.exists():
        shown = script if os.path.isabs(script) else solver.source_dir / script
        raise CaseError(
            f"{shown}: options.{key} runs {program.name} on this script, but it does not "
            f"exist; add it to {solver.source_dir} or fix options.{key} in {_where(solver)} "
            f"({solver.describe()})"
        )


# -- shared ----------------------------------------------------------------------------------


def _split(value: Any) -> list[str]:
    if isinstance(value, str):
        return shlex.split(value)
    return [str(v) for v in value]


def _where(solver: SolverContext) -> str:
    return str(solver.config_file) if solver.config_file else "the gymprecice configuration"


def _environment(solver: SolverContext, *, seed: int | None = None) -> dict[str, str]:
    env = {
        "GYMPRECICE_ENV_INDEX": str(solver.env_index),
        "GYMPRECICE_ENV_DIR": str(solver.env_dir),
        "GYMPRECICE_RUN_DIR": str(solver.run_dir),
        "GYMPRECICE_SOLVER": solver.name,
        "GYMPRECICE_PARTICIPANT": solver.participant or "",
        "GYMPRECICE_PRECICE_CONFIG": str(solver.precice_config_file or ""),
    }
    if seed is not None:
        env["GYMPRECICE_SEED"] = str(seed)
    extra = solver.options.get("env") or {}
    if not isinstance(extra, Mapping):
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.env must be an object of "
            f"environment variables, got {extra!r}"
        )
    env.update({str(k): str(v) for k, v in extra.items()})
    return env


def _timeout(solver: SolverContext, key: str, default: float | None) -> float | None:
    value = solver.options.get(key, default)
    if value is None:
        return None
    try:
        seconds = float(value)
    except (TypeError, ValueError):
        seconds = -1.0
    if seconds <= 0:
        raise ConfigError(
            f"{_where(solver)}: {solver.describe()}: options.{key} must be a positive number "
            f"of seconds or null, got {value!r}"
        )
    return seconds


def _run_step(
    solver: SolverContext,
    argv: list[str],
    step: str,
    timeout_key: str,
    default_timeout: float | None,
) -> None:
    """Run a prepare/reset step to completion in the run directory, log beside the case.

    The step's process group is recorded in the env's pid registry while it runs, so an
    outer supervisor can still kill a long prerun whose env process died.
    """
    # only when used
    from gymprecice.env.pidregistry import PidRegistry
    from gymprecice.env.short_commands import run_to_completion

    seed = None
    if step == "reset" and solver.rng is not None:
        seed = int(solver.rng.integers(2**31 - 1))
    spec = LaunchSpec(
        argv=argv,
        cwd=solver.run_dir,
        env=_environment(solver, seed=seed),
        log_name=f"{step}.log",
    )
    run_to_completion(
        solver.name,
        spec,
        timeout=_timeout(solver, timeout_key, default_timeout),
        env_index=solver.env_index,
        what=step,
        registry=PidRegistry(solver.env_dir),
    )
