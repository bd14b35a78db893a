"""The plugin manager: finds gymprecice plugins and lets core call their hooks.

Plugins are found through the ``gymprecice`` entry-point group, as pytest, llm and
datasette find theirs::

    [project.entry-points.gymprecice]
    openfoam = "gymprecice_openfoam.plugin"

Loading is lazy and happens once: the first :func:`get_plugin_manager` call imports every
plugin module and registers it under its entry-point name; later calls return the same
manager. Core's own :mod:`gymprecice.default_plugin` (kinds ``"script"`` and
``"command"``) is declared as the entry point ``script`` of ``gymprecice-core`` and is
registered like any third-party plugin; when the distribution metadata is missing (running
from a source tree) it is registered directly, and never twice.

``GYMPRECICE_DISABLE_PLUGINS`` keeps third-party plugins out, for hermetic tests and for
ruling out a plugin while debugging: ``1`` (or ``all``) blocks every third-party entry
point, a comma list (``openfoam,gymprecice-dealii``) blocks those entry-point or
distribution names. Core's default plugin is always loaded, because the paper's
configuration form (solvers of kind ``"script"``) must keep working.

A plugin that fails to import or to register does not take gymprecice down with it: it
is reported with a :class:`PluginWarning` naming the plugin and its distribution, and
listed by :func:`plugin_failures` (``gymprecice plugins`` and ``gymprecice doctor`` show
it).

A plugin module may import ``gymprecice`` at its top, as any module does. When such a
module is the first thing a program imports, it is still half imported while
``gymprecice`` loads the plugins: its hooks are not defined yet, and pluggy would register
it without them. So a plugin module met half imported is *deferred*: it is registered,
and its environments with it (:mod:`gymprecice.plugin.registration`), at the next
:func:`get_plugin_manager` call once its import has finished, which every use of a hook
makes. The same holds when another module of the plugin's package comes first
(``from my_plugin.helpers import x``, with ``helpers`` importing gymprecice): the plugin
module then fails on a name ``helpers`` has not defined yet, and is imported again once
``helpers`` has finished.
"""

from __future__ import annotations

import difflib
import importlib.metadata
import os
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, NamedTuple

import pluggy

from gymprecice.plugin import hookspecs

#: Entry-point group (and pluggy project name) of gymprecice plugins.
ENTRY_POINT_GROUP = hookspecs.PROJECT_NAME
#: Environment variable that blocks third-party plugins (``1``/``all`` or a comma list).
DISABLE_ENV_VAR = "GYMPRECICE_DISABLE_PLUGINS"
#: Core's default plugin module, and the entry-point name core declares for it. The
#: module's old path, which core's entry point names: an alias of its home.
DEFAULT_PLUGIN_MODULE = "gymprecice.default_plugin"
DEFAULT_PLUGIN_NAME = "script"
_DEFAULT_PLUGIN_HOME = "gymprecice.env.default_plugin"
#: Distribution that ships core (reported for the default plugin without metadata).
CORE_DISTRIBUTION = "gymprecice-core"

_ALL = frozenset({"1", "true", "yes", "on", "all", "*"})
_NONE = frozenset({"", "0", "false", "no", "off"})

__all__ = [
    "DEFAULT_PLUGIN_NAME",
    "DISABLE_ENV_VAR",
    "ENTRY_POINT_GROUP",
    "GymPrecicePluginManager",
    "PluginFailure",
    "PluginInfo",
    "PluginWarning",
    "SolverKind",
    "disabled_by_environment",
    "get_plugin_manager",
    "list_plugins",
    "on_late_plugins",
    "plugin_failures",
    "register_plugin",
    "reset_plugin_manager",
    "solver_kinds",
    "temporary_plugin",
    "unregister_plugin",
]


class PluginWarning(UserWarning):
    """A plugin could not be loaded, or one of its hooks misbehaved; gymprecice goes on."""


