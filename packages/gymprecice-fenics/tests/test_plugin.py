"""The FEniCS plugin's hooks on the plate case, with stand-in interpreters.

Each bad input of a FEniCS participant gets an error that names the file or interpreter
and the fix, before any solver starts.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.errors import CaseError, ConfigError
from gymprecice.tools.stack import BuildContext, BuildError
from gymprecice_fenics import plugin, solver_env

TRACEBACK = (
    "Traceback (most recent call last):\n"
    '  File "solid.py", line 3, in <module>\n'
    "    import mshr\n"
    "ModuleNotFoundError: No module named 'mshr'\n"
)


def test_prepare_points_the_adapter_file_at_the_envs_xml_and_keeps_the_geometry(
    make_fenics_solver,
) -> None:
    solver = make_fenics_solver()
    assert plugin.gymprecice_prepare_case(solver) is True
    adapter = json.loads((solver.run_dir / "precice-adapter-config.json").read_text())
    xml = (solver.run_dir / adapter["config_file_name"]).resolve()
    assert xml == solver.precice_config_file.resolve()
    geometry = plugin.gymprecice_interface_geometry(solver, "heater", "Solid-Mesh")
    assert geometry is not None
    np.testing.assert_allclose(geometry.coordinates[:, 0], np.linspace(0, 1, 11))
    assert plugin.gymprecice_interface_geometry(solver, "heater", "Fluid-Mesh") is None


def test_a_second_mesh_the_script_sets_through_the_participant_has_its_geometry(
    make_fenics_solver,
) -> None:
    heater = [[0.5 * i, -0.25] for i in range(3)]
    solver = make_fenics_solver(
        dry_run={
            "participant": "Solid",
            "mesh": "Solid-Mesh",
            "coordinates": [[0.0, 0.0], [1.0, 0.0]],
            "meshes": {"Solid-Mesh": [[0.0, 0.0], [1.0, 0.0]], "Solid-Mesh-heater": heater},
        }
    )
    assert plugin.gymprecice_prepare_case(solver) is True
    geometry = plugin.gymprecice_interface_geometry(solver, "heater", "Solid-Mesh-heater")
    np.testing.assert_allclose(geometry.coordinates, heater)
    assert len(plugin.gymprecice_interface_geometry(solver, "plate", "Solid-Mesh").coordinates) == 2


def test_no_fenics_on_the_machine_is_reported_with_the_install_commands(
    make_fenics_solver, tmp_path: Path
) -> None:
    solver = make_fenics_solver(python=tmp_path / "nowhere" / "python")
    for hook in (plugin.gymprecice_prepare_case, plugin.gymprecice_launch_solver):
        with pytest.raises(CaseError) as info:
            hook(solver)
        message = str(info.value)
        assert "nowhere/python does not exist" in message
        assert "apt-get install python3-dolfin" in message
        assert "gymprecice install fenics" in message


def test_an_environment_without_dolfin_is_named(make_fenics_solver) -> None:
    solver = make_fenics_solver(missing={"dolfin": "ModuleNotFoundError: No module named 'dolfin'"})
    with pytest.raises(CaseError, match=r"cannot import dolfin.*apt-get install python3-dolfin"):
        plugin.gymprecice_prepare_case(solver)


def test_numpy_2_in_the_solver_environment_is_refused(make_fenics_solver) -> None:
    solver = make_fenics_solver(
        versions={"numpy": "2.1.3", "dolfin": "2019.2.0", "precice": "3.4.1"}
    )
    with pytest.raises(CaseError, match=r"numpy 2\.1\.3.*numpy<2.*gymprecice install fenics"):
        plugin.gymprecice_prepare_case(solver)


def test_a_script_failing_at_import_is_reported_before_coupling(make_fenics_solver) -> None:
    solver = make_fenics_solver(dry_run_stderr=TRACEBACK, dry_run_status=3)
    with pytest.raises(CaseError) as info:
        plugin.gymprecice_prepare_case(solver)
    message = str(info.value)
    assert "solid.py failed" in message
    assert "No module named 'mshr'" in message


def test_a_script_that_never_couples_is_reported(make_fenics_solver) -> None:
    solver = make_fenics_solver(dry_run={}, dry_run_status=4)
    with pytest.raises(CaseError, match=r"without calling fenicsprecice's Adapter\.initialize"):
        plugin.gymprecice_prepare_case(solver)


def test_an_empty_coupling_subdomain_is_reported(make_fenics_solver) -> None:
    solver = make_fenics_solver(
        dry_run={"participant": "Solid", "mesh": "Solid-Mesh", "coordinates": []}
    )
    with pytest.raises(CaseError, match="contains no mesh vertex"):
        plugin.gymprecice_prepare_case(solver)


def test_a_controller_writing_heat_flux_where_the_script_reads_temperature(
    make_fenics_solver, case: Path
) -> None:
    # A controller participant sends Heat-Flux to the solid's mesh, the script reads
    # Temperature there: validation names both files before anything starts.
    xml = case / "precice-config.xml"
    xml.write_text(
        xml.read_text()
        .replace(
            '<exchange data="Temperature" mesh="Fluid-Mesh" from="Fluid" to="Solid" />',
            '<exchange data="Heat-Flux" mesh="Fluid-Mesh" from="Fluid" to="Solid" />',
        )
        .replace(
            '<read-data name="Temperature" mesh="Solid-Mesh" />',
            '<read-data name="Temperature" mesh="Solid-Mesh" />\n'
            '    <read-data name="Heat-Flux" mesh="Solid-Mesh" />',
        )
        .replace(
            '<write-data name="Temperature" mesh="Fluid-Mesh" />',
            '<write-data name="Temperature" mesh="Fluid-Mesh" />\n'
            '    <write-data name="Heat-Flux" mesh="Fluid-Mesh" />',
        )
    )
    solver = make_fenics_solver()
    from gymprecice.plugin.precice_xml import load_precice_config

    solver.precice = load_precice_config(xml)
    (problem,) = plugin.gymprecice_validate_case(solver)
    assert "reads 'Temperature'" in problem and "'Heat-Flux' from 'Fluid'" in problem
    with pytest.raises(CaseError, match="reads 'Temperature'"):
        plugin.gymprecice_prepare_case(solver)


def test_unknown_options_and_a_missing_script_are_config_errors(make_fenics_solver) -> None:
    solver = make_fenics_solver(options={"np": 2})
    (problem,) = plugin.gymprecice_validate_case(solver)
    assert "unknown option(s) ['np']" in problem
    solver = make_fenics_solver(options={"script": "plate.py"})
    (problem,) = plugin.gymprecice_validate_case(solver)
    assert "plate.py does not exist" in problem and "options.script" in problem
    with pytest.raises(ConfigError, match="threads"):
        plugin.gymprecice_launch_solver(make_fenics_solver(options={"threads": 0}))


def test_reset_removes_outputs_and_precice_logs_only(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    run = solver.run_dir
    for folder in ("output", "precice-profiling", "precice-exports"):
        (run / folder).mkdir()
        (run / folder / "x").write_text("old")
    (run / "precice-Solid-iterations.log").write_text("old")
    assert plugin.gymprecice_reset_case(solver) is True
    assert sorted(p.name for p in run.iterdir()) == ["precice-adapter-config.json", "solid.py"]


def test_launch_runs_the_script_unbuffered_with_the_fenics_interpreter(make_fenics_solver) -> None:
    solver = make_fenics_solver(options={"threads": 2})
    spec = plugin.gymprecice_launch_solver(solver)
    assert list(spec.argv) == [solver.options["python"], "-u", "solid.py"]
    assert spec.cwd == solver.run_dir
    assert spec.env["OMP_NUM_THREADS"] == "2"
    assert spec.env["PYTHONPATH"] == ""  # gymprecice's packages stay out of the solver's Python


@pytest.mark.parametrize(
    ("log", "needle"),
    [
        (TRACEBACK, "No module named 'mshr'; fix the script"),
        (
            'Traceback (most recent call last):\n  File "ufl/log.py"\n'
            "ufl.log.UFLException: Shapes do not match: <Grad> and <Argument>.\n",
            "failed to compile",
        ),
        (
            "Traceback (most recent call last):\nImportError: numpy.core.multiarray failed to import\n",
            "numpy<2",
        ),
        (
            "Traceback (most recent call last):\nModuleNotFoundError: No module named 'dolfin'\n",
            "apt-get install python3-dolfin",
        ),
    ],
)
def test_check_solver_explains_a_traceback(make_fenics_solver, log: str, needle: str) -> None:
    solver = make_fenics_solver()
    answer = plugin.gymprecice_check_solver(solver, "some output\n" + log)
    assert answer is not None and needle in answer and "solid.py" in answer
    assert plugin.gymprecice_check_solver(solver, "---[precice] Time window completed\n") is None


def test_divergence_is_a_petsc_divergence_at_exit_only(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    log = "Solving linear system\nPETSc KSP solve DIVERGED_ITS after 10000 iterations\n"
    assert plugin.gymprecice_detect_divergence(solver, log, None) is None
    assert "DIVERGED_ITS" in plugin.gymprecice_detect_divergence(solver, log, 1)
    assert plugin.gymprecice_detect_divergence(solver, "Segfault\n", 1) is None


def test_doctor_says_how_to_get_a_missing_environment(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setenv(solver_env.PYTHON_ENV, str(tmp_path / "python"))
    checks = {c.name: c for c in plugin.gymprecice_doctor_checks()}
    env_check = checks["FEniCS solver environment"]
    assert env_check.ok is False and "gymprecice install fenics" in env_check.advice


def test_install_step_requires_precice_and_names_debians_fenics(
    monkeypatch, tmp_path: Path
) -> None:
    (step,) = plugin.gymprecice_install_steps()
    assert step.name == "fenics" and step.requires == ("precice",)
    monkeypatch.setattr(solver_env, "SYSTEM_PYTHON", str(tmp_path / "no-python3"))
    ctx = BuildContext(step, tmp_path / "prefix", tmp_path, tmp_path / "log", 1, say=lambda _: None)
    with pytest.raises(
        BuildError, match="apt-get install python3-dolfin python3-scipy python3-venv"
    ):
        step.build(ctx)
    assert step.built(tmp_path / "prefix") is None
