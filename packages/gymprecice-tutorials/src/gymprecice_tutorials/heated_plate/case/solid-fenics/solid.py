"""The heated plate in FEniCS: heat conduction coupled to the fluid through fenicsprecice.

The plate [0, 1] x [-0.25, 0] (100 x 25 linear elements, as in preCICE's
flow-over-heated-plate tutorial) with thermal diffusivity 1 m^2/s and conductivity
100 W/(m K). Its top edge is the coupling interface with the fluid: it reads the fluid's
temperature there (a Dirichlet condition) and writes the heat flux -k dT/dy, through
fenicsprecice. Its bottom edge is held at the heater's temperature, which the controller
writes on a second preCICE mesh, ``Solid-Mesh-heater`` (the bottom's vertices). The sides
are insulated.

fenicsprecice 2.x couples one mesh per participant, so the heater's mesh goes through the
adapter's own preCICE participant: its vertices are set before ``initialize`` (which starts
the coupling) and its temperature is read every time step. The controller writes one
temperature for the whole heater; the plate takes the mean of what it reads.

When the env renders (``render_mode="rgb_array"``), gymprecice sets ``GYMPRECICE_FIELDS``
and ``GYMPRECICE_FIELD_INTERVAL``; the plate then writes its temperature at the mesh
vertices to ``gymprecice-fields/T.npz`` at the start and once per action (see
``gymprecice_fenics.fields``). Otherwise it writes nothing.
"""

import os

import numpy as np
from fenics import (
    Constant,
    DirichletBC,
    Function,
    FunctionSpace,
    Point,
    RectangleMesh,
    SubDomain,
    TestFunction,
    TrialFunction,
    VectorFunctionSpace,
    dot,
    dx,
    grad,
    inner,
    interpolate,
    lhs,
    near,
    rhs,
    solve,
)
from fenicsprecice import Adapter

CONDUCTIVITY = 100.0  # W/(m K)
DIFFUSIVITY = 1.0  # m^2/s
TIME_STEP = 0.01  # s, the preCICE time window
Y_TOP, Y_BOTTOM = 0.0, -0.25
HEATER_MESH = "Solid-Mesh-heater"
FIELDS = [name for name in os.environ.get("GYMPRECICE_FIELDS", "").split(",") if name]
FIELD_INTERVAL = float(os.environ.get("GYMPRECICE_FIELD_INTERVAL") or TIME_STEP)
if set(FIELDS) - {"T"}:
    raise SystemExit(f"solid.py writes the field T only; gymprecice asked for {FIELDS}")


class Top(SubDomain):
    def inside(self, x, on_boundary):
        return on_boundary and near(x[1], Y_TOP, 1e-14)


class Bottom(SubDomain):
    def inside(self, x, on_boundary):
        return on_boundary and near(x[1], Y_BOTTOM, 1e-14)


mesh = RectangleMesh(Point(0, Y_BOTTOM), Point(1, Y_TOP), 100, 25)
V = FunctionSpace(mesh, "P", 1)
V_g = VectorFunctionSpace(mesh, "P", 1)
bottom_temperature = Constant(310.0)
u_n = interpolate(Constant(310.0), V)

precice = Adapter(adapter_config_filename="precice-adapter-config.json")
participant = precice._participant  # the adapter's preCICE participant (see above)
bottom_x = np.unique(mesh.coordinates()[np.isclose(mesh.coordinates()[:, 1], Y_BOTTOM), 0])
heater_ids = participant.set_mesh_vertices(
    HEATER_MESH, np.column_stack([bottom_x, np.full_like(bottom_x, Y_BOTTOM)])
)
precice.initialize(Top(), read_function_space=V, write_object=V_g.sub(1))
coupling_expression = precice.create_coupling_expression()

dt = Constant(min(TIME_STEP, precice.get_max_time_step_size()))
u, v = TrialFunction(V), TestFunction(V)
F = u * v / dt * dx + DIFFUSIVITY * dot(grad(u), grad(v)) * dx - u_n * v / dt * dx
bcs = [
    DirichletBC(V, coupling_expression, Top()),
    DirichletBC(V, bottom_temperature, Bottom()),
]
a, L = lhs(F), rhs(F)
u_np1 = Function(V)
fluxes = Function(V_g)
w, q = TrialFunction(V_g), TestFunction(V_g)
flux_form = (inner(w, q) * dx, inner(-CONDUCTIVITY * grad(u_np1), q) * dx)
t = 0.0


def write_temperature(u, time):
    """``gymprecice-fields/T.npz`` for env.render(), replaced whole (never half written)."""
    os.makedirs("gymprecice-fields", exist_ok=True)
    with open("gymprecice-fields/.T.npz", "wb") as out:
        np.savez(
            out,
            time=np.array(time),
            points=mesh.coordinates(),
            values=u.compute_vertex_values(mesh),
            triangles=mesh.cells().astype(np.int64),
            label=np.array("plate T [K]"),
        )
    os.replace("gymprecice-fields/.T.npz", "gymprecice-fields/T.npz")


if FIELDS:
    write_temperature(u_n, t)

while precice.is_coupling_ongoing():
    if precice.requires_writing_checkpoint():
        precice.store_checkpoint(u_n, t, 0)
    dt.assign(min(TIME_STEP, precice.get_max_time_step_size()))
    precice.update_coupling_expression(coupling_expression, precice.read_data(dt))
    heater = participant.read_data(HEATER_MESH, "Temperature", heater_ids, float(dt))
    bottom_temperature.assign(float(np.mean(heater)))
    solve(a == L, u_np1, bcs)
    # The heat flux at the interface: -k grad T projected onto the vertices; the fluid
    # takes its y component.
    solve(flux_form[0] == flux_form[1], fluxes)
    precice.write_data(fluxes.sub(1))
    precice.advance(dt(0))
    if precice.requires_reading_checkpoint():
        u_cp, t, _ = precice.retrieve_checkpoint()
        u_n.assign(u_cp)
    else:
        u_n.assign(u_np1)
        t += float(dt)
        frames = t / FIELD_INTERVAL
        if FIELDS and abs(frames - round(frames)) < 1e-6 * max(1.0, frames):
            write_temperature(u_n, t)

precice.finalize()
