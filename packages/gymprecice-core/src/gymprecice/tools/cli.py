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
import sys
import warnings
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from gymprecice.plugin.errors import GymPreciceError
from gymprecice.plugin.manager import (
    DISABLE_ENV_VAR,
    GymPrecicePluginManager,
    PluginWarning,
    get_plugin_manager,
    list_plugins,
    plugin_failures,
    solver_kinds,
)
from gymprecice.scaffold import add_new_parser
from gymprecice.tools.clean_command import add_clean_parser
from gymprecice.tools.distribution import core_version

# The doctor (gymprecice.tools.doctor): its names stay importable from here too.
from gymprecice.tools.doctor import (  # noqa: F401
    MIN_PYTHON,
    PRECICE_ADVICE,
    core_checks,
    doctor_report,
)
from gymprecice.tools.doctor import pyprecice_advice as _pyprecice_advice  # noqa: F401
from gymprecice.tools.install_command import add_install_parser
from gymprecice.tools.optional import missing_command, missing_dependency
from gymprecice.tools.prepare_command import add_prepare_parser
from gymprecice.tools.sketch_command import add_sketch_parser

__all__ = ["build_parser", "doctor_report", "main"]

# Read from the metadata: with another distribution's gymprecice/__init__.py in place (see
# gymprecice.distribution), `from gymprecice import __version__` fails, and `doctor` must
# still run to say so.
__version__ = core_version()


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
    add_prepare_parser(sub)
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
    from gymprecice.env.config import check_solver_kinds, load_config

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
