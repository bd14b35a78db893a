"""Jets and rotating walls: exact flow rates, zero net mass flux, impermeable rotation."""

from __future__ import annotations

import numpy as np
import pytest

from gymprecice.plugin.solver import InterfaceGeometry
from gymprecice_openfoam import actuators, mesh

CENTRE = np.array([0.2, 0.2, 0.005])
R = 0.05
DEPTH = 0.01


def faceted_arc(a0_deg: float, a1_deg: float, n: int, dims: int = 3) -> InterfaceGeometry:
    """Faces of a cylinder between two angles, as OpenFOAM would give them."""
    angles = np.radians(np.linspace(a0_deg, a1_deg, n + 1))
    pts = CENTRE[:2] + R * np.column_stack([np.cos(angles), np.sin(angles)])
    mid = 0.5 * (pts[1:] + pts[:-1])
    chord = pts[1:] - pts[:-1]
    length = np.linalg.norm(chord, axis=1)
    # Outward from the fluid = into the cylinder: towards the centre.
    inward = CENTRE[:2] - mid
    normals = np.column_stack([inward / np.linalg.norm(inward, axis=1)[:, None], np.zeros(n)])
    coords = np.column_stack([mid, np.full(n, CENTRE[2])])[:, :dims]
    return InterfaceGeometry(coordinates=coords, normals=normals, areas=length * DEPTH)


def inflow(geometry: InterfaceGeometry, velocity: np.ndarray) -> float:
    """Volume flux into the fluid through the faces."""
    v3 = np.zeros((len(velocity), 3))
    v3[:, : velocity.shape[1]] = velocity
    return float(np.sum(np.einsum("ij,ij->i", v3, -geometry.normals) * geometry.areas))


@pytest.mark.parametrize("direction", ["normal", "radial"])
@pytest.mark.parametrize("dims", [2, 3])
def test_jet_blows_exactly_the_flow_rate(direction, dims):
    jet = faceted_arc(85, 95, 7, dims)
    q = 3.7e-5
    u = actuators.jet_velocity(jet, q, centre=CENTRE, direction=direction)
    assert u.shape == (7, dims)
    assert inflow(jet, u) == pytest.approx(q, rel=1e-13)
    speed = np.linalg.norm(u, axis=1)
    assert np.argmax(speed) == 3  # peak in the middle of the slot
    np.testing.assert_allclose(speed, speed[::-1], rtol=1e-9)  # symmetric profile
    assert speed[0] < 0.35 * speed[3]  # falls off towards the edges (half sine)
    # Blowing points away from the cylinder.
    radial = jet.coordinates[:, :2] - CENTRE[:2]
    assert np.all(np.einsum("ij,ij->i", u[:, :2], radial) > 0)


def test_profile_shape_and_defaults():
    jet = faceted_arc(85, 95, 10)
    shape = actuators.jet_profile(jet, centre=CENTRE)
    theta = np.arctan2(jet.coordinates[:, 1] - 0.2, jet.coordinates[:, 0] - 0.2)
    # Default width: the slot's 10 degrees, recovered from the face centres.
    np.testing.assert_allclose(
        shape, np.cos(np.pi * (theta - np.pi / 2) / np.radians(10)), atol=1e-12
    )
    narrow = actuators.jet_profile(jet, centre=CENTRE, width=np.radians(5))
    assert narrow.min() == 0.0  # faces outside a narrower jet get nothing
    assert actuators.jet_profile(faceted_arc(85, 95, 1), centre=CENTRE).tolist() == [1.0]


def test_two_jets_have_zero_net_mass_flux():
    jet1, jet2 = faceted_arc(85, 95, 5), faceted_arc(265, 275, 5)
    u1, u2 = actuators.synthetic_jets(jet1, jet2, 1e-4, centre=CENTRE)
    assert inflow(jet1, u1) == pytest.approx(1e-4, rel=1e-13)
    assert inflow(jet1, u1) + inflow(jet2, u2) == pytest.approx(0.0, abs=1e-18)
    # Blowing up out of the top slot, sucking up into the bottom one: same speeds.
    np.testing.assert_allclose(u1[:, 1], u2[:, 1], rtol=1e-12)
    assert np.all(u1[:, 1] > 0)


def test_rotating_wall_is_tangential_with_the_right_sense():
    wall = faceted_arc(0, 360, 36)
    omega = 2.0
    u = actuators.rotating_wall_velocity(wall, omega, centre=CENTRE)
    np.testing.assert_allclose(np.einsum("ij,ij->i", u, wall.normals), 0.0, atol=1e-15)
    r_face = np.linalg.norm(wall.coordinates[:, :2] - CENTRE[:2], axis=1)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), omega * r_face, rtol=1e-12)
    # Counter-clockwise for omega > 0: at the top of the cylinder the wall moves to -x.
    top = np.argmax(wall.coordinates[:, 1])
    assert u[top, 0] < 0
    u2d = actuators.rotating_wall_velocity(faceted_arc(0, 360, 36, 2), omega, centre=CENTRE)
    np.testing.assert_allclose(u2d, u[:, :2], atol=1e-15)


def test_faces_without_normals_are_refused():
    nodes = InterfaceGeometry(coordinates=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="faceCenters"):
        actuators.jet_velocity(nodes, 1.0)


@pytest.mark.openfoam
def test_jets_on_a_real_blockmesh_cylinder(run, cylinder_case):
    """Cost: under a second (one blockMesh of the small cylinder)."""
    case = cylinder_case("jets", resolution=1.5)
    run(case, "blockMesh")
    mesh.clear_cache()
    jet1 = mesh.interface_geometry(case, "Fluid-Mesh-jet1", dimensions=2)
    jet2 = mesh.interface_geometry(case, "Fluid-Mesh-jet2", dimensions=2)
    u1, u2 = actuators.synthetic_jets(jet1, jet2, 2e-5, centre=CENTRE)
    assert u1.shape == (len(jet1.coordinates), 2)
    assert inflow(jet1, u1) == pytest.approx(2e-5, rel=1e-12)
    assert inflow(jet2, u2) == pytest.approx(-2e-5, rel=1e-12)
    assert np.all(u1[:, 1] > 0) and np.all(u2[:, 1] > 0)  # jet1 blows up, jet2 sucks (up)
