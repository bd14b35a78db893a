"""Every file of a new package, as text: the values its templates are filled with, the
case's ``gymprecice-config.json``, and :func:`package_files`, which puts them together
(nothing is written here; :mod:`gymprecice.scaffold.writer` writes them).
"""

from __future__ import annotations

import re
from typing import Any

from gymprecice.scaffold import templates as t
from gymprecice.scaffold.kinds import command_argv
from gymprecice.scaffold.plan import NewPackage
from gymprecice.scaffold.render import (
    WIDTH,
    literal,
    render,
    to_json,
    wrap_docstrings,
    wrap_markdown,
)

__all__ = ["STAND_IN_DIR", "package_files"]

STAND_IN_DIR = "stand-in"


def _values(pkg: NewPackage, folder: str) -> dict[str, Any]:
    case = pkg.case
    actuators = case.actuators(pkg.actuators)
    sensors = [list(map(float, s)) for s in case.sensors]
    steps = round(case.end_time / (case.window * case.windows))
    stand_in_dir = case.solver_dir if case.own_program else STAND_IN_DIR
    stand_in_entry = None
    if not case.own_program:
        stand_in_entry = {
            "kind": "command",
            "path": STAND_IN_DIR,
            "participant": case.participant,
            "options": {"argv": command_argv(), "reset_timeout": 60, "log_name": "solver.log"},
        }
    unique = []
    for point in [*actuators, *sensors]:
        if point not in unique:
            unique.append(point)
    low = case.reference - case.actuation_scale
    high = case.reference + case.actuation_scale
    unit = "" if case.write_unit == "no unit" else f" {case.write_unit}"
    if pkg.actuator == "discrete":
        action_text = (
            f"per actuator, 0, 1 or 2: the levels -1, 0, 1, each writing `{case.write}` "
            f"REFERENCE + ACTUATION_SCALE * level ({low:g}, {case.reference:g} or "
            f"{high:g}{unit})."
        )
        action_shape = (
            "Discrete(3)" if pkg.actuators == 1 else f"MultiDiscrete([3] * {pkg.actuators})"
        )
    else:
        action_text = (
            f"each actuator's level in [-1, 1], writing `{case.write}` REFERENCE + "
            f"ACTUATION_SCALE * level ({low:g} to {high:g}{unit})."
        )
        action_shape = f"({pkg.actuators},)"
    dependencies = ['"gymprecice-core>=' + _minor(_core_version()) + '"']
    note = ""
    if pkg.plugin_distribution and pkg.plugin_distribution not in ("gymprecice-core", pkg.dist):
        dependencies.append(f'"{pkg.plugin_distribution}>={_minor(pkg.plugin_version)}"')
        note = f"\n# {pkg.plugin_distribution}: the plugin of the solver kind {pkg.kind}"
    role = (
        "It is the package's solver, on real preCICE and on the test double: replace its "
        "model with your own."
        if case.own_program
        else f"It stands in for the {pkg.kind} solver when the env runs on the test double "
        "(double=True), with a crude model of its response."
    )
    solver_edit = (
        " `solver.py` is the solver: replace its model."
        if case.own_program
        else f" `{STAND_IN_DIR}/solver.py` is the solver's stand-in on the test double."
    )
    return {
        "name": pkg.name,
        "dist": pkg.dist,
        "module": pkg.module,
        "class_name": pkg.class_name,
        "env_id": pkg.env_id,
        "kind": pkg.kind,
        "plugin": pkg.plugin,
        "plugin_distribution": f" (distribution {pkg.plugin_distribution})"
        if pkg.plugin_distribution
        else "",
        "plugin_dependency_note": note,
        "dependencies": ", ".join(dependencies),
        "folder": folder,
        "case_path": f"{folder}/src/{pkg.module}/case",
        "stand_in_path": f"src/{pkg.module}/case/{stand_in_dir}/solver.py",
        "stand_in_dir": stand_in_dir,
        "description": case.description,
        "description_sentence": case.description[:1].upper() + case.description[1:],
        "double_readme": "the package's solver"
        if case.own_program
        else f"the package's stand-in for the {pkg.kind} solver",
        "task": case.task,
        "actuation_text": case.actuation_text,
        "sensing_text": case.sensing_text,
        "solver_text": case.solver_text,
        "real_run_text": case.real_run_text,
        "solver_edit_text": solver_edit,
        "solver_name": case.solver_name,
        "solver_dir": case.solver_dir,
        "participant": case.participant,
        "mesh": case.mesh,
        "write": case.write,
        "read": case.read,
        "write_type": "vector" if case.write_vector else "scalar",
        "read_type": "vector" if case.read_vector else "scalar",
        "write_unit": case.write_unit,
        "read_unit": case.read_unit,
        "read_vector": case.read_vector,
        "actuation_constraint": case.actuation_constraint,
        "window": case.window,
        "windows": case.windows,
        "end_time": case.end_time,
        "action_time": round(case.window * case.windows, 9),
        "steps": steps,
        "n_sensors": len(sensors),
        "action_shape": action_shape,
        "action_text": action_text,
        "stand_in_entry": literal(
            stand_in_entry, 0, WIDTH - len("STAND_IN: dict[str, Any] | None = ")
        ),
        "actuators": literal(actuators, 0, WIDTH - len("ACTUATORS = ")),
        "sensors": literal(sensors, 0, WIDTH - len("SENSORS = ")),
        "stand_in_vertices": literal(unique, 0, WIDTH - len("VERTICES = np.array()")),
        "reference": float(case.reference),
        "actuation_scale": float(case.actuation_scale),
        "vector_actuation": case.write_vector,
        "setpoints": literal(tuple(float(s) for s in case.setpoints)),
        "sensor_scale": float(case.sensor_scale),
        "discrete": pkg.actuator == "discrete",
        "gain": float(case.gain),
        "stand_in_reference": float(case.stand_in_reference),
        "tau": float(case.tau),
        "total": case.total,
        "total_or_mean": "sum" if case.total else "mean",
        "stand_in_title": "The package's solver"
        if case.own_program
        else f"A stand-in for the {pkg.kind} solver",
        "stand_in_role": role,
        "double_what": "the same program"
        if case.own_program
        else f"the stand-in solver ``case/{STAND_IN_DIR}/solver.py``",
    }


