"""Divergence of the deal.II solid solver: a non-finite or absurd displacement."""

from __future__ import annotations

import math
from pathlib import Path

import pluggy
import pytest

from gymprecice import hookspecs
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.solver import SolverContext
from gymprecice_dealii import plugin

HEADER = "  Time  Coordinate0  Coordinate1  Displacement0  Displacement1  Force0  Force1"


def _row(t: float, dx: float, dy: float) -> str:
    return "\n" + "  ".join(f"{v:15.8e}" for v in (t, 0.0, 1.0, dx, dy, 0.0, 0.0))


@pytest.fixture
def pm() -> pluggy.PluginManager:
    manager = pluggy.PluginManager(hookspecs.PROJECT_NAME)
    manager.add_hookspecs(hookspecs)
    manager.register(plugin)
    return manager


def _solver(tmp_path: Path, *rows: str, **options) -> SolverContext:
    # preCICE writes the newline before each row: the file never ends with one
    (tmp_path / "precice-Solid-watchpoint-Flap-Tip.log").write_text(HEADER + "".join(rows))
    return SolverContext(
        name="solid",
        kind="dealii",
        run_dir=tmp_path,
        source_dir=tmp_path,
        env_dir=tmp_path,
        options=options,
    )


def _detect(pm, solver, log="", returncode=None):
    return pm.hook.gymprecice_detect_divergence(solver=solver, log_text=log, returncode=returncode)


def test_a_sane_displacement_is_not_divergence(pm, tmp_path):
    solver = _solver(tmp_path, _row(0.0, 0.0, 0.0), _row(0.01, 0.02, 0.0), max_displacement=1)
    assert _detect(pm, solver) is None
    assert _detect(pm, solver, "Segmentation fault\n", -11) is None


def test_a_non_finite_displacement_is_divergence_while_the_solver_runs(pm, tmp_path):
    solver = _solver(tmp_path, _row(0.0, 0.0, 0.0), _row(0.01, math.nan, 0.0))
    evidence = _detect(pm, solver)
    assert "nan" in evidence and "t = 0.01" in evidence and "Flap-Tip" in evidence


def test_an_absurd_displacement_passes_the_configured_limit(pm, tmp_path):
    rows = (_row(0.0, 0.0, 0.0), _row(0.02, 3.0, 4.0))
    evidence = _detect(pm, _solver(tmp_path, *rows, max_displacement=1))
    assert "|d| = 5 > max_displacement 1" in evidence
    assert _detect(pm, _solver(tmp_path, *rows, max_displacement=10)) is None
    assert _detect(pm, _solver(tmp_path, *rows)) is None  # no limit: only non-finite


def test_a_solver_that_gave_up_converging_diverged(pm, tmp_path):
    solver = _solver(tmp_path, _row(0.0, 0.0, 0.0))
    log = "An error occurred ...\nIterative method reported convergence failure in step 1000.\n"
    assert "convergence failure" in _detect(pm, solver, log, 1)
    assert _detect(pm, solver, log, None) is None  # running: the watch reads displacements


def test_a_nonlinear_solver_whose_newton_iterations_gave_up_diverged(pm, tmp_path):
    """The neo-Hookean solver (FSI3's bar) aborts so when a time step loads it too hard."""
    solver = _solver(tmp_path, _row(0.0, 0.0, 0.0))
    log = "Additional information: \n    No convergence in nonlinear solver!\nAborting!\n"
    assert "No convergence in nonlinear solver" in _detect(pm, solver, log, 134)


@pytest.mark.parametrize("value", [0, -1.0, "big", math.inf])
def test_a_displacement_limit_that_is_not_positive_is_refused(pm, tmp_path, value):
    solver = _solver(tmp_path, _row(0.0, 0.0, 0.0), max_displacement=value)
    with pytest.raises(ConfigError, match=r"options\.max_displacement is .* positive number"):
        _detect(pm, solver)
