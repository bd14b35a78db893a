"""The deal.II plugin's hooks on a copy of the perpendicular-flap solid case."""

from __future__ import annotations

import os
import re
import shutil
import stat
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.errors import CaseError, ConfigError
from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.plugin.solver import SolverContext
from gymprecice.plugin.watchpoints import WatchPointLog
from gymprecice.tools.stack import stack_which
from gymprecice_dealii import plugin
from gymprecice_dealii.prm import ElasticityParameters

FLAP_CASE = (
    Path(__file__).resolve().parents[2]
    / "gymprecice-tutorials/src/gymprecice_tutorials/perpendicular_flap/case"
)


@pytest.fixture
def env_dir(tmp_path: Path) -> Path:
    """An env run directory as core makes it: the case copied, the XML beside it."""
    root = tmp_path / "env_0"
    shutil.copytree(FLAP_CASE / "solid-dealii", root / "solid-dealii")
    shutil.copy(FLAP_CASE / "precice-config.xml", root / "precice-config.xml")
    return root


def context(env_dir: Path, **overrides) -> SolverContext:
    xml = env_dir / "precice-config.xml"
    values = dict(
        name="solid",
        kind="dealii",
        run_dir=env_dir / "solid-dealii",
        source_dir=FLAP_CASE / "solid-dealii",
        env_dir=env_dir,
        participant="Solid",
        config_file=env_dir / "gymprecice-config.json",
        precice=load_precice_config(xml),
        precice_config_file=xml,
    )
    values.update(overrides)
    return SolverContext(**values)


@pytest.fixture
def fake_elasticity(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An executable named elasticity on PATH (the real one is not installed here)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    program = bin_dir / "elasticity"
    program.write_text("#!/bin/sh\nexit 0\n")
    program.chmod(program.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    return program


def test_kind_is_registered() -> None:
    assert "dealii" in plugin.gymprecice_solver_kinds()


def test_other_kinds_are_left_alone(env_dir: Path) -> None:
    other = context(env_dir, kind="openfoam")
    assert plugin.gymprecice_prepare_case(other) is None
    assert plugin.gymprecice_reset_case(other) is None
    assert plugin.gymprecice_launch_solver(other) is None
    assert plugin.gymprecice_open_output(other, "watchpoint", {"name": "Flap-Tip"}) is None
    assert plugin.gymprecice_check_solver(other, "anything") is None


def test_prepare_points_the_solid_at_the_envs_precice_config(env_dir: Path) -> None:
    moved = env_dir / "config" / "precice-env.xml"  # somewhere else than the case's
    moved.parent.mkdir()
    shutil.copy(env_dir / "precice-config.xml", moved)
    solver = context(env_dir, precice_config_file=moved)
    before = (solver.run_dir / "parameters.prm").read_text()
    assert plugin.gymprecice_prepare_case(solver) is True
    prm = ElasticityParameters.read(solver.run_dir / "parameters.prm")
    assert prm.precice_config_file == "../config/precice-env.xml"
    assert (solver.run_dir / prm.precice_config_file).resolve() == moved.resolve()
    # only that line changed
    diff = [(a, b) for a, b in zip(before.splitlines(), prm.text().splitlines()) if a != b]
    assert diff == [
        (
            "  set precice config-file = ../precice-config.xml",
            "  set precice config-file = ../config/precice-env.xml",
        )
    ]
    assert (FLAP_CASE / "solid-dealii/parameters.prm").read_text() == before  # pristine


def test_prepare_can_override_the_output_interval(env_dir: Path) -> None:
    solver = context(env_dir, options={"output_interval": 500})
    plugin.gymprecice_prepare_case(solver)
    assert ElasticityParameters.read(solver.run_dir / "parameters.prm").output_interval == 500


def test_prepare_needs_the_parameter_file(env_dir: Path) -> None:
    (env_dir / "solid-dealii/parameters.prm").unlink()
    with pytest.raises(CaseError, match=r"parameters\.prm does not exist"):
        plugin.gymprecice_prepare_case(context(env_dir))


def test_prepare_rejects_unknown_options(env_dir: Path) -> None:
    with pytest.raises(ConfigError, match=r"unknown option\(s\) \['progam'\]"):
        plugin.gymprecice_prepare_case(context(env_dir, options={"progam": "x"}))


def test_prepare_reports_a_parameter_file_missing_adapter_keys(env_dir: Path) -> None:
    prm = env_dir / "solid-dealii/parameters.prm"
    prm.write_text(prm.read_text().replace("  set Mesh name           = Solid-Mesh\n", ""))
    with pytest.raises(CaseError, match="precice configuration / Mesh name"):
        plugin.gymprecice_prepare_case(context(env_dir))


def test_a_solid_mesh_missing_from_the_xml_is_reported_with_both_files(env_dir: Path) -> None:
    xml = env_dir / "precice-config.xml"
    xml.write_text(xml.read_text().replace("Solid-Mesh", "Flap-Mesh"))
    with pytest.raises(CaseError) as caught:
        plugin.gymprecice_prepare_case(context(env_dir))
    message = str(caught.value)
    assert "'Solid-Mesh'" in message and "['Flap-Mesh']" in message
    assert "parameters.prm" in message and "precice-config.xml" in message


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("Participant name    = Solid", "Participant name    = Structure", "'Structure'"),
        (
            "Read data name      = Force",
            "Read data name      = Stress",
            "'Read data name' is 'Stress'",
        ),
        ("Write data name     = Displacement", "Write data name     = Force", "'Write data name'"),
        ("Time step size  = 0.01", "Time step size  = 0.005", "time step = time-window size"),
    ],
)
def test_prepare_checks_the_parameter_file_against_the_xml(
    env_dir: Path, old: str, new: str, message: str
) -> None:
    prm = env_dir / "solid-dealii/parameters.prm"
    text = prm.read_text()
    assert old in text
    prm.write_text(text.replace(old, new))
    with pytest.raises(CaseError, match=message.replace("(", r"\(")):
        plugin.gymprecice_prepare_case(context(env_dir, participant=None))


