"""The pyprecice test double: API shape, protocol checks, coupling semantics, failure mode.

Two kinds of tests live here. Exact data semantics (what a participant reads in which
window, mappings, subcycling, iterations) run both participants in threads of the test
process, which the double allows because it keeps no process-global state; that gives
full control of both sides. Whole runs and the failure behaviour run participants as real
separate processes (``python -m gymprecice.testing.partner``), as in production.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gymprecice.testing import CASES_DIR, case_config, partner_command
from gymprecice.testing import fake_precice as fp
from gymprecice.testing.flows import fake_cylinder_geometry

pytestmark = pytest.mark.timeout(60)

A_COORDS = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
B_COORDS = np.array([[0.1, 0.0], [0.9, 0.0], [2.2, 0.0], [1.6, 0.0]])


def pair_config(
    tmp_path: Path,
    *,
    kind: str = "parallel-explicit",
    max_time: float | None = 0.05,
    windows: int | None = None,
    window: float = 0.01,
    degree: int = 1,
    initialize: bool = False,
    implicit: str = '<max-iterations value="3" />',
    name: str = "precice-config.xml",
    api_access: bool = False,
) -> Path:
    """Participants A and B: A writes "Up" on its mesh, B answers "Down" (mapped both ways)."""
    exchange = tmp_path / "exchange"
    limits = ""
    if max_time is not None:
        limits += f'<max-time value="{max_time}" />'
    if windows is not None:
        limits += f'<max-time-windows value="{windows}" />'
    init = ' initialize="true"' if initialize else ""
    extras = implicit if kind.endswith("implicit") else ""
    receive_b = (
        '<receive-mesh name="B-Mesh" from="B" api-access="true" />'
        '<read-data name="Down" mesh="B-Mesh" />'
        if api_access
        else ""
    )
    xml = f"""<?xml version="1.0"?>
<precice-configuration>
  <log><sink filter="%Severity% > debug" enabled="false" /></log>
  <data:scalar name="Up" waveform-degree="{degree}" />
  <data:scalar name="Down" waveform-degree="{degree}" />
  <mesh name="A-Mesh" dimensions="2"><use-data name="Up" /><use-data name="Down" /></mesh>
  <mesh name="B-Mesh" dimensions="2"><use-data name="Up" /><use-data name="Down" /></mesh>
  <participant name="A">
    <provide-mesh name="A-Mesh" />
    {receive_b}
    <write-data name="Up" mesh="A-Mesh" />
    <read-data name="Down" mesh="A-Mesh" />
  </participant>
  <participant name="B">
    <provide-mesh name="B-Mesh" />
    <receive-mesh name="A-Mesh" from="A" />
    <read-data name="Up" mesh="B-Mesh" />
    <write-data name="Down" mesh="B-Mesh" />
    <mapping:nearest-neighbor direction="read" from="A-Mesh" to="B-Mesh" constraint="consistent" />
    <mapping:nearest-neighbor direction="write" from="B-Mesh" to="A-Mesh"
                              constraint="conservative" />
  </participant>
  <m2n:sockets acceptor="A" connector="B" exchange-directory="{exchange}" />
  <coupling-scheme:{kind}>
    <participants first="A" second="B" />
    {limits}
    <time-window-size value="{window}" />
    <exchange data="Up" mesh="A-Mesh" from="A" to="B"{init} />
    <exchange data="Down" mesh="A-Mesh" from="B" to="A" />
    {extras}
  </coupling-scheme:{kind}>
</precice-configuration>
"""
    path = tmp_path / name
    path.write_text(xml)
    return path


def run_threads(
    config: Path, roles: dict[str, Callable[[fp.Participant], Any]], timeout: float = 30.0
) -> dict[str, Any]:
    """Run each participant's script in its own thread; return results (or exceptions)."""
    results: dict[str, Any] = {}

    def target(name: str, fn: Callable[[fp.Participant], Any]) -> None:
        try:
            results[name] = fn(fp.Participant(name, str(config), 0, 1))
        except BaseException as exc:  # reported to the test below
            results[name] = exc

    threads = [threading.Thread(target=target, args=(n, f), daemon=True) for n, f in roles.items()]
    for t in threads:
        t.start()
    deadline = time.monotonic() + timeout
    for t in threads:
        t.join(max(0.0, deadline - time.monotonic()))
    alive = [n for t, n in zip(threads, roles) if t.is_alive()]
    assert not alive, f"participants still running after {timeout} s: {alive}; {results}"
    return results


def ok(results: dict[str, Any]) -> dict[str, Any]:
    for name, value in results.items():
        if isinstance(value, BaseException):
            raise AssertionError(f"participant {name} failed") from value
    return results


def scripted(
    mesh: str,
    coords: np.ndarray,
    write: str,
    read: str,
    value: Callable[[int], np.ndarray],
    *,
    dt: float | None = None,
    rel: Callable[[float], float] | None = None,
    initial: np.ndarray | None = None,
) -> Callable[[fp.Participant], list[dict[str, Any]]]:
    """A participant loop that writes ``value(window)`` and records what it reads."""

    def body(p: fp.Participant) -> list[dict[str, Any]]:
        ids = p.set_mesh_vertices(mesh, coords)
        if p.requires_initial_data():
            assert initial is not None
            p.write_data(mesh, write, ids, initial)
        p.initialize()
        log: list[dict[str, Any]] = []
        window = 1
        while p.is_coupling_ongoing():
            if p.requires_writing_checkpoint():
                pass
            max_dt = p.get_max_time_step_size()
            step = min(dt, max_dt) if dt else max_dt
            t_read = rel(step) if rel else step
            got = p.read_data(mesh, read, ids, t_read)
            p.write_data(mesh, write, ids, value(window))
            p.advance(step)
            p.requires_reading_checkpoint()
            log.append({"window": window, "max_dt": max_dt, "read": got, "complete": None})
            log[-1]["complete"] = p.is_time_window_complete()
            if log[-1]["complete"]:
                window += 1
        p.finalize()
        return log

    return body


