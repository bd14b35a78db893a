"""Soak: 100 short episodes on 4 real envs with random, seeded faults; nothing hangs or leaks.

Four :class:`gymprecice.testing.chaos.CylinderEnv` envs (Adapter, coupling worker, preCICE
double, solver process each) run short episodes while a seeded random schedule breaks
them: solvers killed, stopped, exiting 1, running out of disk, outputs corrupted, a case
broken at reset, env processes killed. The test checks that

* the run finishes before a global deadline (nothing hung), and no single batch step
  took longer than the vector env's own timeouts allow;
* every episode that completed kept all its data: as many rewards and observations as
  steps, times advancing window by window up to the end time, rewards consistent with
  the observations;
* every episode cut short by a failure was reported as truncated with its failure;
* each env's worker log and solver log exist;
* no process of any env survives the run (all processes seen during the run are gone
  within 5 s of the close, and every process started with this run's fault directory in
  its environment is gone).
"""

from __future__ import annotations

import functools
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from gymprecice.testing.chaos import (
    FAULTS_VARIABLE,
    CylinderEnv,
    ProcessWatcher,
    corrupt_output,
    describe_processes,
    env_processes,
    inject,
    processes_with_environment,
    solver_groups,
    write_case,
)
from gymprecice.vector import ResilientVectorEnv

pytestmark = [pytest.mark.slow, pytest.mark.waits]  # bounded by timeouts, not CPU

N_ENVS = 4
EPISODES = 100
STEPS_PER_EPISODE = 3  # end time 0.06, windows of 0.01, 2 windows per step
END_TIME = 0.06
#: a hang, not a slow machine: the run takes 70 to 140 s on 2 cores (more while other
#: tests' solvers share them); each batch step is bounded by the vector env's timeouts
DEADLINE_S = 600.0
STEP_TIMEOUT_S = 8.0
RESET_TIMEOUT_S = 60.0
FAULT_PROBABILITY = 0.08  # per env and batch step: about one episode in four fails

ARMED = [  # consumed by the env's next solver launch / reset step
    ("run", "kill", {"window": 3}),
    ("run", "exit", {"window": 2, "code": 1}),
    ("run", "exit", {"window": 0, "code": 1}),
    ("run", "disk-full", {"headroom": 900}),
    ("run", "corrupt-output", {}),
    ("reset", "bad-case", {"patch": "jet2"}),
]
EXTERNAL = ["solver-kill", "solver-stop", "worker-kill"]


def _external(venv: ResilientVectorEnv, index: int, what: str) -> bool:
    pool = venv.pool
    run_dir = pool.run_dirs[index]
    if what == "worker-kill":
        pid = pool.worker_pids[index]
        if pid is None:
            return False
        os.kill(pid, signal.SIGKILL)
        return True
    groups = solver_groups(run_dir) if run_dir else []
    if not groups:
        return False
    sig = signal.SIGKILL if what == "solver-kill" else signal.SIGSTOP
    try:
        os.killpg(groups[0], sig)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.timeout(900)
