"""The OpenFOAM tutorial case recipes: files, preCICE wiring, and real OpenFOAM runs."""

from __future__ import annotations

import ctypes.util
import json
import math
import re
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice_tutorials import recipes
from gymprecice_tutorials.validate import (
    check_smoke,
    deviation,
    openfoam_environment,
    read_force_coeffs,
    shedding_stats,
    validation_spec,
)

CASE_NAMES = sorted(recipes.CASES)
needs_openfoam = pytest.mark.skipif(
    not all(shutil.which(p) for p in ("blockMesh", "checkMesh", "pimpleFoam")),
    reason="OpenFOAM (blockMesh, checkMesh, pimpleFoam) is not on PATH",
)


# --------------------------------------------------------------------------------------
# The packaged cases are the recipes' output
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", CASE_NAMES)
def test_packaged_case_is_the_recipe_output(name: str) -> None:
    case_dir = recipes.CASES_DIR / name
    expected = recipes.case_files(recipes.CASES[name])
    on_disk = {p.relative_to(case_dir).as_posix(): p for p in case_dir.rglob("*") if p.is_file()}
    assert sorted(on_disk) == sorted(expected), (
        "packaged files differ from the recipe: run `python -m gymprecice_tutorials.recipes "
        "regenerate`"
    )
    for rel, text in expected.items():
        assert on_disk[rel].read_text() == text, f"{name}/{rel} differs from its recipe"


def test_no_mesh_or_snapshot_is_packaged() -> None:
    for path in recipes.CASES_DIR.rglob("*"):
        parts = set(path.parts)
        assert "polyMesh" not in parts
        assert not any(p.startswith("processor") for p in parts)
        assert not re.fullmatch(r"\d*\.\d+|[1-9]\d*", path.name), path


def test_write_case_refuses_to_clobber(tmp_path: Path) -> None:
    target = recipes.write_case("quickstart", tmp_path / "qs")
    assert (target / "fluid-openfoam" / "system" / "blockMeshDict").is_file()
    with pytest.raises(FileExistsError):
        recipes.write_case("quickstart", target)
    recipes.write_case("quickstart", target, overwrite=True)


def test_make_uncoupled_drops_only_the_adapter(tmp_path: Path) -> None:
    fluid = recipes.write_fluid_case(recipes.CASES["jet_cylinder"], tmp_path, coupled=True)
    control = (fluid / "system" / "controlDict").read_text()
    assert '#include "preciceAdapterFunctionObject"' in control
    fo = fluid / recipes.PRECICE_FO_FILE
    assert "preciceAdapterFunctionObject" in fo.read_text()
    assert 'libs            ("libpreciceAdapterFunctionObject.so")' in fo.read_text()
    recipes.make_uncoupled(fluid)
    assert "type" not in fo.read_text()
    assert (fluid / "system" / "controlDict").read_text() == control
    recipes.make_coupled(fluid)
    assert "preciceAdapterFunctionObject;" in fo.read_text()


# --------------------------------------------------------------------------------------
# Geometry, probes and mesh parameters
# --------------------------------------------------------------------------------------


def test_probes_follow_rabault_2019() -> None:
    g = recipes.Geometry()
    probes = np.array(recipes.probe_locations(g))
    assert probes.shape == (151, 3)
    # as in the reference layout, three ring points coincide with grid points:
    # (0, ±1 D) of the side grid and (1 D, 0) of the wake grid
    assert len({tuple(p) for p in probes}) == 148
    cx, cy = g.centre
    r = np.hypot(probes[:, 0] - cx, probes[:, 1] - cy)
    assert r.min() == pytest.approx(0.7 * g.diameter)  # inner ring
    assert np.count_nonzero(np.isclose(r, 0.7 * g.diameter)) == 36
    inside = (probes[:, 0] > 0) & (probes[:, 0] < g.length)
    inside &= (probes[:, 1] > 0) & (probes[:, 1] < g.height)
    assert inside.all()
    # wake grid: 9 columns of 7 from 0.75 D to 4.5 D behind the centre
    assert probes[:63, 0].min() == pytest.approx(cx + 0.75 * g.diameter)
    assert probes[:63, 0].max() == pytest.approx(cx + 4.5 * g.diameter)


