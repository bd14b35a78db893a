"""Left-overs of a crash are found and named: ``gymprecice doctor`` and ``gymprecice clean``.

A solver that survived its owner (the owner and its watchdog were killed together, as a
machine short of memory may do) is found from the per-user owner index and the run
directory's pid registry, listed by ``doctor`` with the advice to run ``clean``, and
stopped by ``clean``; only processes proven to be gymprecice's own are touched, never one
found by its name, never a stranger that got a recorded number, never the group of a live
run in a directory a dead one used before. Each test has an ``XDG_STATE_HOME`` of its own.
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

from gymprecice import cli, plugins
from gymprecice.env.pidregistry import GroupRecord, PidRegistry, process_starttime

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="the process checks read /proc"
)

_OWNER = """
import json, os, sys, time
from pathlib import Path
from gymprecice import owner_watchdog
from gymprecice.env.processes import PidRegistry, SolverProcess
from gymprecice.plugin.solver import LaunchSpec

env_dir, kill_watchdog = Path(sys.argv[1]), sys.argv[2] == "1"
env_dir.mkdir(parents=True, exist_ok=True)
spec = LaunchSpec(["bash", "-c", "sleep 1000 & sleep 1000 & wait"], env_dir)
proc = SolverProcess.start("fluid", spec, registry=PidRegistry(env_dir))
if kill_watchdog:  # killed together with its owner
    watchdog = owner_watchdog.watchdog_pid()
    os.kill(watchdog, 9); os.waitpid(watchdog, 0)
