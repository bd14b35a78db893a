"""The project's import structure: no import circle, no private name across modules.

Read from the source of every distribution under ``packages/*/src`` (nothing is
imported): a module's imports, at its top, inside a function or under
``if TYPE_CHECKING:`` (a circle of types is still a circle of the design), are its
arrows. One kind of import draws none: a module's import of a name from a package that
contains it (the package's face, its ``__init__``, which imports its own modules). A circle is a set of modules that import
each other in a loop; a private name is one with a single leading underscore
(``_lookup``, a ``_private`` module), imported from another module.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _modules(roots: list[Path]) -> dict[str, tuple[Path, bool]]:
    """Every module under ``roots``: dotted name -> (file, whether it is a package)."""
    found = {}
    for root in roots:
        for path in sorted(root.rglob("*.py")):
            parts = list(path.relative_to(root).with_suffix("").parts)
            package = parts[-1] == "__init__"
            if package:
                parts = parts[:-1]
            if parts and all(part.isidentifier() for part in parts):
                found[".".join(parts)] = (path, package)
    return found


def _private(name: str) -> bool:
    return any(p.startswith("_") and not p.startswith("__") for p in name.split("."))


def _imports(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement of the module, wherever it stands."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node


def _structure(
    modules: dict[str, tuple[Path, bool]], root: Path = ROOT
) -> tuple[dict[str, set[str]], list[str]]:
    """The arrows between ``modules`` and the private names imported across them (each
    said with its file, relative to ``root``, and line)."""
    tops = {name.split(".")[0] for name in modules}
    arrows: dict[str, set[str]] = {name: set() for name in modules}
    private: list[str] = []
    for name, (path, package) in modules.items():
        here = name if package else name.rpartition(".")[0]
        for node in _imports(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [(a.name, None) for a in node.names]
            else:
                base = (
                    here.split(".")[: len(here.split(".")) - node.level + 1] if node.level else []
                )
                source = ".".join([*base, node.module] if node.module else base)
                targets = [(source, a.name) for a in node.names]
            for source, imported in targets:
                if source.split(".")[0] not in tops:
                    continue
                full = f"{source}.{imported}" if imported else source
                target = full if full in modules else source
                where = f"{path.relative_to(root)}:{node.lineno}"
                if _private(full) and not name.startswith(source + ".") and target != name:
                    private.append(f"{where} imports {full}")
                if target in modules and not (modules[target][1] and name.startswith(target + ".")):
                    arrows[name].add(target)
    return arrows, private


def _circles(arrows: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected sets of more than one module (Tarjan, without recursion)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []
    for start in arrows:
        if start in index:
            continue
        work = [(start, iter(sorted(arrows[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(arrows.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                members = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    members.append(member)
                    if member == node:
                        break
                if len(members) > 1:
                    circles.append(sorted(members))
    return circles


@pytest.fixture(scope="module")
def structure() -> tuple[dict[str, set[str]], list[str]]:
    roots = sorted(p for p in (ROOT / "packages").glob("*/src") if p.is_dir())
    assert roots, "no packages/*/src found"
    return _structure(_modules(roots))


def test_no_import_circle(structure):
    arrows, _ = structure
    circles = _circles(arrows)
    assert not circles, "modules that import each other in a loop: " + "; ".join(
        " <-> ".join(c) for c in circles
    )


def test_no_private_name_imported_across_modules(structure):
    _, private = structure
    assert not private, "private names imported from another module (make them public): " + (
        "; ".join(private)
    )


def test_the_checks_can_fail(tmp_path):
    """A circle and a private import, written on purpose, are both found."""
    package = tmp_path / "src" / "pkg"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from pkg.b import helper\n")
    (package / "b.py").write_text("def helper(): ...\ndef later():\n    from pkg import a\n")
    (package / "c.py").write_text("from pkg.b import _hidden\n")
    (package / "d.py").write_text("from pkg import c\n")  # a package's face: no arrow to it
    (package / "e.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.f import F\n"
    )
    (package / "f.py").write_text("from pkg.e import E\n")
    arrows, private = _structure(_modules([tmp_path / "src"]), tmp_path)
    assert sorted(_circles(arrows)) == [["pkg.a", "pkg.b"], ["pkg.e", "pkg.f"]]
    assert private == ["src/pkg/c.py:1 imports pkg.b._hidden"]
    assert arrows["pkg.d"] == {"pkg.c"}


# -- the plugin surface: a solver plugin imports gymprecice.plugin and nothing else of core --

#: The one part of core a solver plugin's source may import (with its modules).
PLUGIN_SURFACE = "gymprecice.plugin"


def _entry_point_modules(pyproject: Path) -> list[str]:
    import tomllib

    project = tomllib.loads(pyproject.read_text()).get("project", {})
    group = project.get("entry-points", {}).get("gymprecice", {})
    return [value.split(":", 1)[0].strip() for value in group.values()]


def _solver_plugin_sources(packages: Path) -> dict[str, Path]:
    """Distribution -> its ``src``, for each whose ``gymprecice`` entry point names a module
    that answers ``gymprecice_solver_kinds``: a solver plugin (core itself excepted)."""
    found = {}
    for pyproject in sorted(packages.glob("*/pyproject.toml")):
        src = pyproject.parent / "src"
        if pyproject.parent.name == "gymprecice-core" or not src.is_dir():
            continue
        for module in _entry_point_modules(pyproject):
            path = src.joinpath(*module.split(".")).with_suffix(".py")
            if not path.is_file():
                path = src.joinpath(*module.split("."), "__init__.py")
            tree = ast.parse(path.read_text(), str(path))
            if any(
                isinstance(node, ast.FunctionDef) and node.name == "gymprecice_solver_kinds"
                for node in tree.body
            ):
                found[pyproject.parent.name] = src
    return found


def _core_imports_beyond_the_surface(src: Path, root: Path = ROOT) -> list[str]:
    """Every import, anywhere in a module under ``src``, of a ``gymprecice`` module other
    than :data:`PLUGIN_SURFACE` and its modules (said with file and line)."""
    found = []
    for path in sorted(src.rglob("*.py")):
        for node in _imports(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif node.level == 0 and node.module == "gymprecice":
                names = [f"gymprecice.{alias.name}" for alias in node.names]
            elif node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                if name.split(".")[0] != "gymprecice":
                    continue
                if name == PLUGIN_SURFACE or name.startswith(PLUGIN_SURFACE + "."):
                    continue
                found.append(f"{path.relative_to(root)}:{node.lineno} imports {name}")
    return found


def test_solver_plugins_import_only_the_plugin_surface():
    """openfoam, deal.II and FEniCS reach core through ``gymprecice.plugin`` alone, so that
    core's runtime, tools and learners may change without touching a plugin."""
    sources = _solver_plugin_sources(ROOT / "packages")
    assert set(sources) == {"gymprecice-openfoam", "gymprecice-dealii", "gymprecice-fenics"}
    beyond = [line for src in sources.values() for line in _core_imports_beyond_the_surface(src)]
    assert not beyond, f"solver plugins must import core only as {PLUGIN_SURFACE}: " + (
        "; ".join(beyond)
    )


