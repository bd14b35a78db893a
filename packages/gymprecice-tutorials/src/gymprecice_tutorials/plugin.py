"""The tutorials' gymprecice plugin: the tutorial envs' Gymnasium ids and lab cards.

Loaded through the ``gymprecice`` entry point on every ``import gymprecice``, so it must
stay light: environment classes are named by ``"module:Class"`` strings (Gymnasium imports
them only in ``make``). The lab's commands (``gymprecice train``, ``evaluate``, ...) come
from ``gymprecice-lab`` (the ``train`` extra), which reads the cards registered here.

Nothing here imports ``gymprecice`` when the module is imported, and the table is built
inside the hook: whichever module a program imports first (this one, the table, an env
class or ``gymprecice``), the hook runs when ``gymprecice`` registers its plugins and finds
everything it needs whole, so ``gymnasium.make`` knows the tutorials' ids right after.
(Importing ``gymprecice.plugin.hookspecs`` here would work too, but were this module the
first import, gymprecice would meet it half imported and register it only at the next
use of its plugin manager: :mod:`gymprecice.plugin.manager`.)
"""

from __future__ import annotations

from collections.abc import Callable

import pluggy

__all__ = ["gymprecice_register_environments"]

#: ``gymprecice.hookspecs.hookimpl``: the same marker, made without importing gymprecice
hookimpl = pluggy.HookimplMarker("gymprecice")


@hookimpl
def gymprecice_register_environments(register: Callable[..., None]) -> None:
    from gymprecice_tutorials.environments import environments

    for env_id, entry_point, card in environments():
        register(env_id, entry_point, card=card)
