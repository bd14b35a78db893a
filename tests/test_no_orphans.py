"""No solver outlives the process that owns its env, whatever kills that process.

A user ran ``gymprecice evaluate``, killed its Python process with ``kill -9`` and found
``pimpleFoam`` computing on, reparented to init. The same happens when a job's time limit,
the OOM killer or a closed terminal ends the process: no clean-up code of the process runs.
Three layers stop the solvers (:mod:`gymprecice.owner_watchdog`), and each is tested here
alone, with the others made to fail, then all together on an env of the test double and,
once, on the real stack:

* ``PR_SET_PDEATHSIG``: the direct child gets SIGKILL when its owner dies, even when a
  short-lived thread started it (the signal follows the thread that forked);
* the watchdog: kills the rest of each recorded process group (what a script or ``mpirun``
  started, without ``PR_SET_PDEATHSIG``), and exits on its own after a normal close;
* ``gymprecice clean`` for what both missed: see tests/test_clean.py.

Every owner here is a subprocess with its own ``XDG_STATE_HOME`` (the owner index), killed
with SIGKILL.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from gymprecice.env.pidregistry import PidRegistry
from gymprecice.testing.chaos import describe_processes, pid_alive, write_case

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG and /proc are Linux's"
)

#: How long the layers may take to stop everything after the owner died.
STOP_BOUND_S = 5.0

_OWNER_HEAD = """
import json, os, sys, threading, time
from pathlib import Path
from gymprecice import owner_watchdog
from gymprecice.env import launching
from gymprecice.env.processes import PidRegistry, SolverProcess
from gymprecice.plugin.solver import LaunchSpec

env_dir = Path(sys.argv[1])
env_dir.mkdir(parents=True, exist_ok=True)

def report(**values):
    print("REPORT " + json.dumps(values), flush=True)