@dataclass(frozen=True)
class PluginInfo:
    """One registered plugin, as ``gymprecice plugins`` shows it."""

    name: str
    distribution: str | None
    version: str | None
    hooks: tuple[str, ...]
    module: str | None = None


@dataclass(frozen=True)
class PluginFailure:
    """An installed plugin that could not be loaded, with the reason."""

    name: str
    distribution: str | None
    version: str | None
    error: str


class SolverKind(NamedTuple):
    """A solver kind a plugin handles: its one-line description and the plugin's name."""

    description: str
    plugin: str


def _canonical(name: str) -> str:
    """Compare distribution and entry-point names the way packaging does (PEP 503)."""
    return name.strip().lower().replace("_", "-").replace(".", "-")


def _disabled_selector(value: str | None) -> bool | frozenset[str]:
    """Parse ``GYMPRECICE_DISABLE_PLUGINS``: ``True`` (all), ``False`` or a set of names."""
    if value is None or value.strip().lower() in _NONE:
        return False
    if value.strip().lower() in _ALL:
        return True
    return frozenset(_canonical(part) for part in value.split(",") if part.strip())


def disabled_by_environment(
    names: list[str], dist: importlib.metadata.Distribution, disable: str | None = None
) -> bool:
    """Whether ``GYMPRECICE_DISABLE_PLUGINS`` (or ``disable``, in its form) blocks a
    distribution's plugins: all of them, one of ``names`` (its entry-point names), or the
    distribution's own name."""
    selector = _disabled_selector(os.environ.get(DISABLE_ENV_VAR) if disable is None else disable)
    if isinstance(selector, bool):
        return selector
    dist_name = _dist_name(dist)
    wanted = {_canonical(name) for name in names}
    if dist_name is not None:
        wanted.add(_canonical(dist_name))
    return bool(wanted & selector)


def _dist_name(dist: importlib.metadata.Distribution) -> str | None:
    # ``Distribution.name`` is 3.10+; metadata may lack Name for broken installs.
    try:
        return dist.metadata["Name"] or None
    except Exception:
        return None


