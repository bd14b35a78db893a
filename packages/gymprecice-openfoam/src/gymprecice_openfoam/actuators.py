"""Turn a controller's action into boundary velocities on interface faces.

Two actuators of the Gym-preCICE flow-control cases:

* synthetic jets: a volumetric flow rate ``Q`` becomes a velocity on each face of a jet
  patch, shaped like a half sine over the jet's angular width (zero at its edges) and
  scaled so that the discrete flux through the faces, ``sum((u . d) |Sf|)`` with ``d``
  the direction into the fluid, is exactly ``Q`` (a profile sampled on faces does not
  integrate to ``Q`` on its own). Two jets driven with ``+Q`` and ``-Q`` add no net mass.
* a rotating wall: the velocity ``omega x r`` of each face centre about an axis,
  with its normal component removed so the wall stays impermeable.

Both use :class:`gymprecice.solver.InterfaceGeometry` (face centres, unit normals,
areas) and return arrays of shape ``(n, dimensions)`` matching the interface's
coordinates, ready to be written as preCICE vector data.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gymprecice.plugin import InterfaceGeometry

__all__ = ["jet_profile", "jet_velocity", "rotating_wall_velocity", "synthetic_jets"]


def _as3(coords: np.ndarray) -> np.ndarray:
    coords = np.asarray(coords, dtype=float)
    if coords.shape[1] == 3:
        return coords
    out = np.zeros((len(coords), 3))
    out[:, : coords.shape[1]] = coords
    return out


def _require_faces(geometry: InterfaceGeometry, what: str) -> tuple[np.ndarray, np.ndarray]:
    if geometry.normals is None or geometry.areas is None:
        raise ValueError(
            f"{what} needs face normals and areas; use an interface with "
            "'locations faceCenters' (faceNodes geometry has neither)"
        )
    return np.asarray(geometry.normals, dtype=float), np.asarray(geometry.areas, dtype=float)


def _basis(axis: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit ``axis`` and two unit vectors spanning the plane normal to it."""
    a = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(a)
    if norm == 0:
        raise ValueError("axis must be a non-zero vector")
    a = a / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - np.dot(helper, a) * a
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    return a, e1, e2


def _angles(points: np.ndarray, centre: np.ndarray, axis: Sequence[float]) -> np.ndarray:
    _, e1, e2 = _basis(axis)
    rel = points - centre
    return np.arctan2(rel @ e2, rel @ e1)


def _wrap(angle: np.ndarray | float) -> np.ndarray:
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def jet_profile(
    geometry: InterfaceGeometry,
    *,
    centre: Sequence[float] = (0.0, 0.0, 0.0),
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    width: float | None = None,
    jet_angle: float | None = None,
) -> np.ndarray:
    """Unscaled jet shape on each face: ``cos(pi (theta - theta0) / width)``, >= 0.

    ``theta`` is the face centre's angle about ``axis`` through ``centre``; ``theta0``
    (``jet_angle``) defaults to the area-weighted circular mean of the patch, ``width``
    (radians) to the patch's angular extent estimated from its face centres
    (span x n / (n - 1), i.e. the centre span plus one face).
    """
    points = _as3(geometry.coordinates)
    _, areas = _require_faces(geometry, "a jet profile")
    c = np.asarray(centre, dtype=float)
    theta = _angles(points, c, axis)
    if jet_angle is None:
        jet_angle = float(np.arctan2(np.sum(areas * np.sin(theta)), np.sum(areas * np.cos(theta))))
    rel = _wrap(theta - jet_angle)
    if width is None:
        n = len(rel)
        span = float(rel.max() - rel.min()) if n else 0.0
        width = span * n / (n - 1) if n > 1 else 0.0
    if width <= 0:
        return np.ones(len(rel))
    return np.clip(np.cos(np.pi * rel / width), 0.0, None)


def jet_velocity(
    geometry: InterfaceGeometry,
    flow_rate: float,
    *,
    centre: Sequence[float] = (0.0, 0.0, 0.0),
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    width: float | None = None,
    jet_angle: float | None = None,
    direction: str = "normal",
    profile: np.ndarray | None = None,
) -> np.ndarray:
    """Face velocities of a jet blowing ``flow_rate`` (m^3/s, or m^2/s per depth) into the fluid.

    Positive ``flow_rate`` blows into the domain, negative sucks. ``direction`` is
    ``"normal"`` (against the outward face normal) or ``"radial"`` (away from
    ``centre`` in the plane normal to ``axis``, as in Rabault et al.); either way the
    profile is scaled so that the flux into the domain is exactly ``flow_rate``.
    """
    normals, areas = _require_faces(geometry, "a jet velocity")
    shape = (
        jet_profile(geometry, centre=centre, axis=axis, width=width, jet_angle=jet_angle)
        if profile is None
        else np.asarray(profile, dtype=float)
    )
    inward = -normals
    if direction == "normal":
        d = inward
    elif direction == "radial":
        a, _, _ = _basis(axis)
        rel = _as3(geometry.coordinates) - np.asarray(centre, dtype=float)
        rel -= np.outer(rel @ a, a)
        norm = np.linalg.norm(rel, axis=1)
        if np.any(norm == 0):
            raise ValueError("a face centre lies on the axis: no radial direction")
        d = rel / norm[:, None]
    else:
        raise ValueError(f"direction must be 'normal' or 'radial', not {direction!r}")
    flux_per_unit = float(np.sum(shape * np.einsum("ij,ij->i", d, inward) * areas))
    if flux_per_unit == 0:
        raise ValueError("the jet profile carries no flux through these faces")
    velocity = (flow_rate / flux_per_unit) * shape[:, None] * d
    return velocity[:, : geometry.coordinates.shape[1]]


def synthetic_jets(
    jet1: InterfaceGeometry,
    jet2: InterfaceGeometry,
    flow_rate: float,
    **kwargs: object,
) -> tuple[np.ndarray, np.ndarray]:
    """Velocities of two jets with zero net mass flux: ``+flow_rate`` and ``-flow_rate``."""
    return (
        jet_velocity(jet1, flow_rate, **kwargs),  # type: ignore[arg-type]
        jet_velocity(jet2, -flow_rate, **kwargs),  # type: ignore[arg-type]
    )


def rotating_wall_velocity(
    geometry: InterfaceGeometry,
    omega: float,
    *,
    centre: Sequence[float] = (0.0, 0.0, 0.0),
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    tangential: bool = True,
) -> np.ndarray:
    """Wall velocity ``omega * axis x (x - centre)`` at each face centre (rad/s, right-handed).

    With ``tangential`` (default) the component along the face normal is removed, so a
    faceted cylinder does not blow or suck through its own wall.
    """
    a, _, _ = _basis(axis)
    rel = _as3(geometry.coordinates) - np.asarray(centre, dtype=float)
    velocity = omega * np.cross(a, rel)
    if tangential and geometry.normals is not None:
        n = np.asarray(geometry.normals, dtype=float)
        velocity -= np.einsum("ij,ij->i", velocity, n)[:, None] * n
    return velocity[:, : geometry.coordinates.shape[1]]