"""


def _owner(tmp_path: Path, body: str) -> tuple[subprocess.Popen[str], dict]:
    """Start an owner process running ``body``; wait for its REPORT line."""
    script = tmp_path / "owner.py"
    script.write_text(_OWNER_HEAD + textwrap.dedent(body))
    env = {**os.environ, "XDG_STATE_HOME": str(tmp_path / "state")}
    proc = subprocess.Popen(
        [sys.executable, str(script), str(tmp_path / "env")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    if not line.startswith("REPORT "):
        proc.kill()
        raise AssertionError(f"the owner did not report: {line}{proc.communicate()[1]}")
    return proc, json.loads(line[len("REPORT ") :])


def _members(env_dir: Path) -> set[int]:
    """Every live process of the groups recorded in ``env_dir``, and of their sessions
    (``mpirun`` puts each rank in a process group of its own, inside its session)."""
    recorded = set(PidRegistry(env_dir).pgids())
    found = set()
    for entry in os.scandir("/proc"):
        try:
            data = Path(entry.path, "stat").read_bytes() if entry.name.isdigit() else b""
        except OSError:
            continue
        fields = data[data.rfind(b")") + 2 :].split()
        alive = len(fields) > 3 and fields[0] not in (b"Z", b"X")
        if alive and {int(fields[2]), int(fields[3])} & recorded:  # group, session
            found.add(int(entry.name))
    return found


def _wait_dead(pids: set[int], timeout: float = STOP_BOUND_S) -> list[int]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not any(pid_alive(p) for p in pids):
            return []
        time.sleep(0.02)
    return sorted(p for p in pids if pid_alive(p))


def _kill_all(pids: set[int]) -> None:
    for pid in pids:
        if pid_alive(pid):
            os.kill(pid, signal.SIGKILL)


def test_pdeathsig_alone_stops_the_direct_child_even_from_a_finished_thread(tmp_path):
    """The watchdog dies first; a solver started from a thread that has ended survives that
    thread and dies with its owner. Cost: about 1 s (one owner process)."""
    owner, report = _owner(
        tmp_path,
        """
        started = {}
        spec = LaunchSpec(["sleep", "1000"], env_dir)
        thread = threading.Thread(
            target=lambda: started.update(p=SolverProcess.start("s", spec, registry=PidRegistry(env_dir)))
        )
        thread.start(); thread.join()  # the forking thread is gone: the solver must not be
        time.sleep(0.2)
        watchdog = owner_watchdog.watchdog_pid()
        os.kill(watchdog, 9); os.waitpid(watchdog, 0)
        report(solver=started["p"].pid, alive=started["p"].poll() is None)
        time.sleep(1000)
        """,
    )
    solver = report["solver"]
    try:
        assert report["alive"], "the solver died with the thread that started it"
        owner.kill()
        owner.wait()
        assert _wait_dead({solver}, 2.0) == [], describe_processes([solver])
    finally:
        owner.kill()
        _kill_all({solver})


def test_the_watchdog_alone_stops_a_launcher_whose_children_have_no_pdeathsig(tmp_path):
    """No ``PR_SET_PDEATHSIG`` at all (as for the ranks under ``mpirun``, or a script's
    children): the watchdog kills the whole recorded group, says so in the run directory,
    and forgets its owner in the index. Cost: about 1 s (one owner process)."""
    owner, report = _owner(
        tmp_path,
        """
        launching.die_with_parent_hook = lambda: None
        spec = LaunchSpec(["bash", "-c", "sleep 1000 & sleep 1000 & wait"], env_dir)
        proc = SolverProcess.start("s", spec, registry=PidRegistry(env_dir))
        report(watchdog=owner_watchdog.watchdog_pid())
        time.sleep(1000)
        """,
    )
    env_dir = tmp_path / "env"
    deadline = time.monotonic() + 5
    while len(_members(env_dir)) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    members = _members(env_dir)
    try:
        assert len(members) == 3, describe_processes(members)
        owner.kill()
        owner.wait()
        assert _wait_dead(members) == [], describe_processes(members)
        assert _wait_dead({report["watchdog"]}, 2.0) == [], "the watchdog did not exit"
        assert "stopped process groups" in (env_dir / ".gymprecice" / "watchdog.log").read_text()
        assert not list((tmp_path / "state").rglob("owners/*/*")), "the owner is still indexed"
    finally:
        owner.kill()
        _kill_all(members)


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun is not on PATH")
def test_mpirun_and_its_ranks_die_with_their_owner(tmp_path):
    """``mpirun -np 2``: the launcher gets SIGKILL from the kernel and cannot stop its ranks
    itself; the watchdog stops them (they carry the launch token). Cost: about 1 s."""
    owner, _ = _owner(
        tmp_path,
        """
        os.environ.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                          OMPI_MCA_rmaps_base_oversubscribe="1")
        spec = LaunchSpec(["mpirun", "-np", "2", "sleep", "1000"], env_dir)
        proc = SolverProcess.start("mpi", spec, registry=PidRegistry(env_dir))
        report(pgid=proc.pgid)
        time.sleep(1000)
        """,
    )
    env_dir = tmp_path / "env"
    deadline = time.monotonic() + 10
    while len(_members(env_dir)) < 3 and time.monotonic() < deadline:
        time.sleep(0.02)
    members = _members(env_dir)
    try:
        assert len(members) >= 3, describe_processes(members)  # mpirun and two ranks
        owner.kill()
        owner.wait()
        assert _wait_dead(members) == [], describe_processes(members)
    finally:
        owner.kill()
        _kill_all(members)


def test_the_watchdog_exits_by_itself_after_a_normal_close(tmp_path):
    """An owner that ends its solvers and exits normally leaves no watchdog and no index
    entry behind. Cost: about 0.7 s (one owner process)."""
    owner, report = _owner(
        tmp_path,
        """
        proc = SolverProcess.start("s", LaunchSpec(["sleep", "1000"], env_dir), registry=PidRegistry(env_dir))
        proc.terminate()
        report(watchdog=owner_watchdog.watchdog_pid())
        """,
    )
    assert owner.wait(10) == 0
    assert _wait_dead({report["watchdog"]}, 2.0) == [], "the watchdog outlived a normal close"
    assert not list((tmp_path / "state").rglob("owners/*/*")), "the owner is still indexed"
    assert not (tmp_path / "env" / ".gymprecice" / "watchdog.log").exists()


_ENV_OWNER = """
import json, sys, time
from pathlib import Path
import numpy as np
from gymprecice import owner_watchdog
from gymprecice.testing.chaos import CylinderEnv

