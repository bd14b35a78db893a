"""Every hook a gymprecice plugin can implement: the plugin author's contract.

A plugin is any module (usually found through the ``gymprecice`` entry-point group) with
functions marked ``@hookimpl`` whose names match the specs below::

    # my_solver_plugin.py
    from gymprecice.plugin import LaunchSpec, for_kind, hookimpl

    @hookimpl
    def gymprecice_solver_kinds():
        return {"mysolver": "My preCICE-enabled solver"}

    @hookimpl
    @for_kind("mysolver")    # not mine: None, let another plugin answer
    def gymprecice_reset_case(solver):
        return True

    @hookimpl
    @for_kind("mysolver")
    def gymprecice_launch_solver(solver):
        return LaunchSpec(argv=["mysolver", "case.cfg"], cwd=solver.run_dir)

and, in its ``pyproject.toml``::

    [project.entry-points.gymprecice]
    mysolver = "my_solver_plugin"

A plugin needs ``gymprecice_solver_kinds``, ``gymprecice_reset_case`` and
``gymprecice_launch_solver``; every other hook is optional and has a default, stated in
its spec. Everything else a plugin needs comes from :mod:`gymprecice.plugin` (this
module re-exports a part of it too, for plugins written before it): the value types
(``LaunchSpec``, ``InterfaceGeometry``, ``SolverContext``, ``DoctorCheck``,
``InstallStep``, the reader protocols), the errors to raise (``CaseError``,
``ConfigError``), the option checks (``refuse_unknown_options``,
``unknown_option_problems``), the watch-point reader (``WatchPointLog``,
``open_watch_point``, ``watch_point_file_name``; :mod:`gymprecice.watchpoints`) and the
split of a reader's rows at a step's end (``rows_through``; :mod:`gymprecice.readers`). Core never names a solver; plugins never touch preCICE: core owns the coupling
and every process, plugins only prepare files and describe what to run.

**What ``None`` means.** Every hook asked about one solver stands under
``@for_kind(KIND)`` (:func:`gymprecice.plugin.for_kind`), which returns ``None`` for
another kind's solver, and for every one of them ``None`` means exactly one thing: *this
plugin gives no answer for this solver*. Core then asks the next plugin, and when none
answers applies the hook's default (its spec says which). Whether the plugin stayed silent
because the kind is not its own or because it has nothing to add makes no difference to
core, so the two need no separate value. A *failure* is never ``None``: raise
:class:`~gymprecice.errors.CaseError` (a case file is wrong) or
:class:`~gymprecice.errors.ConfigError` (an option is wrong), naming the file and the fix.
The conformance suite (:mod:`gymprecice.testing.conformance`) checks each hook's
``None`` for a foreign kind.

**Where errors surface.** An exception raised in a hook reaches the user unchanged, from
the call that ran the hook: ``gymprecice_validate_case`` from ``Adapter(...)`` and
``gymprecice check``; ``gymprecice_prepare_case`` from the first ``reset()`` (or
``env.run_dir``); ``gymprecice_reset_case``, ``gymprecice_launch_solver`` and
``gymprecice_check_solver`` from ``reset()``; ``gymprecice_detect_divergence`` from
``reset()`` and ``step()``; ``gymprecice_interface_geometry`` from the first
``reset()`` (or ``env.interface_geometry``); ``gymprecice_open_output`` from
``env.open_output`` in the env's own code; ``gymprecice_read_field`` from
``env.render()``; ``gymprecice_sketch_case`` from ``gymprecice sketch``. A problem *returned* by ``gymprecice_validate_case`` becomes a
``ConfigError`` naming the configuration file and the solver; one returned by ``gymprecice_check_solver`` fails the reset (or joins the
crash report of an exited solver) as a :class:`~gymprecice.errors.SolverCrashedError`
that names the solver and the env, so the message itself need not.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import pluggy

from gymprecice.plugin.errors import CaseError, ConfigError
from gymprecice.plugin.fields import Field
from gymprecice.plugin.options import refuse_unknown_options, unknown_option_problems
from gymprecice.plugin.readers import rows_through
from gymprecice.plugin.sketch import SketchPatch, SketchPoints, SolverSketch
from gymprecice.plugin.solver import (
    LIBRARY_ENV_VAR,
    TEST_DOUBLE_LIBRARY,
    DoctorCheck,
    InterfaceGeometry,
    LaunchSpec,
    OutputReader,
    SolverContext,
    WaitableOutputReader,
)
from gymprecice.plugin.watchpoints import WatchPointLog, open_watch_point, watch_point_file_name
from gymprecice.tools.stack import InstallStep

PROJECT_NAME = "gymprecice"

hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)

__all__ = [
    "LIBRARY_ENV_VAR",
    "TEST_DOUBLE_LIBRARY",
    "CaseError",
    "ConfigError",
    "DoctorCheck",
    "Field",
    "InstallStep",
    "InterfaceGeometry",
    "LaunchSpec",
    "OutputReader",
    "SketchPatch",
    "SketchPoints",
    "SolverContext",
    "SolverSketch",
    "WaitableOutputReader",
    "WatchPointLog",
    "hookimpl",
    "hookspec",
    "open_watch_point",
    "refuse_unknown_options",
    "rows_through",
    "unknown_option_problems",
    "watch_point_file_name",
]


@hookspec
def gymprecice_solver_kinds() -> Mapping[str, str]:
    """Name the solver kinds this plugin handles, with a one-line description each.

    Used to validate ``kind`` in ``gymprecice-config.json`` (an unknown kind is reported
    with the list of installed ones) and by ``gymprecice plugins``. Required: a kind no
    plugin declares cannot be configured. ``None`` (or an empty dict) declares nothing.
    """


@hookspec
def gymprecice_validate_case(solver: SolverContext) -> list[str] | None:
    """Check the pristine case of a solver against the preCICE configuration; write nothing.

    Called when a configuration is loaded (``Adapter(...)``, ``gymprecice check``), before
    any run directory exists: ``solver.run_dir`` and ``solver.source_dir`` are both the
    pristine case, ``solver.env_dir`` is the case directory, ``solver.precice`` and
    ``solver.precice_config_file`` the case's own preCICE configuration, and there is no
    ``rng`` and no ``state``. Catches, for example, a solver mesh or data name that the
    preCICE XML does not define, or an unknown option (see
    :func:`~gymprecice.options.unknown_option_problems`), which would otherwise surface
    only at run time.

    Return, for this plugin's kind, a list of problems, each naming the file at fault and
    the fix (``[]`` when all is well). ``None`` means "not my kind": an empty list would
    claim the case was checked. Every plugin is asked (not ``firstresult``); all problems
    are reported together. Default (no plugin answers): no check.
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
    ``options`` given to ``env.reset``. Return ``True`` when reset (also when the solver
    needs nothing reset). ``None`` means "not my kind". Required: when no plugin returns
    ``True``, the reset fails with a :class:`~gymprecice.errors.CaseError` naming this hook.
    """


@hookspec(firstresult=True)
def gymprecice_launch_solver(solver: SolverContext) -> LaunchSpec | None:
    """Describe how to start the coupled solver for one episode.

    Core starts the returned command in its own process group with its output in a log
    file, watches it, and kills the whole group when the episode ends or fails. Core adds
    ``GYMPRECICE_PRECICE_LIBRARY`` (``solver.precice_library``) to its environment unless
    ``LaunchSpec.env`` sets it: a Python solver imports that module as ``precice``, so it
    couples through the same library as the env. Return a
    :class:`~gymprecice.solver.LaunchSpec`; ``None`` means "not my kind". Required: when
    no plugin answers, the reset fails with a :class:`~gymprecice.errors.CaseError`.
    """


@hookspec(firstresult=True)
def gymprecice_check_solver(solver: SolverContext, log_text: str) -> str | None:
    """Look at a waiting or exited solver and say what is wrong, or ``None`` if nothing.

    Called about once a second while core waits for the solver at reset, and once when a
    solver has exited during a reset or a step; ``log_text`` is the tail of the solver's
    log. Use it for problems that would otherwise hang the coupling (a solver that runs
    uncoupled because its preCICE adapter did not load) and to explain an exit status
    (``127``: a program not on ``PATH``). Return one message naming the file and the fix;
    core prefixes the solver and the env, so do not start with ``solver.describe()``. A
    message while the solver waits fails the reset; one about an exited solver is added to
    its crash report as ``diagnosis:``. ``None`` means "nothing to report" (a healthy log,
    or not my kind); an ordinary log must get ``None``.
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
    ``interface`` mesh is mapped to (taken from the preCICE configuration). Called after
    preparation, on the env's copy of the case. Return an
    :class:`~gymprecice.solver.InterfaceGeometry` (3-D coordinates of a 2-D case are cut to
    x, y by core). ``None`` means "I do not know this mesh" (or not my kind); when no
    plugin knows it, the env must call ``set_interface_vertices`` and the error says so.
    """


@hookspec(firstresult=True)
def gymprecice_open_output(
    solver: SolverContext, name: str, options: Mapping[str, Any]
) -> OutputReader | None:
    """Open an incremental reader of one solver output (e.g. ``"probes"``, ``"forces"``).

    Environments call ``self.open_output(solver_name, name, **options)``; core closes the
    readers at every reset and at close. Return an
    :class:`~gymprecice.solver.OutputReader`, preferably a
    :class:`~gymprecice.solver.WaitableOutputReader` (``start_time``, ``latest_time``,
    ``wait_until`` handing out the rows of one step), which env code relies on. For this
    plugin's kind, raise :class:`~gymprecice.errors.ConfigError` listing the outputs and
    options it knows when ``name`` or ``options`` is unknown. ``None`` means "not my
    solver"; when no plugin answers, ``open_output`` raises a ``ConfigError``.

    ``"watchpoint"`` is core's: preCICE writes a participant's watch point from
    ``precice-config.xml`` whatever the solver, so core answers it for every solver,
    before any plugin is asked (:func:`~gymprecice.watchpoints.open_watch_point`). A
    plugin is asked for it only where core steps aside: its solver's participant is
    named nowhere in gymprecice's configuration, or the solver has ``options.outputs``
    and writes the log itself.
    """


@hookspec(firstresult=True)
def gymprecice_read_field(solver: SolverContext, name: str, time: float) -> Field | None:
    """Hand core field ``name`` of the solver, as written at coupling time ``time``.

    Called by ``env.render()`` (``render_mode="rgb_array"``) for every field the env draws
    (``Adapter.render_fields``); core draws it (:mod:`gymprecice.rendering`). ``time`` is
    the coupling time in seconds since the episode's start (add the solver's own start
    time where it has one). Return a :class:`~gymprecice.fields.Field`: the newest
    snapshot written at or before ``time``, with its own ``time``. While the solver has
    not written ``time`` yet (it may be a moment behind the coupling), return the older
    snapshot, or ``None`` when there is none: core asks again, watching the solvers,
    until the snapshot's time reaches ``time`` or the progress timeout passes. Raise
    :class:`~gymprecice.errors.ConfigError` naming the fields the solver writes when
    ``name`` is not one of them. Only read files; never write.

    What to write, and when, is the plugin's to decide at ``gymprecice_reset_case`` (or
    ``gymprecice_launch_solver``): ``solver.fields`` names the fields the env will ask for
    (``()``: the env does not render, so the solver writes nothing extra) and
    ``solver.field_interval`` the coupling time between two frames (one action). ``None``
    means "not my kind"; when no plugin answers, ``render()`` raises a
    :class:`~gymprecice.errors.ConfigError` naming the solver's plugin and this hook.
    """


@hookspec(firstresult=True)
def gymprecice_sketch_case(solver: SolverContext) -> SolverSketch | None:
    """Describe the solver's case for ``gymprecice sketch``: its domain, patches and sensors.

    Called with the context core builds for validation (``solver.run_dir`` and
    ``solver.source_dir`` are both the pristine case: never write there), by
    ``gymprecice sketch`` only. Return a :class:`~gymprecice.sketch.SolverSketch` read from
    the case files: the boundary patches as segments in the x-y plane with their kind
    and the preCICE meshes on each, the loops bounding the domain, the solver's own
    sensors (probes) and each preCICE mesh's vertices. A mesh the case only describes
    (a ``blockMeshDict``) may be built in a temporary directory of the plugin's own,
    removed before the hook returns: nothing may be left running or written. Raise
    :class:`~gymprecice.errors.CaseError` naming the file and the fix when the case cannot
    be read (no mesh and no tool to build it). ``None`` means "not my kind"; a solver no
    plugin sketches is named in the sketch as not drawn.
    """


@hookspec
def gymprecice_doctor_checks() -> list[DoctorCheck]:
    """Report what this plugin needs and whether the machine has it (``gymprecice doctor``).

    Return a list of :class:`~gymprecice.solver.DoctorCheck`; a failed one needs
    ``advice``. ``None`` or ``[]``: nothing to check.
    """


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
    """Register Gymnasium environments: ``register(id, entry_point, *, card=None, **kwargs)``.

    Ids are registered with :func:`gymnasium.register` when ``gymprecice`` is imported,
    so ``gymnasium.make("gymprecice/JetCylinder-v0")`` works for every installed plugin.
    ``card`` is the env's lab card (:class:`gymprecice.card.EnvCard`: its objective,
    held-out starts, uncontrolled setting, feedback law, reference, shipped policies...),
    what ``gymprecice train``, ``evaluate``, ``benchmark`` and the other lab commands read
    beyond the Gymnasium API; a malformed card is refused at load, naming the field.
    """
