"""``gymprecice time-to-floor`` on the test double: the first checkpoint reaching each
fraction of the drag floor and its wall-clock; the median over runs with an interval that
stays open when a run never reached; bad input refused with the fix."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from gymprecice.plugin.card import Reference
from gymprecice_lab.benchmarking.time_to_floor import checkpoints, median_time
from gymprecice_lab.rollouts.evaluate import floor_metrics
from gymprecice_tutorials.environments import FAST_CYLINDER_FLOOR


def _cli(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny training run on the double with a checkpoint every 8 steps."""
    cwd = tmp_path_factory.mktemp("ttf")
    proc = _cli(
        cwd,
        "train",
        "jet-cylinder-fast",
        "--double",
        "--timesteps",
        "16",
        "--n-steps",
        "8",
        "--batch-size",
        "8",
        "--net",
        "8,8",
        "--vec-env",
        "dummy",
        "--episode-time",
        "0.1",
        "--checkpoint-every",
        "8",
        "--no-progress-bar",
        "--out",
        "run",
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return cwd / "run"


def test_the_training_command_records_when_it_started_and_checkpoints_are_timed_from_it(
    run: Path,
) -> None:
    manifest = json.loads((run / "manifest.json").read_text())
    started = manifest["segments"][0]["started_at"]
    assert manifest["segments"][0]["finished_at"] > started
    found = checkpoints(run)
    assert [c.steps for c in found] == [8, 16]
    for c in found:
        assert c.seconds == pytest.approx(c.model.stat().st_mtime - started)
        assert 0 < c.seconds < 600


def _scan(run: Path, *flags: str) -> dict:
    """``gymprecice time-to-floor RUN`` on the double, 2.2 s evaluations, into ``scan``."""
    proc = _cli(run.parent, "time-to-floor", str(run), "--double", "--eval-time", "2.2", *flags)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    result = json.loads((run.parent / "scan/time_to_floor.json").read_text())
    return {"stdout": proc.stdout, "run": result["runs"][0]}


@pytest.mark.timeout(600)
def test_the_scan_stops_at_the_first_checkpoint_reaching_the_highest_fraction(run: Path) -> None:
    # the double's scripted flow takes about 4 % of the floor whatever the policy does:
    # 3 % is reached by the first checkpoint, 90 % never
    scan = _scan(run, "--model", "checkpoints", "--fractions", "0.03", "--out", "scan")
    assert "run: 3% of the floor: checkpoint 8 steps" in scan["stdout"]
    rows = scan["run"]["checkpoints"]
    assert [r["steps"] for r in rows] == [8]  # the scan stopped there
    assert scan["run"]["reached"]["0.03"]["steps"] == 8
    assert 0.03 <= rows[0]["settled_floor_fraction"] < 0.9
    assert len(rows[0]["per_start"]) == 2  # every held-out start

    # 90 % and 95 %: every checkpoint, none reaching
    scan = _scan(run, "--model", "checkpoints", "--out", "scan")
    assert "90% of the floor: not within its 16 steps" in scan["stdout"]
    assert [r["steps"] for r in scan["run"]["checkpoints"]] == [8, 16]
    assert scan["run"]["reached"]["0.9"] is None


def test_bad_input_is_refused_with_the_fix(run: Path, gymprecice_refused) -> None:
    status, err = gymprecice_refused(
        run.parent, "time-to-floor", str(run), "--env", "quickstart", "--double"
    )
    assert status == 2
    assert "needs the lab card field 'reference' of gymprecice/Quickstart-v0" in err
    status, err = gymprecice_refused(
        run.parent, "time-to-floor", str(run), "--double", "--eval-time", "1"
    )
    assert status == 2 and "leaves no settled flow" in err
    empty = run.parent / "empty"
    empty.mkdir()
    status, err = gymprecice_refused(run.parent, "time-to-floor", str(empty), "--double")
    assert status == 2 and "not a training run" in err


def test_the_median_over_runs_has_an_interval_that_stays_open_for_runs_never_reaching() -> None:
    all_reached = median_time([300.0, 420.0, 360.0, 600.0, 390.0], reps=500)
    assert all_reached["median"] == 390.0
    assert all_reached["low"] <= 390.0 <= all_reached["high"] < math.inf
    censored = median_time([300.0, math.inf, 360.0, math.inf, 390.0], reps=500)
    assert censored["median"] == 390.0 and censored["not_reached"] == 2
    assert censored["high"] == math.inf  # resamples with a majority never reaching
    assert median_time([math.inf, math.inf, 300.0])["median"] == math.inf


def test_floor_metrics_take_the_settled_drag_after_the_transient() -> None:
    floor = Reference(metric="Cd", uncontrolled=3.0, floor=2.0, settle_time=2.0)
    t0 = 5.0
    rows = [(0, t0 + 0.5 * k, 3.0 if k < 4 else 2.2, 0.0) for k in range(1, 9)]
    metrics = floor_metrics(rows, t0, floor)
    # times 5.5 .. 9.0: settled from 7.0 on, where Cd is 2.2
    assert metrics["series_settled_mean_Cd"] == pytest.approx(2.2)
    assert metrics["settled_floor_fraction"] == pytest.approx(0.8)
    assert metrics["floor_fraction"] == pytest.approx((3.0 - (3 * 3.0 + 5 * 2.2) / 8) / 1.0)
    assert floor_metrics([], t0, floor) == {}
    assert FAST_CYLINDER_FLOOR.fraction(FAST_CYLINDER_FLOOR.floor) == pytest.approx(1.0)


def test_a_wrapper_passes_the_typed_command_start_and_nonsense_is_ignored(monkeypatch) -> None:
    import time

    from gymprecice_lab.training.segments import command_started_at

    monkeypatch.setenv("GYMPRECICE_STARTED_AT", str(time.time() - 30))
    assert time.time() - command_started_at() == pytest.approx(30, abs=5)
    for nonsense in ("", "soon", str(time.time() + 3600), "-1"):
        monkeypatch.setenv("GYMPRECICE_STARTED_AT", nonsense)
        assert abs(command_started_at() - time.time()) < 5
