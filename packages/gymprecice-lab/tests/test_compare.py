"""``gymprecice compare``: margins of an evaluated controller over the uncontrolled flow, the
best constant and the best sinusoid, from the files other commands write."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from gymprecice_lab.rollouts.compare import Controller, margin

ENV_ID = "gymprecice/PerpendicularFlapFast-v0"


def _manifest(run: Path, command: str, seed: int = 0, env_id: str = ENV_ID) -> None:
    run.mkdir(parents=True)
    manifest = {"command": command, "seeds": {"seed": seed}, "settings": {"env_id": env_id}}
    (run / "manifest.json").write_text(json.dumps(manifest))


def _sweep(run: Path, rows: list[tuple[str, str, list[float]]], **kw) -> Path:
    _manifest(run, "sweep", **kw)
    with (run / "sweep.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["label", "kind", "start_0", "start_1", "start_2", "mean"])
        for label, kind, values in rows:
            writer.writerow([label, kind, *values, sum(values) / 3])
    return run


def _evaluated(run: Path, values: list[float], **kw) -> Path:
    _manifest(run, "evaluate", **kw)
    episodes = [{"mean_mean_tip_displacement": v, "return": -30 * v, "steps": 30} for v in values]
    (run / "summary.json").write_text(json.dumps({"episodes": episodes}))
    return run


def _compare(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", "compare", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_margins_against_the_best_of_pooled_sweeps(tmp_path: Path) -> None:
    _sweep(
        tmp_path / "sweep",
        [
            ("uncontrolled", "uncontrolled", [0.08, 0.06, 0.04]),
            ("constant-1", "constant", [0.09, 0.07, 0.05]),
            ("constant-3", "constant", [0.06, 0.05, 0.02]),
            ("sine-a", "sinusoid", [0.07, 0.05, 0.04]),
        ],
    )
    _sweep(tmp_path / "sweep-top", [("sine-b", "sinusoid", [0.06, 0.04, 0.03])])
    _evaluated(tmp_path / "evaluate", [0.03, 0.025, 0.015])
    proc = _compare(tmp_path, "sweep", "sweep-top", "evaluate", "--out", "cmp")
    assert proc.returncode == 0, proc.stderr
    record = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    margins = record["controllers"]["evaluate"]["margins"]
    assert margins["best constant"]["reference"] == "constant-3"
    assert margins["best sinusoid"]["reference"] == "sine-b"  # the best of both sweeps
    assert margins["uncontrolled"]["per_start_percent"] == pytest.approx([62.5, 58.33, 62.5], 1e-3)
    assert all(m["clear"] for m in margins.values())
    assert "| best constant: constant-3 |" in (tmp_path / "cmp" / "compare.md").read_text()


def test_a_margin_is_clear_only_above_its_spread_and_positive_on_every_start() -> None:
    ref = Controller("ref", "constant", (0.1, 0.1, 0.1))
    assert margin(Controller("x", "run", (0.05, 0.05, 0.05)), ref).clear
    assert not margin(Controller("y", "run", (0.05, 0.05, 0.11)), ref).clear  # worse on one
    assert not margin(Controller("z", "run", (0.01, 0.099, 0.099)), ref).clear  # spread > mean


@pytest.mark.parametrize(
    ("seed", "env_id", "message"),
    [
        (1, ENV_ID, "different seeds"),
        (0, "gymprecice/Quickstart-v0", "different envs"),
    ],
)
def test_runs_from_other_starts_or_envs_are_refused(tmp_path: Path, seed, env_id, message):
    _sweep(tmp_path / "sweep", [("uncontrolled", "uncontrolled", [0.08, 0.06, 0.04])])
    _evaluated(tmp_path / "evaluate", [0.03, 0.025, 0.015], seed=seed, env_id=env_id)
    proc = _compare(tmp_path, "sweep", "evaluate")
    assert proc.returncode != 0 and message in proc.stderr, proc.stderr


def test_a_directory_that_no_command_wrote_is_refused(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    proc = _compare(tmp_path, "empty")
    assert proc.returncode != 0 and "not the output of a gymprecice command" in proc.stderr