@pytest.fixture(autouse=True)
def raise_on_misuse(monkeypatch: pytest.MonkeyPatch) -> None:
    """These tests look at misuses as exceptions (the double's default, see MISUSE)."""
    monkeypatch.setattr(fp, "MISUSE", "raise")
    monkeypatch.delenv("GYMPRECICE_FAKE_PRECICE_MISUSE", raising=False)


@pytest.fixture
def in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Participants in this process write their logs to the working directory: keep it here."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


# --------------------------------------------------------------------------- the module


def test_module_mirrors_the_bindings_surface() -> None:
    info = fp.get_version_information()
    assert isinstance(info, bytes)
    assert info.split(b";")[0] == fp.PRECICE_VERSION.encode()
    assert fp.__version__.startswith("3.")
    assert issubclass(fp.PreciceError, RuntimeError)
    expected = {
        "initialize", "advance", "finalize", "get_mesh_dimensions", "get_data_dimensions",
        "is_coupling_ongoing", "is_time_window_complete", "get_max_time_step_size",
        "requires_initial_data", "requires_writing_checkpoint", "requires_reading_checkpoint",
        "requires_mesh_connectivity_for", "set_mesh_vertex", "get_mesh_vertex_size",
        "set_mesh_vertices", "set_mesh_edge", "set_mesh_edges", "set_mesh_triangle",
        "set_mesh_triangles", "set_mesh_quad", "set_mesh_quads", "set_mesh_tetrahedron",
        "set_mesh_tetrahedra", "reset_mesh", "write_data", "read_data", "write_and_map_data",
        "map_and_read_data", "write_gradient_data", "requires_gradient_data_for",
        "set_mesh_access_region", "get_mesh_vertex_ids_and_coordinates",
        "start_profiling_section", "stop_last_profiling_section",
    }  # fmt: skip
    public = {n for n in dir(fp.Participant) if not n.startswith("_")}
    assert public == expected


# --------------------------------------------------------------------------- construction


def test_constructor_checks_arguments_like_precice(tmp_path: Path) -> None:
    cfg = str(pair_config(tmp_path))
    with pytest.raises(RuntimeError, match="name is an empty string"):
        fp.Participant("", cfg, 0, 1)
    with pytest.raises(RuntimeError, match="needs to be smaller than the solver process size"):
        fp.Participant("A", cfg, 1, 1)
    with pytest.raises(RuntimeError, match="non-negative"):
        fp.Participant("A", cfg, -1, 1)
    with pytest.raises(RuntimeError, match="is not defined in the preCICE configuration"):
        fp.Participant("Nobody", cfg, 0, 1)
    with pytest.raises(RuntimeError, match="serial participants only"):
        fp.Participant("A", cfg, 0, 2)
    with pytest.raises(RuntimeError, match="not found"):
        fp.Participant("A", str(tmp_path / "missing.xml"), 0, 1)
    with pytest.raises(TypeError, match="Could not convert"):
        fp.Participant(3, cfg, 0, 1)  # type: ignore[arg-type]


def test_implicit_scheme_without_limit_or_measure_is_refused(tmp_path: Path) -> None:
    cfg = pair_config(tmp_path, kind="parallel-implicit", implicit="")
    with pytest.raises(RuntimeError, match="maximum iteration limit is forbidden"):
        fp.Participant("A", str(cfg), 0, 1)


def test_mesh_and_data_queries(tmp_path: Path) -> None:
    p = fp.Participant("B", str(pair_config(tmp_path)), 0, 1)
    assert p.get_mesh_dimensions("B-Mesh") == 2
    assert p.get_mesh_dimensions("A-Mesh") == 2
    assert p.get_data_dimensions("B-Mesh", "Down") == 1
    assert p.requires_mesh_connectivity_for("B-Mesh") is False
    assert p.requires_gradient_data_for("B-Mesh", "Down") is False
    with pytest.raises(RuntimeError, match='The mesh named "C-Mesh" is unknown to preCICE'):
        p.get_mesh_dimensions("C-Mesh")
    with pytest.raises(RuntimeError, match='The given data "Force" is unknown to preCICE mesh'):
        p.get_data_dimensions("B-Mesh", "Force")


def test_set_mesh_vertices_returns_int32_ids_and_checks_shapes(tmp_path: Path) -> None:
    p = fp.Participant("B", str(pair_config(tmp_path)), 0, 1)
    ids = p.set_mesh_vertices("B-Mesh", B_COORDS)
    assert ids.dtype == np.int32 and ids.tolist() == [0, 1, 2, 3]
    assert p.set_mesh_vertex("B-Mesh", [5.0, 5.0]) == 4
    assert p.get_mesh_vertex_size("B-Mesh") == 5
    assert p.set_mesh_vertices("B-Mesh", np.zeros((0, 2))).shape == (0,)
    with pytest.raises(AssertionError, match="Provided dimensions: 3, expected dimensions: 2"):
        p.set_mesh_vertices("B-Mesh", np.zeros((2, 3)))
    with pytest.raises(TypeError, match="requires array_like input"):
        p.set_mesh_vertices("B-Mesh", 3.0)
    with pytest.raises(RuntimeError, match='does not provide Mesh "A-Mesh"'):
        p.set_mesh_vertices("A-Mesh", A_COORDS)
    with pytest.raises(RuntimeError, match="initialize\\(\\) has to be called before accessing"):
        p.get_mesh_vertex_size("A-Mesh")


def test_calls_before_initialize_are_refused(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path)), 0, 1)
    ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
    with pytest.raises(RuntimeError, match=r"initialize\(\) has to be called before advance"):
        p.advance(0.01)
    with pytest.raises(RuntimeError, match=r"cannot be called before initialize"):
        p.read_data("A-Mesh", "Down", ids, 0.0)
    with pytest.raises(RuntimeError, match="before isCouplingOngoing"):
        p.is_coupling_ongoing()
    with pytest.raises(RuntimeError, match="before getMaxTimeStepSize"):
        p.get_max_time_step_size()
    with pytest.raises(RuntimeError, match="before requiresWritingCheckpoint"):
        p.requires_writing_checkpoint()
    with pytest.raises(RuntimeError, match="before isTimeWindowComplete"):
        p.is_time_window_complete()
    assert p.requires_initial_data() is False
    # Writing before initialize is allowed (it is how initial data is given).
    p.write_data("A-Mesh", "Up", ids, np.ones(3))


