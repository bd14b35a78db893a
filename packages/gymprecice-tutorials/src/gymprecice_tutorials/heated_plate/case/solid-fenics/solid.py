"""The heated plate in FEniCS: heat conduction coupled to the fluid through fenicsprecice.

The plate [0, 1] x [-0.25, 0] (100 x 25 linear elements, as in preCICE's
flow-over-heated-plate tutorial) with thermal diffusivity 1 m^2/s and conductivity
100 W/(m K). Its top edge is the coupling interface: it reads the fluid's temperature there
(a Dirichlet condition) and writes the heat flux -k dT/dy. Its bottom edge is held at the
heater's temperature, a time table in ``constant/heater-temperature`` (OpenFOAM's list
format ``((t T) ...)``, linear in between and constant outside, the same file and rule as
the laplacianFoam solid's ``tableFile``); the environment writes it for each episode. The
sides are insulated.
"""

import re

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


def heater_table(path="constant/heater-temperature"):
    """(times, temperatures) of an OpenFOAM list ``((t T) ...)``."""
    with open(path) as f:
        pairs = re.findall(r"\(\s*([-+0-9.eE]+)\s+([-+0-9.eE]+)\s*\)", f.read())
    if not pairs:
        raise ValueError(f"{path}: no (time temperature) pairs")
    times, values = np.array(pairs, dtype=float).T
    return times, values


class Top(SubDomain):
    def inside(self, x, on_boundary):
        return on_boundary and near(x[1], Y_TOP, 1e-14)


class Bottom(SubDomain):
    def inside(self, x, on_boundary):
        return on_boundary and near(x[1], Y_BOTTOM, 1e-14)


times, temperatures = heater_table()


def heater(t):
    return float(np.interp(t, times, temperatures))


mesh = RectangleMesh(Point(0, Y_BOTTOM), Point(1, Y_TOP), 100, 25)
V = FunctionSpace(mesh, "P", 1)
V_g = VectorFunctionSpace(mesh, "P", 1)
bottom_temperature = Constant(heater(0.0))
u_n = interpolate(Constant(310.0), V)

precice = Adapter(adapter_config_filename="precice-adapter-config.json")
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

while precice.is_coupling_ongoing():
    if precice.requires_writing_checkpoint():
        precice.store_checkpoint(u_n, t, 0)
    dt.assign(min(TIME_STEP, precice.get_max_time_step_size()))
    precice.update_coupling_expression(coupling_expression, precice.read_data(dt))
    bottom_temperature.assign(heater(t + float(dt)))
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

precice.finalize()
