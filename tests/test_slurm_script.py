"""The SLURM batch script of docs/cluster.md carries a training across a preemption.

The script is taken from the page as a user copies it, with two edits a user makes too:
the placeholder ``/path/to/venv`` becomes this Python's environment, and the training it
runs becomes a small ``gymprecice train quickstart --double`` (PPO, 64 steps, a checkpoint
every 8). It then runs under a stand-in for SLURM written here: the job runs the script
with ``bash`` in a session of its own (``SLURM_JOB_ID``, ``SLURM_SUBMIT_DIR`` and
``SLURM_RESTART_COUNT`` set, ``scontrol`` a stub that records what it is asked), the
scheduler signals it once the training is under way as the script's ``#SBATCH
--signal`` asks (``B:``: the batch script alone), SIGKILLs every process of the job that
is left after the grace period (30 s, SLURM's default), and then requeues it: runs it
again, which must resume the training and finish it.

A second case preempts the job as SLURM does: SIGTERM to every process of the job at
once, so that the training gets it from the scheduler and from the script that passes it
on (the kernel may merge the two; tests/test_preemption.py sends the second one while the
save is under way).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gymprecice.testing.chaos import describe_processes, left_behind

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="/proc and PR_SET_PDEATHSIG are Linux's"
)

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "cluster.md"
#: SLURM's default time between SIGTERM and SIGKILL (``KillWait``)
GRACE_S = 30.0
JOB_ID = "4242"
#: what the stand-in trains instead of the page's run: cheap, on the test double
TRAINING = (
    "quickstart --double --algo ppo --n-steps 8 --batch-size 8 --net 16,16 --episode-time 0.1 "
    "--timesteps 64 --checkpoint-every 8 --no-validation --no-progress-bar "
)
_FENCE = re.compile(r"^```bash\n(.*?)^```", re.M | re.S)
#: ``gymprecice train ENV OPTIONS`` up to its ``--out``, across continuation lines
_TRAIN = re.compile(r"gymprecice train \S+ (?:[^\n]*\\\n)*?[^\n]*?(?=--out )", re.S)


def wait_gone(root: Path, within: float = 5.0) -> set[int]:
    """The processes of ``root`` still alive ``within`` seconds from now (or at once none)."""
    deadline = time.monotonic() + within
    left = left_behind(root)
    while left and time.monotonic() < deadline:
        time.sleep(0.05)
        left = left_behind(root)
    return left


def batch_script() -> str:
    """The page's batch script that requeues itself."""
    (script,) = [b for b in _FENCE.findall(PAGE.read_text()) if "#SBATCH --requeue" in b]
    return script


def _directives(script: str) -> dict[str, str]:
    found = {}
    for line in script.splitlines():
        match = re.match(r"#SBATCH\s+--([\w-]+)(?:=(\S+))?", line)
        if match:
            found[match[1]] = match[2] or ""
    return found


def test_the_page_has_a_requeueing_script_that_reruns_the_same_train_command():
    """Cost: under 0.1 s."""
    script = batch_script()
    directives = _directives(script)
    assert "requeue" in directives
    assert re.fullmatch(r"(B:)?TERM@\d+", directives["signal"]), directives["signal"]
    (command,) = _TRAIN.findall(script)
    assert command.startswith("gymprecice train ")
    assert 'scontrol requeue "$SLURM_JOB_ID"' in script and "source /path/to/venv/" in script


def _job_script(tmp_path: Path) -> Path:
    """The page's script with the user's two edits: their environment, this training."""
    script = batch_script().replace("/path/to/venv", sys.prefix)
    script, count = _TRAIN.subn("gymprecice train " + TRAINING, script)
    assert count == 1
    path = tmp_path / "job.sh"
    path.write_text(script)
    return path


def _stubs(tmp_path: Path) -> Path:
    """A directory with ``scontrol``: it appends its arguments to ``scontrol.log``."""
    stubs = tmp_path / "stubs"
    stubs.mkdir()
    scontrol = stubs / "scontrol"
    scontrol.write_text(f'#!/bin/sh\necho "$@" >> "{tmp_path / "scontrol.log"}"\n')
    scontrol.chmod(0o755)
    return stubs


