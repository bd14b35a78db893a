"""What divergence looks like in an OpenFOAM solver's log.

An agent's action (a jet at ten times its bound) can drive the flow past what the time
step integrates. OpenFOAM then shows it in its log, before or as it dies:

* the Courant number grows without bound (``Courant Number mean: ... max: ...``, written
  every time step by the transient solvers). With the solver option ``max_courant`` the
  episode ends as soon as the last written maximum passes that limit (or is not finite),
  *before* the solver crashes and while its state is still readable;
* the floating-point trap fires (``Foam::sigFpe::sigHandler`` in the stack trace);
* a solver loop gives up (``Maximum number of iterations exceeded``).

The last two are read only once the solver has failed; while it runs, only the Courant
guard applies.

Each is reported with the log line that shows it and the log's last ``Time =``. Anything
else (a missing library, a fatal error in a dictionary, a signal from outside) is not
divergence and stays a fault.
"""

from __future__ import annotations

import math
import re
from typing import Any

from gymprecice.plugin import SolverContext, checked_positive, first_match

__all__ = ["COURANT_OPTION", "EXIT_PATTERNS", "courant_limit", "detect"]

#: solver option: the Courant number past which the episode ends (absent: no guard)
COURANT_OPTION = "max_courant"
#: log lines of a solver that died of divergence: the FPE trap's stack frame, the line a
#: shell prints for SIGFPE, an iteration limit. Anchored and specific, because every
#: OpenFOAM log starts with a banner naming the trap ("trapFpe: Floating point exception
#: trapping enabled", "sigFpe : Enabling floating point exception trapping").
EXIT_PATTERNS = (
    re.compile(r"sigFpe::sigHandler"),
    re.compile(r"^\s*Floating point exception(?! trapping)"),
    re.compile(r"[Mm]aximum number of iterations exceeded"),
)
_COURANT = re.compile(r"^\s*Courant Number mean:\s*(\S+)\s+max:\s*(\S+)", re.MULTILINE)
_TIME = re.compile(r"^Time = (\S+)", re.MULTILINE)


def courant_limit(solver: SolverContext) -> float | None:
    """The solver's ``max_courant``, checked: a positive number, or ``None`` (no guard)."""
    value: Any = solver.options.get(COURANT_OPTION)
    if value is None:
        return None
    where = str(solver.config_file) if solver.config_file else "the gymprecice configuration"
    return checked_positive(
        value,
        f"{where}: {solver.describe()}",
        f"physics_simulation_engine.solvers.{solver.name}.options.{COURANT_OPTION}",
        f'"{COURANT_OPTION}": 5 (a few times the case\'s usual maximum Courant number)',
    )


def detect(solver: SolverContext, log_text: str, returncode: int | None) -> str | None:
    """Evidence of divergence in the log's tail, or ``None`` (see the module docstring)."""
    evidence = _courant_past_limit(log_text, courant_limit(solver))
    if evidence is None and returncode not in (None, 0):  # how it died: only once it has
        line = first_match(log_text, EXIT_PATTERNS)
        evidence = f"log line {line!r}" if line else None
    if evidence is None:
        return None
    times = _TIME.findall(log_text)
    return f"{evidence} (at solver Time = {times[-1]})" if times else evidence


def _courant_past_limit(log_text: str, limit: float | None) -> str | None:
    """The last written Courant maximum, if it passed ``limit`` or is not finite."""
    if limit is None:
        return None
    found = _COURANT.findall(log_text)
    if not found:
        return None
    try:
        largest = float(found[-1][1])
    except ValueError:
        largest = math.nan
    if math.isfinite(largest) and largest <= limit:
        return None
    return f"Courant Number max {found[-1][1]} > {COURANT_OPTION} {limit:g}"