def test_soak_100_episodes_with_random_faults(tmp_path, monkeypatch):
    monkeypatch.setenv("GYMPRECICE_DISABLE_PLUGINS", "1")
    rng = np.random.default_rng(20240917)
    faults = tmp_path / "faults"
    case = write_case(
        tmp_path / "case",
        faults,
        end_time=END_TIME,
        window=0.01,
        windows_per_step=2,
        timeouts={"progress": 3.0, "reset": 30, "kill_grace": 0.5},
    )
    fns = [
        functools.partial(CylinderEnv, str(case), i, run_root=str(tmp_path / "runs"))
        for i in range(N_ENVS)
    ]
    started = time.monotonic()
    venv = ResilientVectorEnv(
        fns,
        step_timeout=STEP_TIMEOUT_S,
        reset_timeout=RESET_TIMEOUT_S,
        max_failures_per_env=25,
        failure_window=25,
        kill_grace=0.5,
        close_timeout=10,
        log_dir=tmp_path / "logs",
    )
    watchers = [
        ProcessWatcher(functools.partial(env_processes, venv.pool, i), interval=0.1)
        for i in range(N_ENVS)
    ]
    completed: list[dict] = []
    failed: list[dict] = []
    episodes = [{"rewards": [], "obs": []} for _ in range(N_ENVS)]
    injected = 0
    longest_step = 0.0
    try:
        obs, _ = venv.reset(seed=7)
        for i in range(N_ENVS):
            episodes[i]["obs"].append(obs[i].copy())
        while len(completed) + len(failed) < EPISODES:
            assert time.monotonic() - started < DEADLINE_S, "the soak run hung"
            for i in range(N_ENVS):
                if rng.random() < FAULT_PROBABILITY:
                    if rng.random() < 0.6:
                        phase, fault, params = ARMED[rng.integers(len(ARMED))]
                        inject(faults, i, phase, fault, **params)
                        injected += 1
                    else:
                        injected += _external(venv, i, EXTERNAL[rng.integers(len(EXTERNAL))])
                    if rng.random() < 0.2:  # a corrupted output mid-episode, too
                        run_dir = venv.pool.run_dirs[i]
                        if run_dir:
                            corrupt_output(Path(run_dir) / "fluid")
            action = rng.uniform(-1, 1, size=(N_ENVS, 1)).astype(np.float32)
            step_started = time.monotonic()
            obs, rewards, terms, truncs, infos = venv.step(action)
            longest_step = max(longest_step, time.monotonic() - step_started)
            for i in range(N_ENVS):
                episode = episodes[i]
                if not truncs[i] and not terms[i]:
                    episode["rewards"].append(float(rewards[i]))
                    episode["obs"].append(obs[i].copy())
                    continue
                if infos.get("_failure", np.zeros(N_ENVS, bool))[i]:
                    episode["failure"] = infos["failure"]["kind"][i]
                    failed.append(episode)
                else:
                    episode["rewards"].append(float(rewards[i]))
                    episode["obs"].append(infos["final_obs"][i].copy())
                    completed.append(episode)
                episodes[i] = {"rewards": [], "obs": [obs[i].copy()]}
    finally:
        venv.close()
        for watcher in watchers:
            watcher.stop()
    elapsed = time.monotonic() - started
    print(
        f"soak: {len(completed)} completed and {len(failed)} failed episodes, {injected} "
        f"faults, {len(venv.failures)} failures, {elapsed:.0f} s, longest step "
        f"{longest_step:.1f} s\n{venv.telemetry.summary()}"
    )

    # nothing hung
    assert elapsed < DEADLINE_S
    assert longest_step < RESET_TIMEOUT_S * 2 + STEP_TIMEOUT_S
    # faults happened and were survived
    assert injected >= 10 and len(failed) >= 5 and len(completed) >= 50
    assert len(venv.failures) >= len(failed)
    # every completed episode kept all its data
    for episode in completed:
        rewards, observations = episode["rewards"], np.array(episode["obs"])
        assert len(rewards) == STEPS_PER_EPISODE == len(observations) - 1
        times = observations[:, 4]
        assert times[0] == 0.0
        assert np.allclose(np.diff(times), 0.02, atol=1e-6)
        assert times[-1] == pytest.approx(END_TIME)
        assert np.allclose(rewards, -observations[1:, 3], atol=1e-5)  # reward = -drag read
    for episode in failed:
        assert episode["failure"] in ("error", "crash", "timeout")
    # logs of every env exist
    for i in range(N_ENVS):
        assert (tmp_path / "logs" / f"env_{i}.log").stat().st_size > 0
        assert (tmp_path / "runs" / f"env_{i}" / "fluid" / "solver.log").exists()
    # nothing leaked
    leaked = sorted({p for w in watchers for p in w.leaked(within=5.0)})
    assert not leaked, f"processes survived the run: {describe_processes(leaked)}"
    assert processes_with_environment(FAULTS_VARIABLE, str(faults.resolve())) == []