def test_block_counts_are_consistent() -> None:
    g = recipes.Geometry()
    for res in (recipes.Resolution.coarse(), recipes.Resolution(), recipes.Resolution.fine()):
        c = recipes.block_counts(g, res)
        assert c.n_jet == res.cells_per_jet
        # uniform tangential spacing: a jet gets jet_width / 360 of the wall faces
        assert c.wall_faces * g.jet_width / 360 == pytest.approx(c.n_jet)
        assert c.radial_grading > 1
    default = recipes.block_counts(g, recipes.Resolution())
    assert 9_000 <= default.cells <= 20_000
    assert recipes.block_counts(g, recipes.Resolution.coarse()).cells < 5_000


def test_invalid_geometry_is_refused() -> None:
    with pytest.raises(ValueError, match="box"):
        recipes.block_counts(recipes.Geometry(box_half=0.25), recipes.Resolution())
    with pytest.raises(ValueError, match="radius"):
        recipes.block_counts(recipes.Geometry(box_half=0.04), recipes.Resolution())


def test_inflow_profile_is_the_benchmark_parabola() -> None:
    text = recipes.fluid_files(recipes.CASES["jet_cylinder"])["0/U"]
    m = re.search(r"polynomial \(\(\((\S+) 0 0\) \(1 1 1\)\) \(\((\S+) 0 0\) \(2 2 2\)\)\)", text)
    assert m is not None
    a1, a2 = float(m[1]), float(m[2])
    y = np.linspace(0, 0.41, 101)
    u = a1 * y + a2 * y**2
    assert u.max() == pytest.approx(1.5)
    assert u[0] == pytest.approx(0) and u[-1] == pytest.approx(0, abs=1e-8)
    assert np.trapezoid(u, y) / 0.41 == pytest.approx(1.0, rel=1e-3)


# --------------------------------------------------------------------------------------
# preCICE wiring: XML, preciceDict and gymprecice-config.json agree
# --------------------------------------------------------------------------------------


def test_one_window_per_action(tmp_path: Path) -> None:
    """``coupling="action"``: one serial-explicit window per action, linear waveform."""
    spec = recipes.case_spec("quickstart", coupling="action", snapshots=(4.7, 4.74))
    recipes.write_case(spec, tmp_path / "case")
    cfg = load_precice_config(tmp_path / "case" / "precice-config.xml")
    [scheme] = cfg.coupling_schemes
    assert scheme.kind == "serial-explicit"
    assert (scheme.first, scheme.second) == ("Controller", "Fluid")
    assert scheme.time_window_size == pytest.approx(spec.steps_per_action * spec.flow.dt)
    assert cfg.data["Velocity"].waveform_degree == 1
    gp = json.loads((tmp_path / "case" / "gymprecice-config.json").read_text())
    assert gp["actions"] == {"windows": 1, "scheme": "hold"}
    options = gp["physics_simulation_engine"]["solvers"]["fluid"]["options"]
    assert options["snapshots"] == [4.7, 4.74]
    # the fluid case, and with it the pre-run, is the same as with one window per step
    assert recipes.fluid_files(spec) == recipes.fluid_files(replace(spec, coupling="step"))
    with pytest.raises(ValueError, match="coupling"):
        _ = replace(spec, coupling="substep").time_window