def test_the_plugin_surface_check_can_fail(tmp_path):
    src = tmp_path / "src" / "my_plugin"
    src.mkdir(parents=True)
    (src / "plugin.py").write_text(
        "import gymprecice\n"
        "from gymprecice import plugin\n"
        "from gymprecice.plugin import hookimpl\n"
        "from gymprecice.plugin.fields import Field\n"
        "from gymprecice import processes\n"
        "def hook():\n    from gymprecice.env.core import Adapter\n"
    )
    assert _core_imports_beyond_the_surface(tmp_path / "src", tmp_path) == [
        "src/my_plugin/plugin.py:1 imports gymprecice",
        "src/my_plugin/plugin.py:5 imports gymprecice.processes",
        "src/my_plugin/plugin.py:7 imports gymprecice.env.core",
    ]


# -- the cases keep their physics: the tutorials import nothing of the lab ------------------

#: The distribution whose source holds the cases, and the one it must not reach: the
#: lab's commands run any registered env, and a case names what the lab needs in its card
#: (a feedback law, its starts) rather than calling the lab itself.
TUTORIALS = ROOT / "packages" / "gymprecice-tutorials" / "src"
LAB = "gymprecice_lab"


def _imports_of(package: str, src: Path, root: Path = ROOT) -> list[str]:
    """Every import of ``package`` or its modules, anywhere in a module under ``src`` (at
    its top or inside a function; ``importlib.import_module("...")`` and ``__import__``
    with a literal name too), said with file and line."""
    found = []
    for path in sorted(src.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            elif (
                isinstance(node, ast.Call)
                and (getattr(node.func, "attr", None) or getattr(node.func, "id", None))
                in {"import_module", "__import__"}
                and node.args
                and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)
            ):
                names = [node.args[0].value]
            else:
                continue
            for name in names:
                if name.split(".")[0] == package:
                    found.append(f"{path.relative_to(root)}:{node.lineno} imports {name}")
    return found