print("REPORT " + json.dumps({"pgid": proc.pgid}), flush=True)
time.sleep(1000)
"""


@pytest.fixture
def state(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An owner index of this test's own."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    return tmp_path / "state"


def _start_owner(
    tmp_path: Path, env_dir: Path, kill_watchdog: bool
) -> tuple[subprocess.Popen, int]:
    script = tmp_path / "owner.py"
    script.write_text(_OWNER)
    owner = subprocess.Popen(
        [sys.executable, str(script), str(env_dir), "1" if kill_watchdog else "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert owner.stdout is not None
    line = owner.stdout.readline()
    if not line.startswith("REPORT "):
        owner.kill()
        raise AssertionError(f"the owner did not start: {line}{owner.communicate()[1]}")
    return owner, json.loads(line[len("REPORT ") :])["pgid"]


def _group(pgid: int) -> list[int]:
    """Live members of a process group."""
    found = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            data = Path(entry.path, "stat").read_bytes()
        except OSError:
            continue
        fields = data[data.rfind(b")") + 2 :].split()
        if int(fields[2]) == pgid and fields[0] not in (b"Z", b"X"):
            found.append(int(entry.name))
    return found


def _wait(predicate, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


def _kill_group(pgid: int) -> None:
    for pid in _group(pgid):
        os.kill(pid, signal.SIGKILL)


def _gone_owner_indexing(state: Path, env_dir: Path) -> Path:
    """An index file of an owner that is gone (a reaped child of ours), naming ``env_dir``."""
    child = subprocess.Popen(["true"])
    child.wait()
    host = os.uname().nodename
    index = state / "gymprecice" / "owners" / host / f"{child.pid}-1"
    index.parent.mkdir(parents=True, exist_ok=True)
    index.write_text(f"{env_dir}\n")
    return index


def test_doctor_lists_an_orphan_and_clean_stops_it(tmp_path, state, capsys, monkeypatch):
    """The owner and its watchdog die together: the kernel kills the solver's script (its
    direct child), the two processes it started run on. ``doctor`` names them and says to
    run ``clean``; ``clean`` stops them and forgets the owner; a second ``clean`` finds
    nothing. Cost: about 3 s (``doctor`` probes pyprecice and the stack; core's plugin only)."""
    monkeypatch.setattr(plugins, "_manager", None)
    monkeypatch.setenv(plugins.DISABLE_ENV_VAR, "1")
    env_dir = tmp_path / "runs" / "env_0"
    owner, pgid = _start_owner(tmp_path, env_dir, kill_watchdog=True)
    try:
        assert _wait(lambda: len(_group(pgid)) == 3)
        owner.kill()
        owner.wait()
        assert _wait(lambda: len(_group(pgid)) == 2)  # the script is gone, its children not
        orphans = _group(pgid)

        assert cli.main(["doctor", "--json"]) in (0, 1)
        report = json.loads(capsys.readouterr().out)
        (line,) = [c for c in report["checks"] if c["name"] == "leftover solvers"]
        assert line["ok"] is False and line["required"] is False
        assert str(env_dir) in line["detail"] and "2 x sleep" in line["detail"]
        assert all(str(pid) in line["detail"] for pid in orphans)
        assert "gymprecice clean" in line["advice"]

        assert cli.main(["clean"]) == 0
        out = capsys.readouterr().out
        assert out.startswith("gymprecice clean: stopped 2 x sleep") and str(env_dir) in out
        assert _wait(lambda: not _group(pgid), 2.0)
        assert PidRegistry(env_dir).entries() == []
        assert not list(state.rglob("owners/*/*"))

        assert cli.main(["clean"]) == 0
        assert "nothing to clean" in capsys.readouterr().out
    finally:
        owner.kill()
        _kill_group(pgid)


def test_clean_with_nothing_to_clean_says_so_and_forgets_gone_owners(tmp_path, state, capsys):
    """No index at all, then a gone owner whose solvers all ended: ``clean`` says there is
    nothing to clean, exits 0 and drops the stale index file. Cost: under 0.1 s."""
    assert cli.main(["clean"]) == 0
    assert capsys.readouterr().out == (
        "gymprecice clean: nothing to clean: no solver of a gone gymprecice run is running\n"
    )
    index = _gone_owner_indexing(state, tmp_path / "runs" / "env_0")
    assert cli.main(["clean", "--dry-run"]) == 0
    assert "nothing to clean" in capsys.readouterr().out
    assert index.exists()  # a dry run changes nothing
    assert cli.main(["clean"]) == 0
    assert "nothing to clean" in capsys.readouterr().out
    assert not index.exists()


def test_clean_never_signals_a_stranger_holding_a_recorded_number(tmp_path, state, capsys):
    """A gone owner's registry records a group whose number is now an unrelated session
    leader's (another start time, no token): it is not proven ours and is left alone.
    Cost: under 0.1 s."""
    env_dir = tmp_path / "runs" / "env_0"
    stranger = subprocess.Popen(["sleep", "1000"], start_new_session=True)
    try:
        start = process_starttime(stranger.pid)
        assert start is not None
        PidRegistry(env_dir).add_record(GroupRecord(stranger.pid, start - 1, "0123456789abcdef"))
        _gone_owner_indexing(state, env_dir)
        assert cli.main(["clean"]) == 0
        assert "nothing to clean" in capsys.readouterr().out
        time.sleep(0.1)
        assert stranger.poll() is None
    finally:
        stranger.kill()
        stranger.wait()


def test_clean_spares_a_live_run_in_a_directory_a_gone_owner_used(tmp_path, state, capsys):
    """A gone owner's index names a run directory that a live owner now runs a solver in,
    even with the live owner's own index entry missing (read before it was written): its
    processes name their live owner, and ``clean`` leaves them alone. Cost: about 0.5 s."""
    env_dir = tmp_path / "runs" / "env_0"
    owner, pgid = _start_owner(tmp_path, env_dir, kill_watchdog=False)
    try:
        assert _wait(lambda: len(_group(pgid)) == 3)
        _gone_owner_indexing(state, env_dir)
        assert cli.main(["clean"]) == 0  # the live owner is indexed: its directory is in use
        assert "nothing to clean" in capsys.readouterr().out
        for path in state.rglob("owners/*/*"):
            if path.name.startswith(f"{owner.pid}-"):
                path.unlink()  # as if clean had read the index before the live owner wrote it
        _gone_owner_indexing(state, env_dir)
        assert cli.main(["clean"]) == 0
        assert "nothing to clean" in capsys.readouterr().out
        assert len(_group(pgid)) == 3
        owner.kill()
        owner.wait()
        assert _wait(lambda: not _group(pgid))  # its own watchdog still ends it
    finally:
        owner.kill()
        _kill_group(pgid)
