"""Turek and Hron's elastic bar in legacy FEniCS, with a state that saves and loads.

The bar of the FSI and CSM benchmarks (Turek & Hron 2006): 0.35 x 0.02 m behind the
cylinder of centre (0.2, 0.2) and radius 0.05, clamped where it meets the cylinder, its
tip's mid-point A = (0.6, 0.2). Plane strain, a St. Venant-Kirchhoff material (the
benchmark's: S = lambda tr(E) I + 2 mu E, with E the Green-Lagrange strain), quadratic
triangles, and Newmark's average-acceleration rule in time (beta 1/4, gamma 1/2: no
numerical damping, so a free oscillation keeps its amplitude).

Why a second solid beside the deal.II adapter's: a control environment starts its
episodes from the developed, swinging state, and the deal.II program always starts from
rest (4 to 5 s of simulated time, 15 to 20 min, before the bar swings). This one writes
its state (displacement, velocity, acceleration, time) with :meth:`Bar.save` and starts
from one with :meth:`Bar.load`.

Runs in the FEniCS solver environment's interpreter (gymprecice_fenics.solver_env), as
the coupled participant (``solid.py``) and for the solid's own benchmarks (``csm.py``).
"""

import math
from dataclasses import dataclass

import numpy as np
from dolfin import (
    AutoSubDomain,
    Constant,
    DirichletBC,
    Function,
    Identity,
    NonlinearVariationalProblem,
    NonlinearVariationalSolver,
    Point,
    RectangleMesh,
    TestFunction,
    VectorFunctionSpace,
    derivative,
    ds,
    dx,
    grad,
    inner,
    set_log_level,
    tr,
    vertex_to_dof_map,
)

#: where the bar meets the cylinder (x), its tip (x) and its faces (y), in m
X_CLAMP = 0.2 + math.sqrt(0.05**2 - 0.01**2)
X_TIP = 0.6
Y_LOW, Y_HIGH = 0.19, 0.21
#: the benchmark's point A, the middle of the tip
POINT_A = (X_TIP, 0.2)
TOLERANCE = 1e-9


@dataclass(frozen=True)
class Material:
    """Density (kg/m^3), shear modulus (Pa) and Poisson's ratio."""

    density: float
    shear: float
    poisson: float

    @property
    def lame(self) -> float:
        """Lame's first parameter, lambda = 2 mu nu / (1 - 2 nu)."""
        return 2.0 * self.shear * self.poisson / (1.0 - 2.0 * self.poisson)


#: the bar of FSI3 and CSM2 (shear modulus 2 MPa)
FSI3 = Material(1000.0, 2.0e6, 0.4)
#: the bar of CSM1 and CSM3 (shear modulus 0.5 MPa)
CSM = Material(1000.0, 0.5e6, 0.4)


class VertexTraction:
    """A load per area given at the mesh's vertices (preCICE's ``Stress`` at the coupling
    vertices of the wetted faces), as a piecewise-linear vector function.

    Why not fenicsprecice's coupling expression: that is a Python ``UserExpression``
    that evaluates a radial-basis interpolant at every quadrature point of every
    assembly, a dozen assemblies a coupling iteration, and it made the bar cost more CPU
    than the fluid. This function is assembled in compiled code; between two vertices
    it is linear, where the interpolant is smooth: they agree at the vertices, and differ
    by the facet's curvature of the load, O(h^2).
    """

    def __init__(self, mesh):
        self.function = Function(VectorFunctionSpace(mesh, "P", 1))
        dofs = vertex_to_dof_map(self.function.function_space()).reshape(-1, 2)
        self._dofs = {self._key(x): dofs[i] for i, x in enumerate(mesh.coordinates())}
        self._values = np.zeros(self.function.vector().local_size())

    @staticmethod
    def _key(point):
        return tuple(np.round(np.asarray(point, dtype=float), 9))

    def update(self, data):
        """Set the load at each vertex of ``data`` (``{(x, y): (tx, ty)}``, fenicsprecice's
        ``read_data``); the other vertices carry none."""
        self._values[:] = 0.0
        for point, value in data.items():
            self._values[self._dofs[self._key(point)]] = value
        self.function.vector().set_local(self._values)
        self.function.vector().apply("insert")


def clamped(x, on_boundary):
    return on_boundary and abs(x[0] - X_CLAMP) < TOLERANCE


def wetted(x, on_boundary):
    """The faces the fluid acts on: both long sides and the tip."""
    return on_boundary and x[0] > X_CLAMP + TOLERANCE


