"""The tutorials' gymprecice plugin: Gymnasium ids of the tutorial envs, and CLI commands.

Loaded through the ``gymprecice`` entry point on every ``import gymprecice``, so it must
stay light: environment classes are named by ``"module:Class"`` strings (Gymnasium imports
them only in ``make``), and the command implementations (SB3, torch, matplotlib) are
imported only when a command runs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from gymprecice.hookspecs import hookimpl
from gymprecice_tutorials.environments import ENVIRONMENTS, TutorialEnv, find_environment

__all__ = ["ENVIRONMENTS", "TutorialEnv", "find_environment"]


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    for env in ENVIRONMENTS.values():
        register(env.env_id, env.entry_point)


@hookimpl
def gymprecice_register_commands(subparsers: Any) -> None:
    from gymprecice_tutorials.cli import add_commands

    add_commands(subparsers)
