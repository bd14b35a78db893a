"""The convergence measures of implicit coupling, as preCICE computes and logs them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gymprecice.testing.fake_precice.numerics import equals


@dataclass
class Measure:
    kind: str
    data: str
    mesh: str
    limit: float = 0.0
    abs_limit: float = 0.0
    rel_limit: float = 0.0
    suffices: bool = False
    strict: bool = False
    first_residual: float | None = None

    @property
    def header(self) -> str:
        abbreviation = {
            "absolute": "Abs",
            "relative": "Rel",
            "absolute-or-relative": "AbsOrRel",
            "residual-relative": "Drop",
        }.get(self.kind, self.kind)
        return f"Res{abbreviation}({self.mesh}:{self.data})"

    def measure(self, old: np.ndarray, new: np.ndarray) -> tuple[bool, float]:
        """(converged, residual as preCICE's convergence log reports it)."""
        diff = float(np.linalg.norm(new - old))
        norm = float(np.linalg.norm(new))
        relative = math.inf if equals(norm, 0.0) else diff / norm
        if self.kind == "absolute":
            return diff <= self.limit, diff
        if self.kind == "relative":
            return diff <= norm * self.limit, relative
        if self.kind == "absolute-or-relative":
            return diff <= norm * self.rel_limit or diff <= self.abs_limit, relative
        if self.first_residual is None:  # residual-relative
            self.first_residual = diff
        drop = math.inf if equals(self.first_residual, 0.0) else diff / self.first_residual
        return diff < self.first_residual * self.limit, drop
