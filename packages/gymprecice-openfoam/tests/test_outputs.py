"""Incremental readers of probes, forces and force coefficients.

Synthetic files pin down each layout and edge case (half-written lines, restarts,
corrupt lines, timeouts); a real pimpleFoam run checks the readers against what
OpenFOAM v1912 actually writes, read while the solver is still writing.
"""

from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from gymprecice_openfoam import outputs

PROBE_HEADER = (
    "# Probe 0 (0.3 0.2 0.005)\n# Probe 1 (0.45 0.22 0.005)\n"
    "#       Probe             0             1\n#        Time\n"
)


def _write(path: Path, text: str, mode: str = "a") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open(mode) as handle:
        handle.write(text)


def _full_table(path: Path) -> np.ndarray:
    """Independent whole-file parse: drop comments and parentheses, split numbers."""
    rows = []
    for line in path.read_text().splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            rows.append([float(x) for x in line.replace("(", " ").replace(")", " ").split()])
    return np.array(rows)


def test_scalar_probes_keep_half_written_lines_for_later(tmp_path):
    path = tmp_path / "probes" / "0" / "p"
    _write(path, PROBE_HEADER + "        0.005     0.0357936     -0.558004\n         0.01     0.03")
    reader = outputs.ProbesReader(tmp_path / "probes", "p")
    rows = reader.read_new()
    np.testing.assert_array_equal(rows.time, [0.005])
    np.testing.assert_array_equal(rows.values, [[0.0357936, -0.558004]])
    assert rows.columns == ("probe0", "probe1")
    np.testing.assert_array_equal(reader.locations, [[0.3, 0.2, 0.005], [0.45, 0.22, 0.005]])
    assert len(reader.read_new()) == 0  # the half line is not handed out
    _write(path, "69837     -0.589493\n        0.015     0.0374848     -0.601034\n")
    rows = reader.read_new()
    np.testing.assert_array_equal(rows.time, [0.01, 0.015])
    np.testing.assert_array_equal(rows.values[:, 0], [0.0369837, 0.0374848])
    assert reader.latest_time == 0.015
    np.testing.assert_array_equal(reader.read_all().time, [0.005, 0.01, 0.015])


def test_vector_probes_have_a_component_axis(tmp_path):
    path = tmp_path / "probes" / "0" / "U"
    _write(
        path,
        PROBE_HEADER
        + "        0.005             (-0.0193224 0.00663556 0)             (0.0797593 0.0263034 0)\n"
        + "         0.01             (-0.036066 0.0125545 0)             (0.130399 0.0473367 0)\n",
    )
    rows = outputs.ProbesReader(tmp_path / "probes", "U").read_new()
    assert rows.values.shape == (2, 2, 3)
    np.testing.assert_array_equal(rows.values[1, 1], [0.130399, 0.0473367, 0])
    np.testing.assert_array_equal(rows.last, rows.values[-1])


def test_truncated_or_corrupt_complete_line_names_file_and_line(tmp_path):
    path = tmp_path / "probes" / "0" / "p"
    _write(path, PROBE_HEADER + "0.005 1.0 2.0\n0.01 1.5\n0.015 1.0 2.0\n")
    with pytest.raises(outputs.OutputFormatError) as err:
        outputs.ProbesReader(tmp_path / "probes", "p").read_new()
    assert f"{path}:6" in str(err.value) and "expected 3 numbers, found 2" in str(err.value)
    _write(path, PROBE_HEADER + "0.005 1.0 2.0\n0.01 1.5 nan?\n", mode="w")
    with pytest.raises(outputs.OutputFormatError, match=rf"{path}:6: not a number"):
        outputs.ProbesReader(tmp_path / "probes", "p").read_new()


