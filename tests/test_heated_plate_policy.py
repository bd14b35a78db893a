"""The shipped heated-plate policy, as a user runs it: ``--policy shipped`` on the double
and on the real stack, against the uncontrolled plate from every held-out start.

* ``gymprecice evaluate heated-plate --policy shipped`` finds the policy of the env's
  training case (``heated-plate-fast``), and on the lumped-plate double tracks the setpoint
  better than the uncontrolled plate from each held-out start;
* on the real stack (``precice``/``openfoam``): 1 s of the training case from each of the
  three held-out starts, then 0.5 s of HeatedPlate-v0 itself (the 12,013-cell fluid) from
  one, each with a lower tracking error than the uncontrolled plate's.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gymprecice_lab.common.registered_env import find_lab_env
from gymprecice_lab.policies.shipped import POLICIES_DIR_ENV, resolve_policy


def _cli(cwd: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != POLICIES_DIR_ENV}
    return subprocess.run(
        [sys.executable, "-m", "gymprecice", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _errors(cwd: Path, command: str, env: str, kwargs: dict[str, Any], *extra: str) -> list:
    """The mean tracking error (K) of every episode of one ``gymprecice`` rollout command."""
    out = cwd / f"{command}-{env}"
    proc = _cli(cwd, command, env, "--env-kwargs", json.dumps(kwargs), "--out", str(out), *extra)
    assert proc.returncode == 0, f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    summary = json.loads((out / "summary.json").read_text())
    return [episode["mean_tracking_error"] for episode in summary["episodes"]]


def test_shipped_on_the_full_env_means_the_training_cases_policy() -> None:
    policy = resolve_policy("shipped", find_lab_env("heated-plate"))
    assert policy.name == "heated-plate-fast"
    assert policy.metadata["env"]["name"] == "heated-plate-fast"


def test_the_policy_list_gives_the_plates_evaluated_tracking_error(tmp_path: Path) -> None:
    proc = _cli(tmp_path, "policies")
    assert proc.returncode == 0, proc.stderr
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("heated-plate-fast:")]
    assert "evaluated mean tracking_error 0.2205 ± 0.06 over 3 episodes" in line, line


@pytest.mark.timeout(300)
def test_shipped_policy_beats_the_uncontrolled_plate_on_the_double(tmp_path: Path) -> None:
    # --double, as a user types it: the double needs no solver, so this runs before the
    # real stack is built (the fast tier)
    uncontrolled = _errors(tmp_path, "baseline", "heated-plate", {}, "--double", "--all-starts")
    controlled = _errors(
        tmp_path, "evaluate", "heated-plate", {}, "--double", "--all-starts", "--policy", "shipped"
    )
    assert len(controlled) == len(uncontrolled) == 3
    for start, (c, u) in enumerate(zip(controlled, uncontrolled, strict=True)):
        assert c < u, f"held-out start {start}: {c:.3f} K controlled, {u:.3f} K uncontrolled"


def _missing(env: str) -> str:
    """What ``env`` lacks on this machine to run on real solvers, as the commands say it."""
    from gymprecice.tools.cli import doctor_report
    from gymprecice_lab.common.requirements import missing_names, missing_requirements

    return missing_names(missing_requirements(doctor_report(), find_lab_env(env)))


@pytest.mark.precice
@pytest.mark.openfoam
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_shipped_policy_beats_the_uncontrolled_plate_on_the_real_stack(tmp_path: Path) -> None:
    """Cost: about 2 to 3 min on 2 cores, about 70 CPU-s (eight coupled runs on buoyantPimpleFoam
    and laplacianFoam: the three held-out starts for 1 s, and one 0.5 s episode of the full
    plate, each uncontrolled and with the policy).
    """
    missing = _missing("heated-plate-fast")
    if missing:
        pytest.skip("needs " + missing)
    fast = {"episode_time": 1.0}
    uncontrolled = _errors(tmp_path, "baseline", "heated-plate-fast", fast, "--all-starts")
    controlled = _errors(
        tmp_path, "evaluate", "heated-plate-fast", fast, "--all-starts", "--policy", "shipped"
    )
    assert len(controlled) == 3
    for start, (c, u) in enumerate(zip(controlled, uncontrolled, strict=True)):
        assert c < u, f"held-out start {start}: {c:.3f} K controlled, {u:.3f} K uncontrolled"
    # HeatedPlate-v0 itself, briefly: the policy transfers to the full fluid.
    full = {"episode_time": 0.5}
    (u,) = _errors(tmp_path, "baseline", "heated-plate", full, "--episodes", "1")
    (c,) = _errors(
        tmp_path, "evaluate", "heated-plate", full, "--episodes", "1", "--policy", "shipped"
    )
    assert c < u, f"HeatedPlate-v0: {c:.3f} K controlled, {u:.3f} K uncontrolled"
