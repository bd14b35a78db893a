"""The tutorials' gymprecice plugin: the tutorial envs' Gymnasium ids and lab cards.

Loaded through the ``gymprecice`` entry point on every ``import gymprecice``, so it must
stay light: environment classes are named by ``"module:Class"`` strings (Gymnasium imports
them only in ``make``). The lab's commands (``gymprecice train``, ``evaluate``, ...) come
from ``gymprecice-lab`` (the ``train`` extra), which reads the cards registered here.

The ids are also declared in the distribution's metadata (the
``gymprecice.environments`` entry points in ``pyproject.toml``), so ``gymnasium.make``
knows them right after ``import gymprecice`` even when a program imports this module
first (gymprecice then meets it half imported and registers its hook at the next use of
its plugin manager: :mod:`gymprecice.plugin.registration`).
"""

from __future__ import annotations

from collections.abc import Callable

from gymprecice.plugin import hookimpl

__all__ = ["gymprecice_register_environments"]


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    from gymprecice_tutorials.environments import environments

    for env_id, entry_point, card in environments():
        register(env_id, entry_point, card=card)
