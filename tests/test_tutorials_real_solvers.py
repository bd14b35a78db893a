"""The tutorial environments on the real stack: preCICE, OpenFOAM and the adapters.

Everything else tests the tutorials against the preCICE test double and a scripted flow;
these tests run them the way users do, with real ``pimpleFoam`` loading the
OpenFOAM-preCICE adapter (and the deal.II adapter's ``elasticity`` for the flap). They
are skipped, naming what is missing, on machines without preCICE or the adapters (none
of the three is in a package registry; docs/get-started.md, "Real preCICE and the
adapters", says how to get them).
"""

from __future__ import annotations

import math
import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gymprecice.env.processes import kill_recorded_groups
from gymprecice.tools.stack import stack_which
from gymprecice_openfoam.testing import missing_coupled_stack

_MISSING = missing_coupled_stack("pimpleFoam")

pytestmark = [
    pytest.mark.precice,
    pytest.mark.openfoam,
    pytest.mark.slow,
    pytest.mark.skipif(bool(_MISSING), reason="needs " + ", ".join(_MISSING)),
]


def _episode(
    env: Any, action: float, seed: int
) -> tuple[list[tuple[float, float]], dict[str, Any]]:
    """(Cd, Cl) after each step of one episode at a constant action; the last step's info."""
    obs, _ = env.reset(seed=seed)
    assert obs.shape == env.observation_space.shape
    coefficients = []
    info: dict[str, Any] = {}
    truncated = terminated = False
    steps = 0
    while not (truncated or terminated):
        obs, reward, terminated, truncated, info = env.step(np.array([action], np.float32))
        steps += 1
        assert np.isfinite(obs).all() and math.isfinite(reward)
        assert env.observation_space.contains(obs)
        coefficients.append((info["Cd"], info["Cl"]))
    assert truncated and not terminated, "the end of the simulated time is a truncation"
    assert steps == env.case_spec.actions_per_episode
    return coefficients, info


def _cylinder_env(name: str, run_root: Path) -> Any:
    """A cylinder env on the coarse quickstart mesh, one process, a short pre-run."""
    from gymprecice_tutorials.quickstart.environment import QuickstartEnv
    from gymprecice_tutorials.recipes import Resolution
    from gymprecice_tutorials.rotating_cylinder.environment import RotatingCylinderEnv

    # the flow need not shed: a restartable snapshot and a few actions are enough
    short = {"prerun_end_time": 0.05, "actions_per_episode": 3}
    if name == "jets":
        return QuickstartEnv(run_root=run_root, case_overrides=short)
    coarse = {"resolution": Resolution.coarse(), "n_procs": 1}
    return RotatingCylinderEnv(run_root=run_root, case_overrides={**short, **coarse})


@pytest.mark.timeout(600)
@pytest.mark.parametrize("actuation", ["jets", "rotation"])
def test_cylinder_envs_run_coupled_to_pimplefoam_and_the_actuation_acts(
    actuation: str, tmp_path: Path
) -> None:
    """Cost: about 10 CPU-s per actuation (blockMesh and a 0.05 s pre-run of the coarse mesh,
    then two 3-action episodes coupled to pimpleFoam).
    """
    env = _cylinder_env(actuation, tmp_path)
    try:
        still, _ = _episode(env, 0.0, seed=1)
        acting, info = _episode(env, float(env.action_space.high[0]), seed=1)
        run_dir = env.env_dir
    finally:
        env.close()

    log = (run_dir / "fluid-openfoam" / "log.pimpleFoam").read_text(errors="replace")
    assert "Loaded the OpenFOAM-preCICE adapter" in log
    assert "The coupling completed" in log or "ended by preCICE" in log
    # The strongest action changes the forces OpenFOAM computes: it reached the boundary
    # (jets: the drag; rotation: the Magnus lift).
    key = 0 if actuation == "jets" else 1
    changed = np.abs(np.asarray(acting[-1]) - np.asarray(still[-1]))[key]
    assert changed > 1e-3 * max(1.0, abs(still[-1][key]))
    assert info["action"] == [pytest.approx(float(env.action_space.high[0]))]
    # Nothing of the episode's solver is left running after close.
    assert kill_recorded_groups(run_dir) == []