FORCE_V1912 = (
    "# Force       \n# CofR        : (0.000000e+00 0.000000e+00 0.000000e+00)\n#\n"
    "# Time        \t(total_x total_y total_z)\t(pressure_x pressure_y pressure_z)\t"
    "(viscous_x viscous_y viscous_z)\n"
    "0.005         \t(-7.438440e-04 9.314391e-05 0.000000e+00)\t(0.000000e+00 9.314391e-05 "
    "0.000000e+00)\t(-7.438440e-04 2.045746e-12 0.000000e+00)\n"
)
FORCE_V2006 = (
    "# Force\n# CofR                : (0 0 0)\n#\n"
    "# Time          total_x         total_y         total_z         pressure_x      "
    "pressure_y      pressure_z      viscous_x       viscous_y       viscous_z\n"
    "0.005   -7.4e-04 9.3e-05 0 0 9.3e-05 0 -7.4e-04 2.0e-12 0\n"
)
FORCES_ORG = (
    "# Forces\n# CofR                : (0 0 0)\n"
    "# Time                forces(pressure viscous) moment(pressure viscous)\n"
    "0.005  ((1 2 3) (4 5 6)) ((7 8 9) (10 11 12))\n"
)


@pytest.mark.parametrize(
    ("name", "text", "column", "value"),
    [
        ("force.dat", FORCE_V1912, "total_x", -7.438440e-04),
        ("force.dat", FORCE_V2006, "viscous_y", 2.0e-12),
        ("forces.dat", FORCES_ORG, "moment_viscous_x", 10.0),
    ],
)
def test_force_layouts_give_named_columns(tmp_path, name, text, column, value):
    _write(tmp_path / "forces" / "0" / name, text)
    rows = outputs.ForcesReader(tmp_path / "forces").read_new()
    assert rows.column(column)[0] == value
    np.testing.assert_array_equal(rows.time, [0.005])
    with pytest.raises(KeyError, match="columns"):
        rows.column("nope")


def test_force_coefficient_layouts(tmp_path):
    esi = (
        "# Force coefficients\n# dragDir     : (1 0 0)\n#\n# Time        \tCd            \t"
        "Cs            \tCl            \tCmRoll        \tCmPitch       \tCmYaw         \t"
        "Cd(f)         \tCd(r)         \tCs(f)         \tCs(r)         \tCl(f)         \tCl(r)\n"
        "0.005         \t-1.487688e+00\t0\t1.862878e-01\t-9.3e-03\t-1.8e+00\t-7.4e-02\t"
        "-7.5e-01\t-7.3e-01\t-7.4e-02\t7.4e-02\t-1.7e+00\t1.9e+00\n"
    )
    _write(tmp_path / "a" / "0" / "coefficient.dat", esi)
    rows = outputs.ForceCoeffsReader(tmp_path / "a").read_new()
    assert rows.column("Cd")[0] == -1.487688
    assert rows.column("Cl(r)")[0] == 1.9
    org = "# Force coefficients\n# Time        \tCm\tCd\tCl\tCl(f)\tCl(r)\n0.1\t0.5\t3.1\t0.2\t0.6\t-0.4\n"
    _write(tmp_path / "b" / "0" / "forceCoeffs.dat", org)
    rows = outputs.ForceCoeffsReader(tmp_path / "b").read_new()
    assert rows.column("Cd")[0] == 3.1 and rows.column("Cl(f)")[0] == 0.6


def test_read_force_coeffs_joins_a_runs_restarts_the_later_run_winning(tmp_path):
    """A finished run's whole history: every start-time directory in time order; a run
    restarted from before where the last one stopped replaces its rows from there on."""
    header = "# Force coefficients\n# Time\tCd\tCs\tCl\n"
    runs = {
        "0": [(0.1, 3.0, 0, 0.5), (0.2, 3.1, 0, 0.6), (0.3, 3.2, 0, 0.7)],
        "0.15": [(0.2, 9.0, 0, 9.0)],  # restarted from 0.15: 0.2 again, 0.3 never reached
        "0.2": [(0.25, 8.0, 0, 8.0), (0.35, 7.0, 0, 7.0)],
    }
    for start, rows in runs.items():
        body = "".join("\t".join(str(v) for v in r) + "\n" for r in rows)
        _write(
            tmp_path / "postProcessing" / "forceCoeffs" / start / "coefficient.dat", header + body
        )
    rows = outputs.read_force_coeffs(tmp_path)
    np.testing.assert_array_equal(rows.time, [0.1, 0.2, 0.25, 0.35])
    np.testing.assert_array_equal(rows.column("Cd"), [3.0, 9.0, 8.0, 7.0])
    assert rows.columns == ("Cd", "Cs", "Cl")
    with pytest.raises(FileNotFoundError, match="no force coefficients under"):
        outputs.read_force_coeffs(tmp_path, "missing")


