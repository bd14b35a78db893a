"""``gymprecice train`` killed with SIGKILL on the real stack, then run again.

A job's time limit, the OOM killer or ``kill -9`` end the lab command without any of its
clean-up. For a single-agent env (jet-cylinder-fast: OpenFOAM and the controller) and for
the four-participant two flaps (two-flaps-fast: OpenFOAM, two deal.II flaps and the
controller), the command is killed at three moments:

* **before the first action**: for the jet cylinder in the middle of its pre-run (the
  uncoupled pimpleFoam run to a developed flow); the two flaps have no pre-run, so in the
  middle of their first reset (the solvers starting and the gust that sets the start);
* **mid-coupling**: a moment after the first checkpoint, in the middle of an episode;
* **mid-save**: while the second checkpoint's replay buffer is being written.

Each time, within 10 s no process the command started is left: neither the training's
worker, the coupling worker and the solvers, nor the watchdogs and MPI daemons (found by
``XDG_STATE_HOME``, set to the test's directory, in their ``/proc/PID/environ``, or by a
``/proc/PID/cwd`` inside that directory; never by name). Then the same command, run again,
resumes (from the first checkpoint where one was written) and finishes.

Every run is SAC, a checkpoint every 4 actions, 12 actions in all; the jet cylinder's
episodes are 0.2 s (8 actions), the two flaps' 0.8 s (8 actions) after a 0.3 s gust. The
jet cylinder's tests share one pre-run cache: the first test's resume makes the pre-run
that the other two reuse.

The mechanisms each kill relies on are checked where they are cheap to switch off: the
layers that stop the solvers in tests/test_no_orphans.py, the saves that stay whole
and the repeated signal in tests/test_preemption.py.

Cost: 3.6 to 4.0 min for the six tests measured on 2 cores with little else running,
7.6 min on 2 busy cores (a load of 4 to 5: another training's pimpleFoam beside them);
each test states its own. Much of it is start-up: a resume of the jet cylinder measured
18 s from its start to its env worker's, of 38 s.

The kill before the first action of the jet cylinder is the hardest: the env's worker is a
child of multiprocessing's forkserver, which lives as long as any of its children does,
so the worker's ``PR_SET_PDEATHSIG`` (tied to the forkserver) cannot fire, and the worker
is busy with the whole pre-run, not reading requests. It watches the training itself
through a pidfd (gymprecice.vector.local), which this test proves.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from gymprecice.testing.chaos import describe_processes, left_behind, pid_alive

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="/proc and PR_SET_PDEATHSIG are Linux's"
)

#: how long the processes of the killed command may take to be gone (a busy machine)
GONE_WITHIN_S = 10.0
#: the training both envs run: 12 actions, a checkpoint every 4, nothing but training
COMMON = [
    "--algo",
    "sac",
    "--timesteps",
    "12",
    "--checkpoint-every",
    "4",
    "--no-validation",
    "--no-progress-bar",
    "--out",
    "run",
]
JET = ["train", "jet-cylinder-fast", "--episode-time", "0.2", *COMMON]
#: the two flaps' replay buffer is small (18 numbers per observation): a million
#: transitions make a save (164 MB) last long enough to be caught in the middle
FLAPS = [
    "train",
    "two-flaps-fast",
    "--episode-time",
    "0.8",
    "--env-kwargs",
    '{"settle_time": 0.3}',
    "--hyperparams",
    "sac.yml",
    *COMMON,
]
FLAPS_HYPERPARAMS = "gymprecice/TwoFlapsFast-v0:\n  buffer_size: 1000000\n"


def _missing_openfoam() -> list[str]:
    from gymprecice_openfoam.testing import missing_coupled_stack

    return missing_coupled_stack("pimpleFoam")


def _missing_dealii() -> list[str]:
    from gymprecice.tools.stack import stack_which

    return _missing_openfoam() + ([] if stack_which("elasticity") else ["the deal.II adapter"])


@pytest.fixture(scope="module")
def jet_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The jet cylinder's pre-run cache for this module: empty for its first test."""
    return tmp_path_factory.mktemp("jet-prerun-cache")


# -- finding the processes of a run -------------------------------------------------------------


def _working_in(directory: Path) -> set[int]:
    """Live processes whose working directory is ``directory`` or below it (solvers)."""
    found = set()
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            cwd = Path(os.readlink(Path(entry.path, "cwd")))
        except OSError:
            continue
        if cwd.is_relative_to(directory) and pid_alive(int(entry.name)):
            found.add(int(entry.name))
    return found


