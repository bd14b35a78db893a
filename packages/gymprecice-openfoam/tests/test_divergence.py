"""Divergence in OpenFOAM logs, as core asks about it: through the detect-divergence hook."""

from __future__ import annotations

from pathlib import Path

import pluggy
import pytest

from gymprecice import hookspecs
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.solver import SolverContext
from gymprecice_openfoam import plugin

#: pimpleFoam's log, written as the run goes: the Courant number grows step by step
HEALTHY = """\
trapFpe: Floating point exception trapping enabled (FOAM_SIGFPE).
sigFpe : Enabling floating point exception trapping (FOAM_SIGFPE).
Courant Number mean: 0.0213 max: 0.412
deltaT = 0.0005
Time = 0.3355

smoothSolver:  Solving for Ux, Initial residual = 0.0012, Final residual = 1e-07, No Iterations 2
"""
BLOWING_UP = (
    HEALTHY
    + """\
Courant Number mean: 1.9 max: 37.5
deltaT = 0.0005
Time = 0.336
"""
)
FPE = (
    HEALTHY
    + """\
#0  Foam::error::printStack(Foam::Ostream&) at ??:?
#1  Foam::sigFpe::sigHandler(int) at ??:?
#2  ? in /lib/x86_64-linux-gnu/libc.so.6
Floating point exception (core dumped)
"""
)
ITERATIONS = HEALTHY + "--> FOAM FATAL ERROR: Maximum number of iterations exceeded: 100\n"
MISSING_LIBRARY = "pimpleFoam: error while loading shared libraries: libpreciceAdapter.so\n"


@pytest.fixture
def pm() -> pluggy.PluginManager:
    manager = pluggy.PluginManager(hookspecs.PROJECT_NAME)
    manager.add_hookspecs(hookspecs)
    manager.register(plugin)
    return manager


def _solver(tmp_path: Path, kind: str = "openfoam", **options) -> SolverContext:
    return SolverContext(
        name="fluid",
        kind=kind,
        run_dir=tmp_path,
        source_dir=tmp_path,
        env_dir=tmp_path,
        options=options,
    )


def _detect(pm, solver, log, returncode):
    return pm.hook.gymprecice_detect_divergence(solver=solver, log_text=log, returncode=returncode)


@pytest.mark.parametrize(
    ("log", "shown"),
    [
        (FPE, "sigFpe"),
        (ITERATIONS, "Maximum number of iterations exceeded"),
    ],
)
def test_a_solver_that_died_of_divergence_is_recognised_with_its_log_line(pm, tmp_path, log, shown):
    evidence = _detect(pm, _solver(tmp_path), log, 136)
    assert shown in evidence and "Time = 0.3355" in evidence


def test_other_deaths_and_healthy_runs_are_not_divergence(pm, tmp_path):
    solver = _solver(tmp_path, max_courant=5)
    assert _detect(pm, solver, MISSING_LIBRARY, 127) is None
    assert _detect(pm, solver, HEALTHY, None) is None
    assert _detect(pm, solver, HEALTHY, 1) is None  # the banner naming the trap is not it
    assert _detect(pm, solver, FPE, None) is None  # still running: only the Courant guard


def test_the_courant_guard_ends_a_running_solver_past_its_limit(pm, tmp_path):
    guarded = _solver(tmp_path, max_courant=5)
    evidence = _detect(pm, guarded, BLOWING_UP, None)
    assert evidence == "Courant Number max 37.5 > max_courant 5 (at solver Time = 0.336)"
    assert _detect(pm, _solver(tmp_path, max_courant=50), BLOWING_UP, None) is None
    assert _detect(pm, _solver(tmp_path), BLOWING_UP, None) is None  # no guard configured
    nan = HEALTHY + "Courant Number mean: nan max: nan\n"
    assert "max nan" in _detect(pm, guarded, nan, None)


def test_other_kinds_are_left_to_their_plugins(pm, tmp_path):
    assert _detect(pm, _solver(tmp_path, kind="command"), FPE, 136) is None


@pytest.mark.parametrize("value", [0, -1, "5", float("nan"), True])
def test_a_courant_limit_that_is_not_positive_is_refused_with_the_key(pm, tmp_path, value):
    solver = _solver(tmp_path, max_courant=value)
    with pytest.raises(ConfigError, match=r"options\.max_courant is .* positive number"):
        _detect(pm, solver, HEALTHY, None)
    with pytest.raises(ConfigError, match="max_courant"):
        plugin._check_options(solver)