@pytest.mark.parametrize("name", CASE_NAMES)
def test_precice_wiring(name: str) -> None:
    spec = recipes.CASES[name]
    case_dir = recipes.CASES_DIR / name
    cfg = load_precice_config(case_dir / "precice-config.xml")
    assert set(cfg.participants) == {"Fluid", "Controller"}
    assert cfg.data["Velocity"].kind == "vector"
    assert all(m.dimensions == 2 for m in cfg.meshes.values())
    [m2n] = cfg.m2n
    assert (m2n.kind, m2n.acceptor, m2n.connector) == ("sockets", "Controller", "Fluid")
    [scheme] = cfg.coupling_schemes
    # one window per solver step (parallel), or per action (serial, the controller first)
    kind = "serial-explicit" if spec.coupling == "action" else "parallel-explicit"
    assert scheme.kind == kind
    assert (scheme.first, scheme.second) == ("Controller", "Fluid")
    assert scheme.time_window_size == pytest.approx(spec.time_window)
    assert scheme.max_time == pytest.approx(spec.episode_time)
    if name.endswith("_fast"):
        assert scheme.time_window_size == pytest.approx(0.025)  # 25 steps x 1e-3 s
        assert scheme.max_time == pytest.approx(1.0)  # 40 actions
    elif name != "quickstart":
        assert scheme.time_window_size == pytest.approx(5e-4)
        assert scheme.max_time == pytest.approx(2.0)  # 80 actions x 50 steps x 5e-4 s

    fluid, controller = cfg.participant("Fluid"), cfg.participant("Controller")
    gp = json.loads((case_dir / "gymprecice-config.json").read_text())
    solver = gp["physics_simulation_engine"]["solvers"]["fluid"]
    assert (solver["kind"], solver["path"], solver["participant"]) == (
        "openfoam",
        "fluid-openfoam",
        "Fluid",
    )
    assert solver["options"]["prerun_end_time"] > 0
    assert gp["controller"]["participant"] == "Controller"
    write_to = gp["controller"]["write_to"]
    assert set(write_to) == set(spec.interfaces)
    assert set(write_to) == ({"jet1", "jet2"} if spec.control == "jets" else {"cylinder"})

    precice_dict = (case_dir / "fluid-openfoam" / "system" / "preciceDict").read_text()
    assert re.search(r'preciceConfig\s+"\.\./precice-config\.xml";', precice_dict)
    for iface, data in write_to.items():
        cmesh = gp["controller"]["meshes"][iface]
        fmesh = f"Fluid-Mesh-{iface}"
        assert cmesh in controller.provided_meshes
        assert (data, cmesh) in controller.write_data
        assert fluid.received_meshes[cmesh] == "Controller"
        assert (data, fmesh) in fluid.read_data
        assert fmesh in fluid.provided_meshes
        [mapping] = [mp for mp in fluid.mappings if mp.to_mesh == fmesh]
        assert (mapping.method, mapping.direction, mapping.from_mesh) == (
            "nearest-neighbor",
            "read",
            cmesh,
        )
        assert mapping.constraint == "consistent"
        assert any(e.data == data and e.mesh == cmesh for e in scheme.exchanges)
        # the adapter's interface on the OpenFOAM patch of the same name
        block = re.search(
            rf"mesh\s+{re.escape(fmesh)};\s*patches\s+\({iface}\);[^}}]*readData\s+\(Velocity\)",
            precice_dict,
        )
        assert block is not None, f"preciceDict lacks the interface {fmesh}"


# --------------------------------------------------------------------------------------
# Validation helpers (synthetic data)
# --------------------------------------------------------------------------------------


def test_shedding_stats_on_a_synthetic_signal() -> None:
    t = np.arange(0, 6, 5e-4)
    f = 3.0  # Hz -> St = 0.3 with D = 0.1, Umean = 1
    cl = 1.0 * np.sin(2 * np.pi * f * t) * (1 - np.exp(-t))
    cd = 3.17 + 0.06 * np.sin(4 * np.pi * f * t)
    s = shedding_stats(t, cd, cl, diameter=0.1, u_mean=1.0)
    assert s.strouhal == pytest.approx(0.3, rel=1e-3)
    assert s.cd_max == pytest.approx(3.23, abs=1e-4)
    assert s.cl_max == pytest.approx(1 - math.exp(-s.window[1]), rel=1e-3)
    assert s.cycles == 10
    with pytest.raises(ValueError, match="periodic"):
        shedding_stats(t, cd, np.zeros_like(t))


def test_validation_plans_match_the_docs() -> None:
    full = validation_spec(smoke=False, n_procs=2)
    smoke = validation_spec(smoke=True, n_procs=1, end_time=1.0)
    assert full.resolution == recipes.Resolution.fine()
    assert full.flow == recipes.CASES["jet_cylinder"].flow  # the case's own numerics
    assert (smoke.end_time, smoke.resolution) == (1.0, recipes.Resolution.coarse())
    cells = {
        name: recipes.block_counts(recipes.Geometry(), res).cells
        for name, res in (
            ("coarse", recipes.Resolution.coarse()),
            ("default", recipes.Resolution.default()),
            ("fine", recipes.Resolution.fine()),
        )
    }
    doc = Path(__file__).resolve().parents[3] / "docs" / "validation.md"
    if not doc.is_file():
        pytest.skip("docs/validation.md is not in this checkout")
    text = doc.read_text()
    for name, n in cells.items():
        assert f"{n:,}".replace(",", " ") in text, f"{name} mesh: {n} cells not in {doc.name}"


def test_deviation_from_reference_interval() -> None:
    assert deviation(3.23, (3.22, 3.24)) == 0
    assert deviation(0.987, (0.99, 1.01)) == pytest.approx(0.003 / 0.99)
    assert deviation(0.31, (0.295, 0.305)) == pytest.approx(0.005 / 0.305)


