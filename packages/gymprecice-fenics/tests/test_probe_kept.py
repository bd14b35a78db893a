"""The FEniCS environment's probe is kept while nothing it depends on changes.

Importing dolfin costs a second of CPU and nearly 3 s in every lab command (its manifest
records the doctor's report), so a healthy probe of a virtual environment is kept in its
folder and taken again until the interpreter, the environment, Debian's packages or the
stack's preCICE change. Here a stand-in interpreter counts how often it is asked.
"""

from __future__ import annotations

import json
from pathlib import Path

from gymprecice_fenics import solver_env

from .conftest import GOOD_VERSIONS


def _counting_env(root: Path, versions: dict | None = None) -> tuple[str, Path]:
    """A virtual environment whose interpreter answers the probe and counts the asking."""
    (root / "bin").mkdir(parents=True)
    (root / "lib" / "python3.11" / "site-packages").mkdir(parents=True)
    (root / "pyvenv.cfg").write_text("home = /usr/bin\n")
    calls = root / "calls"
    answer = {"missing": {}, **(versions or GOOD_VERSIONS)}
    python = root / "bin" / "python"
    python.write_text(
        f"#!/bin/sh\necho x >> {calls}\necho 'GYMPRECICE-PROBE {json.dumps(answer)}'\n"
    )
    python.chmod(0o755)
    return str(python), calls


def _asked(calls: Path) -> int:
    return len(calls.read_text().splitlines()) if calls.exists() else 0


def test_a_healthy_probe_is_kept_until_the_environment_changes(tmp_path: Path) -> None:
    python, calls = _counting_env(tmp_path / "env")
    first = solver_env.probe(python)
    assert first.ok and _asked(calls) == 1
    solver_env._CACHE.clear()  # another process
    again = solver_env.probe(python)
    assert again.ok and again.versions == first.versions and _asked(calls) == 1
    # a package installed into the environment: asked again
    (tmp_path / "env" / "lib" / "python3.11" / "site-packages" / "newpkg").mkdir()
    solver_env._CACHE.clear()
    assert solver_env.probe(python).ok and _asked(calls) == 2
    solver_env._CACHE.clear()
    assert solver_env.probe(python, refresh=True).ok and _asked(calls) == 3


def test_a_probe_that_finds_a_problem_is_asked_again_every_time(tmp_path: Path) -> None:
    python, calls = _counting_env(tmp_path / "env", {**GOOD_VERSIONS, "numpy": "2.1.0"})
    assert not solver_env.probe(python).ok
    solver_env._CACHE.clear()
    assert not solver_env.probe(python).ok and _asked(calls) == 2
    assert not (tmp_path / "env" / solver_env._STORED).exists()


def test_an_interpreter_outside_a_virtual_environment_keeps_nothing(tmp_path: Path) -> None:
    python, calls = _counting_env(tmp_path / "env")
    (tmp_path / "env" / "pyvenv.cfg").unlink()
    solver_env.probe(python)
    solver_env._CACHE.clear()
    solver_env.probe(python)
    assert _asked(calls) == 2 and not (tmp_path / "env" / solver_env._STORED).exists()
