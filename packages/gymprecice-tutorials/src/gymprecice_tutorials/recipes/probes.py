"""Where the observation's pressure probes sit (Rabault et al. 2019)."""

from __future__ import annotations

import math

from gymprecice_tutorials.recipes.spec import Geometry


def probe_locations(geometry: Geometry) -> list[tuple[float, float, float]]:
    """The 151 pressure probes of Rabault et al. (2019), in this geometry's coordinates.

    In units of D around the cylinder centre: a wake grid of 9 x 7 points
    (x = 0.75, 1, 1.5, ..., 4.5; y = -1.5 ... 1.5 step 0.5), 4 x 4 points above and below
    the cylinder (x = -0.25, 0, 0.25, 0.5; y = ±1, ±1.5) and two rings of 36 points
    (every 10°, from 0°) at radii 0.7 D and 1.0 D. Order: wake grid, side grid, rings.
    As in the original layout, three ring points repeat grid points ((0, ±1) and (1, 0)).
    """
    d = geometry.diameter
    cx, cy = geometry.centre
    pts: list[tuple[float, float]] = []
    for x in (0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5):
        for y in (-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5):
            pts.append((x, y))
    for x in (-0.25, 0.0, 0.25, 0.5):
        for y in (-1.5, -1.0, 1.0, 1.5):
            pts.append((x, y))
    for radius in (0.7, 1.0):
        for k in range(36):
            t = math.radians(10.0 * k)
            pts.append((radius * math.cos(t), radius * math.sin(t)))
    return [(round(cx + d * x, 12), round(cy + d * y, 12), 0.0) for x, y in pts]