def test_reset_cleans_outputs_and_precice_logs_in_the_run_dir_only(env_dir: Path) -> None:
    solver = context(env_dir)
    plugin.gymprecice_prepare_case(solver)
    run = solver.run_dir
    (run / "dealii-output").mkdir()
    (run / "dealii-output" / "solution-0.vtu").write_text("x")
    (run / "precice-Solid-watchpoint-Flap-Tip.log").write_text("x")
    (run / "precice-Solid-iterations.log").write_text("x")
    (run / "precice-profiling").mkdir()
    (run / "precice-profiling" / "Solid-0-1.json").write_text("{}")
    (run / "solver.log").write_text("kept")
    elsewhere = env_dir / "precice-Fluid-iterations.log"  # another solver's directory
    elsewhere.write_text("kept")
    assert plugin.gymprecice_reset_case(solver) is True
    assert sorted(p.name for p in run.iterdir()) == ["parameters.prm", "solver.log"]
    assert elsewhere.exists()


def test_reset_never_deletes_an_output_folder_outside_the_run_dir(env_dir: Path) -> None:
    outside = env_dir / "precious"
    outside.mkdir()
    prm = env_dir / "solid-dealii/parameters.prm"
    prm.write_text(prm.read_text().replace("= dealii-output", "= ../precious"))
    solver = context(env_dir)
    plugin.gymprecice_prepare_case(solver)
    plugin.gymprecice_reset_case(solver)
    assert outside.is_dir()


def test_launch_runs_elasticity_with_the_parameter_file(
    env_dir: Path, fake_elasticity: Path
) -> None:
    solver = context(env_dir, options={"threads": 2})
    spec = plugin.gymprecice_launch_solver(solver)
    assert spec.argv == [str(fake_elasticity), "parameters.prm"]
    assert spec.cwd == solver.run_dir
    assert spec.env == {"DEAL_II_NUM_THREADS": "2"}


