"""The files ``gymprecice new`` writes, as text with ``{{name}}`` placeholders.

:mod:`gymprecice.scaffold` fills them in (:func:`gymprecice.scaffold.render`); a placeholder
left unfilled is a bug it refuses. The Python files are formatted as ``ruff format`` leaves
them, so a new package starts clean under the user's own linters.

One module per part of the package: :mod:`.project` (pyproject.toml, README.md,
.gitignore, __init__.py), :mod:`.env`, :mod:`.plugin` (the plugin and its lab card),
:mod:`.package_tests`, :mod:`.case` (the preCICE configuration every kind shares) and
one per solver kind: :mod:`.command`, :mod:`.openfoam`, :mod:`.dealii`, :mod:`.fenics`.
"""

from __future__ import annotations

from gymprecice.scaffold.templates.case import PRECICE_CONFIG, SOLVER_README
from gymprecice.scaffold.templates.command import STAND_IN
from gymprecice.scaffold.templates.dealii import DEALII_PARAMETERS
from gymprecice.scaffold.templates.env import ENV
from gymprecice.scaffold.templates.fenics import FENICS_ADAPTER_CONFIG, FENICS_SCRIPT
from gymprecice.scaffold.templates.openfoam import OPENFOAM_FILES
from gymprecice.scaffold.templates.package_tests import CONFORMANCE_TESTS, TESTS
from gymprecice.scaffold.templates.plugin import PLUGIN, SOLVER_PLUGIN
from gymprecice.scaffold.templates.project import GITIGNORE, INIT, PYPROJECT, README

__all__ = [
    "CONFORMANCE_TESTS",
    "DEALII_PARAMETERS",
    "ENV",
    "FENICS_ADAPTER_CONFIG",
    "FENICS_SCRIPT",
    "GITIGNORE",
    "INIT",
    "OPENFOAM_FILES",
    "PLUGIN",
    "PRECICE_CONFIG",
    "PYPROJECT",
    "README",
    "SOLVER_PLUGIN",
    "SOLVER_README",
    "STAND_IN",
    "TESTS",
]
