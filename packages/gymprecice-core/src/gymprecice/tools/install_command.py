"""``gymprecice install``: build the real stack, and what ``doctor`` says about it.

The steps come from every installed plugin (``gymprecice_install_steps``): core's preCICE and
pyprecice, the OpenFOAM plugin's adapter, the deal.II plugin's ``elasticity``, a third-party
plugin's own adapter. See :mod:`gymprecice.stack` for how a step is built and remembered.
"""

from __future__ import annotations

import argparse
import textwrap
import time
from typing import Any

from gymprecice.plugin.manager import GymPrecicePluginManager, get_plugin_manager
from gymprecice.plugin.solver import DoctorCheck
from gymprecice.tools.prerequisites import describe_missing
from gymprecice.tools.stack import (
    SOURCES_ENV,
    BuildError,
    InstallStep,
    install,
    order_steps,
    stack_prefix,
    stamp_of,
)

__all__ = ["add_install_parser", "install_steps", "stack_checks"]


def install_steps(pm: GymPrecicePluginManager | None = None) -> list[InstallStep]:
    """Every step the installed plugins offer, core's first, each name once."""
    pm = pm or get_plugin_manager()
    steps: dict[str, InstallStep] = {}
    for impl in pm.hook.gymprecice_install_steps.get_hookimpls():  # core (trylast) first
        for step in impl.function() or []:
            steps.setdefault(step.name, step)
    return list(steps.values())


def _prerequisites_epilog() -> str:
    """``--help``'s list of what the builds need, from the same objects the probes use."""
    from gymprecice.tools.precice_install import PRECICE_PREREQUISITES

    packages = " ".join(dict.fromkeys(d for p in PRECICE_PREREQUISITES for d in p.debian))
    items = "\n".join(f"  - {p.title}" for p in PRECICE_PREREQUISITES)
    return (
        "build prerequisites (probed before anything is built; what is missing is listed):\n"
        f"{items}\n"
        "  - for pyprecice, also this Python's headers and an MPI library for mpi4py\n"
        "  - for a solver adapter, also its solver: OpenFOAM (openfoam-adapter), deal.II "
        "(dealii-adapter),\n    Debian's FEniCS (fenics); `gymprecice install --list` shows "
        "each step's state\n\n"
        + textwrap.fill(
            f"Debian/Ubuntu: sudo apt-get install {packages} python3-dev libopenmpi-dev",
            width=88,
            subsequent_indent="    ",
            break_on_hyphens=False,
        )
    )


def add_install_parser(sub: Any) -> None:
    p = sub.add_parser(
        "install",
        help="build preCICE, pyprecice and the solver adapters (whatever is missing)",
        description=textwrap.fill(
            "Build the real coupling stack from release sources: preCICE into a per-user "
            f"prefix ({stack_prefix()}), pyprecice into this Python environment, and each "
            "solver plugin's preCICE adapter. Sources come from the directory in "
            f"${SOURCES_ENV} (an offline mirror of the release archives) or are downloaded; "
            "checksums are verified. What is already built is kept (a second run takes "
            "seconds).",
            width=88,
        ),
        epilog=_prerequisites_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "steps",
        nargs="*",
        default=["all"],
        metavar="STEP",
        help="what to build, with what it requires (default: all; see --list)",
    )
    p.add_argument(
        "--skip",
        action="append",
        default=[],
        metavar="STEP",
        help="leave this step out (repeatable; still built when a wanted step requires it)",
    )
    p.add_argument("--list", action="store_true", help="list the steps and their state")
    p.add_argument("--force", action="store_true", help="rebuild even what is built")
    p.add_argument("--jobs", type=int, default=None, help="parallel compile jobs (default: CPUs)")
    p.add_argument(
        "--at-once",
        type=int,
        default=1,
        metavar="N",
        help="build up to N steps side by side once what they require is built (default: 1)",
    )
    p.set_defaults(func=cmd_install)


def cmd_install(args: argparse.Namespace) -> int:
    steps = install_steps()
    if args.list:
        for step, check in zip(steps, stack_checks(steps)):
            mark = "ok  " if check.ok else "--  "
            print(f"{mark}{check.name.removeprefix('stack: '):<16} {check.detail}")
            absent = [] if check.ok else step.missing_prerequisites()
            if absent:
                print(f"{'':<20} to build it, install: {describe_missing(absent)}")
        return 0
    try:
        ordered = order_steps(steps, args.steps, skip=args.skip)
    except BuildError as exc:
        print(f"gymprecice install: {exc}")
        return 2
    started = time.monotonic()
    print(f"[install] prefix {stack_prefix()}")
    results = install(ordered, force=args.force, jobs=args.jobs, at_once=args.at_once)
    width = max(len(r.step.name) for r in results)
    print(f"[install] summary ({time.monotonic() - started:.0f} s):")
    for r in results:
        took = f" in {r.seconds:.0f} s" if r.status in ("built", "failed") else ""
        print(f"  {r.step.name:<{width}}  {r.status}{took}  {r.detail}")
    return 1 if any(r.status in ("failed", "skipped", "missing") for r in results) else 0


def stack_checks(steps: list[InstallStep] | None = None) -> list[DoctorCheck]:
    """One doctor line per install step: built (version, path), found elsewhere, or missing."""
    checks = []
    for step in install_steps() if steps is None else steps:
        stamp = stamp_of(step)
        if stamp is not None:
            detail = f"{step.title}: built by gymprecice install at {stamp.get('path')}"
            checks.append(DoctorCheck(f"stack: {step.name}", True, detail))
            continue
        elsewhere = step.found()
        if elsewhere:
            checks.append(DoctorCheck(f"stack: {step.name}", True, f"{step.title}: {elsewhere}"))
            continue
        checks.append(
            DoctorCheck(
                f"stack: {step.name}",
                False,
                f"{step.title}: not built",
                f"run `gymprecice install {step.name}`",
            )
        )
    return checks