def test_restarts_continue_in_newer_start_time_directories(tmp_path):
    base = tmp_path / "forces"
    head = FORCE_V2006.split("0.005")[0]
    _write(base / "0" / "force.dat", head + "0.1 1 1 1 1 1 1 1 1 1\n0.2 2 2 2 2 2 2 2 2 2\n0.25 9")
    reader = outputs.ForcesReader(base)
    np.testing.assert_array_equal(reader.read_new().time, [0.1, 0.2])
    # The run stopped mid-line; a restart from 0.2 writes into postProcessing/forces/0.2,
    # and a second restart at the same time makes OpenFOAM write force_0.2.dat.
    _write(base / "0.2" / "force.dat", head + "0.3 3 3 3 3 3 3 3 3 3\n")
    _write(base / "0.2" / "force_0.2.dat", head + "0.3 4 4 4 4 4 4 4 4 4\n")
    rows = reader.read_new()
    np.testing.assert_array_equal(rows.time, [0.3, 0.3])
    np.testing.assert_array_equal(rows.column("total_x"), [3, 4])
    assert [p.name for p in reader.files] == ["force.dat", "force.dat", "force_0.2.dat"]
    # An episode reader skips start-time directories before its start.
    late = outputs.ForcesReader(base, start_time=0.2)
    np.testing.assert_array_equal(late.read_new().column("total_x"), [3, 4])


def test_wait_until_polls_without_busy_waiting_and_times_out(tmp_path):
    path = tmp_path / "probes" / "0" / "p"
    _write(path, PROBE_HEADER)
    reader = outputs.ProbesReader(tmp_path / "probes", "p")

    def writer() -> None:
        for i in range(1, 6):
            time.sleep(0.03)
            _write(path, f"{i * 0.01:g} {i} {-i}\n")

    thread = threading.Thread(target=writer)
    start_cpu = time.process_time()
    thread.start()
    rows = reader.wait_until(0.04, timeout=5.0)
    thread.join()
    assert rows.time[-1] >= 0.04 - 1e-12
    assert time.process_time() - start_cpu < 0.1, "waiting must sleep, not spin"
    rest = reader.wait_until(0.05, timeout=1.0)
    np.testing.assert_array_equal(
        np.concatenate([rows.time, rest.time]), [0.01, 0.02, 0.03, 0.04, 0.05]
    )
    t0 = time.monotonic()
    with pytest.raises(outputs.OutputTimeoutError, match=r"t=0\.1 within 0\.2 s.*read t=0\.05"):
        reader.wait_until(0.1, timeout=0.2)
    assert 0.19 <= time.monotonic() - t0 < 1.0
    empty = outputs.ProbesReader(tmp_path / "none", "p")
    with pytest.raises(outputs.OutputTimeoutError, match="nothing yet"):
        empty.wait_until(0.1, timeout=0.05)