case = Path(sys.argv[1])
env = CylinderEnv(case, 0, run_root=case.parent / "runs")
env.reset(seed=0)
env.step(np.zeros(1, dtype=np.float32))
session = env._gymprecice.run.session
print("REPORT " + json.dumps({
    "env_dir": str(env.env_dir),
    "worker": session.worker.pid,
    "solvers": [p.pid for p in session.solvers],
    "watchdog": owner_watchdog.watchdog_pid(),
}), flush=True)
time.sleep(1000)
"""


def test_sigkill_of_an_env_process_leaves_no_solver(tmp_path):
    """The user's report on the test double: an env mid-episode (coupling worker, solver
    and a process the solver's script left in the background) loses its process to
    SIGKILL; within a few seconds nothing of its recorded groups is alive.
    Cost: about 2 s (one env on the double, one reset and step)."""
    case = write_case(tmp_path / "case", tmp_path / "faults")
    config_file = case / "gymprecice-config.json"
    config = json.loads(config_file.read_text())
    options = config["physics_simulation_engine"]["solvers"]["fluid"]["options"]
    # the solver's script leaves a process behind, as a wrapper or launcher does
    options["argv"] = ["sh", "-c", 'sleep 1000 & exec "$@"', "solver", *options["argv"]]
    config_file.write_text(json.dumps(config))
    script = tmp_path / "env_owner.py"
    script.write_text(_ENV_OWNER)
    owner = subprocess.Popen(
        [sys.executable, str(script), str(case)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "XDG_STATE_HOME": str(tmp_path / "state")},
    )
    assert owner.stdout is not None
    line = owner.stdout.readline()
    if not line.startswith("REPORT "):
        owner.kill()
        raise AssertionError(f"the env did not start: {line}{owner.communicate()[1]}")
    report = json.loads(line[len("REPORT ") :])
    members = _members(Path(report["env_dir"])) | {report["worker"], *report["solvers"]}
    try:
        assert len(members) >= 3, describe_processes(members)  # worker, solver, sleep
        owner.send_signal(signal.SIGKILL)
        owner.wait()
        started = time.monotonic()
        left = _wait_dead(members)
        assert left == [], describe_processes(left)
        took = time.monotonic() - started
        assert _wait_dead({report["watchdog"]}, 2.0) == []
        print(f"all {len(members)} processes gone {took:.2f} s after the SIGKILL")
    finally:
        owner.kill()
        _kill_all(members)


# -- the user's report, on the real stack --------------------------------------------------------


def _alive_pimplefoams(under: Path) -> set[int]:
    """Live (not zombie) ``pimpleFoam`` processes working in a directory under ``under``."""
    found = set()
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            if Path(entry.path, "comm").read_text().strip() != "pimpleFoam":
                continue
            cwd = Path(os.readlink(Path(entry.path, "cwd")))
        except OSError:
            continue
        if cwd.is_relative_to(under) and pid_alive(int(entry.name)):
            found.add(int(entry.name))
    return found


def _program(cmdline: str) -> str:
    """The program's file name in a command line (empty for a process already exiting)."""
    words = cmdline.split()
    return Path(words[0]).name if words else ""


def _children(pid: int) -> dict[int, str]:
    """``pid -> command line`` of the live children of ``pid``."""
    found = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            data = Path(entry.path, "stat").read_bytes()
            argv = Path(entry.path, "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        fields = data[data.rfind(b")") + 2 :].split()
        if int(fields[1]) == pid and fields[0] not in (b"Z", b"X"):
            found[int(entry.name)] = argv
    return found


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_kill_9_of_gymprecice_evaluate_leaves_no_pimplefoam(tmp_path):
    """``gymprecice evaluate jet-cylinder-fast --policy shipped --episode-time 2`` on the
    real stack, ``kill -9`` of its Python process once its coupling worker and pimpleFoam
    run: within 10 s no pimpleFoam of the run is left (it went on computing, reparented to
    init, before).

    Cost: about 1 min on 2 cores (53 s measured; 3 min on a busy machine): blockMesh and
    the 5 s pre-run unless the session's pre-run cache has them, then the kill a second
    into the coupled episode.
    """
    from gymprecice_openfoam.testing import missing_coupled_stack

    missing = missing_coupled_stack("pimpleFoam")
    if missing:
        pytest.skip("needs " + ", ".join(missing))
    argv = [sys.executable, "-m", "gymprecice", "evaluate", "jet-cylinder-fast"]
    argv += ["--policy", "shipped", "--episode-time", "2", "--seed", "0", "--out", "run"]
    log = tmp_path / "evaluate.log"
    with log.open("wb") as out:
        evaluate = subprocess.Popen(
            argv,
            cwd=tmp_path,
            stdout=out,
            stderr=subprocess.STDOUT,
            env={**os.environ, "XDG_STATE_HOME": str(tmp_path / "state")},
        )
    coupled: set[int] = set()
    try:
        deadline = time.monotonic() + 1000
        while time.monotonic() < deadline and evaluate.poll() is None:
            children = _children(evaluate.pid)
            worker = any("gymprecice._worker" in cmd for cmd in children.values())
            coupled = {p for p, cmd in children.items() if _program(cmd) == "pimpleFoam"}
            if worker and coupled:
                break
            time.sleep(0.2)
        assert coupled, f"pimpleFoam never ran coupled:\n{log.read_text()[-3000:]}"
        time.sleep(1.0)  # computing
        evaluate.send_signal(signal.SIGKILL)
        evaluate.wait()
        deadline = time.monotonic() + 10
        left = coupled | _alive_pimplefoams(tmp_path)
        while time.monotonic() < deadline and left:
            time.sleep(0.1)
            left = {p for p in coupled if pid_alive(p)} | _alive_pimplefoams(tmp_path)
        assert not left, f"pimpleFoam left 10 s after kill -9: {describe_processes(left)}"
    finally:
        evaluate.kill()
        _kill_all(coupled | _alive_pimplefoams(tmp_path))
