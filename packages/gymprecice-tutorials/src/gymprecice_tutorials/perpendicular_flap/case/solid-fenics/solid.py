"""The perpendicular flap in FEniCS: linear elastodynamics coupled to the fluid by fenicsprecice.

Adapted from preCICE's perpendicular-flap tutorial, ``perpendicular-flap/solid-fenics/
solid.py`` (https://github.com/precice/tutorials, LGPL-3.0-or-later), which is based on
https://gitlab.enpc.fr/jeremy.bleyer/comet-fenics/-/blob/master/examples/elastodynamics/
demo_elastodynamics.py.rst; see also Jeremy Bleyer (2018), Numerical Tours of Computational
Mechanics with FEniCS, Zenodo, https://doi.org/10.5281/zenodo.1287832.

The same flap as the deal.II solid (``solid-dealii/parameters.prm``): 0.1 wide and 1 tall,
x in [-0.05, 0.05], clamped at y = 0; Young's modulus 4 MPa, Poisson's ratio 0.3, density
3000 kg/m^3; plane strain, no body force. It reads the fluid's nodal ``Force`` on its
coupling boundary (the two sides and the top) as point loads and writes its
``Displacement`` there, on preCICE's ``Solid-Mesh``; preCICE's watch point ``Flap-Tip``
(0, 1) of that mesh is what the environment observes, as with the deal.II solid.

What differs from the tutorial's script:

* the velocity update takes the new acceleration, where the tutorial passes the new
  displacement (see precice/tutorials issue #573, a regression of its tip displacement);
* the stiffness matrix is assembled once per time-step size (it does not change), the
  load vector at every iteration; the Dirichlet condition is applied after the point
  loads;
* the generalized-alpha parameters are alpha_m = alpha_f = 0 (below);
* the mesh (below);
* no VTK output and no matplotlib; when the env renders (``GYMPRECICE_FIELDS`` names
  ``displacement``), the displacement at the mesh vertices goes to
  ``gymprecice-fields/displacement.npz`` at the start and once per action
  (``GYMPRECICE_FIELD_INTERVAL``), as the gymprecice-fenics plugin reads it.

Time integration: the generalized-alpha method (Chung and Hulbert 1993) with alpha_m =
alpha_f = 0, i.e. Newmark's average acceleration (gamma = 1/2, beta = 1/4): for a linear
solid the same scheme as the deal.II solid's theta = 0.5 (the trapezoidal rule), so the
two solids differ in their meshes and elements only. With the tutorial's alpha_m = 0.2,
alpha_f = 0.4 the flap's swing in the training case runs about 0.05 s ahead of the
deal.II solid's and its mean tip displacement is 6 % larger (measured; see the
perpendicular-flap tutorial page); with these values the two agree to 0.1 %.

The mesh: quadratic triangles whose coupling vertices are the deal.II solid's, the support
points of its 3 x 18 cells of degree ``DEALII_DEGREE`` (4 in PerpendicularFlap-v0, 2 in
its training case, which edits the line). Each deal.II cell becomes ``DEALII_DEGREE`` x
``DEALII_DEGREE`` cells (split into triangles) with vertices at deal.II's support points:
equidistant up to degree 2, Gauss-Lobatto from degree 3. The fluid's nodal forces then
land on the same vertices with either solid, so the tip force that preCICE's watch point
reports (a nodal force: it depends on where the vertices are) is the same quantity. The
tutorial's 4 x 26 cells give the same swing but a tip force about 15 times smaller and of
the other sign.
"""

import os

import numpy as np
from fenics import (
    AutoSubDomain,
    Constant,
    DirichletBC,
    Function,
    Identity,
    Point,
    RectangleMesh,
    TestFunction,
    TrialFunction,
    VectorFunctionSpace,
    assemble,
    div,
    dx,
    grad,
    inner,
    lhs,
    rhs,
    solve,
    sym,
)
from fenicsprecice import Adapter

# Geometry (m) and material, the deal.II solid's
HEIGHT, WIDTH = 1.0, 0.1
DENSITY = 3000.0  # kg/m^3
YOUNG = 4.0e6  # Pa
POISSON = 0.3
# The deal.II solid whose coupling vertices the mesh copies (module docstring), and the
# elements: quadratic, as the tutorial's
DEALII_DEGREE = 4
DEALII_CELLS = (3, 18)
DEGREE = 2
TOLERANCE = 1e-14
FIELDS = [name for name in os.environ.get("GYMPRECICE_FIELDS", "").split(",") if name]
FIELD_INTERVAL = float(os.environ.get("GYMPRECICE_FIELD_INTERVAL") or 0.0)
if set(FIELDS) - {"displacement"}:
    raise SystemExit(f"solid.py writes the field displacement only; gymprecice asked for {FIELDS}")


def clamped_boundary(x, on_boundary):
    return on_boundary and abs(x[1]) < TOLERANCE


def coupling_boundary(x, on_boundary):
    """The top and both sides: where the fluid acts."""
    return on_boundary and (
        abs(x[1] - HEIGHT) < TOLERANCE or abs(abs(x[0]) - WIDTH / 2) < TOLERANCE
    )


mu = Constant(YOUNG / (2.0 * (1.0 + POISSON)))
lambda_ = Constant(YOUNG * POISSON / ((1.0 + POISSON) * (1.0 - 2.0 * POISSON)))


def support_points(degree):
    """deal.II's ``FE_Q`` support points on [0, 1]: equidistant up to degree 2, else the
    Gauss-Lobatto points (the ends and the roots of the derivative of P_degree)."""
    if degree <= 2:
        return np.linspace(0.0, 1.0, degree + 1)
    interior = np.sort(np.polynomial.legendre.Legendre.basis(degree).deriv().roots().real)
    return np.concatenate([[0.0], (interior + 1.0) / 2.0, [1.0]])