def test_read_force_coeffs_joins_restarts(tmp_path: Path) -> None:
    header = "# Force coefficients\n# Time\tCd\tCs\tCl\n"
    for start, rows in (
        ("0", [(0.1, 3.0, 0, 0.5), (0.2, 3.1, 0, 0.6)]),
        ("0.15", [(0.2, 9, 0, 9)]),
    ):
        d = tmp_path / "postProcessing" / "forceCoeffs" / start
        d.mkdir(parents=True)
        body = "".join("\t".join(str(v) for v in r) + "\n" for r in rows)
        (d / "coefficient.dat").write_text(header + body)
    c = read_force_coeffs(tmp_path)
    assert c["Time"].tolist() == [0.1, 0.2]
    assert c["Cd"].tolist() == [3.0, 9.0]
    assert c["Cl"].tolist() == [0.5, 9.0]


def test_smoke_band_catches_a_steady_wake() -> None:
    t = np.arange(0, 3, 5e-4)
    steady = {"Time": t, "Cd": np.full_like(t, 3.0), "Cl": np.zeros_like(t)}
    assert any("amplitude" in p for p in check_smoke(steady))
    shedding = dict(steady, Cl=0.5 * np.sin(2 * np.pi * 3 * t))
    assert check_smoke(shedding) == []
    broken = dict(shedding, Cd=np.full_like(t, np.nan))
    assert check_smoke(broken) == ["non-finite force coefficients"]


# --------------------------------------------------------------------------------------
# Real OpenFOAM: mesh, check and a few uncoupled time steps
# --------------------------------------------------------------------------------------


def _foam_list(path: Path) -> list[str]:
    """The entries of an ascii OpenFOAM list file (points, faces), header stripped."""
    text = path.read_text()
    body = text[text.index("}", text.index("FoamFile")) + 1 :]
    body = re.sub(r"//.*", "", body)
    m = re.search(r"^\s*(\d+)\s*\(", body, re.MULTILINE)
    assert m is not None, path
    n = int(m[1])
    entries = re.findall(r"^\s*(\d*\([^()]*\))\s*$", body[m.end() :], re.MULTILINE)
    assert len(entries) == n, path
    return entries


def _patch_ranges(boundary: Path) -> dict[str, tuple[int, int]]:
    text = boundary.read_text()
    out = {}
    for name, body in re.findall(r"^\s*(\w+)\s*\{([^}]*)\}", text, re.MULTILINE):
        if name == "FoamFile":
            continue
        n = int(re.search(r"nFaces\s+(\d+);", body)[1])  # type: ignore[index]
        start = int(re.search(r"startFace\s+(\d+);", body)[1])  # type: ignore[index]
        out[name] = (start, n)
    return out


def _patch_angles(case: Path, patch: str, centre: tuple[float, float]) -> np.ndarray:
    """Angles (degrees, 0..360) of the points of ``patch`` around ``centre``."""
    mesh = case / "constant" / "polyMesh"
    points = np.array(
        [[float(v) for v in p.strip("()").split()] for p in _foam_list(mesh / "points")]
    )
    faces = _foam_list(mesh / "faces")
    start, n = _patch_ranges(mesh / "boundary")[patch]
    ids = sorted(
        {int(v) for f in faces[start : start + n] for v in f[f.index("(") + 1 : -1].split()}
    )
    xy = points[ids, :2] - np.asarray(centre)
    radius = np.hypot(xy[:, 0], xy[:, 1])
    return np.degrees(np.arctan2(xy[:, 1], xy[:, 0])) % 360, radius


