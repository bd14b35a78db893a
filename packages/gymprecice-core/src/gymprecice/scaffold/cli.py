"""The ``gymprecice new`` command: its options, its prompts on a terminal (the defaults
without one), its exit statuses and the summary it prints.

The command line registers it through :func:`add_new_parser`; :func:`cmd_new` plans the
package (:mod:`gymprecice.scaffold.plan`), renders its files
(:mod:`gymprecice.scaffold.files`) and writes them (:mod:`gymprecice.scaffold.writer`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gymprecice.scaffold.checks import (
    ACTUATOR_KINDS,
    MAX_ACTUATORS,
    Refused,
    available_kinds,
    check_name,
    installed_elsewhere,
)
from gymprecice.scaffold.files import package_files
from gymprecice.scaffold.plan import NewPackage, plan_package
from gymprecice.scaffold.writer import Exists, write_package

__all__ = ["add_new_parser", "cmd_new"]


def add_new_parser(sub: Any) -> None:
    """Add ``gymprecice new`` to the command line's sub-parsers."""
    p = sub.add_parser(
        "new",
        help="write a pip-installable package for an environment of your own",
        description="Write a package that registers an environment with its lab card, its "
        "case, a test-double variant and tests. On a terminal it asks for what the options "
        "leave out; without one it takes the defaults.",
    )
    p.add_argument(
        "name",
        nargs="?",
        metavar="NAME",
        help="the package's name (a distribution name such as my-env; its module is my_env)",
    )
    p.add_argument(
        "--kind",
        default=None,
        help="the solver's kind: command (a program of the package's own), or one an "
        "installed plugin adds, such as openfoam, dealii or fenics (default: command)",
    )
    p.add_argument(
        "--actuator",
        default=None,
        metavar="{box,discrete}",
        help="the action: box (a level in [-1, 1] per actuator) or discrete (three levels "
        "each) (default: box)",
    )
    p.add_argument(
        "--actuators",
        type=int,
        default=None,
        metavar="N",
        help="how many actuators (default: 1)",
    )
    p.add_argument(
        "--solver-plugin",
        action="store_true",
        help="give the package a solver kind of its own (named after it) that runs its "
        "program, tested with gymprecice's plugin conformance suite (kind command only)",
    )
    p.add_argument(
        "--dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="the package's folder (default: ./NAME)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="write into an existing folder, overwriting the package's own files there",
    )
    p.set_defaults(func=cmd_new)


def _ask(question: str, default: str | None, check: Callable[[str], Any]) -> str:
    """Ask on the terminal until ``check`` accepts the answer (empty: ``default``)."""
    suffix = f" [{default}]" if default else ""
    while True:
        try:
            answer = input(f"{question}{suffix}: ").strip() or (default or "")
        except EOFError:
            raise Refused(f"no answer to {question!r}") from None
        try:
            check(answer)
        except Refused as exc:
            print(f"  {exc}", file=sys.stderr)
            continue
        return answer


def _settle(args: argparse.Namespace) -> NewPackage:
    """The package the options (and, on a terminal, the answers) ask for."""
    name, kind, actuator, count = args.name, args.kind, args.actuator, args.actuators
    if sys.stdin is not None and sys.stdin.isatty():
        if name is None:
            name = _ask("Package name (e.g. my-env)", None, check_name)
        if kind is None and not args.solver_plugin:
            kinds = sorted(available_kinds(), key=lambda k: (k != "command", k))
            kind = _ask(
                f"Solver kind ({', '.join(kinds)})",
                "command",
                lambda k: k in kinds or _raise(f"choose one of {', '.join(kinds)}"),
            )
        if actuator is None:
            actuator = _ask(
                "Action: box (a level in [-1, 1] per actuator) or discrete (three levels)",
                "box",
                lambda a: a in ACTUATOR_KINDS or _raise("choose box or discrete"),
            )
        if count is None:
            count = int(_ask("How many actuators", "1", _check_count))
    elif name is None:
        raise Refused("NAME is needed (no terminal to ask on): gymprecice new my-env")
    return plan_package(
        name,
        kind or "command",
        actuator or "box",
        1 if count is None else count,
        solver_plugin=args.solver_plugin,
    )


def _raise(message: str) -> bool:
    raise Refused(message)


def _check_count(text: str) -> None:
    if not (text.isdigit() and 1 <= int(text) <= MAX_ACTUATORS):
        raise Refused(f"a whole number from 1 to {MAX_ACTUATORS}")


def cmd_new(args: argparse.Namespace) -> int:
    """``gymprecice new``."""
    try:
        pkg = _settle(args)
        target = args.dir if args.dir is not None else Path(pkg.name)
        elsewhere = installed_elsewhere(pkg.module, target)
        if elsewhere is not None:
            raise Refused(
                f"a module named {pkg.module!r} is installed already ({elsewhere}); the new "
                "package would shadow it or be shadowed: choose another name"
            )
        files = package_files(pkg, target.name)
    except Refused as exc:
        print(f"gymprecice new: error: {exc}", file=sys.stderr)
        return 2
    try:
        write_package(target, files, force=args.force)
    except Exists as exc:
        print(f"gymprecice new: error: {exc}", file=sys.stderr)
        return 1
    shown = _shown(target)
    case = pkg.case
    print(f"gymprecice new: wrote {len(files)} files in {shown}/")
    print(f"  registers {pkg.env_id} (short name {pkg.dist}): {pkg.module}.env:{pkg.class_name}")
    print(
        f"  solver: kind {pkg.kind}, participant {case.participant}, in "
        f"src/{pkg.module}/case/{case.solver_dir}/"
    )
    print("  test double: double=True (--double), no preCICE or solver needed")
    print("next:")
    print(f"  pip install -e {shown}")
    print(f"  gymprecice check {shown}/src/{pkg.module}/case")
    print(f"  gymprecice train {pkg.env_id} --double --timesteps 80")
    print(f"  pytest {shown}/tests")
    return 0


def _shown(target: Path) -> str:
    """How the next steps name the folder: relative to here where it can."""
    try:
        relative = target.resolve().relative_to(Path.cwd().resolve())
    except ValueError:
        return str(target)
    return f"./{relative}" if str(relative) != "." else "."