def test_launch_through_mpirun_when_asked(
    env_dir: Path, fake_elasticity: Path, tmp_path: Path
) -> None:
    launcher = fake_elasticity.parent / "mpirun"
    shutil.copy(fake_elasticity, launcher)
    spec = plugin.gymprecice_launch_solver(context(env_dir, options={"np": 4}))
    assert list(spec.argv) == ["mpirun", "-np", "4", str(fake_elasticity), "parameters.prm"]


def test_launch_takes_the_program_from_the_options(env_dir: Path, tmp_path: Path) -> None:
    program = env_dir / "solid-dealii" / "my-elasticity"
    program.write_text("#!/bin/sh\n")
    program.chmod(0o755)
    spec = plugin.gymprecice_launch_solver(context(env_dir, options={"program": "./my-elasticity"}))
    assert spec.argv[0] == str(env_dir / "solid-dealii" / "./my-elasticity")


def test_missing_elasticity_says_how_to_get_it(
    env_dir: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setenv("GYMPRECICE_STACK_PREFIX", str(tmp_path / "no-stack"))
    with pytest.raises(CaseError) as caught:
        plugin.gymprecice_launch_solver(context(env_dir))
    message = str(caught.value)
    assert "'elasticity'" in message and "not on PATH" in message
    assert "dealii-adapter" in message and "build" in message


@pytest.mark.parametrize("value", [0, -1, 1.5, "2", True])
def test_bad_rank_counts_are_config_errors(env_dir: Path, fake_elasticity: Path, value) -> None:
    with pytest.raises(ConfigError, match=r"options\.np must be a positive integer"):
        plugin.gymprecice_launch_solver(context(env_dir, options={"np": value}))


def test_watchpoint_output_reads_the_solids_log(env_dir: Path) -> None:
    solver = context(env_dir)
    plugin.gymprecice_prepare_case(solver)
    reader = plugin.gymprecice_open_output(solver, "watchpoint", {"name": "Flap-Tip"})
    assert isinstance(reader, WatchPointLog)
    same = plugin.gymprecice_open_output(solver, "watchpoint", {"point": "Flap-Tip"})
    assert same.path == reader.path
    assert reader.path == solver.run_dir / "precice-Solid-watchpoint-Flap-Tip.log"
    reader.path.write_text(
        "  Time  Coordinate0  Coordinate1  Displacement0  Displacement1  Force0  Force1"
        "\n 0.00000000e+00   0.00000000e+00   1.00000000e+00   0.00000000e+00   "
        "0.00000000e+00   0.00000000e+00   0.00000000e+00"
        "\n 1.00000000e-02   1.20000000e-03   1.00000000e+00   1.20000000e-03   "
        "-2.00000000e-06   3.10000000e-01   -4.00000000e-03"
    )
    rows = reader.wait_until(0.01, timeout=1.0)
    np.testing.assert_allclose(reader.field("Displacement", rows)[-1], [1.2e-3, -2e-6])


def test_a_stand_in_that_writes_the_log_itself_opts_into_the_reader(env_dir: Path) -> None:
    # a scripted solid (kind "command") writes the watch-point log that preCICE would; the
    # case's XML declares no watch point for it, or the test double would write one too
    xml = env_dir / "precice-config.xml"
    xml.write_text(re.sub(r"<watch-point [^>]*/>", "", xml.read_text()))
    stand_in = context(env_dir, kind="command", options={"outputs": "dealii"})
    reader = plugin.gymprecice_open_output(stand_in, "watchpoint", {"point": "Flap-Tip"})
    assert isinstance(reader, WatchPointLog)
    assert reader.path == stand_in.run_dir / "precice-Solid-watchpoint-Flap-Tip.log"
    # without the option the reader is not the plugin's business; with it, still no probes
    plain = context(env_dir, kind="command")
    assert plugin.gymprecice_open_output(plain, "watchpoint", {"point": "Flap-Tip"}) is None
    with pytest.raises(ConfigError, match="no output 'probes'"):
        plugin.gymprecice_open_output(stand_in, "probes", {})
    # a real deal.II solid on the same XML is still told to declare its watch point
    with pytest.raises(ConfigError, match="no <watch-point name='Flap-Tip'>"):
        plugin.gymprecice_open_output(
            context(env_dir, precice=load_precice_config(xml)), "watchpoint", {"point": "Flap-Tip"}
        )


def test_unknown_watchpoints_and_outputs_are_reported(env_dir: Path) -> None:
    solver = context(env_dir)
    with pytest.raises(ConfigError, match=r"no <watch-point name='Tip'>.*\['Flap-Tip'\]"):
        plugin.gymprecice_open_output(solver, "watchpoint", {"name": "Tip"})
    with pytest.raises(ConfigError, match="needs the watch point's name"):
        plugin.gymprecice_open_output(solver, "watchpoint", {})
    with pytest.raises(ConfigError, match="needs the watch point's name"):
        plugin.gymprecice_open_output(solver, "watchpoint", {"point": "Flap-Tip", "x": 1})
    with pytest.raises(ConfigError, match=r"no output 'probes'.*\['watchpoint'\]"):
        plugin.gymprecice_open_output(solver, "probes", {})


def test_check_solver_explains_known_failures(env_dir: Path) -> None:
    solver = context(env_dir)
    log = "An error occurred ... This solver supports only constant time-step sizes.Configured"
    message = plugin.gymprecice_check_solver(solver, log)
    assert "Time step size" in message and "parameters.prm" in message
    assert plugin.gymprecice_check_solver(solver, "Timestep 3 @ 0.03s") is None


def test_doctor_reports_library_and_program(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setenv("GYMPRECICE_STACK_PREFIX", str(tmp_path / "no-stack"))
    monkeypatch.setenv("DEAL_II_DIR", str(tmp_path / "dealii"))
    header = tmp_path / "dealii/include/deal.II/base/config.h"
    header.parent.mkdir(parents=True)
    header.write_text('#define DEAL_II_PACKAGE_VERSION "9.5.2"\n')
    checks = {c.name: c for c in plugin.gymprecice_doctor_checks()}
    library = checks["deal.II library"]
    program = checks["deal.II-preCICE adapter (elasticity)"]
    assert library.ok and "9.5.2" in library.detail
    assert not program.ok and "dealii-adapter" in program.advice


@pytest.mark.dealii
def test_real_elasticity_starts_on_the_prepared_case(env_dir: Path, tmp_path: Path) -> None:
    """With the adapter installed: elasticity reads the prepared parameter file.

    Without its preCICE partner it cannot couple: it parses the file, builds the mesh and
    then waits for the fluid, which is where the test stops it.

    Cost: under a second (elasticity reads its file and builds its mesh, then is stopped).
    """
    if stack_which("elasticity") is None:
        pytest.skip("no elasticity program: run `gymprecice install dealii-adapter`")
    import subprocess
    import time

    solver = context(env_dir)
    plugin.gymprecice_prepare_case(solver)
    spec = plugin.gymprecice_launch_solver(solver)
    log = tmp_path / "elasticity.log"
    with log.open("w") as out:
        process = subprocess.Popen(
            list(spec.argv), cwd=spec.cwd, stdout=out, stderr=subprocess.STDOUT
        )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and process.poll() is None:
            if "communication to coupling partner" in log.read_text(errors="replace"):
                break
            time.sleep(0.2)
        text = log.read_text(errors="replace")
    finally:
        process.kill()
        process.wait()
    assert "ParameterHandler" not in text
    assert "Number of active cells" in text, text[-2000:]
    assert "communication to coupling partner" in text, text[-2000:]


def test_elasticity_built_by_gymprecice_install_is_found_without_path(
    env_dir: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    stack = tmp_path / "stack"
    program = stack / "bin" / "elasticity"
    program.parent.mkdir(parents=True)
    program.write_text("#!/bin/sh\n")
    program.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setenv("GYMPRECICE_STACK_PREFIX", str(stack))
    spec = plugin.gymprecice_launch_solver(context(env_dir))
    assert spec.argv[0] == str(program)
