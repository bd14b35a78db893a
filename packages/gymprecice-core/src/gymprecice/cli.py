"""The ``gymprecice`` command line: ``plugins``, ``check DIR``, ``doctor``, ``install``,
``sketch ENV`` and plugin commands.

The first three commands answer the questions a new user asks before a first run:
what is installed (``plugins``), is my case directory right (``check``), and does this
machine have the solvers and preCICE (``doctor``); ``sketch`` draws a case from its files
(:mod:`gymprecice.sketch_command`). Plugins add their own commands through
``gymprecice_register_commands(subparsers)`` (for example the tutorials' ``train``).

Every check is done without running a solver or initialising preCICE, so the commands are
safe on a login node. ``doctor`` imports pyprecice in a child interpreter: a broken MPI or
preCICE installation can abort the process that imports it, and the report must still be
printed.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import re
import subprocess
import sys
import warnings
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from gymprecice.clean_command import add_clean_parser, leftover_check
from gymprecice.distribution import CLASH_FIX, core_version, name_clash
from gymprecice.errors import GymPreciceError
from gymprecice.install_command import add_install_parser, stack_checks
from gymprecice.optional import missing_command, missing_dependency
from gymprecice.plugins import (
    DISABLE_ENV_VAR,
    GymPrecicePluginManager,
    PluginWarning,
    get_plugin_manager,
    list_plugins,
    plugin_failures,
    solver_kinds,
)
from gymprecice.scaffold import add_new_parser
from gymprecice.sketch_command import add_sketch_parser
from gymprecice.solver import DoctorCheck
from gymprecice.stack import stack_prefix

__all__ = ["build_parser", "doctor_report", "main"]

# Read from the metadata: with another distribution's gymprecice/__init__.py in place (see
# gymprecice.distribution), `from gymprecice import __version__` fails, and `doctor` must
# still run to say so.
__version__ = core_version()

MIN_PYTHON = (3, 10)
PRECICE_ADVICE = (
    "run `gymprecice install` (builds preCICE and pyprecice from release sources), or build "
    'preCICE v3 yourself and `pip install "gymprecice-core[precice]"` (pyprecice)'
)


# -- parser ----------------------------------------------------------------------------------


def build_parser(pm: GymPrecicePluginManager | None = None) -> argparse.ArgumentParser:
    """The full parser: built-in commands, then the commands plugins contribute."""
    parser = argparse.ArgumentParser(
        prog="gymprecice",
        description="Gymnasium environments from preCICE-coupled simulations.",
    )
    parser.add_argument("--version", action="version", version=f"gymprecice {__version__}")
    parser.set_defaults(func=None)
    sub = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")

    p = sub.add_parser("plugins", help="list installed plugins, their versions and hooks")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument(
        "--hook", action="append", default=[], metavar="NAME", help="only plugins implementing NAME"
    )
    p.set_defaults(func=cmd_plugins)

    p = sub.add_parser("check", help="validate a case directory (gymprecice-config.json)")
    p.add_argument("case", type=Path, metavar="DIR", help="case directory (or its JSON file)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("doctor", help="check Python, preCICE and the solvers on this machine")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_doctor)

    add_install_parser(sub)
    add_sketch_parser(sub)
    add_clean_parser(sub)
    add_new_parser(sub)

    _add_plugin_commands(sub, pm or get_plugin_manager())
    return parser


def _add_plugin_commands(sub: Any, pm: GymPrecicePluginManager) -> None:
    """Let each plugin add commands; one that fails or clashes is skipped with a warning."""
    for impl in reversed(pm.hook.gymprecice_register_commands.get_hookimpls()):
        before = dict(sub.choices)
        try:
            impl.function(**({"subparsers": sub} if "subparsers" in impl.argnames else {}))
        except Exception as exc:
            _warn(f"plugin {impl.plugin_name!r} could not add its commands: {exc}")
        clobbered = [name for name, p in before.items() if sub.choices.get(name) is not p]
        if clobbered:
            # Python < 3.11 lets add_parser silently replace a command of the same name.
            sub.choices.update({name: before[name] for name in clobbered})
            _warn(f"plugin {impl.plugin_name!r} tried to replace the commands {clobbered}")


def _warn(message: str) -> None:
    warnings.warn(message, PluginWarning, stacklevel=3)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 success, 1 failure, 2 usage)."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    elsewhere = None if command in _commands(parser) else missing_command(command or "")
    if elsewhere is not None:
        print(f"gymprecice: error: {elsewhere}", file=sys.stderr)
        return 2
    args = parser.parse_args(argv)
    if args.func is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        status = args.func(args)
    except GymPreciceError as exc:
        print(f"gymprecice {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:
        # An optional dependency the command needs (a plugin's extra): one line naming the
        # install, exit 2 as for a usage error. Any other missing module is a bug: re-raised.
        message = missing_dependency(exc, _owner_module(args.func))
        if message is None:
            raise
        print(f"gymprecice {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    return 0 if status is None else int(status)


def _commands(parser: argparse.ArgumentParser) -> set[str]:
    return {
        name
        for action in parser._actions
        if isinstance(action, argparse._SubParsersAction)
        for name in action.choices
    }


def _owner_module(func: Any) -> str | None:
    """The module that defines a command's function (a plugin's), unwrapping partials."""
    while isinstance(func, functools.partial):
        func = func.func
    return getattr(func, "__module__", None)


# -- plugins ---------------------------------------------------------------------------------


def cmd_plugins(args: argparse.Namespace) -> int:
    kinds = solver_kinds()
    rows = []
    for info in list_plugins():
        if args.hook and not set(args.hook) & set(info.hooks):
            continue
        row = asdict(info)
        row["hooks"] = list(info.hooks)
        row["kinds"] = sorted(k for k, v in kinds.items() if v.plugin == info.name)
        rows.append(row)
    failed = [asdict(f) for f in plugin_failures()]
    if args.json:
        print(json.dumps({"plugins": rows, "failed": failed}, indent=2))
        return 0
    for row in rows:
        origin = (
            f"{row['distribution']} {row['version']}" if row["distribution"] else "(no package)"
        )
        print(f"{row['name']}: {origin}  [{row['module']}]")
        if row["kinds"]:
            print(f"    kinds: {', '.join(row['kinds'])}")
        print(f"    hooks: {', '.join(row['hooks']) or '(none)'}")
    for fail in failed:
        origin = f"{fail['distribution']} {fail['version']}" if fail["distribution"] else ""
        print(f"{fail['name']}: {origin}  FAILED TO LOAD: {fail['error']}")
    if os.environ.get(DISABLE_ENV_VAR):
        print(
            f"({DISABLE_ENV_VAR}={os.environ[DISABLE_ENV_VAR]} is set: third-party plugins may be hidden)"
        )
    return 0


# -- check -----------------------------------------------------------------------------------


def cmd_check(args: argparse.Namespace) -> int:
    from gymprecice.config import check_solver_kinds, load_config

    try:
        config = load_config(args.case)
        kinds = solver_kinds()
        check_solver_kinds(config, kinds, plugin_failures())
    except GymPreciceError as exc:
        if args.json:
            print(json.dumps({"ok": False, "error": str(exc)}, indent=2))
        else:
            print(f"FAILED: {exc}", file=sys.stderr)
        return 1
    summary = _summary(config, kinds)
    if args.json:
        print(json.dumps({"ok": True, **summary}, indent=2))
        return 0
    print(f"OK: {summary['config']}")
    print(f"  preCICE configuration: {summary['precice_config']}")
    participants = [
        p + (" (controller)" if p == summary["controller"] else "") for p in summary["participants"]
    ]
    print(f"  participants: {', '.join(participants)}")
    for s in summary["solvers"]:
        plays = f" as {s['participant']}" if s["participant"] else ""
        print(f"  solver {s['name']}: kind {s['kind']} ({s['plugin']}){plays}, in {s['path']}")
    for i in summary["interfaces"]:
        partner = f" <-> {i['partner']}:{i['partner_mesh']}" if i["partner"] else ""
        data = "; ".join(
            part
            for part in (
                f"write {', '.join(i['write'])}" if i["write"] else "",
                f"read {', '.join(i['read'])}" if i["read"] else "",
            )
            if part
        )
        print(f"  interface {i['name']}: mesh {i['mesh']} ({i['dimensions']}D){partner}; {data}")
    print(f"  end time: {_fmt(summary['end_time'])}")
    print(f"  time window size: {_fmt(summary['time_window_size'])}")
    if summary["time_windows"] is not None:
        print(
            f"  time windows: {summary['time_windows']} "
            f"({summary['windows_per_step']} per env step)"
        )
    return 0


def _fmt(value: float | None) -> str:
    return "not set" if value is None else f"{value:g}"


def _summary(config: Any, kinds: dict[str, Any]) -> dict[str, Any]:
    end, size = config.end_time, config.time_window_size
    windows = round(end / size) if end is not None and size else None
    return {
        "config": str(config.where()),
        "precice_config": str(config.precice_file),
        "controller": config.participant,
        "participants": sorted(config.precice.participants),
        "solvers": [
            {
                "name": s.name,
                "kind": s.kind,
                "plugin": kinds[s.kind].plugin if s.kind in kinds else None,
                "participant": s.participant,
                "path": s.path,
            }
            for s in config.solvers.values()
        ],
        "interfaces": [
            {
                "name": i.name,
                "mesh": i.mesh,
                "dimensions": i.dimensions,
                "write": list(i.write),
                "read": list(i.read),
                "partner": i.partner,
                "partner_mesh": i.partner_mesh,
            }
            for i in config.interfaces.values()
        ],
        "end_time": end,
        "time_window_size": size,
        "time_windows": windows,
        "windows_per_step": config.model.actions.windows,
    }


# -- doctor ----------------------------------------------------------------------------------


def cmd_doctor(args: argparse.Namespace) -> int:
    report = doctor_report()
    if args.json:
        print(json.dumps(report, indent=2))
        return 0 if report["ok"] else 1
    for check in report["checks"]:
        mark = "[ok]     " if check["ok"] else "[MISSING]" if check["required"] else "[--]     "
        required = " (required)" if check["required"] else ""
        source = "" if check["source"] == "core" else f" [{check['source']}]"
        print(f"{mark} {check['name']}{required}{source}: {check['detail']}")
        if not check["ok"] and check["advice"]:
            print(f"          -> {check['advice']}")
    if report["ok"]:
        print("Everything required is there.")
    else:
        missing = [c["name"] for c in report["checks"] if c["required"] and not c["ok"]]
        print(f"Missing required pieces: {', '.join(missing)}")
    return 0 if report["ok"] else 1


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


def _pyprecice_advice(error: str) -> str:
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
        return DoctorCheck(name, False, probe["error"], _pyprecice_advice(probe["error"]), True)
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
