"""The base-flow floor: the symmetric case, the plateau it is read from, a real run."""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gymprecice_tutorials import base_flow, recipes
from gymprecice_tutorials.base_flow import SYMMETRY_CL, plateau, symmetric_spec
from gymprecice_tutorials.fast_cases import FAST_REWARD_OFFSET


@pytest.mark.parametrize("name", ["jet_cylinder_fast", "rotating_cylinder", "jet_cylinder"])
def test_symmetric_spec_centres_the_cylinder_and_mirrors_the_mesh(name: str) -> None:
    packaged = recipes.case_spec(name)
    spec = symmetric_spec(name, end_time=3.0)
    assert spec.geometry.centre == (packaged.geometry.centre[0], packaged.geometry.height / 2)
    assert packaged.geometry.centre[1] != spec.geometry.centre[1]  # the recipes are offset
    assert spec.resolution == packaged.resolution and spec.flow == packaged.flow
    assert spec.end_time == 3.0
    counts = recipes.block_counts(spec.geometry, spec.resolution)
    assert counts.n_top == counts.n_bottom


def test_symmetric_spec_changes_only_the_resolution_asked_for() -> None:
    spec = symmetric_spec("jet_cylinder", end_time=3.0, cells_per_jet=4, wall_cell=0.0075)
    assert spec.resolution == recipes.Resolution.fine()
    assert recipes.block_counts(spec.geometry, spec.resolution).cells == 17416


def test_unknown_case_names_the_recipes() -> None:
    with pytest.raises(KeyError, match="jet_cylinder_fast"):
        symmetric_spec("jet-cylinder", end_time=3.0)


def _settling_run(t: np.ndarray, *, onset: float) -> tuple[np.ndarray, np.ndarray]:
    """Drag relaxing to 2.9 from the start, lift growing into shedding from ``onset``."""
    cd = 2.9 + 0.1 * np.exp(-2.0 * t)
    envelope = 1e-3 * np.exp(4.0 * (t - onset))
    cl = np.minimum(envelope, 1.0) * np.sin(2 * np.pi * 3.0 * t)
    cd = cd + 0.3 * np.minimum(envelope, 1.0) ** 2
    return cd, cl


def test_plateau_takes_the_last_symmetric_window() -> None:
    t = np.arange(0.001, 6.0, 0.001)
    cd, cl = _settling_run(t, onset=3.5)
    base = plateau(t, cd, cl)
    a, b = base.window
    assert b <= 3.5 + np.log(SYMMETRY_CL / 1e-3) / 4.0  # before |Cl| reaches SYMMETRY_CL
    assert np.abs(cl[(t >= b) & (t < b + 0.5)]).max() >= SYMMETRY_CL  # the next one sheds
    assert base.max_abs_cl < SYMMETRY_CL
    inside = (t >= a) & (t < b)
    assert base.cd == pytest.approx(cd[inside].mean())
    assert 2.9 < base.cd < 2.91 and base.drift < 0


def test_plateau_refuses_a_run_that_never_settles_symmetric() -> None:
    t = np.arange(0.001, 4.0, 0.001)
    cd, cl = _settling_run(t, onset=0.0)
    with pytest.raises(ValueError, match=r"never stayed symmetric.*--end-time"):
        plateau(t, cd, cl)


def test_main_without_openfoam_says_so(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(base_flow, "have_openfoam", lambda: False)
    assert base_flow.main(["jet_cylinder_fast"]) == 2
    assert "OpenFOAM" in capsys.readouterr().err


def test_main_says_when_the_run_ended_before_the_wake_settled(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    t = np.arange(0.001, 2.0, 0.001)
    cd, cl = _settling_run(t, onset=10.0)  # 2 s: still relaxing at 1e-2 per window
    monkeypatch.setattr(base_flow, "have_openfoam", lambda: True)
    monkeypatch.setattr(base_flow, "prepare_case", lambda spec, fluid, kick: fluid)
    monkeypatch.setattr(base_flow, "run_case", lambda fluid, n_procs: 1.0)
    monkeypatch.setattr(
        base_flow, "read_force_coeffs", lambda fluid: {"Time": t, "Cd": cd, "Cl": cl}
    )
    assert base_flow.main(["jet_cylinder_fast", "--end-time", "2", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "base-flow Cd 2.9" in out and "not settled" in out and "--end-time" in out


@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("pimpleFoam") is None, reason="OpenFOAM is not on PATH")
@pytest.mark.timeout(600)
def test_base_flow_of_the_training_case_with_real_openfoam(tmp_path: Path) -> None:
    """4 s of the coarse case: the symmetric wake settles below the shedding's drag.

    Cost: about 30 s (pimpleFoam on the symmetric training case until its wake settles).
    """
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "gymprecice_tutorials.base_flow",
            "jet_cylinder_fast",
            "--out",
            str(tmp_path),
            "--baseline-cd",
            str(FAST_REWARD_OFFSET),
            "--figure",
            str(tmp_path / "base-flow.png"),
        ],
        capture_output=True,
        text=True,
        timeout=550,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    line = next(x for x in done.stdout.splitlines() if x.startswith("base-flow Cd"))
    cd = float(line.split()[2])
    # the shedding's mean is 3.2195; the settled base flow is 2.9755 (docs/training.md)
    assert 2.97 < cd < 2.98
    assert "not settled" not in done.stdout
    assert "% below the uncontrolled mean Cd" in done.stdout
    assert (tmp_path / "base-flow.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_resolution_options_give_only_the_knobs_typed() -> None:
    parser = argparse.ArgumentParser()
    recipes.add_resolution_options(parser)
    assert recipes.resolution_overrides(parser.parse_args([])) == {}
    typed = parser.parse_args(["--cells-per-jet", "4", "--wall-cell", "0.0075"])
    assert recipes.resolution_overrides(typed) == {"cells_per_jet": 4, "wall_cell": 0.0075}


def test_recipes_write_applies_the_resolution_options(tmp_path: Path) -> None:
    assert recipes.main(["write", "jet_cylinder", str(tmp_path), "--cells-per-jet", "4"]) == 0
    mesh = (tmp_path / recipes.FLUID_DIR / "system" / "blockMeshDict").read_text()
    spec = recipes.case_spec("jet_cylinder")
    finer = replace(spec.resolution, cells_per_jet=4)
    assert mesh == recipes.blockmesh_dict(spec.geometry, finer)
    assert mesh != recipes.blockmesh_dict(spec.geometry, spec.resolution)