@pytest.mark.dealii
@pytest.mark.timeout(600)
@pytest.mark.skipif(stack_which("elasticity") is None, reason="needs the deal.II adapter")
def test_perpendicular_flap_runs_fsi_with_deal_ii_and_closes_mid_episode(
    tmp_path: Path,
) -> None:
    """Cost: about 8 CPU-s (blockMesh, then three 0.1 s steps of the three-participant FSI,
    closed mid-episode).
    """
    from gymprecice_tutorials.perpendicular_flap.environment import PerpendicularFlapEnv

    env = PerpendicularFlapEnv(run_root=tmp_path)
    try:
        env.reset(seed=0)
        tips = []
        for centre in (1.0, 1.0, 3.0):
            _, reward, terminated, truncated, info = env.step(np.array([centre], np.float32))
            assert not (terminated or truncated)
            assert info["metrics"]["mean_tip_displacement"] == pytest.approx(-reward)
            tips.append(info["metrics"]["tip_dx"])
        run_dir = env.env_dir
        assert env.time == pytest.approx(0.3)
    finally:
        env.close()  # mid-episode: the solvers are stopped, not waited for

    # The flow pushes the flap downstream: the tip moves in +x from rest.
    assert 0.0 < tips[0] < tips[-1]
    assert "Loaded the OpenFOAM-preCICE adapter" in (
        run_dir / "fluid-openfoam" / "log.pimpleFoam"
    ).read_text(errors="replace")
    assert kill_recorded_groups(run_dir) == []


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.dealii
@pytest.mark.timeout(600)
@pytest.mark.skipif(stack_which("elasticity") is None, reason="needs the deal.II adapter")
@pytest.mark.parametrize("victim", ["fluid", "solid"])
def test_killing_one_of_three_participants_leaves_nothing_of_the_other_behind(
    tmp_path: Path, victim: str
) -> None:
    """PerpendicularFlapFast-v0: SIGKILL of the fluid or the solid mid-episode ends the
    step with an error naming it, the other solver's process group is gone, and the next
    reset starts a whole new three-participant run.

    Cost: about 4 CPU-s per victim (PerpendicularFlapFast-v0: 0.2 s settling, a step, the kill, a
    new episode's first step).
    """
    from gymprecice.plugin.errors import CouplingError, SolverError
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    env = PerpendicularFlapFastEnv(run_root=tmp_path, settle_time=0.2, episode_time=0.5)
    try:
        env.reset(seed=0, options={"split": "eval"})
        env.step(np.array([2.0], np.float32))
        solvers = {process.name: process for process in env._gymprecice.run.session.solvers}
        assert set(solvers) == {"fluid", "solid"}
        groups = {name: process.pgid for name, process in solvers.items()}
        os.killpg(groups[victim], signal.SIGKILL)
        with pytest.raises((SolverError, CouplingError)) as raised:
            for _ in range(5):
                env.step(np.array([2.0], np.float32))
        assert victim in str(raised.value)
        assert not any(_group_alive(pgid) for pgid in groups.values())
        assert kill_recorded_groups(env.env_dir) == []
        obs, info = env.reset(seed=1, options={"split": "eval"})
        assert np.isfinite(obs).all() and info["start"]["split"] == "eval"
        *_, truncated, _ = env.step(np.array([2.0], np.float32))
        assert not truncated
    finally:
        env.close()
    assert kill_recorded_groups(env.env_dir) == []


@pytest.mark.dealii
@pytest.mark.timeout(600)
@pytest.mark.skipif(stack_which("elasticity") is None, reason="needs the deal.II adapter")
def test_the_flap_tip_read_through_precice_is_the_watch_points_state_of_the_same_window(
    tmp_path: Path,
) -> None:
    """PerpendicularFlapFast-v0 with ``observe="precice"``: the controller reads the tip's
    displacement through preCICE (a tip mesh, two more explicit schemes). It is the
    converged state of the step's last window, the same one the watch point logs: no lag,
    no stale iterate, and the flap has moved.

    Cost: about 3 CPU-s (PerpendicularFlapFast-v0: 0.3 s settling and five steps).
    """
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    env = PerpendicularFlapFastEnv(
        run_root=tmp_path, observe="precice", settle_time=0.3, episode_time=0.5
    )
    try:
        obs, _ = env.reset(seed=0, options={"split": "eval"})
        moved = []
        for _ in range(5):
            obs, *_ = env.step(np.array([2.0], np.float32))
            row = env._tip.data[-1:]
            assert float(row[0, 0]) == pytest.approx(env.time)
            watched = env._tip.field("Displacement", row)[0]
            np.testing.assert_allclose(obs[:2], watched, rtol=0.02, atol=1e-5)
            assert np.isfinite(obs).all() and np.linalg.norm(obs[4:6]) > 0
            moved.append(abs(float(obs[0])))
        assert max(moved) > 1e-3
    finally:
        env.close()
    assert kill_recorded_groups(env.env_dir) == []


