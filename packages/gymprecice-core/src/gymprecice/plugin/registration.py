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

A distribution may also declare its ids in its metadata, in the entry-point group
``gymprecice.environments`` (the name is the id, the value the ``"module:Class"``)::

    [project.entry-points."gymprecice.environments"]
    "gymprecice/MyEnv-v0" = "my_env.env:MyEnv"

Those ids are registered first, from the metadata alone, before any plugin module is
imported: so ``gymnasium.make`` knows them right after ``import gymprecice``, whichever
module a program imports first (a plugin module met half imported registers its hook's
ids and cards only at the next use of the plugin manager, :mod:`gymprecice.plugin.manager`).
When the plugin's hook then registers the same id, its registration (with its keyword
arguments) takes the declared one's place; the card comes from the hook, as before.
"""

from __future__ import annotations

import importlib.metadata
import warnings
from collections.abc import Callable
from typing import Any

from gymprecice.plugin.card import CardError, record_card
from gymprecice.plugin.manager import (
    ENTRY_POINT_GROUP,
    GymPrecicePluginManager,
    PluginWarning,
    disabled_by_environment,
    get_plugin_manager,
    on_late_plugins,
)

__all__ = [
    "ENVIRONMENTS_GROUP",
    "declared_environments",
    "register_declared_environments",
    "register_environments",
    "registered_environments",
]

#: Entry-point group in which a distribution declares its ids: ``"id" = "module:Class"``.
ENVIRONMENTS_GROUP = "gymprecice.environments"

#: environment id -> name of the plugin that registered it (this process)
_registered: dict[str, str] = {}
#: id -> entry point, of the ids registered from metadata that no hook has registered yet
_declared: dict[str, str] = {}


def registered_environments() -> dict[str, str]:
    """Environment ids gymprecice registered, each with the plugin that provided it."""
    return dict(_registered)


def declared_environments() -> dict[str, tuple[str, str]]:
    """The ids installed distributions declare in ``gymprecice.environments``: id ->
    (``"module:Class"``, the plugin's name: its ``gymprecice`` entry point's, else the
    distribution's). Distributions blocked by ``GYMPRECICE_DISABLE_PLUGINS`` are left out;
    of a distribution seen twice (an editable install), the first one."""
    declared: dict[str, tuple[str, str]] = {}
    for dist in importlib.metadata.distributions():
        ids = [ep for ep in dist.entry_points if ep.group == ENVIRONMENTS_GROUP]
        if not ids:
            continue
        plugins = [ep.name for ep in dist.entry_points if ep.group == ENTRY_POINT_GROUP]
        if disabled_by_environment(plugins, dist):
            continue
        name = plugins[0] if plugins else (dist.metadata["Name"] or "?")
        for ep in ids:
            declared.setdefault(ep.name.strip(), (ep.value.strip(), name))
    return declared


def register_declared_environments() -> list[str]:
    """Register the ids of :func:`declared_environments` with Gymnasium, importing no
    plugin module; return the new ones. An id registered already is left alone."""
    import gymnasium

    added = []
    for env_id, (entry_point, plugin_name) in declared_environments().items():
        if env_id in gymnasium.registry:
            continue
        try:
            gymnasium.register(id=env_id, entry_point=entry_point)
        except Exception as exc:
            warnings.warn(
                f"gymprecice plugin {plugin_name!r} declares the environment id {env_id!r} "
                f"({ENVIRONMENTS_GROUP!r} entry points), which Gymnasium refuses: {exc}",
                PluginWarning,
                stacklevel=2,
            )
            continue
        _declared[env_id] = entry_point
        _registered[env_id] = plugin_name
        added.append(env_id)
    return added


def register_environments(
    pm: GymPrecicePluginManager | None = None, only: list[str] | None = None
) -> list[str]:
    """Call every plugin's ``gymprecice_register_environments`` (``only``: the plugins of
    these names); return the new ids. Without ``pm`` and ``only`` (as on ``import
    gymprecice``), the ids declared in metadata are registered first.

    Safe to call again (for example after :func:`~gymprecice.plugins.register_plugin`):
    ids that exist already are skipped.
    """
    import gymnasium

    added: list[str] = []
    if pm is None and only is None:
        added += register_declared_environments()
    pm = pm or get_plugin_manager()
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
            if _declared.get(id) != gymnasium.registry[id].entry_point:
                return  # registered by a hook, or by the user: theirs stays
            # declared in metadata: the hook's registration (its kwargs) takes its place
            del gymnasium.registry[id]
            _declared.pop(id)
        gymnasium.register(id=id, entry_point=entry_point, **kwargs)
        _registered[id] = plugin_name
        if id not in added:
            added.append(id)

    return register


def _arguments(argnames: tuple[str, ...], **available: Any) -> dict[str, Any]:
    """Pass only the hook arguments an implementation declares (pluggy allows fewer)."""
    return {name: available[name] for name in argnames if name in available}


def _register_late(pm: GymPrecicePluginManager, names: list[str]) -> None:
    """The environments of plugins registered late (met half imported, then finished)."""
    register_environments(pm, only=names)


on_late_plugins(_register_late)
