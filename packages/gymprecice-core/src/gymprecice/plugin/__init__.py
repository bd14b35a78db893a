"""Everything a gymprecice solver plugin needs, in one import: the plugin author's guide.

A plugin teaches gymprecice one kind of solver (OpenFOAM, deal.II, FEniCS, ...). It is a
module whose functions are marked ``@hookimpl`` and named after the hook specs in
:mod:`gymprecice.plugin.hookspecs`, declared in its distribution's ``pyproject.toml``::

    [project.entry-points.gymprecice]
    mysolver = "my_solver_plugin"

and it imports from here, and from nowhere else in gymprecice::

    # my_solver_plugin.py
    from gymprecice.plugin import LaunchSpec, for_kind, hookimpl

    KIND = "mysolver"

    @hookimpl
    def gymprecice_solver_kinds():
        return {KIND: "My preCICE-enabled solver"}

    @hookimpl
    @for_kind(KIND)  # another kind's solver: None, the next plugin answers
    def gymprecice_reset_case(solver):
        return True

    @hookimpl
    @for_kind(KIND)
    def gymprecice_launch_solver(solver):
        return LaunchSpec(argv=["mysolver", "case.cfg"], cwd=solver.run_dir)

What is here, by the job it does (each name lives in the module named; this package
only gathers them, and ``tests/test_architecture.py`` keeps the in-repository plugins to
this one surface):

* **the hooks**: :data:`hookimpl`, :data:`hookspec` and every hook's contract, with what
  ``None`` means and where a raised error surfaces (:mod:`gymprecice.plugin.hookspecs`);
  :func:`for_kind`, the guard that keeps a hook to its own solver kind;
* **what a hook is given and returns** (:mod:`gymprecice.plugin.solver`):
  :class:`SolverContext`, :class:`LaunchSpec`, :class:`InterfaceGeometry`,
  :class:`DoctorCheck`, the reader protocols (:class:`OutputReader`,
  :class:`WaitableOutputReader`), :data:`LIBRARY_ENV_VAR`;
* **what a hook raises** (:mod:`gymprecice.plugin.errors`): :class:`CaseError` (a case
  file is wrong), :class:`ConfigError` (an option is wrong), :class:`GymPreciceError`;
  the option checks :func:`refuse_unknown_options` and :func:`unknown_option_problems`
  (:mod:`gymprecice.plugin.options`);
* **outputs**: fields to draw (:class:`Field` and the files that hand them over,
  :mod:`gymprecice.plugin.fields`), readers' rows at a step's end (:func:`rows_through`,
  :func:`time_tolerance`; :mod:`gymprecice.plugin.readers`), preCICE watch points
  (:class:`WatchPointLog`, :func:`open_watch_point`, ...; :mod:`gymprecice.plugin.watchpoints`);
* **divergence**: :func:`first_match` and :func:`checked_positive`
  (:mod:`gymprecice.plugin.divergence`);
* **episode starts** from saved states: :func:`choose_start`, a reset's pick of the
  train, eval or validation split's start, the same in every plugin
  (:mod:`gymprecice.plugin.starts`);
* **the case's preCICE configuration** as core read it: :class:`PreciceConfig`,
  :class:`ParticipantSpec` (:mod:`gymprecice.plugin.precice_xml`);
* **sketches** for ``gymprecice sketch``: :class:`SolverSketch`, :class:`SketchPatch`,
  :class:`SketchPoints` (:mod:`gymprecice.plugin.sketch`);
* **installing the solver's adapter** with ``gymprecice install``: :class:`InstallStep`,
  :class:`BuildContext`, :class:`SourceArchive`, :class:`Prerequisite` and the common
  prerequisites (``CXX``, ``CMAKE``, ...), the stack's helpers (from
  :mod:`gymprecice.tools.stack` and :mod:`gymprecice.tools.prerequisites`, where
  ``gymprecice install`` keeps them).

A plugin's tests may use :mod:`gymprecice.testing` too: :func:`~gymprecice.testing.
make_solver_context` and the conformance suite every plugin runs
(:mod:`gymprecice.testing.conformance`).

Core itself loads the plugins (:mod:`gymprecice.plugin.manager`) and registers their
environments (:mod:`gymprecice.plugin.registration`, with each env's lab card,
:mod:`gymprecice.plugin.card`); a solver plugin needs neither.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

from gymprecice.plugin.divergence import checked_positive, first_match
from gymprecice.plugin.errors import CaseError, ConfigError, GymPreciceError
from gymprecice.plugin.fields import (
    FIELDS_DIR,
    FIELDS_ENV_VAR,
    Field,
    field_file,
    read_field_file,
)
from gymprecice.plugin.hookspecs import PROJECT_NAME, hookimpl, hookspec
from gymprecice.plugin.options import refuse_unknown_options, unknown_option_problems
from gymprecice.plugin.precice_xml import ParticipantSpec, PreciceConfig
from gymprecice.plugin.readers import rows_through, time_tolerance
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
from gymprecice.plugin.starts import choose_start
from gymprecice.plugin.watchpoints import (
    WatchPointLog,
    open_watch_point,
    watch_point_file_name,
    watch_point_options,
)
from gymprecice.tools.prerequisites import (
    CMAKE,
    CXX,
    MAKE,
    PKG_CONFIG,
    Prerequisite,
    header,
)
from gymprecice.tools.stack import (
    BuildContext,
    BuildError,
    InstallStep,
    SourceArchive,
    command_output,
    solver_environment,
    stack_prefix,
    stack_which,
)

__all__ = [
    "CMAKE",
    "CXX",
    "FIELDS_DIR",
    "FIELDS_ENV_VAR",
    "LIBRARY_ENV_VAR",
    "MAKE",
    "PKG_CONFIG",
    "PROJECT_NAME",
    "TEST_DOUBLE_LIBRARY",
    "BuildContext",
    "BuildError",
    "CaseError",
    "ConfigError",
    "DoctorCheck",
    "Field",
    "GymPreciceError",
    "InstallStep",
    "InterfaceGeometry",
    "LaunchSpec",
    "OutputReader",
    "ParticipantSpec",
    "PreciceConfig",
    "Prerequisite",
    "SketchPatch",
    "SketchPoints",
    "SolverContext",
    "SolverSketch",
    "SourceArchive",
    "WaitableOutputReader",
    "WatchPointLog",
    "checked_positive",
    "choose_start",
    "command_output",
    "field_file",
    "first_match",
    "for_kind",
    "header",
    "hookimpl",
    "hookspec",
    "open_watch_point",
    "read_field_file",
    "refuse_unknown_options",
    "rows_through",
    "solver_environment",
    "stack_prefix",
    "stack_which",
    "time_tolerance",
    "unknown_option_problems",
    "watch_point_file_name",
    "watch_point_options",
]

Hook = TypeVar("Hook", bound=Callable[..., Any])


def for_kind(kind: str) -> Callable[[Hook], Hook]:
    """Keep a hook to the solvers of one ``kind``: for any other it returns ``None``.

    The hook's first argument is the :class:`SolverContext`; ``None`` tells core that
    this plugin gives no answer for that solver, so it asks the next plugin (see
    :mod:`gymprecice.plugin.hookspecs`). Put it under ``@hookimpl``::

        @hookimpl
        @for_kind("mysolver")
        def gymprecice_reset_case(solver): ...

    The hook keeps its name and signature, which pluggy reads.
    """

    def decorate(hook: Hook) -> Hook:
        @functools.wraps(hook)
        def answer(solver: SolverContext, *args: Any, **kwargs: Any) -> Any:
            if solver.kind != kind:
                return None
            return hook(solver, *args, **kwargs)

        return answer  # type: ignore[return-value]

    return decorate