class Job:
    """One run of the job under the stand-in scheduler."""

    def __init__(self, tmp_path: Path, script: Path, stubs: Path, restarts: int) -> None:
        self.tmp_path = tmp_path
        env = {
            **os.environ,
            "PATH": f"{stubs}:{os.environ['PATH']}",
            "SLURM_JOB_ID": JOB_ID,
            "SLURM_SUBMIT_DIR": str(tmp_path),
            "SLURM_RESTART_COUNT": str(restarts),
            "XDG_STATE_HOME": str(tmp_path / "state"),
        }
        with (tmp_path / f"slurm-{JOB_ID}.out").open("ab") as out:  # --open-mode=append
            self.proc = subprocess.Popen(
                ["bash", str(script)],
                cwd=tmp_path,
                stdout=out,
                stderr=subprocess.STDOUT,
                env=env,
                start_new_session=True,  # the job's processes: its session
            )

    def signal_when(self, condition, batch_only: bool, timeout: float = 300) -> None:
        """SIGTERM once ``condition()`` holds: to the batch script alone, or to every
        process of the job."""
        deadline = time.monotonic() + timeout
        while not condition():
            assert self.proc.poll() is None, self.output()
            assert time.monotonic() < deadline, self.output()
            time.sleep(0.02)
        if batch_only:
            self.proc.send_signal(signal.SIGTERM)
        else:
            os.killpg(self.proc.pid, signal.SIGTERM)

    def end(self, grace: float) -> tuple[int | None, bool]:
        """Wait ``grace`` seconds for the job to end, then SIGKILL what is left of it; its
        exit status (None: killed) and whether anything had to be killed."""
        try:
            status = self.proc.wait(grace)
        except subprocess.TimeoutExpired:
            status = None
        killed = status is None
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()
        return status, killed

    def output(self) -> str:
        return (self.tmp_path / f"slurm-{JOB_ID}.out").read_text()

    def failure(self) -> str:
        """The job's output for a failure message: its last lines (a traceback's end)
        first, since a long message is cut at its end."""
        text = self.output()
        return "last lines:\n" + "\n".join(text.splitlines()[-12:]) + "\n\nwhole:\n" + text


def _requeues(tmp_path: Path) -> list[str]:
    log = tmp_path / "scontrol.log"
    return log.read_text().splitlines() if log.exists() else []


def _preempted_then_requeued(tmp_path: Path, batch_only: bool) -> None:
    script, stubs = _job_script(tmp_path), _stubs(tmp_path)
    run = tmp_path / "runs" / "jet-cylinder-fast"
    first = Job(tmp_path, script, stubs, restarts=0)
    try:
        first.signal_when(lambda: any((run / "checkpoints").glob("ppo_*_steps.zip")), batch_only)
        status, killed = first.end(GRACE_S)
        left = wait_gone(tmp_path)
    finally:
        first.end(0)
    assert not killed, f"the job did not end within the grace period:\n{first.output()}"
    assert not left, describe_processes(left)
    assert "interrupted (SIGTERM)" in first.output(), first.output()
    assert _requeues(tmp_path) == [f"requeue {JOB_ID}"]
    result = json.loads((run / "manifest.json").read_text())["result"]
    assert result["interrupted"] == "SIGTERM" and 0 < result["timesteps"] < 64
    saved = run / "checkpoints" / f"ppo_{result['timesteps']}_steps.zip"
    assert saved.is_file()

    second = Job(tmp_path, script, stubs, restarts=1)  # requeued: the same script again
    try:
        status, killed = second.end(300)
    finally:
        second.end(0)
    text = second.output()
    assert status == 0 and not killed, second.failure()
    assert f"gymprecice train: resuming from {saved}" in text
    result = json.loads((run / "manifest.json").read_text())["result"]
    assert result["interrupted"] is None and result["timesteps"] >= 64
    assert _requeues(tmp_path) == [f"requeue {JOB_ID}"]  # a finished job stays finished
    left = wait_gone(tmp_path)
    assert not left, describe_processes(left)


@pytest.mark.slow
@pytest.mark.waits
@pytest.mark.timeout(900)
def test_a_job_signalled_before_its_time_limit_saves_requeues_and_resumes(tmp_path):
    """``--signal=B:TERM@60``: SIGTERM to the batch script alone, which passes it on,
    waits for the save and requeues the job; the requeued job resumes and finishes.
    Cost: 47 to 67 s measured on 2 busy cores (two jobs of a small training on the
    double)."""
    assert _directives(batch_script())["signal"].startswith("B:")
    _preempted_then_requeued(tmp_path, batch_only=True)


@pytest.mark.slow
@pytest.mark.waits
@pytest.mark.timeout(900)
def test_a_preempted_job_saves_and_resumes(tmp_path):
    """A preemption: SIGTERM to every process of the job at once, the training's from the
    scheduler and from the script; the job saves within the grace period, the script asks
    for a requeue (SLURM requeues a preempted ``--requeue`` job anyway) and the requeued
    job resumes and finishes. Cost: 41 to 71 s measured on 2 busy cores (two jobs of a
    small training on the double)."""
    _preempted_then_requeued(tmp_path, batch_only=False)
