"""``python -m gymprecice_tutorials.recipes``: write, regenerate and size the cases.

Also the :class:`~gymprecice_tutorials.recipes.spec.Resolution` options that every command
writing a mesh shares (``recipes write``, ``validate``, ``base_flow``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from gymprecice_tutorials.recipes.case import regenerate, write_case
from gymprecice_tutorials.recipes.mesh import block_counts
from gymprecice_tutorials.recipes.spec import CASES, case_spec


def add_resolution_options(parser: argparse.ArgumentParser) -> None:
    """The :class:`Resolution` knobs as options, for the commands that write a mesh."""
    parser.add_argument("--cells-per-jet", type=int, help="mesh: see recipes.Resolution")
    parser.add_argument("--wall-cell", type=float, help="mesh: see recipes.Resolution")
    parser.add_argument("--wake-grading", type=float, help="mesh: see recipes.Resolution")


def resolution_overrides(args: argparse.Namespace) -> dict[str, float]:
    """The :class:`Resolution` fields given by :func:`add_resolution_options`' options."""
    given = {
        "cells_per_jet": args.cells_per_jet,
        "wall_cell": args.wall_cell,
        "wake_grading": args.wake_grading,
    }
    return {k: v for k, v in given.items() if v is not None}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m gymprecice_tutorials.recipes")
    sub = parser.add_subparsers(dest="command", required=True)
    w = sub.add_parser("write", help="write one case into a directory")
    w.add_argument("name", choices=sorted(CASES))
    w.add_argument("target", type=Path)
    add_resolution_options(w)
    w.add_argument("--overwrite", action="store_true")
    sub.add_parser("regenerate", help="rewrite the packaged cases")
    i = sub.add_parser("info", help="print the block counts of the cases")
    i.add_argument("name", nargs="?", choices=sorted(CASES))
    args = parser.parse_args(argv)

    if args.command == "write":
        spec = case_spec(args.name)
        knobs = resolution_overrides(args)
        if knobs:
            spec = replace(spec, resolution=replace(spec.resolution, **knobs))
        print(write_case(spec, args.target, overwrite=args.overwrite))
    elif args.command == "regenerate":
        for path in regenerate():
            print(path)
    else:
        for name in [args.name] if args.name else sorted(CASES):
            spec = CASES[name]
            c = block_counts(spec.geometry, spec.resolution)
            print(f"{name}: ~{c.cells} cells, {c}")
    return 0