def _program(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return "?"


# -- one kill and its resume ----------------------------------------------------------------------


class Run:
    """The command run in ``root`` as a user runs it, with its own owner index."""

    def __init__(self, root: Path, argv: list[str], cache: Path | None = None) -> None:
        self.root, self.argv = root, argv
        self.env = {**os.environ, "XDG_STATE_HOME": str(root / "state")}
        if cache is not None:
            self.env["GYMPRECICE_CACHE_DIR"] = str(cache)
        self.runs = 0

    def start(self) -> subprocess.Popen[bytes]:
        self.runs += 1
        with self.log.open("ab") as out:
            out.write(f"\n== run {self.runs}\n".encode())
            return subprocess.Popen(
                [sys.executable, "-m", "gymprecice", *self.argv],
                cwd=self.root,
                stdout=out,
                stderr=subprocess.STDOUT,
                env=self.env,
            )

    @property
    def log(self) -> Path:
        return self.root / "train.log"

    def last_output(self) -> str:
        return self.log.read_text().rsplit(f"== run {self.runs}\n", 1)[-1]

    def kill_when(
        self, condition: Callable[[], bool], after: float = 0.0
    ) -> tuple[dict[int, str], list[str]]:
        """Start, SIGKILL the command ``after`` seconds once ``condition()`` holds; check
        that nothing of it is left within :data:`GONE_WITHIN_S`; the processes (pid and
        program) that worked in the env's directory when it was killed, and what was
        left (nothing)."""
        proc = self.start()
        try:
            deadline = time.monotonic() + 600
            while not condition():
                assert proc.poll() is None, f"ended before the moment:\n{self.last_output()}"
                assert time.monotonic() < deadline, self.last_output()[-3000:]
                time.sleep(0.005)
            time.sleep(after)
            assert proc.poll() is None, f"ended before the kill:\n{self.last_output()}"
            solvers = {p: _program(p) for p in _working_in(self.root / "run" / "envs")}
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            started = time.monotonic()
            left = left_behind(self.root)
            while left and time.monotonic() - started < GONE_WITHIN_S:
                time.sleep(0.05)
                left = left_behind(self.root)
            took = time.monotonic() - started
            described = describe_processes(left)
            assert not left, f"left {took:.1f} s after SIGKILL: {described}"
            if not left:
                print(f"all processes gone {took:.2f} s after the SIGKILL")
            return solvers, described
        finally:
            proc.kill()
            for pid in left_behind(self.root):
                try:
                    os.kill(pid, signal.SIGKILL)
                except OSError:
                    pass

    def resume(self) -> str:
        """Run the same command again to its end; its output."""
        proc = self.start()
        try:
            status = proc.wait(900)
        finally:
            proc.kill()
        text = self.last_output()
        assert status == 0, text[-4000:]
        result = json.loads((self.root / "run" / "manifest.json").read_text())["result"]
        assert result["interrupted"] is None and result["timesteps"] >= 12, result
        assert not list((self.root / "run" / "checkpoints").glob(".*.partial"))
        return text

    # the moments

    def checkpoint(self, steps: int) -> Path:
        return self.root / "run" / "checkpoints" / f"sac_{steps}_steps.zip"

    def saving_the_second_checkpoint(self) -> bool:
        try:
            names = os.listdir(self.root / "run" / "checkpoints")
        except OSError:
            return False
        return "sac_4_steps.zip" in names and any(n.endswith(".partial") for n in names)


def _coupled(run: Run, programs: set[str]) -> None:
    """Killed mid-episode, a moment after the first checkpoint, with the solvers
    ``programs`` running; resumed from the checkpoint."""
    solvers, _ = run.kill_when(run.checkpoint(4).is_file, after=0.5)
    assert programs <= set(solvers.values()), solvers
    assert not run.checkpoint(8).exists()
    assert f"resuming from {run.checkpoint(4)} (4 steps)" in run.resume()


def _saving(run: Run) -> None:
    """Killed while the second checkpoint is written; resumed from the first."""
    run.kill_when(run.saving_the_second_checkpoint)
    partial = sorted(p.name for p in (run.root / "run" / "checkpoints").glob(".*.partial"))
    assert partial and all("_8_steps" in name for name in partial), partial
    assert not run.checkpoint(8).exists()
    text = run.resume()
    assert f"resuming from {run.checkpoint(4)} (4 steps)" in text
    assert "is torn" not in text


# -- jet-cylinder-fast ----------------------------------------------------------------------------


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_jet_cylinder_killed_mid_prerun_leaves_nothing_and_resumes(tmp_path, jet_cache):
    """SIGKILL of ``gymprecice train jet-cylinder-fast`` a second into its pre-run: the
    pre-run's pimpleFoam and everything else gone within 10 s; the same command runs the
    pre-run again (the killed one stored nothing) and finishes.

    Cost: 70 s measured on 2 cores (141 s busy): blockMesh and a second of pre-run,
    then the resume's whole pre-run (about 45 s) and 12 coupled actions.
    """
    missing = _missing_openfoam()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    cache = jet_cache if not any(jet_cache.iterdir()) else tmp_path / "cache"
    run = Run(tmp_path, JET, cache)
    fluid = tmp_path / "run" / "envs" / "env_0" / "fluid-openfoam"

    def prerunning() -> bool:
        return (fluid / "log.prerun.pimpleFoam").is_file() and bool(_working_in(fluid))

    solvers, left = run.kill_when(prerunning, after=1.0)
    assert "pimpleFoam" in solvers.values(), solvers
    assert not (fluid / "precice-Fluid-iterations.log").exists()  # never coupled
    assert not run.checkpoint(4).exists()
    assert not left, left
    text = run.resume()
    assert "pre-run at t =" in text and "resuming from" not in text


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_jet_cylinder_killed_mid_coupling_leaves_nothing_and_resumes(tmp_path, jet_cache):
    """SIGKILL of ``gymprecice train jet-cylinder-fast`` mid-episode, half a second after
    its first checkpoint: the coupling worker, pimpleFoam and the rest gone within 10 s;
    the same command resumes from the checkpoint and finishes.

    Cost: 27 to 29 s measured on 2 cores (74 s busy) with the module's pre-run cache:
    two short runs of 4 and 8 coupled actions (without the cache, a pre-run more: about
    45 s).
    """
    missing = _missing_openfoam()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    _coupled(Run(tmp_path, JET, jet_cache), {"pimpleFoam"})


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_jet_cylinder_killed_mid_save_leaves_nothing_and_resumes(tmp_path, jet_cache):
    """SIGKILL of ``gymprecice train jet-cylinder-fast`` while its second checkpoint's
    replay buffer (122 MB) is written: nothing left within 10 s, only a temporary file
    where the checkpoint was being saved; the same command resumes from the first
    checkpoint, with no word of a torn file, and finishes.

    Cost: 31 to 34 s measured on 2 cores (70 s busy) with the module's pre-run cache:
    two short runs of 8 and 8 coupled actions.
    """
    missing = _missing_openfoam()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    _saving(Run(tmp_path, JET, jet_cache))


# -- two-flaps-fast: four participants ----------------------------------------------------------


def _flaps(tmp_path: Path) -> Run:
    (tmp_path / "sac.yml").write_text(FLAPS_HYPERPARAMS)
    return Run(tmp_path, FLAPS)


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_two_flaps_killed_mid_reset_leaves_nothing_and_resumes(tmp_path):
    """SIGKILL of ``gymprecice train two-flaps-fast`` in its first reset, once the
    coupled run has done a time window of the gust that sets the start (6 windows, before
    the first action): pimpleFoam, both deal.II flaps, the coupling worker and the rest
    gone within 10 s; the same command starts over and finishes.

    Cost: 32 to 38 s measured on 2 cores (53 s busy): a first reset cut short, then 12
    coupled actions of the four participants and two resets.
    """
    missing = _missing_dealii()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    run = _flaps(tmp_path)
    iterations = tmp_path / "run/envs/env_0/fluid-openfoam/precice-Fluid-iterations.log"

    def in_the_gust() -> bool:  # a header, then a line per time window
        try:
            return 2 <= len(iterations.read_text().splitlines()) <= 6
        except OSError:
            return False

    solvers, _ = run.kill_when(in_the_gust)
    assert {"pimpleFoam", "elasticity"} <= set(solvers.values()), solvers
    assert len(iterations.read_text().splitlines()) <= 7  # killed before the first action
    assert not run.checkpoint(4).exists()
    assert "resuming from" not in run.resume()


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_two_flaps_killed_mid_coupling_leaves_nothing_and_resumes(tmp_path):
    """SIGKILL of ``gymprecice train two-flaps-fast`` mid-episode, half a second after its
    first checkpoint: the four participants' processes and the rest gone within 10 s; the
    same command resumes from the checkpoint and finishes.

    Cost: 28 to 29 s measured on 2 cores (59 s busy): runs of 4 and 8 coupled actions
    of the four participants.
    """
    missing = _missing_dealii()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    _coupled(_flaps(tmp_path), {"pimpleFoam", "elasticity"})


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.dealii
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_two_flaps_killed_mid_save_leaves_nothing_and_resumes(tmp_path):
    """SIGKILL of ``gymprecice train two-flaps-fast`` while its second checkpoint's
    replay buffer (164 MB) is written: nothing left within 10 s; the same command resumes
    from the first checkpoint and finishes.

    Cost: 26 to 38 s measured on 2 cores (59 s busy): runs of 8 and 8 coupled actions
    of the four participants.
    """
    missing = _missing_dealii()
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    _saving(_flaps(tmp_path))
