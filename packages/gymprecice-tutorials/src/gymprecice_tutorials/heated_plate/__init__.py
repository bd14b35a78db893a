"""Heated plate: conjugate heat transfer held at a setpoint by a heater under the plate.

The case of preCICE's flow-over-heated-plate tutorial (a 1 x 0.25 plate under a channel
flow of 0.1 m/s at 300 K) with the plate's bottom, held at 310 K in the tutorial, turned
into a heater that the controller drives, and the inflow velocity turned into the
disturbance. Three preCICE participants: the fluid (OpenFOAM buoyantPimpleFoam,
``fluid-openfoam/``), the plate (OpenFOAM laplacianFoam, ``solid-openfoam/``, or a FEniCS
script through fenicsprecice, ``solid-fenics/``: the env's ``solid`` option) and the
environment itself.

Files of the case, in ``case/`` next to this module: ``gymprecice-config.json`` (with the
OpenFOAM plate), ``precice-config.xml`` and the three solver directories (no mesh:
``system/blockMeshDict`` generates it; the FEniCS script builds its own). The environment
is :class:`~.environment.HeatedPlateEnv`.
"""

from pathlib import Path

#: directory holding the case (``gymprecice-config.json`` and the solver directories)
CASE_DIR = Path(__file__).resolve().parent / "case"
