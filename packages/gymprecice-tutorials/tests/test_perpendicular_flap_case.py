"""The perpendicular-flap FSI case: its files agree with each other, OpenFOAM meshes it,
and its environment turns actions and watch-point rows into data, observations, rewards.

Nothing here needs preCICE or the deal.II-preCICE adapter; the OpenFOAM tests need
``blockMesh`` (v1912 or newer) and skip without it.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from foamlib import FoamFile

from gymprecice.env.config import load_config
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.plugin.solver import SolverContext
from gymprecice.plugin.watchpoints import WatchPointLog
from gymprecice_dealii.plugin import check_against_precice
from gymprecice_dealii.prm import ElasticityParameters
from gymprecice_tutorials.perpendicular_flap import CASE_DIR
from gymprecice_tutorials.perpendicular_flap.environment import (
    INLET_HEIGHT,
    PerpendicularFlapEnv,
    jet_profile,
    sinusoidal_jet_centre,
)

XML = CASE_DIR / "precice-config.xml"
FLUID = CASE_DIR / "fluid-openfoam"
SOLID = CASE_DIR / "solid-dealii"


# -- the preCICE configuration ---------------------------------------------------------------


def test_precice_config_parses_with_three_participants() -> None:
    cfg = load_precice_config(XML)
    assert set(cfg.participants) == {"Fluid", "Solid", "Controller"}
    assert {m.name: m.dimensions for m in cfg.meshes.values()} == {
        "Fluid-Mesh-flap": 2,
        "Fluid-Mesh-inlet": 2,
        "Solid-Mesh": 2,
        "Controller-Mesh-inlet": 2,
    }


def test_fluid_and_solid_are_coupled_implicitly_by_a_multi_scheme() -> None:
    cfg = load_precice_config(XML)
    multi = [s for s in cfg.coupling_schemes if s.kind == "multi"]
    assert len(multi) == 1
    scheme = multi[0]
    assert scheme.implicit
    assert sorted(scheme.participants) == ["Fluid", "Solid"]
    assert scheme.control == "Fluid"
    assert scheme.max_iterations == 50
    assert {(e.data, e.mesh, e.from_participant, e.to_participant) for e in scheme.exchanges} == {
        ("Force", "Solid-Mesh", "Fluid", "Solid"),
        ("Displacement", "Solid-Mesh", "Solid", "Fluid"),
    }


def test_controller_drives_the_inlet_explicitly() -> None:
    cfg = load_precice_config(XML)
    (scheme,) = cfg.schemes_of("Controller")
    assert scheme.kind == "parallel-explicit" and not scheme.implicit
    assert (scheme.first, scheme.second) == ("Controller", "Fluid")
    (exchange,) = scheme.exchanges
    assert (exchange.data, exchange.mesh) == ("Velocity", "Controller-Mesh-inlet")
    assert (exchange.from_participant, exchange.to_participant) == ("Controller", "Fluid")
    assert exchange.initialize  # the first action acts from t = 0
    fluid = cfg.participant("Fluid")
    assert ("Velocity", "Fluid-Mesh-inlet") in fluid.read_data
    assert cfg.mapped_partner_mesh("Controller-Mesh-inlet") == ("Fluid", "Fluid-Mesh-inlet")


def test_all_participants_share_time_window_and_end_time() -> None:
    cfg = load_precice_config(XML)
    for participant in ("Fluid", "Solid", "Controller"):
        assert cfg.time_window_size(participant) == pytest.approx(0.01)
        assert cfg.end_time(participant) == pytest.approx(5.0)
    windows = {s.time_window_size for s in cfg.coupling_schemes}
    assert windows == {0.01}  # preCICE needs explicit windows aligned with implicit ones


def test_solid_watches_the_flap_tip() -> None:
    (point,) = load_precice_config(XML).participant("Solid").watch_points
    assert (point.name, point.mesh, point.coordinate) == ("Flap-Tip", "Solid-Mesh", (0.0, 1.0))


# -- gymprecice-config.json against the XML and the solver directories ---------------------


def test_gymprecice_config_is_explicit_and_cross_checks() -> None:
    config = load_config(CASE_DIR / "gymprecice-config.json")
    assert {n: (s.kind, s.path, s.participant) for n, s in config.solvers.items()} == {
        "fluid": ("openfoam", "fluid-openfoam", "Fluid"),
        "solid": ("dealii", "solid-dealii", "Solid"),
    }
    inlet = config.interfaces["inlet"]
    assert (inlet.mesh, inlet.write, inlet.read) == ("Controller-Mesh-inlet", ("Velocity",), ())
    assert (inlet.partner, inlet.partner_mesh) == ("Fluid", "Fluid-Mesh-inlet")
    assert config.time_window_size == pytest.approx(0.01)


def copy_case(tmp_path: Path) -> Path:
    case = tmp_path / "perpendicular_flap"
    shutil.copytree(
        CASE_DIR, case, ignore=shutil.ignore_patterns("__pycache__", "*.py", "gymprecice-runs")
    )
    return case


def test_a_solid_mesh_missing_from_the_xml_fails_load_config_naming_both_files(
    tmp_path: Path,
) -> None:
    case = copy_case(tmp_path)
    xml = case / "precice-config.xml"
    xml.write_text(xml.read_text().replace("Solid-Mesh", "Flap-Mesh"))
    with pytest.raises(ConfigError) as caught:
        load_config(case / "gymprecice-config.json")
    message = str(caught.value)
    assert "Solid-Mesh" in message
    assert "gymprecice-config.json" in message and "precice-config.xml" in message


def test_a_solid_mesh_missing_from_the_xml_is_reported_at_preparation(tmp_path: Path) -> None:
    case = copy_case(tmp_path)
    xml = case / "precice-config.xml"
    xml.write_text(xml.read_text().replace("Solid-Mesh", "Flap-Mesh"))
    params = ElasticityParameters.read(case / "solid-dealii/parameters.prm")
    solver = SolverContext(
        name="solid",
        kind="dealii",
        run_dir=case / "solid-dealii",
        source_dir=case / "solid-dealii",
        env_dir=case,
        participant="Solid",
        precice=load_precice_config(xml),
    )
    with pytest.raises(Exception, match=r"parameters\.prm.*'Solid-Mesh'.*precice-config\.xml"):
        check_against_precice(solver, params)


def test_solid_parameters_agree_with_the_xml() -> None:
    params = ElasticityParameters.read(SOLID / "parameters.prm")
    cfg = load_precice_config(XML)
    assert (SOLID / params.precice_config_file).resolve() == XML.resolve()
    assert params.time_step == cfg.time_window_size("Solid")
    assert params.end_time >= cfg.end_time("Solid")
    solver = SolverContext(
        name="solid",
        kind="dealii",
        run_dir=SOLID,
        source_dir=SOLID,
        env_dir=CASE_DIR,
        participant="Solid",
        precice=cfg,
    )
    check_against_precice(solver, params)  # raises on any disagreement


def test_precice_dict_matches_the_xml_and_the_mesh_patches() -> None:
    precice_dict = FoamFile(FLUID / "system/preciceDict")
    assert (FLUID / str(precice_dict["preciceConfig"]).strip('"')).resolve() == XML.resolve()
    assert precice_dict["participant"] == "Fluid"
    cfg = load_precice_config(XML)
    fluid = cfg.participant("Fluid")
    interfaces = precice_dict["interfaces"]
    declared = {}
    for name in interfaces:
        entry = interfaces[name]
        mesh = entry["mesh"]
        assert mesh in fluid.provided_meshes
        assert {(d, mesh) for d in entry["readData"]} <= set(fluid.read_data)
        assert {(d, mesh) for d in entry["writeData"]} <= set(fluid.write_data)
        declared[mesh] = list(entry["patches"])
    assert declared == {"Fluid-Mesh-flap": ["flap"], "Fluid-Mesh-inlet": ["inlet"]}
    block_mesh = (FLUID / "system/blockMeshDict").read_text()
    for patch in ("inlet", "outlet", "flap", "upperWall", "lowerWall", "frontAndBack"):
        assert re.search(rf"^\s+{patch}\s*$", block_mesh, re.MULTILINE), patch


def test_fluid_case_ships_no_mesh_and_controldict_matches_the_xml() -> None:
    assert not (FLUID / "constant/polyMesh").exists()
    control = FoamFile(FLUID / "system/controlDict")
    cfg = load_precice_config(XML)
    assert control["deltaT"] == pytest.approx(cfg.time_window_size("Fluid"))
    assert control["endTime"] >= cfg.end_time("Fluid")
    assert control["application"] == "pimpleFoam"


# -- OpenFOAM --------------------------------------------------------------------------------


def openfoam_env() -> dict[str, str]:
    """Environment for OpenFOAM programs; Debian's package only needs WM_PROJECT_DIR."""
    program = shutil.which("blockMesh")
    if program is None:
        pytest.skip("OpenFOAM's blockMesh is not on PATH")
    env = dict(os.environ)
    if "WM_PROJECT_DIR" not in env:
        debian = Path(program).resolve().parent.parent / "share" / "openfoam"
        if (debian / "etc" / "controlDict").is_file():
            env["WM_PROJECT_DIR"] = str(debian)
    return env


