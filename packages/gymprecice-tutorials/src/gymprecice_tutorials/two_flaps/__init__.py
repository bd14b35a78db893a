"""Two flaps in one channel: two agents, four preCICE participants.

The case of preCICE's multiple-perpendicular-flaps tutorial (two elastic flaps, 0.1 wide
and 1 tall, on the floor of a 6 x 4 channel at x = -1 and x = 1, a uniform 5 m/s inflow),
with a blowing and suction slot in the floor in front of each flap. Four preCICE
participants: the fluid (OpenFOAM pimpleFoam on a moving mesh, ``fluid-openfoam/``), the
two solids (the deal.II-preCICE adapter's ``elasticity``, ``solid-upstream-dealii/`` and
``solid-downstream-dealii/``) and the environment, in which each flap's slot is one agent.

Files of the case, in ``case/`` next to this module (so that a run directory, a copy of
the case, holds no Python modules). The environments: :class:`~.environment.TwoFlapsEnv`
(the packaged case) and :class:`~.fast.TwoFlapsFastEnv` (its training case, gust starts
and the test double).
"""

from pathlib import Path

#: directory holding the case (``gymprecice-config.json`` and the solver directories)
CASE_DIR = Path(__file__).resolve().parent / "case"
