"""Patch geometry of the recipe's cylinder, computed from the recipe instead of a mesh.

On real OpenFOAM the OpenFOAM plugin reads the jet and cylinder faces from the mesh. A
stand-in solver (the test double's scripted flow) has no mesh, yet the controller and that
flow must agree on the vertices of the coupling meshes, and the actuators need face
normals and areas. Both sides take them from here: the recipe's O-grid splits the
cylinder wall into equal arcs, so the faces are chords of equal angular width.

Kept free of Gymnasium and of gymprecice's core so the partner process imports it fast.
"""

from __future__ import annotations

import numpy as np

from gymprecice.plugin.solver import InterfaceGeometry
from gymprecice_tutorials import recipes
from gymprecice_tutorials.recipes import CaseSpec

__all__ = ["arc_geometry", "patch_geometry"]


def arc_geometry(
    spec: CaseSpec, start_deg: float, stop_deg: float, faces: int
) -> InterfaceGeometry:
    """Face centres (x, y), unit normals and areas of a cylinder arc of ``faces`` equal faces.

    Each face is the chord between two arc points extruded over the mesh depth, so its
    centre lies just inside the circle. Normals point out of the fluid (into the cylinder),
    as OpenFOAM's boundary face normals do.
    """
    if faces < 1:
        raise ValueError(f"an arc needs at least one face, got {faces}")
    g = spec.geometry
    edges = np.radians(np.linspace(start_deg, stop_deg, faces + 1))
    mid = 0.5 * (edges[:-1] + edges[1:])
    half = 0.5 * (edges[1:] - edges[:-1])
    outward = np.stack([np.cos(mid), np.sin(mid), np.zeros_like(mid)], axis=1)
    centre = np.array([g.centre[0], g.centre[1], 0.0])
    centres = centre + outward * (g.radius * np.cos(half))[:, None]
    areas = 2.0 * g.radius * np.sin(half) * g.depth
    return InterfaceGeometry(centres[:, :2], -outward, areas, ())


def patch_geometry(spec: CaseSpec, patch: str) -> InterfaceGeometry:
    """Geometry of the recipe patch ``jet1``, ``jet2`` or ``cylinder`` (whole wall, no jets)."""
    g = spec.geometry
    half = g.jet_width / 2
    n_jet = spec.resolution.cells_per_jet
    if patch == "jet1":
        geometry = arc_geometry(spec, 90 - half, 90 + half, n_jet)
    elif patch == "jet2":
        geometry = arc_geometry(spec, 270 - half, 270 + half, n_jet)
    elif patch == "cylinder":
        faces = recipes.block_counts(g, spec.resolution).wall_faces
        geometry = arc_geometry(spec, -45.0, 315.0, faces)
    else:
        raise ValueError(f"no recipe patch {patch!r}; the patches are jet1, jet2, cylinder")
    return InterfaceGeometry(geometry.coordinates, geometry.normals, geometry.areas, (patch,))
