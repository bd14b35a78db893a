"""JetCylinderFast-v0 / RotatingCylinderFast-v0 and ``coupling="action"`` on the test double.

The ``*-fast`` training cases couple one preCICE time window per action (serial-explicit,
the controller first, ``waveform-degree="1"``) and let the solver subcycle 25 steps of
1e-3 s in it. On the double the scripted fluid must do what OpenFOAM and its adapter do:
step with the case's own time step inside the window, read the action interpolated
linearly across the window, and write a probe and force row at every step, before the
step's ``advance`` (otherwise the controller, waiting for the window's last row, and the
fluid, waiting in ``advance`` for the next action, block each other).
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import gymprecice  # noqa: F401  (registers the tutorial environments)
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.testing import fake_precice
from gymprecice_tutorials import fake_flow, recipes
from gymprecice_tutorials.fast_cases import FAST_REWARD_OFFSET

FAST = {
    "gymprecice/JetCylinderFast-v0": ("jet_cylinder_fast", 2.5e-5),
    "gymprecice/RotatingCylinderFast-v0": ("rotating_cylinder_fast", 2.0),
}
LIFT_PENALTY = 0.2


def _coupling(case: Path) -> tuple[str, float, int | None]:
    """(scheme, window size, Velocity's waveform degree) of a case's preCICE config."""
    cfg = load_precice_config(case)
    [scheme] = cfg.coupling_schemes
    return scheme.kind, float(scheme.time_window_size), cfg.data["Velocity"].waveform_degree


@pytest.mark.parametrize("env_id", sorted(FAST))
def test_fast_env_runs_a_whole_episode_on_the_double(env_id: str, tmp_path: Path) -> None:
    recipe, bound = FAST[env_id]
    spec = recipes.case_spec(recipe)
    assert (spec.coupling, spec.flow.dt, spec.steps_per_action) == ("action", 1e-3, 25)
    assert spec.actions_per_episode == 40 and spec.episode_time == pytest.approx(1.0)
    env = gym.make(env_id, double=True, run_root=str(tmp_path / "runs"), output_timeout=30)
    try:
        space = env.action_space
        assert space.shape == (1,)
        assert np.allclose(space.low, -bound) and np.allclose(space.high, bound)
        base = env.unwrapped
        assert base.reward_offset == pytest.approx(FAST_REWARD_OFFSET)
        assert base.averaging_window == pytest.approx(0.025)
        obs, _ = env.reset(seed=0)
        assert obs.shape == (151,)
        case = next((tmp_path / "runs").glob("env_*"))
        assert _coupling(case / "precice-config.xml") == ("serial-explicit", 0.025, 1)
        times, observations = [], []
        for k in range(40):
            action = np.array([bound * np.sin(0.7 * k)], dtype=np.float32)
            obs, reward, terminated, truncated, info = env.step(action)
            assert not terminated, f"terminated at action {k + 1}"
            assert truncated == (k == 39), f"truncated={truncated} at action {k + 1}"
            assert info["time"] == pytest.approx(0.025 * (k + 1))
            rows = np.asarray(info["coefficients"])
            # one row per solver step of the action, at the solver's own times
            assert rows.shape == (25, 3), f"action {k + 1}: {rows.shape}"
            expected_times = 0.025 * k + 1e-3 * np.arange(1, 26)
            assert np.allclose(rows[:, 0], expected_times, atol=1e-9)
            cd, cl = rows[:, 1].mean(), rows[:, 2].mean()
            assert reward == pytest.approx(FAST_REWARD_OFFSET - cd - LIFT_PENALTY * abs(cl))
            assert info["Cd"] == pytest.approx(cd) and info["Cl"] == pytest.approx(cl)
            assert np.isfinite(obs).all() and obs.shape == (151,)
            times.append(rows[:, 0])
            observations.append(obs)
        assert np.allclose(np.concatenate(times), 1e-3 * np.arange(1, 1001), atol=1e-9)
        # the wake moves: observations differ from action to action
        assert np.ptp(np.array(observations), axis=0).max() > 1e-3
    finally:
        env.close()


def _quickstart_rows(tmp_path: Path, coupling: str, actions: int) -> list[np.ndarray]:
    env = gym.make(
        "gymprecice/Quickstart-v0",
        double=True,
        run_root=str(tmp_path / coupling),
        output_timeout=10,
        case_overrides={"coupling": coupling},
    )
    try:
        env.reset(seed=0)
        bound = float(env.action_space.high.reshape(-1)[0])
        rows = []
        for k in range(actions):
            *_, info = env.step(np.array([(-1) ** k * 0.5 * bound], dtype=np.float32))
            rows.append(np.asarray(info["coefficients"]))
        return rows
    finally:
        env.close()


def test_action_coupling_quickstart_gives_output_every_action(tmp_path: Path) -> None:
    spec = recipes.case_spec("quickstart", coupling="action")
    n, dt = spec.steps_per_action, spec.flow.dt
    action_rows = _quickstart_rows(tmp_path, "action", 4)
    case = tmp_path / "action" / "env_0"
    kind, window, degree = _coupling(case / "precice-config.xml")
    assert (kind, degree) == ("serial-explicit", 1)
    assert window == pytest.approx(spec.action_time)
    for k, rows in enumerate(action_rows):
        assert rows.shape == (n, 3), f"action {k + 1}: {rows.shape}"
        assert np.allclose(rows[:, 0], (k * n + np.arange(1, n + 1)) * dt, atol=1e-9)
    # the same rows (times) as the one-window-per-step coupling
    step_rows = _quickstart_rows(tmp_path, "step", 4)
    for a, s in zip(action_rows, step_rows):
        assert np.allclose(a[:, 0], s[:, 0], atol=1e-9)


def test_double_ramps_the_action_linearly_across_the_window(tmp_path: Path) -> None:
    """The double's serial-explicit scheme with waveform-degree 1, as the fast cases use it.

    The controller writes one value per window; the fluid subcycles 25 steps and reads at
    the end of each: it must see the previous action ramped linearly to the new one.
    """
    spec = recipes.case_spec("jet_cylinder_fast", actions_per_episode=3)
    config = tmp_path / "precice-config.xml"
    text = recipes.precice_config(spec)
    assert 'exchange-directory=".."' in text
    config.write_text(text.replace('exchange-directory=".."', f'exchange-directory="{tmp_path}"'))
    points = np.array([[0.0, 0.0], [1.0, 0.0]])
    actions = [np.array([2.0, -1.0]), np.array([-4.0, 3.0]), np.array([1.0, 1.0])]
    reads: list[tuple[float, np.ndarray]] = []
    errors: list[BaseException] = []

    def fluid() -> None:
        try:
            p = fake_precice.Participant("Fluid", str(config), 0, 1)
            ids = {}
            for name in spec.interfaces:
                mesh = recipes.mesh_name("Fluid", name)
                ids[mesh] = p.set_mesh_vertices(mesh, points)
            p.initialize()
            t = 0.0
            while p.is_coupling_ongoing():
                dt = min(spec.flow.dt, p.get_max_time_step_size())
                mesh = recipes.mesh_name("Fluid", "jet1")
                reads.append((t + dt, p.read_data(mesh, "Velocity", ids[mesh], dt)[:, 0].copy()))
                p.advance(dt)
                t += dt
            p.finalize()
        except BaseException as exc:  # reported by the main thread
            errors.append(exc)

    thread = threading.Thread(target=fluid, daemon=True)
    controller = fake_precice.Participant("Controller", str(config), 0, 1)
    ids = {}
    for name in spec.interfaces:
        mesh = recipes.mesh_name("Controller", name)
        ids[mesh] = controller.set_mesh_vertices(mesh, points)
    thread.start()
    controller.initialize()
    for action in actions:
        for mesh, vertex_ids in ids.items():
            values = np.column_stack([action, np.zeros(2)])
            controller.write_data(mesh, "Velocity", vertex_ids, values)
        controller.advance(controller.get_max_time_step_size())
    assert not controller.is_coupling_ongoing()
    controller.finalize()
    thread.join(30)
    assert not thread.is_alive() and not errors, errors
    assert len(reads) == 3 * 25
    previous = [np.zeros(2), *actions]
    for i, (t, value) in enumerate(reads):
        k, s = divmod(i, 25)
        assert t == pytest.approx(0.025 * k + 1e-3 * (s + 1))
        w = (s + 1) / 25
        assert np.allclose(value, (1 - w) * previous[k] + w * actions[k]), (i, value)


def test_double_case_subcycles_only_where_a_window_holds_several_steps() -> None:
    for coupling in ("action", "step"):
        spec = recipes.case_spec("jet_cylinder_fast", coupling=coupling)
        files = fake_flow.double_case_files(spec)
        config = json.loads(files["gymprecice-config.json"])
        argv = config["physics_simulation_engine"]["solvers"]["fluid"]["options"]["argv"]
        assert float(argv[argv.index("--dt") + 1]) == spec.flow.dt
        assert ("--write-every-step" in argv) == (coupling == "action")


@pytest.mark.slow
def test_train_jet_cylinder_fast_on_the_double(tmp_path: Path) -> None:
    args = ["train", "jet-cylinder-fast", "--double", "--timesteps", "80", "--n-envs", "1"]
    args += ["--normalize", "--out", "train"]
    proc = subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    model = tmp_path / "train" / "model.zip"
    assert model.is_file()
    with zipfile.ZipFile(model) as archive:
        assert "policy.pth" in archive.namelist()
    # 80 steps of one env: two whole 40-action episodes
    [monitor] = (tmp_path / "train" / "monitor").glob("*.csv")
    lines = monitor.read_text().splitlines()
    assert "JetCylinderFast-v0" in lines[0]
    lengths = [int(line.split(",")[1]) for line in lines[2:]]
    assert lengths == [40, 40]
