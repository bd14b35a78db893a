"""Which preCICE library a solver runs, read from its log, against the env's own.

Every participant of a run must use the same library: real preCICE and gymprecice's test
double cannot talk to each other. A mixed set-up does not fail by itself: depending on who
publishes the connection address, one side waits forever for a partner that never comes,
and the run ends in a progress timeout that says nothing about the cause. Both libraries
print the same first line when a participant is created (``This is preCICE version
3.4.1``; the double adds ``(gymprecice fake_precice)``), so the env, which knows its own
library, can tell from a solver's log within a second of its start.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from gymprecice.plugin.solver import LIBRARY_ENV_VAR, TEST_DOUBLE_LIBRARY

__all__ = ["LogLibrary", "library_in_log", "mixed_library_problem"]

# preCICE colours its log prefix: "---[precice] \x1b[0m This is preCICE version 3.4.1".
_BANNER = re.compile(
    r"This is preCICE version (?P<version>[^\s(]+)(?P<double>\s*\(gymprecice fake_precice\))?"
)


class LogLibrary(NamedTuple):
    """The library a log shows: ``double`` or not, and the version it printed."""

    double: bool
    version: str

    def describe(self) -> str:
        if self.double:
            return f"the preCICE test double ({TEST_DOUBLE_LIBRARY})"
        return f"real preCICE {self.version}"


def library_in_log(log_text: str) -> LogLibrary | None:
    """The library whose banner ``log_text`` holds, or ``None`` before any banner."""
    match = _BANNER.search(log_text)
    if match is None:
        return None
    return LogLibrary(bool(match.group("double")), match.group("version"))


def mixed_library_problem(env_library: str, log_text: str) -> str | None:
    """Say so when the solver's log shows another library than the env's ``env_library``."""
    shown = library_in_log(log_text)
    if shown is None:
        return None
    env_double = env_library == TEST_DOUBLE_LIBRARY
    if shown.double == env_double:
        return None
    env_side = (
        f"the preCICE test double ({env_library!r})"
        if env_double
        else f"real preCICE (module {env_library!r})"
    )
    use = "'precice'" if not shown.double else repr(TEST_DOUBLE_LIBRARY)
    return (
        f"it runs {shown.describe()}, but the env's coupling uses {env_side}; every "
        "participant of a run must use the same library, or they never connect. Either "
        f"set precice.library in gymprecice-config.json (or {LIBRARY_ENV_VAR}) to {use}, "
        f"or start the solver with {env_side} (a Python solver imports the module named "
        f"by ${LIBRARY_ENV_VAR}, which core sets for it)"
    )
