"""Turek and Hron's published FSI3 values, and the same figures measured on a series.

Turek & Hron (2006), "Proposal for numerical benchmarking of fluid-structure interaction
between an elastic object and laminar incompressible flow", FSI3 on their finest
mesh: the bar tip's displacement (point A) and the drag and lift on the cylinder and
the bar together, each as ``mean ± amplitude`` of the periodic state, with its
frequency. The mean and the amplitude are the benchmark's: half the sum and half the
difference of the last period's largest and smallest values.

Each figure carries a tolerance, set before any run was compared with it: relative for
the frequencies, the amplitudes and the drag's mean; absolute for the means that
swing about zero (the tip's ``dy`` and the lift), where a relative error means
nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PUBLISHED", "Figure", "Oscillation", "oscillation", "up_crossings"]


@dataclass(frozen=True)
class Figure:
    """One published value and the tolerance a run must meet."""

    value: float
    tolerance: float
    #: "relative": |run / value - 1| <= tolerance; "absolute": |run - value| <= tolerance
    kind: str = "relative"

    def error(self, measured: float) -> float:
        """The run's error in the figure's own kind (a fraction, or the quantity's unit)."""
        if self.kind == "relative":
            return abs(measured / self.value - 1.0)
        return abs(measured - self.value)

    def passes(self, measured: float) -> bool:
        return bool(np.isfinite(measured)) and self.error(measured) <= self.tolerance


#: FSI3's published figures: the tip's displacement in m, the forces in N per metre of
#: depth, the frequencies in Hz. Keys: ``<signal>_<mean|amplitude|frequency>``.
PUBLISHED: dict[str, Figure] = {
    "tip_dx_mean": Figure(-2.69e-3, 0.25),
    "tip_dx_amplitude": Figure(2.53e-3, 0.25),
    "tip_dx_frequency": Figure(10.9, 0.05),
    "tip_dy_mean": Figure(1.48e-3, 2.0e-3, "absolute"),
    "tip_dy_amplitude": Figure(34.38e-3, 0.10),
    "tip_dy_frequency": Figure(5.3, 0.05),
    "drag_mean": Figure(457.3, 0.05),
    "drag_amplitude": Figure(22.66, 0.30),
    "drag_frequency": Figure(10.9, 0.05),
    "lift_mean": Figure(2.22, 10.0, "absolute"),
    "lift_amplitude": Figure(149.78, 0.15),
    "lift_frequency": Figure(5.3, 0.05),
}


@dataclass(frozen=True)
class Oscillation:
    """The benchmark's figures of one signal over a run's last periods."""

    mean: float
    amplitude: float
    frequency: float
    periods: int  # whole periods the frequency was measured over


def up_crossings(time: np.ndarray, values: np.ndarray, level: float = 0.0) -> np.ndarray:
    """The times at which ``values`` crosses ``level`` upwards, interpolated linearly
    between samples."""
    t = np.asarray(time, dtype=float)
    v = np.asarray(values, dtype=float)
    idx = np.nonzero((v[:-1] < level) & (v[1:] >= level))[0]
    return t[idx] + (level - v[idx]) * (t[idx + 1] - t[idx]) / (v[idx + 1] - v[idx])


def oscillation(time: np.ndarray, values: np.ndarray, window: float) -> Oscillation:
    """``mean ± amplitude`` and frequency of ``values`` over the last ``window`` seconds.

    The frequency counts the upward crossings of the window's mid-value, interpolated
    between samples, over whole periods (first to last crossing). Mean and amplitude are
    taken over the last whole period, as the benchmark defines them. A window with fewer
    than two crossings has no period: NaNs.
    """
    t = np.asarray(time, dtype=float)
    v = np.asarray(values, dtype=float)
    keep = t >= t[-1] - window
    t, v = t[keep], v[keep]
    crossings = up_crossings(t, v, 0.5 * (v.max() + v.min()))
    if len(crossings) < 2:
        return Oscillation(float("nan"), float("nan"), float("nan"), 0)
    periods = len(crossings) - 1
    frequency = periods / (crossings[-1] - crossings[0])
    last = (t >= crossings[-2]) & (t <= crossings[-1])
    high, low = float(v[last].max()), float(v[last].min())
    return Oscillation(0.5 * (high + low), 0.5 * (high - low), float(frequency), periods)
