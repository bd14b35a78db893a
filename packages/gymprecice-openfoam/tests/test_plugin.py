"""The hooks as core calls them: through pluggy, answering only for kind "openfoam"."""

from __future__ import annotations

from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pluggy
import pytest

from gymprecice import hookspecs
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import MeshSpec, PreciceConfig
from gymprecice.plugin.solver import SolverContext
from gymprecice_openfoam import case, outputs, plugin, testing


@pytest.fixture
def pm() -> pluggy.PluginManager:
    manager = pluggy.PluginManager(hookspecs.PROJECT_NAME)
    manager.add_hookspecs(hookspecs)
    manager.register(plugin)
    return manager


def _solver(tmp_path: Path, kind: str = "openfoam", **kw) -> SolverContext:
    run_dir = tmp_path / "run"
    (run_dir / "system").mkdir(parents=True, exist_ok=True)
    return SolverContext(
        name="fluid",
        kind=kind,
        run_dir=run_dir,
        source_dir=tmp_path / "src",
        env_dir=tmp_path,
        **kw,
    )


def test_entry_point_and_kinds(pm):
    names = {ep.name: ep.value for ep in entry_points(group="gymprecice")}
    assert names.get("openfoam") == "gymprecice_openfoam.plugin"
    kinds = {}
    for answer in pm.hook.gymprecice_solver_kinds():
        kinds.update(answer)
    assert "openfoam" in kinds


def test_other_kinds_are_left_to_other_plugins(pm, tmp_path):
    other = _solver(tmp_path, kind="dealii")
    assert pm.hook.gymprecice_prepare_case(solver=other) is None
    assert pm.hook.gymprecice_reset_case(solver=other) is None
    assert pm.hook.gymprecice_launch_solver(solver=other) is None
    assert pm.hook.gymprecice_check_solver(solver=other, log_text="") is None
    assert pm.hook.gymprecice_interface_geometry(solver=other, interface="i", mesh="m") is None
    assert pm.hook.gymprecice_open_output(solver=other, name="watchpoint", options={}) is None


def test_openfoam_format_outputs_of_any_solver_kind_can_be_read(pm, tmp_path):
    # e.g. a scripted partner of kind "command" that writes OpenFOAM-format probes
    other = _solver(tmp_path, kind="command")
    assert pm.hook.gymprecice_open_output(solver=other, name="probes", options={}) is None
    other.options = {"outputs": "openfoam"}
    probes = other.run_dir / "postProcessing" / "probes" / "0"
    probes.mkdir(parents=True)
    (probes / "p").write_text("# Probe 0 (0 0 0)\n#  Time  0\n0.1  2.5\n")
    reader = pm.hook.gymprecice_open_output(solver=other, name="probes", options={"field": "p"})
    rows = reader.read_new()
    assert rows.time.tolist() == [0.1] and rows.values.ravel().tolist() == [2.5]
    reader.close()


def test_open_output_builds_readers_from_the_episode_start(pm, tmp_path):
    solver = _solver(tmp_path)
    solver.state["initial_time"] = 0.2
    post = solver.run_dir / "postProcessing"
    (post / "probes" / "0").mkdir(parents=True)
    (post / "probes" / "0" / "p").write_text("# Probe 0 (0 0 0)\n# Time\n0.1 5\n")
    (post / "probes" / "0.2").mkdir()
    (post / "probes" / "0.2" / "p").write_text("# Probe 0 (0 0 0)\n# Time\n0.3 7\n")
    reader = pm.hook.gymprecice_open_output(solver=solver, name="probes", options={})
    assert isinstance(reader, outputs.ProbesReader)  # the only field: found by itself
    np.testing.assert_array_equal(reader.read_new().values, [[7.0]])  # the pre-run's 0.1 skipped
    (post / "lift" / "0.2").mkdir(parents=True)
    (post / "lift" / "0.2" / "coefficient.dat").write_text("# Time Cd Cl\n0.3 1 2\n")
    coeffs = pm.hook.gymprecice_open_output(solver=solver, name="lift", options={})
    assert isinstance(coeffs, outputs.ForceCoeffsReader)
    assert coeffs.read_new().column("Cl")[0] == 2.0
    forces = pm.hook.gymprecice_open_output(
        solver=solver, name="forces", options={"object": "f2", "which": "moment"}
    )
    assert isinstance(forces, outputs.ForcesReader) and forces.which == "moment"
    with pytest.raises(ConfigError, match="unknown options"):
        pm.hook.gymprecice_open_output(solver=solver, name="probes", options={"field": "p", "x": 1})
    (post / "probes" / "0.2" / "U").write_text("")
    with pytest.raises(ConfigError, match="field="):
        pm.hook.gymprecice_open_output(solver=solver, name="probes", options={})


