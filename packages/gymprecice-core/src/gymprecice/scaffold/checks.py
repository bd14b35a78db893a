"""The checks ``gymprecice new`` makes before it writes anything: the package's name (a
distribution name whose module is a Python name that shadows nothing) and the solver kinds
it can use here.

What fails a check is :class:`Refused`: one line on stderr and exit status 2, with nothing
written.
"""

from __future__ import annotations

import importlib.util
import keyword
import re
import sys
from pathlib import Path
from typing import Any

__all__ = [
    "ACTUATOR_KINDS",
    "EXCLUDED_KINDS",
    "MAX_ACTUATORS",
    "RESERVED_MODULES",
    "Refused",
    "available_kinds",
    "check_name",
    "installed_elsewhere",
]

#: the action spaces ``--actuator`` offers
ACTUATOR_KINDS = ("box", "discrete")
#: kinds ``gymprecice new`` does not write a case for, and why
EXCLUDED_KINDS = {
    "script": "kind 'script' runs the Gym-preCICE paper's shell scripts; a new package "
    "uses 'command' (any program)",
}
#: module names a new package must not take: it would shadow what it imports
RESERVED_MODULES = frozenset(
    {"gymprecice", "gymnasium", "numpy", "precice", "pytest", "setuptools", "test", "tests"}
)
MAX_ACTUATORS = 64
_DISTRIBUTION = re.compile(r"^[A-Za-z0-9](?:[A-Za-z0-9._-]*[A-Za-z0-9])?$")


class Refused(ValueError):
    """Input ``gymprecice new`` cannot use: one line on stderr, exit status 2."""


def available_kinds() -> dict[str, Any]:
    """The solver kinds a new package can use here: ``command`` and every installed
    plugin's (each with its :class:`~gymprecice.plugins.SolverKind`)."""
    from gymprecice.plugin.manager import solver_kinds

    return {k: v for k, v in solver_kinds().items() if k not in EXCLUDED_KINDS}


def check_name(name: str) -> tuple[str, str, str]:
    """``(distribution, module, class)`` of a package name; :class:`Refused` when the name
    is not a distribution name whose module is a Python identifier, or would shadow a
    module the package imports."""
    name = name.strip()
    fix = "use letters, digits and '-', starting with a letter, e.g. my-env"
    if not _DISTRIBUTION.match(name):
        raise Refused(f"{name!r} is not a package name: {fix}")
    dist = re.sub(r"[-_.]+", "-", name).lower()
    module = dist.replace("-", "_")
    if not module.isidentifier():
        raise Refused(f"{name!r} gives the module name {module!r}, not a Python name: {fix}")
    if keyword.iskeyword(module):
        raise Refused(f"{name!r} gives the module name {module!r}, a Python keyword: {fix}")
    stdlib = getattr(sys, "stdlib_module_names", frozenset())
    if module in RESERVED_MODULES or module in stdlib or module.startswith("gymprecice_"):
        raise Refused(
            f"{name!r} gives the module name {module!r}, which would shadow a module of that "
            "name; choose another name"
        )
    parts = [p for p in re.split(r"[-_.]+", name) if p]
    class_name = "".join(p[:1].upper() + p[1:] for p in parts)
    return dist, module, class_name


def installed_elsewhere(module: str, target: Path) -> str | None:
    """Where an importable module of that name lives, unless inside ``target``."""
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None
    if spec is None or spec.origin in (None, "namespace"):
        return None  # nothing, or a bare folder of that name (not a package)
    if Path(spec.origin).resolve().is_relative_to(target.resolve()):
        return None  # this package itself, installed from its folder (--force)
    return spec.origin
