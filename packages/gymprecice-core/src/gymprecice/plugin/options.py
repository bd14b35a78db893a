"""Refusing the solver options a plugin does not know: the plugin's job, this is the helper.

Core passes ``physics_simulation_engine.solvers.<name>.options`` to the plugin untouched
(``SolverContext.options``): only the plugin knows which keys its kind reads. A misspelt
key that nobody refuses is silently ignored (``prerun_end_tme`` would skip a pre-run), so
every plugin should refuse unknown keys in ``gymprecice_validate_case`` (``gymprecice
check`` and env construction report it) and again in ``gymprecice_prepare_case`` (an
env built with validation off)::

    from gymprecice.plugin.hookspecs import (
        hookimpl,
        refuse_unknown_options,
        unknown_option_problems,
    )

    OPTIONS = ("steps", "log_name")

    @hookimpl
    def gymprecice_validate_case(solver):
        if solver.kind != "mysolver":
            return None
        return unknown_option_problems(solver, OPTIONS)

    @hookimpl
    def gymprecice_prepare_case(solver):
        if solver.kind != "mysolver":
            return None
        refuse_unknown_options(solver, OPTIONS)
        return True
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.solver import SolverContext

__all__ = ["refuse_unknown_options", "unknown_option_problems"]


def unknown_option_problems(solver: SolverContext, known: Iterable[str]) -> list[str]:
    """One problem naming the configuration file, the unknown keys and the known ones.

    An empty list when every key of ``solver.options`` is in ``known``; a close match is
    offered for each unknown key (``'stpes' (did you mean 'steps'?)``).
    """
    known = list(known)
    unknown = sorted(set(solver.options) - set(known))
    if not unknown:
        return []
    hints = []
    for key in unknown:
        close = difflib.get_close_matches(key, known, n=1)
        hints.append(f"{key!r} (did you mean {close[0]!r}?)" if close else repr(key))
    where = str(solver.config_file) if solver.config_file else "the gymprecice configuration"
    return [
        f"{where}: {solver.describe()}: unknown option(s) {', '.join(hints)} in "
        f"physics_simulation_engine.solvers.{solver.name}.options; kind {solver.kind!r} "
        f"knows {known}"
    ]


def refuse_unknown_options(solver: SolverContext, known: Iterable[str]) -> None:
    """Raise :class:`~gymprecice.errors.ConfigError` for an option key not in ``known``."""
    problems = unknown_option_problems(solver, known)
    if problems:
        raise ConfigError(problems[0])
