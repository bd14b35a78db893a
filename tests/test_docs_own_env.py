"""docs/guides/your-own-environment.md runs as printed: `gymprecice new` to a benchmark.

Every fenced block of the page carries a ``<!-- docs-test: own-env-<what> -->`` mark (a
block without one fails here), and the page is replayed in its order, as a reader who
follows it would:

* ``own-env-shell``: the block runs in bash (``-e``), in a working folder of its own, with ``pip``,
  ``gymprecice`` and ``pytest`` those of a virtual environment that sees the set-up's
  ``.venv`` (so ``pip install -e ./my-env`` installs the generated package there, offline,
  and leaves ``.venv`` as it was);
* ``own-env-edit [FILE]``: an edit of the generated package (FILE, under ``my-env/``; by
  default the env module). A ``diff`` block replaces its ``-`` and context lines, found
  once in the file, by its ``+`` and context lines. A Python block adds its imports after
  the file's last import, replaces the methods (and class attributes) of its class, and
  replaces a top-level function of the same name or adds it before the first one;
* ``own-env-script NAME``: the Python block is saved as NAME in the working folder (the
  page tells the reader to save it; a shell block runs it);
* ``own-env-layout``: the tree of the generated package: each file it names exists;
* ``own-env-output``: the text block is what the command or script before it printed:
  each of its lines is a line of the real output, in order (``...`` stands for any
  text: timings and this machine's paths), so a changed output fails here;
* ``own-env-real``: the commands that need preCICE and a real solver; they are not run,
  but each ``gymprecice`` line must parse with the command line.

The quick tests check the page's structure and apply its edits to a freshly generated
package; the slow one replays the whole page on the test double.
"""

from __future__ import annotations

import ast
import itertools
import os
import re
import shlex
import subprocess
import sysconfig
import textwrap
import venv
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "guides" / "your-own-environment.md"
_FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.M | re.S)
_MARK = re.compile(r"<!--\s*docs-test:\s*(own-env-[\w-]+)(?:\s+(?!-->)(\S+))?")
KINDS = ("shell", "edit", "script", "output", "layout", "real")
#: the file an ``own-env-edit`` block edits when its mark names none
DEFAULT_EDIT = "src/my_env/env.py"
#: seconds one command of the page may take before the test fails instead of hanging
COMMAND_TIMEOUT = 600


@dataclass(frozen=True)
class Block:
    line: int
    kind: str
    arg: str
    lang: str
    code: str


def page_blocks(page: Path = PAGE) -> list[Block]:
    """Every fenced block of the page, in order, with its mark."""
    text = page.read_text()
    blocks = []
    for match in _FENCE.finditer(text):
        line = text.count("\n", 0, match.start()) + 1
        before = text[: match.start()].rstrip("\n").rsplit("\n", 1)[-1]
        mark = _MARK.search(before)
        assert mark, f"{page.name}:{line}: a code block without an own-env docs-test mark"
        kind = mark.group(1).removeprefix("own-env-")
        assert kind in KINDS, f"{page.name}:{line}: unknown mark own-env-{kind}"
        blocks.append(Block(line, kind, mark.group(2) or "", match.group(1), match.group(2)))
    return blocks


# -- edits -------------------------------------------------------------------------------------


def apply_diff(source: str, diff: str) -> str:
    """``source`` with the diff's ``-``/context lines replaced by its ``+``/context lines."""
    old, new = [], []
    for line in diff.splitlines():
        sign, rest = line[:1], line[1:]
        if sign in (" ", ""):
            old.append(rest)
            new.append(rest)
        elif sign == "-":
            old.append(rest)
        elif sign == "+":
            new.append(rest)
        else:
            raise ValueError(f"not a diff line: {line!r}")
    before = "\n".join(old) + "\n"
    count = source.count(before)
    if count != 1:
        raise ValueError(f"the lines to replace are found {count} times, not once:\n{before}")
    return source.replace(before, "\n".join(new) + "\n")


def _span(node: ast.AST) -> tuple[int, int]:
    """Lines of a statement (0-based, end excluded), decorators included."""
    first = min([node.lineno, *(d.lineno for d in getattr(node, "decorator_list", []))])
    return first - 1, node.end_lineno


def _segment(code: str, node: ast.AST) -> list[str]:
    start, end = _span(node)
    return textwrap.dedent("\n".join(code.splitlines()[start:end])).splitlines()


def _targets(node: ast.Assign | ast.AnnAssign) -> set[str]:
    return {
        ast.unparse(t) for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
    }


def _comments_above(code: str, node: ast.AST) -> list[str]:
    """The comment lines right above a statement of the block (a constant's ``#:``)."""
    lines = code.splitlines()[: _span(node)[0]]
    above: list[str] = []
    while lines and lines[-1].lstrip().startswith("#"):
        above.insert(0, lines.pop())
    return above


