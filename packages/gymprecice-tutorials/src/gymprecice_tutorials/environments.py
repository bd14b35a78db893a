"""The tutorial environments: their Gymnasium ids, classes and lab cards, in one table.

The plugin (``plugin.py``) registers each row of :func:`environments` with ``register(id,
entry_point, card=card)``, the public route every environment package takes: ``gymprecice
train``, ``evaluate``, ``benchmark`` and the other lab commands (``gymprecice-lab``) read
these cards and nothing else of the tutorials. Every field a command reads is written out
here (the cylinders' shared fields once, in ``cylinder``), also where it equals the card's
default, so that the table alone says how the lab treats each env.

Kept free of plugin machinery and of anything heavy: ``plugin.py`` is loaded on every
``import gymprecice``. The table is built by a function, on first use, not when this
module is imported: building it imports :mod:`gymprecice.card`, and so ``gymprecice``,
which registers every plugin's envs; were the table built at import, importing this
module before ``gymprecice`` would meet the plugin asking for a table half built.
``ENVIRONMENTS`` and ``FAST_CYLINDER_FLOOR`` are still module attributes, built when
first read.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gymprecice.plugin.card import EnvCard, Reference

#: ENVIRONMENTS and FAST_CYLINDER_FLOOR come from ``__getattr__``, built when first read
__all__ = [
    "ENVIRONMENTS",  # noqa: F822
    "FAST_CYLINDER_FLOOR",  # noqa: F822
    "POLICIES",
    "environments",
    "fast_cylinder_floor",
]


#: the training case of the jet and rotating cylinders (3,580 cells): the uncontrolled mean
#: drag over 10 s from a held-out start, and the drag of the base flow of the mid-height
#: cylinder (docs/training.md); settled: after the first 2 s of transient
@functools.cache
def fast_cylinder_floor() -> Reference:
    """The drag floor of the fast cylinders' training case (``FAST_CYLINDER_FLOOR``)."""
    from gymprecice.plugin.card import Reference

    return Reference(
        metric="Cd", uncontrolled=3.2195, floor=2.9755, settle_time=2.0, label="drag floor"
    )


#: the package folder of the shipped policies (``gymprecice policies``)
POLICIES = "gymprecice_tutorials:policies"

#: the ``gymprecice doctor`` checks the cylinders need: OpenFOAM and its preCICE adapter,
#: blockMesh and, for the two-process cases, decomposePar and mpirun
_CYLINDER_CHECKS = ("pyprecice", "openfoam", "blockmesh", "decomposepar", "mpirun")
#: the training cases run one solver rank: no decomposePar, no mpirun
_ONE_RANK_CHECKS = ("pyprecice", "openfoam", "blockmesh")
_FLAP_CHECKS = ("pyprecice", "openfoam", "deal.ii", "elasticity")
#: a flap or plate made with ``solid="fenics"`` runs FEniCS instead of deal.II / OpenFOAM
_FENICS_FLAP = {"solid=fenics": ("pyprecice", "openfoam", "fenics")}
_FENICS_PLATE = {"solid=fenics": (*_ONE_RANK_CHECKS, "fenics")}
#: FSI3's episodes from starts run the FEniCS bar (the deal.II program cannot restart)
#: beside OpenFOAM's fluid, its mesh from blockMesh
_FSI3_CHECKS = (*_ONE_RANK_CHECKS, "fenics")


