"""gymprecice plugin for FEniCS participants (legacy FEniCS with the fenicsprecice adapter).

The plugin module is :mod:`gymprecice_fenics.plugin`; the solver environment it launches
scripts in (Debian's dolfin, numpy 1.x, pyprecice built against the stack, fenicsprecice)
is described and built by :mod:`gymprecice_fenics.solver_env`.
"""

__version__ = "0.1.0"
