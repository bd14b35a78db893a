"""A resumed run's training time: its segments summed, the gaps between them left out
(what time-to-floor and the kept model's record report)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from gymprecice_lab.benchmarking.time_to_floor import candidates, checkpoints
from gymprecice_lab.common.kept_model import kept_summary
from gymprecice_lab.common.training_clock import training_seconds

# a run trained 100 s, stopped, resumed 3,900 s later and still running
SEGMENTS = [
    {"started_at": 1000.0, "finished_at": 1100.0, "result": {"seconds": 80.0}},
    {"started_at": 5000.0, "finished_at": None, "result": None},
]


def test_the_gap_between_segments_is_not_training() -> None:
    assert training_seconds(SEGMENTS, 1050.0) == 50.0
    assert training_seconds(SEGMENTS, 5030.0) == 130.0
    # the current segment's start: everything before it, whole
    assert training_seconds(SEGMENTS, 5000.0) == 100.0
    assert training_seconds([], 5000.0) is None


def test_older_and_killed_segments_are_bounded() -> None:
    # a manifest written before ``finished_at``: the learning seconds (a lower bound)
    older = [{"started_at": 1000.0, "result": {"seconds": 80.0}}, {"started_at": 5000.0}]
    assert training_seconds(older, 5010.0) == 90.0
    # a segment killed before it wrote anything: up to the next start (an upper bound)
    killed = [{"started_at": 1000.0, "result": None}, {"started_at": 1300.0}]
    assert training_seconds(killed, 1310.0) == 310.0


def _run(tmp_path: Path) -> Path:
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    (run / "eval").mkdir()
    (run / "manifest.json").write_text(json.dumps({"segments": SEGMENTS}))
    for steps, saved in ((8, 1050.0), (16, 5030.0)):
        path = run / "checkpoints" / f"sac_{steps}_steps.zip"
        path.write_bytes(b"model")
        os.utime(path, (saved, saved))
    return run


def test_time_to_floor_times_checkpoints_and_the_kept_model_by_training(tmp_path) -> None:
    run = _run(tmp_path)
    assert [(c.steps, c.seconds) for c in checkpoints(run)] == [(8, 50.0), (16, 130.0)]
    (run / "best_model.zip").write_bytes(b"kept")
    record = {"mean_return": 0.9, "timesteps": 16, "saved_at": 5030.0}
    (run / "eval" / "best.json").write_text(json.dumps(record))
    [kept] = candidates(run, "kept")
    assert kept.seconds == pytest.approx(130.0)


def test_the_kept_models_line_says_training_time_when_the_run_was_resumed() -> None:
    record = {"mean_return": 0.9, "timesteps": 16}
    one = {**record, "seconds_from_command": 551.0, "seconds_of_training": 551.0}
    assert kept_summary(one).endswith("9 min 11 s after the command was typed")
    resumed = {**record, "seconds_from_command": 30.0, "seconds_of_training": 130.0}
    line = kept_summary(resumed)
    assert "after 2 min 10 s of training over the run's segments" in line
    assert "30 s after the resuming command" in line


def test_a_benchmark_reports_each_seeds_training_time_and_kept_model(tmp_path) -> None:
    from gymprecice_lab.benchmarking.seed_training import training_record
    from gymprecice_lab.benchmarking.tables import _training_note

    run = _run(tmp_path)
    finished = [SEGMENTS[0], {"started_at": 5000.0, "finished_at": 5200.0, "result": {}}]
    manifest = {"segments": finished, "result": {"timesteps": 16}}
    (run / "manifest.json").write_text(json.dumps(manifest))
    (run / "best_model.zip").write_bytes(b"kept")
    kept = {"mean_return": 0.9, "timesteps": 8, "score": "settled", "saved_at": 1050.0}
    (run / "eval" / "best.json").write_text(json.dumps(kept))
    assert training_record(run)["validations"] == []  # trained without them
    np.savez(
        run / "eval" / "evaluations.npz",
        timesteps=np.array([8, 16]),
        results=np.array([[0.8, 0.9], [0.7, 0.7]]),
    )
    record = training_record(run)
    assert record["validations"] == [[8, 0.85], [16, 0.7]]
    assert record["training_seconds"] == 300.0  # 100 s, then 200 s; not the 3,900 s gap
    assert record["segments"] == 2 and record["timesteps"] == 16
    # a record written before seconds_of_training: timed from its save by the segments
    assert record["kept"] == {
        "timesteps": 8,
        "score": "settled",
        "value": 0.9,
        "training_seconds": 50.0,
    }
    note = _training_note({"SAC seed 0": record})
    assert "SAC seed 0: 16 steps in 5 min, kept the model of step 8" in note
    assert "(settled 0.9 on validation), 1 min into training" in note
    # a last segment recorded before finished_at: it ends at the manifest's last write
    older = [SEGMENTS[0], {"started_at": 5000.0, "result": {"seconds": 150.0}}]
    (run / "manifest.json").write_text(json.dumps({"segments": older}))
    os.utime(run / "manifest.json", (5180.0, 5180.0))
    assert training_record(run)["training_seconds"] == 280.0  # 100 s, then 180 s
    # still running: its end is not known yet
    (run / "manifest.json").write_text(json.dumps({"segments": SEGMENTS}))
    assert training_record(run)["training_seconds"] is None
