"""The command reference (docs/reference/commands.md) says what the command line says.

The page is written from ``gymprecice``'s own parsers when the site is built
(scripts/docs_commands.py, called through the docs macros), so it lists every command of
:func:`gymprecice.cli.build_parser` (core's and the installed plugins'), every argument
with its default, and an example that the same parser takes.
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import sys
from html import unescape
from pathlib import Path

import pytest

from gymprecice.tools.cli import build_parser
from gymprecice.tools.distribution import core_version

ROOT = Path(__file__).resolve().parents[1]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


docs_commands = _load("docs_commands")


def _arguments(parser: argparse.ArgumentParser) -> list[str]:
    """How the page names each argument: an option's flags, a positional's metavar."""
    formatter = argparse.HelpFormatter(parser.prog)
    return [
        formatter._format_action_invocation(action)
        for action in parser._actions
        if not isinstance(action, argparse._HelpAction) and action.help != argparse.SUPPRESS
    ]


def test_every_command_and_argument_is_on_the_page() -> None:
    parser = build_parser()
    page = docs_commands.command_reference(parser)
    commands = docs_commands.commands(parser)
    assert {"plugins", "check", "doctor", "new", "train", "evaluate"} <= set(commands)
    for name, sub in commands.items():
        start = page.index(f"\n## gymprecice {name}\n")
        section = page[start : page.find("\n## ", start + 1)]
        for argument in _arguments(sub):
            for part in argument.split(", "):
                assert f"`{part}`" in section, f"gymprecice {name}: {part} is not on the page"
        example = section.split("```bash\n", 1)[1].split("\n```", 1)[0]
        assert example.startswith(f"gymprecice {name}"), example


def test_an_example_the_parser_refuses_fails_the_page(monkeypatch) -> None:
    parser = argparse.ArgumentParser(prog="gymprecice")
    sub = parser.add_subparsers()
    tool = sub.add_parser("tool", help="a tool")
    tool.add_argument("--speed", type=float, default=1.0, help="how fast, in m/s")
    monkeypatch.setitem(docs_commands.EXAMPLES, "tool", "gymprecice tool --sped 2")
    with pytest.raises(docs_commands.ExampleError, match="--sped"):
        docs_commands.command_reference(parser)
    monkeypatch.setitem(docs_commands.EXAMPLES, "tool", "gymprecice tool --speed 2")
    page = docs_commands.command_reference(parser)
    assert "| `--speed SPEED` | `1.0` | how fast, in m/s |" in page


def test_help_text_is_taken_literally() -> None:
    assert docs_commands._text("runs/<env>/out, a *glob*, [0, 1] and `a_b`") == (
        r"runs/&lt;env&gt;/out, a \*glob\*, \[0, 1\] and `a_b`"
    )
    assert str(Path.home()) not in docs_commands._text(f"under {Path.home()}/stack")


@pytest.mark.slow
def test_the_built_page_lists_every_command_and_every_page_shows_the_version(
    tmp_path,
) -> None:
    """Cost: about 6 s (one strict build of the site)."""
    build_docs = _load("build_docs")
    missing = build_docs.missing_requirements()
    if missing:
        pytest.skip(build_docs.install_advice(missing))
    result = build_docs.build(tmp_path / "site")
    assert result.ok, "\n".join(result.problems) or result.output
    page = (tmp_path / "site" / "reference" / "commands.html").read_text()
    ids = set(re.findall(r'<h2 id="([^"]+)"', page))
    for name in docs_commands.commands(build_parser()):
        assert f"gymprecice-{name}" in ids, f"gymprecice {name} is not on the built page"
    for html_page in (tmp_path / "site").rglob("*.html"):
        if html_page.name == "404.html":
            continue
        footer = re.search(
            r'class="md-copyright__highlight">(.*?)</div>', html_page.read_text(), re.S
        )
        assert footer and unescape(footer.group(1)).strip() == f"gymprecice {core_version()}", (
            html_page
        )


def test_the_changelog_and_the_citation_name_the_packages_version() -> None:
    """CHANGELOG.md has an Unreleased section and one for the version core carries, and
    CITATION.cff cites that version; the site shows the changelog."""
    pyproject = (ROOT / "packages" / "gymprecice-core" / "pyproject.toml").read_text()
    version = re.search(r'^version = "([^"]+)"', pyproject, re.M).group(1)
    changelog = (ROOT / "CHANGELOG.md").read_text()
    headings = re.findall(r"^## \[([^\]]+)\]", changelog, re.M)
    assert headings[:2] == ["Unreleased", version], headings
    citation = (ROOT / "CITATION.cff").read_text()
    assert re.search(rf"^version: {re.escape(version)}$", citation, re.M), "CITATION.cff"
    assert "doi: 10.1016/j.softx.2023.101446" in citation
    assert '--8<-- "CHANGELOG.md"' in (ROOT / "docs" / "changelog.md").read_text()
