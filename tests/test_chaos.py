"""Chaos tests: real envs (Adapter, coupling worker, preCICE double, solver) failing on purpose.

Each case runs a :class:`~gymprecice.vector.ResilientVectorEnv` of two
:class:`gymprecice.testing.chaos.CylinderEnv` envs and makes env 1 fail, at reset or in
the middle of an episode, the way CFD runs fail: the solver is killed with SIGKILL, stopped
with SIGSTOP (hung), exits 1 with an error message, leaves a corrupt output file that the
env reads, has a broken case (a mesh patch missing at reset), or runs out of disk. Two more
cases hit the env process itself (SIGSTOP: the controller blocked in preCICE; SIGKILL),
which only the vector env, outside it, can resolve.

Every case checks that:

* the failure reaches the learner within the timeout, as a truncated episode with
  ``info["failure"]`` naming env 1 and carrying the log tail, and is logged;
* no process of the failed episode survives (every process seen descending from env 1's
  worker, or in its recorded process groups, is gone, except the new incarnation's);
* the pristine case directory is untouched (hashed before and after);
* env 0 keeps stepping, its episode unaffected;
* env 1's next episode (the reset done by the vector env) works.

How disk-full is simulated: see :mod:`gymprecice.testing.chaos` (RLIMIT_FSIZE on the
solver; mounting a tiny tmpfs needs privileges test machines rarely have).

Every case runs on the pyprecice double. The solver faults (SIGKILL, SIGSTOP, exit 1, at
reset and mid-episode), two envs failing at once, and two envs running whole episodes side
by side also run on real preCICE (marked ``precice``; skipped where ``import precice``
fails in a child interpreter): both the coupling worker and the solver then use pyprecice.
Real preCICE may finish a window or two with zero data after its partner died before
blocking; the contract is the same: the failure is reported within the timeout as a
truncation with ``info["failure"]``, the env respawns, nothing survives, the case is
pristine. "Nothing survives" allows one thing real pyprecice brings: the ``orted`` Open MPI
4 forks beside each MPI singleton (pyprecice imports mpi4py), in a session of its own,
which exits by itself a moment after its singleton died (see
:func:`gymprecice.testing.chaos.survivors`).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gymprecice.env.core import LIBRARY_ENV_VAR
from gymprecice.testing.chaos import (
    CylinderEnv,
    ProcessWatcher,
    corrupt_output,
    describe_processes,
    env_processes,
    inject,
    process_family,
    solver_groups,
    survivors,
    write_case,
)
from gymprecice.vector import ResilientVectorEnv

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="process checks read /proc"
)

FAILED = 1
#: Adapter timeouts (the precise reports) and the vector env's outer safety net.
PROGRESS_S = 4.0
STEP_TIMEOUT_S = 8.0
#: generous upper bound on "reported within the timeout" (loaded CI machines)
REPORT_BOUND_S = PROGRESS_S + STEP_TIMEOUT_S + 10.0

DOUBLE = "gymprecice.testing.fake_precice"
REAL = "precice"


def _real_precice_importable() -> bool:
    # pyprecice loads the preCICE C++ library: check in a child so that a broken install
    # skips instead of crashing the test process.
    probe = subprocess.run([sys.executable, "-c", "import precice"], capture_output=True)
    return probe.returncode == 0


#: Marks of a real-preCICE variant; a hang fails the test instead of blocking the run.
REAL_MARKS = [
    pytest.mark.precice,
    pytest.mark.skipif(
        not _real_precice_importable(), reason="pyprecice / the preCICE library is not installed"
    ),
    pytest.mark.timeout(180),
]
#: The faults that also run on real preCICE (ids of RESET_FAULTS and MID_FAULTS).
REAL_FAULTS = {"kill-9", "sigstop", "exit-1", "solver-kill-9", "solver-sigstop", "solver-exit-1"}

LIBRARIES = [
    pytest.param(DOUBLE, id="double"),
    pytest.param(REAL, id="real-precice", marks=REAL_MARKS),
]


def with_real_variants(cases: list[tuple]) -> list:
    """Each case on the double (id unchanged), plus ``<id>-real-precice`` for REAL_FAULTS."""
    params = [pytest.param(DOUBLE, *case[1:], id=case[0]) for case in cases]
    params += [
        pytest.param(REAL, *case[1:], id=f"{case[0]}-real-precice", marks=REAL_MARKS)
        for case in cases
        if case[0] in REAL_FAULTS
    ]
    return params


# -- helpers ---------------------------------------------------------------------------------


def tree_hash(root: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        digest.update(str(path.relative_to(root)).encode())
        if path.is_file():
            digest.update(path.read_bytes())
    return digest.hexdigest()


class Chaos:
    def __init__(self, tmp_path: Path, library: str = DOUBLE):
        self.tmp = tmp_path
        self.library = library
        self.faults = tmp_path / "faults"
        self.case = write_case(
            tmp_path / "case",
            self.faults,
            end_time=0.2,
            window=0.01,
            windows_per_step=2,
            timeouts={"progress": PROGRESS_S, "reset": 30, "kill_grace": 0.5},
            library=library,
        )
        self.runs = tmp_path / "runs"
        self.pristine = tree_hash(self.case)
        self.venv: ResilientVectorEnv | None = None

    def make(self, n: int = 2) -> ResilientVectorEnv:
        fns = [
            functools.partial(CylinderEnv, str(self.case), i, run_root=str(self.runs))
            for i in range(n)
        ]
        self.venv = ResilientVectorEnv(
            fns,
            step_timeout=STEP_TIMEOUT_S,
            reset_timeout=60,
            kill_grace=0.5,
            close_timeout=10,
            log_dir=self.tmp / "logs",
        )
        return self.venv

    def env_dir(self, index: int) -> Path:
        assert self.venv is not None
        run_dir = self.venv.pool.run_dirs[index]
        assert run_dir is not None
        return Path(run_dir)

    def act(self) -> np.ndarray:
        assert self.venv is not None
        return np.full((self.venv.num_envs, 1), 0.3, dtype=np.float32)


@pytest.fixture
def library() -> str:
    """The preCICE library of the case (tests parametrized on ``library`` override it)."""
    return DOUBLE


@pytest.fixture
def chaos(tmp_path, monkeypatch, library):
    # Coupling workers start faster without third-party plugins (they need none).
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")
    # The case's library is the env's and the solver's: no override of the env's side.
    monkeypatch.delenv(LIBRARY_ENV_VAR, raising=False)
    state = Chaos(tmp_path, library)
    yield state
    if state.venv is not None:
        state.venv.close()


def check_failure(
    infos: dict, failure_index: int, *, phase: str, kind: str, type_suffix: str, tail: str
) -> dict:
    failure = (
        {k: v[failure_index] for k, v in infos["failure"].items() if not k.startswith("_")}
        if phase == "step"
        else infos["reset_failures"][failure_index][0]
    )
    assert failure["env_index"] == failure_index
    assert failure["phase"] == phase and failure["kind"] == kind
    assert failure["type"].endswith(type_suffix), failure["type"]
    assert tail in failure["log_tail"], failure["log_tail"]
    return failure


def watch(venv: ResilientVectorEnv, index: int) -> ProcessWatcher:
    return ProcessWatcher(lambda: env_processes(venv.pool, index))


def finish(chaos: Chaos, watcher: ProcessWatcher, caplog, *, steps: int = 2) -> None:
    """After the failure: env 1 runs its new episode, nothing old survives, case pristine."""
    venv = chaos.venv
    assert venv is not None
    assert any(f"env {FAILED} failed" in r.getMessage() for r in caplog.records)
    times = []
    for _ in range(steps):
        obs, _, _, truncs, infos = venv.step(chaos.act())
        assert "failure" not in infos and not truncs.any()
        times.append(obs[:, 4].copy())
    assert np.all(np.diff(np.array(times), axis=0) > 0)  # both envs advance in time
    watcher.stop()
    current = watcher.sample()
    leaked = survivors(watcher.seen, keep=current)
    assert not leaked, f"processes of the failed episode survived: {describe_processes(leaked)}"
    assert tree_hash(chaos.case) == chaos.pristine
    assert len(venv.failures) == 1
    venv.close()
    leaked = survivors(watcher.seen | current)
    assert not leaked, f"processes survived close(): {describe_processes(leaked)}"


# -- faults at reset ---------------------------------------------------------------------------

RESET_FAULTS = [
    # (id, phase, fault, params, failure kind/type, text in the log tail)
    ("kill-9", "run", "kill", {}, "SolverCrashedError", "SIGKILL before connecting"),
    ("sigstop", "run", "stop", {}, "SolverTimeoutError", "SIGSTOP before connecting"),
    ("exit-1", "run", "exit", {"code": 1}, "SolverCrashedError", "FOAM FATAL ERROR"),
    ("corrupt-output", "run", "corrupt-output", {}, "ValueError", "corrupt forceCoeffs"),
    ("missing-patch", "reset", "bad-case", {"patch": "jet1"}, "SolverCrashedError", "'jet1'"),
    ("disk-full", "run", "disk-full", {"headroom": 0}, "SolverCrashedError", "disk full"),
]


@pytest.mark.parametrize(
    ("library", "phase", "fault", "params", "type_suffix", "tail"),
    with_real_variants(RESET_FAULTS),
)
def test_fault_at_reset(chaos, caplog, library, phase, fault, params, type_suffix, tail):
    """Cost: about 3 to 9 s per case, most of it waiting: a SIGSTOP case waits out the reset
    timeout it checks; the real-preCICE cases add its start-up.
    """
    caplog.set_level(logging.WARNING, logger="gymprecice.vector")
    venv = chaos.make()
    watcher = watch(venv, FAILED)
    inject(chaos.faults, FAILED, phase, fault, **params)
    started = time.monotonic()
    obs, infos = venv.reset(seed=0)
    assert time.monotonic() - started < REPORT_BOUND_S + 10
    assert infos["_reset_failures"].tolist() == [False, True]
    check_failure(infos, FAILED, phase="reset", kind="error", type_suffix=type_suffix, tail=tail)
    assert np.all(obs[:, 4] == 0.0)  # both envs start their episode
    finish(chaos, watcher, caplog)


# -- faults in the middle of an episode -------------------------------------------------------


def _signal_solver(chaos: Chaos, sig: signal.Signals) -> None:
    groups = solver_groups(chaos.env_dir(FAILED))
    assert len(groups) == 1
    os.killpg(groups[0], sig)


def _signal_worker(chaos: Chaos, sig: signal.Signals) -> None:
    assert chaos.venv is not None
    pid = chaos.venv.pool.worker_pids[FAILED]
    assert pid is not None
    os.kill(pid, sig)


#: A solver signalled right after the env's 2nd step (window 4) may not have printed its
#: window-4 line yet, with either library: the env's advance() returns once the solver has
#: sent its data, before the solver's own advance() returned. Its window-3 line is always
#: in the tail.
MID_FAULTS = [
    # (id, armed before reset, action after 2 steps, kind, type, text in the log tail)
    (
        "solver-kill-9",
        None,
        lambda c: _signal_solver(c, signal.SIGKILL),
        "error",
        "SolverCrashedError",
        "[Fluid] window 3",
    ),
    (
        "solver-sigstop",
        None,
        lambda c: _signal_solver(c, signal.SIGSTOP),
        "error",
        "SolverTimeoutError",
        "[Fluid] window 3",
    ),
    (
        "solver-exit-1",
        ("exit", {"window": 5, "code": 1}),
        None,
        "error",
        "SolverCrashedError",
        "FOAM FATAL ERROR",
    ),
    (
        "corrupt-output",
        None,
        lambda c: corrupt_output(c.env_dir(FAILED) / "fluid"),
        "error",
        "ValueError",
        "corrupt forceCoeffs",
    ),
    (
        "disk-full",
        ("disk-full", {"headroom": 1500}),
        None,
        "error",
        "SolverCrashedError",
        "disk full",
    ),
    (
        "env-process-sigstop",
        None,
        lambda c: _signal_worker(c, signal.SIGSTOP),
        "timeout",
        "Timeout",
        "worker pid",
    ),
    (
        "env-process-kill-9",
        None,
        lambda c: _signal_worker(c, signal.SIGKILL),
        "crash",
        "WorkerCrashed",
        "worker pid",
    ),
]


def fail_mid_episode(
    chaos: Chaos, venv, armed, action, kind: str, type_suffix: str, tail: str
) -> tuple[dict, list[int], float]:
    """Two good steps, the fault, then steps until env 1's episode ends in a failure.

    Asserts what every backend must give: the failure surfaces within a few steps as a
    truncation of env 1 alone, with a zero reward, env 1 already in its next episode and
    its last observation in ``final_obs``, while env 0 goes on. Returns the failure, the
    solver groups env 1 had before the fault and the seconds from the fault to the report.
    """
    if armed is not None:
        inject(chaos.faults, FAILED, "run", armed[0], **armed[1])
    venv.reset(seed=0)
    for _ in range(2):
        obs, _, _, truncs, infos = venv.step(chaos.act())
        assert "failure" not in infos
    last = obs.copy()
    groups_before = solver_groups(chaos.env_dir(FAILED))
    if action is not None:
        action(chaos)
    started = time.monotonic()
    failure = None
    for _ in range(6):  # an armed fault fires within a few steps
        obs, rewards, terms, truncs, infos = venv.step(chaos.act())
        assert not truncs[0]
        if truncs[FAILED]:
            failure = check_failure(
                infos, FAILED, phase="step", kind=kind, type_suffix=type_suffix, tail=tail
            )
            break
        last = obs.copy()
    assert failure is not None, "the fault never surfaced"
    seconds = time.monotonic() - started
    assert rewards[FAILED] == 0.0 and not terms.any()
    assert obs[FAILED, 4] == 0.0  # env 1 already runs its next episode
    assert np.array_equal(infos["final_obs"][FAILED], last[FAILED])  # last obs it saw
    assert obs[0, 4] > last[0, 4]  # env 0 went on
    return failure, groups_before, seconds


@pytest.mark.parametrize(
    ("library", "armed", "action", "kind", "type_suffix", "tail"),
    with_real_variants(MID_FAULTS),
)
def test_fault_mid_episode(chaos, caplog, library, armed, action, kind, type_suffix, tail):
    """Cost: about 3 to 14 s per case, most of it waiting for the fault's report (a SIGSTOP case
    waits out the progress timeout it checks).
    """
    caplog.set_level(logging.WARNING, logger="gymprecice.vector")
    venv = chaos.make()
    watcher = watch(venv, FAILED)
    _, groups_before, seconds = fail_mid_episode(
        chaos, venv, armed, action, kind, type_suffix, tail
    )
    assert seconds < REPORT_BOUND_S
    if kind != "error":
        # The env process died (or was killed by the vector env): its solver groups died
        # with it (PR_SET_PDEATHSIG, its watchdog), or the vector env killed what was left.
        left = process_family(None, groups_before)
        assert not survivors(left), describe_processes(left)
    finish(chaos, watcher, caplog)


@pytest.mark.parametrize("library", LIBRARIES)
def test_two_envs_failing_at_once_recover_in_parallel(chaos, caplog, library):
    """Cost: about 5 s per library (two envs, two faults, two recoveries)."""
    venv = chaos.make(n=3)
    watchers = [watch(venv, 1), watch(venv, 2)]
    venv.reset(seed=0)
    venv.step(chaos.act())
    os.killpg(solver_groups(chaos.env_dir(1))[0], signal.SIGKILL)
    os.kill(venv.pool.worker_pids[2], signal.SIGKILL)
    obs, _, _, truncs, infos = venv.step(chaos.act())
    assert list(truncs) == [False, True, True]
    assert [infos["failure"]["env_index"][i] for i in (1, 2)] == [1, 2]
    assert obs[0, 4] > 0 and np.all(obs[1:, 4] == 0.0)
    venv.step(chaos.act())
    current = set()
    for watcher in watchers:
        watcher.stop()
        current |= watcher.sample()
    leaked = survivors(set().union(*(w.seen for w in watchers)), keep=current)
    assert not leaked, f"processes of the failed episodes survived: {describe_processes(leaked)}"
    assert tree_hash(chaos.case) == chaos.pristine


# -- two envs running whole episodes side by side ----------------------------------------------


@pytest.mark.parametrize("library", LIBRARIES)
def test_two_envs_run_whole_episodes_side_by_side(tmp_path, monkeypatch, library):
    """Two envs couple at once (each its own worker, solver and exchange directory) through
    two whole episodes; both advance every step, and nothing runs after close().

    Cost: about 7 s per library (two whole episodes at once).
    """
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")
    monkeypatch.delenv(LIBRARY_ENV_VAR, raising=False)
    windows, per_step = 6, 2
    case = write_case(
        tmp_path / "case",
        tmp_path / "faults",
        end_time=windows * 0.01,
        window=0.01,
        windows_per_step=per_step,
        timeouts={"progress": PROGRESS_S, "reset": 30, "kill_grace": 0.5},
        library=library,
    )
    pristine = tree_hash(case)
    fns = [
        functools.partial(CylinderEnv, str(case), i, run_root=str(tmp_path / "runs"))
        for i in range(2)
    ]
    venv = ResilientVectorEnv(
        fns, step_timeout=STEP_TIMEOUT_S, reset_timeout=60, kill_grace=0.5, close_timeout=10
    )
    watchers = [watch(venv, 0), watch(venv, 1)]
    actions = np.array([[0.0], [0.9]], dtype=np.float32)
    try:
        obs, _ = venv.reset(seed=0)
        assert venv.pool.run_dirs[0] != venv.pool.run_dirs[1]
        for _episode in range(2):
            assert np.all(obs[:, 4] == 0.0)
            times = [obs[:, 4].copy()]
            for step in range(windows // per_step):
                obs, _, terms, truncs, infos = venv.step(actions)
                assert "failure" not in infos and not terms.any()
                last = step == windows // per_step - 1
                assert list(truncs) == [last, last]  # the coupling's end time: a time limit
                final = np.asarray(infos["final_obs"].tolist()) if last else obs.copy()
                times.append(final[:, 4])
            times = np.array(times)
            assert np.all(np.diff(times, axis=0) > 0)  # both envs advance every step
            assert times[-1] == pytest.approx([windows * 0.01] * 2)
            # each solver got its own env's jets through preCICE: blowing changes the drag
            assert final[0, 3] != final[1, 3]
        assert not venv.failures
    finally:
        venv.close()
    seen = set()
    for watcher in watchers:
        seen |= watcher.stop()
    assert len(seen) >= 2 * 2 * 2  # two episodes of two envs: worker and solver each
    leaked = survivors(seen)
    assert not leaked, f"processes survived close(): {describe_processes(leaked)}"
    assert tree_hash(case) == pristine
