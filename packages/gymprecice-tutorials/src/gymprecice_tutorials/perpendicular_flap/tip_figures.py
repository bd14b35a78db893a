"""The five figures of a flap tip's swing, and preCICE's published series they are read from.

A series of the tip's x-displacement ``dx`` over a run from rest gives

* ``first_peak`` (m) and ``first_peak_time`` (s): the run's first maximum of ``dx``;
* ``period`` (s): twice the mean spacing of the run's successive extrema;
* ``amplitude`` (m): half the mean rise or fall between successive extrema;
* ``mean`` (m): the time-average of ``dx`` over the run.

An extremum is a sample that is the largest (smallest) within 0.2 s on either side and
from which the series moves away by 5 % of the swing: the rule ignores the jitter of a
series digitized from a figure, which a comparison of neighbours would count, and is the
same for every series compared. Each extremum is placed by the parabola through it and its
neighbours. The series is first put on a 0.01 s grid (the tutorial's time window).

:data:`PUBLISHED` is preCICE's series for the tutorial's setup with an OpenFOAM fluid;
:data:`TOLERANCE` is how far a run of the same setup may lie from it, and why.
"""

from __future__ import annotations

from importlib import resources
from typing import NamedTuple

import numpy as np

__all__ = [
    "PUBLISHED",
    "TOLERANCE",
    "TipFigures",
    "parabola_vertex",
    "published_series",
    "tip_figures",
]

#: the grid a series is put on (s), and the half-width of an extremum's window (s)
GRID = 0.01
WINDOW = 0.2
#: how far the series must move away from an extremum, as a share of its swing
PROMINENCE = 0.05


class TipFigures(NamedTuple):
    """The figures of one run (module docstring); ``period``, ``amplitude`` and ``mean``
    are ``nan`` for a run too short to hold two extrema."""

    first_peak: float
    first_peak_time: float
    period: float
    amplitude: float
    mean: float


#: how far a run of preCICE's setup may lie from :data:`PUBLISHED`, and why:
#: the first peak and the period 3 % (the OpenFOAM-CalculiX, -deal.II, -FEniCS and -DUNE
#: curves of the published figure lie within about 1.5 % of each other, and digitizing
#: adds 0.5 mm); the time of the first peak 0.03 s (five pixel columns of the figure, three
#: time windows); the amplitude and the mean 5 % (they sum the small differences of every
#: swing of the run, and the published curves part by up to 0.01 m by the third swing)
TOLERANCE = TipFigures(
    first_peak=0.03, first_peak_time=0.03, period=0.03, amplitude=0.05, mean=0.05
)
#: which tolerances are relative (a share of the published figure) rather than absolute
RELATIVE = TipFigures(
    first_peak=True, first_peak_time=False, period=True, amplitude=True, mean=True
)

_PUBLISHED_FILE = "published/openfoam-fenics-tip-dx.csv"


def published_series() -> np.ndarray:
    """preCICE's published tip series, rows ``(time, dx)`` (see the file's header)."""
    text = (
        resources.files("gymprecice_tutorials.perpendicular_flap")
        .joinpath(_PUBLISHED_FILE)
        .read_text()
    )
    rows = [line for line in text.splitlines() if line and not line.startswith("#")]
    return np.array([[float(v) for v in row.split(",")] for row in rows[1:]])


def parabola_vertex(left: float, mid: float, right: float) -> tuple[float, float]:
    """The vertex of the parabola through three equally spaced samples: its offset from
    the middle one, in sample spacings, and its value. Places an extremum between rows."""
    curvature = left - 2.0 * mid + right
    shift = 0.0 if curvature == 0 else 0.5 * (left - right) / curvature
    return shift, mid - 0.25 * (left - right) * shift


def _extrema(time: np.ndarray, dx: np.ndarray) -> list[tuple[float, float, int]]:
    """``(time, value, +1 for a maximum / -1 for a minimum)`` of each extremum."""
    width = round(WINDOW / GRID)
    swing = float(np.ptp(dx)) or 1.0
    found: list[tuple[float, float, int]] = []
    for i in range(1, len(dx) - 1):
        lo, hi = max(0, i - width), min(len(dx), i + width + 1)
        if hi - i <= width:  # too near the run's end to know
            break
        for sign in (1, -1):
            values = sign * dx
            around = values[lo:hi]
            if values[i] < around.max() or values[i] == values[i - 1]:
                continue
            if values[i] - values[i:hi].min() < PROMINENCE * swing:
                continue
            if i - lo == width and values[i] - values[lo:i].min() < PROMINENCE * swing:
                continue
            shift, value = parabola_vertex(dx[i - 1], dx[i], dx[i + 1])
            found.append((time[i] + shift * GRID, value, sign))
    return found


def tip_figures(time: np.ndarray, dx: np.ndarray) -> TipFigures:
    """The figures of the series ``dx`` at ``time`` (a run from rest at ``time[0]``).

    Raises ``ValueError`` when the series holds no maximum."""
    time, dx = np.asarray(time, dtype=float), np.asarray(dx, dtype=float)
    grid = np.arange(time[0], time[-1] + GRID / 2, GRID)
    values = np.interp(grid, time, dx)
    extrema = _extrema(grid, values)
    peaks = [e for e in extrema if e[2] > 0]
    if not peaks:
        raise ValueError(
            f"the tip's dx has no maximum between t = {time[0]:g} and {time[-1]:g} s: "
            "too short a run for a first peak"
        )
    nan = float("nan")
    period = amplitude = nan
    if len(extrema) >= 2:
        times = np.array([e[0] for e in extrema])
        heights = np.array([e[1] for e in extrema])
        period = float(2.0 * np.mean(np.diff(times)))
        amplitude = float(np.mean(np.abs(np.diff(heights))) / 2.0)
    mean = float(np.trapezoid(values, grid) / (grid[-1] - grid[0])) if len(extrema) >= 2 else nan
    return TipFigures(
        first_peak=float(peaks[0][1]),
        first_peak_time=float(peaks[0][0] - time[0]),
        period=period,
        amplitude=amplitude,
        mean=mean,
    )


#: the figures of preCICE's published series, over its 5 s
PUBLISHED = tip_figures(*published_series().T)
