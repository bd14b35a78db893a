"""Fixtures of the OpenFOAM plugin's tests: real OpenFOAM where installed, skipped otherwise.

Tests marked ``openfoam`` need OpenFOAM's programs; they are skipped (with the reason)
when ``blockMesh`` cannot be found, so the suite passes on machines without OpenFOAM.
"""

from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from gymprecice.plugin.errors import CaseError
from gymprecice.plugin.solver import SolverContext
from gymprecice_openfoam import testing
from gymprecice_openfoam.installation import OpenFOAMInstallation, find_openfoam, run_tool


def _installation() -> OpenFOAMInstallation | None:
    if shutil.which("blockMesh") is None and not os.environ.get("WM_PROJECT_DIR"):
        return None
    try:
        return find_openfoam()
    except CaseError:
        return None


_INST = _installation()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if _INST is not None:
        return
    skip = pytest.mark.skip(reason="OpenFOAM not available (blockMesh not on PATH)")
    for item in items:
        if "openfoam" in item.keywords:
            item.add_marker(skip)


@pytest.fixture
def foam() -> OpenFOAMInstallation:
    """The OpenFOAM installation (tests using it must be marked ``openfoam``)."""
    if _INST is None:
        pytest.skip("OpenFOAM not available (blockMesh not on PATH)")
    return _INST


@pytest.fixture
def run(foam: OpenFOAMInstallation) -> Callable[..., None]:
    """Run an OpenFOAM tool in a case: ``run(case, "blockMesh", "-dict", ...)``."""

    def _run(case: Path, *argv: str, log: str | None = None, np: int = 1) -> None:
        from gymprecice_openfoam.installation import mpi_env

        name = log or f"log.{argv[0]}"
        if np > 1:
            argv = ("mpirun", "-np", str(np), *argv, "-parallel")
        run_tool(list(argv), case, name, foam, extra_env=mpi_env() if np > 1 else None)

    return _run


def tree_digest(root: Path, *, skip: tuple[str, ...] = ()) -> dict[str, str]:
    """Relative path -> sha256 of every file (and "<dir>" for directories) under ``root``."""
    out: dict[str, str] = {}
    for path in sorted(root.rglob("*")):
        rel = str(path.relative_to(root))
        if any(rel == s or rel.startswith(s + os.sep) for s in skip):
            continue
        if path.is_dir():
            out[rel] = "<dir>"
        else:
            out[rel] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


@pytest.fixture
def digest() -> Callable[..., dict[str, str]]:
    return tree_digest


JET_PRECICE_DICT = testing.precice_dict(
    {
        "Interface1": {"mesh": "Fluid-Mesh-jet1", "patches": ["jet1"], "read": ["Velocity"]},
        "Interface2": {"mesh": "Fluid-Mesh-jet2", "patches": ["jet2"], "read": ["Velocity"]},
        "Interface3": {
            "mesh": "Fluid-Mesh-body",
            "patches": ["cylinder", "jet2", "jet1"],
            "write": ["Pressure"],
        },
        "Interface4": {
            "mesh": "Fluid-Mesh-nodes",
            "patches": ["jet1", "jet2"],
            "locations": "faceNodes",
        },
    }
)


@pytest.fixture
def cylinder_case(tmp_path: Path) -> Callable[..., Path]:
    """Factory of a small cylinder-with-jets pimpleFoam case (mesh recipe only)."""

    def make(name: str = "fluid", resolution: float = 0.5, **control: object) -> Path:
        params: dict[str, object] = {
            "end_time": 0.02,
            "delta_t": 0.002,
            "write_precision": 17,
            "probes": [(0.3, 0.2, 0.005), (0.45, 0.22, 0.005), (0.6, 0.18, 0.005)],
            "force_patches": ["cylinder", "jet1", "jet2"],
        }
        params.update(control)
        return testing.write_flow_case(
            tmp_path / name,
            testing.cylinder_block_mesh_dict(resolution),
            testing.CYLINDER_PATCHES,
            precice_dict=JET_PRECICE_DICT,
            **params,
        )

    return make


@pytest.fixture
def solver_for(tmp_path: Path) -> Callable[..., SolverContext]:
    """Copy a source case into a run dir (as core does) and build its SolverContext."""

    def make(source: Path, **options: object) -> SolverContext:
        env_dir = tmp_path / f"env-{source.name}"
        run_dir = env_dir / source.name
        if run_dir.exists():
            shutil.rmtree(run_dir)
        shutil.copytree(source, run_dir)
        return SolverContext(
            name="fluid",
            kind="openfoam",
            run_dir=run_dir,
            source_dir=source,
            env_dir=env_dir,
            options=dict(options),
        )

    return make
