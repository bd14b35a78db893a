"""Turek and Hron's FSI3: an elastic bar behind a cylinder in a channel, at Re = 200.

The benchmark of Turek & Hron (2006): the flow past the cylinder sheds vortices, and
the bar behind it, as dense as the fluid, swings at about 5.3 Hz. Three preCICE
participants: the fluid (OpenFOAM pimpleFoam on a moving mesh, ``fluid-openfoam/``),
the solid (the deal.II-preCICE adapter's ``elasticity`` in its FSI3 scenario,
``solid-dealii/``) and the environment, which drives two jets on the cylinder.

``case/`` holds the files that do not change; :mod:`.case` adds the mesh
(:mod:`.mesh`), the ramped inflow and the time step of a run. The environment is
:class:`~.environment.TurekHronEnv`; :mod:`.validate` compares the uncontrolled run
with the benchmark's published values (:mod:`.reference`), from the series
:mod:`.series` reads. Episodes can start from the swinging state instead of rest: a
library of saved fluid and bar states (:mod:`.starts`), built by one uncontrolled run
(:mod:`.build_starts`), with the FEniCS bar that restarts (``case/solid-fenics/``,
checked alone by :mod:`.solid_checks`).
"""

from pathlib import Path

#: directory holding the case's fixed files
CASE_DIR = Path(__file__).resolve().parent / "case"
