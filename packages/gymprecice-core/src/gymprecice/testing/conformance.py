"""A conformance suite every solver plugin runs against itself.

The hook specs (:mod:`gymprecice.hookspecs`) state rules that pluggy cannot enforce: a
``firstresult`` hook answers ``None`` for a kind it does not handle, a plugin never writes
into the pristine case, a launch runs inside the env's run directory. A plugin that breaks
one of them works alone and fails next to another plugin, or corrupts the case shared by
every env. Subclass :class:`SolverPluginConformance` in the plugin's tests and provide three
fixtures; the tests come with the base class::

    # tests/test_conformance.py of a plugin package
    import pytest
    from gymprecice.testing.conformance import (
        SolverPluginConformance,
        make_solver_context,
    )

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
                options = {"prm": "solid.prm"}
                return make_solver_context(kind, source, base, options=options)
            return make

Mark the subclass (``pytestmark = pytest.mark.openfoam``) when preparing a case needs the
solver installed. Class attributes tune the suite: ``requires_entry_point`` (the plugin
must be declared in the ``gymprecice`` entry-point group) and ``heavy_modules`` (modules
that importing the plugin module must not import, so ``import gymprecice`` stays fast).

This module imports pytest: it is meant for test suites only, and pytest comes with the
``testing`` extra (``pip install 'gymprecice-core[testing]'``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import json
import os
import subprocess
import sys
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from gymprecice.tools.optional import optional_import_error

try:
    import pytest
except ModuleNotFoundError as exc:  # say which extra brings it: gymprecice-core[testing]
    raise optional_import_error(exc, __name__) from None

from gymprecice.env import lifecycle
from gymprecice.plugin import hookspecs
from gymprecice.plugin.manager import (
    DISABLE_ENV_VAR,
    ENTRY_POINT_GROUP,
    GymPrecicePluginManager,
    PluginWarning,
)
from gymprecice.plugin.solver import DoctorCheck, InterfaceGeometry, SolverContext
from gymprecice.testing.contexts import make_solver_context, validation_context

__all__ = [
    "FIRSTRESULT_HOOKS",
    "PER_SOLVER_HOOKS",
    "ConformanceError",
    "SolverPluginConformance",
    "make_solver_context",
    "tree_snapshot",
    "validation_context",
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

#: Every hook that is asked about one solver: each answers ``None`` for a foreign kind.
PER_SOLVER_HOOKS: tuple[str, ...] = tuple(sorted({*FIRSTRESULT_HOOKS, "gymprecice_validate_case"}))


class ConformanceError(AssertionError):
    """A plugin breaks a rule of the hook contract; the message says which and how to fix it.

    An ``AssertionError`` (pytest reports it as a failure), but never a bare one: pytest
    does not rewrite the asserts of an installed module, so each check states its hook,
    what was expected, what came back, and the fix.
    """

    def __init__(self, hook: str, expected: str, got: str, fix: str) -> None:
        self.hook = hook
        self.expected = expected
        self.got = got
        self.fix = fix
        super().__init__(f"{hook}: expected {expected}; got {got or 'nothing'}. Fix: {fix}")


def _require(ok: bool, hook: str, expected: str, got: str, fix: str) -> None:
    if not ok:
        raise ConformanceError(hook, expected, got, fix)


#: Core's own bookkeeping directory inside an env directory (pid registry, worker log).
_CORE_STATE_DIR = ".gymprecice"


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


def _names_module(name: str, module: str, plugin: Any) -> bool:
    """Whether an entry point's module ``name`` is the plugin's: its own name, or another
    name of the same package that imports as the plugin (an alias, as core's
    ``gymprecice.default_plugin`` is of ``gymprecice.env.default_plugin``)."""
    if name == module:
        return True
    if name.split(".")[0] != module.split(".")[0]:
        return False
    try:
        return importlib.import_module(name) is plugin
    except ImportError:
        return False


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
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PluginWarning)
            pm.register(plugin, name="under-test")
        problems = [str(w.message) for w in caught if issubclass(w.category, PluginWarning)]
        _require(
            not problems,
            "registration",
            "the plugin to register without warnings",
            "; ".join(problems),
            "rename each @hookimpl function to the gymprecice hook it implements",
        )
        return pm

    @pytest.fixture
    def solver(self, make_solver: Callable[[Path], SolverContext], tmp_path: Path) -> SolverContext:
        ctx = make_solver(tmp_path)
        _require(
            isinstance(ctx, SolverContext),
            "the make_solver fixture",
            "a SolverContext",
            repr(ctx),
            "return make_solver_context(kind, source_dir, base) from the factory",
        )
        _require(
            ctx.run_dir.is_dir(),
            "the make_solver fixture",
            f"the run directory {ctx.run_dir} to exist",
            "no such directory",
            "copy the case into it (make_solver_context does)",
        )
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
            "time": 0.0,
        }
        spec = getattr(manager.hook, hook).spec
        return {arg: sample[arg] for arg in spec.argnames}

    @staticmethod
    def _answers(manager: GymPrecicePluginManager, hook: str, kwargs: dict) -> list[Any]:
        """The plugin's own answer(s), whether or not the hook is ``firstresult``."""
        caller = getattr(manager.hook, hook)
        return [impl.function(**kwargs) for impl in caller.get_hookimpls()]

    # -- the tests ------------------------------------------------------------------------------

    def test_registers_without_unknown_hooks(self, plugin: Any) -> None:
        """Every ``@hookimpl`` matches a spec: a misspelt hook would never be called."""
        pm = GymPrecicePluginManager()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PluginWarning)
            pm.register(plugin, name="under-test")
        unknown = [c.name for c in pm.get_hookcallers(plugin) or [] if not c.has_spec()]
        _require(
            not unknown,
            ", ".join(unknown) or "@hookimpl",
            "every @hookimpl function to be named after a gymprecice hook",
            f"functions no hook spec knows: {unknown}",
            "rename them to hooks of gymprecice.hookspecs (`gymprecice plugins` lists them)",
        )

    def test_declares_its_kind(self, manager: GymPrecicePluginManager, kind: str) -> None:
        hook = "gymprecice_solver_kinds"
        declared: dict[Any, Any] = {}
        for answer in manager.hook.gymprecice_solver_kinds():
            declared.update(answer or {})
        _require(
            kind in declared,
            hook,
            f"a dict with the kind {kind!r}",
            repr(declared),
            f'return {{"{kind}": "one line saying what the solver is"}}',
        )
        for name, description in declared.items():
            _require(
                isinstance(name, str) and bool(name),
                hook,
                "non-empty strings as kind names",
                repr(name),
                "name each kind with the string used as `kind` in gymprecice-config.json",
            )
            _require(
                isinstance(description, str) and bool(description.strip()),
                hook,
                f"a one-line description of kind {name!r}",
                repr(description),
                "map the kind to a short description (`gymprecice plugins` shows it)",
            )

    def test_declared_as_entry_point(self, plugin: Any) -> None:
        if not self.requires_entry_point:
            pytest.skip("requires_entry_point is False")
        module = getattr(plugin, "__name__", None) or type(plugin).__module__
        values = [
            ep.value
            for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)
            if _names_module(ep.value.split(":", 1)[0].strip(), module, plugin)
        ]
        _require(
            bool(values),
            "the entry point",
            f"{module} in the {ENTRY_POINT_GROUP!r} entry-point group",
            "not declared (or the package is not installed)",
            f'add [project.entry-points.{ENTRY_POINT_GROUP}] <name> = "{module}" to '
            "pyproject.toml and reinstall the package",
        )

    @pytest.mark.parametrize("hook", PER_SOLVER_HOOKS)
    def test_foreign_kind_gets_none(
        self, manager: GymPrecicePluginManager, solver: SolverContext, hook: str
    ) -> None:
        """``None`` is the answer for another plugin's solver, and looking writes nothing.

        Answering for a kind that is not the plugin's would hijack another plugin's
        solver (``firstresult`` hooks stop at the first answer); an empty list from
        ``gymprecice_validate_case`` would claim to have checked a case it cannot read.
        """
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        foreign = dataclasses.replace(solver, kind=self.foreign_kind, state={})
        before = tree_snapshot(solver.env_dir)
        answers = self._answers(manager, hook, self._call_kwargs(manager, hook, foreign))
        _require(
            all(answer is None for answer in answers),
            hook,
            f"None for a solver of kind {self.foreign_kind!r}, which is not this plugin's",
            repr(answers[0] if len(answers) == 1 else answers),
            f"begin the hook with `if solver.kind != {self._kind_hint(manager)}: return None`",
        )
        changed = _diff(before, tree_snapshot(solver.env_dir))
        _require(
            not changed,
            hook,
            "no file changes for a solver of another kind",
            ", ".join(changed),
            "return None before touching any file when the kind is not yours",
        )

    def test_validate_case_reads_only_and_answers_a_list(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        """Validation sees the pristine case (``run_dir == source_dir``) and writes nothing.

        Core validates when a configuration is loaded, before any run directory exists;
        for its own kind the plugin answers a list of problems (empty when all is well).
        """
        hook = "gymprecice_validate_case"
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        pristine = validation_context(solver)
        before = tree_snapshot(pristine.source_dir)
        for answer in self._answers(manager, hook, {"solver": pristine}):
            _require(
                isinstance(answer, list) and all(isinstance(p, str) and p for p in answer),
                hook,
                "a list of problem messages (empty when the case is fine) for the plugin's "
                "own kind; None means 'not my kind'",
                repr(answer),
                "return [] when all is well, or one string per problem naming the file and the fix",
            )
        changed = _diff(before, tree_snapshot(pristine.source_dir))
        _require(
            not changed,
            hook,
            "no file changes in the pristine case (validation only reads)",
            ", ".join(changed),
            "read the files; write only in gymprecice_prepare_case, under solver.run_dir",
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

        changed = _diff(source_before, tree_snapshot(solver.source_dir))
        _require(
            not changed,
            "gymprecice_prepare_case/gymprecice_reset_case",
            f"the pristine case {solver.source_dir} to stay as it was",
            ", ".join(changed),
            "write only under solver.run_dir (the env's copy); read solver.source_dir",
        )
        changed = _diff(around_before, tree_snapshot(tmp_path, exclude=excluded))
        _require(
            not changed,
            "gymprecice_prepare_case/gymprecice_reset_case",
            "no file changes outside the run directory",
            ", ".join(changed),
            "write only under solver.run_dir",
        )

    def test_launch_spec_runs_inside_run_dir(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        hook = "gymprecice_launch_solver"
        lifecycle.prepare_case(manager.hook, solver)
        lifecycle.reset_case(manager.hook, solver)
        spec = lifecycle.launch_spec(manager.hook, solver)
        argv = list(spec.argv)
        _require(
            bool(argv),
            hook,
            "a LaunchSpec with a non-empty argv",
            "argv=[]",
            "give the program and its arguments, e.g. LaunchSpec(argv=['mysolver', 'case.cfg'], "
            "cwd=solver.run_dir)",
        )
        _require(
            all(isinstance(a, (str, os.PathLike)) for a in argv),
            hook,
            "argv items that are strings or paths",
            repr(argv),
            "convert numbers to str",
        )
        _require(
            _inside(Path(spec.cwd), solver.run_dir),
            hook,
            f"LaunchSpec.cwd inside the run directory {solver.run_dir}",
            str(spec.cwd),
            "use cwd=solver.run_dir (or a directory below it), never solver.source_dir",
        )
        env = dict(spec.env)
        _require(
            all(isinstance(k, str) and isinstance(v, str) for k, v in env.items()),
            hook,
            "LaunchSpec.env mapping str to str",
            repr(env),
            "convert the values to str",
        )
        _require(
            bool(spec.log_name) and Path(spec.log_name).name == spec.log_name,
            hook,
            "LaunchSpec.log_name to be a plain file name (the log lands in cwd)",
            repr(spec.log_name),
            "give a name like 'mysolver.log', without directories",
        )

    def test_check_solver_answers_str_or_none(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        """``None`` means "nothing wrong that I can see"; a problem is a non-empty string."""
        hook = "gymprecice_check_solver"
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        for log_text in ("", "some ordinary solver output\n"):
            answer = manager.hook.gymprecice_check_solver(solver=solver, log_text=log_text)
            _require(
                answer is None or (isinstance(answer, str) and bool(answer.strip())),
                hook,
                "None (nothing wrong) or a non-empty message",
                repr(answer),
                "return None for a healthy log; a problem as one string naming the file and "
                "the fix",
            )
            _require(
                answer is None,
                hook,
                f"None for an ordinary log ({log_text!r}): nothing points to a problem",
                repr(answer),
                "only report what the log shows to be wrong (core fails the reset on any answer)",
            )

    def test_interface_geometry_answers_geometry_or_none(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        """``None`` means "I do not know this mesh": the user can still set vertices."""
        hook = "gymprecice_interface_geometry"
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        lifecycle.prepare_case(manager.hook, solver)
        answer = manager.hook.gymprecice_interface_geometry(
            solver=solver, interface="conformance-interface", mesh="Conformance-Mesh"
        )
        _require(
            answer is None or isinstance(answer, InterfaceGeometry),
            hook,
            "an InterfaceGeometry, or None for a mesh the plugin does not know",
            repr(answer),
            "return None for the mesh 'Conformance-Mesh', which no case defines",
        )

    def test_detect_divergence_reads_only_and_spares_a_healthy_solver(
        self, manager: GymPrecicePluginManager, solver: SolverContext
    ) -> None:
        """A healthy run is never called diverged, and looking never changes a file.

        A false divergence ends every episode with the penalty: the agent would learn
        from noise. Core calls the hook while the solver runs (``returncode=None``) and
        after a failure; either way the run directory must stay as it was.
        """
        hook = "gymprecice_detect_divergence"
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        lifecycle.prepare_case(manager.hook, solver)
        lifecycle.reset_case(manager.hook, solver)
        before = tree_snapshot(solver.env_dir)
        for returncode in (None, 0, 1):
            for log_text in ("", "some ordinary solver output\n"):
                answer = manager.hook.gymprecice_detect_divergence(
                    solver=solver, log_text=log_text, returncode=returncode
                )
                _require(
                    answer is None,
                    hook,
                    f"None (not diverged) for a freshly reset solver (returncode {returncode}, "
                    f"log {log_text!r})",
                    repr(answer),
                    "return evidence only when the log or a measured quantity shows divergence",
                )
        changed = _diff(before, tree_snapshot(solver.env_dir))
        _require(
            not changed,
            hook,
            "no file changes (the hook only reads)",
            ", ".join(changed),
            "read the log and output files; never write or delete them here",
        )

    def test_doctor_checks_are_doctor_checks(self, manager: GymPrecicePluginManager) -> None:
        hook = "gymprecice_doctor_checks"
        if not self._implemented(manager, hook):
            pytest.skip(f"{hook} is not implemented")
        for answer in manager.hook.gymprecice_doctor_checks():
            _require(
                isinstance(answer, list),
                hook,
                "a list of DoctorCheck",
                repr(answer),
                "return [DoctorCheck(...), ...] (an empty list when there is nothing to check)",
            )
            for check in answer:
                _require(
                    isinstance(check, DoctorCheck),
                    hook,
                    "DoctorCheck items",
                    repr(check),
                    "build each item with gymprecice.hookspecs.DoctorCheck",
                )
                _require(
                    bool(check.name) and isinstance(check.ok, bool),
                    hook,
                    "a name and a bool `ok` in every DoctorCheck",
                    repr(check),
                    "set name='what was looked for' and ok=True/False",
                )
                _require(
                    check.ok or bool(check.advice),
                    hook,
                    f"advice on the failed check {check.name!r}",
                    "advice=''",
                    "say what to install or set, e.g. advice='run `gymprecice install ...`'",
                )

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
        _require(
            proc.returncode == 0,
            "the plugin module",
            f"`import {module}` to work in a fresh interpreter",
            proc.stderr.strip()[-2000:],
            "fix the import error above",
        )
        imported = json.loads(proc.stdout.strip().splitlines()[-1])
        _require(
            not imported,
            "the plugin module",
            f"importing {module} not to import {heavy}",
            f"it imports {imported}",
            "move those imports into the functions that use them",
        )

    def _kind_hint(self, manager: GymPrecicePluginManager) -> str:
        kinds: list[str] = []
        for answer in manager.hook.gymprecice_solver_kinds():
            kinds.extend(answer or {})
        return repr(kinds[0]) if len(kinds) == 1 else f"a kind of {kinds!r}"
