"""The flap's two solids without solvers: the case keeps one, the FEniCS flap is the deal.II
flap, the envs take either, the test double runs with either, and the swing's figures.

The coupled comparison of the two solids is ``tests/test_flap_solids_real.py``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.config import load_config
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice_fenics.adapter_config import AdapterConfig, check_against_precice
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.perpendicular_flap import CASE_DIR
from gymprecice_tutorials.perpendicular_flap.environment import PerpendicularFlapEnv
from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv
from gymprecice_tutorials.perpendicular_flap.packaged_case import SOLIDS, case_files
from gymprecice_tutorials.perpendicular_flap.swing import swing_figures
from gymprecice_tutorials.perpendicular_flap.training_case import WINDOW, fast_case_files


def test_the_case_keeps_the_named_solid_only() -> None:
    dealii = case_files("dealii")
    assert dealii["gymprecice-config.json"] == (CASE_DIR / "gymprecice-config.json").read_text()
    assert not any(rel.startswith("solid-fenics/") for rel in dealii)
    fenics = case_files("fenics")
    assert not any(rel.startswith("solid-dealii/") for rel in fenics)
    assert {"solid-fenics/solid.py", "solid-fenics/precice-adapter-config.json"} <= set(fenics)
    solid = json.loads(fenics["gymprecice-config.json"])["physics_simulation_engine"]["solvers"]
    assert solid["solid"] == {"kind": "fenics", "path": "solid-fenics", "participant": "Solid"}
    assert fenics["precice-config.xml"] == dealii["precice-config.xml"]
    with pytest.raises(ValueError, match=r"solid must be one of \['dealii', 'fenics'\]"):
        case_files("calculix")


def _number(pattern: str, text: str) -> float:
    match = re.search(pattern, text, re.MULTILINE)
    assert match is not None, pattern
    return float(match.group(1))


def test_the_fenics_flap_is_the_deal_ii_flap() -> None:
    """Material and geometry of ``solid.py`` against ``parameters.prm`` and the watch point."""
    script = (CASE_DIR / "solid-fenics/solid.py").read_text()
    prm = (CASE_DIR / "solid-dealii/parameters.prm").read_text()
    young, poisson = (
        _number(r"^YOUNG = ([0-9.e]+)", script),
        _number(r"^POISSON = ([0-9.]+)", script),
    )
    assert poisson == _number(r"set Poisson's ratio = ([0-9.]+)", prm)
    shear = young / (2.0 * (1.0 + poisson))
    assert shear == pytest.approx(_number(r"set Shear modulus\s+= ([0-9.]+)", prm), rel=1e-6)
    assert _number(r"^DENSITY = ([0-9.]+)", script) == _number(r"set rho\s+= ([0-9.]+)", prm)
    # the deal.II adapter's scenario PF: 0.1 wide, 1 tall, centred on x = 0
    assert re.search(r"^HEIGHT, WIDTH = 1\.0, 0\.1$", script, re.MULTILINE)
    assert "set Scenario            = PF" in prm
    # the watch point the env reads lies on the FEniCS coupling boundary's top edge
    watch = re.search(
        r'<watch-point mesh="Solid-Mesh" name="Flap-Tip" coordinate="([^"]+)"',
        (CASE_DIR / "precice-config.xml").read_text(),
    )
    assert watch is not None and watch.group(1) == "0.0;1.0"


def test_the_fenics_training_case_agrees_with_its_precice_configuration(tmp_path: Path) -> None:
    case = write_case_files("flap-fast-fenics", fast_case_files(4.0, solid="fenics"), tmp_path)
    assert not (case / "solid-dealii").exists()
    precice = load_precice_config(case / "precice-config.xml")
    assert {s.max_time for s in precice.coupling_schemes} == {4.0}
    assert {s.time_window_size for s in precice.coupling_schemes} == {WINDOW}
    assert "nxSide      15;" in (case / "fluid-openfoam/system/blockMeshDict").read_text()
    config = load_config(case / "gymprecice-config.json")
    assert config.solvers["solid"].kind == "fenics"
    assert config.model.actions.windows == 2
    adapter = AdapterConfig.read(case / "solid-fenics/precice-adapter-config.json")
    assert check_against_precice(adapter, precice, "Solid", "solid-fenics") == []
    # the observation through preCICE edits the XML only: it applies to either solid
    routed = fast_case_files(4.0, "precice", "fenics")
    assert "Controller-Mesh-tip" in routed["precice-config.xml"]


@pytest.mark.parametrize("env_class", [PerpendicularFlapEnv, PerpendicularFlapFastEnv])
def test_the_envs_take_either_solid_and_refuse_another(env_class, tmp_path: Path) -> None:
    for solid in SOLIDS:
        env = env_class(solid=solid, run_root=tmp_path)
        try:
            assert env.solid == solid
            spec = env.config.solvers["solid"]
            assert (spec.kind, spec.path) == (solid, SOLIDS[solid])
        finally:
            env.close()
    with pytest.raises(ValueError, match=r"solid must be one of \['dealii', 'fenics'\], got 'x'"):
        env_class(solid="x", run_root=tmp_path)


def _double_episode(solid: str, root: Path) -> np.ndarray:
    env = PerpendicularFlapFastEnv(
        solid=solid, double=True, settle_time=0.3, episode_time=0.5, run_root=root
    )
    try:
        obs, _ = env.reset(seed=0, options={"split": "eval", "start": 0})
        observations = [obs]
        truncated = False
        while not truncated:
            obs, _, terminated, truncated, _ = env.step(np.array([2.5], np.float32))
            assert not terminated
            observations.append(obs)
        assert env.solid == solid
    finally:
        env.close()
    return np.array(observations)


def test_the_test_double_runs_the_same_scripted_flap_with_either_solid(tmp_path: Path) -> None:
    dealii = _double_episode("dealii", tmp_path / "dealii")
    fenics = _double_episode("fenics", tmp_path / "fenics")
    assert len(dealii) == 6 and np.abs(dealii[:, 0]).max() > 0.0
    np.testing.assert_array_equal(dealii, fenics)


def test_swing_figures_of_a_sampled_swing() -> None:
    period, start = 1.6, 1.0
    time = np.arange(0.0, 4.0 + 1e-9, WINDOW)
    dx = 0.05 + 0.1 * np.cos(2.0 * np.pi * (time - 1.3) / period)
    figures = swing_figures(time, dx, np.abs(dx), start)
    assert figures.first_peak == pytest.approx(0.15, abs=1e-3)
    assert figures.first_peak_time == pytest.approx(0.3, abs=5e-3)
    assert figures.period == pytest.approx(period, abs=0.01)
    assert figures.mean_displacement == pytest.approx(np.abs(dx[time > start]).mean())
    with pytest.raises(ValueError, match="too short an episode"):
        swing_figures(time[:24], dx[:24], np.abs(dx[:24]), start)


def test_the_flap_card_declares_the_reference_inflow_as_uncontrolled(tmp_path: Path) -> None:
    from gymprecice_lab.common.registered_env import find_lab_env

    kwargs = dict(find_lab_env("gymprecice/PerpendicularFlap-v0").baseline_kwargs)
    assert kwargs == {"jet_height": 4.0}
    env = PerpendicularFlapEnv(run_root=tmp_path, **kwargs)
    try:
        assert env.action_space.low[0] == env.action_space.high[0] == 2.0
    finally:
        env.close()