def test_the_tutorials_import_nothing_of_the_lab():
    """The cases hold their physics (an env, its case, its feedback law); running,
    sweeping, comparing and plotting any env is the lab's (``gymprecice sweep``,
    ``evaluate``, ...). A command a case still offers (``python -m
    gymprecice_tutorials.heated_plate.pid``) runs the lab's commands through the
    ``gymprecice`` command line, never by importing the lab."""
    found = _imports_of(LAB, TUTORIALS)
    assert not found, f"gymprecice_tutorials must not import {LAB}: " + "; ".join(found)


def test_the_lab_import_check_can_fail(tmp_path):
    src = tmp_path / "src" / "cases"
    src.mkdir(parents=True)
    (src / "case.py").write_text(
        "import importlib\n"
        "import gymprecice_lab_extra\n"
        "from gymprecice.cli import main\n"
        "def run():\n"
        "    from gymprecice_lab.rollouts import sweep\n"
        "    import gymprecice_lab\n"
        "    return importlib.import_module('gymprecice_lab.policies')\n"
    )
    assert _imports_of(LAB, tmp_path / "src", tmp_path) == [
        "src/cases/case.py:5 imports gymprecice_lab.rollouts",
        "src/cases/case.py:6 imports gymprecice_lab",
        "src/cases/case.py:7 imports gymprecice_lab.policies",
    ]


# -- the old module paths: each one is its new home, the same module object ----------------


def _moved_tables() -> dict[str, str]:
    from gymprecice.old_paths import MOVED as core_moved
    from gymprecice_lab.old_paths import MOVED as lab_moved

    return {**core_moved, **lab_moved}


def test_every_old_module_path_is_its_new_home():
    """An old path imports as the module that holds it now, and keeps no file of its own
    (the folder tree shows the wings alone)."""
    import importlib

    moved = _moved_tables()
    assert len(moved) == 98
    for old, new in moved.items():
        package, _, name = old.rpartition(".")
        folder = ROOT / "packages" / f"{package.replace('_', '-')}" / "src" / package
        if package == "gymprecice":
            folder = ROOT / "packages" / "gymprecice-core" / "src" / package
        assert not (folder / f"{name}.py").exists(), old
        assert (ROOT / "packages").glob(f"*/src/{new.replace('.', '/')}.py"), new
        module = importlib.import_module(new)
        assert importlib.import_module(old) is module, old
        assert module.__spec__.name == new, f"{old} changed {new}'s __spec__"
        assert module.__name__ == new


