"""``render_mode="rgb_array"`` on the real stack: the deal.II and FEniCS solids' fields.

OpenFOAM's fields are tested in ``test_rendering_real.py``; these run a three-participant
case with each of the other solver families: the flap (OpenFOAM fluid, deal.II solid) and
the heated plate with its FEniCS plate. Checks as on the double: the frame's shape, that
it shows something, that it changes between two actions, and that the same env without
``render_mode`` makes its solid write nothing more than before. Skipped, naming what is
missing, on machines without the real stack; ``GYMPRECICE_REQUIRE_REAL=1`` (CI) fails
instead.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.processes import kill_recorded_groups
from gymprecice.tools.stack import stack_which
from gymprecice_openfoam.testing import missing_coupled_stack

VARIANCE_FLOOR = 100.0
#: a frame's width (the env's); its height follows the drawn domain, in macro blocks of 16
WIDTH = 640


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def _rendered_episode(env, action: np.ndarray, reset_options=None) -> tuple[np.ndarray, ...]:
    """Frames after reset and after each action of one whole episode."""
    env.reset(seed=0, options=reset_options)
    frames = [env.render()]
    truncated = False
    while not truncated:
        *_, terminated, truncated, _ = env.step(action)
        assert not terminated
        frames.append(env.render())
    return tuple(frames)


def _plain_episode(env, action: np.ndarray, reset_options=None) -> None:
    env.reset(seed=0, options=reset_options)
    truncated = False
    while not truncated:
        *_, truncated, _ = env.step(action)


def _check_frames(frames: tuple[np.ndarray, ...]) -> None:
    for frame in frames:  # one size for the episode
        assert frame.shape == frames[0].shape and frame.dtype == np.uint8
        assert frame.var() > VARIANCE_FLOOR
    assert frames[0].shape[1:] == (WIDTH, 3) and frames[0].shape[0] % 16 == 0
    assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).sum() > 0


_FLAP_MISSING = missing_coupled_stack("pimpleFoam") + (
    [] if stack_which("elasticity") else ["the deal.II adapter (elasticity)"]
)


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.skipif(bool(_FLAP_MISSING), reason="needs " + ", ".join(_FLAP_MISSING))
def test_the_flap_renders_fluid_and_bent_solid_and_writes_nothing_more_without_render_mode(
    tmp_path: Path,
) -> None:
    """Cost: two PerpendicularFlapFast-v0 runs of 0.4 s (0.1 s settling, 3 actions) on real
    pimpleFoam and elasticity, about 30 s on 2 cores."""
    from gymprecice.plugin.solver import SolverContext
    from gymprecice_dealii.fields import read_vtk
    from gymprecice_dealii.prm import ElasticityParameters
    from gymprecice_openfoam.fields import read_field
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    short = {"settle_time": 0.1, "episode_time": 0.3}
    env = PerpendicularFlapFastEnv(
        run_root=tmp_path / "rendering", render_mode="rgb_array", **short
    )
    plain = PerpendicularFlapFastEnv(run_root=tmp_path / "plain", **short)
    jet = np.array([1.0], np.float32)
    try:
        frames = _rendered_episode(env, jet)
        solid, fluid = env.solver_dirs["solid"], env.solver_dirs["fluid"]
        _plain_episode(plain, jet)
        plain_solid, plain_fluid = plain.solver_dirs["solid"], plain.solver_dirs["fluid"]
    finally:
        env.close()
        plain.close()
    _check_frames(frames)
    written = sorted(p.name for p in (solid / "dealii-output").iterdir())
    # the start, and one snapshot per action: settling and the episode's 3
    assert written == [f"solution-{k:03d}.vtk" for k in range(5)]
    # the last frame's flap is bent downstream by the flow (the tip moves +x)
    last = read_vtk(solid / "dealii-output" / written[-1]).point_data["displacement"]
    assert last[:, 0].max() > 1e-3
    # Without render_mode the solid writes what it wrote before rendering existed: the
    # packaged interval (a snapshot every 2.5 s: only the start in 0.4 s).
    prm = ElasticityParameters.read(plain_solid / "parameters.prm")
    assert prm.output_interval == 50
    assert sorted(p.name for p in (plain_solid / "dealii-output").iterdir()) == ["solution-000.vtk"]
    extra = _files(solid) - _files(plain_solid)
    assert all(name.startswith("dealii-output/solution-") for name in extra), sorted(extra)
    # The fluid (a moving mesh, coupled implicitly to the flap) writes per action only what
    # a frame needs: U and the mesh's points (and OpenFOAM's uniform/time beside them), not
    # its whole state.
    extra = _files(fluid) - _files(plain_fluid)
    written = {name.split("/", 1)[1] for name in extra if not name.startswith("log")}
    assert written == {"U", "polyMesh/points", "uniform/time"}, sorted(extra)
    assert len({name.split("/")[0] for name in extra}) == 4  # settling and 3 actions
    # ...and is drawn on its mesh as it is at the frame's time, bent with the flap
    reader = SolverContext(
        name="fluid",
        kind="openfoam",
        run_dir=fluid,
        source_dir=fluid,
        env_dir=fluid.parent,
        env_index=0,
        fields=("U",),
        field_interval=0.1,
    )
    moved = read_field(reader, "U", 0.4)
    assert moved is not None and moved.time == pytest.approx(0.4)
    assert moved.displacement is not None and moved.displacement[:, 0].max() > 1e-4
    assert kill_recorded_groups(env.env_dir) == []


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.skipif(bool(_FLAP_MISSING), reason="needs " + ", ".join(_FLAP_MISSING))
def test_the_flap_renders_its_last_frame_after_the_truncating_step(tmp_path: Path) -> None:
    """Cost: one PerpendicularFlapFast-v0 run of 0.3 s (0.1 s settling, 2 actions) on real
    pimpleFoam and elasticity, about 15 s on 2 cores.

    The fluid couples implicitly, so it writes its frames after the preCICE adapter; at the
    coupling's last step the adapter sets the time step to 0 and ends the run, and the
    end time over the frame's interval (0.3 / 0.1 = 2.9999999999999996) lands a hair under
    3: the frame's interval must still count it as the last action's end. Gymnasium's
    RecordVideo renders after the last step, as the lab's --video does.
    """
    from gymprecice_openfoam import fields
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    env = PerpendicularFlapFastEnv(
        run_root=tmp_path / "runs", render_mode="rgb_array", settle_time=0.1, episode_time=0.2
    )
    try:
        frames = _rendered_episode(env, np.array([1.0], np.float32))
        fluid = env.solver_dirs["fluid"]
    finally:
        env.close()
    assert len(frames) == 3  # the reset's and one per action, the last one too
    _check_frames(frames)
    control = (fluid / "system" / "controlDict").read_text()
    assert control.index("preCICE_Adapter") < control.index(fields.FUNCTION)
    written = {p.parent.name for p in fluid.glob("*/U")}
    assert written == {"0", "0.1", "0.2", "0.3"}
    # the last frame's files only, not the whole state of the run's end
    last = {str(p.relative_to(fluid / "0.3")) for p in (fluid / "0.3").rglob("*") if p.is_file()}
    assert last == {"U", "polyMesh/points", "uniform/time"}
    assert kill_recorded_groups(env.env_dir) == []


def _fenics_missing() -> list[str]:
    from gymprecice_fenics import solver_env

    missing = missing_coupled_stack("buoyantPimpleFoam", "blockMesh")
    return missing + list(solver_env.probe().problems)


_PLATE_MISSING = _fenics_missing()


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.fenics
@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.skipif(bool(_PLATE_MISSING), reason="needs " + ", ".join(_PLATE_MISSING))
def test_the_fenics_plate_renders_its_temperature_and_writes_nothing_more_without_render_mode(
    tmp_path: Path,
) -> None:
    """Cost: two HeatedPlate-v0 runs with the FEniCS plate of 0.2 s (0.1 s settling, one
    action) on real buoyantPimpleFoam and FEniCS, about 2 minutes on 2 cores (the full
    fluid mesh: the training case has no FEniCS plate)."""
    from gymprecice.plugin.fields import FIELDS_DIR, read_field_file
    from gymprecice_tutorials.heated_plate.environment import HeatedPlateEnv

    short = {"solid": "fenics", "settle_time": 0.1, "episode_time": 0.1}
    env = HeatedPlateEnv(run_root=tmp_path / "rendering", render_mode="rgb_array", **short)
    plain = HeatedPlateEnv(run_root=tmp_path / "plain", **short)
    heater = np.array([330.0], np.float32)
    split = {"split": "eval"}
    try:
        frames = _rendered_episode(env, heater, split)
        solid = env.solver_dirs["solid"]
        _plain_episode(plain, heater, split)
        plain_solid = plain.solver_dirs["solid"]
    finally:
        env.close()
        plain.close()
    _check_frames(frames)
    # the last frame's plate: warmed from its bottom by the 330 K heater
    plate = read_field_file(solid / FIELDS_DIR / "T.npz")
    assert plate.time == pytest.approx(0.2)
    assert 320.0 < plate.values.max() <= 330.0 + 1e-6
    assert _files(solid) - _files(plain_solid) == {f"{FIELDS_DIR}/T.npz"}
    assert not (plain_solid / FIELDS_DIR).exists()
    assert kill_recorded_groups(env.env_dir) == []
