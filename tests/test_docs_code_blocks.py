"""Every Python code block of README.md and docs/**/*.md runs (or at least compiles) in CI.

A block is executed on its own unless the HTML comment on the line before it says
otherwise: ``<!-- docs-test: compile ... -->`` (it needs names the reader supplies),
``<!-- docs-test: jet-env ... -->`` (docs/writing-an-env.md's env: run against the test double with
the fake cylinder flow writing OpenFOAM-format probes and force coefficients), or
``<!-- docs-test: plugin -->`` (registered as a plugin and its hooks called), or
``<!-- docs-test: compose-... -->`` (docs/composing.md's files and envs, run together by
tests/test_docs_composing.py, which also runs its XML and JSON blocks), or
``<!-- docs-test: own-env-... -->`` (docs/guides/your-own-environment.md's edits and
scripts, replayed in order on a package `gymprecice new` writes, by
tests/test_docs_own_env.py). Blocks that
define an env are constructed and stepped, so an example that cannot run fails here. A
block that only includes a file (``--8<-- "examples/x.py"``) is skipped: the file is
tested where it lives (tests/test_examples.py; RLlib's in tests/test_rllib.py).
"""

from __future__ import annotations

import importlib
import re
import sys
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from gymprecice.testing.conformance import SolverPluginConformance, make_solver_context

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
_FENCE = re.compile(r"^```python[^\n]*\n(.*?)^```", re.M | re.S)
_MARK = re.compile(r"<!--\s*docs-test:\s*([\w-]+)")
#: a block that only includes a file (pymdownx.snippets): the file is tested where it lives
_INCLUDE = re.compile(r"^(?:\s*--8<--.*\n?)+$")


@dataclass(frozen=True)
class Block:
    file: Path
    line: int
    code: str
    mode: str

    @property
    def id(self) -> str:
        return f"{self.file.relative_to(ROOT)}:{self.line}"


def _blocks() -> list[Block]:
    found = []
    for path in DOCS:
        text = path.read_text()
        for match in _FENCE.finditer(text):
            if _INCLUDE.match(match.group(1)):
                continue
            line = text.count("\n", 0, match.start()) + 1
            before = text[: match.start()].rstrip("\n").rsplit("\n", 1)[-1]
            mark = _MARK.search(before)
            found.append(Block(path, line, match.group(1), mark.group(1) if mark else "run"))
    return found


BLOCKS = _blocks()


def _run(block: Block) -> dict:
    namespace: dict = {"__name__": f"docs_block_{block.line}"}
    exec(compile(block.code, f"{block.file}:{block.line}", "exec"), namespace)
    return namespace


def _only(mode: str) -> Block:
    (block,) = [b for b in BLOCKS if b.mode == mode]
    return block


def test_the_blocks_are_found() -> None:
    modes = ("run", "compile", "jet-env", "plugin", "plugin-guide")
    assert {"jet-env", "plugin", "plugin-guide", "compile"} <= {b.mode for b in BLOCKS}
    prefixes = ("compose-", "own-env-")
    assert all(b.mode in modes or b.mode.startswith(prefixes) for b in BLOCKS), BLOCKS


@pytest.mark.parametrize("block", BLOCKS, ids=[b.id for b in BLOCKS])
def test_every_block_compiles(block: Block) -> None:
    compile(block.code, f"{block.file}:{block.line}", "exec")


