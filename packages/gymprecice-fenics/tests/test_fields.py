"""The FEniCS plugin's fields for ``env.render()``: the script's ``gymprecice-fields/`` files.

The script runs in FEniCS's own interpreter, so here a file is written the way the heated
plate's ``solid.py`` writes it (``numpy.savez``, then renamed), without FEniCS.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.fields import FIELDS_ENV_VAR, field_file, grid_points
from gymprecice_fenics import plugin
from gymprecice_fenics.fields import FIELD_INTERVAL_ENV_VAR


def _write_like_the_script(run_dir: Path, time: float, warm: float) -> None:
    points, triangles = grid_points(np.linspace(0, 1, 5), np.linspace(-0.25, 0, 3))
    target = field_file(run_dir, "T")
    target.parent.mkdir(exist_ok=True)
    with open(target.with_name(".T.npz"), "wb") as out:
        np.savez(
            out,
            time=np.array(time),
            points=points,
            values=300.0 + warm * (points[:, 1] + 0.25),
            triangles=triangles,
            label=np.array("plate T [K]"),
        )
    os.replace(target.with_name(".T.npz"), target)


def test_a_rendering_env_tells_the_script_what_to_write_and_how_often(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    plain = plugin.gymprecice_launch_solver(solver).env
    assert FIELDS_ENV_VAR not in plain and FIELD_INTERVAL_ENV_VAR not in plain

    solver.fields, solver.field_interval = ("T",), 0.1
    env = plugin.gymprecice_launch_solver(solver).env
    assert env[FIELDS_ENV_VAR] == "T"
    assert float(env[FIELD_INTERVAL_ENV_VAR]) == 0.1


def test_the_scripts_latest_file_is_the_field_and_reset_removes_it(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    solver.fields, solver.field_interval = ("T",), 0.1
    assert plugin.gymprecice_read_field(solver, "T", 0.0) is None  # not written yet

    _write_like_the_script(solver.run_dir, 0.1, warm=40.0)
    field = plugin.gymprecice_read_field(solver, "T", 0.1)
    assert field.time == pytest.approx(0.1)
    assert field.label == "plate T [K]"
    assert field.triangles is not None and len(field.triangles) == 2 * 4 * 2
    assert field.scalar.min() == pytest.approx(300.0)
    assert field.scalar.max() == pytest.approx(310.0)

    assert plugin.gymprecice_reset_case(solver) is True
    assert not field_file(solver.run_dir, "T").parent.exists()


def test_a_field_not_asked_for_and_a_file_of_another_shape_are_named(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    solver.fields = ("T",)
    with pytest.raises(ConfigError, match=r"field 'u' was not requested"):
        plugin.gymprecice_read_field(solver, "u", 0.0)
    target = field_file(solver.run_dir, "T")
    target.parent.mkdir()
    np.savez(target, time=np.array(0.0), points=np.zeros((4, 2)), values=np.zeros(3))
    with pytest.raises(ConfigError, match=r"T\.npz is not a field file"):
        plugin.gymprecice_read_field(solver, "T", 0.0)


def test_other_kinds_are_left_alone(make_fenics_solver) -> None:
    solver = make_fenics_solver()
    solver.kind = "openfoam"
    assert plugin.gymprecice_read_field(solver, "T", 0.0) is None
