"""The pre-run progress lines of ``gymprecice train``."""

from __future__ import annotations

from pathlib import Path

from gymprecice_lab.training.prerun_progress import PrerunProgress, last_time


def _log(path: Path, times: list[float]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    body = "".join(f"Time = {t:g}\n\nPIMPLE: iteration 1\nsmoothSolver: ...\n" for t in times)
    path.write_text("Starting time loop\n\n" + body)


def test_last_time_reads_the_newest_time_step(tmp_path: Path) -> None:
    log = tmp_path / "log.prerun.pimpleFoam"
    _log(log, [0.0005, 0.001, 0.0015])
    assert last_time(log) == 0.0015
    assert last_time(tmp_path / "missing") is None


def test_progress_reports_each_env_once_per_new_time(tmp_path: Path) -> None:
    envs = tmp_path / "envs"
    watcher = PrerunProgress(envs, end_time=6.0)
    assert watcher.poll() == []  # nothing started yet
    _log(envs / "env_0" / "fluid-openfoam" / "log.prerun.pimpleFoam", [0.5, 1.0])
    [line] = watcher.poll()
    assert "env_0 pre-run at t = 1 s of 6 s" in line
    assert watcher.poll() == []  # no new time step: nothing to say
    _log(envs / "env_0" / "fluid-openfoam" / "log.prerun.pimpleFoam", [0.5, 1.0, 1.5])
    _log(envs / "env_1" / "fluid-openfoam" / "log.prerun.pimpleFoam", [0.5])
    lines = watcher.poll()
    assert [ln.split(" pre-run")[0][-5:] for ln in lines] == ["env_0", "env_1"]
    assert "t = 1.5 s" in lines[0]


def test_the_thread_says_lines_and_stops(tmp_path: Path) -> None:
    envs = tmp_path / "envs"
    _log(envs / "env_0" / "fluid-openfoam" / "log.prerun.pimpleFoam", [2.0])
    said: list[str] = []
    with PrerunProgress(envs, every=0.01, say=said.append) as watcher:
        while not said:
            watcher._stop.wait(0.01)
    assert len(said) == 1 and "t = 2 s" in said[0]