@pytest.mark.parametrize(
    "block", [b for b in BLOCKS if b.mode == "run"], ids=[b.id for b in BLOCKS if b.mode == "run"]
)
def test_plain_blocks_run(block: Block, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    _run(block)


def test_readme_plugin_block_is_a_working_plugin(tmp_path: Path) -> None:
    from gymprecice.plugin.manager import solver_kinds, temporary_plugin

    module = types.ModuleType("my_plugin")
    module.__dict__.update(_run(_only("plugin")))
    with temporary_plugin(module, "my_plugin") as pm:
        assert "mysolver" in solver_kinds()
        source = tmp_path / "case"
        source.mkdir()
        solver = make_solver_context("mysolver", source, tmp_path)
        (solver.run_dir / "output.dat").write_text("old")
        assert pm.hook.gymprecice_reset_case(solver=solver) is True
        assert not (solver.run_dir / "output.dat").exists()
        spec = pm.hook.gymprecice_launch_solver(solver=solver)
        assert list(spec.argv) == ["mysolver", "case.cfg"] and spec.cwd == solver.run_dir


def _import_block(mode: str, module: str, where: Path, monkeypatch) -> types.ModuleType:
    """The block, written to ``<module>.py`` and imported from there as a plugin would be."""
    (where / f"{module}.py").write_text(_only(mode).code)
    monkeypatch.syspath_prepend(str(where))
    sys.modules.pop(module, None)
    return importlib.import_module(module)


class _PrintedPluginConformance(SolverPluginConformance):
    """A plugin printed in the docs, imported as written, through the conformance suite.

    Only the entry point is not checked, since the printed ``pyproject.toml`` is not
    installed here. Subclasses name the block, its module and the case it runs on.
    """

    __test__ = False
    requires_entry_point = False
    mode = module = solver_dir = case_cfg = ""
    context: dict[str, str] = {}

    @pytest.fixture
    def plugin(self, tmp_path_factory: pytest.TempPathFactory, monkeypatch) -> types.ModuleType:
        where = tmp_path_factory.mktemp(self.mode)
        yield _import_block(self.mode, self.module, where, monkeypatch)
        sys.modules.pop(self.module, None)

    @pytest.fixture
    def kind(self) -> str:
        return "mysolver"

    @pytest.fixture
    def make_solver(self, kind: str):
        def make(base: Path):
            source = base / "case" / self.solver_dir
            source.mkdir(parents=True)
            (source / "case.cfg").write_text(self.case_cfg)
            return make_solver_context(kind, source, base, **self.context)

        return make


class TestReadmePluginConformance(_PrintedPluginConformance):
    """The README's plugin, exactly as printed, passes the suite a plugin package runs."""

    __test__ = True
    mode, module, solver_dir, case_cfg = "plugin", "my_plugin", "solver", "steps = 10\n"


class TestPluginGuideConformance(_PrintedPluginConformance):
    """docs/writing-a-plugin.md's plugin, as printed, passes the suite."""

    __test__ = True
    mode, module, solver_dir = "plugin-guide", "my_solver_plugin", "rod"
    case_cfg = "participant = Rod\n"
    context = {"name": "rod", "participant": "Rod"}

    def test_its_reader_follows_the_reader_conventions(self, plugin, solver) -> None:
        from gymprecice.plugin.solver import WaitableOutputReader

        reader = plugin.gymprecice_open_output(solver=solver, name="temperature", options={})
        assert isinstance(reader, WaitableOutputReader)
        assert reader.read_new().shape == (0, 2) and reader.latest_time is None
        (solver.run_dir / "temperature.dat").write_text("0.1 300.5\n0.2 301.0\n0.3 30")
        rows = reader.wait_until(0.2, timeout=5)
        assert rows.tolist() == [[0.1, 300.5], [0.2, 301.0]] and reader.latest_time == 0.2
        with pytest.raises(TimeoutError, match=r"temperature\.dat: no row for t=0\.3"):
            reader.wait_until(0.3, timeout=0)  # the last line is not complete yet
        assert reader.wait_until(0.2, timeout=0) is rows  # asked again: the same rows
        with (solver.run_dir / "temperature.dat").open("a") as handle:
            handle.write("1.5\n0.4 302.0\n")  # the solver runs a row ahead
        assert reader.wait_until(0.3, timeout=5).tolist() == [[0.3, 301.5]]
        assert reader.latest_time == 0.3 and reader.read_new().tolist() == [[0.4, 302.0]]

    def test_it_finds_what_validation_is_for(self, plugin, solver, tmp_path: Path) -> None:
        from gymprecice.testing import case_config, validation_context

        solver.options["cgf"] = "case.cfg"
        xml = case_config("fake_cylinder", tmp_path / "xml")  # participants Controller, Fluid
        problems = plugin.gymprecice_validate_case(solver=validation_context(solver, xml))
        assert "'cgf' (did you mean 'cfg'?)" in problems[0]
        assert (
            "participant 'Rod' is not in" in problems[1]
            and "['Controller', 'Fluid']" in problems[1]
        )


def test_readme_plugin_runs_in_an_env_without_a_prepare_hook(tmp_path: Path) -> None:
    """The README's plugin has no prepare hook: core's copy of the case is its preparation."""
    from gymprecice import lifecycle
    from gymprecice.plugin.manager import temporary_plugin

    module = types.ModuleType("my_plugin")
    module.__dict__.update(_run(_only("plugin")))
    assert not hasattr(module, "gymprecice_prepare_case")  # the point of this test
    with temporary_plugin(module, "my_plugin") as pm:
        source = tmp_path / "case"
        source.mkdir()
        solver = make_solver_context("mysolver", source, tmp_path)
        assert lifecycle.prepare_case(pm.hook, solver) is False  # nothing beyond the copy
        lifecycle.reset_case(pm.hook, solver)
        assert lifecycle.launch_spec(pm.hook, solver).log_name == "mysolver.log"


def _jet_geometry_plugin(spec) -> types.ModuleType:
    """Stands in for the OpenFOAM plugin's patch geometry of the fake flow's jets."""
    from gymprecice.plugin.hookspecs import hookimpl
    from gymprecice_tutorials.cylinder_geometry import patch_geometry

    @hookimpl
    def gymprecice_interface_geometry(solver, interface, mesh):
        patch = next((p for p in ("jet1", "jet2") if p in mesh), None)
        return None if patch is None else patch_geometry(spec, patch)

    module = types.ModuleType("jet_geometry")
    module.gymprecice_interface_geometry = gymprecice_interface_geometry
    return module


def test_readme_jet_env_runs_against_the_double(tmp_path: Path, monkeypatch) -> None:
    """The documented env, unchanged, on the fake cylinder flow (OpenFOAM-format outputs)."""
    from gymprecice.plugin.manager import temporary_plugin
    from gymprecice_tutorials import fake_flow, recipes

    spec = recipes.case_spec("jet_cylinder")
    case = tmp_path / "case"
    for name, text in fake_flow.double_case_files(spec).items():
        (case / name).parent.mkdir(parents=True, exist_ok=True)
        (case / name).write_text(text)
    monkeypatch.chdir(tmp_path)
    JetEnv = _run(_only("jet-env"))["JetEnv"]
    with temporary_plugin(_jet_geometry_plugin(spec), "jet-geometry"):
        env = JetEnv(str(case))
        try:
            obs, _ = env.reset(seed=0)
            assert obs.shape == (151,) and not obs.any()  # no probe row at the start time
            for _ in range(2):
                obs, reward, terminated, _, _ = env.step(np.array([5e-5], np.float32))
                assert obs.shape == (151,) and np.isfinite(obs).all() and obs.any()
                assert np.isfinite(reward) and not terminated
        finally:
            env.close()
