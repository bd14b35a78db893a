"""Which solvers an environment needs, and what to say when they are missing.

``gymprecice train`` and the rollouts check this before starting any environment, so a
machine without preCICE or OpenFOAM gets one line with the fix (``--double``, or what to
install) instead of an environment that restarts and a traceback.
"""

from __future__ import annotations

import io
import sys
from collections.abc import Mapping
from typing import Any

from gymprecice_lab.common.registered_env import LabEnv

__all__ = ["doctor_text", "missing_names", "missing_requirements", "require_solvers"]


#: the checks an env needs whose card names none (``solver_checks``)
DEFAULT_CHECKS: tuple[str, ...] = ("pyprecice",)


def missing_requirements(
    report: Mapping[str, Any], env: LabEnv, kwargs: Mapping[str, Any] | None = None
) -> list[dict[str, Any]]:
    """The failed doctor checks that ``env``, made with ``kwargs``, needs on real solvers.

    Every failed *required* check counts, plus the checks the env itself needs (its lab
    card's ``solver_checks``, or the ``solver_checks_with`` entry that ``kwargs`` match: a
    flap whose ``solid="fenics"`` needs FEniCS, not deal.II; a check counting when its
    lower-case name starts with one of them): the doctor marks only Python and pyprecice
    as required for everyone.
    """
    needs = tuple(n.lower() for n in env.checks_for(kwargs)) or DEFAULT_CHECKS
    missing = []
    for check in report["checks"]:
        if check["ok"]:
            continue
        name = str(check["name"]).lower()
        if check.get("required") or name.startswith(needs):
            missing.append(dict(check))
    return missing


def doctor_text(report: Mapping[str, Any]) -> str:
    """The doctor report as ``gymprecice doctor`` prints it."""
    out = io.StringIO()
    for check in report["checks"]:
        mark = "[ok]     " if check["ok"] else "[MISSING]" if check["required"] else "[--]     "
        required = " (required)" if check["required"] else ""
        source = "" if check["source"] == "core" else f" [{check['source']}]"
        print(f"{mark} {check['name']}{required}{source}: {check['detail']}", file=out)
        if not check["ok"] and check.get("advice"):
            print(f"          -> {check['advice']}", file=out)
    return out.getvalue()


def missing_names(missing: list[Mapping[str, Any]]) -> str:
    """The missing checks as a comma-separated list for one line of text."""
    return ", ".join(
        "pyprecice (the preCICE library and its Python bindings)"
        if c["name"] == "pyprecice"
        else str(c["name"])
        for c in missing
    )


def require_solvers(
    env: LabEnv,
    command: str = "train",
    report: Mapping[str, Any] | None = None,
    *,
    verbose: bool = True,
    kwargs: Mapping[str, Any] | None = None,
) -> int:
    """0 when this machine can run ``env`` (made with ``kwargs``) on real solvers; else
    explain and return 1.

    ``verbose`` (``--require-solvers``) prints the whole doctor report; otherwise one line
    names what is missing and suggests ``--double``: without solvers an environment would
    only restart until its failure budget is spent.
    """
    if report is None:
        from gymprecice.tools.cli import doctor_report

        report = doctor_report()
    missing = missing_requirements(report, env, kwargs)
    if not missing:
        return 0
    names = missing_names(missing)
    if not verbose:
        print(
            f"gymprecice {command}: {env.name} needs {names}, not found on this machine; "
            f"add --double to run the pipeline on gymprecice's preCICE test double (minutes), "
            f"or install them (`gymprecice doctor` says how)",
            file=sys.stderr,
        )
        return 1
    print(
        f"gymprecice {command}: {env.name} cannot run on real solvers on this machine; "
        f"missing: {names}.\n\n{doctor_text(report)}\n"
        "Install what is missing (see the advice above and docs/get-started.md, 'Real "
        "preCICE and the adapters'), "
        f"or add --double to run against gymprecice's preCICE test double.",
        file=sys.stderr,
    )
    return 1
