"""preCICE's own perpendicular flap (``setup="precice"``), the tip's figures, and the
validation command's refusals: everything of the flap's validation that needs no solver.

The run itself, against preCICE's published series, is tests/test_flap_validation_real.py.
"""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from gymprecice_tutorials.perpendicular_flap.packaged_case import case_files
from gymprecice_tutorials.perpendicular_flap.precice_setup import setup_case_files
from gymprecice_tutorials.perpendicular_flap.tip_figures import (
    PUBLISHED,
    TOLERANCE,
    TipFigures,
    published_series,
    tip_figures,
)
from gymprecice_tutorials.perpendicular_flap.validate import compare, read_watch_point_log


def _cells(block_mesh: str) -> int:
    """The cells of the flap's five blocks, from the counts the blockMeshDict declares."""
    value = {
        name: int(number)
        for name, number in re.findall(r"^(n[xy]\w+)\s+(\d+);", block_mesh, re.MULTILINE)
    }
    below = 2 * value["nxSide"] * value["nyFlap"]
    above = (2 * value["nxSide"] + value["nxFlap"]) * value["nyAbove"]
    return below + above


def test_precice_setup_has_the_tutorials_mesh_start_and_pressure_corrections() -> None:
    packaged, precice = case_files("dealii"), setup_case_files("dealii")
    mesh = "fluid-openfoam/system/blockMeshDict"
    assert _cells(packaged[mesh]) == 3780
    assert _cells(precice[mesh]) == 2790  # preCICE's blockMeshDict: 2 x 30 x 15 + 63 x 30
    assert precice[mesh].count("simpleGrading ($gradeIn 2 1)") == 1  # graded above the tip
    assert "internalField   uniform (10 0 0);" in precice["fluid-openfoam/0/U"]
    assert "nCorrectors              4;" in precice["fluid-openfoam/system/fvSolution"]
    # the coupling and the solid are the packaged case's
    for name in ("precice-config.xml", "solid-dealii/parameters.prm"):
        assert precice[name] == packaged[name]
    assert "solid-fenics/solid.py" in setup_case_files("fenics")


def test_the_env_refuses_an_unknown_setup_and_a_setup_with_a_case_of_its_own(tmp_path) -> None:
    from gymprecice_tutorials.perpendicular_flap.environment import PerpendicularFlapEnv

    with pytest.raises(ValueError, match="setup must be one of jet, precice"):
        PerpendicularFlapEnv(setup="uniform", run_root=tmp_path)
    with pytest.raises(ValueError, match="makes its own case"):
        PerpendicularFlapEnv(tmp_path / "gymprecice-config.json", setup="precice")


def test_precice_setup_acts_on_the_inflow_speed(tmp_path) -> None:
    from gymprecice_tutorials.perpendicular_flap.environment import PerpendicularFlapEnv

    env = PerpendicularFlapEnv(setup="precice", run_root=tmp_path)
    try:
        assert env.action_space.low[0] == 0.0 and env.action_space.high[0] == 20.0
        assert env._initial_action()[0] == 10.0
        assert env.jet_centre(np.array([25.0])) == 20.0  # clipped to the space
    finally:
        env.close()


def test_tip_figures_of_a_known_swing() -> None:
    """A swing about 0.1 m of amplitude 0.08 m and period 1.6 s, from rest."""
    t = np.arange(0.0, 5.0 + 1e-9, 0.01)
    dx = 0.1 - 0.08 * np.cos(2 * np.pi * t / 1.6) - 0.02 * np.exp(-t)
    figures = tip_figures(t, dx)
    assert figures.first_peak_time == pytest.approx(0.8, abs=0.01)
    assert figures.first_peak == pytest.approx(0.18 - 0.02 * np.exp(-0.8), abs=1e-3)
    assert figures.period == pytest.approx(1.6, abs=0.01)
    assert figures.amplitude == pytest.approx(0.08, abs=0.002)
    # a short run gives its first peak and nothing else
    short = tip_figures(t[t <= 1.2], dx[t <= 1.2])
    assert short.first_peak == pytest.approx(figures.first_peak)
    assert np.isnan(short.period)
    with pytest.raises(ValueError, match="no maximum"):
        tip_figures(t[t <= 0.5], dx[t <= 0.5])


def test_the_published_series_reads_as_the_tutorials_figure_shows() -> None:
    rows = published_series()
    assert rows[0].tolist() == [0.0, 0.0] and rows[-1, 0] == pytest.approx(5.0, abs=0.01)
    assert PUBLISHED.first_peak == pytest.approx(0.199, abs=0.002)
    assert PUBLISHED.first_peak_time == pytest.approx(0.75, abs=0.01)
    assert PUBLISHED.period == pytest.approx(1.61, abs=0.02)
    assert PUBLISHED.mean == pytest.approx(0.094, abs=0.003)


def test_compare_flags_each_figure_outside_its_tolerance() -> None:
    off = PUBLISHED._replace(
        first_peak=PUBLISHED.first_peak * (1 + 2 * TOLERANCE.first_peak),
        first_peak_time=PUBLISHED.first_peak_time + 0.5 * TOLERANCE.first_peak_time,
        period=float("nan"),
    )
    table = compare(off, PUBLISHED)
    assert set(table) == set(TipFigures._fields)
    assert not table["first_peak"]["within"]
    assert table["first_peak_time"]["within"]
    assert not table["period"]["within"]  # a figure the run could not give fails
    assert table["mean"]["within"] and table["amplitude"]["within"]
    only = compare(off, PUBLISHED, ("first_peak_time",))
    assert list(only) == ["first_peak_time"]


def test_a_precice_watch_point_log_is_read_by_its_header(tmp_path) -> None:
    log = tmp_path / "precice-Solid-watchpoint-Flap-Tip.log"
    log.write_text(
        "  Time  Coordinate0  Coordinate1  Displacement0  Displacement1  Force0  Force1\n"
        "  0.0  0.0  1.0  0.0  0.0  0.0  0.0\n"
        "  0.01  0.0  1.0  0.002  -1e-6  1.5  2.5\n"
    )
    assert read_watch_point_log(log).tolist() == [[0.0, 0.0, 0.0], [0.01, 0.002, -1e-6]]
    log.write_text("time x\n0 0\n")
    with pytest.raises(ValueError, match="not a preCICE watch-point log"):
        read_watch_point_log(log)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--end-time", "7"], "--end-time must lie in (0, 5] s"),
        (["--reference", "no-such.log"], "--reference no-such.log: no such file"),
        (["--solid", "calculix"], "invalid choice: 'calculix'"),
    ],
)
def test_the_validation_command_refuses_bad_input_before_running(tmp_path, args, message) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "gymprecice_tutorials.perpendicular_flap.validate", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stderr
    assert message in result.stderr
    assert list(tmp_path.iterdir()) == []
