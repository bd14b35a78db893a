"""Preemption is an ordinary event for ``gymprecice train``, ``benchmark`` and ``sweep``.

SLURM ends a job with SIGTERM and, a grace period later (30 s unless the cluster sets
another), SIGKILL. ``gymprecice train`` turns the SIGTERM into a saved model and
checkpoint; what is checked here, on the test double:

* the save after SIGTERM of a SAC run whose replay buffer is full (SB3's default 100,000
  transitions of the quickstart's 151 probes: 122 MB of pickle) ends well inside the grace
  period (measured and printed);
* a save that SIGKILL cuts short leaves the previous checkpoint whole
  (:func:`gymprecice_lab.callbacks.save_checkpoint` writes under temporary names and
  renames once whole), and the same command resumes from it and finishes;
* a second SIGTERM during that save does not cut it short;
* SIGTERM, then SIGKILL 2 s later: nothing is left running and the same command resumes;
* ``gymprecice benchmark`` killed with SIGKILL mid-training, mid-evaluation and mid-sweep
  leaves no process behind (its worker processes die with it) and, run again, keeps every
  finished seed, evaluation and controller and goes on from the first unfinished one.

Every command runs in a subprocess with ``XDG_STATE_HOME`` in the test's directory, so that
every process it starts (workers, solvers, watchdogs) is found by that variable in its
``/proc/PID/environ``, or by a ``/proc/PID/cwd`` inside the directory, never by name.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from gymprecice.testing.chaos import describe_processes, left_behind

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="/proc and PR_SET_PDEATHSIG are Linux's"
)

#: SLURM's default time between SIGTERM and SIGKILL (``KillWait``)
GRACE_S = 30.0
#: how long the processes of a killed command may take to be gone
GONE_WITHIN_S = 5.0
#: SAC on the quickstart, test double, with SB3's replay buffer of 100,000 transitions
SAC = [
    "train",
    "quickstart",
    "--double",
    "--algo",
    "sac",
    "--episode-time",
    "0.1",
    "--no-validation",
    "--no-progress-bar",
    "--out",
    "sac",
]


def _environment(root: Path) -> dict[str, str]:
    return {**os.environ, "XDG_STATE_HOME": str(root / "state")}


def _start(root: Path, argv: list[str], log: str) -> subprocess.Popen[bytes]:
    with (root / log).open("ab") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "gymprecice", *argv],
            cwd=root,
            stdout=out,
            stderr=subprocess.STDOUT,
            env=_environment(root),
        )


def _run(root: Path, argv: list[str], log: str, timeout: float = 300) -> tuple[int, str]:
    proc = _start(root, argv, log)
    try:
        status = proc.wait(timeout)
    finally:
        proc.kill()
    return status, (root / log).read_text()


def wait_gone(root: Path, within: float = GONE_WITHIN_S) -> tuple[set[int], float]:
    """The processes of ``root`` still alive ``within`` seconds from now (none: at once
    when they are gone), and how long it took."""
    started = time.monotonic()
    left = left_behind(root)
    while left and time.monotonic() - started < within:
        time.sleep(0.05)
        left = left_behind(root)
    return left, time.monotonic() - started


def _kill_all(pids: set[int]) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def _episodes(run: Path) -> int:
    """Episodes the Monitor files of a training run record."""
    return sum(
        max(0, len(path.read_text().splitlines()) - 2)
        for path in (run / "monitor").glob("*.monitor.csv")
    )


def _wait_for(condition, proc: subprocess.Popen[bytes], log: Path, timeout: float = 240) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise AssertionError(f"never happened (exit {proc.poll()}):\n{log.read_text()[-3000:]}")
        time.sleep(0.02)


def _fill_replay_buffer(path: Path) -> int:
    """Fill a saved replay buffer with random transitions and mark it full; its size."""
    buffer = pickle.loads(path.read_bytes())
    rng = np.random.default_rng(0)
    for name in ("observations", "next_observations", "actions", "rewards"):
        array = getattr(buffer, name)
        array[...] = rng.standard_normal(array.shape).astype(array.dtype)
    buffer.full, buffer.pos = True, 0
    path.write_bytes(pickle.dumps(buffer, protocol=pickle.HIGHEST_PROTOCOL))
    return buffer.buffer_size


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_sac_saves_a_full_replay_buffer_within_a_grace_period_after_sigterm(tmp_path):
    """A SAC run resumed with its replay buffer full (100,000 random transitions) gets
    SIGTERM: it exits 143 with its new checkpoint and a whole, full replay buffer, well
    inside SLURM's default grace of 30 s (SIGTERM to exit: 1.3 s measured on 2 cores,
    3.9 s on 2 busy cores). Cost: 48 to 82 s measured on 2 busy cores (two short SAC
    runs on the double, 4 x 122 MB written)."""
    status, out = _run(tmp_path, [*SAC, "--timesteps", "4"], "first.log")
    assert status == 0, out
    checkpoints = tmp_path / "sac" / "checkpoints"
    size = _fill_replay_buffer(checkpoints / "sac_replay_buffer_4_steps.pkl")
    proc = _start(tmp_path, [*SAC, "--timesteps", "100000"], "resumed.log")
    log = tmp_path / "resumed.log"
    try:
        before = _episodes(tmp_path / "sac")
        _wait_for(lambda: _episodes(tmp_path / "sac") >= before + 3, proc, log)
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        status = proc.wait(GRACE_S)
        took = time.monotonic() - sent
    finally:
        proc.kill()
    text = log.read_text()
    assert "resuming from" in text and status == 128 + signal.SIGTERM, text
    manifest = json.loads((tmp_path / "sac" / "manifest.json").read_text())
    steps = manifest["result"]["timesteps"]
    assert manifest["result"]["interrupted"] == "SIGTERM" and steps > 4
    saved = pickle.loads((checkpoints / f"sac_replay_buffer_{steps}_steps.pkl").read_bytes())
    assert saved.full and saved.buffer_size == size == 100_000
    assert not list(checkpoints.glob(".*.partial"))
    print(f"SIGTERM to exit with a full replay buffer of {size:,} transitions: {took:.2f} s")
    assert took < GRACE_S


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_second_sigterm_during_the_save_does_not_cut_it_short(tmp_path):
    """SIGTERM, and again while the replay buffer is being written (a scheduler that
    signals at the time limit a save begun at its warning, an impatient user): the save
    finishes, the checkpoint of the step the run stopped at is whole and recorded.
    Cost: 18 to 29 s measured on 2 busy cores (one short SAC run on the double, 122 MB
    written)."""
    proc = _start(tmp_path, [*SAC, "--timesteps", "100000"], "train.log")
    log = tmp_path / "train.log"
    checkpoints = tmp_path / "sac" / "checkpoints"

    def saving() -> bool:
        try:
            return any(n.endswith(".partial") for n in os.listdir(checkpoints))
        except OSError:
            return False

    try:
        _wait_for(lambda: _episodes(tmp_path / "sac") >= 3, proc, log)
        proc.send_signal(signal.SIGTERM)
        _wait_for(saving, proc, log, timeout=GRACE_S)
        proc.send_signal(signal.SIGTERM)
        status = proc.wait(GRACE_S)
    finally:
        proc.kill()
    assert status == 128 + signal.SIGTERM, log.read_text()
    result = json.loads((tmp_path / "sac" / "manifest.json").read_text())["result"]
    assert result["interrupted"] == "SIGTERM"
    steps = result["timesteps"]
    assert (checkpoints / f"sac_{steps}_steps.zip").is_file()
    assert pickle.loads((checkpoints / f"sac_replay_buffer_{steps}_steps.pkl").read_bytes())
    assert not list(checkpoints.glob(".*.partial"))


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_sigterm_then_sigkill_2_s_later_and_the_same_command_resumes(tmp_path):
    """SIGTERM a moment after the first checkpoint, SIGKILL 2 s later whatever the run is
    doing (saving or gone): no process of the run is left, and the same command resumes
    from a checkpoint and finishes. Cost: 47 to 84 s measured on 2 busy cores (two short
    SAC runs on the double)."""
    argv = [*SAC, "--timesteps", "48", "--checkpoint-every", "8"]
    proc = _start(tmp_path, argv, "first.log")
    checkpoints = tmp_path / "sac" / "checkpoints"
    try:
        _wait_for(lambda: any(checkpoints.glob("sac_*_steps.zip")), proc, tmp_path / "first.log")
        proc.send_signal(signal.SIGTERM)
        time.sleep(2.0)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        left, _ = wait_gone(tmp_path)
        assert not left, describe_processes(left)
    finally:
        proc.kill()
        _kill_all(left_behind(tmp_path))
    status, out = _run(tmp_path, argv, "second.log")
    assert status == 0, out
    assert "gymprecice train: resuming from" in out
    result = json.loads((tmp_path / "sac" / "manifest.json").read_text())["result"]
    assert result["interrupted"] is None and result["timesteps"] >= 48
    assert result["resumed_from"] and result["steps_this_run"] < 48


_KILLED_MID_WRITE = """
import os, sys
from pathlib import Path
from gymprecice_lab.training.callbacks import save_checkpoint