def apply_python(source: str, code: str) -> str:
    """``source`` with the block's imports, functions and class members put in."""
    lines = source.splitlines()
    tree = ast.parse(source)
    # edits from the bottom up, so that earlier line numbers stay true
    edits: list[tuple[int, int, list[str]]] = []
    imports = [n for n in ast.parse(code).body if isinstance(n, (ast.Import, ast.ImportFrom))]
    if imports:
        last = max(n.end_lineno for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom)))
        new = [line for n in imports for line in _segment(code, n)]
        edits.append((last, last, new))
    first_def = next(n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef)))
    for node in ast.parse(code).body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            continue
        if isinstance(node, ast.FunctionDef):
            same = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == node.name]
            new = _segment(code, node)
            if same:
                edits.append((*_span(same[0]), new))
            else:
                at = _span(first_def)[0]
                edits.append((at, at, [*new, "", ""]))
        elif isinstance(node, ast.ClassDef):
            (cls,) = [n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == node.name]
            indent = " " * cls.body[0].col_offset
            body = cls.body
            doc = body[0] if isinstance(body[0], ast.Expr) else None
            for member in node.body:
                new = textwrap.indent("\n".join(_segment(code, member)), indent).splitlines()
                if isinstance(member, ast.FunctionDef):
                    same = [
                        n for n in body if isinstance(n, ast.FunctionDef) and n.name == member.name
                    ]
                    if same:
                        edits.append((*_span(same[0]), new))
                        continue
                    at = cls.end_lineno
                    edits.append((at, at, ["", *new]))
                else:  # a class attribute: after the docstring
                    at = doc.end_lineno if doc else cls.body[0].lineno - 1
                    edits.append((at, at, new))
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):  # a constant: replaced or added
            same = [
                n for n in tree.body if isinstance(n, (ast.Assign, ast.AnnAssign))
                and _targets(n) == _targets(node)
            ]  # fmt: skip
            new = _segment(code, node)
            comments = _comments_above(code, node)
            if same:
                edits.append((*_span(same[0]), new))
            else:
                at = _span(first_def)[0]
                edits.append((at, at, [*comments, *new, "", ""]))
        else:
            raise ValueError(f"a Python edit holds imports, constants, functions and classes, not "
                             f"{ast.unparse(node)!r}")  # fmt: skip
    # bottom up; of two insertions at one line, the block's later one first, so that
    # the earlier one lands above it
    order = sorted(range(len(edits)), key=lambda i: (edits[i][0], edits[i][1], i), reverse=True)
    for start, end, new in (edits[i] for i in order):
        lines[start:end] = new
    return "\n".join(lines) + "\n"


def apply_edit(package: Path, block: Block) -> None:
    path = package / (block.arg or DEFAULT_EDIT)
    source = path.read_text()
    if block.lang == "diff":
        path.write_text(apply_diff(source, block.code))
    else:
        path.write_text(apply_python(source, block.code))
    compile(path.read_text(), str(path), "exec")


# -- outputs -----------------------------------------------------------------------------------


def shown_in(shown: str, output: str) -> str | None:
    """Why the shown lines are not the output's (``None``: each is an output line, in order;
    ``...`` stands for any text)."""
    actual = [line.rstrip() for line in output.splitlines()]
    at = 0
    for line in shown.splitlines():
        pattern = re.compile(".*".join(re.escape(p) for p in line.rstrip().split("...")))
        while at < len(actual) and not pattern.fullmatch(actual[at]):
            at += 1
        if at == len(actual):
            return f"not printed (in this order): {line!r}"
        at += 1
    return None


# -- the quick tests ---------------------------------------------------------------------------


def test_every_block_is_marked_and_outputs_follow_commands() -> None:
    blocks = page_blocks()
    kinds = [b.kind for b in blocks]
    assert set(KINDS) <= set(kinds), sorted(set(KINDS) - set(kinds))
    for before, block in itertools.pairwise(blocks):
        if block.kind == "output":
            assert before.kind == "shell", f"line {block.line}"
    assert blocks[0].kind == "shell" and blocks[0].code.startswith("gymprecice new my-env")


def test_the_real_solver_commands_parse() -> None:
    from gymprecice.tools.cli import build_parser

    real = [b for b in page_blocks() if b.kind == "real"]
    lines = [ln.split("#", 1)[0].strip() for b in real for ln in b.code.splitlines()]
    commands = [ln for ln in lines if ln.startswith("gymprecice ")]
    assert {shlex.split(c)[1] for c in commands} >= {"doctor", "train", "evaluate"}
    for command in commands:
        try:
            build_parser().parse_args(shlex.split(command)[1:])
        except SystemExit:
            pytest.fail(f"{PAGE.name}: `{command}` does not parse")


def test_a_changed_output_fails() -> None:
    assert shown_in("a ... c\nd", "x\na b c\nd\n") is None
    assert "'a ... c'" in shown_in("d\na ... c", "a b c\nd\n")
    assert shown_in("reward=-0.230", "reward=-0.231") is not None


