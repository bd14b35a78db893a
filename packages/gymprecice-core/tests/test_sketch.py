"""``gymprecice sketch``: a case's sketch as data, drawn, and the command's refusals.

A toy plugin sketches the ``command`` solver of core's test case (a channel, a cylinder,
two jets the controller writes, a probe mesh it reads): what core makes of it comes from
the preCICE configuration alone, so the kinds, roles and markers are checked as data
before any pixel. The picture is checked for what it must hold (a PNG of the right size, an
SVG naming the patches); the refusals each say the fix in one line, with exit status 2,
and write nothing.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.config import load_config
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import temporary_plugin
from gymprecice.plugin.sketch import SketchPatch, SketchPoints, SolverSketch
from gymprecice.tools.case_sketch import CaseSketch, DrawnPatch, sketch_case
from gymprecice.tools.cli import main

pytest.importorskip("matplotlib", reason="the render extra: gymprecice-core[render]")


def _arc(start: float, stop: float, n: int, centre=(0.2, 0.2), radius=0.05) -> np.ndarray:
    angles = np.linspace(start, stop, n + 1)
    points = np.stack([centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)], 1)
    return np.stack([points[:-1], points[1:]], axis=1)


def _line(a, b, n: int = 4) -> np.ndarray:
    points = np.linspace(a, b, n + 1)
    return np.stack([points[:-1], points[1:]], axis=1)


def toy_sketch() -> SolverSketch:
    """A channel 2.2 x 0.41 with a cylinder and two jets: the cylinder benchmark's shape."""
    jet1, jet2 = (
        _arc(math.radians(85), math.radians(95), 2),
        _arc(-math.radians(95), -math.radians(85), 2),
    )
    circle = np.concatenate([_arc(0, 2 * math.pi, 36)[:, 0]])
    outer = np.array([[0, 0], [2.2, 0], [2.2, 0.41], [0, 0.41]], float)
    return SolverSketch(
        patches=(
            SketchPatch("inlet", "inlet", _line((0, 0), (0, 0.41))),
            SketchPatch("outlet", "outlet", _line((2.2, 0), (2.2, 0.41))),
            SketchPatch(
                "walls",
                "wall",
                np.concatenate([_line((0, 0), (2.2, 0)), _line((0, 0.41), (2.2, 0.41))]),
            ),
            SketchPatch(
                "cylinder",
                "wall",
                _arc(math.radians(95), math.radians(265), 16),
                ("Fluid-Mesh-probe",),
            ),
            SketchPatch("jet1", "patch", jet1, ("Fluid-Mesh-jet1",)),
            SketchPatch("jet2", "patch", jet2, ("Fluid-Mesh-jet2",)),
        ),
        loops=(outer, circle),
        points=(SketchPoints("probes", [[0.3, 0.2, 0.0], [0.5, 0.2, 0.0]], "toy probes (p): 2"),),
        vertices={
            "Fluid-Mesh-jet1": jet1.mean(axis=1),
            "Fluid-Mesh-jet2": jet2.mean(axis=1),
            "Fluid-Mesh-probe": np.array([[0.2, 0.0], [0.4, 0.05], [0.6, -0.05]]),
        },
        notes=("the toy's mesh",),
    )


class ToySketcher:
    """Sketches core's ``command`` solver; records the context it was asked with."""

    def __init__(self) -> None:
        self.asked: list = []

    @hookimpl
    def gymprecice_sketch_case(self, solver):
        if solver.kind != "command":
            return None
        self.asked.append(solver)
        return toy_sketch()


@pytest.fixture
def toy():
    sketcher = ToySketcher()
    with temporary_plugin(sketcher, "toy-sketcher"):
        yield sketcher


def _files(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_size for p in root.rglob("*") if p.is_file()}


# -- the data --------------------------------------------------------------------------------


def test_the_coupling_makes_actuators_and_sensed_patches(toy, case_dir: Path) -> None:
    sketch = sketch_case(load_config(case_dir), "toy")
    assert [c.run_dir for c in toy.asked] == [case_dir / "fluid"]  # the pristine case, read only
    assert sketch.patch("jet1").kind == sketch.patch("jet2").kind == "actuator"
    assert sketch.patch("jet1").role == "controller writes Velocity"
    cylinder = sketch.patch("cylinder")
    assert cylinder.kind == "wall" and cylinder.role == "controller reads Pressure"
    assert sketch.patch("inlet").kind == "inlet" and sketch.patch("inlet").role == ""
    kinds = {p.kind: p for p in sketch.points}
    assert len(kinds["controller writes"].points) == 4  # two faces per jet
    np.testing.assert_allclose(kinds["controller reads"].points[:, 0], [0.2, 0.4, 0.6])
    assert kinds["probe"].label == "toy probes (p): 2"
    assert sketch.notes == ["fluid: the toy's mesh"] and sketch.undrawn == []
    assert [r.label for r in sketch.regions] == ["fluid (command, Fluid)"]


