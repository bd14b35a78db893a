"""Perpendicular flap: fluid-structure interaction steered by a moving inlet jet.

The case of preCICE's perpendicular-flap tutorial (an elastic flap, 0.1 wide and 1 tall,
on the floor of a 6 x 4 channel), with the uniform inflow replaced by a parabolic jet
whose centre the controller moves along the inlet. Three preCICE participants: the fluid
(OpenFOAM pimpleFoam on a moving mesh, ``fluid-openfoam/``), the solid (the deal.II-preCICE
adapter's ``elasticity``, ``solid-dealii/``, or a FEniCS script coupled through
fenicsprecice, ``solid-fenics/``) and the environment itself.

Files of the case, in ``case/`` next to this module (so that a run directory, a copy of
the case, holds no Python modules of this package): ``gymprecice-config.json`` (it names
the deal.II solid; :mod:`.packaged_case` swaps it), ``precice-config.xml``,
``solid-dealii/parameters.prm``, ``solid-fenics/`` (``solid.py``, run by the FEniCS
interpreter, and ``precice-adapter-config.json``) and ``fluid-openfoam/`` (no mesh:
``system/blockMeshDict`` generates it). The environment is
:class:`~.environment.PerpendicularFlapEnv`.
"""

from pathlib import Path

#: directory holding the case (``gymprecice-config.json`` and the solver directories)
CASE_DIR = Path(__file__).resolve().parent / "case"
