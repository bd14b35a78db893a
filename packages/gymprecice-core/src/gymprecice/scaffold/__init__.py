"""``gymprecice new NAME``: a pip-installable package for an environment of your own.

The package it writes registers one environment with its lab card through the
``gymprecice`` entry point, ships its case as package data and runs on gymprecice's preCICE
test double out of the box::

    my-env/
      pyproject.toml       depends on gymprecice-core; entry point "gymprecice"
      README.md
      src/my_env/
        plugin.py          registers my-env/MyEnv-v0 and its lab card
        env.py             MyEnv(Adapter): spaces, the four user methods, metrics
        case/              gymprecice-config.json, precice-config.xml, the solver's folder
      tests/test_env.py    gymprecice check, the card, check_env on the test double

so that ``pip install -e ./my-env`` then ``gymprecice train my-env/MyEnv-v0 --double``
works before any edit. The env holds a sensed value at a setpoint drawn each episode with
one or more actuators (``--actuator box``: a Box action in [-1, 1] per actuator;
``discrete``: three levels each). Its solver is of kind ``--kind``: ``command`` (a Python
program of the package's own, which speaks the pyprecice v3 API), or a kind an installed
plugin adds (``openfoam``: a channel whose inlet velocity the controller sets; ``dealii``:
an elastic flap pushed at its tip; ``fenics``: a plate whose top edge temperature it sets;
another plugin's kind: an empty solver folder to fill). On the test double a kind other
than ``command`` is replaced by the package's stand-in program, so ``--double`` needs no
solver installed.

On a terminal the command asks for what its options leave out; without one (stdin not a
tty) it asks nothing and takes the defaults: kind ``command``, one Box actuator. A bad
name or an unknown kind is refused in one line with exit status 2 before anything is
written; an existing folder is left as it is unless ``--force`` (which overwrites the
package's own files there, and no other).

The command is split by responsibility: :mod:`.cli` (the command and its prompts),
:mod:`.checks` (the name and kind checks), :mod:`.kinds` (what each solver kind puts in
the case), :mod:`.plan` (the package the answers ask for), :mod:`.files` (every file of
the package, as text), :mod:`.render` (placeholders filled, source written as ruff
formats it), :mod:`.writer` (the files on disk, nothing overwritten unasked) and
:mod:`.templates` (the files' texts). This module re-exports what other code imports.
"""

from __future__ import annotations

from gymprecice.scaffold.checks import (
    ACTUATOR_KINDS,
    EXCLUDED_KINDS,
    MAX_ACTUATORS,
    RESERVED_MODULES,
    Refused,
    available_kinds,
    check_name,
)
from gymprecice.scaffold.cli import add_new_parser, cmd_new
from gymprecice.scaffold.files import STAND_IN_DIR, package_files
from gymprecice.scaffold.kinds import (
    COMMAND,
    DEALII,
    FENICS,
    KNOWN_KINDS,
    OPENFOAM,
    KindCase,
)
from gymprecice.scaffold.plan import NewPackage, plan_package
from gymprecice.scaffold.render import WIDTH, render
from gymprecice.scaffold.writer import Exists, write_package

__all__ = [
    "ACTUATOR_KINDS",
    "KindCase",
    "NewPackage",
    "Refused",
    "add_new_parser",
    "available_kinds",
    "cmd_new",
    "package_files",
    "plan_package",
    "render",
    "write_package",
    # also kept importable from here, as from the single module this package replaces
    "COMMAND",
    "DEALII",
    "EXCLUDED_KINDS",
    "Exists",
    "FENICS",
    "KNOWN_KINDS",
    "MAX_ACTUATORS",
    "OPENFOAM",
    "RESERVED_MODULES",
    "STAND_IN_DIR",
    "WIDTH",
    "check_name",
]
