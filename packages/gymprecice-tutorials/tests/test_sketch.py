"""``gymprecice sketch`` on the tutorial envs: the data each picture is drawn from.

Each env is made with its run root in a temporary directory (its packaged case written
there), OpenFOAM's blockMesh meshes the fluid (and the plate) in another, and core reads
the coupling from the preCICE configuration: the flap's inlet is the actuator and the flap
its FSI interface; the plate's heater and inlet are written by the controller, its CHT
interface read; the cylinders' jets are actuators among 151 probes. The command itself
leaves only its picture behind.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from gymprecice.tools.case_sketch import CaseSketch, sketch_case
from gymprecice.tools.cli import main
from gymprecice.tools.sketch_command import load_case

needs_blockmesh = pytest.mark.skipif(
    shutil.which("blockMesh") is None, reason="OpenFOAM (blockMesh) is not on PATH"
)


def _sketch(env: str, tmp_path: Path) -> CaseSketch:
    config, title, made = load_case(env, str(tmp_path / "runs"), {})
    try:
        return sketch_case(config, title)
    finally:
        made.close()


@pytest.mark.openfoam
@needs_blockmesh
def test_the_flap_s_inlet_is_its_actuator_and_the_flap_its_fsi_interface(tmp_path) -> None:
    """Cost: about 2 s (the env made, blockMesh of the 4,000-cell training case)."""
    sketch = _sketch("perpendicular-flap-fast", tmp_path)
    assert sketch.title == "gymprecice/PerpendicularFlapFast-v0 (perpendicular-flap-fast)"
    inlet, flap = sketch.patch("inlet"), sketch.patch("flap")
    assert (inlet.kind, inlet.role) == ("actuator", "controller writes Velocity")
    assert (flap.kind, flap.role) == ("interface", "coupled with Solid")
    assert {p.name: p.kind for p in sketch.patches if p.name not in ("inlet", "flap")} == {
        "outlet": "outlet", "upperWall": "wall", "lowerWall": "wall",
    }  # fmt: skip
    points = {p.kind: p for p in sketch.points}
    assert points["watch point"].names == ("Flap-Tip",)
    np.testing.assert_allclose(points["watch point"].points, [[0.0, 1.0]])
    assert len(points["controller writes"].points) == len(inlet.segments)
    assert sketch.undrawn == ["solid (dealii)"]


@pytest.mark.openfoam
@needs_blockmesh
def test_the_plate_s_heater_and_interface_are_read_from_both_solvers(tmp_path) -> None:
    """Cost: about 2 s (the env made, blockMesh of the fluid and of the plate)."""
    sketch = _sketch("heated-plate-fast", tmp_path)
    heater = sketch.patch("bottom", "solid")
    assert (heater.kind, heater.role) == ("actuator", "controller writes Temperature")
    fluid_side = sketch.patch("interface", "fluid")
    assert fluid_side.kind == "interface"
    assert fluid_side.role == "controller reads Temperature; coupled with Solid"
    assert sketch.patch("interface", "solid").role == "coupled with Fluid"
    assert sketch.patch("outlet").kind == "outlet", "a fixed pressure, though typed wall"
    assert [r.solver for r in sketch.regions] == ["fluid", "solid"]
    labels = sorted(p.label for p in sketch.points)
    assert labels == [
        "controller reads Temperature (41 vertices)",
        "controller writes Temperature (32 vertices)",
        "controller writes Velocity (11 vertices)",
        "preCICE watch points",
    ]


@pytest.mark.openfoam
@needs_blockmesh
def test_the_command_draws_the_jet_cylinder_and_leaves_only_its_picture(
    tmp_path, monkeypatch, capsys
) -> None:
    """Cost: about 4 s (the env made, blockMesh of the 3,580-cell case, the picture)."""
    work, scratch = tmp_path / "work", tmp_path / "scratch"
    work.mkdir(), scratch.mkdir()
    monkeypatch.chdir(work)
    monkeypatch.setenv("TMPDIR", str(scratch))
    assert main(["sketch", "jet-cylinder-fast", "--out", "jet.png"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == ["fluid: mesh built by blockMesh in a temporary directory", "jet.png"]
    assert sorted(p.name for p in work.iterdir()) == ["jet.png"]
    assert list(scratch.iterdir()) == []


def test_a_double_has_nothing_to_sketch(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    status = main(["sketch", "jet-cylinder-fast", "--env-kwargs", '{"double": true}'])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1
    assert "no installed plugin sketches its solvers (fluid: command)" in err
    assert list(tmp_path.iterdir()) == []
