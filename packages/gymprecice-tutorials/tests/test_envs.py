"""The tutorial environments, run for real against the preCICE test double and the fake flow.

Every env here couples through gymprecice's worker process and the test double to the
scripted partner participant, which writes OpenFOAM-format probe and force-coefficient
files; the envs read them with the OpenFOAM plugin's readers. Only the physics is fake.
"""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import gymprecice  # noqa: F401  (registers the ids)
from gymprecice.env.config import load_config
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice_openfoam.outputs import ForceCoeffsReader, ProbesReader
from gymprecice_tutorials import fake_flow, recipes
from gymprecice_tutorials.cylinder_geometry import patch_geometry
from gymprecice_tutorials.environments import ENVIRONMENTS
from gymprecice_tutorials.jet_cylinder.environment import (
    MAX_FLOW_RATE,
    JetCylinderEnv,
    materialise_case,
)
from gymprecice_tutorials.rotating_cylinder.environment import RotatingCylinderEnv

CYLINDER_IDS = [
    "gymprecice/JetCylinder-v0",
    "gymprecice/RotatingCylinder-v0",
    "gymprecice/Quickstart-v0",
]


@pytest.fixture(autouse=True)
def _light_subprocesses(monkeypatch):
    """Keep plugins out of the coupling worker and the partner: neither uses them, and
    importing every installed plugin costs each of the ~20 process starts of a checker run
    a second. This test process has loaded its plugins already (at import)."""
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")


@pytest.fixture
def closing():
    """``env = closing(make())``: the env is closed at teardown even when the test fails,
    so no solver process outlives a failed test."""
    envs = []

    def keep(env):
        envs.append(env)
        return env

    yield keep
    for env in envs:
        env.close()