def test_write_data_checks(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path)), 0, 1)
    ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
    with pytest.raises(RuntimeError, match='does not use data "Down" via mesh "A-Mesh"'):
        p.write_data("A-Mesh", "Down", ids, np.ones(3))
    with pytest.raises(RuntimeError, match=r"invalid Vertex ID at vertices\[1\]"):
        p.write_data("A-Mesh", "Up", np.array([0, 7, 1]), np.ones(3))
    with pytest.raises(AssertionError, match="Vertex IDs are of incorrect length"):
        p.write_data("A-Mesh", "Up", ids, np.ones(4))
    b = fp.Participant("B", str(pair_config(tmp_path)), 0, 1)
    with pytest.raises(RuntimeError, match='does not provide Mesh "A-Mesh" nor does it enable'):
        b.write_data("A-Mesh", "Down", [0], [1.0])
    with pytest.raises(RuntimeError, match='The mesh named "B-Mesh" is unknown to preCICE'):
        p.write_data("B-Mesh", "Up", [0], [1.0])


def test_vector_data_shape_assertions(tmp_path: Path) -> None:
    cfg = case_config("fake_cylinder", tmp_path / "case")
    p = fp.Participant("Controller", str(cfg), 0, 1)
    geo = fake_cylinder_geometry()["jet1"]
    ids = p.set_mesh_vertices("Controller-Mesh-jet1", geo.coordinates)
    assert p.get_data_dimensions("Controller-Mesh-jet1", "Velocity") == 2
    with pytest.raises(AssertionError, match=r"shape \[N x D\]"):
        p.write_data("Controller-Mesh-jet1", "Velocity", ids, np.ones(len(ids)))
    with pytest.raises(AssertionError, match="Provided dimensions: 3, expected dimensions: 2"):
        p.write_data("Controller-Mesh-jet1", "Velocity", ids, np.ones((len(ids), 3)))


def test_initialize_requires_the_initial_data_promise(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path, initialize=True)), 0, 1)
    p.set_mesh_vertices("A-Mesh", A_COORDS)
    with pytest.raises(RuntimeError, match="Initial data has to be written to preCICE before"):
        p.initialize()
    assert p.requires_initial_data() is True


def test_finalize_once_and_nothing_after(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path)), 0, 1)
    ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
    p.finalize()
    with pytest.raises(RuntimeError, match=r"finalize\(\) may only be called once"):
        p.finalize()
    with pytest.raises(RuntimeError, match=r"advance\(\) cannot be called after finalize"):
        p.advance(0.01)
    with pytest.raises(RuntimeError, match=r"writeData\(...\) cannot be called after finalize"):
        p.write_data("A-Mesh", "Up", ids, np.ones(3))
    with pytest.raises(RuntimeError, match=r"initialize\(\) cannot be called after finalize"):
        p.initialize()
    with pytest.raises(RuntimeError, match="isCouplingOngoing\\(\\) cannot be called after"):
        p.is_coupling_ongoing()


def test_access_region_rules(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path, api_access=True)), 0, 1)
    with pytest.raises(RuntimeError, match="is either not a received mesh or its api access"):
        p.set_mesh_access_region("A-Mesh", [0, 1, 0, 1])
    with pytest.raises(AssertionError, match="Dimensions of bounding box"):
        p.set_mesh_access_region("B-Mesh", [0, 1])
    with pytest.raises(RuntimeError, match="ill defined"):
        p.set_mesh_access_region("B-Mesh", [1, 0, 0, 1])
    p.set_mesh_access_region("B-Mesh", [0, 1, 0, 1])
    with pytest.raises(RuntimeError, match="may only be called once per mesh"):
        p.set_mesh_access_region("B-Mesh", [0, 1, 0, 1])


def test_profiling_sections_must_be_closed(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path)), 0, 1)
    p.start_profiling_section("solve")
    with pytest.raises(RuntimeError, match="unstopped user defined events"):
        p.initialize()
    p.stop_last_profiling_section()
    with pytest.raises(RuntimeError, match="no user-started event"):
        p.stop_last_profiling_section()


def test_errors_are_logged_once_like_precice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = pair_config(tmp_path)
    cfg.write_text(cfg.read_text().replace('enabled="false"', 'enabled="true"'))
    p = fp.Participant("A", str(cfg), 0, 1)
    with pytest.raises(RuntimeError):
        p.get_mesh_dimensions("X")
    out = capsys.readouterr().out
    assert out.count('ERROR: The mesh named "X" is unknown to preCICE') == 1


def test_crash_mode_aborts_like_precice(tmp_path: Path) -> None:
    script = (
        "import sys; from gymprecice.testing import fake_precice as fp; "
        "p = fp.Participant('A', sys.argv[1], 0, 1); p.is_coupling_ongoing()"
    )
    env = {**os.environ, "GYMPRECICE_FAKE_PRECICE_MISUSE": "crash", "PYTHONFAULTHANDLER": ""}
    proc = subprocess.run(
        [sys.executable, "-c", script, str(pair_config(tmp_path))],
        capture_output=True, text=True, env=env, timeout=60,
    )  # fmt: skip
    assert proc.returncode == -signal.SIGABRT
    assert "terminate called after throwing an instance of 'precice::Error'" in proc.stderr
    assert "what():  initialize() has to be called before isCouplingOngoing()" in proc.stderr


def test_experimental_api_is_locked(tmp_path: Path) -> None:
    p = fp.Participant("A", str(pair_config(tmp_path)), 0, 1)
    with pytest.raises(RuntimeError, match="part of the experimental API"):
        p.map_and_read_data("A-Mesh", "Down", [[0.0, 0.0]], 0.0)
    with pytest.raises(RuntimeError, match="part of the experimental API"):
        p.reset_mesh("A-Mesh")


