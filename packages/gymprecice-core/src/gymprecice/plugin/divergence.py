"""Divergence: a solver pushed by the agent's actions past what it can integrate.

An exploring agent will sooner or later drive a solver into divergence (a Courant number
growing without bound, a floating-point exception, NaN forces). That is a consequence of
its actions, which it must learn from, not a broken machine: the step ends the episode
with ``terminated=True``, the environment's divergence penalty as reward and
``info["diverged"]`` (:meth:`Divergence.as_info`). True faults (a killed solver, a
segfault, a hang, a missing library) stay :class:`~gymprecice.errors.SolverError`\\ s.

Which output means divergence is solver knowledge, so plugins answer it through
:func:`gymprecice.hookspecs.gymprecice_detect_divergence`; this module holds what they
share: finding a log line by pattern, and checking the configured numbers.
"""

from __future__ import annotations

import math
import re
import signal
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from gymprecice.plugin.errors import ConfigError

__all__ = [
    "HARD_FAULT_STATUSES",
    "Divergence",
    "checked_penalty",
    "checked_positive",
    "first_match",
]

#: Exit statuses no diverging solver produces on its own: SIGKILL comes from outside (the
#: OOM killer, a scheduler), SIGSEGV and SIGBUS from a broken binary or machine. A solver
#: that ends so stays a fault, whatever its log says.
HARD_FAULT_STATUSES = frozenset({-signal.SIGKILL, -signal.SIGSEGV, -signal.SIGBUS})


@dataclass(frozen=True)
class Divergence:
    """Which solver diverged, at what simulated time, and what showed it."""

    solver: str
    time: float
    evidence: str

    def as_info(self) -> dict[str, Any]:
        return {"solver": self.solver, "time": self.time, "evidence": self.evidence}


def first_match(log_text: str, patterns: Iterable[str | re.Pattern[str]]) -> str | None:
    """The first log line matching any of ``patterns`` (regular expressions), stripped."""
    compiled = [re.compile(p) if isinstance(p, str) else p for p in patterns]
    if not compiled:
        return None
    for line in log_text.splitlines():
        if any(p.search(line) for p in compiled):
            return line.strip()
    return None


def checked_penalty(value: Any, where: str, key: str) -> float:
    """``value`` as a finite float, or a :class:`ConfigError` naming ``key`` and the fix.

    A NaN or infinite reward would poison every value estimate the learner makes.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(
            f"{where}: {key} is {value!r}; it must be a finite number (the reward of the step "
            f"in which a solver diverged), e.g. {key}: -10"
        )
    return float(value)


def checked_positive(value: Any, where: str, key: str, example: str) -> float:
    """``value`` as a positive finite float, or a :class:`ConfigError` with the fix."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise ConfigError(
            f"{where}: {key} is {value!r}; it must be a positive number, e.g. {example}"
        )
    return float(value)
