"""Fixtures shared by the lab's tests: a command as a user types it, one refused in this
process, a Ray cluster."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest


@pytest.fixture
def gymprecice_cli() -> Callable[..., str]:
    """``gymprecice ARGS`` as a user types it, in ``cwd``: its output, or a failed test
    showing both streams."""

    def run(cwd: Path, *args: str) -> str:
        proc = subprocess.run(
            [sys.executable, "-m", "gymprecice", *args],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
        return proc.stdout + proc.stderr

    return run


@pytest.fixture
def gymprecice_refused(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> Callable[..., tuple[int, str]]:
    """``gymprecice ARGS`` in ``cwd``, run in this process, for a command that is refused
    before it runs anything: its exit status and its stderr, with the message a
    ``SystemExit`` carries (which the interpreter prints, exiting with status 1).

    A refusal costs a process of its own a second or more of imports (the lab, and for
    training and evaluation PyTorch) to print one line; here it costs what the check
    costs. A command that is not refused runs here too, and its test fails on the status.
    """
    from gymprecice.tools.cli import main

    def run(cwd: Path, *args: str) -> tuple[int, str]:
        monkeypatch.chdir(cwd)
        capsys.readouterr()  # only this command's output
        try:
            status, message = main(list(args)), ""
        except SystemExit as exc:
            code = exc.code
            status, message = (code, "") if isinstance(code, int) else (1, f"{code}\n")
        return status, capsys.readouterr().err + message

    return run


@pytest.fixture(scope="module")
def ray_cluster():
    """A real Ray cluster on this machine: a head with no CPU and two worker nodes of two
    CPUs each, so that every actor and task that asks for a CPU lands on a worker."""
    ray = pytest.importorskip("ray", reason="--ray needs gymprecice-core[ray]")
    from ray.cluster_utils import Cluster

    cluster = Cluster(
        initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False}
    )
    for _ in range(2):
        cluster.add_node(num_cpus=2)
    cluster.wait_for_nodes()
    yield cluster
    if ray.is_initialized():
        ray.shutdown()
    cluster.shutdown()
