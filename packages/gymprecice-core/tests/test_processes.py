"""Solver process supervision: groups, logs, exit wake-ups, kills, registry, MPI env."""

from __future__ import annotations

import importlib.util
import json
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
import time
from multiprocessing import connection
from pathlib import Path

import pytest

from gymprecice.env import launching
from gymprecice.env.processes import (
    PROCESS_TOKEN_VARIABLE,
    PidRegistry,
    SolverProcess,
    clean_mpi_environment,
    kill_recorded_groups,
    read_tail,
    run_to_completion,
)
from gymprecice.plugin.errors import CaseError, SolverCrashedError, SolverTimeoutError
from gymprecice.plugin.solver import LaunchSpec

pytestmark = pytest.mark.skipif(
    not Path("/proc/self/stat").exists(), reason="these checks read /proc (Linux)"
)

TREE = ["bash", "-c", "sleep 1000 & sleep 1000 & wait"]


def _state(pid: int) -> str | None:
    """The /proc state letter of a pid, or None when the pid is gone."""
    try:
        data = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return None
    return data[data.rfind(b")") + 2 :].split()[0].decode()


def _ppid(pid: int) -> int | None:
    try:
        data = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return None
    return int(data[data.rfind(b")") + 2 :].split()[1])


def _dead(pid: int) -> bool:
    """Gone, or a zombie that init (not this test process) still has to reap."""
    state = _state(pid)
    return state is None or (state == "Z" and _ppid(pid) != os.getpid())


def _group(pgid: int) -> list[int]:
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                data = (entry / "stat").read_bytes()
            except OSError:
                continue
            fields = data[data.rfind(b")") + 2 :].split()
            if int(fields[2]) == pgid and fields[0] != b"Z":
                pids.append(int(entry.name))
    return pids