def vertex_positions(start, length, cells, degree):
    """The ``cells * degree + 1`` vertex positions along one side."""
    local = support_points(degree)[:-1]
    steps = np.concatenate([k + local for k in range(cells)] + [[float(cells)]])
    return start + steps * length / cells


mesh = RectangleMesh(
    Point(-WIDTH / 2, 0),
    Point(WIDTH / 2, HEIGHT),
    DEALII_CELLS[0] * DEALII_DEGREE,
    DEALII_CELLS[1] * DEALII_DEGREE,
)
# move the evenly spaced vertices onto deal.II's support points (a no-op up to degree 2)
for axis, (start, length) in enumerate(((-WIDTH / 2, WIDTH), (0.0, HEIGHT))):
    cells = DEALII_CELLS[axis]
    positions = vertex_positions(start, length, cells, DEALII_DEGREE)
    coordinates = mesh.coordinates()[:, axis]
    index = np.rint((coordinates - start) / length * cells * DEALII_DEGREE).astype(int)
    mesh.coordinates()[:, axis] = positions[index]
V = VectorFunctionSpace(mesh, "P", DEGREE)
du, v = TrialFunction(V), TestFunction(V)
u_np1 = Function(V)
u_n, v_n, a_n = Function(V), Function(V), Function(V)  # the last completed time step's

coupling = AutoSubDomain(coupling_boundary)
fixed = AutoSubDomain(clamped_boundary)

precice = Adapter(adapter_config_filename="precice-adapter-config.json")
precice.initialize(coupling, read_function_space=V, write_object=V, fixed_boundary=fixed)

bc = DirichletBC(V, Constant((0, 0)), fixed)
dt = Constant(precice.get_max_time_step_size())

# Generalized-alpha parameters, alpha_m <= alpha_f <= 1/2 (module docstring; the tutorial's
# are 0.2 and 0.4)
alpha_m, alpha_f = 0.0, 0.0
assert alpha_m <= alpha_f <= 0.5
gamma = 0.5 + alpha_f - alpha_m
beta = (gamma + 0.5) ** 2 / 4.0


def sigma(u):
    strain = sym(grad(u))
    return lambda_ * div(u) * Identity(2) + 2 * mu * strain


def new_acceleration(u, u_old, v_old, a_old, step):
    return (u - u_old - step * v_old) / (beta * step**2) - (1 - 2 * beta) / (2 * beta) * a_old


def new_velocity(a, v_old, a_old, step):
    return v_old + step * ((1 - gamma) * a_old + gamma * a)


def mix(old, new, alpha):
    return alpha * old + (1 - alpha) * new


# The residual at t_{n+1-alpha}: mass at alpha_m, stiffness at alpha_f; the fluid's force
# enters as point loads on the assembled right-hand side
a_np1 = new_acceleration(du, u_n, v_n, a_n, dt)
residual = DENSITY * inner(mix(a_n, a_np1, alpha_m), v) * dx
residual += inner(sigma(mix(u_n, du, alpha_f)), sym(grad(v))) * dx
a_form, L_form = lhs(residual), rhs(residual)
matrix, matrix_dt = None, None


def write_displacement(u, time):
    """``gymprecice-fields/displacement.npz`` for env.render(), replaced whole."""
    values = u.compute_vertex_values(mesh).reshape(2, -1).T
    os.makedirs("gymprecice-fields", exist_ok=True)
    with open("gymprecice-fields/.displacement.npz", "wb") as out:
        np.savez(
            out,
            time=np.array(time),
            points=mesh.coordinates(),
            values=np.linalg.norm(values, axis=1),
            displacement=values,
            triangles=mesh.cells().astype(np.int64),
            label=np.array("|d| [m]"),
        )
    os.replace("gymprecice-fields/.displacement.npz", "gymprecice-fields/displacement.npz")


t = 0.0
n = 0
if FIELDS:
    write_displacement(u_n, t)

while precice.is_coupling_ongoing():
    if precice.requires_writing_checkpoint():
        precice.store_checkpoint((u_n, v_n, a_n), t, n)
    step = precice.get_max_time_step_size()
    dt.assign(step)
    if matrix is None or step != matrix_dt:
        matrix, matrix_dt = assemble(a_form), step
        bc.apply(matrix)

    # the force at t_{n+1-alpha_f}, as point loads on the coupling vertices
    forces_x, forces_y = precice.get_point_sources(precice.read_data((1 - alpha_f) * step))
    load = assemble(L_form)
    for source in (*forces_x, *forces_y):
        source.apply(load)
    bc.apply(load)
    solve(matrix, u_np1.vector(), load)
    precice.write_data(u_np1)
    precice.advance(step)

    if precice.requires_reading_checkpoint():
        (u_cp, v_cp, a_cp), t, n = precice.retrieve_checkpoint()
        u_n.assign(u_cp)
        v_n.assign(v_cp)
        a_n.assign(a_cp)
    else:
        u_new, u_old = u_np1.vector().get_local(), u_n.vector().get_local()
        v_old, a_old = v_n.vector().get_local(), a_n.vector().get_local()
        a_new = new_acceleration(u_new, u_old, v_old, a_old, step)
        v_new = new_velocity(a_new, v_old, a_old, step)
        a_n.vector().set_local(a_new)
        a_n.vector().apply("insert")
        v_n.vector().set_local(v_new)
        v_n.vector().apply("insert")
        u_n.assign(u_np1)
        t += step
        n += 1
        if FIELDS and FIELD_INTERVAL > 0:
            frames = t / FIELD_INTERVAL
            if abs(frames - round(frames)) < 1e-6 * max(1.0, frames):
                write_displacement(u_n, t)

precice.finalize()