@functools.cache
def environments() -> tuple[tuple[str, str, EnvCard], ...]:
    """``(id, "module:Class", lab card)`` of every tutorial environment."""
    from dataclasses import replace

    from gymprecice.plugin.card import EnvCard
    from gymprecice_tutorials.turek_hron.reference import PUBLISHED

    floor = fast_cylinder_floor()
    # what every cylinder's card says alike: its force coefficients, the lift as the signal a
    # classical law feeds back, the shipped policies, the test double, recipe episodes, 10 s
    # evaluations and forcing near the shedding frequency (each row adds or overrides)
    cylinder = EnvCard(
        metrics=("Cd", "Cl"),
        feedback_signal="Cl",
        policies=POLICIES,
        double=True,
        episode_time=True,
        rollout_time=10.0,
        open_loop_frequency=3.0,
    )
    return (
        (
            "gymprecice/JetCylinder-v0",
            "gymprecice_tutorials.jet_cylinder.environment:JetCylinderEnv",
            replace(
                cylinder,
                name="jet-cylinder",
                description="two synthetic jets on a cylinder at Re = 100 (Rabault et al. 2019)",
                action_unit="m³/s",
                action_bound=2.5e-4,
                solver_checks=_CYLINDER_CHECKS,
                training_case="jet-cylinder-fast",
            ),
        ),
        (
            "gymprecice/RotatingCylinder-v0",
            "gymprecice_tutorials.rotating_cylinder.environment:RotatingCylinderEnv",
            replace(
                cylinder,
                name="rotating-cylinder",
                description="a rotating cylinder at Re = 100, the action is its angular velocity",
                action_unit="rad/s",
                action_bound=5.0,
                solver_checks=_CYLINDER_CHECKS,
                training_case="rotating-cylinder-fast",
            ),
        ),
        (
            "gymprecice/JetCylinderFast-v0",
            "gymprecice_tutorials.fast_cases:JetCylinderFastEnv",
            replace(
                cylinder,
                name="jet-cylinder-fast",
                description="the jet cylinder's training case: coarse mesh, 1 s episodes from "
                "eight start snapshots, Rabault's reward and jet bound",
                held_out_starts=True,
                validation_starts=True,
                reference=floor,
                action_unit="m³/s",
                action_bound=2.5e-5,
                solver_checks=_ONE_RANK_CHECKS,
            ),
        ),
        (
            "gymprecice/RotatingCylinderFast-v0",
            "gymprecice_tutorials.fast_cases:RotatingCylinderFastEnv",
            replace(
                cylinder,
                name="rotating-cylinder-fast",
                description="the rotating cylinder on the jet cylinder's training case",
                held_out_starts=True,
                validation_starts=True,
                reference=floor,
                action_unit="rad/s",
                action_bound=2.0,
                solver_checks=_ONE_RANK_CHECKS,
            ),
        ),
        (
            "gymprecice/Quickstart-v0",
            "gymprecice_tutorials.quickstart.environment:QuickstartEnv",
            replace(
                cylinder,
                name="quickstart",
                description="the jet cylinder on a coarse mesh with short episodes, to see "
                "the pipeline work on real OpenFOAM",
                rollout_time=2.0,
                action_unit="m³/s",
                action_bound=2.5e-4,
                solver_checks=_ONE_RANK_CHECKS,
            ),
        ),
        (
            "gymprecice/PerpendicularFlap-v0",
            "gymprecice_tutorials.perpendicular_flap.environment:PerpendicularFlapEnv",
            EnvCard(
                name="perpendicular-flap",
                description="an elastic flap in a channel (OpenFOAM + deal.II or FEniCS FSI), "
                "the action steers the inflow",
                # a jet as tall as the inlet is the packaged case's reference inflow, whatever
                # the action (the action space shrinks to the one centre, 2 m)
                uncontrolled={"jet_height": 4.0},
                policies=POLICIES,
                open_loop_frequency=0.5,
                action_unit="m",
                solver_checks=_FLAP_CHECKS,
                solver_checks_with=_FENICS_FLAP,
                training_case="perpendicular-flap-fast",
            ),
        ),
        (
            "gymprecice/PerpendicularFlapFast-v0",
            "gymprecice_tutorials.perpendicular_flap.fast:PerpendicularFlapFastEnv",
            EnvCard(
                name="perpendicular-flap-fast",
                description="the flap's training case: damp the swing after a gust (coarse FSI, "
                "3 s episodes from gust starts, three held out)",
                objective="mean_tip_displacement",
                held_out_starts=True,
                validation_starts=True,
                uncontrolled={"uncontrolled": True},
                policies=POLICIES,
                double=True,
                open_loop_frequency=0.6,
                action_unit="m",
                solver_checks=_FLAP_CHECKS,
                solver_checks_with=_FENICS_FLAP,
            ),
        ),
        (
            "gymprecice/HeatedPlate-v0",
            "gymprecice_tutorials.heated_plate.environment:HeatedPlateEnv",
            EnvCard(
                name="heated-plate",
                description="conjugate heat transfer: hold the plate's interface temperature "
                "with a heater (OpenFOAM fluid; OpenFOAM or FEniCS plate)",
                objective="tracking_error",
                held_out_starts=True,
                validation_starts=True,
                uncontrolled={"uncontrolled": True},
                feedback_law="gymprecice_tutorials.heated_plate.pid:PID_LAW",
                policies=POLICIES,
                shipped_policy="heated-plate-fast",
                training_case="heated-plate-fast",
                double=True,
                open_loop_frequency=0.5,
                action_unit="K",
                # the OpenFOAM plate by default; solid="fenics" needs the FEniCS solver env
                solver_checks=_ONE_RANK_CHECKS,
                solver_checks_with=_FENICS_PLATE,
            ),
        ),
        (
            "gymprecice/HeatedPlateFast-v0",
            "gymprecice_tutorials.heated_plate.fast:HeatedPlateFastEnv",
            EnvCard(
                name="heated-plate-fast",
                description="the heated plate's training case: a coarser fluid and explicit "
                "coupling, 3.5 s an episode (the task and starts of heated-plate)",
                objective="tracking_error",
                held_out_starts=True,
                validation_starts=True,
                uncontrolled={"uncontrolled": True},
                feedback_law="gymprecice_tutorials.heated_plate.pid:PID_LAW",
                policies=POLICIES,
                double=True,
                open_loop_frequency=0.5,
                action_unit="K",
                solver_checks=_ONE_RANK_CHECKS,
            ),
        ),
        (
            # Two flaps, four participants. The PettingZoo env (one agent per flap) is
            # gymprecice_tutorials.two_flaps.fast.TwoFlapsFastEnv, which Gymnasium cannot make;
            # this id is its single-controller view (both slots, both flaps' mean), what the
            # single-agent lab commands can run and a shared policy is compared with.
            "gymprecice/TwoFlapsFast-v0",
            "gymprecice_tutorials.two_flaps.fast:TwoFlapsJointEnv",
            EnvCard(
                name="two-flaps-fast",
                description="two flaps in one channel (OpenFOAM + two deal.II solids), one floor "
                "slot each: damp both after a gust; one controller for both slots, or one "
                "policy both flaps share (train --shared-policy)",
                objective="mean_tip_displacement",
                held_out_starts=True,
                validation_starts=True,
                uncontrolled={"uncontrolled": True},
                feedback_law="gymprecice_tutorials.two_flaps.feedback:TIP_LAW",
                double=True,
                episode_time=True,
                open_loop_frequency=0.6,
                action_unit="x 10 m/s",
                solver_checks=_FLAP_CHECKS,
                agents=("upstream", "downstream"),
                policies=POLICIES,
            ),
        ),
        (
            # Episodes from a library of the swinging state, built once by a long
            # uncontrolled run (turek_hron/build_starts.py); made without one, the env
            # says where it looked and how to build it.
            "gymprecice/TurekHronFSI3-v0",
            "gymprecice_tutorials.turek_hron.environment:TurekHronControlEnv",
            EnvCard(
                name="turek-hron-fsi3",
                description="Turek and Hron's FSI3 (OpenFOAM + FEniCS bar): two jets on the "
                "cylinder damp the elastic bar's swing without raising the drag, 1 s "
                "episodes from a library of the swinging state",
                objective="cost",
                metrics=("mean_abs_tip_dy", "drag"),
                held_out_starts=True,
                validation_starts=True,
                uncontrolled={"uncontrolled": True},
                policies=POLICIES,
                episode_time=True,
                # forcing at the bar's swing, the benchmark's frequency of the tip's dy
                open_loop_frequency=PUBLISHED["tip_dy_frequency"].value,
                action_unit="m³/s",
                solver_checks=_FSI3_CHECKS,
            ),
        ),
    )


def __getattr__(name: str) -> Any:
    """``ENVIRONMENTS`` and ``FAST_CYLINDER_FLOOR``, built on first use."""
    if name == "ENVIRONMENTS":
        return environments()
    if name == "FAST_CYLINDER_FLOOR":
        return fast_cylinder_floor()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