# --------------------------------------------------------------------------- coupling semantics


def test_parallel_explicit_exchanges_with_one_window_lag(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=0.05)
    res = ok(
        run_threads(
            cfg,
            {
                "A": scripted("A-Mesh", A_COORDS, "Up", "Down", lambda w: np.full(3, float(w))),
                "B": scripted("B-Mesh", B_COORDS, "Down", "Up", lambda w: np.full(4, 100.0 * w)),
            },
        )
    )
    a, b = res["A"], res["B"]
    assert [e["window"] for e in a] == [1, 2, 3, 4, 5]
    assert all(e["complete"] for e in a)
    # B reads in window k what A wrote in window k-1 (zero in window 1), and vice versa.
    assert [e["read"][0] for e in b] == [0.0, 1.0, 2.0, 3.0, 4.0]
    # A reads B's conservatively mapped values: vertex 2 of A collects B's vertices 2 and 3.
    assert a[1]["read"].tolist() == [100.0, 100.0, 200.0]
    assert a[4]["read"].tolist() == [400.0, 400.0, 800.0]
    assert a[0]["read"].shape == (3,) and a[0]["read"].dtype == np.float64


def test_serial_explicit_second_reads_current_window(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="serial-explicit", max_time=0.04)
    res = ok(
        run_threads(
            cfg,
            {
                "A": scripted("A-Mesh", A_COORDS, "Up", "Down", lambda w: np.full(3, float(w))),
                "B": scripted(
                    "B-Mesh",
                    B_COORDS,
                    "Down",
                    "Up",
                    lambda w: np.full(4, 10.0 * w),
                    rel=lambda dt: dt / 2,
                ),
            },
        )
    )
    # B (second) reads A's value of the same window; halfway through the window, linear
    # interpolation (waveform-degree 1) gives the mean of the window's start and end values.
    assert [e["read"][0] for e in res["B"]] == pytest.approx([0.5, 1.5, 2.5, 3.5], abs=1e-12)
    # A (first) reads B's previous window.
    assert [e["read"][0] for e in res["A"]] == [0.0, 10.0, 20.0, 30.0]


def test_waveform_degree_zero_reads_constant_values(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="serial-explicit", max_time=0.03, degree=0)
    res = ok(
        run_threads(
            cfg,
            {
                "A": scripted("A-Mesh", A_COORDS, "Up", "Down", lambda w: np.full(3, float(w))),
                "B": scripted(
                    "B-Mesh", B_COORDS, "Down", "Up", lambda w: np.zeros(4), rel=lambda dt: dt / 2
                ),
            },
        )
    )
    assert [e["read"][0] for e in res["B"]] == [1.0, 2.0, 3.0]


def test_subcycling_max_dt_shrinks_and_window_completes_at_its_end(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="serial-explicit", max_time=0.02)
    res = ok(
        run_threads(
            cfg,
            {
                "A": scripted("A-Mesh", A_COORDS, "Up", "Down", lambda w: np.full(3, float(w))),
                "B": scripted("B-Mesh", B_COORDS, "Down", "Up", lambda w: np.zeros(4), dt=0.004),
            },
        )
    )
    b = res["B"]
    assert [round(e["max_dt"], 12) for e in b] == [0.01, 0.006, 0.002] * 2
    assert [e["complete"] for e in b] == [False, False, True] * 2
    # Reading at the end of each substep interpolates linearly inside the window.
    reads = [round(float(e["read"][0]), 12) for e in b]
    assert reads == [0.4, 0.8, 1.0, 1.4, 1.8, 2.0]


def test_truncated_last_window_and_dt_bound(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=0.025)

    def a(p: fp.Participant) -> list[float]:
        ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        sizes = []
        while p.is_coupling_ongoing():
            dt = p.get_max_time_step_size()
            sizes.append(dt)
            with pytest.raises(RuntimeError, match="exceeds the maximum allowed time step size"):
                p.advance(dt * 1.5)
            p.write_data("A-Mesh", "Up", ids, np.ones(3))
            p.advance(dt)
        assert p.get_max_time_step_size() == 0.0
        with pytest.raises(RuntimeError, match="cannot be called when isCouplingOngoing"):
            p.advance(0.01)
        with pytest.raises(RuntimeError, match="forbidden if coupling is not ongoing"):
            p.write_data("A-Mesh", "Up", ids, np.ones(3))
        with pytest.raises(RuntimeError, match="outside of current time window"):
            p.read_data("A-Mesh", "Down", ids, 0.01)
        assert p.read_data("A-Mesh", "Down", ids, 0.0).shape == (3,)
        p.finalize()
        return sizes

    def b(p: fp.Participant) -> int:
        ids = p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        n = 0
        while p.is_coupling_ongoing():
            p.write_data("B-Mesh", "Down", ids, np.ones(4))
            p.advance(p.get_max_time_step_size())
            n += 1
        p.finalize()
        return n

    res = ok(run_threads(cfg, {"A": a, "B": b}))
    assert [round(x, 12) for x in res["A"]] == [0.01, 0.01, 0.005]
    assert res["B"] == 3


