"""The package ``gymprecice new`` is asked for: :class:`NewPackage` (its names, its kind,
its actuators) and :func:`plan_package`, which checks the answers and settles the case of
their kind, before anything is written.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from gymprecice.scaffold.checks import (
    ACTUATOR_KINDS,
    EXCLUDED_KINDS,
    MAX_ACTUATORS,
    Refused,
    available_kinds,
    check_name,
)
from gymprecice.scaffold.kinds import KNOWN_KINDS, KindCase, other_kind

__all__ = ["NewPackage", "plan_package"]


@dataclass(frozen=True)
class NewPackage:
    """Everything a new package is made from: its names, its kind, its actuators."""

    name: str
    dist: str
    module: str
    class_name: str
    kind: str
    case: KindCase
    actuator: str = "box"
    actuators: int = 1
    #: the plugin that handles ``kind``, and the distribution that ships it (None: core)
    plugin: str = "script"
    plugin_distribution: str | None = None
    plugin_version: str | None = None
    #: whether the package declares its own solver kind (named ``dist``) for its program
    solver_plugin: bool = False

    @property
    def env_id(self) -> str:
        return f"{self.dist}/{self.class_name}-v0"


def plan_package(
    name: str,
    kind: str = "command",
    actuator: str = "box",
    actuators: int = 1,
    solver_plugin: bool = False,
) -> NewPackage:
    """The package for these answers; :class:`Refused` (one line) for a bad name, an
    unknown kind, an unknown actuator or a count out of range.

    ``solver_plugin``: the package also declares a solver kind of its own, named after
    it, that runs its program (kind ``command`` only), and tests it with gymprecice's
    conformance suite."""
    dist, module, class_name = check_name(name)
    if solver_plugin and kind != "command":
        raise Refused(
            "--solver-plugin gives the package a solver kind of its own, which runs its own "
            f"program; it cannot go with --kind {kind}"
        )
    kinds = available_kinds()
    if kind not in kinds:
        why = EXCLUDED_KINDS.get(kind)
        known = ", ".join(sorted(kinds))
        raise Refused(
            f"{why}" if why else f"unknown solver kind {kind!r}; installed kinds: {known}"
        )
    if actuator not in ACTUATOR_KINDS:
        raise Refused(f"unknown actuator {actuator!r}; choose {' or '.join(ACTUATOR_KINDS)}")
    if not 1 <= actuators <= MAX_ACTUATORS:
        raise Refused(f"--actuators takes 1 to {MAX_ACTUATORS}, got {actuators}")
    plugin = kinds[kind].plugin
    distribution = version = None
    if kind != "command":
        from gymprecice.plugin.manager import get_plugin_manager

        dist_info = get_plugin_manager().distributions.get(plugin)
        if dist_info is not None:
            distribution = dist_info.metadata["Name"]
            version = dist_info.version
    case = KNOWN_KINDS.get(kind) or other_kind(kind)
    if solver_plugin:
        kind, plugin, distribution = dist, dist, dist
        case = dataclasses.replace(
            case,
            options={},
            solver_text=f"The solver is `solver.py`, a Python program of the package's own "
            f"that speaks the pyprecice v3 API, run by the package's own solver kind "
            f"`{dist}` (its plugin, `plugin.py`): replace its model with yours.",
        )
    return NewPackage(
        name=name.strip(),
        dist=dist,
        module=module,
        class_name=class_name,
        kind=kind,
        case=case,
        actuator=actuator,
        actuators=actuators,
        plugin=plugin,
        plugin_distribution=distribution,
        plugin_version=version,
        solver_plugin=solver_plugin,
    )
