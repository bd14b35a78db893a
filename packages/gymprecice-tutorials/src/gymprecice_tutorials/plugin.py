"""The tutorials' gymprecice plugin: Gymnasium ids of the tutorial envs, and CLI commands.

Loaded through the ``gymprecice`` entry point on every ``import gymprecice``, so it must
stay light: environment classes are named by ``"module:Class"`` strings (Gymnasium imports
them only in ``make``), and the command implementations (SB3, torch, matplotlib) are
imported only when a command runs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from gymprecice.hookspecs import hookimpl

__all__ = ["ENVIRONMENTS", "TutorialEnv", "find_environment"]


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
        ),
        TutorialEnv(
            "quickstart",
            "gymprecice/Quickstart-v0",
            "gymprecice_tutorials.quickstart.environment:QuickstartEnv",
            "the jet cylinder on a coarse mesh with short episodes (minutes on 2 cores)",
        ),
        TutorialEnv(
            "perpendicular-flap",
            "gymprecice/PerpendicularFlap-v0",
            "gymprecice_tutorials.perpendicular_flap.environment:PerpendicularFlapEnv",
            "an elastic flap in a channel (OpenFOAM + deal.II FSI), the action steers the inflow",
            double=False,
            recipe=False,
            open_loop_frequency=0.5,
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


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    for env in ENVIRONMENTS.values():
        register(env.env_id, env.entry_point)


@hookimpl
def gymprecice_register_commands(subparsers: Any) -> None:
    from gymprecice_tutorials.cli import add_commands

    add_commands(subparsers)