def _wait_for(predicate, timeout: float = 2.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return predicate()


@pytest.fixture(params=["pidfd", "pipe"])
def wake_mode(request, monkeypatch):
    """Run a test with pidfds and again with the pipe fallback."""
    if request.param == "pidfd":
        if not launching._pidfd_available():
            pytest.skip("pidfd_open is not available on this kernel")
    else:
        monkeypatch.setattr(launching, "_pidfd_checked", False)
    return request.param


# -- start, log, exit status -------------------------------------------------------------


def test_start_runs_in_own_group_with_log_cwd_env_and_devnull_stdin(tmp_path, monkeypatch):
    monkeypatch.setenv("OMPI_MCA_ess", "singleton")
    monkeypatch.setenv("OMPI_ALLOW_RUN_AS_ROOT", "1")
    script = (
        'echo "foo=$FOO ess=${OMPI_MCA_ess-unset} root=$OMPI_ALLOW_RUN_AS_ROOT"; '
        f'echo "token=${{{PROCESS_TOKEN_VARIABLE}:+set}}"; pwd; cat; echo to-stderr >&2'
    )
    spec = LaunchSpec(["sh", "-c", script], tmp_path, env={"FOO": "bar"}, log_name="fluid.log")
    proc = SolverProcess.start("fluid", spec)
    try:
        assert proc.pgid == proc.pid == os.getpgid(proc.pid)
        assert os.getsid(proc.pid) == proc.pid
        assert proc.wait(5) == 0  # `cat` would block without stdin=/dev/null
        assert proc.log_path == tmp_path / "fluid.log"
        assert proc.log_path.read_text().splitlines() == [
            "foo=bar ess=unset root=1",
            "token=set",
            str(tmp_path),
            "to-stderr",
        ]
        assert proc.log_size() == proc.log_path.stat().st_size > 0
        assert proc.log_tail(2) == f"{tmp_path}\nto-stderr\n"
    finally:
        proc.terminate()


def test_log_truncated_per_episode_unless_append(tmp_path):
    spec = LaunchSpec(["sh", "-c", "echo episode"], tmp_path)
    for append in (False, False, True):
        with SolverProcess.start("s", spec, append=append) as proc:
            proc.wait(5)
    assert (tmp_path / "solver.log").read_text() == "episode\nepisode\n"


def test_log_in_subdirectory_is_created(tmp_path):
    spec = LaunchSpec(["sh", "-c", "echo hi"], tmp_path, log_name="logs/run.log")
    with SolverProcess.start("s", spec) as proc:
        proc.wait(5)
    assert (tmp_path / "logs" / "run.log").read_text() == "hi\n"


def test_read_tail_reads_backwards_across_blocks(tmp_path):
    path = tmp_path / "log"
    lines = [f"line {i} " + "x" * (i % 37) for i in range(5000)]
    path.write_text("\n".join(lines) + "\n")
    for n in (1, 3, 40, 700):
        assert read_tail(path, n, block=64) == "\n".join(lines[-n:]) + "\n"
    path.write_text("a\nb\r\nprogress 10%\rprogress 20%")  # no final newline, bare \r kept
    assert read_tail(path, 2, block=4) == "b\r\nprogress 10%\rprogress 20%"
    assert read_tail(path, 10) == path.read_bytes().decode()
    path.write_bytes(b"ok\n\xff\xfe broken\n")
    assert read_tail(path, 1) == "\ufffd\ufffd broken\n"
    assert read_tail(tmp_path / "missing", 5) == ""
    assert read_tail(path, 0) == ""


def test_exit_status_and_signal_are_reported(tmp_path):
    with SolverProcess.start("s", LaunchSpec(["sh", "-c", "exit 3"], tmp_path)) as proc:
        assert proc.wait(5) == 3
        assert proc.returncode == proc.poll() == 3
        assert proc.describe_status() == "exited with status 3"
    with SolverProcess.start("s", LaunchSpec(["sh", "-c", "kill -SEGV $$"], tmp_path)) as proc:
        assert proc.wait(5) == -signal.SIGSEGV
        assert proc.describe_status() == "was killed by SIGSEGV"
    with SolverProcess.start("s", LaunchSpec(["sleep", "1000"], tmp_path)) as proc:
        assert proc.poll() is None
        assert proc.describe_status() == "is still running"
        assert "running" in repr(proc)


# -- exit wake-up through multiprocessing.connection.wait ---------------------------------


def test_fileno_wakes_connection_wait_on_kill(tmp_path, wake_mode):
    reader, writer = multiprocessing.Pipe(duplex=False)
    proc = SolverProcess.start("s", LaunchSpec(["sleep", "1000"], tmp_path))
    try:
        assert connection.wait([reader, proc], timeout=0.1) == []
        killed_at = time.monotonic()
        os.kill(proc.pid, signal.SIGKILL)
        ready = connection.wait([reader, proc], timeout=2.0)
        assert time.monotonic() - killed_at < 0.5
        assert ready == [proc]
        assert proc.poll() == -signal.SIGKILL
    finally:
        proc.terminate()
        reader.close()
        writer.close()


def test_fileno_wakes_connection_wait_on_normal_exit(tmp_path, wake_mode):
    proc = SolverProcess.start("s", LaunchSpec(["sleep", "0.2"], tmp_path))
    try:
        started = time.monotonic()
        assert connection.wait([proc], timeout=2.0) == [proc]
        assert 0.15 < time.monotonic() - started < 0.7
        assert proc.wait(1) == 0
    finally:
        proc.terminate()


# -- terminate ---------------------------------------------------------------------------


def test_terminate_kills_whole_tree_and_reaps(tmp_path, wake_mode):
    proc = SolverProcess.start("s", LaunchSpec(TREE, tmp_path))
    assert _wait_for(lambda: len(_group(proc.pgid)) == 3)
    pids = _group(proc.pgid)
    assert proc.pid in pids
    started = time.monotonic()
    assert proc.terminate(grace=2.0) == -signal.SIGTERM
    assert time.monotonic() - started < 1.0  # SIGTERM was enough, no need to wait for grace
    assert all(_dead(pid) for pid in pids), {pid: _state(pid) for pid in pids}
    assert _state(proc.pid) is None  # our own child is reaped, not a zombie
    assert proc.closed
    with pytest.raises(OSError):
        proc.fileno()
    again = time.monotonic()
    assert proc.terminate() == -signal.SIGTERM  # idempotent and immediate
    assert time.monotonic() - again < 0.05


def test_terminate_kills_stopped_group(tmp_path):
    proc = SolverProcess.start("s", LaunchSpec(TREE, tmp_path))
    assert _wait_for(lambda: len(_group(proc.pgid)) == 3)
    pids = _group(proc.pgid)
    os.killpg(proc.pgid, signal.SIGSTOP)
    assert _wait_for(lambda: all(_state(pid) == "T" for pid in pids))
    started = time.monotonic()
    proc.terminate(grace=2.0)
    # SIGCONT after SIGTERM lets stopped processes die at once instead of after SIGKILL.
    assert time.monotonic() - started < 1.0
    assert all(_dead(pid) for pid in pids), {pid: _state(pid) for pid in pids}


def test_terminate_escalates_to_sigkill(tmp_path):
    stubborn = ["bash", "-c", "trap '' TERM; sleep 1000 & sleep 1000 & wait"]
    proc = SolverProcess.start("s", LaunchSpec(stubborn, tmp_path))
    assert _wait_for(lambda: len(_group(proc.pgid)) == 3)
    pids = _group(proc.pgid)
    os.killpg(proc.pgid, signal.SIGSTOP)
    started = time.monotonic()
    assert proc.terminate(grace=0.3) == -signal.SIGKILL
    assert 0.3 <= time.monotonic() - started < 1.5
    assert all(_dead(pid) for pid in pids), {pid: _state(pid) for pid in pids}


def test_terminate_after_exit_kills_leftover_background_processes(tmp_path):
    spec = LaunchSpec(["sh", "-c", "sleep 1000 & echo $! > bg.pid"], tmp_path)
    proc = SolverProcess.start("s", spec)
    assert proc.wait(5) == 0
    background = int((tmp_path / "bg.pid").read_text())
    assert not _dead(background)
    proc.terminate()
    assert _wait_for(lambda: _dead(background), 1.0)


# -- registry ----------------------------------------------------------------------------


def test_bare_add_records_the_leaders_start_time(tmp_path):
    """A record that proves nothing is never signalled, so add(pid) proves it at once."""
    from gymprecice.env.pidregistry import process_starttime

    registry = PidRegistry(tmp_path)
    registry.add(os.getpid())
    [record] = registry.entries()
    assert record.starttime == process_starttime(os.getpid()) is not None


def test_registry_records_and_forgets_groups(tmp_path):
    registry = PidRegistry(tmp_path)
    assert registry.entries() == []
    registry.add(11, starttime=5, token="ab")
    registry.add(12, token="ef")
    registry.add(11, starttime=6, token="cd")  # replaces the older record
    assert registry.path == tmp_path / ".gymprecice" / "pids"
    assert registry.path.read_text() == "12 - ef\n11 6 cd\n"
    assert [line.split()[0] for line in registry.path.read_text().splitlines()] == ["12", "11"]
    registry.remove(12, 99)
    assert registry.pgids() == [11]
    registry.clear()
    assert registry.pgids() == []

    def add_many(start: int) -> None:
        for pgid in range(start, start + 25):
            registry.add(pgid)

    threads = [threading.Thread(target=add_many, args=(1000 * i,)) for i in range(1, 5)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(registry.pgids()) == 100  # no lost update


def test_solver_process_registers_and_unregisters(tmp_path):
    registry = PidRegistry(tmp_path)
    proc = SolverProcess.start("s", LaunchSpec(["sleep", "1000"], tmp_path), registry=registry)
    [record] = registry.entries()
    assert record.pgid == proc.pgid
    assert record.starttime is not None and record.token
    proc.terminate()
    assert registry.entries() == []


_DYING_ENV = textwrap.dedent(
    """
    import os, sys
    from pathlib import Path
    from gymprecice import owner_watchdog
    from gymprecice.env import launching
    from gymprecice.env.processes import PidRegistry, SolverProcess
    from gymprecice.plugin.solver import LaunchSpec

    # The layers that end the solvers with their owner (PR_SET_PDEATHSIG, the watchdog)
    # fail here, so that what is left is the outer supervisor's to kill.
    launching.die_with_parent_hook = lambda: None
    env_dir = Path(sys.argv[1])
    spec = LaunchSpec(["bash", "-c", "sleep 1000 & sleep 1000 & wait"], env_dir)
    proc = SolverProcess.start("fluid", spec, registry=PidRegistry(env_dir))
    watchdog = owner_watchdog.watchdog_pid()
    os.kill(watchdog, 9)
    os.waitpid(watchdog, 0)
    print(proc.pgid, flush=True)
    os._exit(0)  # the env dies without cleaning up
    """
)


def test_kill_recorded_groups_after_the_env_process_died(tmp_path):
    out = subprocess.run(
        [sys.executable, "-c", _DYING_ENV, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=20,
        check=True,
    )
    pgid = int(out.stdout)
    try:
        assert _wait_for(lambda: len(_group(pgid)) == 3)
        pids = _group(pgid)
        assert PidRegistry(tmp_path).pgids() == [pgid]
        assert kill_recorded_groups(tmp_path, grace=1.0) == [pgid]
        assert all(_dead(pid) for pid in pids), {pid: _state(pid) for pid in pids}
        assert PidRegistry(tmp_path).entries() == []
        assert kill_recorded_groups(tmp_path) == []
    finally:
        if _group(pgid):
            os.killpg(pgid, signal.SIGKILL)


def test_kill_recorded_groups_ignores_stale_and_reused_numbers(tmp_path):
    finished = subprocess.Popen(["true"])
    finished.wait()
    # A live group whose leader is not the process that was recorded (number reused).
    other = subprocess.Popen(["sleep", "1000"], start_new_session=True)
    try:
        registry = PidRegistry(tmp_path)
        registry.add(finished.pid, starttime=1, token="aa")
        registry.add(other.pid, starttime=1, token="bb")
        assert kill_recorded_groups(tmp_path, grace=0.2) == []
        assert other.poll() is None
        assert registry.entries() == []
    finally:
        other.kill()
        other.wait()


def test_kill_recorded_groups_recognises_leaderless_group_by_token(tmp_path):
    registry = PidRegistry(tmp_path / "env")
    spec = LaunchSpec(["sh", "-c", "sleep 1000 & echo $! > bg.pid"], tmp_path)
    proc = SolverProcess.start("s", spec, registry=registry)
    assert proc.wait(5) == 0
    proc._popen.wait()  # the leader is gone and reaped (as by init), its background job lives on
    background = int((tmp_path / "bg.pid").read_text())
    [record] = registry.entries()
    try:
        foreign = PidRegistry(tmp_path / "foreign")
        foreign.add(record.pgid, starttime=record.starttime, token="0123456789abcdef")
        assert kill_recorded_groups(tmp_path / "foreign", grace=0.2) == []
        assert not _dead(background)
        assert kill_recorded_groups(tmp_path / "env", grace=1.0) == [proc.pgid]
        assert _wait_for(lambda: _dead(background), 1.0)
    finally:
        proc.terminate(grace=0.1)


# -- launch errors -----------------------------------------------------------------------


def test_missing_program_is_a_case_error(tmp_path):
    spec = LaunchSpec(["no-such-solver-program", "-case", "."], tmp_path)
    with pytest.raises(CaseError) as info:
        SolverProcess.start("fluid", spec, env_index=4)
    message = str(info.value)
    assert "'no-such-solver-program'" in message
    assert str(tmp_path) in message
    assert "'fluid'" in message and "env 4" in message


def test_not_executable_and_missing_directory_are_case_errors(tmp_path):
    (tmp_path / "run.sh").write_text("#!/bin/sh\necho hi\n")
    with pytest.raises(CaseError, match=r"not executable.*chmod"):
        SolverProcess.start("fluid", LaunchSpec(["./run.sh"], tmp_path))
    with pytest.raises(CaseError, match="does not exist"):
        SolverProcess.start("fluid", LaunchSpec(["true"], tmp_path / "missing"))


# -- run_to_completion -------------------------------------------------------------------


def test_run_to_completion_success_kills_leftovers(tmp_path):
    spec = LaunchSpec(["sh", "-c", "echo ready > out.txt; sleep 1000 & echo $! > bg.pid"], tmp_path)
    run_to_completion("fluid", spec, timeout=5)
    assert (tmp_path / "out.txt").read_text() == "ready\n"
    assert _wait_for(lambda: _dead(int((tmp_path / "bg.pid").read_text())), 1.0)


def test_run_to_completion_failure(tmp_path):
    spec = LaunchSpec(
        ["sh", "-c", "echo 'cannot find mesh' >&2; exit 3"], tmp_path, log_name="p.log"
    )
    with pytest.raises(SolverCrashedError) as info:
        run_to_completion("fluid", spec, timeout=5, env_index=2, what="reset")
    err = info.value
    assert err.returncode == 3 and err.solver == "fluid" and err.env_index == 2
    assert "cannot find mesh" in err.log_tail
    assert err.log_file == str(tmp_path / "p.log")
    text = str(err)
    for part in ("reset", "'fluid'", "exited with status 3", "exit 3", "p.log", "cannot find mesh"):
        assert part in text


def test_run_to_completion_timeout_kills_group(tmp_path):
    spec = LaunchSpec(["sh", "-c", "echo starting; sleep 1000 & echo $! > bg.pid; wait"], tmp_path)
    started = time.monotonic()
    with pytest.raises(SolverTimeoutError) as info:
        run_to_completion("fluid", spec, timeout=0.3)
    assert time.monotonic() - started < 1.5
    assert "0.3 s" in str(info.value) and "starting" in info.value.log_tail
    assert _wait_for(lambda: _dead(int((tmp_path / "bg.pid").read_text())), 1.0)


# -- MPI environment ---------------------------------------------------------------------

# What `from mpi4py import MPI` (Open MPI 4.1.4 singleton) puts into the C environment,
# which every process started afterwards inherits.
_SINGLETON = {
    "OMPI_MCA_ess": "singleton",
    "ORTE_SCHIZO_DETECTION": "ORTE",
    "OMPI_MCA_orte_launch": "1",
    "OMPI_MCA_orte_ess_num_procs": "1",
    "OMPI_MCA_orte_precondition_transports": "1fe4e7bd4502fbd4-ed9b7d19310a4c02",
    "OMPI_MCA_pmix": "^s1,s2,cray,isolated",
    "OMPI_APP_CTX_NUM_PROCS": "1",
    "PMIX_NAMESPACE": "1309868033",
    "PMIX_RANK": "0",
    "PMIX_SERVER_URI4": "1309868032.0;tcp4://127.0.0.1:50473",
    "PMIX_SERVER_TMPDIR": "/tmp/ompi.host.0/pid.8941",
    "PMIX_SECURITY_MODE": "native",
    "PMIX_GDS_MODULE": "ds21,ds12,hash",
    "PMIX_VERSION": "4.2.2rc2",
}
# What mpirun sets for its ranks (a Python env started under mpirun).
_LAUNCHED = {
    "OMPI_COMM_WORLD_RANK": "0",
    "OMPI_COMM_WORLD_SIZE": "2",
    "OMPI_COMM_WORLD_LOCAL_RANK": "0",
    "OMPI_UNIVERSE_SIZE": "2",
    "OMPI_FILE_LOCATION": "/tmp/ompi.host.0/pid.1/0/0",
    "OMPI_MCA_ess_base_jobid": "1",
    "OMPI_MCA_orte_hnp_uri": "1.0;tcp://10.0.0.1:5",
    "OMPI_MCA_initial_wdir": "/tmp",
    "OMPI_NUM_APP_CTX": "1",
    "OMPI_COMMAND": "python",
    "PMI_RANK": "0",
    "PMI_SIZE": "2",
    "PMI_FD": "5",
    "MPI_LOCALRANKID": "0",
    "MPI_LOCALNRANKS": "2",
    "PRTE_LAUNCHED": "1",
}
_USER = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_btl": "^openib",
    "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "OMPI_MCA_orte_tmpdir_base": "/scratch/tmp",
    "OMPI_MCA_hwloc_base_binding_policy": "none",
    "OMPI_CC": "gcc",
    "OPAL_PREFIX": "/opt/openmpi",
    "PMIX_MCA_gds": "hash",
    "PRTE_MCA_rmaps_default_mapping_policy": ":oversubscribe",
    "I_MPI_PIN": "0",
    "I_MPI_FABRICS": "shm",
    "MPIR_CVAR_CH4_NETMOD": "ofi",
    "MPICH_GPU_SUPPORT_ENABLED": "0",
    "HYDRA_HOST_FILE": "/etc/hosts.mpi",
    "MPI_HOME": "/usr/lib/x86_64-linux-gnu/openmpi",
    "FOAM_MPI": "sys-openmpi",
    "WM_MPLIB": "SYSTEMOPENMPI",
    "PATH": "/usr/bin:/bin",
    "HOME": "/root",
}


def test_clean_mpi_environment_strips_runtime_keeps_user_settings():
    environ = {**_SINGLETON, **_LAUNCHED, **_USER}
    before = dict(environ)
    cleaned = clean_mpi_environment(environ)
    assert cleaned == _USER
    assert environ == before  # the input is not modified
    assert cleaned is not environ


_MPI_ENV_PROBE = textwrap.dedent(
    """
    import json, os, subprocess, sys
    from pathlib import Path
    from gymprecice.env.processes import SolverProcess
    from gymprecice.plugin.solver import LaunchSpec

    run_dir = Path(sys.argv[1])
    # No --allow-run-as-root and no --oversubscribe: the user's variables must carry them.
    argv = ["mpirun", "-np", "2", "hostname"]
    raw = subprocess.run(argv, cwd=run_dir, capture_output=True, text=True, timeout=30)
    proc = SolverProcess.start("mpi", LaunchSpec(argv, run_dir, log_name="mpi.log"))
    cleaned = proc.wait(30)
    proc.terminate()
    print(json.dumps({
        "singleton": os.environ.get("OMPI_MCA_ess"),
        "raw": raw.returncode,
        "cleaned": cleaned,
        "log": proc.log_path.read_text(),
    }))
    """
)

# The parent initialises MPI, then starts a Python process the way a vector env starts
# its workers: that child inherits the singleton's variables in os.environ.
_MPI_PARENT = (
    "import subprocess, sys; from mpi4py import MPI; MPI.COMM_WORLD.Barrier(); "
    "sys.exit(subprocess.call([sys.executable, '-c', sys.argv[1], sys.argv[2]]))"
)


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="mpirun is not on PATH")
@pytest.mark.skipif(importlib.util.find_spec("mpi4py") is None, reason="mpi4py is not installed")
def test_mpirun_works_from_a_process_that_inherited_an_mpi_singleton(tmp_path):
    env = {
        **os.environ,
        "OMPI_ALLOW_RUN_AS_ROOT": "1",
        "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
        "OMPI_MCA_rmaps_base_oversubscribe": "1",
    }
    out = subprocess.run(
        [sys.executable, "-c", _MPI_PARENT, _MPI_ENV_PROBE, str(tmp_path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["cleaned"] == 0, result["log"]
    assert len(result["log"].split()) == 2  # two ranks printed the host name
    if result["singleton"] == "singleton":
        # Open MPI 4: the raw inherited environment makes mpirun fail (silently, status 1).
        assert result["raw"] != 0
