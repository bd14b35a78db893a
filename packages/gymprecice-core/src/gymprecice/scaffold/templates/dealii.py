"""Kind ``dealii``: the parameters of the deal.II-preCICE adapter's ``elasticity``
program for an elastic flap pushed at its tip.
"""

from __future__ import annotations

__all__ = ["DEALII_PARAMETERS"]

DEALII_PARAMETERS = """\
# An elastic flap (0.1 x 1 m, clamped at y = 0), run by the deal.II-preCICE adapter's
# `elasticity` program (scenario PF builds the flap's mesh itself). SI units. gymprecice
# points `precice config-file` at each env's own preCICE configuration and checks this
# file against it before every run.

subsection Time
  # Must equal the preCICE time-window size (the adapter aborts otherwise).
  set Time step size  = {{window}}
  # The coupling (preCICE max-time) ends the run; keep this at least as long.
  set End time        = 100
  set Output interval = 10
  set Output folder   = dealii-output
end

subsection Discretization
  set Polynomial degree = 3
end

subsection System properties
  # Young's modulus 4 MPa and Poisson's ratio 0.3 give this shear modulus.
  set Poisson's ratio = 0.3
  set Shear modulus   = 1538462
  set rho             = 3000
  set body forces     = 0.0, 0.0, 0.0
end

subsection Solver
  set Model                         = linear
  set Solver type                   = Direct
  set Max iteration multiplier      = 1
  set Residual                      = 1e-6
  set Max iterations Newton-Raphson = 10
  set Tolerance displacement        = 1.0e-6
  set Tolerance force               = 1.0e-9
end

subsection precice configuration
  set Scenario            = PF
  set precice config-file = ../precice-config.xml
  set Participant name    = {{participant}}
  set Mesh name           = {{mesh}}
  # Force (nodal forces) on the coupling mesh.
  set Read data name      = {{write}}
  set Write data name     = {{read}}
end
"""
