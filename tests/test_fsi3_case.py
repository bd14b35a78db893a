"""Turek and Hron's FSI3: the case's files, the figures of an oscillation and the
validation command's comparisons and refusals, everything that needs no solver.

The mesh through blockMesh and the coupled run itself are tests/test_fsi3_real.py.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gymprecice_tutorials.turek_hron.case import INFLOW_MEAN, case_files, inflow
from gymprecice_tutorials.turek_hron.mesh import (
    GEOMETRY,
    RESOLUTIONS,
    Fsi3Resolution,
    blockmesh_dict,
    cell_count,
)
from gymprecice_tutorials.turek_hron.reference import PUBLISHED, Figure, oscillation
from gymprecice_tutorials.turek_hron.validate import compare, study_table


def _sine(mean: float, amplitude: float, frequency: float, end: float = 3.0) -> tuple:
    t = np.arange(0.0, end, 1e-3)
    return t, mean + amplitude * np.sin(2 * math.pi * frequency * t + 0.3)


def _published(scale: float) -> dict[str, np.ndarray]:
    """Sines at the published means and frequencies, ``scale`` times their amplitudes."""
    out: dict[str, np.ndarray] = {}
    for signal in ("tip_dx", "tip_dy", "drag", "lift"):
        mean = PUBLISHED[f"{signal}_mean"].value
        amplitude = scale * PUBLISHED[f"{signal}_amplitude"].value
        t, v = _sine(mean, amplitude, PUBLISHED[f"{signal}_frequency"].value)
        out["time"], out[signal] = t, v
    return out


def test_an_oscillations_figures_are_the_benchmarks_mean_amplitude_and_frequency() -> None:
    t, v = _sine(0.4, 2.5, 5.3)
    figures = oscillation(t, v, window=1.0)
    assert figures.mean == pytest.approx(0.4, abs=1e-3)
    assert figures.amplitude == pytest.approx(2.5, rel=1e-3)
    assert figures.frequency == pytest.approx(5.3, rel=1e-3)
    assert figures.periods == 4  # five upward crossings in a second at 5.3 Hz


def test_a_window_without_two_crossings_has_no_figures() -> None:
    t = np.linspace(0.0, 1.0, 200)
    figures = oscillation(t, t**2, window=0.5)  # rises throughout: no period
    assert math.isnan(figures.frequency) and figures.periods == 0


def test_figures_pass_within_their_tolerance_and_only_there() -> None:
    relative, absolute = Figure(100.0, 0.05), Figure(0.0, 2.0, "absolute")
    assert relative.passes(104.9) and not relative.passes(105.1)
    assert absolute.passes(-1.9) and not absolute.passes(2.1)
    assert not relative.passes(float("nan"))


def test_a_run_at_the_published_values_is_within_every_tolerance_and_one_off_is_not() -> None:
    table = compare(_published(1.0), window=1.0)
    assert set(table) == set(PUBLISHED)
    assert all(row["within"] for row in table.values()), table
    damped = compare(_published(0.5), window=1.0)  # half the swing
    assert not damped["tip_dy_amplitude"]["within"]
    assert damped["tip_dy_frequency"]["within"]


def test_the_published_figures_are_turek_and_hrons_fsi3() -> None:
    assert PUBLISHED["tip_dy_amplitude"].value == pytest.approx(34.38e-3)
    assert PUBLISHED["lift_amplitude"].value == pytest.approx(149.78)
    assert PUBLISHED["drag_mean"].value == pytest.approx(457.3)
    assert PUBLISHED["tip_dy_frequency"].value == pytest.approx(5.3)
    assert PUBLISHED["drag_frequency"].value == pytest.approx(10.9)


def test_the_mesh_declares_every_patch_and_the_cells_it_counts() -> None:
    text = blockmesh_dict(RESOLUTIONS["coarse"])
    for patch in ("inlet", "outlet", "walls", "cylinder", "jet1", "jet2", "flap"):
        assert re.search(rf"^    {patch}\n    {{\n        type (wall|patch);", text, re.M), patch
    cells = 0
    for nx, ny in re.findall(r"\) \((\d+) (\d+) 1\) simpleGrading", text):
        cells += int(nx) * int(ny)
    assert cells == cell_count(RESOLUTIONS["coarse"])
    # the bar's five faces: its two surfaces in the box and beside it, and its tip
    flap = text.split("    flap\n", 1)[1].split(");", 1)[0]
    assert flap.count("(") - 1 == 5


def test_finer_resolutions_have_more_cells() -> None:
    counts = [cell_count(RESOLUTIONS[name]) for name in ("coarse", "medium", "fine")]
    assert counts == sorted(counts) and counts[0] > 1000
    assert cell_count(Fsi3Resolution(cell=0.005)) > counts[0]


def test_the_inflow_is_turek_and_hrons_ramped_parabola() -> None:
    h = GEOMETRY.height
    assert inflow(h / 2, 10.0) == pytest.approx(1.5 * INFLOW_MEAN)  # peak, after the ramp
    assert inflow(h / 2, 1.0) == pytest.approx(0.75 * INFLOW_MEAN)  # half way up the ramp
    assert inflow(0.0, 5.0) == 0.0 and inflow(h, 5.0) == pytest.approx(0.0, abs=1e-12)


def test_a_runs_time_step_and_end_reach_every_file_that_holds_them() -> None:
    files = case_files("coarse", time_step=0.002, end_time=3.0, degree=3, action_time=0.02)
    xml = files["precice-config.xml"]
    assert xml.count('<time-window-size value="0.002" />') == 2
    assert xml.count('<max-time value="3" />') == 2
    assert "deltaT          0.002;" in files["fluid-openfoam/system/controlDict"]
    prm = files["solid-dealii/parameters.prm"]
    assert "set Time step size  = 0.002" in prm and "set End time        = 3" in prm
    assert "set Polynomial degree = 3" in prm
    assert json.loads(files["gymprecice-config.json"])["actions"]["windows"] == 10
    assert "fluid-openfoam/system/blockMeshDict" in files
    ramp = [k for k in files if k.endswith("/U") and "boundaryData" in k]
    assert len(ramp) == 42  # 0 to 2 s every 0.05 s, then held
    assert not [k for k in files if k.startswith("solid-fenics/")]


def test_a_run_with_the_fenics_bar_keeps_that_solid_and_its_settings() -> None:
    files = case_files("coarse", time_step=0.002, end_time=3.0, degree=3, solid="fenics")
    assert not [k for k in files if k.startswith("solid-dealii/")]
    assert {"solid.py", "bar.py", "solid.json", "precice-adapter-config.json"} <= {
        k.split("/", 1)[1] for k in files if k.startswith("solid-fenics/")
    }
    solid = json.loads(files["gymprecice-config.json"])["physics_simulation_engine"]["solvers"][
        "solid"
    ]
    assert (solid["kind"], solid["path"], solid["options"]) == ("fenics", "solid-fenics", {})
    assert json.loads(files["solid-fenics/solid.json"])["degree"] == 3
    adapter = json.loads(files["solid-fenics/precice-adapter-config.json"])
    xml = files["precice-config.xml"]  # the same data and meshes as the deal.II program's
    assert adapter["participant_name"] == "Solid"
    assert f'<read-data name="{adapter["interface"]["read_data_name"]}" mesh="Solid-Mesh" />' in xml
    assert '<write-data name="Displacement" mesh="Solid-Mesh" />' in xml
    assert xml.count('<time-window-size value="0.002" />') == 2


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"solid": "calculix"}, "solid must be one of"),
        ({"resolution": "huge"}, "resolution must be one of"),
        ({"action_time": 0.0155}, "whole number of time windows"),
        ({"time_step": 0.0}, "must be positive"),
    ],
)
def test_a_case_of_bad_settings_is_refused_naming_the_setting(kwargs, message) -> None:
    with pytest.raises(ValueError, match=message):
        case_files(**kwargs)


def test_the_validation_command_refuses_a_window_longer_than_the_run(tmp_path) -> None:
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "gymprecice_tutorials.turek_hron.validate",
            "--end-time",
            "1",
            "--window",
            "2",
            "--out",
            str(tmp_path / "runs"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert "--window must lie in (0, 1) s" in result.stderr
    assert not (tmp_path / "runs").exists()


def test_the_study_table_has_a_row_per_run_marking_the_figures_out_of_tolerance() -> None:
    def record(resolution: str, scale: float) -> dict:
        return {
            "resolution": resolution,
            "cells": 4808,
            "time_step": 0.002,
            "figures": compare(_published(scale), window=1.0),
            "wall_clock_s": 600.0,
        }

    fenics = {**record("coarse", 1.0), "solid": "fenics"}
    rows = [record("coarse", 0.5), record("medium", 1.0), fenics]
    table = study_table(rows).splitlines()
    assert table[2].startswith("| published | | | | 34.38 |")
    # a record written before the FEniCS bar names no solid: deal.II's
    assert table[3].startswith("| coarse | deal.II | 4,808 | 0.002 | 17.19 (out) |")
    assert "(out)" not in table[4] and table[4].endswith("| 10 min |")
    assert table[5].startswith("| coarse | FEniCS | 4,808 |")


def test_a_jet_bound_that_is_not_positive_is_refused_before_any_case_is_written(tmp_path):
    from gymprecice_tutorials.turek_hron.environment import TurekHronEnv

    with pytest.raises(ValueError, match="max_flow_rate must be positive"):
        TurekHronEnv(max_flow_rate=0.0, run_root=tmp_path)
    assert not any(tmp_path.iterdir())


def _csm3(scale: float = 1.0) -> dict:
    """A CSM3 record swinging at the published figures (``scale``: of the swing)."""
    from gymprecice_tutorials.turek_hron.solid_checks import PUBLISHED_CSM

    published = PUBLISHED_CSM["CSM3"]
    t = np.arange(0.0, 10.0, 0.005)
    phase = 2 * np.pi * published["dy_frequency"].value * t
    record = {"test": "CSM3", "time": t.tolist()}
    for signal in ("dx", "dy"):
        mean = published[f"{signal}_mean"].value
        amplitude = scale * published[f"{signal}_amplitude"].value
        record[signal] = (mean + amplitude * np.cos(phase)).tolist()
    return record


def test_the_bars_checks_pass_at_the_published_values_and_only_there() -> None:
    from gymprecice_tutorials.turek_hron.solid_checks import PUBLISHED_CSM, compare_csm

    for test in ("CSM1", "CSM2"):
        exact = {k: f.value for k, f in PUBLISHED_CSM[test].items()}
        assert all(r["within"] for r in compare_csm({"test": test, **exact}).values())
        soft = {k: 1.05 * v for k, v in exact.items()}  # 5 % more sag
        assert not any(r["within"] for r in compare_csm({"test": test, **soft}).values())
    rows = compare_csm(_csm3())
    assert all(r["within"] for r in rows.values()), rows
    damped = compare_csm(_csm3(scale=0.9))
    assert not damped["dy_amplitude"]["within"] and damped["dy_frequency"]["within"]
    # Turek & Hron (2006), tables 4 and 5
    assert PUBLISHED_CSM["CSM1"]["dy"].value == pytest.approx(-66.10e-3)
    assert PUBLISHED_CSM["CSM3"]["dy_frequency"].value == pytest.approx(1.0995)


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--tests", "CSM4"], "unknown ['CSM4']"), (["--cells", "36"], "two whole numbers")],
)
def test_the_bars_checks_refuse_bad_input_naming_it(argv, message, tmp_path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "gymprecice_tutorials.turek_hron.solid_checks",
            *argv,
            "--out",
            str(tmp_path / "runs"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr
    assert not (tmp_path / "runs").exists()


def test_the_fenics_bar_s_load_is_a_setting_of_the_validation_and_only_of_that_bar(tmp_path):
    from gymprecice_tutorials.turek_hron.validate import main, study_table

    files = case_files("coarse", solid="fenics", solid_settings={"load": "vertex"})
    assert json.loads(files["solid-fenics/solid.json"])["load"] == "vertex"
    assert json.loads(case_files("coarse", solid="fenics")["solid-fenics/solid.json"])["load"] == (
        "rbf"  # the validated runs' load, unless asked
    )
    with pytest.raises(SystemExit):
        main(["--load", "vertex", "--out", str(tmp_path)])  # the deal.II program has none
    assert not any(tmp_path.iterdir())
    results = Path(__file__).resolve().parents[1] / "docs" / "results"
    record = json.loads((results / "validation-fsi3-fenics-coarse-dt2ms.json").read_text())
    assert "FEniCS (vertex load)" in study_table([{**record, "load": "vertex"}])
    assert "(rbf load)" not in study_table([record])  # the runs before the setting
