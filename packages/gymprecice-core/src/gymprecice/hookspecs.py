"""Every hook a gymprecice plugin can implement: the plugin author's contract.

A plugin is any module (usually found through the ``gymprecice`` entry-point group) with
functions marked ``@hookimpl`` whose names match the specs below::

    # my_solver_plugin.py
    from gymprecice.hookspecs import hookimpl, LaunchSpec

    @hookimpl
    def gymprecice_solver_kinds():
        return {"mysolver": "My preCICE-enabled solver"}

    @hookimpl
    def gymprecice_launch_solver(solver):
        if solver.kind != "mysolver":
            return None          # not mine: let another plugin answer
        return LaunchSpec(argv=["mysolver", "case.cfg"], cwd=solver.run_dir)

and, in its ``pyproject.toml``::

    [project.entry-points.gymprecice]
    mysolver = "my_solver_plugin"

Hooks that act on one solver are ``firstresult``: each plugin checks ``solver.kind`` and
returns ``None`` for solvers it does not handle, so the first plugin that knows the kind
answers. Core never names a solver; plugins never touch preCICE: core owns the coupling
and every process, plugins only prepare files and describe what to run.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import pluggy

from gymprecice.solver import (
    DoctorCheck,
    InterfaceGeometry,
    LaunchSpec,
    OutputReader,
    SolverContext,
)
from gymprecice.stack import InstallStep

PROJECT_NAME = "gymprecice"

hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)

__all__ = [
    "DoctorCheck",
    "InstallStep",
    "InterfaceGeometry",
    "LaunchSpec",
    "OutputReader",
    "SolverContext",
    "hookimpl",
    "hookspec",
]


@hookspec
def gymprecice_solver_kinds() -> Mapping[str, str]:
    """Name the solver kinds this plugin handles, with a one-line description each.

    Used to validate ``kind`` in ``gymprecice-config.json`` (an unknown kind is reported
    with the list of installed ones) and by ``gymprecice plugins``.
    """


@hookspec
def gymprecice_validate_case(solver: SolverContext) -> list[str] | None:
    """Check the pristine case of a solver against the preCICE configuration; write nothing.

    Called when a configuration is loaded (``Adapter(...)``, ``gymprecice check``), before
    any run directory exists: ``solver.run_dir`` is the pristine case here. Return a list of
    problems, each naming the file at fault and the fix (an empty list when all is well), or
    ``None`` for solvers of other kinds. Catches, for example, a solver mesh or data name
    that the preCICE XML does not define, which would otherwise surface only at run time.
    """


@hookspec(firstresult=True)
def gymprecice_prepare_case(solver: SolverContext) -> bool | None:
    """Prepare the solver's case in ``solver.run_dir`` once per environment.

    Core has already copied the pristine case into the env's run directory. Typical work:
    generate the mesh, decompose, run an uncoupled pre-run to a developed state, and
    remember in ``solver.state`` what :func:`gymprecice_reset_case` must restore.
    Return ``True`` when prepared. ``None`` means "no preparation from this plugin" (not
    its kind, or nothing to do): when no plugin prepares a solver, core's copy of the case
    is its preparation, so a plugin whose solver needs only its case files may leave this
    hook out. Raise :class:`gymprecice.errors.CaseError` with the file and the fix on bad
    input; any other answer (``False``) is refused as a plugin bug.
    """


@hookspec(firstresult=True)
def gymprecice_reset_case(solver: SolverContext) -> bool | None:
    """Bring ``solver.run_dir`` back to the episode's initial state (every episode).

    Only files under ``run_dir`` may change. ``solver.rng`` is the episode's seeded
    generator (use it for randomised initial states) and ``solver.reset_options`` holds the
    ``options`` given to ``env.reset``. Return ``True`` when handled.
    """


@hookspec(firstresult=True)
def gymprecice_launch_solver(solver: SolverContext) -> LaunchSpec | None:
    """Describe how to start the coupled solver for one episode.

    Core starts the returned command in its own process group with its output in a log
    file, watches it, and kills the whole group when the episode ends or fails.
    """


@hookspec(firstresult=True)
def gymprecice_check_solver(solver: SolverContext, log_text: str) -> str | None:
    """Look at a running or failed solver and say what is wrong, or ``None`` if nothing.

    Called while core waits for the solver at reset and when it has failed; ``log_text`` is
    the tail of the solver's log. Use it for problems that would otherwise hang the
    coupling, such as a solver that runs uncoupled because its preCICE adapter did not
    load. The message should name the file and the fix.
    """


@hookspec(firstresult=True)
def gymprecice_detect_divergence(
    solver: SolverContext, log_text: str, returncode: int | None
) -> str | None:
    """Say whether the solver diverged (the agent's doing) and what shows it, else ``None``.

    Called in two situations; only read files, never change them:

    * ``returncode is None``: the solver is running. Core calls this while it waits for
      the solver and after every step, whenever the solver's log grew, with the log's
      tail. Watch a quantity here to end the episode *before* the solver crashes (a
      Courant number past a configured limit, a displacement out of all proportion).
    * ``returncode`` is an int: the step failed and this solver has ended with that
      status (negative: killed by that signal). Classify its exit from its log: a
      floating-point exception or an iteration limit is divergence; anything else is
      not yours to excuse.

    Return the evidence, the log line or measured quantity that shows the divergence
    (it goes to ``info["diverged"]["evidence"]``), or ``None``: not diverged, or not this
    plugin's kind. Core ends the episode with ``terminated=True`` and the env's
    ``divergence_penalty``; the vector pool does not count it as a failure. Exits by
    SIGKILL, SIGSEGV or SIGBUS and hangs stay faults and are never asked about.
    """


@hookspec(firstresult=True)
def gymprecice_interface_geometry(
    solver: SolverContext, interface: str, mesh: str
) -> InterfaceGeometry | None:
    """Give the vertices of a controller interface that couples to this solver.

    ``mesh`` is the solver participant's own preCICE mesh that the controller's
    ``interface`` mesh is mapped to (taken from the preCICE configuration). Return ``None``
    when this plugin does not know the mesh. A user can still set coordinates by hand.
    """


@hookspec(firstresult=True)
def gymprecice_open_output(
    solver: SolverContext, name: str, options: Mapping[str, Any]
) -> OutputReader | None:
    """Open an incremental reader of one solver output (e.g. ``"probes"``, ``"forces"``).

    Environments call ``self.open_output(solver_name, name, **options)``; core closes the
    readers at every reset and at close.
    """


@hookspec
def gymprecice_doctor_checks() -> list[DoctorCheck]:
    """Report what this plugin needs and whether the machine has it (``gymprecice doctor``)."""


@hookspec
def gymprecice_install_steps() -> list[InstallStep]:
    """Pieces this plugin can build for ``gymprecice install`` (e.g. a solver's preCICE adapter).

    Return :class:`gymprecice.stack.InstallStep` objects: how to tell the piece is there and
    how to build it into the stack prefix. Core provides ``precice`` and ``pyprecice``; a step
    that links preCICE lists ``requires=("precice",)`` and gets it built first. Return an
    empty list (or nothing) when the plugin needs nothing built.
    """


@hookspec
def gymprecice_register_commands(subparsers: Any) -> None:
    """Add sub-commands to the ``gymprecice`` command line.

    ``subparsers`` is an :mod:`argparse` sub-parsers action: call ``add_parser`` and set
    ``func`` with ``set_defaults(func=callable)``; the callable receives the parsed
    arguments and returns an exit status.
    """


@hookspec
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    """Register Gymnasium environments: ``register(id, entry_point, **kwargs)``.

    Ids are registered with :func:`gymnasium.register` when ``gymprecice`` is imported,
    so ``gymnasium.make("gymprecice/JetCylinder-v0")`` works for every installed plugin.
    """
