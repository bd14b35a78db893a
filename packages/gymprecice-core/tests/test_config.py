from __future__ import annotations

import json
from pathlib import Path

import pytest

from gymprecice.env.config import SolverSpec, check_solver_kinds, load_config
from gymprecice.plugin.errors import ConfigError


def _write(case: Path, config: dict) -> Path:
    path = case / "gymprecice-config.json"
    path.write_text(json.dumps(config))
    return path


def test_explicit_form_resolves_interfaces_and_partner_meshes(case_dir: Path) -> None:
    cfg = load_config(case_dir)
    assert cfg.participant == "Controller"
    assert set(cfg.interfaces) == {"jet1", "jet2", "probe"}
    jet1 = cfg.interfaces["jet1"]
    assert (jet1.mesh, jet1.write, jet1.read, jet1.dimensions) == (
        "Controller-Mesh-jet1",
        ("Velocity",),
        (),
        2,
    )
    assert (jet1.partner, jet1.partner_mesh) == ("Fluid", "Fluid-Mesh-jet1")
    assert cfg.interfaces["probe"].read == ("Pressure",)
    assert cfg.solvers["fluid"].kind == "command"
    assert cfg.end_time == pytest.approx(0.01)


def test_paper_form_is_accepted(case_dir: Path) -> None:
    (case_dir / "fluid-openfoam").mkdir()
    for script in ("reset.sh", "run.sh"):
        (case_dir / "fluid-openfoam" / script).write_text("#!/bin/sh\n")
        (case_dir / "fluid-openfoam" / script).chmod(0o755)
    path = _write(
        case_dir,
        {
            "environment": {"name": "jet_cylinder"},
            "physics_simulation_engine": {
                "solvers": ["fluid-openfoam"],
                "reset_script": "reset.sh",
                "run_script": "run.sh",
            },
            "controller": {"read_from": {}, "write_to": {"jet1": "Velocity", "jet2": "Velocity"}},
        },
    )
    cfg = load_config(path)
    solver = cfg.solvers["fluid-openfoam"]
    assert solver.kind == "script"
    assert solver.options == {"run_script": "run.sh", "reset_script": "reset.sh"}


def test_dict_source_uses_case_dir(case_dir: Path, base_config) -> None:
    cfg = load_config(base_config(), case_dir=case_dir)
    assert cfg.file is None and cfg.case_dir == case_dir.resolve()


@pytest.mark.parametrize(
    ("mutate", "patterns"),
    [
        (
            lambda c: c["controller"].update(wirte_to={}),
            ["unknown key 'controller.wirte_to'", "write_to"],
        ),
        (lambda c: c.update(bogus=1), ["unknown key 'bogus'", "physics_simulation_engine"]),
        (
            lambda c: c["physics_simulation_engine"]["solvers"]["fluid"].update(knd="x"),
            ["unknown key 'physics_simulation_engine.solvers.fluid.knd'", "participant"],
        ),
        (lambda c: c.update(actions={"windows": 0}), ["actions.windows"]),
        (lambda c: c.update(actions={"scheme": "smooth"}), ["actions.scheme", "hold"]),
        (lambda c: c.pop("physics_simulation_engine"), ["missing key 'physics_simulation_engine'"]),
    ],
)
def test_schema_errors_name_file_and_key(case_dir: Path, base_config, mutate, patterns) -> None:
    config = base_config()
    mutate(config)
    path = _write(case_dir, config)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    message = str(info.value)
    assert str(path) in message
    for pattern in patterns:
        assert pattern in message


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [
        (lambda c: c["controller"].update(participant="Ctrl"), "has no such participant"),
        (lambda c: c["controller"]["write_to"].update(jet3="Velocity"), "interface 'jet3'"),
        (
            lambda c: c["controller"]["write_to"].update(jet1="Pressure"),
            "write 'Pressure' on mesh 'Controller-Mesh-jet1'",
        ),
        (lambda c: c["controller"]["read_from"].update(probe="Velocity"), "read 'Velocity'"),
        (lambda c: c["controller"].update(meshes={"jet1": "Nope"}), "provides no such mesh"),
        (
            lambda c: c["physics_simulation_engine"]["solvers"]["fluid"].update(
                participant="Solid"
            ),
            "solvers.fluid.participant",
        ),
    ],
)
def test_cross_check_names_both_files(case_dir: Path, base_config, mutate, pattern) -> None:
    config = base_config()
    mutate(config)
    path = _write(case_dir, config)
    with pytest.raises(ConfigError, match=pattern) as info:
        load_config(path)
    assert str(path) in str(info.value)
    assert str(case_dir / "precice-config.xml") in str(info.value)