class _WithoutTiming(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Drop ``info["timing"]``: wall-clock seconds differ between two identical steps.

    Gymnasium's checker compares the infos of two equally seeded steps for equality;
    everything else in the info (time, window, Cd, Cl, coefficient rows, action) must be
    identical, and is still compared.
    """

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        info.pop("timing", None)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info.pop("timing", None)
        return obs, reward, terminated, truncated, info


def _double(env_id: str, tmp_path: Path, **kwargs) -> gym.Env:
    kwargs.setdefault("episode_time", 0.05)
    return gym.make(env_id, double=True, run_root=str(tmp_path / "runs"), **kwargs)


# -- registration ---------------------------------------------------------------------------


def test_ids_are_registered_with_lazy_entry_points(monkeypatch):
    monkeypatch.delenv("GYMPRECICE_DISABLE_PLUGINS")
    for env_id, entry_point, _card in ENVIRONMENTS:
        spec = gym.spec(env_id)
        assert spec.entry_point == entry_point
        assert isinstance(spec.entry_point, str)
    # importing gymprecice must not import the env modules, torch or matplotlib
    code = (
        "import sys, gymnasium, gymprecice\n"
        "print(sorted(i for i in gymnasium.registry if i.startswith('gymprecice/')))\n"
        "heavy = [m for m in ('gymprecice_tutorials.jet_cylinder.environment', 'torch',"
        " 'matplotlib', 'stable_baselines3') if m in sys.modules]\n"
        "print(heavy)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    assert eval(out[0]) == sorted(env_id for env_id, _, _ in ENVIRONMENTS)
    assert eval(out[1]) == []


def test_the_ids_declared_in_the_metadata_are_the_plugin_s_table():
    """pyproject.toml declares each id with its class (``gymprecice.environments``), so
    that ``gymnasium.make`` knows it before the plugin module has loaded; the plugin's
    table registers the same ids with their cards. The two may not drift apart."""
    import tomllib

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    declared = tomllib.loads(pyproject.read_text())["project"]["entry-points"][
        "gymprecice.environments"
    ]
    assert declared == {env_id: entry_point for env_id, entry_point, _card in ENVIRONMENTS}


# -- the Gymnasium and SB3 checkers ---------------------------------------------------------


@pytest.mark.parametrize("env_id", CYLINDER_IDS)
def test_env_passes_gymnasium_and_sb3_checkers(env_id, tmp_path):
    env = _double(env_id, tmp_path).unwrapped
    try:
        with warnings.catch_warnings():
            # both checkers advise [-1, 1] action boxes and finite observation bounds;
            # the physical units are deliberate (training rescales actions)
            warnings.simplefilter("ignore")
            check_env(_WithoutTiming(env), skip_render_check=True)
            sb3_check_env(env, warn=False)
    finally:
        env.close()


# -- actuation -------------------------------------------------------------------------------


def _flux(velocity: np.ndarray, geometry) -> float:
    """Flow rate out of the cylinder through the faces (radial velocity x area)."""
    spec = recipes.case_spec("jet_cylinder")
    rel = geometry.coordinates - np.array(spec.geometry.centre)
    radial = rel / np.linalg.norm(rel, axis=1, keepdims=True)
    return float(np.sum(np.sum(velocity * radial, axis=1) * geometry.areas))


def test_jets_carry_the_flow_rate_with_zero_net_mass_flux(tmp_path):
    env = JetCylinderEnv(double=True, run_root=tmp_path / "runs")
    assert env.action_space.shape == (1,)
    assert env.action_space.high[0] == pytest.approx(MAX_FLOW_RATE)
    assert env.action_space.low[0] == pytest.approx(-MAX_FLOW_RATE)
    assert env.observation_space.shape == (151,)
    q = 1.7e-4
    velocities = env._get_action(np.array([q]), env.write_var_list)
    jet1 = _flux(velocities["jet1"], env.geometry_of("jet1"))
    jet2 = _flux(velocities["jet2"], env.geometry_of("jet2"))
    assert jet1 == pytest.approx(q, rel=1e-9)
    assert jet2 == pytest.approx(-q, rel=1e-9)
    # out-of-bounds actions are clipped to the bound before they reach the solver
    too_much = env._get_action(np.array([1.0]), env.write_var_list)["jet1"]
    assert _flux(too_much, env.geometry_of("jet1")) == pytest.approx(MAX_FLOW_RATE, rel=1e-6)
    assert velocities["jet1"].shape == (
        recipes.case_spec("jet_cylinder").resolution.cells_per_jet,
        2,
    )
    env.close()


def test_constants_are_constructor_arguments(tmp_path):
    env = JetCylinderEnv(
        double=True,
        run_root=tmp_path / "runs",
        max_flow_rate=1e-4,
        jet_width=20.0,
        reward_offset=4.0,
        lift_penalty=0.5,
        averaging_window=0.1,
    )
    assert env.action_space.high[0] == pytest.approx(1e-4)
    assert env.case_spec.geometry.jet_width == 20.0
    assert (env.reward_offset, env.lift_penalty, env.averaging_window) == (4.0, 0.5, 0.1)
    # the jet width reaches the case: the analytic jet spans 20 degrees
    angles = np.degrees(np.arctan2(*(env.geometry_of("jet1").coordinates - [0.2, 0.2]).T[::-1]))
    assert angles.max() - angles.min() > 10.0
    env.close()
    with pytest.raises(ValueError, match="max_flow_rate"):
        JetCylinderEnv(double=True, run_root=tmp_path / "runs", max_flow_rate=0.0)
    with pytest.raises(ValueError, match="packaged case recipe"):
        JetCylinderEnv(options=str(env.config.case_dir), double=True)


def test_lift_measure_abs_penalises_the_mean_lift_magnitude(tmp_path):
    env = JetCylinderEnv(double=True, run_root=tmp_path / "runs", lift_measure="abs")
    # a lift swinging about zero: |<Cl>| = 0, <|Cl|> = 2
    env._history = np.array([[0.1, 3.0, 2.0], [0.2, 3.0, -2.0]])
    assert env._get_reward() == pytest.approx(env.reward_offset - 3.0 - env.lift_penalty * 2.0)
    env.lift_measure = "mean"
    assert env._get_reward() == pytest.approx(env.reward_offset - 3.0)
    env.close()
    with pytest.raises(ValueError, match="lift_measure"):
        JetCylinderEnv(double=True, run_root=tmp_path / "runs", lift_measure="rms")


def test_rotating_wall_moves_tangentially_at_omega_r(tmp_path):
    env = RotatingCylinderEnv(double=True, run_root=tmp_path / "runs")
    assert env.action_space.high[0] == pytest.approx(5.0)
    velocity = env._get_action(np.array([3.0]), env.write_var_list)["cylinder"]
    geometry = env.geometry_of("cylinder")
    rel = geometry.coordinates - np.array([0.2, 0.2])
    radial = rel / np.linalg.norm(rel, axis=1, keepdims=True)
    assert np.allclose(np.sum(velocity * radial, axis=1), 0.0, atol=1e-12)
    speed = np.linalg.norm(velocity, axis=1)
    assert np.allclose(speed, 3.0 * np.linalg.norm(rel, axis=1), rtol=1e-9)
    # counter-clockwise for positive omega: (r x u)_z > 0
    assert np.all(rel[:, 0] * velocity[:, 1] - rel[:, 1] * velocity[:, 0] > 0)
    env.close()


# -- a whole episode ---------------------------------------------------------------------------


def test_episode_reward_and_observation_come_from_the_solver_files(tmp_path, closing):
    env = closing(
        JetCylinderEnv(
            double=True,
            run_root=tmp_path / "runs",
            episode_time=0.1,
            reward_offset=10.0,
            lift_penalty=0.5,
            averaging_window=0.06,
        )
    )
    obs, info = env.reset(seed=3)
    assert obs.shape == (151,) and obs.dtype == np.float32
    steps, truncated = 0, False
    while not truncated:
        obs, reward, terminated, truncated, info = env.step(np.array([MAX_FLOW_RATE], np.float32))
        steps += 1
        assert terminated is False
    assert steps == 4 and info["time"] == pytest.approx(0.1)
    assert set(info) >= {"Cd", "Cl", "coefficients", "action", "timing", "time"}
    assert info["action"] == [pytest.approx(MAX_FLOW_RATE)]
    run = env.solver_dirs["fluid"]
    env.close()
    coeffs = ForceCoeffsReader(run / "postProcessing" / "forceCoeffs").read_all()
    recent = coeffs.time > 0.1 - 0.06 + 1e-9
    cd, cl = coeffs.column("Cd")[recent].mean(), coeffs.column("Cl")[recent].mean()
    assert reward == pytest.approx(10.0 - cd - 0.5 * abs(cl), rel=1e-9)
    assert (info["Cd"], info["Cl"]) == (pytest.approx(cd), pytest.approx(cl))
    # the step's coefficient rows are the last 50 solver steps
    assert info["coefficients"].shape == (50, 3)
    assert info["coefficients"][-1, 0] == pytest.approx(0.1)
    probes = ProbesReader(run / "postProcessing" / "probes", "p").read_all()
    assert probes.time[-1] == pytest.approx(0.1)
    assert np.allclose(obs, probes.values[-1].astype(np.float32))


def test_the_fake_flow_responds_to_the_jets(tmp_path, closing):
    def mean_drag(q: float, root: Path) -> float:
        env = closing(JetCylinderEnv(double=True, run_root=root, episode_time=0.075))
        env.reset(seed=0)
        drags, truncated = [], False
        while not truncated:
            _, _, _, truncated, info = env.step(np.array([q], np.float32))
            drags.append(info["Cd"])
        env.close()
        return float(np.mean(drags))

    closed = mean_drag(0.0, tmp_path / "a")
    blowing = mean_drag(MAX_FLOW_RATE, tmp_path / "b")
    assert blowing != pytest.approx(closed, abs=1e-3)


# -- the case ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cls", "recipe", "interfaces"),
    [
        (JetCylinderEnv, "jet_cylinder", {"jet1", "jet2"}),
        (RotatingCylinderEnv, "rotating_cylinder", {"cylinder"}),
    ],
)
def test_default_case_is_the_openfoam_recipe(tmp_path, cls, recipe, interfaces):
    """Without arguments an env runs the packaged recipe on OpenFOAM (nothing starts yet)."""
    env = cls(run_root=tmp_path)
    config = env.config
    assert config.case_dir.parent == tmp_path / "cases"
    assert config.solvers["fluid"].kind == "openfoam"
    assert config.model.precice.library == "precice"
    assert config.model.actions.windows == 50 and config.model.actions.scheme == "ramp"
    assert env.dt == pytest.approx(5e-4) and env.end_time == pytest.approx(2.0)
    assert set(config.interfaces) == interfaces
    spec = recipes.case_spec(recipe)
    assert (config.case_dir / "precice-config.xml").read_text() == recipes.precice_config(spec)
    assert not (tmp_path / "env_0").exists()
    env.close()
    longer = cls(run_root=tmp_path, episode_time=10.0)
    assert longer.end_time == pytest.approx(10.0)
    assert longer.config.case_dir != config.case_dir
    longer.close()


def test_materialised_cases_are_shared_and_race_free(tmp_path):
    spec = recipes.case_spec("jet_cylinder")
    with ThreadPoolExecutor(4) as pool:
        dirs = set(pool.map(lambda _: materialise_case(spec, tmp_path), range(8)))
    assert len(dirs) == 1
    (case,) = dirs
    assert (case / "gymprecice-config.json").is_file()
    assert (case / "fluid-openfoam" / "system" / "blockMeshDict").is_file()
    assert [p.name for p in (tmp_path / "cases").iterdir()] == [case.name]
    wide = recipes.case_spec("jet_cylinder", geometry=recipes.Geometry(jet_width=20.0))
    other = materialise_case(wide, tmp_path)
    assert other != case
    double = materialise_case(spec, tmp_path, double=True)
    assert double not in (case, other) and "double" in double.name


def test_double_case_is_the_recipe_coupling_with_the_partner(tmp_path):
    spec = recipes.case_spec("rotating_cylinder")
    case = materialise_case(spec, tmp_path, double=True, step_sleep=0.01)
    assert (case / "precice-config.xml").read_text() == recipes.precice_config(spec)
    config = load_config(case)
    solver = config.solvers["fluid"]
    assert solver.kind == "command"
    argv = solver.options["argv"]
    assert "gymprecice_tutorials.fake_flow:CylinderWake" in argv
    assert argv[argv.index("--step-sleep") + 1] == "0.01"
    assert config.model.precice.library == "gymprecice.testing.fake_precice"
    assert config.model.actions.windows == 50 and config.model.actions.scheme == "ramp"
    assert fake_flow.spec_from_json((case / "fluid-fake" / "fake-flow.json").read_text()) == spec


# -- the fake flow -----------------------------------------------------------------------------


def _wake(tmp_path: Path, name: str = "jet_cylinder") -> fake_flow.CylinderWake:
    spec = recipes.case_spec(name)
    case = materialise_case(spec, tmp_path, double=True)
    cfg = load_precice_config(case / "precice-config.xml")
    flow = fake_flow.CylinderWake(
        cfg, "Fluid", {"case": str(case / "fluid-fake" / "fake-flow.json")}
    )
    for mesh in cfg.participant("Fluid").provided_meshes:
        flow.mesh_coordinates(mesh)
    return flow


def _run_wake(
    flow: fake_flow.CylinderWake, gain: float, seconds: float = 4.0
) -> tuple[float, float]:
    """Mean Cd and Cl over the last shedding period, under feedback q = -gain * Cl."""
    spec = recipes.case_spec("jet_cylinder")
    jets = {m: patch_geometry(spec, p) for m, (p, _) in flow.geometry.items()}
    rows, dt = [], 5e-4
    for _ in range(round(seconds / 0.025)):
        q = float(np.clip(-gain * flow.lift, -1, 1)) * fake_flow.FLOW_RATE_SCALE
        inputs = {}
        for mesh, geometry in jets.items():
            rel = geometry.coordinates - np.array(spec.geometry.centre)
            radial = rel / np.linalg.norm(rel, axis=1, keepdims=True)
            rate = q if "jet1" in mesh else -q
            inputs[("Velocity", mesh)] = rate / geometry.areas.sum() * radial
        for _ in range(50):
            flow.step(0.0, dt, inputs)
            rows.append((flow.drag, flow.lift))
    last = np.array(rows[-670:])
    return float(last[:, 0].mean()), float(last[:, 1].mean())


def test_fake_wake_sheds_without_control_and_feedback_lowers_the_drag(tmp_path):
    cd0, cl0 = _run_wake(_wake(tmp_path), gain=0.0)
    assert cd0 == pytest.approx(3.205, abs=0.01)  # the reward offset's uncontrolled drag
    assert abs(cl0) < 0.05
    cd_fb, _ = _run_wake(_wake(tmp_path), gain=2.0)
    cd_bad, _ = _run_wake(_wake(tmp_path), gain=-1.0)
    assert cd_fb < cd0 - 0.1
    assert cd_bad > cd0


def test_fake_wake_writes_openfoam_files_the_readers_parse(tmp_path):
    flow = _wake(tmp_path)
    out = tmp_path / "out"
    for k in range(1, 4):
        flow.step(0.0, 5e-4, {})
        flow.write_outputs(out, k * 5e-4)
    probes = ProbesReader(out / "postProcessing" / "probes", "p").read_new()
    assert probes.values.shape == (3, 151)
    expected = np.array(recipes.probe_locations(recipes.case_spec("jet_cylinder").geometry))
    assert np.allclose(probes.locations, expected)
    coeffs = ForceCoeffsReader(out / "postProcessing" / "forceCoeffs").read_new()
    assert np.allclose(coeffs.time, [5e-4, 1e-3, 1.5e-3])
    assert coeffs.column("Cd")[-1] == pytest.approx(flow.drag)
    assert coeffs.column("Cl")[-1] == pytest.approx(flow.lift)
    assert math.isfinite(float(probes.values.sum()))


# -- real preCICE ------------------------------------------------------------------------------


def _precice_import_error() -> str | None:
    """Why ``import precice`` fails in a fresh interpreter (``None`` when it works)."""
    proc = subprocess.run([sys.executable, "-c", "import precice"], capture_output=True, text=True)
    return None if proc.returncode == 0 else (proc.stderr.strip().splitlines() or ["?"])[-1]


@pytest.mark.precice
def test_an_episode_on_real_precice_matches_the_double(tmp_path, closing):
    """Cost: about 2 s (one short episode with real preCICE, one with the double, the scripted
    flow).
    """
    error = _precice_import_error()
    if error is not None:
        pytest.skip(f"cannot import precice: {error}")

    def episode(library: str) -> tuple[list[float], np.ndarray]:
        env = closing(
            JetCylinderEnv(
                double=True,
                double_options={"library": library},
                run_root=tmp_path / library,
                episode_time=0.1,
            )
        )
        env.reset(seed=0)
        rewards, truncated = [], False
        actions = iter([1.0, -0.5, 0.25, 0.0])
        while not truncated:
            obs, reward, _, truncated, _ = env.step(np.array([next(actions) * MAX_FLOW_RATE]))
            rewards.append(reward)
        env.close()
        return rewards, obs

    real_rewards, real_obs = episode("precice")
    fake_rewards, fake_obs = episode("gymprecice.testing.fake_precice")
    assert real_rewards == pytest.approx(fake_rewards, rel=1e-9)
    assert np.allclose(real_obs, fake_obs)


# -- the real mesh -----------------------------------------------------------------------------


def _openfoam():
    from gymprecice.plugin.errors import CaseError
    from gymprecice_openfoam.installation import find_openfoam

    try:
        return find_openfoam()
    except CaseError as exc:
        pytest.skip(f"OpenFOAM not available: {exc}")


def _by_angle(geometry, centre) -> np.ndarray:
    rel = geometry.coordinates[:, :2] - np.asarray(centre)
    return np.argsort(np.mod(np.arctan2(rel[:, 1], rel[:, 0]), 2 * np.pi))


@pytest.mark.openfoam
@pytest.mark.parametrize(
    ("recipe", "patches"), [("quickstart", ("jet1", "jet2")), ("rotating_cylinder", ("cylinder",))]
)
def test_recipe_mesh_patches_match_the_analytic_geometry(tmp_path, recipe, patches):
    """blockMesh's patches are the faces the double's flow and the env's actuators assume,
    and the jet actuator carries exactly Q through the real mesh's faces.

    Cost: under a second per recipe (one blockMesh).
    """
    from gymprecice_openfoam import mesh
    from gymprecice_openfoam.actuators import jet_velocity
    from gymprecice_openfoam.installation import run_tool

    installation = _openfoam()
    spec = recipes.case_spec(recipe)
    fluid = recipes.write_fluid_case(spec, tmp_path / "fluid", coupled=True)
    run_tool(["blockMesh"], fluid, "log.blockMesh", installation, timeout=300)
    centre = spec.geometry.centre
    for patch in patches:
        real = mesh.interface_geometry(fluid, f"Fluid-Mesh-{patch}", dimensions=2)
        analytic = patch_geometry(spec, patch)
        i, j = _by_angle(real, centre), _by_angle(analytic, centre)
        assert len(i) == len(j)
        assert np.allclose(real.coordinates[i], analytic.coordinates[j], atol=1e-9)
        assert np.allclose(real.normals[i], analytic.normals[j], atol=1e-9)
        assert np.allclose(real.areas[i], analytic.areas[j], rtol=1e-6)
        if patch.startswith("jet"):
            angle = math.radians(90.0 if patch == "jet1" else 270.0)
            velocity = jet_velocity(
                real,
                2e-4,
                centre=(*centre, 0.0),
                width=math.radians(spec.geometry.jet_width),
                jet_angle=angle,
                direction="radial",
            )
            assert _flux(velocity, real) == pytest.approx(2e-4, rel=1e-9)