def test_a_solver_no_plugin_sketches_is_named_as_not_drawn(case_dir: Path) -> None:
    sketch = sketch_case(load_config(case_dir), "toy", {"fluid": None})
    assert sketch.undrawn == ["fluid (command)"] and sketch.patches == []


def test_a_plugin_sketch_is_checked() -> None:
    with pytest.raises(ValueError, match="kind 'jet'"):
        SketchPatch("jet1", "jet", np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match=r"segments: expected shape \(-1, 2, 2\)"):
        SketchPatch("jet1", "wall", np.zeros((3, 2)))
    with pytest.raises(ValueError, match="points 'p'"):
        SketchPoints("p", np.zeros(4))


# -- the picture -----------------------------------------------------------------------------


def test_the_picture_holds_every_patch_and_an_enlarged_panel(toy, case_dir, tmp_path) -> None:
    import imageio.v2 as imageio

    from gymprecice.tools.sketch_drawing import detail_box, draw_sketch

    sketch = sketch_case(load_config(case_dir), "toy")
    box = detail_box(sketch)
    assert box is not None, "the jets are small beside the channel: an enlarged panel"
    assert np.all(box[0] <= [0.15, 0.15]) and np.all(box[1] >= [0.25, 0.25])
    png = draw_sketch(sketch, tmp_path / "toy.png")
    image = np.asarray(imageio.imread(png))
    assert image.shape[1] == 880 and image.shape[0] > 400 and image[..., :3].var() > 100
    svg = draw_sketch(sketch, tmp_path / "toy.svg").read_text()
    for name in ("jet1", "jet2", "cylinder", "inlet", "outlet", "walls", "x [m]"):
        assert name in svg, name


def test_no_enlarged_panel_where_the_actuators_are_large() -> None:
    from gymprecice.tools.sketch_drawing import detail_box

    big = DrawnPatch("fluid", "inlet", "actuator", _line((0, 0), (0, 4)))
    wall = DrawnPatch("fluid", "walls", "wall", _line((0, 0), (6, 0)))
    assert detail_box(CaseSketch("t", patches=[big, wall])) is None


# -- the command -----------------------------------------------------------------------------


def run(capsys, *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_the_command_writes_only_its_picture(toy, case_dir, tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    before = _files(case_dir)
    status, out, err = run(capsys, "sketch", str(case_dir), "--out", "toy.svg")
    assert status == 0, err
    assert out.splitlines() == ["fluid: the toy's mesh", "toy.svg"]
    assert _files(case_dir) == before
    assert sorted(_files(tmp_path / "tmp")) == [] and (tmp_path / "toy.svg").stat().st_size > 0


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["no-such-env"], "no registered gymprecice environment 'no-such-env'"),
        (["CASE", "--out", "toy.jpg"], "a sketch is a .png or .svg file"),
        (["CASE", "--out", "missing/toy.png"], "the directory missing does not exist"),
        (["CASE", "--out", "afile/toy.png"], "the directory afile does not exist"),
        (["CASE", "--out", "."], "is a directory; give a file in it"),
        (["CASE", "--env-kwargs", "{}x"], "--env-kwargs: not JSON"),
        (["CASE", "--env-kwargs", '{"a": 1}'], "only a registered environment takes them"),
    ],
)
def test_bad_input_is_refused_in_one_line(toy, case_dir, tmp_path, capsys, monkeypatch, argv, says):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    argv = [str(case_dir) if a == "CASE" else a for a in argv]
    before = _files(tmp_path)
    status, out, err = run(capsys, "sketch", *argv)
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("gymprecice sketch: error: ") and says in err
    assert _files(tmp_path) == before


def test_a_case_no_plugin_sketches_is_refused(case_dir, tmp_path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    status, _, err = run(capsys, "sketch", str(case_dir), "--out", "x.png")
    assert status == 2 and err.count("\n") == 1
    assert "no installed plugin sketches its solvers (fluid: command)" in err
    assert "gymprecice_sketch_case" in err and not (tmp_path / "x.png").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_an_unwritable_directory_is_refused(toy, case_dir, tmp_path, capsys) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    status, _, err = run(capsys, "sketch", str(case_dir), "--out", str(locked / "x.png"))
    assert status == 2 and "is not writable" in err
