"""What divergence looks like for the deal.II elasticity solver: its displacement.

A structure driven too hard (a flap pushed by a jet far beyond its bound) makes the
solid solver's displacement blow up: first to absurd values, then to NaN, before the
Newton or linear solver gives up. The displacement is in the preCICE watch-point logs
the solid participant writes (``precice-<participant>-watchpoint-<name>.log``, one row
per time window), so it can be watched while the solver runs:

* a non-finite displacement in the last row of any watch point is divergence;
* with the solver option ``max_displacement`` (a positive length), so is a displacement
  whose magnitude passes it;
* a solver that died with ``Iterative method reported convergence failure`` (deal.II's
  ``SolverControl::NoConvergence``), or whose Newton iterations gave up (the neo-Hookean
  solver's ``No convergence in nonlinear solver!``, e.g. a bar loaded too hard in one
  time step), diverged.

Anything else stays a fault.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin import SolverContext, WatchPointLog, checked_positive, first_match

__all__ = ["DISPLACEMENT_OPTION", "detect", "displacement_limit"]

#: solver option: the displacement magnitude past which the episode ends
DISPLACEMENT_OPTION = "max_displacement"
_EXIT_PATTERNS = (
    re.compile(r"Iterative method reported convergence failure"),
    re.compile(r"NoConvergence"),
    re.compile(r"No convergence in nonlinear solver"),
)


def displacement_limit(solver: SolverContext) -> float | None:
    """The solver's ``max_displacement``, checked: a positive number, or ``None``."""
    value: Any = solver.options.get(DISPLACEMENT_OPTION)
    if value is None:
        return None
    where = str(solver.config_file) if solver.config_file else "the gymprecice configuration"
    return checked_positive(
        value,
        f"{where}: {solver.describe()}",
        f"physics_simulation_engine.solvers.{solver.name}.options.{DISPLACEMENT_OPTION}",
        f'"{DISPLACEMENT_OPTION}": 1.0 (a length far beyond any physical deflection)',
    )


def detect(solver: SolverContext, log_text: str, returncode: int | None) -> str | None:
    """Evidence of divergence (see the module docstring), or ``None``."""
    limit = displacement_limit(solver)
    for path in sorted(Path(solver.run_dir).glob("precice-*-watchpoint-*.log")):
        evidence = _displacement_evidence(path, limit)
        if evidence:
            return evidence
    if returncode is not None:
        line = first_match(log_text, _EXIT_PATTERNS)
        if line:
            return f"log line {line!r}"
    return None


def _displacement_evidence(path: Path, limit: float | None) -> str | None:
    reader = WatchPointLog(path)
    try:
        rows = reader.read_new()
        if not len(rows) or "Displacement" not in reader.fields:
            return None
        last = np.atleast_1d(reader.field("Displacement", rows[-1:])[-1])
    except (OSError, ValueError):
        return None  # a file being rewritten: the next look reads it whole
    finally:
        reader.close()
    time = rows[-1][0]
    magnitude = float(np.linalg.norm(last)) if np.all(np.isfinite(last)) else math.nan
    if math.isfinite(magnitude) and (limit is None or magnitude <= limit):
        return None
    bound = "" if limit is None else f" > {DISPLACEMENT_OPTION} {limit:g}"
    return (
        f"displacement {last.tolist()} (|d| = {magnitude:g}{bound}) at t = {time:g} in {path.name}"
    )
