"""Turek and Hron's FSI3 on the real stack: the mesh through blockMesh and checkMesh, and
the coupled run through the environment (``validate --smoke``).

The comparison with the published values needs seconds of simulated time (tens of
minutes on 2 cores): it is the documented full run of docs/validation.md. Skipped,
naming what is missing, on machines without the real stack;
``GYMPRECICE_REQUIRE_REAL=1`` (CI) fails instead.
"""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from gymprecice.tools.stack import stack_which
from gymprecice_openfoam.installation import find_openfoam
from gymprecice_openfoam.testing import missing_coupled_stack
from gymprecice_tutorials.case_files import write_case_files
from gymprecice_tutorials.turek_hron.case import case_files
from gymprecice_tutorials.turek_hron.mesh import RESOLUTIONS, cell_count


@pytest.mark.openfoam
def test_the_coarse_mesh_is_sound_and_has_the_cells_and_patches_it_declares(tmp_path) -> None:
    """Cost: about 2 s (blockMesh and checkMesh of 4,808 cells)."""
    missing = missing_coupled_stack("blockMesh", "checkMesh")
    if any(item.startswith("OpenFOAM") for item in missing):
        pytest.skip("needs " + ", ".join(missing))
    case = write_case_files("fsi3", case_files("coarse"), tmp_path) / "fluid-openfoam"
    env = find_openfoam().environ()
    for program in ("blockMesh", "checkMesh"):
        done = subprocess.run(
            [program], cwd=case, env=env, capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    report = done.stdout
    assert "Mesh OK." in report
    assert int(re.search(r"cells:\s+(\d+)", report).group(1)) == cell_count(RESOLUTIONS["coarse"])
    sizes = dict(re.findall(r"^\s+(\w+)\s+(\d+)\s+\d+\s+ok", report, re.MULTILINE))
    assert {"inlet", "outlet", "walls", "cylinder", "jet1", "jet2", "flap"} <= set(sizes)
    # the bar (0.35 m long, 0.02 m thick, cells of 0.01 m) is wetted on three sides
    assert int(sizes["flap"]) >= 2 * 35 + 2


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_the_coupled_fsi3_run_goes_through_the_environment(tmp_path) -> None:
    """Cost: about half a minute (0.04 s of FSI3, 40 implicitly coupled windows: enough
    for every output of the coupled run; the full run is docs/validation.md's)."""
    missing = missing_coupled_stack("pimpleFoam", "blockMesh")
    if not stack_which("elasticity"):
        missing.append("the deal.II-preCICE adapter (elasticity)")
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    _smoke_run(tmp_path, "--end-time", "0.04")  # its watch point must have 40 windows


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.fenics
@pytest.mark.slow
@pytest.mark.timeout(500)
def test_an_episode_from_a_saved_start_repeats_the_uncontrolled_run_it_was_saved_from(
    tmp_path,
) -> None:
    """The FEniCS bar (tests/test_fsi3_solid_real.py) as the coupled solid: a smoke-size
    library of starts is built by the uncontrolled run through the env (20 windows, in
    two segments: the second starts from the first's checkpoint), then an episode of the
    registered control env (``gymprecice/TurekHronFSI3-v0``) from its validation start,
    made ``uncontrolled`` and asked for the jets' full flow, must repeat that run: the
    fluid restarts from its time directory on the deformed mesh, the bar from its saved
    state, and each hands the other its state at the first window; every step's drag
    (read on the fluid's clock, which begins at the start's time) and reward are the
    run's, and the env renders the flow and the bent bar (the bar writes its field on
    the coupling's clock). Cost: about 1.5 min."""
    import gymnasium as gym
    import numpy as np

    import gymprecice  # noqa: F401  (registers the ids)
    from gymprecice_fenics import solver_env
    from gymprecice_tutorials.turek_hron import starts
    from gymprecice_tutorials.turek_hron.environment import reward_terms
    from gymprecice_tutorials.turek_hron.series import recorded_series

    missing = missing_coupled_stack("pimpleFoam", "blockMesh")
    report = solver_env.probe()
    if not report.ok:
        missing += list(report.problems)
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    built = _run_module("build_starts", "--smoke", "--out", str(tmp_path / "starts"))
    assert "t = 0.01 s of 0.04 s" in built  # a checkpoint, which the last segment started from
    library = starts.load(tmp_path / "starts")
    assert library.times == ("0.02", "0.03", "0.04")
    assert not (tmp_path / ".starts-run").exists()  # the build's run is removed
    uncontrolled = dict(np.load(library.path / starts.UNCONTROLLED))

    env = gym.make(
        "gymprecice/TurekHronFSI3-v0",
        starts=library.path,
        time_step=0.002,
        episode_time=0.01,
        action_time=0.002,
        uncontrolled=True,
        run_root=tmp_path / "runs",
        render_mode="rgb_array",
        disable_env_checker=True,
    )
    steps = []
    try:
        obs, info = env.reset(seed=0, options={"split": "validation", "start": 0})
        assert info["start"] == {"split": "validation", "index": 0, "time": "0.03"}
        first = env.render()
        full = np.asarray(env.action_space.high, dtype=np.float32)
        truncated = False
        while not truncated:
            *_, reward, terminated, truncated, step_info = env.step(full)
            assert not terminated
            steps.append((reward, step_info))
        last = env.render()
        episode = recorded_series(env.unwrapped, start_time=0.03)
    finally:
        env.close()
    assert first.shape == last.shape and first.shape[2] == 3 and first.var() > 100.0
    assert np.abs(last.astype(int) - first.astype(int)).sum() > 0

    def uncontrolled_at(name: str, times: np.ndarray) -> np.ndarray:
        return np.interp(times + 0.03, uncontrolled["time"], uncontrolled[name])

    # the first observation is the bar's saved state, not the bar at rest
    assert obs[0] == pytest.approx(uncontrolled_at("tip_dx", np.zeros(1))[0], rel=1e-3)
    assert abs(obs[0]) > 1e-7
    # five windows on, the restarted run is the uncontrolled one (ASCII time
    # directories of 10 digits: close, not to the bit), whatever the action asked
    assert len(steps) == 5
    for name in ("tip_dx", "drag"):
        expected = uncontrolled_at(name, episode["time"][-1:])[0]
        assert episode[name][-1] == pytest.approx(expected, rel=1e-2), name
    for k, (reward, step_info) in enumerate(steps):
        assert step_info["action"] == [0.0]  # the jets shut
        metrics = step_info["metrics"]
        expected = uncontrolled_at("drag", np.array([0.002 * (k + 1)]))[0]
        assert metrics["drag"] == pytest.approx(expected, rel=1e-2), k
        swing, penalty = reward_terms(metrics["mean_abs_tip_dy"], metrics["drag"])
        assert reward == pytest.approx(-(swing + penalty))
        assert metrics["cost"] == pytest.approx(-reward)


def _smoke_run(tmp_path, *options: str) -> str:
    """``validate --smoke`` (0.1 s of FSI3 unless `options` say otherwise) into
    ``tmp_path/runs``; its output."""
    output = _run_module("validate", "--smoke", *options, "--out", str(tmp_path / "runs"))
    assert "smoke run: every output in place" in output
    return output


def _run_module(module: str, *args: str) -> str:
    """``python -m gymprecice_tutorials.turek_hron.<module> ARGS``, which must succeed;
    its output."""
    result = subprocess.run(
        [sys.executable, "-m", f"gymprecice_tutorials.turek_hron.{module}", *args],
        capture_output=True,
        text=True,
        timeout=360,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return result.stdout