def _core_version() -> str:
    from gymprecice.tools.distribution import core_version

    return core_version()


def _minor(version: str | None) -> str:
    """``0.2`` of ``0.2.0``: the oldest release the new package accepts."""
    numbers = re.findall(r"\d+", version or "")
    return ".".join(numbers[:2]) if len(numbers) >= 2 else "0"


def _case_config(pkg: NewPackage) -> dict[str, Any]:
    case = pkg.case
    return {
        "environment": {"name": pkg.dist},
        "precice": {"config_file": "precice-config.xml", "library": "precice"},
        "physics_simulation_engine": {
            "solvers": {
                case.solver_name: {
                    "kind": pkg.kind,
                    "path": case.solver_dir,
                    "participant": case.participant,
                    "options": case.options,
                }
            }
        },
        "controller": {
            "participant": "Controller",
            "write_to": {"actuator": case.write},
            "read_from": {"sensor": case.read},
        },
        "actions": {"windows": case.windows, "scheme": "hold"},
        "timeouts": case.timeouts,
    }


def package_files(pkg: NewPackage, folder: str | None = None) -> dict[str, str]:
    """Every file of the package, by its path in the package's folder."""
    values = _values(pkg, folder or pkg.name)
    src = f"src/{pkg.module}"
    case = f"{src}/case"
    files = {
        "pyproject.toml": t.PYPROJECT,
        "README.md": t.README,
        ".gitignore": t.GITIGNORE,
        f"{src}/__init__.py": t.INIT,
        f"{src}/plugin.py": t.SOLVER_PLUGIN if pkg.solver_plugin else t.PLUGIN,
        f"{src}/env.py": t.ENV,
        f"{case}/precice-config.xml": t.PRECICE_CONFIG,
        "tests/test_env.py": t.TESTS,
    }
    if pkg.solver_plugin:
        files["tests/test_conformance.py"] = t.CONFORMANCE_TESTS
    for relative, text in pkg.case.files.items():
        files[f"{case}/{pkg.case.solver_dir}/{relative}"] = text
    stand_in_dir = pkg.case.solver_dir if pkg.case.own_program else STAND_IN_DIR
    files[f"{case}/{stand_in_dir}/solver.py"] = t.STAND_IN
    out = {path: render(text, values) for path, text in files.items()}
    for path, text in out.items():
        if path.endswith(".py"):
            out[path] = wrap_docstrings(text)
        elif path.endswith(".md"):
            out[path] = wrap_markdown(text)
    out[f"{case}/gymprecice-config.json"] = to_json(_case_config(pkg)) + "\n"
    return dict(sorted(out.items()))
