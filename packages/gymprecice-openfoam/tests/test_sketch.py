"""The OpenFOAM plugin's case sketch: patches, kinds, loops, preCICE meshes and probes.

Read from the case's own files: the function objects of controlDict (their ``#include``
files too), and the mesh, which blockMesh builds in a temporary directory when the case
has none, leaving the case untouched and nothing behind.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.errors import CaseError
from gymprecice.plugin.solver import SolverContext
from gymprecice_openfoam import testing
from gymprecice_openfoam.function_objects import function_objects, probe_sets
from gymprecice_openfoam.plugin import gymprecice_sketch_case

CONTROL = (
    testing.HEADER.format(cls="dictionary", obj="controlDict")
    + """
application pimpleFoam;
functions
{
    #include "probes"
    forces { type forces; patches (cylinder); }
}
"""
)
PROBES = """probes
{
    type probes;
    fields (p U);
    probeLocations ((0.3 0.2 0) (0.4 0.2 0.005));
}
"""


def test_probes_are_found_through_include_files(tmp_path: Path) -> None:
    (tmp_path / "system").mkdir()
    (tmp_path / "system" / "controlDict").write_text(CONTROL)
    (tmp_path / "system" / "probes").write_text(PROBES)
    assert sorted(function_objects(tmp_path)) == ["forces", "probes"]
    (probes,) = probe_sets(tmp_path)
    assert probes.fields == ("p", "U") and probes.label == "OpenFOAM probes (p, U): 2"
    np.testing.assert_allclose(probes.locations[:, :2], [[0.3, 0.2], [0.4, 0.2]])
    (tmp_path / "system" / "probes").unlink()
    with pytest.raises(CaseError, match=r"system/probes: included by controlDict's functions"):
        function_objects(tmp_path)


def test_another_kind_is_not_sketched(tmp_path: Path) -> None:
    solver = SolverContext("fluid", "dealii", tmp_path, tmp_path, tmp_path)
    assert gymprecice_sketch_case(solver) is None


def _tree(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_size for p in root.rglob("*") if p.is_file()}


@pytest.mark.openfoam
def test_a_case_without_a_mesh_is_meshed_elsewhere_and_read(
    cylinder_case, tmp_path: Path, monkeypatch
) -> None:
    """Cost: about 1 s (blockMesh of a 600-cell cylinder case, in a temporary directory)."""
    case = cylinder_case()
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    before = _tree(case)
    solver = SolverContext("fluid", "openfoam", case, case, case.parent, participant="Fluid")
    sketch = gymprecice_sketch_case(solver)
    assert _tree(case) == before and _tree(tmp_path / "tmp") == {}, "nothing written, nothing left"
    assert sketch.notes == ("mesh built by blockMesh in a temporary directory",)
    kinds = {p.name: p.kind for p in sketch.patches}
    assert kinds == {
        "inlet": "inlet",
        "outlet": "outlet",
        "walls": "wall",
        "cylinder": "wall",
        "jet1": "wall",
        "jet2": "wall",
    }, "frontAndBack (empty) is not in the x-y plane"
    patches = {p.name: p for p in sketch.patches}
    assert patches["jet1"].meshes == ("Fluid-Mesh-jet1", "Fluid-Mesh-body", "Fluid-Mesh-nodes")
    assert patches["inlet"].meshes == ()
    inlet = patches["inlet"].segments
    np.testing.assert_allclose(inlet[..., 0], 0.0, atol=1e-12)
    assert math.isclose(np.abs(inlet[:, 1, 1] - inlet[:, 0, 1]).sum(), 0.41, rel_tol=1e-9)
    outer, hole = sketch.loops
    assert math.isclose(abs(_area(outer)), 2.2 * 0.41, rel_tol=1e-9)
    assert math.isclose(abs(_area(hole)), math.pi * 0.05**2, rel_tol=0.03)
    (probes,) = sketch.points
    assert probes.points.shape == (3, 2) and probes.label == "OpenFOAM probes (p, U): 3"
    assert len(sketch.vertices["Fluid-Mesh-jet1"]) == len(patches["jet1"].segments)
    assert set(sketch.vertices) == {
        "Fluid-Mesh-jet1", "Fluid-Mesh-jet2", "Fluid-Mesh-body", "Fluid-Mesh-nodes",
    }  # fmt: skip


def _area(loop: np.ndarray) -> float:
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_without_openfoam_a_case_without_a_mesh_says_what_is_missing(
    tmp_path: Path, monkeypatch
) -> None:
    (tmp_path / "system").mkdir()
    (tmp_path / "system" / "controlDict").write_text(CONTROL)
    import gymprecice_openfoam.installation as installation

    def absent(**_: object) -> None:
        raise CaseError("OpenFOAM: not found; install it")

    monkeypatch.setattr(installation, "find_openfoam", absent)
    solver = SolverContext("fluid", "openfoam", tmp_path, tmp_path, tmp_path)
    with pytest.raises(CaseError, match=r"has no mesh \(constant/polyMesh\) and OpenFOAM, wh"):
        gymprecice_sketch_case(solver)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["system"]
