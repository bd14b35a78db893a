"""``gymprecice prepare ENV``: an env's cases prepared ahead, into the shared caches.

On real OpenFOAM (the quickstart's case, its pre-run shortened): the pre-run lands in the
cache and a second ``prepare`` (as a training's first env would) takes it from there; a
``prepare`` stopped with SIGTERM mid-pre-run leaves no solver running, no temporary run
directory and no cache entry. Bad input is refused in one line, exit status 2.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gymprecice.testing.chaos import describe_processes, left_behind

#: the quickstart's pre-run to 0.05 s: a restartable snapshot in seconds
SHORT = {"case_overrides": {"prerun_end_time": 0.05}}
#: the quickstart's own pre-run (to 5 s): long enough to be stopped in the middle
LONG: dict = {}


def _prepare(tmp_path: Path, *args: str) -> subprocess.Popen[str]:
    env = {
        **os.environ,
        "GYMPRECICE_CACHE_DIR": str(tmp_path / "cache"),
        "TMPDIR": str(tmp_path / "tmp"),
        "XDG_STATE_HOME": str(tmp_path / "state"),
    }
    (tmp_path / "tmp").mkdir(exist_ok=True)
    return subprocess.Popen(
        [sys.executable, "-m", "gymprecice", "prepare", *args],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _entries(tmp_path: Path) -> list[str]:
    folder = tmp_path / "cache" / "openfoam-prerun"
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if (p / "entry.json").is_file())


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["no-such-env"], "no-such-env"),
        (["quickstart", "--env-kwargs", "[1]"], "--env-kwargs: give a JSON object"),
        (["."], "give a registered environment"),
    ],
)
def test_bad_input_is_refused_in_one_line(tmp_path: Path, args: list[str], said: str) -> None:
    proc = _prepare(tmp_path, *args)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 2, (out, err)
    assert said in err and err.count("\n") == 1, err
    assert _entries(tmp_path) == [] and list((tmp_path / "tmp").iterdir()) == []


@pytest.mark.openfoam
@pytest.mark.timeout(300)
def test_the_pre_run_lands_in_the_cache_and_the_next_env_takes_it(tmp_path: Path) -> None:
    """Cost: about 5 s (two prepares, one pimpleFoam pre-run to 0.05 s)."""
    kwargs = json.dumps(SHORT)
    first = _prepare(tmp_path, "quickstart", "--env-kwargs", kwargs)
    out, err = first.communicate(timeout=240)
    assert first.returncode == 0, (out, err)
    assert "prepared in" in out and "fluid" in out, out
    (entry,) = _entries(tmp_path)
    log = tmp_path / "cache" / "openfoam-prerun" / entry / "log.prerun.pimpleFoam"
    stored = log.stat().st_mtime_ns
    second = _prepare(tmp_path, "quickstart", "--env-kwargs", kwargs)
    out, err = second.communicate(timeout=240)
    assert second.returncode == 0, (out, err)
    assert _entries(tmp_path) == [entry] and log.stat().st_mtime_ns == stored  # taken, not rerun
    assert list((tmp_path / "tmp").iterdir()) == []  # the run root is gone


@pytest.mark.openfoam
@pytest.mark.timeout(300)
def test_stopped_mid_pre_run_it_leaves_nothing_running_and_nothing_half_kept(
    tmp_path: Path,
) -> None:
    """Cost: about 2 s (the quickstart's pre-run started, then stopped)."""
    proc = _prepare(tmp_path, "quickstart", "--env-kwargs", json.dumps(LONG))
    deadline = time.monotonic() + 120
    solver = []
    while time.monotonic() < deadline and proc.poll() is None:
        solver = [
            pid for pid in left_behind(tmp_path) if "pimpleFoam" in describe_processes([pid])[0]
        ]
        if solver:
            break
        time.sleep(0.2)
    assert solver, f"no pre-run started: {proc.poll()} {proc.stderr.read() if proc.stderr else ''}"
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, (out, err)
    assert "stopped" in err, err
    deadline = time.monotonic() + 10
    while left_behind(tmp_path) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = left_behind(tmp_path)
    assert not left, describe_processes(left)
    assert _entries(tmp_path) == []
    assert list((tmp_path / "tmp").iterdir()) == []