def test_dt_validation_messages(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=0.01)

    def a(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        with pytest.raises(RuntimeError, match="time step size of 0"):
            p.advance(0.0)
        with pytest.raises(RuntimeError, match="negative time step size"):
            p.advance(-0.01)
        with pytest.raises(RuntimeError, match="infinite time step size"):
            p.advance(float("inf"))
        p.write_data("A-Mesh", "Up", ids, np.ones(3))
        p.advance(0.01)
        p.finalize()

    def b(p: fp.Participant) -> None:
        p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        p.advance(0.01)
        p.finalize()

    ok(run_threads(cfg, {"A": a, "B": b}))


def test_written_data_is_reset_after_every_advance(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="serial-explicit", max_time=0.03)

    def a(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        window = 0
        while p.is_coupling_ongoing():
            window += 1
            if window != 2:  # write nothing in window 2: preCICE then sends zeros
                p.write_data("A-Mesh", "Up", ids, np.full(3, 7.0))
            p.advance(p.get_max_time_step_size())
        p.finalize()

    res = ok(
        run_threads(
            cfg,
            {"A": a, "B": scripted("B-Mesh", B_COORDS, "Down", "Up", lambda w: np.zeros(4))},
        )
    )
    assert [e["read"][0] for e in res["B"]] == [7.0, 0.0, 7.0]


def test_initial_data_reaches_the_partner_in_the_first_window(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=0.02, initialize=True)
    res = ok(
        run_threads(
            cfg,
            {
                "A": scripted(
                    "A-Mesh",
                    A_COORDS,
                    "Up",
                    "Down",
                    lambda w: np.full(3, float(w)),
                    initial=np.array([5.0, 6.0, 7.0]),
                ),
                "B": scripted("B-Mesh", B_COORDS, "Down", "Up", lambda w: np.zeros(4)),
            },
        )
    )
    # Nearest neighbours of B's vertices among A's: 0, 1, 2, 2.
    assert res["B"][0]["read"].tolist() == [5.0, 6.0, 7.0, 7.0]
    assert res["B"][1]["read"].tolist() == [1.0, 1.0, 1.0, 1.0]


def test_direct_access_with_region(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=0.02, api_access=True)

    def a(p: fp.Participant) -> tuple[Any, ...]:
        ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.set_mesh_access_region("B-Mesh", [0.5, 3.0, -1.0, 1.0])
        p.initialize()
        size = p.get_mesh_vertex_size("B-Mesh")
        b_ids, coords = p.get_mesh_vertex_ids_and_coordinates("B-Mesh")
        reads = []
        while p.is_coupling_ongoing():
            dt = p.get_max_time_step_size()
            reads.append(p.read_data("B-Mesh", "Down", b_ids, dt))
            p.write_data("A-Mesh", "Up", ids, np.ones(3))
            p.advance(dt)
        p.finalize()
        return size, b_ids, coords, reads

    def b(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        while p.is_coupling_ongoing():
            p.write_data("B-Mesh", "Down", ids, np.array([1.0, 2.0, 3.0, 4.0]))
            p.advance(p.get_max_time_step_size())
        p.finalize()

    cfg_text = cfg.read_text().replace(
        '<exchange data="Down" mesh="A-Mesh" from="B" to="A" />',
        '<exchange data="Down" mesh="A-Mesh" from="B" to="A" />'
        '<exchange data="Down" mesh="B-Mesh" from="B" to="A" />',
    )
    cfg.write_text(cfg_text)
    size, b_ids, coords, reads = ok(run_threads(cfg, {"A": a, "B": b}))["A"]
    assert size == 3  # the vertex at x=0.1 lies outside the region
    assert b_ids.dtype == np.int32 and b_ids.tolist() == [1, 2, 3]
    assert coords.tolist() == B_COORDS[1:].tolist()
    assert reads[0].tolist() == [0.0, 0.0, 0.0]
    assert reads[1].tolist() == [2.0, 3.0, 4.0]


def test_direct_access_without_region_is_refused_in_serial(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, api_access=True)

    def a(p: fp.Participant) -> None:
        p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()

    def b(p: fp.Participant) -> None:
        p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()

    res = run_threads(cfg, {"A": a, "B": b}, timeout=10)
    assert isinstance(res["A"], RuntimeError)
    assert "Did you call setMeshAccessRegion" in str(res["A"])


def test_parallel_implicit_iterates_to_max_iterations(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="parallel-implicit", max_time=0.02)
    events: dict[str, list[str]] = {"A": [], "B": []}

    def loop(name: str, mesh: str, coords: np.ndarray, write: str) -> Callable[..., None]:
        def body(p: fp.Participant) -> None:
            ids = p.set_mesh_vertices(mesh, coords)
            p.initialize()
            while p.is_coupling_ongoing():
                if p.requires_writing_checkpoint():
                    events[name].append("write")
                p.write_data(mesh, write, ids, np.ones(len(coords)))
                p.advance(p.get_max_time_step_size())
                if p.requires_reading_checkpoint():
                    events[name].append("read")
                else:
                    events[name].append("complete" if p.is_time_window_complete() else "?")
            p.finalize()

        return body

    ok(
        run_threads(
            cfg,
            {"A": loop("A", "A-Mesh", A_COORDS, "Up"), "B": loop("B", "B-Mesh", B_COORDS, "Down")},
        )
    )
    window = ["write", "read", "read", "complete"]
    assert events["A"] == window * 2
    assert events["B"] == window * 2
    log = (in_tmp / "precice-A-iterations.log").read_text().splitlines()
    assert log[0].split() == ["TimeWindow", "TotalIterations", "Iterations", "Convergence"]
    assert [row.split() for row in log[1:]] == [["1", "3", "3", "0"], ["2", "6", "3", "0"]]


def test_implicit_converges_by_relative_measure(in_tmp: Path) -> None:
    measure = (
        '<max-iterations value="10" />'
        '<relative-convergence-measure limit="1e-9" data="Down" mesh="A-Mesh" />'
    )
    cfg = pair_config(in_tmp, kind="serial-implicit", max_time=0.03, implicit=measure)
    iterations: list[int] = []

    def a(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        window = 1
        while p.is_coupling_ongoing():
            p.requires_writing_checkpoint()
            p.write_data("A-Mesh", "Up", ids, np.full(3, float(window)))
            p.advance(p.get_max_time_step_size())
            if not p.requires_reading_checkpoint():
                window += 1
        p.finalize()

    def b(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        count = 0
        while p.is_coupling_ongoing():
            p.requires_writing_checkpoint()
            up = p.read_data("B-Mesh", "Up", ids, p.get_max_time_step_size())
            p.write_data("B-Mesh", "Down", ids, up * 2.0)
            p.advance(p.get_max_time_step_size())
            count += 1
            if not p.requires_reading_checkpoint():
                iterations.append(count)
                count = 0
        p.finalize()

    ok(run_threads(cfg, {"A": a, "B": b}))
    # The answer of iteration 1 differs from last window's; iteration 2 repeats it exactly.
    assert iterations == [2, 2, 2]


def test_checkpoint_promises_are_enforced(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="parallel-implicit", max_time=0.02)

    def a(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        p.write_data("A-Mesh", "Up", ids, np.ones(3))
        with pytest.raises(RuntimeError, match="The iteration checkpoint wasn't written"):
            p.advance(0.01)

    def b(p: fp.Participant) -> None:
        ids = p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        assert p.requires_writing_checkpoint()
        p.write_data("B-Mesh", "Down", ids, np.ones(4))
        assert p.requires_reading_checkpoint() is False

    ok(run_threads(cfg, {"A": a, "B": b}, timeout=10))


def test_reading_checkpoint_must_be_acknowledged(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, kind="parallel-implicit", max_time=0.02)
    outcome: dict[str, str] = {}

    def a(p: fp.Participant) -> None:
        p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        p.requires_writing_checkpoint()
        p.advance(0.01)  # iteration 1 of 3: the window is repeated
        try:
            p.advance(0.01)  # ... but the checkpoint was never read back
        except RuntimeError as exc:
            outcome["A"] = str(exc)

    def b(p: fp.Participant) -> None:
        p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        p.requires_writing_checkpoint()
        p.advance(0.01)

    run_threads(cfg, {"A": a, "B": b}, timeout=10)
    assert "The iteration checkpoint wasn't read" in outcome["A"]


def test_max_time_windows_ends_the_coupling(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=None, windows=3)
    res = ok(
        run_threads(
            cfg,
            {
                "A": scripted("A-Mesh", A_COORDS, "Up", "Down", lambda w: np.ones(3)),
                "B": scripted("B-Mesh", B_COORDS, "Down", "Up", lambda w: np.ones(4)),
            },
        )
    )
    assert len(res["A"]) == len(res["B"]) == 3


def test_leftover_address_file_is_reported(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp)
    stale = in_tmp / "exchange" / "precice-run" / "A-B" / "fake-precice.address"
    stale.parent.mkdir(parents=True)
    stale.write_text("/nowhere\n")
    p = fp.Participant("A", str(cfg), 0, 1)
    p.set_mesh_vertices("A-Mesh", A_COORDS)
    with pytest.raises(RuntimeError, match="connection file already exists"):
        p.initialize()


def test_exchange_directory_is_relative_to_the_working_directory(in_tmp: Path) -> None:
    cfg = pair_config(in_tmp, max_time=0.01)
    cfg.write_text(cfg.read_text().replace(str(in_tmp / "exchange"), "relative-exchange"))
    seen: list[bool] = []

    def a(p: fp.Participant) -> None:
        p.set_mesh_vertices("A-Mesh", A_COORDS)
        p.initialize()
        seen.append((in_tmp / "relative-exchange" / "precice-run" / "A-B").is_dir())
        p.advance(0.01)
        p.finalize()

    def b(p: fp.Participant) -> None:
        p.set_mesh_vertices("B-Mesh", B_COORDS)
        p.initialize()
        p.advance(0.01)
        p.finalize()

    ok(run_threads(cfg, {"A": a, "B": b}))
    assert seen == [True]


# --------------------------------------------------------------------------- separate processes


def _env() -> dict[str, str]:
    # Partners need not register gymnasium environments; skipping plugins speeds up start-up.
    return {**os.environ, "GYMPRECICE_DISABLE_PLUGINS": "1"}


class Processes:
    """Partner processes of one test, each in its own session, killed at teardown."""

    def __init__(self, cwd: Path) -> None:
        self.cwd = cwd
        self.procs: list[subprocess.Popen[bytes]] = []

    def start(
        self, argv: list[str], log: str, env: dict[str, str] | None = None
    ) -> subprocess.Popen[bytes]:
        out = (self.cwd / f"{log}.out").open("wb")
        err = (self.cwd / f"{log}.err").open("wb")
        proc = subprocess.Popen(
            argv,
            cwd=self.cwd,
            stdout=out,
            stderr=err,
            env={**_env(), **(env or {})},
            start_new_session=True,
        )
        out.close()
        err.close()
        self.procs.append(proc)
        return proc

    def log(self, name: str) -> str:
        return (self.cwd / f"{name}.out").read_text()

    def err(self, name: str) -> str:
        return (self.cwd / f"{name}.err").read_text()

    def kill_all(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(10)


@pytest.fixture
def procs(tmp_path: Path) -> Iterator[Processes]:
    p = Processes(tmp_path)
    yield p
    p.kill_all()


def _controller_run(config: Path, implicit: bool = False) -> dict[str, Any]:
    """Play the gymprecice Controller in this process against a partner Fluid process."""
    p = fp.Participant("Controller", str(config), 0, 1)
    geometry = fake_cylinder_geometry()
    ids = {
        jet: p.set_mesh_vertices(f"Controller-Mesh-{jet}", g.coordinates)
        for jet, g in geometry.items()
    }
    p.set_mesh_access_region("Fluid-Mesh-cylinder", [-1.0, 1.0, -1.0, 1.0])
    p.initialize()
    p_ids, p_coords = p.get_mesh_vertex_ids_and_coordinates("Fluid-Mesh-cylinder")
    windows, iterations, pressures = 0, 0, []
    while p.is_coupling_ongoing():
        if implicit:
            p.requires_writing_checkpoint()
        dt = p.get_max_time_step_size()
        pressures.append(p.read_data("Fluid-Mesh-cylinder", "Pressure", p_ids, dt))
        q = 2.0 if windows >= 3 else 0.0  # blow hard from window 4 on
        for jet, g in geometry.items():
            sign = 1.0 if jet == "jet1" else -1.0
            velocity = sign * q * g.normals[:, :2]
            p.write_data(f"Controller-Mesh-{jet}", "Velocity", ids[jet], velocity)
        p.advance(dt)
        iterations += 1
        if implicit and p.requires_reading_checkpoint():
            continue
        windows += 1
    p.finalize()
    return {"windows": windows, "iterations": iterations, "pressures": pressures,
            "coords": p_coords}  # fmt: skip


def test_explicit_run_to_max_time_with_partner_process(
    tmp_path: Path, procs: Processes, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    cfg = case_config("fake_cylinder", tmp_path, max_time=0.1, exchange_directory=tmp_path)
    fluid = procs.start(partner_command(cfg, "Fluid"), "fluid")
    out = _controller_run(cfg)
    assert fluid.wait(30) == 0, procs.err("fluid")
    assert out["windows"] == 10
    lines = [ln for ln in procs.log("fluid").splitlines() if ln.startswith("[Fluid] window")]
    assert len(lines) == 10
    assert out["coords"].shape == (32, 2)
    # The partner's pressure responds to the jets: the wake amplitude decays once they blow.
    amplitude = [float(np.ptp(p)) for p in out["pressures"]]
    assert amplitude[0] == 0.0  # nothing received yet in the first window
    assert amplitude[-1] < amplitude[3]


def test_implicit_run_to_max_time_with_partner_process(
    tmp_path: Path, procs: Processes, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    cfg = case_config(
        "fake_cylinder", tmp_path, variant="implicit", max_time=0.05, exchange_directory=tmp_path
    )
    fluid = procs.start(partner_command(cfg, "Fluid"), "fluid")
    out = _controller_run(cfg, implicit=True)
    assert fluid.wait(30) == 0, procs.err("fluid")
    assert out["windows"] == 5
    # Each window needs at least two iterations (the second confirms the first).
    assert out["iterations"] >= 10
    assert (tmp_path / "precice-Controller-iterations.log").is_file()


@pytest.mark.parametrize("variant", [None, "compositional"])
def test_fsi_three_participants(tmp_path: Path, procs: Processes, variant: str | None) -> None:
    cfg = case_config("fake_flap", tmp_path, variant=variant, max_time=0.05)
    flows = {
        "Controller": "gymprecice.testing.flows:JetController",
        "Fluid": "gymprecice.testing.flows:FlapFluid",
        "Solid": "gymprecice.testing.flows:FlapSolid",
    }
    options = {"Controller": {"frequency": 0, "amplitude": 0.5}}
    started = {
        name: procs.start(
            partner_command(cfg, name, flow=flow, options=options.get(name)), name.lower()
        )
        for name, flow in flows.items()
    }
    for name, proc in started.items():
        assert proc.wait(60) == 0, procs.err(name.lower())
        windows = [ln for ln in procs.log(name.lower()).splitlines() if "] window " in ln]
        assert len(windows) == 5, procs.log(name.lower())
    # Implicit iterations happened between Fluid and Solid (more steps than windows) ...
    last_solid = next(ln for ln in procs.log("solid").splitlines() if " window 5 " in ln)
    assert int(last_solid.split("steps=")[1].split()[0]) > 5
    # ... and the Controller iterates only in the multi scheme.
    last_ctrl = next(ln for ln in procs.log("controller").splitlines() if " window 5 " in ln)
    ctrl_steps = int(last_ctrl.split("steps=")[1].split()[0])
    assert (ctrl_steps > 5) if variant is None else (ctrl_steps == 5)
    # At convergence both sides agree on the force: F = f0 (1 + u_in) - k_fb d with d = F
    # and the Controller's constant inlet velocity u_in = 0.5 mapped onto the inlet.
    last_fluid = next(ln for ln in procs.log("fluid").splitlines() if " window 5 " in ln)
    force_fluid = float(last_fluid.split(" F=")[1].split()[0])
    force_solid = float(last_solid.split(" F=")[1].split()[0])
    assert force_fluid == pytest.approx(force_solid, rel=1e-3)
    assert 1.0 < force_fluid < 1.5
    tip = (tmp_path / "precice-Solid-watchpoint-Flap-Tip.log").read_text().splitlines()
    assert tip[0].split()[:3] == ["Time", "Coordinate0", "Coordinate1"]
    assert len(tip) == 1 + 6  # header, t=0 and one row per window


def _alive_after(proc: subprocess.Popen[bytes], seconds: float) -> bool:
    time.sleep(seconds)
    return proc.poll() is None


@pytest.mark.parametrize("death", ["sigkill", "exit1", "sigstop"])
def test_survivor_blocks_forever_when_partner_dies(
    tmp_path: Path, procs: Processes, death: str
) -> None:
    """With ``PARTNER_LOSS=hang`` the double waits as preCICE 3.4.1 does: forever."""
    cfg = case_config("fake_cylinder", tmp_path, max_time=10.0)
    ctrl = procs.start(
        partner_command(cfg, "Controller", flow="gymprecice.testing.flows:JetController"),
        "controller",
        env={"GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS": "hang"},
    )
    flags: dict[str, Any] = {}
    if death == "sigkill":
        flags = {"crash_at_window": 3}
    elif death == "exit1":
        flags = {"crash_at_window": 3, "exit_code": 1}
    fluid = procs.start(partner_command(cfg, "Fluid", **flags), "fluid")
    if death == "sigstop":
        deadline = time.monotonic() + 30
        while "window 3 " not in procs.log("fluid") and time.monotonic() < deadline:
            time.sleep(0.05)
        os.killpg(fluid.pid, signal.SIGSTOP)
        time.sleep(0.2)
    else:
        rc = fluid.wait(30)
        assert rc == (-signal.SIGKILL if death == "sigkill" else 1)
    fluid_windows = procs.log("fluid").count("[Fluid] window ")
    assert fluid_windows >= 3
    if death == "exit1":
        assert "FOAM FATAL ERROR" in procs.err("fluid")
    time.sleep(0.5)
    size = len(procs.log("controller"))
    assert _alive_after(ctrl, 1.0), procs.err("controller")
    assert len(procs.log("controller")) == size  # blocked: no progress, no error
    assert "Error" not in procs.err("controller")
    # The controller got at most one window ahead of its partner, then stopped for good.
    windows = procs.log("controller").count("[Controller] window ")
    assert fluid_windows <= windows <= fluid_windows + 1
    if death == "sigstop":
        os.killpg(fluid.pid, signal.SIGCONT)
    os.killpg(ctrl.pid, signal.SIGKILL)
    assert ctrl.wait(10) == -signal.SIGKILL


def test_a_solver_left_alone_gives_up_when_its_controller_is_killed(
    tmp_path: Path, procs: Processes
) -> None:
    """The controller is SIGKILLed mid-run (an env killed with its job): the solver on the
    double waits its ``PARTNER_LOSS`` seconds, then ends non-zero with preCICE's message,
    instead of waiting for hours. Cost: about 6 s (the default 5 s wait)."""
    cfg = case_config("fake_cylinder", tmp_path, max_time=10.0)
    flow = "gymprecice.testing.flows:JetController"
    ctrl = procs.start(partner_command(cfg, "Controller", flow=flow, crash_at_window=3), "ctrl")
    fluid = procs.start(partner_command(cfg, "Fluid"), "fluid")
    assert ctrl.wait(60) == -signal.SIGKILL
    killed = time.monotonic()
    status = fluid.wait(30)  # fails the test (TimeoutExpired) where it would wait on
    waited = time.monotonic() - killed
    assert status == 1, procs.err("fluid")
    assert 3.0 < waited < 30.0  # it waited, as preCICE does, before it gave up
    said = procs.log("fluid") + procs.err("fluid")
    assert '"Controller" (using sockets) failed' in said
    assert "This often means that the other participant exited" in said
    assert "ERROR:" in procs.log("fluid")  # logged as preCICE logs an error


def test_partner_loss_setting_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    from gymprecice.testing.fake_precice.errors import partner_loss_wait

    for text, seconds in (("hang", None), ("0.5", 0.5), ("0", 0.0)):
        monkeypatch.setattr(fp, "PARTNER_LOSS", text)
        assert partner_loss_wait() == seconds
    monkeypatch.setattr(fp, "PARTNER_LOSS", "soon")
    with pytest.raises(fp.PreciceError, match="GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS='soon'"):
        partner_loss_wait()


def test_config_mismatch_between_participants_is_reported(
    tmp_path: Path, procs: Processes, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    cfg = pair_config(tmp_path)
    other = pair_config(tmp_path, max_time=0.07, name="other.xml")
    procs.start(partner_command(other, "B", flow="gymprecice.testing.flows:NullFlow"), "b")
    p = fp.Participant("A", str(cfg), 0, 1)
    p.set_mesh_vertices("A-Mesh", A_COORDS)
    with pytest.raises(RuntimeError, match="uses a different configuration file"):
        p.initialize()


def test_connector_waits_without_timeout_for_the_acceptor(
    tmp_path: Path, procs: Processes, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    cfg = pair_config(tmp_path, max_time=0.02)
    b = procs.start(partner_command(cfg, "B", flow="gymprecice.testing.flows:NullFlow"), "b")
    assert _alive_after(b, 1.5)  # still waiting for A's address, as preCICE would
    res = scripted("A-Mesh", A_COORDS, "Up", "Down", lambda w: np.ones(3))(
        fp.Participant("A", str(cfg), 0, 1)
    )
    assert len(res) == 2
    assert b.wait(30) == 0, procs.err("b")


def test_an_acceptor_killed_while_it_waits_leaves_nothing_in_the_temporary_directory(
    tmp_path: Path, procs: Processes, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A participant killed before its partner came (a crashed or stopped run) leaves no
    socket file behind: a day of such runs must not fill ``/tmp``."""
    monkeypatch.chdir(tmp_path)
    cfg = pair_config(tmp_path, max_time=0.02)
    temp = Path(tempfile.mkdtemp(prefix="fp-", dir="/tmp"))  # short enough for a socket file
    try:
        a = procs.start(
            partner_command(cfg, "A", flow="gymprecice.testing.flows:NullFlow"),
            "a",
            env={"TMPDIR": str(temp)},
        )
        address = tmp_path / "exchange" / "precice-run" / "A-B" / "fake-precice.address"
        deadline = time.monotonic() + 30
        while not address.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert address.exists(), procs.err("a")
        os.killpg(a.pid, signal.SIGKILL)
        a.wait(10)
        assert list(temp.iterdir()) == []
    finally:
        shutil.rmtree(temp, ignore_errors=True)


def test_real_precice_acceptor_is_detected(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    cfg = pair_config(tmp_path)
    # What real preCICE leaves: precice-run/<acceptor>-<connector>/<2 hex>/<hash>.
    real = tmp_path / "exchange" / "precice-run" / "A-B" / "a3" / "f00d"
    real.parent.mkdir(parents=True)
    real.write_text("127.0.0.1:50000\n")
    p = fp.Participant("B", str(cfg), 0, 1)
    p.set_mesh_vertices("B-Mesh", B_COORDS)
    with pytest.raises(RuntimeError, match="real preCICE"):
        p.initialize()


def test_shipped_cases_load(tmp_path: Path) -> None:
    names = sorted(p.relative_to(CASES_DIR).as_posix() for p in CASES_DIR.rglob("*.xml"))
    assert names == [
        "fake_cylinder/precice-config-implicit.xml",
        "fake_cylinder/precice-config.xml",
        "fake_flap/precice-config-compositional.xml",
        "fake_flap/precice-config.xml",
    ]
    for name in names:
        for participant in ("Controller", "Fluid"):
            fp.Participant(participant, str(CASES_DIR / name), 0, 1).finalize()


def test_partner_command_runs_this_interpreter(tmp_path: Path) -> None:
    argv = partner_command(tmp_path / "c.xml", "Fluid", crash_at_window=2, step_sleep=0.01)
    assert argv[:3] == [sys.executable, "-m", "gymprecice.testing.partner"]
    assert argv[argv.index("--crash-at-window") + 1] == "2"
    assert argv[argv.index("--step-sleep") + 1] == "0.01"