def _run(args: list[str], cwd: Path) -> str:
    proc = subprocess.run(
        args,
        cwd=cwd,
        env=openfoam_environment(),
        capture_output=True,
        text=True,
        timeout=240,
        check=False,
    )
    assert proc.returncode == 0, (
        f"{' '.join(args)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
    return proc.stdout


@pytest.mark.openfoam
@needs_openfoam
@pytest.mark.parametrize("name", CASE_NAMES)
def test_case_meshes_and_runs_uncoupled(name: str, tmp_path: Path) -> None:
    """Cost: about 1 s per case, 3 s for the five (blockMesh and a few pimpleFoam steps each)."""
    spec = recipes.CASES[name]
    steps = 4
    run_spec = replace(spec, end_time=steps * spec.flow.dt)
    fluid = recipes.write_fluid_case(run_spec, tmp_path / "fluid-openfoam", coupled=False)

    _run(["blockMesh"], fluid)
    check = _run(["checkMesh"], fluid)
    assert "Mesh OK." in check
    cells = int(re.search(r"^\s*cells:\s+(\d+)", check, re.MULTILINE)[1])  # type: ignore[index]
    assert cells == recipes.block_counts(spec.geometry, spec.resolution).cells

    patches = _patch_ranges(fluid / "constant" / "polyMesh" / "boundary")
    expected = {"inlet", "outlet", "walls", "cylinder", "frontAndBack"}
    if spec.control == "jets":
        expected |= {"jet1", "jet2"}
    assert set(patches) == expected

    g = spec.geometry
    if spec.control == "jets":
        for patch, centre_angle in (("jet1", 90.0), ("jet2", 270.0)):
            angles, radius = _patch_angles(fluid, patch, g.centre)
            assert radius == pytest.approx(g.radius, rel=1e-6)
            assert angles.min() == pytest.approx(centre_angle - g.jet_width / 2, abs=1e-6)
            assert angles.max() == pytest.approx(centre_angle + g.jet_width / 2, abs=1e-6)
            assert patches[patch][1] == spec.resolution.cells_per_jet
        angles, _ = _patch_angles(fluid, "cylinder", g.centre)
        assert not np.any((angles > 85.0 + 1e-6) & (angles < 95.0 - 1e-6))
    else:
        angles, radius = _patch_angles(fluid, "cylinder", g.centre)
        assert radius == pytest.approx(g.radius, rel=1e-6)
        assert np.ptp(np.sort(angles)) > 355  # the whole wall

    _run(["pimpleFoam"], fluid)
    probe_file = fluid / "postProcessing" / "probes" / "0" / "p"
    lines = probe_file.read_text().splitlines()
    assert sum(1 for ln in lines if ln.startswith("# Probe ")) == 151
    rows = [ln.split() for ln in lines if not ln.startswith("#")]
    assert len(rows) == steps and all(len(r) == 152 for r in rows)
    assert np.all(np.isfinite(np.array(rows, dtype=float)))
    coeffs = read_force_coeffs(fluid)
    assert len(coeffs["Time"]) == steps
    assert np.all(np.isfinite(coeffs["Cd"])) and np.all(np.isfinite(coeffs["Cl"]))
    assert coeffs["Cd"][-1] > 0


def _without_the_adapter(env: dict[str, str]) -> dict[str, str]:
    """``env`` with no library directory that holds the preCICE adapter, so that a coupled
    case cannot load it (where it loads, pimpleFoam would wait for its partners)."""
    name = "libpreciceAdapterFunctionObject.so"
    env = dict(env)
    for key in ("FOAM_USER_LIBBIN", "FOAM_SITE_LIBBIN", "LD_LIBRARY_PATH"):
        kept = [d for d in env.get(key, "").split(":") if d and not (Path(d) / name).is_file()]
        env[key] = ":".join(kept)
    return env


@pytest.mark.openfoam
@needs_openfoam
def test_coupled_case_needs_the_adapter(tmp_path: Path) -> None:
    """Without make_uncoupled, pimpleFoam must try to load the preCICE adapter.

    Cost: under a second (blockMesh and a pimpleFoam that stops at once).
    """
    spec = replace(recipes.CASES["quickstart"], end_time=5e-4)
    fluid = recipes.write_fluid_case(spec, tmp_path / "fluid-openfoam", coupled=True)
    _run(["blockMesh"], fluid)
    environment = _without_the_adapter(openfoam_environment())
    if ctypes.util.find_library("preciceAdapterFunctionObject") is not None:
        pytest.skip("the adapter is in a system library directory: pimpleFoam would wait")
    proc = subprocess.run(
        ["pimpleFoam"],
        cwd=fluid,
        env=environment,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert "libpreciceAdapterFunctionObject" in proc.stdout + proc.stderr


@pytest.mark.openfoam
@needs_openfoam
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun is not on PATH")
def test_jet_case_runs_decomposed(tmp_path: Path) -> None:
    """Cost: about 3 s (blockMesh, decomposePar and a few two-rank pimpleFoam steps)."""
    spec = replace(recipes.CASES["jet_cylinder"], end_time=2 * 5e-4)
    assert spec.n_procs == 2
    fluid = recipes.write_fluid_case(spec, tmp_path / "fluid-openfoam")
    _run(["blockMesh"], fluid)
    _run(["decomposePar"], fluid)
    assert (fluid / "processor1").is_dir()
    _run(["mpirun", "-np", "2", "pimpleFoam", "-parallel"], fluid)
    p = (fluid / "postProcessing" / "probes" / "0" / "p").read_text().splitlines()
    rows = [ln.split() for ln in p if not ln.startswith("#")]
    assert len(rows) == 2 and all(len(r) == 152 for r in rows)
