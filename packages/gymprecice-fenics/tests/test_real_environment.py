"""The plugin against the real FEniCS solver environment (``gymprecice install fenics``).

Skipped where the environment is missing; CI (``GYMPRECICE_REQUIRE_REAL=1``) fails instead.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.errors import CaseError
from gymprecice_fenics import plugin, solver_env

pytestmark = [
    pytest.mark.fenics,
    pytest.mark.skipif(
        not solver_env.probe().ok,
        reason="needs the FEniCS solver environment: " + "; ".join(solver_env.probe().problems),
    ),
]


def test_the_environment_has_debians_dolfin_numpy_1_and_precice_3() -> None:
    """Cost: about 1 s (one probe of the FEniCS interpreter)."""
    report = solver_env.probe()
    assert report.versions["numpy"].startswith("1.")
    assert report.versions["dolfin"].startswith("2019.")
    assert report.versions["precice"].lstrip("v").startswith("3.")
    assert report.versions["fenicsprecice"] == solver_env.FENICSPRECICE_VERSION


def test_dry_run_gives_the_scripts_coupling_vertices(make_fenics_solver) -> None:
    """Cost: about 2 s (a dry run of the FEniCS script: dolfin's import and mesh)."""
    solver = make_fenics_solver(python=Path(solver_env.fenics_python()))
    assert plugin.gymprecice_prepare_case(solver) is True
    geometry = plugin.gymprecice_interface_geometry(solver, "top", "Solid-Mesh")
    # The plate's top edge y = 0 with 10 cells: 11 vertices, as fenicsprecice sets them.
    assert geometry.coordinates.shape == (11, 2)
    np.testing.assert_allclose(sorted(geometry.coordinates[:, 0]), np.linspace(0, 1, 11))
    np.testing.assert_allclose(geometry.coordinates[:, 1], 0.0)


def test_a_script_importing_a_module_beside_it_dry_runs(make_fenics_solver) -> None:
    """As ``python solid.py`` does, the dry run finds the script's own modules beside it
    (FSI3's bar is ``bar.py`` beside ``solid.py``). Cost: about 2 s."""
    solver = make_fenics_solver(python=Path(solver_env.fenics_python()))
    script = solver.run_dir / "solid.py"
    (solver.run_dir / "helper_beside.py").write_text("CELLS = 10\n")
    script.write_text("import helper_beside\n" + script.read_text())
    assert plugin.gymprecice_prepare_case(solver) is True


def test_a_script_failing_at_import_is_named_with_its_error(make_fenics_solver) -> None:
    """Cost: about 2 s (two dry runs of the FEniCS interpreter)."""
    solver = make_fenics_solver(python=Path(solver_env.fenics_python()))
    script = solver.run_dir / "solid.py"
    script.write_text("import mshr_that_is_not_installed\n" + script.read_text())
    with pytest.raises(CaseError) as info:
        plugin.gymprecice_prepare_case(solver)
    assert "solid.py failed" in str(info.value)
    assert "No module named 'mshr_that_is_not_installed'" in str(info.value)


def test_gymprecices_own_interpreter_is_refused_for_numpy_2_and_no_dolfin(
    make_fenics_solver,
) -> None:
    """Cost: under a second (two interpreter probes)."""
    import numpy

    solver = make_fenics_solver(python=Path(sys.executable))
    with pytest.raises(CaseError) as info:
        plugin.gymprecice_prepare_case(solver)
    assert "cannot import dolfin" in str(info.value)
    # gymprecice's own environment has numpy 2, which fenicsprecice refuses.
    numpy_2 = int(numpy.__version__.split(".")[0]) >= 2
    assert ("numpy<2" in str(info.value)) == numpy_2


def test_a_form_that_fails_to_compile_is_explained(make_fenics_solver, tmp_path: Path) -> None:
    """Cost: about 1 s (one dry run that fails in dolfin's form compiler)."""
    bad = tmp_path / "bad_form.py"
    bad.write_text(
        "from fenics import *\n"
        "mesh = UnitSquareMesh(2, 2)\n"
        "V = FunctionSpace(mesh, 'P', 1)\n"
        "u, v = TrialFunction(V), TestFunction(V)\n"
        "f = Function(V)\n"
        "solve(inner(grad(u), v) * dx == f * v * dx, f)\n"
    )
    proc = subprocess.run(
        [solver_env.fenics_python(), str(bad)], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode != 0
    solver = make_fenics_solver(python=Path(solver_env.fenics_python()))
    answer = plugin.gymprecice_check_solver(solver, proc.stdout + proc.stderr)
    assert answer is not None and "failed to compile" in answer and "Shapes do not match" in answer
