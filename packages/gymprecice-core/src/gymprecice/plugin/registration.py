"""Register the plugins' Gymnasium environments (done on ``import gymprecice``).

Gymnasium 1.x no longer discovers environments through entry points, so gymprecice does it
for its plugins: each plugin's ``gymprecice_register_environments(register)`` hook is
called with a ``register(id, entry_point, *, card=None, **kwargs)`` callable that forwards
to :func:`gymnasium.register`; ``card`` is the env's lab card (:mod:`gymprecice.card`),
checked here and kept for the lab's commands. After ``import gymprecice``::

    gymnasium.make("gymprecice/JetCylinder-v0")
    # the "gymprecice:" prefix imports gymprecice first
    gymnasium.make("gymprecice:gymprecice/JetCylinder-v0")

Importing gymprecice must stay fast and must survive a broken plugin, so:

* plugins should pass ``entry_point`` as a ``"module:Class"`` string: Gymnasium imports the
  environment module only in ``make``; the plugin module itself (loaded through its entry
  point) must keep heavy imports (solvers' Python bindings, torch, plotting) inside
  functions;
* every plugin's hook is called on its own, and one that raises is reported with a
  :class:`~gymprecice.plugins.PluginWarning` naming it; the other plugins' environments
  are still registered;
* an id that is registered already (by an earlier call, or by the user) is left alone, so
  registering twice is harmless and a user's own registration wins.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

from gymprecice.plugin.card import CardError, record_card
from gymprecice.plugin.manager import (
    GymPrecicePluginManager,
    PluginWarning,
    get_plugin_manager,
    on_late_plugins,
)

__all__ = ["register_environments", "registered_environments"]

#: environment id -> name of the plugin that registered it (this process)
_registered: dict[str, str] = {}


def registered_environments() -> dict[str, str]:
    """Environment ids gymprecice registered, each with the plugin that provided it."""
    return dict(_registered)


def register_environments(
    pm: GymPrecicePluginManager | None = None, only: list[str] | None = None
) -> list[str]:
    """Call every plugin's ``gymprecice_register_environments`` (``only``: the plugins of
    these names); return the new ids.

    Safe to call again (for example after :func:`~gymprecice.plugins.register_plugin`):
    ids that exist already are skipped.
    """
    import gymnasium

    pm = pm or get_plugin_manager()
    added: list[str] = []
    # Same order pluggy would call them in: the most recently registered plugin first.
    for impl in reversed(pm.hook.gymprecice_register_environments.get_hookimpls()):
        if only is not None and impl.plugin_name not in only:
            continue
        register = _registrar(gymnasium, impl.plugin_name, added)
        try:
            impl.function(**_arguments(impl.argnames, register=register))
        except Exception as exc:
            warnings.warn(
                f"gymprecice plugin {impl.plugin_name!r} failed to register its environments "
                f"({type(exc).__name__}: {exc}); environments it registered before the error "
                "remain available",
                PluginWarning,
                stacklevel=2,
            )
    return added


def _registrar(gymnasium: Any, plugin_name: str, added: list[str]) -> Callable[..., None]:
    def register(id: str, entry_point: Any = None, *, card: Any = None, **kwargs: Any) -> None:
        try:
            # Checked even when the id exists already: a malformed card is refused at load.
            record_card(id, card, plugin_name)
        except CardError as exc:
            # The env itself is still registered; the lab reports the refusal for it.
            warnings.warn(str(exc), PluginWarning, stacklevel=3)
        if id in gymnasium.registry:
            return
        gymnasium.register(id=id, entry_point=entry_point, **kwargs)
        _registered[id] = plugin_name
        added.append(id)

    return register


def _arguments(argnames: tuple[str, ...], **available: Any) -> dict[str, Any]:
    """Pass only the hook arguments an implementation declares (pluggy allows fewer)."""
    return {name: available[name] for name in argnames if name in available}


def _register_late(pm: GymPrecicePluginManager, names: list[str]) -> None:
    """The environments of plugins registered late (met half imported, then finished)."""
    register_environments(pm, only=names)


on_late_plugins(_register_late)
