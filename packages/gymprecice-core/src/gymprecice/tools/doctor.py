"""``gymprecice doctor``: does this machine have what the solvers and preCICE need?

:func:`doctor_report` gathers core's checks (Python, who owns the ``gymprecice``
package, pyprecice and the preCICE library it loads, processes left behind), the coupling
stack's and every plugin's (``gymprecice_doctor_checks``) as JSON-ready data; the
``doctor`` command of :mod:`gymprecice.tools.cli` prints it, and the lab reads it to say
what an environment lacks before it starts anything.

Nothing here runs a solver or initialises preCICE: pyprecice is imported in a child
interpreter, since a broken MPI or preCICE installation can abort the process that
imports it, and the report must still be printed.
"""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys
from dataclasses import asdict
from typing import Any

from gymprecice.plugin.manager import DISABLE_ENV_VAR, get_plugin_manager
from gymprecice.plugin.solver import DoctorCheck
from gymprecice.tools.clean_command import leftover_check
from gymprecice.tools.distribution import CLASH_FIX, core_version, name_clash
from gymprecice.tools.install_command import stack_checks
from gymprecice.tools.stack import stack_prefix

__all__ = ["MIN_PYTHON", "PRECICE_ADVICE", "core_checks", "doctor_report", "pyprecice_advice"]

# Read from the metadata: with another distribution's gymprecice/__init__.py in place (see
# gymprecice.tools.distribution), `from gymprecice import __version__` fails, and `doctor`
# must still run to say so.
__version__ = core_version()

MIN_PYTHON = (3, 10)
PRECICE_ADVICE = (
    "run `gymprecice install` (builds preCICE and pyprecice from release sources), or build "
    'preCICE v3 yourself and `pip install "gymprecice-core[precice]"` (pyprecice)'
)


def doctor_report() -> dict[str, Any]:
    """Core's checks plus every plugin's, as JSON-ready data; ``ok`` = all required pass."""
    checks: list[tuple[str, DoctorCheck]] = [("core", c) for c in core_checks()]
    checks += [("install", c) for c in stack_checks()]
    pm = get_plugin_manager()
    for fail in pm.failures:
        origin = f"{fail.distribution} {fail.version}" if fail.distribution else fail.name
        checks.append(
            (
                "core",
                DoctorCheck(
                    name=f"plugin {fail.name}",
                    ok=False,
                    detail=f"{origin} could not be loaded: {fail.error}",
                    advice=f"reinstall or uninstall {fail.distribution or fail.name}; "
                    f"{DISABLE_ENV_VAR}={fail.name} hides it meanwhile",
                ),
            )
        )
    for impl in reversed(pm.hook.gymprecice_doctor_checks.get_hookimpls()):
        try:
            result = list(impl.function() or [])
        except Exception as exc:
            result = [
                DoctorCheck(
                    name="doctor checks",
                    ok=False,
                    detail=f"the plugin's checks failed: {type(exc).__name__}: {exc}",
                    advice="report this to the plugin's authors",
                )
            ]
        for item in result:
            if not isinstance(item, DoctorCheck):
                item = DoctorCheck(
                    name="doctor checks",
                    ok=False,
                    detail=f"returned {item!r} instead of a gymprecice.solver.DoctorCheck",
                    advice="report this to the plugin's authors",
                )
            checks.append((impl.plugin_name, item))
    rows = [{"source": source, **asdict(check)} for source, check in checks]
    return {"ok": all(r["ok"] for r in rows if r["required"]), "checks": rows}


def core_checks() -> list[DoctorCheck]:
    """What core itself looks for: Python, who owns the ``gymprecice`` package, and pyprecice
    + preCICE (solvers are the plugins')."""
    checks = [_check_python()]
    clash = name_clash()
    if clash is not None:
        checks.append(DoctorCheck("gymprecice package", False, clash, CLASH_FIX, True))
    checks.append(_check_pyprecice())
    checks.append(leftover_check())
    return checks


def _check_python() -> DoctorCheck:
    ok = sys.version_info >= MIN_PYTHON
    need = ".".join(map(str, MIN_PYTHON))
    return DoctorCheck(
        name="python",
        ok=ok,
        detail=f"{platform.python_version()} ({sys.executable}); gymprecice {__version__}",
        advice="" if ok else f"use Python {need} or newer",
        required=True,
    )


_PRECICE_PROBE = r"""
import json
out = {}
try:
    import precice
except Exception as exc:
    out["error"] = f"{type(exc).__name__}: {exc}"
else:
    out["module"] = getattr(precice, "__file__", None)
    out["version"] = str(getattr(precice, "__version__", "") or "") or None
    get = getattr(precice, "get_version_information", None)
    if get is not None:
        try:
            info = get()
            out["library"] = info.decode(errors="replace") if isinstance(info, bytes) else str(info)
        except Exception as exc:
            out["library_error"] = f"{type(exc).__name__}: {exc}"
print("GYMPRECICE-PROBE " + json.dumps(out))
"""


def pyprecice_advice(error: str) -> str:
    """What to do when ``import precice`` failed, from why it failed."""
    if "No module named" in error:
        return "pyprecice is not installed in this environment: run `gymprecice install`"
    if "libprecice" in error and "cannot open shared object" in error:
        built = sorted((stack_prefix() / "lib").glob("libprecice.so*"))
        where = f"; preCICE is built at {built[0].parent}" if built else ""
        return (
            "pyprecice is installed but the dynamic linker does not find libprecice"
            f"{where}: run `gymprecice install pyprecice --force` (links pyprecice to the "
            "stack's preCICE with an RPATH), or add preCICE's lib directory to LD_LIBRARY_PATH"
        )
    return PRECICE_ADVICE


def _check_pyprecice() -> DoctorCheck:
    name = "pyprecice"
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PRECICE_PROBE],
            capture_output=True,
            text=True,
            timeout=120,
            stdin=subprocess.DEVNULL,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        return DoctorCheck(name, False, f"could not probe pyprecice: {exc}", PRECICE_ADVICE, True)
    found = re.search(r"^GYMPRECICE-PROBE (.*)$", proc.stdout, re.MULTILINE)
    if found is None:
        tail = " | ".join((proc.stderr or proc.stdout).strip().splitlines()[-3:])
        return DoctorCheck(
            name,
            False,
            f"importing precice crashed the interpreter (exit status {proc.returncode}): {tail}",
            "pyprecice does not match the installed preCICE/MPI; rebuild it: "
            '`pip install --force-reinstall --no-binary :all: "gymprecice-core[precice]"`',
            True,
        )
    probe = json.loads(found.group(1))
    if "error" in probe:
        return DoctorCheck(name, False, probe["error"], pyprecice_advice(probe["error"]), True)
    library = (probe.get("library") or "").split(";", 1)[0].strip()
    detail = f"pyprecice {probe.get('version') or '?'} at {probe.get('module')}"
    detail += f"; preCICE library {library}" if library else "; preCICE library version unknown"
    override = os.environ.get("GYMPRECICE_PRECICE_LIBRARY")
    if override:
        detail += f"; GYMPRECICE_PRECICE_LIBRARY={override} overrides it in envs"
    if library and not library.startswith(("3", "v3")) and library[:1].isdigit():
        return DoctorCheck(
            name,
            False,
            detail,
            f"gymprecice needs preCICE v3, this is {library}; " + PRECICE_ADVICE,
            True,
        )
    return DoctorCheck(name, True, detail, "", True)