def test_the_edits_apply_to_a_fresh_package(tmp_path: Path) -> None:
    """Every edit of the page applies, once, to what `gymprecice new` writes today, and
    leaves Python that compiles. Cost: about 3 s (`gymprecice new`)."""
    from gymprecice.tools.cli import main

    assert main(["new", "my-env", "--dir", str(tmp_path / "my-env")]) == 0
    edits = [b for b in page_blocks() if b.kind == "edit"]
    assert len(edits) >= 4
    for block in edits:
        apply_edit(tmp_path / "my-env", block)
    env = (tmp_path / "my-env" / DEFAULT_EDIT).read_text()
    assert "render_mode=render_mode" in env and "0.1 * effort" in env


def test_a_stale_edit_is_refused() -> None:
    with pytest.raises(ValueError, match="found 0 times"):
        apply_diff("a\nb\n", "-c\n+d")
    assert apply_diff("a\nb\nc\n", " a\n-b\n+B\n") == "a\nB\nc\n"
    source = "import os\n\n\nclass A:\n    'doc'\n\n    def f(self):\n        return 1\n"
    edited = apply_python(source, "import sys\n\n\nclass A:\n    x = 1\n\n    def f(self):\n"
                          "        return 2\n")  # fmt: skip
    assert "import sys" in edited and "    x = 1" in edited and "return 2" in edited
    assert "return 1" not in edited
    added = apply_python("import os\n\n\ndef f():\n    pass\n", "A = 1\nB = A\n")
    assert added.index("A = 1") < added.index("B = A") < added.index("def f")


# -- the whole page ----------------------------------------------------------------------------


def _user_environment(where: Path) -> dict[str, str]:
    """A virtual environment that sees ``.venv``'s packages, with ``pip``, ``gymprecice``
    and ``pytest`` on its PATH; pip installs offline, without build isolation."""
    env_dir = where / "venv"
    venv.EnvBuilder(system_site_packages=False, with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    own = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    outer = sysconfig.get_paths()["purelib"]
    (Path(own.stdout.strip()) / "_setup_venv.pth").write_text(
        f"import site; site.addsitedir({outer!r})\n"
    )
    for tool, module in (("pip", "pip"), ("gymprecice", "gymprecice"), ("pytest", "pytest")):
        script = env_dir / "bin" / tool
        script.write_text(f'#!/bin/sh\nexec "{python}" -m {module} "$@"\n')
        script.chmod(0o755)
    drop = ("PYTHONPATH", "VIRTUAL_ENV", "GYMPRECICE_DISABLE_PLUGINS", "GYMPRECICE_REQUIRE_REAL")
    env = {k: v for k, v in os.environ.items() if k not in drop and not k.startswith("PYTEST")}
    env.update(
        PATH=f"{env_dir / 'bin'}{os.pathsep}{env['PATH']}",
        PIP_NO_INDEX="1",
        PIP_NO_BUILD_ISOLATION="0",
        PIP_DISABLE_PIP_VERSION_CHECK="1",
        PIP_CONFIG_FILE=os.devnull,
        COLUMNS="80",  # a terminal as wide as the page's code
    )
    return env


def _run(argv: list[str], cwd: Path, env: dict[str, str], what: str) -> str:
    result = subprocess.run(
        argv, cwd=cwd, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
        timeout=COMMAND_TIMEOUT,
    )  # fmt: skip
    output = result.stdout + result.stderr
    if result.returncode != 0:
        pytest.fail(f"{PAGE.name}: {what} exited {result.returncode}:\n{output[-4000:]}")
    return output


def replay(where: Path, report=None) -> None:
    """Follow the page in ``where``: run, save, edit and compare as its marks say."""
    env = _user_environment(where)
    work = where / "work"
    work.mkdir()
    output = ""
    for block in page_blocks():
        what = f"the block at line {block.line}"
        if block.kind == "shell":
            output = _run(["bash", "-ec", block.code], work, env, what)
        elif block.kind == "edit":
            apply_edit(work / "my-env", block)
        elif block.kind == "script":
            (work / block.arg).write_text(block.code)
        elif block.kind == "layout":
            names = {p.name for p in (work / "my-env").rglob("*")}
            listed = {
                w.split()[0].rstrip("/").rsplit("/", 1)[-1]
                for w in block.code.splitlines()
                if w.strip()
            }
            missing = {n for n in listed if "." in n and n not in names}
            assert not missing, f"{PAGE.name}:{block.line}: not written: {sorted(missing)}"
        elif block.kind == "output":
            if report is not None:
                report(block, output)
                continue
            problem = shown_in(block.code, output)
            assert problem is None, f"{PAGE.name}:{block.line}: {problem}\nprinted:\n{output}"


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_page_runs_as_printed(tmp_path: Path) -> None:
    """The whole page on the test double: `gymprecice new`, `pip install -e`, the package's
    own tests, each edit and the script's output after it, one frame, a tiny training,
    evaluation and benchmark. Cost: about 4 min on 2 idle cores (pip 15 s, the package's
    tests 30 s, each script run 5 to 10 s, training 50 s, evaluation 30 s, the benchmark
    about 2 min; most of it processes starting)."""
    replay(tmp_path)