class Bar:
    """The bar's discretisation, its state and one time step.

    ``cells``: triangles are made of ``(nx, ny)`` rectangles, each cut in four
    ("crossed", so the mesh is symmetric about the bar's axis). ``gravity``: the body
    force per mass in -y (m/s^2). ``traction``: None, or a function that takes the bar's
    function space and returns an expression of the load per reference area on its
    faces (the coupled fluid's stress: a :class:`VertexTraction`, made once preCICE
    knows the function space's coupling vertices).
    """

    def __init__(self, material, cells=(36, 4), degree=2, gravity=0.0, traction=None):
        set_log_level(30)  # dolfin's WARNING: no line per Newton iteration
        self.material = material
        self.mesh = RectangleMesh(
            Point(X_CLAMP, Y_LOW), Point(X_TIP, Y_HIGH), cells[0], cells[1], "crossed"
        )
        self.V = VectorFunctionSpace(self.mesh, "P", degree)
        self.u = Function(self.V)  # the displacement being solved for, t_{n+1}
        self.u_n, self.v_n, self.a_n = Function(self.V), Function(self.V), Function(self.V)
        self.time = 0.0
        self.dt = Constant(1.0)
        self.dynamic = Constant(1.0)  # 0: a static solve (no inertia)
        self.gravity = Constant((0.0, -gravity))
        self.bc = DirichletBC(self.V, Constant((0.0, 0.0)), AutoSubDomain(clamped))
        beta = 0.25
        w = TestFunction(self.V)
        a_new = (self.u - self.u_n - self.dt * self.v_n) / (beta * self.dt**2) - (
            1.0 - 2.0 * beta
        ) / (2.0 * beta) * self.a_n
        rho = Constant(material.density)
        residual = self.dynamic * rho * inner(a_new, w) * dx
        residual += inner(self._first_piola(self.u), grad(w)) * dx
        residual -= rho * inner(self.gravity, w) * dx
        if traction is not None:
            residual -= inner(traction(self.V), w) * ds
        problem = NonlinearVariationalProblem(
            residual, self.u, [self.bc], derivative(residual, self.u)
        )
        self.solver = NonlinearVariationalSolver(problem)
        newton = self.solver.parameters["newton_solver"]
        newton["absolute_tolerance"] = 1e-8  # the round-off floor is about 1e-9
        newton["relative_tolerance"] = 1e-8
        newton["maximum_iterations"] = 30
        newton["error_on_nonconvergence"] = True

    def _first_piola(self, u):
        """P = F S, S = lambda tr(E) I + 2 mu E: St. Venant-Kirchhoff."""
        identity = Identity(2)
        F = identity + grad(u)
        E = 0.5 * (F.T * F - identity)
        S = (
            Constant(self.material.lame) * tr(E) * identity
            + 2.0 * Constant(self.material.shear) * E
        )
        return F * S

    def solve_static(self, increments=4):
        """Static equilibrium under the full load, reached in ``increments`` load steps
        (Newton from the unloaded bar may not converge under a large load)."""
        self.dynamic.assign(0.0)
        full = self.gravity.values().copy()
        try:
            for k in range(1, increments + 1):
                self.gravity.assign(Constant(tuple(full * k / increments)))
                self.solver.solve()
        finally:
            self.dynamic.assign(1.0)
            self.gravity.assign(Constant(tuple(full)))
        self.u_n.assign(self.u)

    def step(self, dt):
        """Solve for t + dt; :meth:`advance` makes it the state (a coupled solid may
        iterate a time window several times first)."""
        self.dt.assign(dt)
        self.u.assign(self.u_n)  # Newton starts from the last state
        self.solver.solve()

    def advance(self, dt):
        """Accept the solution of :meth:`step` as the state at t + dt (Newmark's update)."""
        beta, gamma = 0.25, 0.5
        u_new, u_old = self.u.vector().get_local(), self.u_n.vector().get_local()
        v_old, a_old = self.v_n.vector().get_local(), self.a_n.vector().get_local()
        a_new = (u_new - u_old - dt * v_old) / (beta * dt**2) - (1.0 - 2.0 * beta) / (
            2.0 * beta
        ) * a_old
        v_new = v_old + dt * ((1.0 - gamma) * a_old + gamma * a_new)
        for function, values in ((self.a_n, a_new), (self.v_n, v_new), (self.u_n, u_new)):
            function.vector().set_local(values)
            function.vector().apply("insert")
        self.time += dt

    def tip(self):
        """The displacement (dx, dy) of point A, m."""
        return tuple(float(c) for c in self.u_n(Point(*POINT_A)))

    def state(self):
        """The state's functions (displacement, velocity, acceleration), for a coupling
        iteration's checkpoint (fenicsprecice copies them); the time goes beside."""
        return [self.u_n, self.v_n, self.a_n]

    def restore(self, functions, time):
        for mine, saved in zip((self.u_n, self.v_n, self.a_n), functions):
            mine.assign(saved)
        self.time = time

    def save(self, path):
        """The state as an ``.npz``, written whole or not at all (a temporary file,
        then renamed). Only a bar of the same mesh and degree can load it."""
        import os

        tmp = f"{path}.tmp.npz"
        np.savez(
            tmp,
            u=self.u_n.vector().get_local(),
            v=self.v_n.vector().get_local(),
            a=self.a_n.vector().get_local(),
            time=np.array(self.time),
            dofs=np.array(self.V.dim()),
        )
        os.replace(tmp, path)

    def load(self, path):
        with np.load(path) as saved:
            if int(saved["dofs"]) != self.V.dim():
                raise ValueError(
                    f"{path}: a state of {int(saved['dofs'])} unknowns, this bar has "
                    f"{self.V.dim()}: it was saved with another mesh or degree"
                )
            for function, key in ((self.u_n, "u"), (self.v_n, "v"), (self.a_n, "a")):
                function.vector().set_local(saved[key])
                function.vector().apply("insert")
            self.time = float(saved["time"])
        self.u.assign(self.u_n)
