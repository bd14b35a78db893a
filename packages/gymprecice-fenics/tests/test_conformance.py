"""The FEniCS plugin against core's plugin conformance suite."""

from __future__ import annotations

from pathlib import Path

import pytest

from gymprecice.testing.conformance import SolverPluginConformance, make_solver_context


class TestFenicsConformance(SolverPluginConformance):
    @pytest.fixture
    def plugin(self):
        from gymprecice_fenics import plugin

        return plugin

    @pytest.fixture
    def kind(self) -> str:
        return "fenics"

    @pytest.fixture
    def make_solver(self, fake_python, plate_case: Path):
        def make(base: Path):
            # A stand-in for the FEniCS environment's interpreter, outside the case.
            python = fake_python(base / "fake-python")
            return make_solver_context(
                "fenics",
                plate_case / "solid-fenics",
                base,
                name="solid",
                options={"python": str(python)},
            )

        return make