@pytest.mark.dealii
@pytest.mark.timeout(600)
@pytest.mark.skipif(stack_which("elasticity") is None, reason="needs the deal.II adapter")
def test_a_flap_driven_to_diverge_reports_participant_time_and_log_line_and_goes_on(
    tmp_path: Path,
) -> None:
    """PerpendicularFlapFast-v0 with ten times its inflow: pimpleFoam's floating-point trap
    ends the episode as an outcome (which participant, when, the log line), at once
    rather than after the watch point's timeout, and the next episode starts clean.

    Cost: about 7 CPU-s (two PerpendicularFlapFast-v0 episodes at ten times the inflow, each ended
    by the divergence within a few steps).
    """
    import time

    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    env = PerpendicularFlapFastEnv(
        run_root=tmp_path, inlet_max_velocity=100.0, settle_time=0.2, episode_time=2.0
    )
    try:
        for seed in (0, 1):
            env.reset(seed=seed, options={"split": "eval"})
            outcome = None
            for _ in range(20):
                started = time.monotonic()
                _, reward, terminated, truncated, info = env.step(np.array([1.0], np.float32))
                if terminated or truncated:
                    outcome = (reward, terminated, info, time.monotonic() - started)
                    break
            assert outcome is not None and outcome[1], "the flow did not diverge"
            reward, _, info, took = outcome
            assert reward == env.divergence_penalty
            assert info["diverged"]["solver"] == "fluid"
            assert "sigFpe" in info["diverged"]["evidence"] and info["diverged"]["time"] > 0.2
            assert took < env.watch_timeout / 4  # not the watch point's timeout
            assert kill_recorded_groups(env.env_dir) == []
    finally:
        env.close()


@pytest.mark.timeout(600)
def test_a_training_run_whose_agent_drives_the_flow_to_diverge_finishes_and_counts_them(
    tmp_path: Path,
) -> None:
    """``gymprecice train`` on the quickstart with a jet bound 200 times its own: most
    episodes diverge under PPO's first actions. The run finishes with its model, the
    training log counts the divergences, and none of them is charged as a failure.

    Cost: about 15 CPU-s (``gymprecice train`` of 24 PPO steps on the quickstart: blockMesh, a
    0.05 s pre-run, episodes of 6 actions that mostly diverge).
    """
    import csv
    import json
    import subprocess
    import sys

    kwargs = {
        "max_flow_rate": 0.05,
        "case_overrides": {"prerun_end_time": 0.05, "actions_per_episode": 6},
    }
    args = ["train", "quickstart", "--require-solvers", "--n-envs", "1", "--timesteps", "24"]
    args += ["--n-steps", "12", "--batch-size", "12", "--seed", "0", "--out", "train"]
    args += ["--env-kwargs", json.dumps(kwargs)]
    proc = subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=540,
    )
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    assert (tmp_path / "train" / "model.zip").is_file()
    with open(tmp_path / "train" / "progress.csv", newline="") as handle:
        # the last row of training figures (a validation row may follow it)
        rows = [r for r in csv.DictReader(handle) if r["gymprecice/divergences_total"]]
    last = rows[-1]
    assert float(last["gymprecice/divergences_total"]) > 0
    assert float(last["gymprecice/failures_total"]) == 0
    assert "0 failures" in proc.stdout


@pytest.mark.timeout(600)
def test_a_jet_far_beyond_its_bound_diverges_as_an_outcome_and_the_next_episode_runs(
    tmp_path: Path,
) -> None:
    """pimpleFoam pushed past what its time step integrates: an episode outcome.

    The quickstart's jets at a thousand times their bound blow the flow up: OpenFOAM's
    floating-point trap or an iteration limit ends the solver. The step must say so
    (``terminated``, the penalty, ``info["diverged"]``) instead of raising, and the next
    reset must start clean and run a whole episode.

    Cost: about 13 CPU-s (blockMesh and a 0.05 s pre-run of the quickstart, an episode that diverges
    within 6 actions, then a whole 6-action episode).
    """
    from gymprecice_tutorials.jet_cylinder.environment import MAX_FLOW_RATE
    from gymprecice_tutorials.quickstart.environment import QuickstartEnv

    short = {"prerun_end_time": 0.05, "actions_per_episode": 6}
    env = QuickstartEnv(run_root=tmp_path, case_overrides=short, max_flow_rate=1000 * MAX_FLOW_RATE)
    try:
        env.reset(seed=1)
        outcome = None
        for _ in range(6):
            _, reward, terminated, truncated, info = env.step(env.action_space.high)
            if terminated or truncated:
                outcome = (reward, terminated, info)
                break
        assert outcome is not None and outcome[1], "the flow did not diverge"
        reward, _, info = outcome
        assert reward == env.divergence_penalty
        assert info["diverged"]["solver"] == "fluid"
        assert info["diverged"]["evidence"]
        coefficients, _ = _episode(env, 0.0, seed=2)  # clean again, to the end
        assert all(math.isfinite(cd) for cd, _ in coefficients)
        run_dir = env.env_dir
    finally:
        env.close()
    assert kill_recorded_groups(run_dir) == []