def test_interface_geometry_hook(pm, tmp_path):
    solver = _solver(tmp_path)
    assert pm.hook.gymprecice_interface_geometry(solver=solver, interface="jet1", mesh="M") is None
    (solver.run_dir / "system" / "preciceDict").write_text(
        testing.precice_dict({"I": {"mesh": "Fluid-Mesh", "patches": ["top"]}})
    )
    # A mesh the adapter does not provide: not ours to describe.
    assert pm.hook.gymprecice_interface_geometry(solver=solver, interface="x", mesh="M") is None
    mesh_dir = solver.run_dir / "constant" / "polyMesh"
    mesh_dir.mkdir(parents=True)
    head = testing.HEADER
    (mesh_dir / "points").write_text(
        head.format(cls="vectorField", obj="points")
        + "4\n(\n(0 0 0)\n(1 0 0)\n(1 0 1)\n(0 0 1)\n)\n"
    )
    (mesh_dir / "faces").write_text(
        head.format(cls="faceList", obj="faces") + "1\n(\n4(0 1 2 3)\n)\n"
    )
    (mesh_dir / "boundary").write_text(
        head.format(cls="polyBoundaryMesh", obj="boundary")
        + "1\n(\n    top\n    {\n        type wall;\n        nFaces 1;\n        startFace 0;\n    }\n)\n"
    )
    solver.precice = PreciceConfig(
        path=tmp_path / "p.xml", meshes={"Fluid-Mesh": MeshSpec("Fluid-Mesh", 2)}
    )
    geometry = pm.hook.gymprecice_interface_geometry(
        solver=solver, interface="jet", mesh="Fluid-Mesh"
    )
    np.testing.assert_allclose(geometry.coordinates, [[0.5, 0.0]])  # 2-D: z dropped
    np.testing.assert_allclose(geometry.normals, [[0.0, -1.0, 0.0]])
    np.testing.assert_allclose(geometry.areas, [1.0])


def test_doctor_lists_openfoam_and_the_adapter(pm):
    checks = [c for answer in pm.hook.gymprecice_doctor_checks() for c in answer]
    names = [c.name for c in checks]
    assert names[0] == "OpenFOAM"
    if checks[0].ok:
        assert "OpenFOAM-preCICE adapter" in names
        adapter = checks[names.index("OpenFOAM-preCICE adapter")]
        assert adapter.ok or "libpreciceAdapterFunctionObject.so" in adapter.detail


@pytest.mark.openfoam
def test_hooks_drive_a_whole_episode_cycle(pm, cylinder_case, solver_for):
    """Cost: under a second (blockMesh; the episode's solver is a stand-in)."""
    solver = solver_for(cylinder_case("fluid", end_time=0.01), np=1)
    assert pm.hook.gymprecice_prepare_case(solver=solver) is True
    spec = pm.hook.gymprecice_launch_solver(solver=solver)
    assert Path(spec.argv[0]).name == "pimpleFoam" and spec.log_name == "log.pimpleFoam"
    assert "WM_PROJECT_DIR" in spec.env
    assert pm.hook.gymprecice_reset_case(solver=solver) is True
    # A reset in a fresh process (empty state) finds what prepare recorded on disk.
    solver.state.clear()
    assert pm.hook.gymprecice_reset_case(solver=solver) is True
    assert isinstance(solver.state["openfoam"], case.PreparedCase)


def test_a_misspelt_option_is_refused_before_anything_runs(pm, tmp_path):
    config = tmp_path / "gymprecice-config.json"
    solver = SolverContext(
        name="fluid",
        kind="openfoam",
        run_dir=tmp_path / "fluid",  # never looked at: the options fail first
        source_dir=tmp_path / "fluid-source",
        env_dir=tmp_path,
        options={"prerun_end_tme": 0.3, "np": 2},
        config_file=config,
    )
    with pytest.raises(ConfigError) as caught:
        pm.hook.gymprecice_prepare_case(solver=solver)
    message = str(caught.value)
    assert str(config) in message
    assert "'prerun_end_tme' (did you mean 'prerun_end_time'?)" in message
    assert "physics_simulation_engine.solvers.fluid.options" in message
    assert not (tmp_path / "fluid").exists()