class GymPrecicePluginManager(pluggy.PluginManager):
    """A :class:`pluggy.PluginManager` that remembers where each plugin came from.

    Besides pluggy's registry it keeps the distribution of every entry-point plugin (for
    ``gymprecice plugins``) and the plugins that failed to load (for ``gymprecice doctor``).
    """

    def __init__(self) -> None:
        super().__init__(hookspecs.PROJECT_NAME)
        self.add_hookspecs(hookspecs)
        #: plugin name -> distribution it was loaded from
        self.distributions: dict[str, importlib.metadata.Distribution] = {}
        #: plugins that could not be loaded or registered
        self.failures: list[PluginFailure] = []
        #: plugin modules met half imported, waiting for their import to finish
        self.deferred: list[tuple[importlib.metadata.EntryPoint, Any, Any]] = []
        self.loaded = False

    # -- loading -------------------------------------------------------------------------

    def load_plugins(self, disable: str | None = None) -> int:
        """Register every plugin of the entry-point group, then core's default plugin.

        Mirrors :meth:`pluggy.PluginManager.load_setuptools_entrypoints` (skip names
        already registered or blocked, register under the entry-point name) but keeps the
        distribution of each plugin and turns a broken plugin into a warning: one bad
        package must not stop environments of the others from working. Calling it again
        only picks up plugins not seen before. Returns how many plugins it registered.
        """
        count = 0
        for dist in list(importlib.metadata.distributions()):
            for ep in dist.entry_points:
                if ep.group != ENTRY_POINT_GROUP:
                    continue
                if self.has_plugin(ep.name) or self.is_blocked(ep.name):
                    # The same distribution is often visible twice (an editable install's
                    # dist-info and the source tree's egg-info): the first one wins.
                    continue
                is_core = ep.value.split(":", 1)[0].strip() in (
                    DEFAULT_PLUGIN_MODULE,
                    _DEFAULT_PLUGIN_HOME,
                )
                if not is_core and disabled_by_environment([ep.name], dist, disable):
                    continue
                if self._load_entry_point(ep, dist):
                    count += 1
        count += self._ensure_default_plugin()
        self.loaded = True
        return count

    def _load_entry_point(
        self, ep: importlib.metadata.EntryPoint, dist: importlib.metadata.Distribution
    ) -> bool:
        try:
            plugin = ep.load()
        except Exception as exc:
            if _package_half_imported(ep):
                # a module of the plugin's own package is being imported further up the
                # stack (``from my_plugin.helpers import x`` before gymprecice), and the
                # plugin module failed on a name it has not defined yet: load it again
                # once that import has finished
                self.deferred.append((ep, dist, None))
                return False
            self._fail(ep.name, dist, f"cannot import {ep.value!r}: {type(exc).__name__}: {exc}")
            return False
        if _half_imported(plugin):
            # this very import is under way further up the stack: its hooks come later
            self.deferred.append((ep, dist, plugin))
            return False
        return self._register_loaded(ep, dist, plugin)

    def register_deferred(self) -> list[str]:
        """Register the deferred plugins whose import has finished; their names. A plugin
        whose module failed to import while its package was half imported is imported
        again now; failing again, it is reported as any broken plugin."""
        ready = [item for item in self.deferred if not _still_importing(item)]
        if not ready:
            return []
        self.deferred = [item for item in self.deferred if _still_importing(item)]
        names = []
        for ep, dist, plugin in ready:
            if plugin is None:
                try:
                    plugin = ep.load()
                except Exception as exc:
                    error = f"cannot import {ep.value!r}: {type(exc).__name__}: {exc}"
                    self._fail(ep.name, dist, error)
                    continue
            if self._register_loaded(ep, dist, plugin):
                names.append(ep.name)
        return names

    def _register_loaded(
        self, ep: importlib.metadata.EntryPoint, dist: importlib.metadata.Distribution, plugin: Any
    ) -> bool:
        if self.is_registered(plugin):
            # Declared under two names (or by two distributions): register it once only,
            # or every hook of it would answer twice.
            return False
        try:
            self.register(plugin, name=ep.name)
        except Exception as exc:
            # pluggy may have half-registered the plugin before validation failed.
            try:
                self.unregister(name=ep.name)
            except Exception:
                pass
            self._fail(ep.name, dist, f"{type(exc).__name__}: {exc}")
            return False
        self.distributions[ep.name] = dist
        return True

    def _ensure_default_plugin(self) -> int:
        """Register core's default plugin if no entry point brought it in."""
        from gymprecice.env import default_plugin

        if self.is_registered(default_plugin):
            return 0
        name = DEFAULT_PLUGIN_NAME
        if self.has_plugin(name) or self.is_blocked(name):
            # A third-party plugin took the entry-point name: keep core's under its module.
            name = DEFAULT_PLUGIN_MODULE
        self.register(default_plugin, name=name)
        return 1

    def _fail(self, name: str, dist: importlib.metadata.Distribution | None, error: str) -> None:
        dist_name = _dist_name(dist) if dist is not None else None
        version = dist.version if dist is not None else None
        self.failures.append(PluginFailure(name, dist_name, version, error))
        origin = f" (from {dist_name} {version})" if dist_name else ""
        warnings.warn(
            f"gymprecice plugin {name!r}{origin} could not be loaded and is skipped: {error}",
            PluginWarning,
            stacklevel=3,
        )

    # -- registration --------------------------------------------------------------------

    def register(self, plugin: Any, name: str | None = None) -> str | None:
        """Register ``plugin`` and warn about hook implementations no spec knows.

        pluggy accepts ``@hookimpl def gymprecice_solver_kind()`` silently and simply never
        calls it; a typo in a hook name is the commonest plugin bug, so name it here.
        """
        plugin_name = super().register(plugin, name)
        if plugin_name is not None:
            self._warn_unknown_hooks(plugin, plugin_name)
        return plugin_name

    def _warn_unknown_hooks(self, plugin: Any, plugin_name: str) -> None:
        known = sorted(
            name for name in vars(self.hook) if not name.startswith("_") and self._has_spec(name)
        )
        for caller in self.get_hookcallers(plugin) or []:
            if caller.has_spec():
                continue
            impls = [i for i in caller.get_hookimpls() if i.plugin is plugin]
            if all(i.optionalhook for i in impls):
                continue
            close = difflib.get_close_matches(caller.name, known, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; the hooks are {known}"
            warnings.warn(
                f"gymprecice plugin {plugin_name!r} implements {caller.name!r}, which is not "
                f"a gymprecice hook and will never be called{hint}",
                PluginWarning,
                stacklevel=4,
            )

    def _has_spec(self, name: str) -> bool:
        caller = getattr(self.hook, name, None)
        return caller is not None and caller.has_spec()

    # -- introspection -------------------------------------------------------------------

    def plugin_info(self, name: str, plugin: Any) -> PluginInfo:
        dist = self.distributions.get(name)
        module = getattr(plugin, "__name__", None) or type(plugin).__module__
        if module == _DEFAULT_PLUGIN_HOME:
            module = DEFAULT_PLUGIN_MODULE  # the name its entry point gives it
        if dist is not None:
            dist_name, version = _dist_name(dist), dist.version
        elif module == DEFAULT_PLUGIN_MODULE:
            from gymprecice.tools.distribution import core_version

            dist_name, version = CORE_DISTRIBUTION, core_version()
        else:
            dist_name = version = None
        hooks = tuple(sorted(c.name for c in self.get_hookcallers(plugin) or []))
        return PluginInfo(name, dist_name, version, hooks, module)


_lock = threading.RLock()
_manager: GymPrecicePluginManager | None = None
_loading: GymPrecicePluginManager | None = None


def _half_imported(plugin: Any) -> bool:
    """Whether ``plugin`` is a module whose import is still running (importlib marks its
    spec ``_initializing`` until the module's code has run to the end)."""
    spec = getattr(plugin, "__spec__", None)
    return bool(getattr(spec, "_initializing", False))


def _package_half_imported(ep: importlib.metadata.EntryPoint) -> bool:
    """Whether a module of the entry point's top-level package is half imported."""
    top = ep.value.split(":", 1)[0].strip().split(".", 1)[0]
    return any(
        _half_imported(module)
        for name, module in list(sys.modules.items())
        if name == top or name.startswith(f"{top}.")
    )


def _still_importing(item: tuple[Any, Any, Any]) -> bool:
    """Whether a deferred plugin must wait on: its module, or, where its import failed,
    a module of its package, is still half imported."""
    ep, _, plugin = item
    return _package_half_imported(ep) if plugin is None else _half_imported(plugin)


def get_plugin_manager() -> GymPrecicePluginManager:
    """Return the process-wide plugin manager, loading the plugins on the first call.

    Thread-safe and idempotent. A plugin module that itself calls this function while it
    is being imported gets the manager being filled (instead of a recursive load). Plugin
    modules deferred because they were half imported are registered here, with their
    environments, once their import has finished.
    """
    global _manager, _loading
    manager = _manager
    if manager is not None:
        if manager.deferred:
            _register_deferred(manager)
        return manager
    with _lock:
        if _manager is not None:
            return _manager
        if _loading is not None:  # re-entered from a plugin import in this thread
            return _loading
        manager = GymPrecicePluginManager()
        _loading = manager
        try:
            manager.load_plugins()
        finally:
            _loading = None
        _manager = manager
        return manager


#: called with the manager and the names of deferred plugins once they are registered
#: (:mod:`gymprecice.plugin.registration` registers their environments)
_late_plugin_listeners: list[Callable[[GymPrecicePluginManager, list[str]], object]] = []


def on_late_plugins(listener: Callable[[GymPrecicePluginManager, list[str]], object]) -> None:
    """Call ``listener(manager, names)`` whenever plugins deferred because they were half
    imported are registered (see the module's docstring)."""
    if listener not in _late_plugin_listeners:
        _late_plugin_listeners.append(listener)


def _register_deferred(manager: GymPrecicePluginManager) -> None:
    with _lock:
        names = manager.register_deferred()
    if names:
        for listener in list(_late_plugin_listeners):
            listener(manager, names)


def reset_plugin_manager() -> None:
    """Forget the manager: the next :func:`get_plugin_manager` call loads plugins anew.

    For tests that change ``GYMPRECICE_DISABLE_PLUGINS`` or ``sys.path``, and for an
    interpreter in which a plugin was installed after gymprecice loaded its plugins.
    """
    global _manager
    with _lock:
        _manager = None


def register_plugin(plugin: Any, name: str | None = None) -> str:
    """Register a plugin object or module by hand (tests, notebooks, local plugins).

    Returns the name it is registered under; raises :class:`ValueError` if that name or
    that plugin is registered already.
    """
    registered = get_plugin_manager().register(plugin, name=name)
    if registered is None:
        raise ValueError(f"the plugin name {name!r} is blocked by {DISABLE_ENV_VAR}")
    return registered


def unregister_plugin(plugin_or_name: Any) -> Any:
    """Remove a plugin (given by object or by name); returns it, or ``None`` if unknown."""
    pm = get_plugin_manager()
    if isinstance(plugin_or_name, str):
        return pm.unregister(name=plugin_or_name)
    if not pm.is_registered(plugin_or_name):
        return None
    return pm.unregister(plugin=plugin_or_name)


@contextmanager
def temporary_plugin(plugin: Any, name: str | None = None) -> Iterator[GymPrecicePluginManager]:
    """Register ``plugin`` for the duration of a ``with`` block (tests)::

    with temporary_plugin(MyPlugin(), "mine") as pm:
        pm.hook.gymprecice_launch_solver(solver=ctx)
    """
    pm = get_plugin_manager()
    registered = register_plugin(plugin, name)
    try:
        yield pm
    finally:
        pm.unregister(name=registered)


def list_plugins() -> list[PluginInfo]:
    """Every registered plugin with its distribution, version and implemented hooks."""
    pm = get_plugin_manager()
    infos = [pm.plugin_info(name, plugin) for name, plugin in pm.list_name_plugin() if plugin]
    return sorted(infos, key=lambda info: info.name)


def plugin_failures() -> list[PluginFailure]:
    """Installed plugins that could not be loaded (each was warned about once)."""
    return list(get_plugin_manager().failures)


def solver_kinds() -> dict[str, SolverKind]:
    """Map every installed solver kind to its description and the plugin that handles it.

    Each plugin's ``gymprecice_solver_kinds`` is called on its own so that a kind can be
    attributed to its plugin and one failing plugin costs only its own kinds. When two
    plugins claim one kind, the one whose hooks are consulted first wins (pluggy calls the
    most recently registered plugin first) and a :class:`PluginWarning` names both.
    """
    pm = get_plugin_manager()
    kinds: dict[str, SolverKind] = {}
    # get_hookimpls() is in registration order; pluggy calls them in reverse.
    for impl in reversed(pm.hook.gymprecice_solver_kinds.get_hookimpls()):
        try:
            declared = impl.function() or {}
            items = list(dict(declared).items())
        except Exception as exc:
            warnings.warn(
                f"gymprecice plugin {impl.plugin_name!r}: gymprecice_solver_kinds() failed "
                f"({type(exc).__name__}: {exc}); its solver kinds are unavailable",
                PluginWarning,
                stacklevel=2,
            )
            continue
        for kind, description in items:
            if kind in kinds:
                warnings.warn(
                    f"solver kind {kind!r} is claimed by plugins {kinds[kind].plugin!r} and "
                    f"{impl.plugin_name!r}; {kinds[kind].plugin!r} handles it",
                    PluginWarning,
                    stacklevel=2,
                )
                continue
            kinds[kind] = SolverKind(str(description), impl.plugin_name)
    return kinds
