"""A conformance suite every solver plugin runs against itself.

The hook specs (:mod:`gymprecice.hookspecs`) state rules that pluggy cannot enforce: a
``firstresult`` hook answers ``None`` for a kind it does not handle, a plugin never writes
into the pristine case, a launch runs inside the env's run directory. A plugin that breaks
one of them works alone and fails next to another plugin, or corrupts the case shared by
every env. Subclass :class:`SolverPluginConformance` in the plugin's tests and provide three
fixtures; the tests come with the base class::

    # tests/test_conformance.py of a plugin package
    import pytest
    from gymprecice.testing.conformance import SolverPluginConformance, make_solver_context

    class TestMySolverConformance(SolverPluginConformance):
        @pytest.fixture
        def plugin(self):
            from my_package import plugin
            return plugin

        @pytest.fixture
        def kind(self):
            return "mysolver"

        @pytest.fixture
        def make_solver(self, kind):
            def make(base):
                source = base / "case" / "solid"
                source.mkdir(parents=True)
                (source / "solid.prm").write_text("...")
                return make_solver_context(kind, source, base, options={"prm": "solid.prm"})
            return make

Mark the subclass (``pytestmark = pytest.mark.openfoam``) when preparing a case needs the
solver installed. Class attributes tune the suite: ``requires_entry_point`` (the plugin
must be declared in the ``gymprecice`` entry-point group) and ``heavy_modules`` (modules
that importing the plugin module must not import, so ``import gymprecice`` stays fast).

This module imports pytest: it is meant for test suites only.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import json
import os
import shutil
import subprocess
import sys
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from gymprecice import hookspecs, lifecycle
from gymprecice.plugins import (
    DISABLE_ENV_VAR,
    ENTRY_POINT_GROUP,
    GymPrecicePluginManager,
    PluginWarning,
)
from gymprecice.solver import DoctorCheck, LaunchSpec, SolverContext

__all__ = [
    "FIRSTRESULT_HOOKS",
    "SolverPluginConformance",
    "make_solver_context",
    "tree_snapshot",
]

#: The hooks that act on one solver; each must answer ``None`` for a foreign kind.
FIRSTRESULT_HOOKS: tuple[str, ...] = tuple(
    sorted(
        name
        for name in dir(hookspecs)
        if (getattr(getattr(hookspecs, name), f"{hookspecs.PROJECT_NAME}_spec", None) or {}).get(
            "firstresult"
        )
    )
)

#: Core's own bookkeeping directory inside an env directory (pid registry, worker log).
_CORE_STATE_DIR = ".gymprecice"


def make_solver_context(
    kind: str,
    source_dir: Path,
    base: Path,
    *,
    name: str = "solver",
    options: dict[str, Any] | None = None,
    participant: str | None = None,
    env_index: int = 0,
    seed: int = 0,
) -> SolverContext:
    """Copy ``source_dir`` into ``base/env_<index>/<name>`` and describe it as core would.

    The copy is real (no symlinks into the pristine case), like each env's run directory.
    """
    source_dir = Path(source_dir)
    env_dir = Path(base) / f"env_{env_index}"
    run_dir = env_dir / name
    shutil.copytree(source_dir, run_dir, symlinks=True)
    return SolverContext(
        name=name,
        kind=kind,
        run_dir=run_dir,
        source_dir=source_dir,
        env_dir=env_dir,
        env_index=env_index,
        participant=participant,
        options=dict(options or {}),
        rng=np.random.default_rng(seed),
    )


def tree_snapshot(root: Path, exclude: Iterable[Path] = ()) -> dict[str, tuple[str, int]]:
    """Content hash and mode of every file under ``root`` (paths in ``exclude`` skipped).

    Directories appear with an empty hash, so created or removed empty directories count
    as changes too. Modification times are ignored: rewriting a file with the same bytes
    is harmless.
    """
    root = Path(root)
    skip = {Path(p).resolve() for p in exclude}
    snapshot: dict[str, tuple[str, int]] = {}
    if not root.exists():
        return snapshot
    for dirpath, dirnames, filenames in os.walk(root):
        here = Path(dirpath)
        dirnames[:] = [d for d in dirnames if (here / d).resolve() not in skip]
        for d in dirnames:
            snapshot[str((here / d).relative_to(root)) + "/"] = ("", 0)
        for f in filenames:
            path = here / f
            if path.resolve() in skip:
                continue
            if path.is_symlink():
                digest = "symlink:" + os.readlink(path)
                mode = 0
            else:
                digest = hashlib.sha256(path.read_bytes()).hexdigest()
                mode = path.stat().st_mode & 0o7777
            snapshot[str(path.relative_to(root))] = (digest, mode)
    return snapshot


def _diff(before: dict[str, Any], after: dict[str, Any]) -> list[str]:
    changed = sorted(k for k in before.keys() & after.keys() if before[k] != after[k])
    return (
        [f"created {k}" for k in sorted(after.keys() - before.keys())]
        + [f"removed {k}" for k in sorted(before.keys() - after.keys())]
        + [f"changed {k}" for k in changed]
    )


def _inside(path: Path, root: Path) -> bool:
    try:
        Path(path).resolve().relative_to(Path(root).resolve())
    except ValueError:
        return False
    return True


class SolverPluginConformance:
    """Base class of a plugin's conformance tests (not collected itself: no ``Test`` prefix).

    Subclasses provide the fixtures ``plugin`` (the plugin module or object), ``kind`` (a
    solver kind it handles) and ``make_solver`` (a factory ``base_dir -> SolverContext``
    whose run directory is a fresh copy of a small valid case, see
    :func:`make_solver_context`).
    """

    #: fail when the plugin is not declared in the ``gymprecice`` entry-point group
    requires_entry_point: bool = True
    #: modules importing the plugin module must not pull in
    heavy_modules: tuple[str, ...] = (
        "torch",
        "matplotlib",
        "precice",
        "mpi4py",
        "stable_baselines3",
        "pandas",
    )
    #: a kind no plugin handles, for the "not mine" answers
    foreign_kind: str = "gymprecice-conformance-foreign-kind"

    # -- fixtures a subclass must provide -----------------------------------------------------

    @pytest.fixture
    def plugin(self) -> Any:
        raise NotImplementedError(
            f"{type(self).__name__} must override the 'plugin' fixture (return the plugin module)"
        )

    @pytest.fixture
    def kind(self) -> str:
        raise NotImplementedError(
            f"{type(self).__name__} must override the 'kind' fixture (a solver kind it handles)"
        )

    @pytest.fixture
    def make_solver(self) -> Callable[[Path], SolverContext]:
        raise NotImplementedError(
            f"{type(self).__name__} must override the 'make_solver' fixture "
            "(a factory base_dir -> SolverContext, see make_solver_context)"
        )

    # -- derived fixtures ---------------------------------------------------------------------

    @pytest.fixture
    def manager(self, plugin: Any) -> GymPrecicePluginManager:
        """A manager holding only this plugin: other installed plugins cannot answer for it."""
        pm = GymPrecicePluginManager()
        with warnings.catch_warnings():
            warnings.simplefilter("error", PluginWarning)
            pm.register(plugin, name="under-test")
        return pm

    @pytest.fixture
    def solver(self, make_solver: Callable[[Path], SolverContext], tmp_path: Path) -> SolverContext:
        ctx = make_solver(tmp_path)
        assert isinstance(ctx, SolverContext), "make_solver must return a SolverContext"
        assert ctx.run_dir.is_dir(), f"make_solver must create the run directory {ctx.run_dir}"
        return ctx

    # -- helpers --------------------------------------------------------------------------------

    @staticmethod
    def _implemented(manager: GymPrecicePluginManager, hook: str) -> bool:
        return bool(getattr(manager.hook, hook).get_hookimpls())

    @staticmethod
    def _call_kwargs(manager: GymPrecicePluginManager, hook: str, solver: SolverContext) -> dict:
        sample = {
            "solver": solver,
            "log_text": "",
            "returncode": None,
            "interface": "conformance-interface",
            "mesh": "Conformance-Mesh",
            "name": "conformance-output",
            "options": {},
        }
        spec = getattr(manager.hook, hook).spec
        return {arg: sample[arg] for arg in spec.argnames}

    # -- the tests ------------------------------------------------------------------------------

    def test_registers_without_unknown_hooks(self, plugin: Any) -> None:
        """Every ``@hookimpl`` matches a spec: a misspelt hook would never be called."""
        pm = GymPrecicePluginManager()
        with warnings.catch_warnings():
            warnings.simplefilter("error", PluginWarning)
            pm.register(plugin, name="under-test")
        unknown = [c.name for c in pm.get_hookcallers(plugin) or [] if not c.has_spec()]
        assert not unknown, f"hooks without a gymprecice spec: {unknown}"

    def test_declares_its_kind(self, manager: GymPrecicePluginManager, kind: str) -> None:
        declared: dict[str, Any] = {}
        for answer in manager.hook.gymprecice_solver_kinds():
            declared.update(answer or {})
        assert kind in declared, f"gymprecice_solver_kinds() lacks {kind!r}: {declared}"
        for name, description in declared.items():
            assert isinstance(name, str) and name, f"kind names must be strings: {name!r}"
            assert isinstance(description, str) and description.strip(), (
                f"kind {name!r} needs a one-line description"
            )

    def test_declared_as_entry_point(self, plugin: Any) -> None:
        if not self.requires_entry_point:
            pytest.skip("requires_entry_point is False")
        module = getattr(plugin, "__name__", None) or type(plugin).__module__
        values = [
            ep.value
            for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)
            if ep.value.split(":", 1)[0].strip() == module
        ]
        assert values, (
            f"{module} is not declared in the {ENTRY_POINT_GROUP!r} entry-point group; add "
            f'[project.entry-points.{ENTRY_POINT_GROUP}] <name> = "{module}" to pyproject.toml '
            "and reinstall the package"
        )

    @pytest.mark.parametrize("hook", FIRSTRESULT_HOOKS)
    def test_foreign_kind_gets_none(
        self, manager: GymPrecicePluginManager, solver: SolverContext, hook: str
    ) -> None:
        """Answering for a kind that is not the plugin's would hijack another plugin's solver."""
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        foreign = dataclasses.replace(solver, kind=self.foreign_kind, state={})
        before = tree_snapshot(solver.env_dir)
        result = getattr(manager.hook, hook)(**self._call_kwargs(manager, hook, foreign))
        assert result is None, f"{hook} answered {result!r} for kind {self.foreign_kind!r}"
        assert not _diff(before, tree_snapshot(solver.env_dir)), (
            f"{hook} changed files for a solver that is not its kind"
        )

    def test_prepare_and_reset_write_only_under_run_dir(
        self, manager: GymPrecicePluginManager, solver: SolverContext, tmp_path: Path
    ) -> None:
        """The pristine case is shared by every env: only the env's copy may change."""
        source_before = tree_snapshot(solver.source_dir)
        excluded = [solver.run_dir, solver.env_dir / _CORE_STATE_DIR]
        around_before = tree_snapshot(tmp_path, exclude=excluded)

        lifecycle.prepare_case(manager.hook, solver)
        for episode in range(2):  # a reset must also work after a reset
            solver.rng = np.random.default_rng(episode)
            lifecycle.reset_case(manager.hook, solver)

        assert not _diff(source_before, tree_snapshot(solver.source_dir)), (
            f"the pristine case {solver.source_dir} was modified"
        )
        changed = _diff(around_before, tree_snapshot(tmp_path, exclude=excluded))
        assert not changed, f"files outside the run directory changed: {changed}"

    def test_launch_spec_runs_inside_run_dir(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        lifecycle.prepare_case(manager.hook, solver)
        lifecycle.reset_case(manager.hook, solver)
        spec = lifecycle.launch_spec(manager.hook, solver)
        assert isinstance(spec, LaunchSpec), f"launch returned {spec!r}, not a LaunchSpec"
        argv = list(spec.argv)
        assert argv, "LaunchSpec.argv is empty"
        assert all(isinstance(a, (str, os.PathLike)) for a in argv), f"argv items: {argv!r}"
        assert _inside(Path(spec.cwd), solver.run_dir), (
            f"LaunchSpec.cwd {spec.cwd} is outside the run directory {solver.run_dir}"
        )
        assert all(isinstance(k, str) and isinstance(v, str) for k, v in dict(spec.env).items()), (
            f"LaunchSpec.env must map str to str: {dict(spec.env)!r}"
        )
        assert spec.log_name and Path(spec.log_name).name == spec.log_name, (
            f"LaunchSpec.log_name must be a plain file name, got {spec.log_name!r}"
        )

    def test_check_solver_answers_str_or_none(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        if not self._implemented(manager, "gymprecice_check_solver"):
            pytest.skip("gymprecice_check_solver is not implemented")
        for log_text in ("", "some ordinary solver output\n"):
            answer = manager.hook.gymprecice_check_solver(solver=solver, log_text=log_text)
            assert answer is None or (isinstance(answer, str) and answer.strip()), answer

    def test_detect_divergence_reads_only_and_spares_a_healthy_solver(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        """A healthy run is never called diverged, and looking never changes a file.

        A false divergence ends every episode with the penalty: the agent would learn
        from noise. Core calls the hook while the solver runs (``returncode=None``) and
        after a failure; either way the run directory must stay as it was.
        """
        if not self._implemented(manager, "gymprecice_detect_divergence"):
            pytest.skip("gymprecice_detect_divergence is not implemented")
        lifecycle.prepare_case(manager.hook, solver)
        lifecycle.reset_case(manager.hook, solver)
        before = tree_snapshot(solver.env_dir)
        for returncode in (None, 0, 1):
            for log_text in ("", "some ordinary solver output\n"):
                answer = manager.hook.gymprecice_detect_divergence(
                    solver=solver, log_text=log_text, returncode=returncode
                )
                assert answer is None, (
                    f"gymprecice_detect_divergence called a freshly reset solver diverged "
                    f"(returncode {returncode}, log {log_text!r}): {answer!r}"
                )
        assert not _diff(before, tree_snapshot(solver.env_dir)), (
            "gymprecice_detect_divergence changed files; it may only read them"
        )

    def test_doctor_checks_are_doctor_checks(self, manager: GymPrecicePluginManager) -> None:
        if not self._implemented(manager, "gymprecice_doctor_checks"):
            pytest.skip("gymprecice_doctor_checks is not implemented")
        for answer in manager.hook.gymprecice_doctor_checks():
            assert isinstance(answer, list), f"doctor checks must be a list, got {answer!r}"
            for check in answer:
                assert isinstance(check, DoctorCheck), f"{check!r} is not a DoctorCheck"
                assert check.name and isinstance(check.ok, bool)
                if not check.ok:
                    assert check.advice, f"failed check {check.name!r} says nothing about a fix"

    def test_import_is_light(self, plugin: Any) -> None:
        """``import gymprecice`` loads every plugin module: heavy imports belong in functions."""
        module = getattr(plugin, "__name__", None)
        if not isinstance(plugin, ModuleType) or not module:
            pytest.skip("the plugin is not a module")
        heavy = [m for m in self.heavy_modules if m.split(".")[0] != module.split(".")[0]]
        code = (
            "import importlib, json, sys\n"
            f"importlib.import_module({module!r})\n"
            f"print(json.dumps([m for m in {heavy!r} if m in sys.modules]))\n"
        )
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
        env[DISABLE_ENV_VAR] = "1"  # only this plugin, not the others it would load
        proc = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
        )
        assert proc.returncode == 0, proc.stderr
        imported = json.loads(proc.stdout.strip().splitlines()[-1])
        assert not imported, (
            f"importing {module} imports {imported}; move those imports into the functions "
            "that use them"
        )
