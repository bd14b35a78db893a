"""The module paths of earlier versions, each answered with the module that now holds it.

Core's flat modules moved into wings (``gymprecice.core`` is now ``gymprecice.env.core``;
the table is :data:`MOVED`). Code, pickles and ``python -m`` commands written against the
old paths keep working: a finder on ``sys.meta_path`` answers an old name with its new
module, so both names are the same module object (a monkeypatch on either is seen by
both, and a run pickled under an old name loads). ``python -m OLD`` runs the new module
as ``__main__``. New code imports the new paths.

One table per package instead of one three-line file per old path, so that the folder
tree shows the wings alone. :func:`install` is public because the lab answers its own
old paths the same way (``gymprecice_lab.old_paths``).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
from collections.abc import Mapping, Sequence
from types import CodeType, ModuleType


def _homes(wing: str, names: Sequence[str]) -> dict[str, str]:
    return {f"gymprecice.{name}": f"gymprecice.{wing}.{name}" for name in names}


#: Core's old module path -> the module that holds it now (docs/architecture.md).
MOVED: dict[str, str] = {
    **_homes(
        "plugin",
        [
            "card",
            "divergence",
            "errors",
            "fields",
            "hookspecs",
            "logscan",
            "options",
            "precice_xml",
            "readers",
            "registration",
            "sketch",
            "solver",
            "watchpoints",
        ],
    ),
    "gymprecice.plugins": "gymprecice.plugin.manager",
    **_homes(
        "env",
        [
            "action_shaping",
            "actions",
            "config",
            "core",
            "coupled_run",
            "coupling",
            "default_plugin",
            "episode",
            "exit_cleanup",
            "frames",
            "guards",
            "lifecycle",
            "owner_watchdog",
            "pidregistry",
            "precice_library",
            "processes",
            "rendering",
            "returned_values",
            "rundir",
            "timed_reader",
            "values",
            "vertices",
        ],
    ),
    **_homes(
        "tools",
        [
            "case_sketch",
            "clean_command",
            "cli",
            "distribution",
            "install_command",
            "optional",
            "precice_install",
            "prerequisites",
            "sketch_command",
            "sketch_drawing",
            "stack",
        ],
    ),
    **_homes("learners", ["rllib", "robustness", "sb3"]),
    "gymprecice.telemetry": "gymprecice.vector.telemetry",
}


class _MovedLoader(importlib.abc.Loader):
    """Loads an old path as its new module (the object itself, not a copy)."""

    def __init__(self, home: str) -> None:
        self.home = home

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(self.home)
        self._home_spec = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the new module ran when it was imported.

        The import system has just set the module's ``__spec__`` to the old path's; it is
        put back, so that the module still says where it lives (``reload``, ``pickle``).
        """
        module.__spec__ = self._home_spec

    def get_code(self, fullname: str) -> CodeType | None:
        """The new module's code, for ``python -m OLD`` (runpy asks for it)."""
        spec = importlib.util.find_spec(self.home)
        loader = spec.loader if spec is not None else None
        if not isinstance(loader, importlib.abc.InspectLoader):
            return None
        return loader.get_code(self.home)


class OldPathFinder(importlib.abc.MetaPathFinder):
    """A ``sys.meta_path`` finder that answers the old paths of one table."""

    def __init__(self, moved: Mapping[str, str]) -> None:
        self.moved = dict(moved)

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None = None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        home = self.moved.get(fullname)
        if home is None:
            return None
        # The new file as origin: ``python -m OLD`` puts it in ``sys.argv[0]``.
        found = importlib.util.find_spec(home)
        origin = found.origin if found is not None else None
        return importlib.machinery.ModuleSpec(fullname, _MovedLoader(home), origin=origin)


def install(moved: Mapping[str, str]) -> OldPathFinder:
    """Answer the old paths of ``moved`` from now on; once per table, however often called."""
    for finder in sys.meta_path:
        if isinstance(finder, OldPathFinder) and finder.moved == dict(moved):
            return finder
    finder = OldPathFinder(moved)
    sys.meta_path.append(finder)
    return finder