def test_an_old_path_runs_as_a_command_and_unpickles():
    """``python -m OLD`` runs the new module as ``__main__`` (the owner's watchdog is
    started that way), and an object pickled under an old path loads."""
    import pickle

    code = "import pickle, sys; print(type(pickle.loads(sys.stdin.buffer.read())).__module__)"
    from gymprecice.plugin.errors import CaseError

    # a pickle written by a version whose CaseError lived in gymprecice.errors
    payload = pickle.dumps(CaseError("x"), protocol=0).replace(
        b"gymprecice.plugin.errors", b"gymprecice.errors"
    )
    assert b"gymprecice.errors" in payload
    loaded = subprocess.run(
        [sys.executable, "-c", code], input=payload, capture_output=True, check=True
    )
    assert loaded.stdout.decode().strip() == "gymprecice.plugin.errors"
    # no descriptor to watch: the new module's main runs, as __main__, and refuses it
    run = subprocess.run(
        [sys.executable, "-m", "gymprecice.owner_watchdog", "not-a-descriptor"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert run.returncode != 0
    assert 'gymprecice/env/owner_watchdog.py", line' in run.stderr, run.stderr
    assert "in <module>" in run.stderr and "in main" in run.stderr, run.stderr


# -- the multi-agent env: composed of the episode runner, no reach into other objects --------

#: The multi-agent package, which runs on the Adapter's episode runner by composition.
MULTIAGENT = ROOT / "packages" / "gymprecice-core" / "src" / "gymprecice" / "multiagent"


def _own(node: ast.expr) -> bool:
    """``self``, ``cls`` or ``super()``: the object whose code this is."""
    if isinstance(node, ast.Name):
        return node.id in {"self", "cls"}
    return (
        isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "super"
    )


def _private_of_another(node: ast.AST) -> bool:
    """``other._x``, or ``getattr(other, "_x")`` (``setattr``, ``hasattr``, ``delattr``)."""
    if isinstance(node, ast.Attribute):
        return _private(node.attr) and not _own(node.value)
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
        return False
    if node.func.id not in {"getattr", "setattr", "hasattr", "delattr"} or len(node.args) < 2:
        return False
    name = node.args[1]
    return (
        isinstance(name, ast.Constant)
        and isinstance(name.value, str)
        and _private(name.value)
        and not _own(node.args[0])
    )


def _reach_ins(src: Path, root: Path = ROOT) -> list[str]:
    """Every private attribute of another object (``env._engine``, ``getattr(env, "_x")``)
    and every subclass of ``Adapter``, in the modules under ``src`` (file and line)."""
    found = []
    for path in sorted(src.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            where = f"{path.relative_to(root)}:{getattr(node, 'lineno', 0)}"
            if _private_of_another(node):
                found.append(f"{where} reaches into {ast.unparse(node)}")
            elif isinstance(node, ast.ClassDef):
                for base in node.bases:
                    name = base.attr if isinstance(base, ast.Attribute) else getattr(base, "id", "")
                    if name == "Adapter":
                        found.append(f"{where} subclasses Adapter: {node.name}")
    return found


def test_the_multi_agent_env_is_composed_and_reaches_into_no_other_object():
    """The multi-agent env hands the episode runner what it needs (a view, the user's
    methods as callables) instead of being an Adapter or reading another object's
    private attributes, so either side can change without breaking the other."""
    found = _reach_ins(MULTIAGENT)
    assert not found, "pass it explicitly (a callable, a public attribute): " + "; ".join(found)


def test_the_reach_in_check_can_fail(tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    (src / "env.py").write_text(
        "from gymprecice.core import Adapter\n"
        "class Engine(Adapter):\n"
        "    def step(self, owner):\n"
        "        self._fine = super()._also_fine\n"
        "        owner._slots.clear()\n"
        "        return getattr(owner, '_who')(), owner.__class__, owner.public\n"
    )
    assert _reach_ins(src, tmp_path) == [
        "src/env.py:2 subclasses Adapter: Engine",
        "src/env.py:5 reaches into owner._slots",
        "src/env.py:6 reaches into getattr(owner, '_who')",
    ]