def run_foam(argv: list[str], case: Path, env: dict[str, str]) -> str:
    done = subprocess.run(argv, cwd=case, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"{argv[0]} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


@pytest.fixture
def meshed_fluid(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    env = openfoam_env()
    case = tmp_path / "fluid-openfoam"
    shutil.copytree(FLUID, case)
    run_foam(["blockMesh"], case, env)
    return case, env


@pytest.mark.openfoam
def test_blockmesh_builds_the_channel_with_the_flap(meshed_fluid) -> None:
    """Cost: under a second (the flap channel's blockMesh, shared by the module)."""
    case, env = meshed_fluid
    boundary = FoamFile(case / "constant/polyMesh/boundary")[None]
    patches = {name: dict(entry) for name, entry in boundary}
    assert set(patches) == {"inlet", "outlet", "flap", "upperWall", "lowerWall", "frontAndBack"}
    assert patches["inlet"]["nFaces"] == 60  # 15 below the tip height, 45 above
    assert patches["flap"]["nFaces"] == 15 + 4 + 15  # both sides and the tip
    assert patches["flap"]["type"] == "wall"
    assert patches["frontAndBack"]["type"] == "empty"
    report = run_foam(["checkMesh"], case, env)
    assert "Mesh OK." in report
    box = re.search(r"Overall domain bounding box \(([^)]*)\) \(([^)]*)\)", report)
    assert box is not None
    low, high = (np.array(part.split(), dtype=float) for part in box.groups())
    np.testing.assert_allclose(low, [-3, 0, 0])
    np.testing.assert_allclose(high, [3, 4, 1])
    cells = int(re.search(r"cells:\s+(\d+)", report).group(1))
    assert cells == (30 + 4 + 30) * 45 + (30 + 30) * 15  # the flap is no fluid


@pytest.mark.openfoam
@pytest.mark.slow
def test_fluid_runs_uncoupled_on_its_moving_mesh(meshed_fluid) -> None:
    """The dictionaries are complete for pimpleFoam with a dynamic mesh (adapter removed).

    Cost: under a second (a few pimpleFoam steps on the shared mesh).
    """
    case, env = meshed_fluid
    control = case / "system/controlDict"
    text = control.read_text()
    text = text[: text.index("functions")] + "functions {}\n"
    control.write_text(text.replace("endTime         5;", "endTime         0.03;"))
    velocity = case / "0/U"
    velocity.write_text(
        velocity.read_text().replace(
            "value           uniform (0 0 0);", "value uniform (1 0 0);", 1
        )
    )
    log = run_foam(["pimpleFoam"], case, env)
    assert "cellDisplacement" in log  # the mesh-motion solver ran
    assert (case / "0.03").is_dir() or "End" in log


# -- the environment -------------------------------------------------------------------------


def test_jet_profile_carries_the_reference_flow_rate_anywhere() -> None:
    y = (np.arange(60) + 0.5) * INLET_HEIGHT / 60
    areas = np.full(60, INLET_HEIGHT / 60)
    for centre in (1.0, 1.7, 2.0, 3.0):
        u = jet_profile(y, centre, 2.0, mean_velocity=20 / 3, areas=areas)
        assert u @ areas == pytest.approx(20 / 3 * INLET_HEIGHT)
        inside = np.abs(y - centre) < 1.0
        assert np.all(u[~inside] == 0) and np.all(u[inside] > 0)
        assert y[np.argmax(u)] == pytest.approx(centre, abs=INLET_HEIGHT / 60)
    # centred jet of half the inlet: peak twice the reference peak (up to discretisation)
    assert jet_profile(y, 2.0, 2.0, 20 / 3, areas).max() == pytest.approx(20.0, rel=0.01)


def test_jet_profile_uses_the_face_areas() -> None:
    y = np.array([0.5, 1.5, 2.5, 3.5])
    u = jet_profile(y, 2.0, 4.0, 1.0, areas=np.array([1.0, 1.0, 1.0, 3.0]))
    assert u @ np.array([1.0, 1.0, 1.0, 3.0]) == pytest.approx(6.0)
    with pytest.raises(ValueError, match="covers none"):
        jet_profile(y, 10.0, 1.0, 1.0)


def test_sinusoidal_controller_sweeps_the_action_range() -> None:
    values = [sinusoidal_jet_centre(t, 1.0, 3.0, frequency=0.5) for t in np.arange(0, 4, 0.01)]
    assert min(values) == pytest.approx(1.0, abs=1e-3)
    assert max(values) == pytest.approx(3.0, abs=1e-3)
    assert sinusoidal_jet_centre(0.0, 1.0, 3.0) == 2.0
    assert sinusoidal_jet_centre(0.5, 1.0, 3.0, frequency=0.5) == pytest.approx(3.0)


@pytest.fixture
def env(tmp_path: Path):
    environment = PerpendicularFlapEnv(run_root=tmp_path / "runs")
    yield environment
    environment.close()


def test_env_spaces_and_inlet_data(env: PerpendicularFlapEnv) -> None:
    assert env.action_space.shape == (1,)
    assert (env.action_space.low[0], env.action_space.high[0]) == (1.0, 3.0)
    assert env.observation_space.shape == (4,)
    y = (np.arange(40) + 0.5) * 0.1
    env.set_interface_vertices("inlet", np.column_stack([np.full(40, -3.0), y]))
    (ref,) = env.write_var_list
    data = env._get_action(np.array([5.0], np.float32), env.write_var_list)  # clipped to 3
    velocity = data[ref]
    assert velocity.shape == (40, 2)
    assert np.all(velocity[:, 1] == 0)
    assert np.all(velocity[y < 2.0, 0] == 0) and np.all(velocity[y > 2.0, 0] > 0)
    assert velocity[:, 0].sum() * 0.1 == pytest.approx(2 / 3 * 10 * 4)
    assert env._initial_action()[0] == 2.0


def test_env_observation_and_reward_come_from_the_watch_point(
    env: PerpendicularFlapEnv, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    log = tmp_path / "precice-Solid-watchpoint-Flap-Tip.log"
    columns = ["Time", "Coordinate0", "Coordinate1", "Displacement0", "Displacement1"]
    columns += ["Force0", "Force1"]

    def rows(times, dx):
        return "".join(
            "\n" + "  ".join(f"{v:15.8e}" for v in (t, d, 1.0, d, 0.0, 1.0, -2.0))
            for t, d in zip(times, dx)
        )

    log.write_text("".join(f"  {c}" for c in columns) + rows([0.0], [0.0]))
    opened = []
    monkeypatch.setattr(
        env,
        "open_output",
        lambda solver, name, **o: opened.append((solver, name, o)) or WatchPointLog(log),
    )
    env.time = 0.0
    first = env._get_observation({}, [])
    assert opened == [("solid", "watchpoint", {"point": "Flap-Tip"})]
    np.testing.assert_allclose(first, [0, 0, 1, -2])
    with log.open("a") as handle:
        handle.write(rows([0.01, 0.02, 0.03], [0.1, -0.2, 0.3]))
    env.time = 0.03
    observation = env._get_observation({}, [])
    assert observation.dtype == np.float32
    np.testing.assert_allclose(observation, [0.3, 0.0, 1.0, -2.0], rtol=1e-6)
    assert env._get_reward() == pytest.approx(-0.2)  # mean |d| of the step's three windows
    env._close_external_resources()  # a reset: the next episode opens a new reader
    env._get_observation({}, [])
    assert len(opened) == 2


def test_env_calls_open_output_in_a_form_core_accepts(env: PerpendicularFlapEnv) -> None:
    """The watch point's keyword must not collide with open_output's own parameters."""
    import inspect

    from gymprecice.env.core import Adapter

    inspect.signature(Adapter.open_output).bind(
        env, PerpendicularFlapEnv.SOLID, "watchpoint", point=PerpendicularFlapEnv.WATCH_POINT
    )
