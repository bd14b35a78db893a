"""The OpenFOAM plugin against core's plugin conformance suite (real blockMesh)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gymprecice.testing.conformance import SolverPluginConformance, make_solver_context
from gymprecice_openfoam import testing

pytestmark = pytest.mark.openfoam

PRECICE_DICT = testing.precice_dict(
    {"Interface1": {"mesh": "Fluid-Mesh-jet1", "patches": ["jet1"], "read": ["Velocity"]}}
)


class TestOpenFOAMConformance(SolverPluginConformance):
    """Core's conformance suite on the OpenFOAM plugin, with a small cylinder case.

    Cost: about 3 s for the whole class (a blockMesh of the small cylinder in the tests that
    prepare a case; the others read only).
    """

    @pytest.fixture
    def plugin(self):
        from gymprecice_openfoam import plugin

        return plugin

    @pytest.fixture
    def kind(self) -> str:
        return "openfoam"

    @pytest.fixture
    def make_solver(self):
        def make(base: Path):
            source = testing.write_flow_case(
                base / "case" / "fluid-openfoam",
                testing.cylinder_block_mesh_dict(0.3),
                testing.CYLINDER_PATCHES,
                precice_dict=PRECICE_DICT,
                end_time=0.01,
                delta_t=0.002,
            )
            return make_solver_context("openfoam", source, base, name="fluid")

        return make
