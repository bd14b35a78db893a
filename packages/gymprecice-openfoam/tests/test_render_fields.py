"""What an OpenFOAM case writes for ``env.render()``, and where its fields are drawn.

The frame's function objects go after the preCICE adapter's where the participant couples
implicitly (before it, the adapter rewrites the whole state at every action) and its
advance never waits for the controller, and first otherwise; a moving mesh writes its
points too, and its fields are drawn at the cell centres of those points. Hermetic: a
small hexahedral mesh written by hand, no OpenFOAM.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.precice_xml import CouplingSchemeSpec, PreciceConfig
from gymprecice.plugin.solver import SolverContext
from gymprecice.testing.contexts import make_solver_context
from gymprecice_openfoam import fields, foamio
from gymprecice_openfoam.testing import HEADER

DIVIDER = "\n// ************************************************************************* //\n"
CONTROL = (
    HEADER.format(cls="dictionary", obj="controlDict")
    + """application     pimpleFoam;
writeControl    runTime;
writeInterval   0.5;

functions
{
    // the adapter { with a brace in a comment }
    preCICE_Adapter
    {
        type    preciceAdapterFunctionObject;
        libs    ("libpreciceAdapterFunctionObject.so");
    }
}
"""
)
DYNAMIC = (
    HEADER.format(cls="dictionary", obj="dynamicMeshDict")
    + "dynamicFvMesh dynamicMotionSolverFvMesh;\nsolver displacementLaplacian;\n"
)
NX, NY = 4, 3


def _vectors(rows: np.ndarray) -> str:
    return "\n".join(f"({' '.join(f'{v:.17g}' for v in row)})" for row in rows)


def _grid(nx: int, ny: int) -> tuple[np.ndarray, list[list[int]], list[int], list[int]]:
    """Points, faces, owner and neighbour of ``nx x ny`` unit hexahedra, one layer in z."""
    points = np.array(
        [(i, j, k) for k in range(2) for j in range(ny + 1) for i in range(nx + 1)], dtype=float
    )

    def p(i: int, j: int, k: int) -> int:
        return i + (nx + 1) * (j + (ny + 1) * k)

    def c(i: int, j: int) -> int:
        return i + nx * j

    def x_face(i: int, j: int) -> list[int]:
        return [p(i, j, 0), p(i, j + 1, 0), p(i, j + 1, 1), p(i, j, 1)]

    def y_face(i: int, j: int) -> list[int]:
        return [p(i, j, 0), p(i + 1, j, 0), p(i + 1, j, 1), p(i, j, 1)]

    faces, owner, neighbour = [], [], []
    for j in range(ny):
        for i in range(nx):
            if i + 1 < nx:
                faces.append(x_face(i + 1, j))
                owner.append(c(i, j))
                neighbour.append(c(i + 1, j))
            if j + 1 < ny:
                faces.append(y_face(i, j + 1))
                owner.append(c(i, j))
                neighbour.append(c(i, j + 1))
    for j in range(ny):
        for i in (0, nx):
            faces.append(x_face(i, j))
            owner.append(c(min(i, nx - 1), j))
    for i in range(nx):
        for j in (0, ny):
            faces.append(y_face(i, j))
            owner.append(c(i, min(j, ny - 1)))
        for j in range(ny):
            for k in (0, 1):
                faces.append([p(i, j, k), p(i + 1, j, k), p(i + 1, j + 1, k), p(i, j + 1, k)])
                owner.append(c(i, j))
    return points, faces, owner, neighbour


def _write_points(directory: Path, points: np.ndarray) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    text = HEADER.format(cls="vectorField", obj="points")
    (directory / "points").write_text(f"{text}{len(points)}\n(\n{_vectors(points)}\n)\n{DIVIDER}")


def _write_u(directory: Path, values: np.ndarray) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    text = HEADER.format(cls="volVectorField", obj="U") + "dimensions [0 1 -1 0 0 0 0];\n"
    text += f"internalField nonuniform List<vector>\n{len(values)}\n(\n{_vectors(values)}\n)\n;\n"
    (directory / "U").write_text(f"{text}boundaryField\n{{\n}}\n{DIVIDER}")


def _case(root: Path, *, moving: bool) -> Path:
    points, faces, owner, neighbour = _grid(NX, NY)
    mesh_dir = root / "constant" / "polyMesh"
    _write_points(mesh_dir, points)
    rows = "\n".join(f"4({' '.join(map(str, face))})" for face in faces)
    head = HEADER.format(cls="faceList", obj="faces")
    (mesh_dir / "faces").write_text(f"{head}{len(faces)}\n(\n{rows}\n)\n{DIVIDER}")
    for name, labels in (("owner", owner), ("neighbour", neighbour)):
        head = HEADER.format(cls="labelList", obj=name)
        body = "\n".join(map(str, labels))
        (mesh_dir / name).write_text(f"{head}{len(labels)}\n(\n{body}\n)\n{DIVIDER}")
    (root / "system").mkdir(parents=True)
    (root / "system" / "controlDict").write_text(CONTROL)
    if moving:
        (root / "constant" / "dynamicMeshDict").write_text(DYNAMIC)
    _write_u(root / "0", np.ones((NX * NY, 3)))
    return root


def _functions(run_dir: Path) -> dict:
    return foamio.load(run_dir / "system" / "controlDict")["functions"]


@pytest.mark.parametrize("after", [False, True])
@pytest.mark.parametrize("moving", [False, True])
def test_frame_writes_go_beside_the_adapter_and_go_without_render_mode(tmp_path, moving, after):
    run_dir = _case(tmp_path / "case", moving=moving)
    assert fields.moving_mesh(run_dir) is moving
    assert fields.set_field_writes(run_dir, ("U",), 0.1, after_adapter=after)
    functions = _functions(run_dir)
    ours = [fields.POINTS_FUNCTION] if moving else []  # the points first: complete once U is
    ours.append(fields.FUNCTION)
    expected = ["preCICE_Adapter", *ours] if after else [*ours, "preCICE_Adapter"]
    assert list(functions) == expected
    if moving:
        assert functions[fields.POINTS_FUNCTION]["objects"] == ["points"]
    assert functions[fields.FUNCTION]["objects"] == ["U"]
    assert functions[fields.FUNCTION]["writeInterval"] == pytest.approx(0.1)
    # every reset: no change
    assert not fields.set_field_writes(run_dir, ("U",), 0.1, after_adapter=after)
    assert fields.set_field_writes(run_dir, (), None)
    assert (run_dir / "system" / "controlDict").read_text() == CONTROL


def _written_steps(interval: float, dt: float, steps: int, start: float = 0.0) -> list[int]:
    """The steps at which a ``writeControl runTime`` function object after the adapter writes.

    OpenFOAM v1912's ``timeControl::execute``: it writes when ``label((t - start +
    deltaT/2) / interval)`` grows. The time is a sum of steps; after the adapter's function
    object ``deltaT`` is the next step's, and 0 at the coupling's last step (preCICE has no
    time left: the adapter's ``adjustSolverTimeStepAndReadData``).
    """
    written, index, time = [], 0, start
    for step in range(1, steps + 1):
        time += dt
        delta = dt if step < steps else 0.0
        now = int((time - start + 0.5 * delta) / interval)
        if now > index:
            index = now
            written.append(step)
    return written


@pytest.mark.parametrize("dt", [0.025, 0.01, 0.005, 0.001])
def test_after_the_adapter_every_frame_is_written_the_last_one_too(tmp_path, dt):
    """The frame's interval after the adapter: each action's end written once, on time,
    whatever the rounding of the summed time steps; the plain interval misses some ends."""
    run_dir = _case(tmp_path / "case", moving=True)
    fields.set_field_writes(run_dir, ("U",), 0.1, after_adapter=True)
    functions = _functions(run_dir)
    interval = float(functions[fields.FUNCTION]["writeInterval"])
    assert float(functions[fields.POINTS_FUNCTION]["writeInterval"]) == interval
    assert 0.1 * (1 - 2 * fields.UNDER) < interval < 0.1
    per_frame = round(0.1 / dt)
    missed = 0
    for frames in range(1, 31):  # runs of 1 to 30 actions
        steps = frames * per_frame
        expected = [per_frame * k for k in range(1, frames + 1)]
        assert _written_steps(interval, dt, steps) == expected, (dt, frames)
        assert _written_steps(interval, dt, steps, start=1.0) == expected, (dt, frames)
        missed += _written_steps(0.1, dt, steps)[-1:] != [steps]
    assert missed > 0  # the bare interval: some runs' last frame is never written
    # before the adapter the step is still there at the last one: the interval as given
    fields.set_field_writes(run_dir, ("U",), 0.1)
    assert _functions(run_dir)[fields.FUNCTION]["writeInterval"] == 0.1


def _coupled(*schemes: CouplingSchemeSpec) -> SolverContext:
    config = PreciceConfig(path=Path("precice-config.xml"), coupling_schemes=list(schemes))
    here = Path(__file__).parent
    return SolverContext(
        name="fluid",
        kind="openfoam",
        run_dir=here,
        source_dir=here,
        env_dir=here,
        env_index=0,
        participant="Fluid",
        precice=config,
    )


def test_only_an_implicit_participant_that_never_waits_for_the_controller_writes_after():
    fsi = CouplingSchemeSpec("multi", ["Fluid", "Solid"], control="Fluid")
    parallel = CouplingSchemeSpec("parallel-explicit", ["Controller", "Fluid"], "Controller")
    serial = CouplingSchemeSpec("serial-explicit", ["Controller", "Fluid"], "Controller", "Fluid")
    serial_first = CouplingSchemeSpec("serial-implicit", ["Fluid", "Solid"], "Fluid", "Solid")
    # the flap: its advance exchanges with the controller at each window's end
    assert fields.after_adapter(_coupled(fsi, parallel))
    assert fields.after_adapter(_coupled(serial_first, parallel))
    # the cylinders: never checkpoints; second of a serial scheme: would wait for the frame
    assert not fields.after_adapter(_coupled(serial))
    assert not fields.after_adapter(_coupled(fsi, serial))


def test_a_control_dict_without_functions_gets_them(tmp_path):
    run_dir = _case(tmp_path / "case", moving=False)
    path = run_dir / "system" / "controlDict"
    path.write_text(CONTROL.split("functions")[0])
    fields.set_field_writes(run_dir, ("U", "p"), 0.05)
    assert _functions(run_dir)[fields.FUNCTION]["objects"] == ["U", "p"]


def test_other_dynamic_meshes_are_drawn_undeformed(tmp_path):
    run_dir = _case(tmp_path / "case", moving=False)
    (run_dir / "constant" / "dynamicMeshDict").write_text(
        HEADER.format(cls="dictionary", obj="dynamicMeshDict")
        + "dynamicFvMesh dynamicRefineFvMesh;\n"
    )
    assert not fields.moving_mesh(run_dir)


def _solver(tmp_path: Path, run_dir: Path):
    ctx = make_solver_context("openfoam", run_dir, tmp_path / "runs", name="fluid")
    return dataclasses.replace(ctx, fields=("U",), field_interval=0.1)


def _shear(points: np.ndarray) -> np.ndarray:
    """An affine motion: hexahedra stay parallelepipeds, their centres move with them."""
    moved = points.copy()
    moved[:, 0] = points[:, 0] + 0.2 * points[:, 1] + 0.5
    moved[:, 1] = 1.1 * points[:, 1] - 0.1
    return moved


def test_a_moving_mesh_is_drawn_at_the_points_of_the_frames_time(tmp_path):
    solver = _solver(tmp_path, _case(tmp_path / "case", moving=True))
    run_dir = Path(solver.run_dir)
    fields.set_field_writes(run_dir, solver.fields, solver.field_interval)
    start = fields.read_field(solver, "U", 0.0)
    assert start is not None and start.displacement is None  # no points yet: undeformed
    centres = np.array([(i + 0.5, j + 0.5) for j in range(NY) for i in range(NX)])
    np.testing.assert_allclose(start.points, centres, atol=1e-12)

    points, *_ = _grid(NX, NY)
    _write_points(run_dir / "0.1" / "polyMesh", _shear(points))
    _write_u(run_dir / "0.1", np.full((NX * NY, 3), 2.0))
    moved = fields.read_field(solver, "U", 0.1)
    assert moved is not None and moved.time == pytest.approx(0.1)
    np.testing.assert_allclose(moved.points, centres, atol=1e-12)  # triangulated once
    expected = _shear(np.column_stack([centres, np.full(len(centres), 0.5)]))[:, :2]
    np.testing.assert_allclose(moved.positions, expected, atol=1e-12)
    np.testing.assert_allclose(moved.scalar, np.sqrt(12.0))

    # a later frame without points of its own: the newest points before it, as OpenFOAM
    _write_u(run_dir / "0.2", np.full((NX * NY, 3), 3.0))
    later = fields.read_field(solver, "U", 0.2)
    assert later is not None
    np.testing.assert_allclose(later.positions, expected, atol=1e-12)


def test_points_being_written_are_asked_for_again(tmp_path):
    solver = _solver(tmp_path, _case(tmp_path / "case", moving=True))
    run_dir = Path(solver.run_dir)
    points, *_ = _grid(NX, NY)
    _write_points(run_dir / "0.1" / "polyMesh", _shear(points))
    path = run_dir / "0.1" / "polyMesh" / "points"
    path.write_text(path.read_text().split(DIVIDER)[0][:-40])
    _write_u(run_dir / "0.1", np.ones((NX * NY, 3)))
    assert fields.read_field(solver, "U", 0.1) is None


def test_a_snapshot_is_parsed_once_while_core_waits_for_the_next(tmp_path, monkeypatch):
    solver = _solver(tmp_path, _case(tmp_path / "case", moving=False))
    parsed = []
    values = fields._values
    monkeypatch.setattr(fields, "_values", lambda path, n: parsed.append(path) or values(path, n))
    first = fields.read_field(solver, "U", 0.1)  # only 0 is written: core asks again
    again = fields.read_field(solver, "U", 0.1)
    assert again is first and len(parsed) == 1
    _write_u(Path(solver.run_dir) / "0.1", np.full((NX * NY, 3), 2.0))
    newer = fields.read_field(solver, "U", 0.1)
    assert newer is not None and newer.time == pytest.approx(0.1) and len(parsed) == 2
