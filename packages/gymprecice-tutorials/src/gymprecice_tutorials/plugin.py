"""The tutorials' gymprecice plugin: the tutorial envs' Gymnasium ids and lab cards.

Loaded through the ``gymprecice`` entry point on every ``import gymprecice``, so it must
stay light: environment classes are named by ``"module:Class"`` strings (Gymnasium imports
them only in ``make``). The lab's commands (``gymprecice train``, ``evaluate``, ...) come
from ``gymprecice-lab`` (the ``train`` extra), which reads the cards registered here.
"""

from __future__ import annotations

from collections.abc import Callable

from gymprecice.hookspecs import hookimpl
from gymprecice_tutorials.environments import ENVIRONMENTS

__all__ = ["gymprecice_register_environments"]


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    for env_id, entry_point, card in ENVIRONMENTS:
        register(env_id, entry_point, card=card)
