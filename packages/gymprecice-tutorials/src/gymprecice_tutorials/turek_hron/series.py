"""An FSI3 episode's time series: the bar tip's displacement, the drag and the lift.

:mod:`.validate` compares the uncontrolled run's series with the benchmark, and
:mod:`.build_starts` keeps the part its starts come from; both run the env with the jets
shut to the end of its episode (:func:`run_to_end`) and read what it recorded
(:func:`recorded_series`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gymprecice_openfoam.outputs import last_per_time
from gymprecice_tutorials.turek_hron.mesh import GEOMETRY

__all__ = ["SIGNALS", "Series", "recorded_series", "run_to_end"]

#: the signals of a series, after its ``time``
SIGNALS = ("tip_dx", "tip_dy", "drag", "lift")

#: a run's time series by name: ``time``, then each of :data:`SIGNALS`
Series = dict[str, np.ndarray]


def run_to_end(env: Any) -> None:
    """Step ``env`` with the jets shut until its episode is truncated; a terminated
    episode (a solver that diverged) is an error."""
    shut = np.zeros(1, dtype=np.float32)
    while True:
        *_, terminated, truncated, _ = env.step(shut)
        if terminated:
            raise RuntimeError(f"the uncontrolled run ended early at t = {env.time:g} s")
        if truncated:
            return


def recorded_series(env: Any, start_time: float = 0.0) -> Series:
    """The episode's series so far at every time window: the bar tip's displacement
    from the solid's watch point, the drag and lift from the fluid's forces. Times are
    the coupling's, from the episode's start; the fluid's are the simulation's, so an
    episode from a saved state at ``start_time`` has its forces shifted by it."""
    tip = env.open_output(env.SOLID, "watchpoint", point=env.WATCH_POINT)
    tip.read_new()
    forces = last_per_time(env.open_output(env.FLUID, "forces", type="forces").read_all())
    displacement = tip.field("Displacement")
    series: Series = {"time": np.asarray(tip.field("Time"))}
    series["tip_dx"], series["tip_dy"] = displacement[:, 0], displacement[:, 1]
    # the fluid's converged row of each window, at the solid's times
    force_time = np.asarray(forces.time) - start_time
    for name, column in (("drag", "total_x"), ("lift", "total_y")):
        values = np.asarray(forces.column(column)) / GEOMETRY.depth
        series[name] = np.interp(series["time"], force_time, values)
    return series
