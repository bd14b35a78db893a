"""The conformance suite itself: each broken plugin fails with the hook, the rule and the fix.

The suite is an installed module, so pytest does not rewrite its asserts: a bare
``assert`` would fail with an empty ``AssertionError``. These tests run the suite's checks
on plugins that break one rule each and read the failure.
"""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

from gymprecice.plugin.errors import CaseError
from gymprecice.plugin.hookspecs import LaunchSpec, hookimpl
from gymprecice.plugin.manager import GymPrecicePluginManager
from gymprecice.testing import conformance
from gymprecice.testing.conformance import (
    ConformanceError,
    SolverPluginConformance,
    make_solver_context,
)

KIND = "toy"


class Minimal:
    """The least a plugin needs: a kind, a reset and a launch (no prepare hook)."""

    @hookimpl
    def gymprecice_solver_kinds(self):
        return {KIND: "a toy solver"}

    @hookimpl
    def gymprecice_reset_case(self, solver):
        return None if solver.kind != KIND else True

    @hookimpl
    def gymprecice_launch_solver(self, solver):
        if solver.kind != KIND:
            return None
        return LaunchSpec(argv=["toy"], cwd=solver.run_dir)


class Greedy(Minimal):
    @hookimpl
    def gymprecice_launch_solver(self, solver):
        return LaunchSpec(argv=["toy"], cwd=solver.run_dir)  # answers for every kind


class ValidatesEverything(Minimal):
    @hookimpl
    def gymprecice_validate_case(self, solver):
        return []  # claims to have checked cases of kinds it cannot read


class FalsePrepare(Minimal):
    @hookimpl
    def gymprecice_prepare_case(self, solver):
        return None if solver.kind != KIND else False


class BlankCheck(Minimal):
    @hookimpl
    def gymprecice_check_solver(self, solver, log_text):
        return None if solver.kind != KIND else "  "


def manager_of(plugin) -> GymPrecicePluginManager:
    pm = GymPrecicePluginManager()
    pm.register(plugin, name="under-test")
    return pm


@pytest.fixture
def solver(tmp_path: Path):
    source = tmp_path / "case" / "toy"
    source.mkdir(parents=True)
    (source / "toy.cfg").write_text("n = 1\n")
    return make_solver_context(KIND, source, tmp_path)


def test_the_suite_has_no_bare_asserts() -> None:
    tree = ast.parse(inspect.getsource(conformance))
    asserts = [node.lineno for node in ast.walk(tree) if isinstance(node, ast.Assert)]
    assert not asserts, f"bare asserts in gymprecice/testing/conformance.py at lines {asserts}"


def test_a_minimal_plugin_without_prepare_passes(solver, tmp_path: Path) -> None:
    suite, pm = SolverPluginConformance(), manager_of(Minimal())
    suite.test_prepare_and_reset_write_only_under_run_dir(pm, solver, tmp_path)
    suite.test_launch_spec_runs_inside_run_dir(pm, solver)
    for hook in ("gymprecice_reset_case", "gymprecice_launch_solver"):
        suite.test_foreign_kind_gets_none(pm, solver, hook)


def test_answering_for_a_foreign_kind_names_the_hook_and_the_fix(solver) -> None:
    with pytest.raises(ConformanceError) as caught:
        SolverPluginConformance().test_foreign_kind_gets_none(
            manager_of(Greedy()), solver, "gymprecice_launch_solver"
        )
    message = str(caught.value)
    assert message.startswith("gymprecice_launch_solver: expected None for a solver of kind")
    assert "LaunchSpec(" in message  # what came back
    assert "Fix: begin the hook with `if solver.kind != 'toy': return None`" in message


def test_validate_case_must_answer_none_for_a_foreign_kind(solver) -> None:
    with pytest.raises(ConformanceError) as caught:
        SolverPluginConformance().test_foreign_kind_gets_none(
            manager_of(ValidatesEverything()), solver, "gymprecice_validate_case"
        )
    assert caught.value.hook == "gymprecice_validate_case"
    assert caught.value.got == "[]"


def test_a_false_prepare_is_refused_with_the_hook_named(solver, tmp_path: Path) -> None:
    with pytest.raises(CaseError, match=r"gymprecice_prepare_case returned False; it must return"):
        SolverPluginConformance().test_prepare_and_reset_write_only_under_run_dir(
            manager_of(FalsePrepare()), solver, tmp_path
        )


def test_a_blank_diagnosis_is_refused(solver) -> None:
    with pytest.raises(ConformanceError) as caught:
        SolverPluginConformance().test_check_solver_answers_str_or_none(
            manager_of(BlankCheck()), solver
        )
    assert caught.value.hook == "gymprecice_check_solver"
    assert "None (nothing wrong) or a non-empty message" in caught.value.expected


def test_a_missing_reset_says_which_hook_to_implement(solver, tmp_path: Path) -> None:
    class NoReset:
        @hookimpl
        def gymprecice_solver_kinds(self):
            return {KIND: "a toy solver"}

    with pytest.raises(CaseError, match=r"every hook gymprecice_reset_case returned None"):
        SolverPluginConformance().test_prepare_and_reset_write_only_under_run_dir(
            manager_of(NoReset()), solver, tmp_path
        )


def test_make_solver_context_sets_every_field_a_hook_reads(tmp_path: Path) -> None:
    from gymprecice.testing import case_config, make_solver_context, validation_context

    source = tmp_path / "case" / "solid"
    source.mkdir(parents=True)
    (source / "solid.cfg").write_text("x\n")
    xml = case_config("fake_flap", tmp_path / "case")
    ctx = make_solver_context(
        "toy",
        source,
        tmp_path / "runs",
        name="solid",
        options={"cfg": "solid.cfg"},
        participant="Solid",
        env_index=2,
        seed=7,
        precice_config=xml,
        config_file=tmp_path / "case" / "gymprecice-config.json",
        precice_library="gymprecice.testing.fake_precice",
        reset_options={"gust": 1.0},
        state={"k": 1},
    )
    assert (
        ctx.run_dir == tmp_path / "runs" / "env_2" / "solid"
        and (ctx.run_dir / "solid.cfg").is_file()
    )
    assert ctx.precice_config_file == tmp_path / "runs" / "env_2" / "precice-config.xml"
    assert ctx.precice is not None and "Solid" in ctx.precice.participants
    assert ctx.uses_test_double and ctx.reset_options == {"gust": 1.0} and ctx.state == {"k": 1}
    assert ctx.rng is not None and ctx.config_file.name == "gymprecice-config.json"

    pristine = validation_context(ctx, xml)
    assert pristine.run_dir == pristine.source_dir == source
    assert pristine.env_dir == tmp_path / "case" and pristine.precice_config_file == xml
    assert pristine.rng is None and pristine.state == {} and pristine.options == ctx.options
