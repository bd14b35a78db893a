"""The suite's own rules (conftest.py, scripts/suite_report.py): its two tiers are the whole
suite, each session records its durations, a real-stack test states its cost, and a suite
over its budget fails naming its slowest tests. Each test runs pytest on a small sample."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import suite_report  # noqa: E402

SAMPLE = '''
import os
import pytest

@pytest.mark.precice
def test_real():
    """Cost: nothing (a sample)."""

@pytest.mark.slow
def test_slow():
    pass

def test_plain():
    # a session's settings are not handed down to a pytest run inside a test
    assert "GYMPRECICE_DURATIONS" not in os.environ
    assert "GYMPRECICE_TIER" not in os.environ

def test_needs_the_stack():
    if not os.path.exists("stack-built"):
        pytest.skip("the stack is not built yet")

@pytest.fixture
def ray_cluster():
    return "a cluster"

def test_on_a_cluster(ray_cluster):
    pass

@pytest.mark.slow
@pytest.mark.waits
def test_waiting():
    pass
'''

NO_COST = '''
import pytest

@pytest.mark.openfoam
def test_real_without_cost():
    """Runs something expensive, but does not say how expensive."""

@pytest.mark.openfoam
class TestShared:
    """A class of tests sharing one case.

    Cost: about 10 s in all (a sample).
    """

    def test_one(self):
        pass
'''


def _pytest(
    tmp_path: Path, source: str, *args: str, **env: str
) -> subprocess.CompletedProcess[str]:
    shutil.copy(ROOT / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_sample.py").write_text(source)
    (tmp_path / "pytest.ini").write_text(
        "[pytest]\nmarkers =\n    precice: real preCICE\n    openfoam: OpenFOAM\n    slow: slow\n    waits: waits\n"
    )
    clean = {k: v for k, v in os.environ.items() if not k.startswith("GYMPRECICE_")}
    plugins = list(args) or ["-p", "no:xdist"]
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *plugins],
        cwd=tmp_path,
        env={**clean, **env},
        capture_output=True,
        text=True,
        timeout=120,
    )


def _names(durations: Path) -> list[str]:
    return sorted(t["nodeid"].split("::")[-1] for t in json.loads(durations.read_text())["tests"])


def test_the_fast_tier_and_the_rest_are_the_whole_suite(tmp_path: Path) -> None:
    skipped = tmp_path / "out" / "skipped.txt"
    fast = _pytest(
        tmp_path,
        SAMPLE,
        GYMPRECICE_TIER="fast",
        GYMPRECICE_TIER_SKIPPED=str(skipped),
        GYMPRECICE_DURATIONS=str(tmp_path / "out" / "fast.json"),
    )
    assert fast.returncode == 0, fast.stdout
    assert _names(tmp_path / "out" / "fast.json") == ["test_needs_the_stack", "test_plain"]
    assert skipped.read_text() == "test_sample.py::test_needs_the_stack\n"

    (tmp_path / "stack-built").touch()  # the stack is built between the two tiers
    rest = _pytest(
        tmp_path,
        SAMPLE,
        GYMPRECICE_TIER="rest",
        GYMPRECICE_TIER_SKIPPED=str(skipped),
        GYMPRECICE_DURATIONS=str(tmp_path / "out" / "rest.json"),
    )
    assert rest.returncode == 0 and "5 passed" in rest.stdout, rest.stdout
    assert _names(tmp_path / "out" / "rest.json") == [
        "test_needs_the_stack",  # skipped in the fast tier, run again
        "test_on_a_cluster",
        "test_real",
        "test_slow",
        "test_waiting",
    ]
    data = json.loads((tmp_path / "out" / "rest.json").read_text())
    assert data["tier"] == "rest" and data["wall_s"] > 0 and data["started_at"] > 0
    assert all(t["seconds"] >= 0 and t["cpu_s"] >= 0 for t in data["tests"])

    # the rest's two parts, which scripts/test.sh runs side by side, are the rest
    parts = {}
    for part in ("waiting", "local"):
        run = _pytest(
            tmp_path,
            SAMPLE,
            GYMPRECICE_TIER=part,
            GYMPRECICE_TIER_SKIPPED=str(skipped),
            GYMPRECICE_DURATIONS=str(tmp_path / "out" / f"{part}.json"),
        )
        assert run.returncode == 0, run.stdout
        parts[part] = _names(tmp_path / "out" / f"{part}.json")
    assert parts["waiting"] == ["test_on_a_cluster", "test_waiting"]
    assert parts["local"] == ["test_needs_the_stack", "test_real", "test_slow"]


def test_an_unknown_tier_is_refused(tmp_path: Path) -> None:
    run = _pytest(tmp_path, SAMPLE, GYMPRECICE_TIER="slowest")
    assert run.returncode != 0
    assert "GYMPRECICE_TIER='slowest': use fast, rest" in run.stdout + run.stderr


def test_sessions_side_by_side_count_once_in_the_suite_s_time() -> None:
    sessions = [
        {**_session("fast", 100.0, {"t.py::quick": 1.0}), "started_at": 0.0},
        {**_session("local", 300.0, {"t.py::solver": 250.0}), "started_at": 150.0},
        {**_session("waiting", 200.0, {"t.py::cluster": 190.0}), "started_at": 150.0},
    ]
    assert suite_report.suite_wall(sessions) == 400.0  # 100, a pause of 50, then 300
    text, inside = suite_report.report(sessions, budget=450.0)
    assert inside and "6 min 40 s (budget 7 min 30 s) (10 min 00 s of sessions" in text
    del sessions[0]["started_at"]  # an older file: taken as one after another
    assert suite_report.suite_wall(sessions) == 600.0


def test_a_real_test_that_does_not_state_its_cost_fails(tmp_path: Path) -> None:
    run = _pytest(tmp_path, NO_COST)
    assert run.returncode == 1 and "1 failed, 1 passed" in run.stdout, run.stdout
    assert "test_real_without_cost" in run.stdout
    assert "does not state its cost" in run.stdout and "Cost: about" in run.stdout


SOLVERS = """
import time
import pytest

