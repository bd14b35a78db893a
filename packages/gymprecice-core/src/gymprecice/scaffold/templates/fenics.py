"""Kind ``fenics``: a FEniCS script of a plate whose top edge temperature the controller
sets, and its fenicsprecice adapter configuration.
"""

from __future__ import annotations

__all__ = ["FENICS_ADAPTER_CONFIG", "FENICS_SCRIPT"]

FENICS_ADAPTER_CONFIG = """\
{
  "participant_name": "{{participant}}",
  "config_file_name": "../precice-config.xml",
  "interface": {
    "coupling_mesh_name": "{{mesh}}",
    "write_data_name": "{{read}}",
    "read_data_name": "{{write}}",
    "interpolation_type": "rbf"
  }
}
"""

FENICS_SCRIPT = '''\
"""A heat-conducting plate coupled through fenicsprecice (participant "{{participant}}").

The plate [0, 1] x [-0.25, 0] takes the temperature of its top edge from the controller
and writes the heat flux there; its bottom edge is held at 310 K. It runs in the FEniCS
solver environment (`gymprecice install fenics`), not in gymprecice's own.
"""

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

K = 100.0  # thermal conductivity, W/(m K)
ALPHA = 1.0  # thermal diffusivity, m^2/s


class Top(SubDomain):
    def inside(self, x, on_boundary):
        return on_boundary and near(x[1], 0.0, 1e-14)


class Bottom(SubDomain):
    def inside(self, x, on_boundary):
        return on_boundary and near(x[1], -0.25, 1e-14)


mesh = RectangleMesh(Point(0, -0.25), Point(1, 0), 20, 5)
V = FunctionSpace(mesh, "P", 1)
V_g = VectorFunctionSpace(mesh, "P", 1)
u_bottom = Constant(310.0)
u_n = interpolate(u_bottom, V)

precice = Adapter(adapter_config_filename="precice-adapter-config.json")
precice.initialize(Top(), read_function_space=V, write_object=V_g.sub(1))
coupling = precice.create_coupling_expression()
dt = Constant(precice.get_max_time_step_size())

u, v = TrialFunction(V), TestFunction(V)
F = u * v / dt * dx + ALPHA * dot(grad(u), grad(v)) * dx - u_n * v / dt * dx
bcs = [DirichletBC(V, coupling, Top()), DirichletBC(V, u_bottom, Bottom())]
a, L = lhs(F), rhs(F)
u_np1 = Function(V)
flux = Function(V_g)
w, q = TrialFunction(V_g), TestFunction(V_g)

while precice.is_coupling_ongoing():
    dt.assign(np.min([{{window}}, precice.get_max_time_step_size()]))
    precice.update_coupling_expression(coupling, precice.read_data(dt))
    solve(a == L, u_np1, bcs)
    solve(inner(w, q) * dx == inner(-K * grad(u_np1), q) * dx, flux)
    precice.write_data(flux.sub(1))
    precice.advance(dt(0))
    u_n.assign(u_np1)
    print(f"t advanced by {dt(0):g}", flush=True)
precice.finalize()
'''
