"""The tutorial environments: one table that the plugin, the commands and the API read.

Kept free of gymprecice's plugin machinery and of the commands, so that ``plugin.py``
(loaded on every ``import gymprecice``) and ``cli.py`` / ``train.py`` / ``evaluate.py``
each import it without importing one another.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ENVIRONMENTS", "DragFloor", "TutorialEnv", "find_environment"]


@dataclass(frozen=True)
class DragFloor:
    """Where a cylinder's drag can go by suppressing the shedding, as measured.

    ``floor_cd`` is the drag of the case's steady, symmetric base flow
    (:mod:`gymprecice_tutorials.base_flow`), ``uncontrolled_cd`` the developed shedding's
    mean drag; a controller's *fraction of the floor* is how much of the drop between
    them it takes, ``(uncontrolled_cd - Cd) / (uncontrolled_cd - floor_cd)``: 1 is the
    whole drop. *Settled* drag leaves out the first ``settle_time`` seconds of an
    episode, the transient out of the developed shedding.
    """

    uncontrolled_cd: float
    floor_cd: float
    settle_time: float = 2.0

    def fraction(self, cd: float) -> float:
        """The fraction of the floor's drop that a mean drag ``cd`` reaches."""
        return (self.uncontrolled_cd - cd) / (self.uncontrolled_cd - self.floor_cd)


#: the training case of the jet and rotating cylinders (3,580 cells): the uncontrolled mean
#: over 10 s from a held-out start, the base flow of the mid-height cylinder (docs/training.md)
FAST_CYLINDER_FLOOR = DragFloor(uncontrolled_cd=3.2195, floor_cd=2.9755)


@dataclass(frozen=True)
class TutorialEnv:
    """One tutorial environment: its command-line name, Gymnasium id and class."""

    name: str
    env_id: str
    entry_point: str
    description: str
    #: whether ``gymprecice train --double`` can run it on the test double's fake flow
    double: bool = True
    #: whether it is built from a case recipe (accepts ``episode_time``, ``double``, ...)
    recipe: bool = True
    #: ``gymprecice open-loop``'s default forcing frequency (Hz): near the cylinders'
    #: shedding frequency; well below the flap's 10 actions per second
    open_loop_frequency: float = 3.0
    #: ``evaluate`` / ``baseline`` / ``open-loop``'s default simulated seconds per episode:
    #: longer than a training episode, to show that control holds (``None``: the case's)
    rollout_time: float | None = 10.0
    #: the action in the env's own units, as figures label it, and its bound (``None``:
    #: none to draw); the jets' flow rate and the cylinder's spin are symmetric boxes
    action_unit: str = "m³/s"
    action_bound: float | None = 2.5e-4
    #: the per-action metric (``info["metrics"]``) that ``gymprecice sweep`` compares
    #: controllers on, lower is better (``None``: the negated mean reward)
    objective: str | None = None
    #: keyword arguments that make the env's uncontrolled flow, where no action means it
    #: (``gymprecice baseline`` and ``sweep`` add them)
    baseline_kwargs: tuple[tuple[str, object], ...] = ()
    #: whether its packaged case keeps starts out of training (``held_out_starts``), the
    #: starts ``gymprecice benchmark`` evaluates every controller on
    held_out_starts: bool = False
    #: ``gymprecice feedback``'s default signal: the ``info["metrics"]`` entry fed back
    #: (``None``: none; the command then needs ``--signal``)
    feedback_signal: str | None = "Cl"
    #: the shipped policy that ``--policy shipped`` means on this env (``None``: the one
    #: named after it); an env evaluated with the policy of its training case names it
    shipped_policy: str | None = None
    #: the drag floor that ``evaluate`` and ``benchmark`` measure a cylinder controller
    #: against (``None``: not measured for this env)
    drag_floor: DragFloor | None = None
    #: ``"module:attribute"`` of the env's own classical feedback family
    #: (:class:`~gymprecice_tutorials.feedback.FeedbackLaw`), which ``sweep`` and
    #: ``benchmark`` tune instead of the lift fed back (``None``: the lift's law)
    feedback_law: str | None = None


