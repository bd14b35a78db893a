"""HeatedPlate-v0 on the real stack: OpenFOAM fluid with an OpenFOAM and a FEniCS plate.

One short coupled episode with each plate (buoyantPimpleFoam with laplacianFoam, then with
the FEniCS script in its solver environment), the heater driven to 330 K. The two plates
are the same physics, so their interface temperatures must agree; the heater must reach
the plate through the second coupling mesh in both. Skipped, naming what is missing, on
machines without the real stack; ``GYMPRECICE_REQUIRE_REAL=1`` (CI) fails instead.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.processes import kill_recorded_groups
from gymprecice_fenics import solver_env
from gymprecice_openfoam.testing import missing_coupled_stack
from gymprecice_tutorials.heated_plate.environment import SOLID_AGREEMENT_K, HeatedPlateEnv


def _missing(solid: str) -> list[str]:
    missing = missing_coupled_stack("buoyantPimpleFoam", "laplacianFoam", "blockMesh")
    if solid == "fenics":
        missing += list(solver_env.probe().problems)
    return missing


pytestmark = [pytest.mark.precice, pytest.mark.openfoam, pytest.mark.slow]

#: the heater during the episode, and the uncontrolled interface temperature (K) at the
#: episode's end (measured: 302.92 K with both plates, heater at 310 K)
HEATER = 330.0
UNCONTROLLED_END = 302.92


def _episode(solid: str, root: Path) -> list[float]:
    """Mean interface temperature after settling and after each step at a 330 K heater."""
    env = HeatedPlateEnv(solid=solid, settle_time=0.1, episode_time=0.3, run_root=root)
    try:
        obs, info = env.reset(seed=0, options={"split": "eval"})
        temperatures = [float(obs[0]) + env.start.setpoint]
        truncated = False
        while not truncated:
            obs, _, terminated, truncated, info = env.step(np.array([HEATER], np.float32))
            assert not terminated
            assert info["metrics"]["heater_temperature"] == HEATER
            temperatures.append(info["metrics"]["interface_temperature"])
        assert env.time == pytest.approx(0.4)
        env_dir = env.env_dir
    finally:
        env.close()
    # Nothing of the episode's solvers is left running after close.
    assert kill_recorded_groups(env_dir) == []
    return temperatures


@pytest.fixture(scope="module")
def episodes(tmp_path_factory) -> dict[str, list[float]]:
    done = {}
    for solid in ("openfoam", "fenics"):
        missing = _missing(solid)
        if not missing:
            done[solid] = _episode(solid, tmp_path_factory.mktemp(f"plate-{solid}"))
    return done


@pytest.mark.parametrize("solid", ["openfoam", pytest.param("fenics", marks=pytest.mark.fenics)])
def test_one_coupled_episode_with_each_plate_follows_the_heater(episodes, solid: str) -> None:
    """Cost: about 40 CPU-s (1 to 2 min on 2 cores), paid once by the module: two coupled 0.4 s
    episodes, buoyantPimpleFoam with laplacianFoam, then with the FEniCS plate; each case only
    reads them.
    """
    if solid not in episodes:
        pytest.skip("needs " + ", ".join(_missing(solid)))
    temperatures = episodes[solid]
    assert len(temperatures) == 4  # after settling, then three actions of 0.1 s
    assert 300.0 < temperatures[0] < 310.0
    # The heater at 330 K reaches the interface through the plate within a step: far
    # above the uncontrolled plate, and rising.
    assert temperatures[-1] > UNCONTROLLED_END + 2.0
    assert np.all(np.diff(temperatures) > 0)


@pytest.mark.fenics
def test_the_openfoam_and_fenics_plates_agree(episodes) -> None:
    """Cost: nothing of its own: it compares the module's two episodes."""
    missing = _missing("fenics")
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    difference = np.abs(np.subtract(episodes["openfoam"], episodes["fenics"]))
    assert difference.max() < SOLID_AGREEMENT_K, (episodes, difference)