@pytest.mark.openfoam
def test_readers_match_a_real_run_read_while_it_writes(foam, run, cylinder_case):
    """Cost: about 1 s (blockMesh and a 0.02 s pimpleFoam run of the small cylinder)."""
    case = cylinder_case("live", end_time=0.3, delta_t=0.0005, write_interval=10, adapter=False)
    run(case, "blockMesh")
    program = foam.which("pimpleFoam")
    probes = outputs.ProbesReader(case / "postProcessing" / "probes", "p")
    vprobes = outputs.ProbesReader(case / "postProcessing" / "probes", "U")
    forces = outputs.ForcesReader(case / "postProcessing" / "forces")
    coeffs = outputs.ForceCoeffsReader(case / "postProcessing" / "forceCoeffs")
    collected: dict[str, list] = {"p": [], "U": [], "f": [], "c": []}
    reads_during_run = 0
    with (case / "log.pimpleFoam").open("wb") as log:
        proc = subprocess.Popen(
            [program], cwd=case, env=foam.environ(), stdout=log, stderr=subprocess.STDOUT
        )
        try:
            while proc.poll() is None:
                new = probes.read_new()
                if len(new) and proc.poll() is None:
                    reads_during_run += 1
                collected["p"].append(new)
                collected["U"].append(vprobes.read_new())
                collected["f"].append(forces.read_new())
                collected["c"].append(coeffs.read_new())
                time.sleep(0.02)
        finally:
            proc.wait(timeout=120)
    assert proc.returncode == 0, (case / "log.pimpleFoam").read_text()[-2000:]
    for key, reader in (("p", probes), ("U", vprobes), ("f", forces), ("c", coeffs)):
        collected[key].append(reader.read_new())
    assert reads_during_run >= 2, "the solver finished before the readers saw it write"

    p = outputs.Rows.concatenate(collected["p"])
    table = _full_table(case / "postProcessing" / "probes" / "0" / "p")
    assert len(table) == 600  # one row per step, none lost or repeated
    np.testing.assert_array_equal(p.time, table[:, 0])
    np.testing.assert_array_equal(p.values, table[:, 1:])
    u = outputs.Rows.concatenate(collected["U"])
    table = _full_table(case / "postProcessing" / "probes" / "0" / "U")
    np.testing.assert_array_equal(u.values, table[:, 1:].reshape(len(table), 3, 3))
    f = outputs.Rows.concatenate(collected["f"])
    table = _full_table(case / "postProcessing" / "forces" / "0" / "force.dat")
    np.testing.assert_array_equal(f.values, table[:, 1:])
    assert f.columns[:3] == ("total_x", "total_y", "total_z")
    c = outputs.Rows.concatenate(collected["c"])
    table = _full_table(case / "postProcessing" / "forceCoeffs" / "0" / "coefficient.dat")
    np.testing.assert_array_equal(c.values, table[:, 1:])
    assert c.column("Cd")[-1] > 0  # flow from the left pushes the cylinder downstream


def test_the_readers_follow_cores_reader_conventions(tmp_path: Path) -> None:
    """``start_time``, ``latest_time`` and ``wait_until``: what env code relies on."""
    from gymprecice.plugin.solver import WaitableOutputReader

    reader = outputs.TableReader(tmp_path / "postProcessing" / "forces", ["force.dat"])
    assert isinstance(reader, WaitableOutputReader)
    assert reader.start_time is None and reader.latest_time is None


def test_wait_until_keeps_rows_past_its_time_for_the_next_step(tmp_path: Path) -> None:
    """A solver running ahead has written the next step's rows: they wait for that step."""
    path = tmp_path / "forceCoeffs" / "0" / "coefficient.dat"
    _write(path, "# Time Cd Cl\n0.01 1.0 0.1\n0.02 2.0 0.2\n0.03 3.0 0.3\n0.04 4.0 0.")
    reader = outputs.ForceCoeffsReader(tmp_path / "forceCoeffs")
    step = reader.wait_until(0.02, timeout=0.0)
    np.testing.assert_array_equal(step.time, [0.01, 0.02])
    assert step.column("Cd").mean() == 1.5 and step.last.tolist() == [2.0, 0.2]
    assert reader.latest_time == 0.02
    assert reader.wait_until(0.02, timeout=0.0) is step  # the reward asks after the observation
    _write(path, "4\n")  # the half-written 0.04 row is complete now
    np.testing.assert_array_equal(reader.wait_until(0.03, timeout=0.0).time, [0.03])
    np.testing.assert_array_equal(reader.read_new().time, [0.04])  # the rest, whatever its time
    np.testing.assert_array_equal(reader.read_all().time, [0.01, 0.02, 0.03, 0.04])


def test_a_step_s_rows_do_not_depend_on_the_solver_s_lead(tmp_path: Path) -> None:
    def steps(lead: int) -> list[list[float]]:
        path = tmp_path / f"lead{lead}" / "probes" / "0" / "p"
        _write(path, PROBE_HEADER)
        reader = outputs.ProbesReader(path.parent.parent, "p")
        written, out = 0, []
        for k in range(1, 5):
            while written < k + lead:
                written += 1
                _write(path, f"{written * 0.005:g} {written} {-written}\n")
            out.append(reader.wait_until(k * 0.005, timeout=0.0).time.tolist())
        return out

    assert steps(0) == steps(1) == steps(4) == [[0.005], [0.01], [0.015], [0.02]]