ENVIRONMENTS: dict[str, TutorialEnv] = {
    env.name: env
    for env in (
        TutorialEnv(
            "jet-cylinder",
            "gymprecice/JetCylinder-v0",
            "gymprecice_tutorials.jet_cylinder.environment:JetCylinderEnv",
            "two synthetic jets on a cylinder at Re = 100 (Rabault et al. 2019)",
        ),
        TutorialEnv(
            "rotating-cylinder",
            "gymprecice/RotatingCylinder-v0",
            "gymprecice_tutorials.rotating_cylinder.environment:RotatingCylinderEnv",
            "a rotating cylinder at Re = 100, the action is its angular velocity",
            action_unit="rad/s",
            action_bound=5.0,
        ),
        TutorialEnv(
            "jet-cylinder-fast",
            "gymprecice/JetCylinderFast-v0",
            "gymprecice_tutorials.fast_cases:JetCylinderFastEnv",
            "the jet cylinder's training case: coarse mesh, 1 s episodes from eight start "
            "snapshots, Rabault's reward and jet bound (PPO reaches 95 % of its drag floor "
            "in minutes on 2 cores: docs/benchmark.md)",
            action_bound=2.5e-5,
            held_out_starts=True,
            drag_floor=FAST_CYLINDER_FLOOR,
        ),
        TutorialEnv(
            "rotating-cylinder-fast",
            "gymprecice/RotatingCylinderFast-v0",
            "gymprecice_tutorials.fast_cases:RotatingCylinderFastEnv",
            "the rotating cylinder on the jet cylinder's training case",
            action_unit="rad/s",
            action_bound=2.0,
            held_out_starts=True,
            drag_floor=FAST_CYLINDER_FLOOR,
        ),
        TutorialEnv(
            "quickstart",
            "gymprecice/Quickstart-v0",
            "gymprecice_tutorials.quickstart.environment:QuickstartEnv",
            "the jet cylinder on a coarse mesh with short episodes (minutes on 2 cores)",
            rollout_time=2.0,
        ),
        TutorialEnv(
            "perpendicular-flap",
            "gymprecice/PerpendicularFlap-v0",
            "gymprecice_tutorials.perpendicular_flap.environment:PerpendicularFlapEnv",
            "an elastic flap in a channel (OpenFOAM + deal.II FSI), the action steers the inflow",
            double=False,
            recipe=False,
            open_loop_frequency=0.5,
            rollout_time=None,
            action_unit="m",
            action_bound=None,
            feedback_signal=None,
        ),
        TutorialEnv(
            "perpendicular-flap-fast",
            "gymprecice/PerpendicularFlapFast-v0",
            "gymprecice_tutorials.perpendicular_flap.fast:PerpendicularFlapFastEnv",
            "the flap's training case: damp the swing after a gust (coarse FSI, 3 s "
            "episodes from gust starts, three held out)",
            recipe=False,
            open_loop_frequency=0.6,
            rollout_time=None,
            action_unit="m",
            action_bound=None,
            objective="mean_tip_displacement",
            baseline_kwargs=(("uncontrolled", True),),
            held_out_starts=True,
            feedback_signal=None,
        ),
        TutorialEnv(
            "heated-plate",
            "gymprecice/HeatedPlate-v0",
            "gymprecice_tutorials.heated_plate.environment:HeatedPlateEnv",
            "conjugate heat transfer: hold the plate's interface temperature with a heater "
            "(OpenFOAM fluid; OpenFOAM or FEniCS plate)",
            shipped_policy="heated-plate-fast",
            recipe=False,
            open_loop_frequency=0.5,
            rollout_time=None,
            action_unit="K",
            action_bound=None,
            objective="tracking_error",
            baseline_kwargs=(("uncontrolled", True),),
            held_out_starts=True,
            feedback_signal=None,
            feedback_law="gymprecice_tutorials.heated_plate.pid:PID_LAW",
        ),
        TutorialEnv(
            "heated-plate-fast",
            "gymprecice/HeatedPlateFast-v0",
            "gymprecice_tutorials.heated_plate.fast:HeatedPlateFastEnv",
            "the heated plate's training case: a coarser fluid and explicit coupling, "
            "3.5 s an episode (the task and starts of heated-plate)",
            recipe=False,
            open_loop_frequency=0.5,
            rollout_time=None,
            action_unit="K",
            action_bound=None,
            objective="tracking_error",
            baseline_kwargs=(("uncontrolled", True),),
            held_out_starts=True,
            feedback_signal=None,
            feedback_law="gymprecice_tutorials.heated_plate.pid:PID_LAW",
        ),
    )
}


def find_environment(name: str) -> TutorialEnv:
    """Look an environment up by command-line name (``jet-cylinder``) or Gymnasium id."""
    key = name.strip()
    for env in ENVIRONMENTS.values():
        if key in (env.name, env.env_id, env.env_id.split("/", 1)[1]):
            return env
    raise KeyError(
        f"no tutorial environment {name!r}; choose one of {', '.join(ENVIRONMENTS)} "
        f"(or their ids {', '.join(e.env_id for e in ENVIRONMENTS.values())})"
    )