def test_missing_solver_dir_and_precice_file(case_dir: Path, base_config) -> None:
    config = base_config()
    config["physics_simulation_engine"]["solvers"]["fluid"]["path"] = "nowhere"
    with pytest.raises(ConfigError, match=r"nowhere.*does not exist"):
        load_config(_write(case_dir, config))
    config = base_config(precice={"config_file": "missing.xml"})
    with pytest.raises(ConfigError, match=r"precice\.config_file"):
        load_config(_write(case_dir, config))


def test_invalid_json_reports_line(case_dir: Path) -> None:
    (case_dir / "gymprecice-config.json").write_text('{"environment": {,}')
    with pytest.raises(ConfigError, match=r"gymprecice-config.json:1:\d+: not valid JSON"):
        load_config(case_dir)


def test_paper_form_without_run_script(case_dir: Path) -> None:
    path = _write(
        case_dir,
        {
            "physics_simulation_engine": {"solvers": ["fluid"]},
            "controller": {"write_to": {"jet1": "Velocity"}},
        },
    )
    with pytest.raises(ConfigError, match="run_script is missing"):
        load_config(path)


def test_unknown_kind_lists_installed(case_dir: Path) -> None:
    cfg = load_config(case_dir)
    with pytest.raises(
        ConfigError,
        match=r"'command'.*installed kinds: \['openfoam'\].*pip install gymprecice-command",
    ):
        check_solver_kinds(cfg, {"openfoam": "OpenFOAM"})
    check_solver_kinds(cfg, {"command": "argv"})


def test_misspelled_kind_suggests_the_closest_installed_kind(case_dir: Path) -> None:
    cfg = load_config(case_dir)
    cfg.solvers["fluid"].kind = "comand"
    with pytest.raises(ConfigError) as info:
        check_solver_kinds(cfg, {"command": "argv", "script": "scripts", "openfoam": "OF"})
    message = str(info.value)
    assert "did you mean 'command'?" in message and "solvers.fluid.kind" in message
    assert "pip install" not in message and str(cfg.file) in message


def test_misspelled_core_option_fails_at_load_naming_the_file(case_dir: Path) -> None:
    path = case_dir / "gymprecice-config.json"
    raw = json.loads(path.read_text())
    raw["physics_simulation_engine"]["solvers"]["fluid"]["options"]["reset_timout"] = 5
    path.write_text(json.dumps(raw))
    with pytest.raises(ConfigError) as info:
        load_config(case_dir)
    assert str(path) in str(info.value)
    assert "'reset_timout' (did you mean 'reset_timeout'?)" in str(info.value)
    # a problem of gymprecice-config.json, not a disagreement with the preCICE file
    assert "does not agree with" not in str(info.value)
    assert "has problems in its case" in str(info.value)


def test_a_problem_against_the_precice_file_says_so(case_dir: Path) -> None:
    from gymprecice.plugin.hookspecs import hookimpl
    from gymprecice.plugin.manager import temporary_plugin

    class MeshNames:
        @hookimpl
        def gymprecice_validate_case(self, solver):
            if solver.kind != "command":
                return None
            xml = solver.precice_config_file
            return [f"case.cfg: mesh 'Rod-Mesh' is not in {xml}; use one of its meshes"]

    agree = r"does not agree with .*precice-config.xml:\n"
    with temporary_plugin(MeshNames(), "mesh-names"), pytest.raises(ConfigError, match=agree):
        load_config(case_dir)


def test_a_kind_of_a_plugin_that_failed_to_load_shows_its_import_error(case_dir: Path) -> None:
    """Installed but broken is not missing: `pip install` would change nothing."""
    from gymprecice.plugin.manager import PluginFailure

    cfg = load_config(case_dir)
    cfg.solvers["fluid"].kind = "rod"
    broken = PluginFailure(
        "rod", "gymprecice-rod", "0.1", "cannot import 'rod_plugin': ModuleNotFoundError: numba"
    )
    with pytest.raises(ConfigError) as info:
        check_solver_kinds(cfg, {"command": "argv"}, [broken])
    message = str(info.value)
    assert "'rod' (from gymprecice-rod 0.1): cannot import 'rod_plugin'" in message
    assert "ModuleNotFoundError: numba" in message and "pip install" not in message


def test_solver_cpus_adds_up_each_solvers_np_one_when_unset(case_dir: Path) -> None:
    cfg = load_config(case_dir)
    assert cfg.solver_cpus == 1  # one serial solver
    # np is an option of the kinds that run MPI (openfoam, dealii), not of "command"
    cfg.solvers = {
        "fluid": SolverSpec("fluid", "openfoam", "fluid", "Fluid", {"np": 4}),
        "solid": SolverSpec("solid", "dealii", "solid", "Solid", {"np": None}),
        "heat": SolverSpec("heat", "fenics", "heat", "Heat"),
    }
    assert [spec.cpus for spec in cfg.solvers.values()] == [4, 1, 1]
    assert cfg.solver_cpus == 6
