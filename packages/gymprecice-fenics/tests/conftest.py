"""Fixtures of the FEniCS plugin's tests: its small plate case and stand-in interpreters.

A stand-in interpreter is a shell script that answers the plugin's two questions (the
environment probe and the dry run) the way a configured FEniCS environment would, or the
way a broken one does, so most tests run on machines without FEniCS.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from gymprecice.plugin.precice_xml import load_precice_config
from gymprecice.testing.conformance import make_solver_context

CASE = Path(__file__).parent / "cases" / "plate"
GOOD_VERSIONS = {
    "python": "3.11.2",
    "numpy": "1.24.2",
    "dolfin": "2019.2.0.dev0",
    "precice": "3.4.1",
    "fenicsprecice": "2.3.1",
}
GOOD_DRY_RUN = {
    "participant": "Solid",
    "mesh": "Solid-Mesh",
    "coordinates": [[0.1 * i, 0.0] for i in range(11)],
}


def write_fake_python(
    path: Path,
    *,
    versions: dict | None = None,
    missing: dict | None = None,
    dry_run: dict | None = None,
    dry_run_stderr: str = "",
    dry_run_status: int = 0,
) -> Path:
    """A shell script standing in for the FEniCS environment's interpreter."""
    probe = {"missing": missing or {}, **(GOOD_VERSIONS if versions is None else versions)}
    if dry_run is None and not dry_run_stderr:
        dry_run = GOOD_DRY_RUN
    dry_line = f"echo 'GYMPRECICE-DRY-RUN {json.dumps(dry_run)}'" if dry_run else ":"
    stderr = dry_run_stderr.replace("'", "'\\''")
    path.write_text(
        "#!/bin/sh\n"
        'if [ "$1" = "-c" ]; then\n'
        f"  echo 'GYMPRECICE-PROBE {json.dumps(probe)}'\n"
        "  exit 0\n"
        "fi\n"
        f"{dry_line}\n"
        f"printf '%s' '{stderr}' >&2\n"
        f"exit {dry_run_status}\n"
    )
    path.chmod(0o755)
    return path


@pytest.fixture(autouse=True)
def _fresh_probe_cache() -> None:
    """Probes are cached per interpreter path; each test starts without."""
    from gymprecice_fenics import solver_env

    solver_env._CACHE.clear()


@pytest.fixture
def fake_python() -> Callable[..., Path]:
    """:func:`write_fake_python`, for tests and fixtures that make stand-in interpreters."""
    return write_fake_python


@pytest.fixture
def plate_case() -> Path:
    """The pristine plate case shipped with these tests (never write into it)."""
    return CASE


@pytest.fixture
def case(tmp_path: Path) -> Path:
    """A private copy of the plate case (preCICE XML and the FEniCS solid)."""
    target = tmp_path / "case"
    shutil.copytree(CASE, target)
    return target


@pytest.fixture
def make_fenics_solver(case: Path, tmp_path: Path) -> Callable[..., object]:
    """``make(**fake)``: a solver context on the plate's solid with a stand-in interpreter."""

    made = []

    def make(options: dict | None = None, python: Path | None = None, **fake):
        solid = case / "solid-fenics"
        index = len(made)
        made.append(index)
        if python is None:
            python = write_fake_python(tmp_path / f"fake-python-{index}", **fake)
        ctx = make_solver_context(
            "fenics",
            solid,
            tmp_path / "envs",
            name="solid",
            participant="Solid",
            env_index=index,
            options={"python": str(python), **(options or {})},
        )
        ctx.precice = load_precice_config(case / "precice-config.xml")
        ctx.precice_config_file = case / "precice-config.xml"
        return ctx

    return make