def write(path, data, name, killed_in):
    with open(path, "wb") as handle:
        handle.write(data[: len(data) // 2])
        handle.flush()
        if name == killed_in:
            os.kill(os.getpid(), 9)
        handle.write(data[len(data) // 2 :])


class Model:
    replay_buffer = object()

    def __init__(self, killed_in):
        self.killed_in = killed_in

    def save_replay_buffer(self, path):
        write(path, b"new buffer " * 1000, "buffer", self.killed_in)

    def save(self, path):
        write(path, b"new zip " * 1000, "zip", self.killed_in)


class Stats:
    def __init__(self, killed_in):
        self.killed_in = killed_in

    def save(self, path):
        write(path, b"new stats " * 1000, "stats", self.killed_in)


for killed_in in sys.argv[2:]:  # one child per file, killed while it writes that file
    pid = os.fork()
    if pid == 0:
        d = Path(sys.argv[1]) / killed_in
        save_checkpoint(
            Model(killed_in),
            d / "sac_8_steps.zip",
            replay_buffer=d / "sac_replay_buffer_8_steps.pkl",
            stats=Stats(killed_in),
            stats_path=d / "sac_vecnormalize_8_steps.pkl",
        )
        os._exit(0)
    _, status = os.waitpid(pid, 0)
    print(killed_in, os.WTERMSIG(status) if os.WIFSIGNALED(status) else "exited")
"""


def test_a_checkpoint_saved_over_and_killed_mid_write_stays_whole(tmp_path):
    """A save of a checkpoint that exists already (the final save at the step of the last
    periodic one) killed in the middle of each of its files in turn: every file keeps its
    earlier content, and the temporary files are removed by the next run.
    Cost: 4 to 13 s measured on 2 busy cores (one Python process that imports
    Stable-Baselines3)."""
    from gymprecice_lab.training.callbacks import remove_partial_saves

    names = ("sac_8_steps.zip", "sac_replay_buffer_8_steps.pkl", "sac_vecnormalize_8_steps.pkl")
    files = ("stats", "buffer", "zip")
    for killed_in in files:
        (tmp_path / killed_in).mkdir()
        for name in names:
            (tmp_path / killed_in / name).write_bytes(f"old {name}".encode())
    script = tmp_path / "save.py"
    script.write_text(textwrap.dedent(_KILLED_MID_WRITE))
    proc = subprocess.run(
        [sys.executable, str(script), str(tmp_path), *files],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.stdout.split() == [w for f in files for w in (f, str(int(signal.SIGKILL)))], (
        proc.stdout + proc.stderr
    )
    for killed_in in files:
        directory = tmp_path / killed_in
        assert {n: (directory / n).read_bytes() for n in names} == {
            n: f"old {n}".encode() for n in names
        }, killed_in
        partial = sorted(p.name for p in directory.glob(".*.partial"))
        assert partial, f"killed in {killed_in}: no temporary file, the kill was not mid-write"
        assert sorted(p.name for p in remove_partial_saves(directory, "sac")) == partial
        assert sorted(p.name for p in directory.iterdir()) == sorted(names)


def test_companions_of_a_checkpoint_never_completed_are_removed(tmp_path):
    """A kill between the renames (or mid-way through pruning) leaves a replay buffer or
    statistics without their zip: hundreds of megabytes nothing reads, removed by the next
    run; a complete checkpoint's are kept. Cost: under 0.1 s."""
    from gymprecice_lab.training.callbacks import remove_partial_saves

    for name in (
        "sac_8_steps.zip",
        "sac_replay_buffer_8_steps.pkl",
        "sac_vecnormalize_8_steps.pkl",
        "sac_replay_buffer_16_steps.pkl",
        "sac_vecnormalize_16_steps.pkl",
        "best.json",
    ):
        (tmp_path / name).write_bytes(b"x")
    removed = remove_partial_saves(tmp_path, "sac")
    assert sorted(p.name for p in removed) == [
        "sac_replay_buffer_16_steps.pkl",
        "sac_vecnormalize_16_steps.pkl",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "best.json",
        "sac_8_steps.zip",
        "sac_replay_buffer_8_steps.pkl",
        "sac_vecnormalize_8_steps.pkl",
    ]


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_sigkill_mid_save_leaves_the_previous_checkpoint_whole_and_the_run_resumes(
    tmp_path, capsys
):
    """SIGKILL while the second checkpoint's replay buffer (122 MB) is being written: the
    first checkpoint is the newest whole one, taken without a word about a torn file, and
    the same command resumes from it and finishes. Cost: 37 to 74 s measured on 2 busy
    cores (two short SAC runs on the double)."""
    from gymprecice_lab.common.wrapped_env import newest_checkpoint

    argv = [*SAC, "--timesteps", "40", "--checkpoint-every", "8", "--keep-checkpoints", "3"]
    proc = _start(tmp_path, argv, "first.log")
    checkpoints = tmp_path / "sac" / "checkpoints"

    def saving_the_second() -> bool:
        try:
            names = os.listdir(checkpoints)
        except OSError:
            return False
        return "sac_8_steps.zip" in names and any(n.endswith(".partial") for n in names)

    try:
        _wait_for(saving_the_second, proc, tmp_path / "first.log")
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        left, _ = wait_gone(tmp_path)
        assert not left, describe_processes(left)
    finally:
        proc.kill()
        _kill_all(left_behind(tmp_path))
    partial = sorted(p.name for p in checkpoints.glob(".*.partial"))
    assert partial and all("_16_steps" in name for name in partial), partial
    assert not (checkpoints / "sac_16_steps.zip").exists()
    capsys.readouterr()
    assert newest_checkpoint(checkpoints) == (checkpoints / "sac_8_steps.zip", 8)
    assert "torn" not in capsys.readouterr().err
    buffer = pickle.loads((checkpoints / "sac_replay_buffer_8_steps.pkl").read_bytes())
    assert buffer.pos in (7, 8)  # SB3 stores a step's transition after its callbacks
    status, out = _run(tmp_path, argv, "second.log")
    assert status == 0, out
    assert f"resuming from {checkpoints / 'sac_8_steps.zip'} (8 steps)" in out
    assert json.loads((tmp_path / "sac" / "manifest.json").read_text())["result"]["timesteps"] >= 40
    assert not list(checkpoints.glob(".*.partial"))


# -- benchmark and sweep ---------------------------------------------------------------------

BENCHMARK = [
    "benchmark",
    "jet-cylinder-fast",
    "--double",
    "--seeds",
    "2",
    "--algo",
    "ppo",
    "--timesteps",
    "48",
    "--train-args",
    "--n-steps 8 --batch-size 8 --net 8,8 --vec-env dummy --checkpoint-every 8 --no-validation",
    "--bootstrap-reps",
    "200",
    "--episode-time",
    "0.1",
    # long enough that an evaluation or a controller outlasts the check for processes left
    "--eval-time",
    "2",
    "--constants",
    "2",
    "--amplitudes",
    "1",
    "--frequencies",
    "3",
    "--feedback-gains=",
    "--workers",
    "2",
    "--out",
    "bench",
]


def _kill_when(root: Path, condition, log: str) -> None:
    """Start the benchmark, SIGKILL it once ``condition()`` holds, and check that every
    process it started is gone within a few seconds."""
    proc = _start(root, BENCHMARK, log)
    try:
        _wait_for(condition, proc, root / log, timeout=300)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        left, took = wait_gone(root)
        assert not left, f"{log}: left {took:.1f} s after SIGKILL: {describe_processes(left)}"
    finally:
        proc.kill()
        _kill_all(left_behind(root))


def _finished_evaluations(bench: Path) -> dict[str, str]:
    """``seed -> created`` of each evaluation whose manifest records its result."""
    found = {}
    for manifest in sorted(bench.glob("eval/ppo/seed_*/manifest.json")):
        data = json.loads(manifest.read_text())
        if data.get("result") is not None:
            found[manifest.parent.name] = data["created"]
    return found


def _finished_controllers(bench: Path) -> dict[str, int]:
    """``label -> summary.json's mtime`` of each controller of the sweep that finished."""
    found = {}
    for summary in sorted((bench / "baselines").glob("*/summary.json")):
        try:
            episodes = json.loads(summary.read_text())["episodes"]
        except (OSError, ValueError, KeyError):
            continue
        if len(episodes) == 2:
            found[summary.parent.name] = summary.stat().st_mtime_ns
    return found


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_benchmark_killed_at_each_stage_resumes_at_the_first_unfinished_piece(tmp_path):
    """``gymprecice benchmark`` on the double killed with SIGKILL three times: while seed 1
    trains (after its first checkpoint), once the evaluations have started, once the
    baselines' sweep has finished a controller. Each time nothing is left running within
    5 s (the evaluations' and the sweep's worker processes die with the command; left on,
    they would write into the directories the rerun works in), and each rerun keeps what
    was finished: seed 0, then seed 1 resumed from its checkpoint, the finished
    evaluations, the finished controllers. Cost: 103 to 173 s measured on 2 busy cores
    (four runs of a tiny benchmark on the double, two seeds, two held-out starts, four
    controllers)."""
    bench = tmp_path / "bench"
    seed_1 = bench / "train" / "ppo" / "seed_1" / "checkpoints" / "ppo_8_steps.zip"
    _kill_when(tmp_path, seed_1.is_file, "1-training.log")
    seed_0 = json.loads((bench / "train/ppo/seed_0/manifest.json").read_text())
    assert seed_0["result"]["timesteps"] >= 48
    assert json.loads((bench / "train/ppo/seed_1/manifest.json").read_text())["result"] is None

    _kill_when(tmp_path, (bench / "eval/ppo/seed_0/manifest.json").is_file, "2-evaluating.log")
    text = (tmp_path / "2-evaluating.log").read_text()
    assert "ppo seed 0: trained already, kept" in text
    assert f"resuming from {seed_1} (8 steps)" in text
    assert "ppo seed 1: trained already" not in text
    assert json.loads((bench / "train/ppo/seed_0/manifest.json").read_text()) == seed_0
    evaluations = _finished_evaluations(bench)
    assert len(evaluations) < 2, "both evaluations finished before the kill"

    _kill_when(tmp_path, lambda: len(_finished_controllers(bench)) >= 1, "3-sweeping.log")
    text = (tmp_path / "3-sweeping.log").read_text()
    assert "ppo seed 1: trained already, kept" in text
    assert _finished_evaluations(bench).items() >= evaluations.items()  # kept, not rerun
    assert len(_finished_evaluations(bench)) == 2
    controllers = _finished_controllers(bench)
    assert 1 <= len(controllers) < 4, controllers

    status, text = _run(tmp_path, BENCHMARK, "4-finishing.log", timeout=600)
    assert status == 0, text
    assert (
        f"gymprecice sweep: {len(controllers)} of 4 controllers were finished by an earlier "
        "run of this sweep: kept" in text
    )
    assert _finished_controllers(bench).items() >= controllers.items()  # not run again
    assert "gymprecice train:" not in text and "gymprecice evaluate:" not in text
    results = json.loads((bench / "results.json").read_text())
    assert {c["label"] for c in results["controllers"]} >= {"PPO", "uncontrolled"}
