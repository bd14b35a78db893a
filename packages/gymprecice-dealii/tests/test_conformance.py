"""The deal.II plugin against core's plugin conformance suite."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from gymprecice.testing.conformance import SolverPluginConformance, make_solver_context

FLAP_SOLID = (
    Path(__file__).resolve().parents[2]
    / "gymprecice-tutorials/src/gymprecice_tutorials/perpendicular_flap/case/solid-dealii"
)


class TestDealiiConformance(SolverPluginConformance):
    @pytest.fixture
    def plugin(self):
        from gymprecice_dealii import plugin

        return plugin

    @pytest.fixture
    def kind(self) -> str:
        return "dealii"

    @pytest.fixture
    def make_solver(self):
        def make(base: Path):
            source = base / "case" / "solid-dealii"
            shutil.copytree(FLAP_SOLID, source)
            # A stand-in for the adapter's program, which is not installed everywhere.
            program = source / "elasticity"
            program.write_text("#!/bin/sh\nexit 0\n")
            program.chmod(0o755)
            return make_solver_context(
                "dealii", source, base, name="solid", options={"program": "./elasticity"}
            )

        return make