@pytest.fixture(scope="module")
def shared():
    return object()

@pytest.mark.openfoam
@pytest.mark.parametrize("case", range(4))
def test_solver(case):
    \"\"\"Cost: 0.5 s (a sample).\"\"\"
    time.sleep(0.5)

@pytest.mark.parametrize("case", range(4))
def test_fixture(shared, case):
    time.sleep(0.1)
"""


def test_two_workers_share_the_solver_tests_and_keep_a_module_fixture_on_one(
    tmp_path: Path,
) -> None:
    """The real solvers' tests go to whichever worker is free (a coupled run keeps about one
    core busy); the tests that share a module-wide fixture stay on one worker."""
    pytest.importorskip("xdist", reason="pytest-xdist (scripts/setup.sh installs it)")
    out = tmp_path / "out.json"
    run = _pytest(
        tmp_path, SOLVERS, "-n", "2", "--dist", "loadgroup", GYMPRECICE_DURATIONS=str(out)
    )
    assert run.returncode == 0 and "8 passed" in run.stdout, run.stdout
    tests = json.loads(out.read_text())["tests"]
    assert all("@" not in t["nodeid"] for t in tests)  # xdist's group suffix is taken off
    solvers = {t["worker"] for t in tests if "test_solver" in t["nodeid"]}
    sharing = {t["worker"] for t in tests if "test_fixture" in t["nodeid"]}
    assert solvers == {"gw0", "gw1"}
    assert len(sharing) == 1 and sharing <= {"gw0", "gw1"}


def _session(tier: str, wall: float, tests: dict[str, float]) -> dict:
    rows = [{"nodeid": n, "seconds": s, "cpu_s": s / 2} for n, s in tests.items()]
    return {"tier": tier, "wall_s": wall, "tests": rows}


def test_the_report_fails_a_suite_over_its_budget_naming_the_slowest(tmp_path: Path) -> None:
    sessions = [
        _session("fast", 100.0, {"t.py::quick": 1.0}),
        _session("rest", 500.0, {"t.py::solver": 300.0, "t.py::medium": 20.0}),
    ]
    text, inside = suite_report.report(sessions, budget=550.0, setup_times="apt 90 s")
    assert not inside
    lines = text.splitlines()
    assert "apt 90 s" in lines
    assert any(line.split()[:3] == ["suite", "10", "min"] for line in lines)
    slowest = [line.split()[-1] for line in lines if line.startswith("  ") and "::" in line]
    assert slowest == ["t.py::solver", "t.py::medium", "t.py::quick"]
    assert "FAILED: the test suite took 10 min 00 s, over its budget of 9 min 10 s" in text

    for path, session in zip(("a.json", "b.json"), sessions):
        (tmp_path / path).write_text(json.dumps(session))
    files = [str(tmp_path / "a.json"), str(tmp_path / "b.json")]
    assert suite_report.main([*files, "--budget", "550"]) == 1
    assert suite_report.main([*files, "--budget", "600"]) == 0
