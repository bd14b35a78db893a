"""The new package's ``plugin.py``: the ``gymprecice`` plugin that registers its env
with its lab card; with ``--solver-plugin``, the one that also handles a solver kind of the
package's own (named after it) that runs its program.
"""

from __future__ import annotations

__all__ = ["PLUGIN", "SOLVER_PLUGIN"]

PLUGIN = '''\
"""The package's gymprecice plugin: registers {{env_id}} and its lab card.

gymprecice loads this module through the ``gymprecice`` entry point (pyproject.toml) on
every ``import gymprecice``, so it stays light: the env class is named by a
``"module:Class"`` string, which Gymnasium imports only in ``make``.
"""

from __future__ import annotations

from collections.abc import Callable

from gymprecice.card import EnvCard
from gymprecice.hookspecs import hookimpl

ENV_ID = "{{env_id}}"

CARD = EnvCard(
    name="{{dist}}",
    description="{{description}}",
    # the info["metrics"] entry every controller is ranked on (lower is better)
    objective="tracking_error",
    metrics=("tracking_error", "sensed", "actuation"),
    # the env keyword that makes it ignore its action: what `gymprecice baseline` runs
    uncontrolled={"uncontrolled": True},
    # the env takes double=True: `--double` runs it on the preCICE test double
    double=True,
)


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    register(ENV_ID, "{{module}}.env:{{class_name}}", card=CARD)
'''

SOLVER_PLUGIN = '''\
"""The package's gymprecice plugin: registers {{env_id}} and its lab card, and handles
the solver kind "{{dist}}" (the package's own program, ``solver.py``).

gymprecice loads this module through the ``gymprecice`` entry point (pyproject.toml) on
every ``import gymprecice``, so it stays light: the env class is named by a
``"module:Class"`` string, which Gymnasium imports only in ``make``. The solver hooks
describe; core acts: it copies the case into each env's run directory, starts the
program that ``gymprecice_launch_solver`` names, watches it and owns the coupling. The
package's tests run gymprecice's conformance suite on them (tests/test_conformance.py).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from gymprecice.card import EnvCard
from gymprecice.hookspecs import (
    CaseError,
    LaunchSpec,
    hookimpl,
    refuse_unknown_options,
    unknown_option_problems,
)

ENV_ID = "{{env_id}}"
#: the solver kind this plugin handles, and the options it reads
KIND = "{{dist}}"
OPTIONS = ("program", "log_name")
#: the participant the program plays where the configuration names none
PARTICIPANT = "{{participant}}"

CARD = EnvCard(
    name="{{dist}}",
    description="{{description}}",
    # the info["metrics"] entry every controller is ranked on (lower is better)
    objective="tracking_error",
    metrics=("tracking_error", "sensed", "actuation"),
    # the env keyword that makes it ignore its action: what `gymprecice baseline` runs
    uncontrolled={"uncontrolled": True},
    # the env takes double=True: `--double` runs it on the preCICE test double
    double=True,
)


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    register(ENV_ID, "{{module}}.env:{{class_name}}", card=CARD)


# -- the solver kind -------------------------------------------------------------


def _program(solver) -> Path:
    """The solver's program in ``run_dir`` (the pristine case, or an env's copy)."""
    path = solver.run_dir / solver.options.get("program", "solver.py")
    if not path.is_file():
        raise CaseError(f"{path}: missing; name the program in options.program")
    return path


@hookimpl
def gymprecice_solver_kinds() -> dict[str, str]:
    return {KIND: "the solver program of the {{dist}} package"}


@hookimpl
def gymprecice_validate_case(solver) -> list[str] | None:
    """At load time, on the pristine case: every problem, nothing written."""
    if solver.kind != KIND:
        return None  # not mine (an empty list would claim the case was checked)
    problems = unknown_option_problems(solver, OPTIONS)
    try:
        _program(solver)
    except CaseError as exc:
        problems.append(str(exc))
    participant = solver.participant or PARTICIPANT
    if solver.precice is not None and participant not in solver.precice.participants:
        problems.append(
            f"{solver.precice_config_file}: no participant {participant!r} (its "
            f"participants are {sorted(solver.precice.participants)}); name the "
            "solver's participant in gymprecice-config.json"
        )
    return problems


@hookimpl
def gymprecice_reset_case(solver) -> bool | None:
    """Every episode: the program starts from scratch; only its old logs go."""
    if solver.kind != KIND:
        return None
    for log in solver.run_dir.glob("precice-*.log"):
        log.unlink()
    return True


@hookimpl
def gymprecice_launch_solver(solver) -> LaunchSpec | None:
    if solver.kind != KIND:
        return None
    refuse_unknown_options(solver, OPTIONS)
    argv = [sys.executable, _program(solver).name]
    argv += ["--participant", solver.participant or PARTICIPANT]
    if solver.precice_config_file is not None:
        argv += ["--config", str(solver.precice_config_file)]
    log_name = solver.options.get("log_name", "solver.log")
    return LaunchSpec(argv=argv, cwd=solver.run_dir, log_name=log_name)
'''
