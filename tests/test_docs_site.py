"""The documentation site builds strictly (mkdocs.yml) and says where a problem is.

The build itself is scripts/build_docs.py: ``mkdocs build --strict``, with every warning
placed at ``docs/PAGE.md:LINE``. The tests build into a folder of their own, then copy the
site into ``site/`` (ignored by git). Where the site's dependencies are missing the build
test skips naming them, and fails under GYMPRECICE_REQUIRE_REAL=1 (CI), whose set-up
installs them. Code blocks must fit the content column at 1280 px (``CONTENT_COLUMN``).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from html import unescape
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load_build_docs():
    spec = importlib.util.spec_from_file_location("build_docs", ROOT / "scripts" / "build_docs.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


build_docs = _load_build_docs()

#: characters of monospace that fit the content column of mkdocs-material at a 1280 px wide
#: window, with both sidebars shown: the code element is 656 px wide inside its padding and
#: a character of the theme's 13.6 px monospace is 8.2 px (measured in headless Chromium)
CONTENT_COLUMN = 80
_PRE = re.compile(r"<pre[^>]*>(.*?)</pre>", re.S)


@dataclass(frozen=True)
class Built:
    result: object
    seconds: float
    site: Path


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Built]:
    """The site, built once for the tests of this module, into a folder of their own (a
    build running beside them, into ``site/``, cannot pull pages away under them)."""
    missing = build_docs.missing_requirements()
    if missing:
        advice = build_docs.install_advice(missing)
        if os.environ.get("GYMPRECICE_REQUIRE_REAL", "0") not in ("", "0"):
            pytest.fail(advice)
        pytest.skip(advice)
    site = tmp_path_factory.mktemp("site")
    started = time.monotonic()
    result = build_docs.build(site)
    yield Built(result, time.monotonic() - started, site)
    if result.ok:  # the site the README opens: site/index.html
        shutil.copytree(site, ROOT / "site", dirs_exist_ok=True)


def _site_config(monkeypatch: pytest.MonkeyPatch, **variables: str):
    """mkdocs.yml as the build reads it, under the build's repository variables alone."""
    pytest.importorskip("mkdocs")
    from mkdocs.config import load_config

    for name in ("GYMPRECICE_REPO_URL", "GYMPRECICE_REPO_NAME", "GYMPRECICE_EDIT_URI"):
        monkeypatch.delenv(name, raising=False)
    for name, value in variables.items():
        monkeypatch.setenv(name, value)
    monkeypatch.chdir(ROOT)
    return load_config(str(ROOT / "mkdocs.yml"))


def test_with_a_repository_address_every_page_links_it_and_its_own_source(monkeypatch):
    """``--repo-url``: the header's repository link and each page's edit button, which
    opens that page's Markdown in the repository."""
    config = _site_config(
        monkeypatch, **build_docs.repository_env("https://example.org/group/gymprecice")
    )
    assert config.repo_url == "https://example.org/group/gymprecice"
    assert config.repo_name == "group/gymprecice"
    assert config.edit_uri == "edit/main/docs/"
    assert "content.action.edit" in config.theme["features"]
    config = _site_config(
        monkeypatch, **build_docs.repository_env("https://example.org/g/p", "_edit/dev/docs")
    )
    assert config.edit_uri == "_edit/dev/docs/"


def test_without_an_address_no_page_has_a_repository_or_edit_link(monkeypatch):
    config = _site_config(monkeypatch)
    assert config.repo_url is None and config.edit_uri is None
    assert build_docs.repository_env(None) == {}


def test_a_repository_address_that_is_not_a_web_address_is_refused(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        build_docs.main(["--repo-url", "gymprecice.git"])
    assert exit_.value.code == 2
    assert "--repo-url must be an http(s) address" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        build_docs.main(["--edit-uri", "edit/main/docs/"])
    assert "--edit-uri needs --repo-url" in capsys.readouterr().err


def test_the_site_serves_the_source_that_get_started_sets_up(built: Built) -> None:
    """A reader of the site alone gets the source: the archive Get started links holds the
    set-up and test commands and every distribution, as committed."""
    import tarfile

    assert built.result.ok
    page = (built.site / "get-started.html").read_text()
    assert 'href="downloads/gymprecice-source.tar.gz"' in page
    with tarfile.open(built.site / "downloads" / "gymprecice-source.tar.gz") as tar:
        names = set(tar.getnames())
    for path in ("README.md", "scripts/setup.sh", "scripts/test.sh", "pyproject.toml"):
        assert f"gymprecice/{path}" in names, path
    for package in ("core", "openfoam", "dealii", "fenics", "lab", "tutorials"):
        assert f"gymprecice/packages/gymprecice-{package}/pyproject.toml" in names, package
    assert not [n for n in names if n.startswith(("gymprecice/.venv", "gymprecice/runs/"))]


@pytest.mark.timeout(120)
def test_the_site_builds_strictly_in_under_a_minute(built: Built) -> None:
    result, took = built.result, built.seconds
    assert result.ok, "\n".join(result.problems) or result.output
    assert took < 60, f"the site took {took:.0f} s to build"
    site = built.site
    for page in ("index.html", "tutorials/jet-cylinder.html", "reference/core.html"):
        assert (site / page).is_file(), page
    # opened from the disk, every link of the navigation reaches a page, not a folder
    home = (site / "index.html").read_text()
    links = set(re.findall(r'class="md-nav__link[^"]*"[^>]*href="([^"#]+)"', home))
    links |= set(re.findall(r'href="([^"#:]+)"[^>]*class="md-nav__link', home))
    assert "get-started.html" in links, sorted(links)
    assert not [link for link in links if link.endswith("/")], sorted(links)
    hooks = (site / "reference" / "hooks.html").read_text()
    assert "gymprecice_launch_solver" in hooks and "gymprecice_reset_case" in hooks
    # the measured figures are quoted from their files (scripts/docs_macros.py), not left raw
    for page in ("index.html", "get-started.html", "training.html", "benchmark.html"):
        assert "{{" not in (site / page).read_text(), f"{page}: a figure left unrendered"


def test_a_broken_link_is_named_by_page_and_line(tmp_path: Path) -> None:
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "guide.md").write_text("# Guide\n\nfine text\n\nsee [the rest](nowhere.md)\n")
    warning = (
        "Doc file 'guide.md' contains a link 'nowhere.md', but the target is not found "
        "among documentation files."
    )
    assert build_docs.locate(warning, docs) == [f"docs/guide.md:5: {warning}"]
    autoref = "mkdocs_autorefs: guide.md: Could not find cross-reference target 'gymprecice.Nope'"
    (docs / "guide.md").write_text("# Guide\n\n[gymprecice.Nope][]\n")
    assert build_docs.locate(autoref, docs) == [f"docs/guide.md:3: {autoref}"]
    # a broken reference in a docstring: placed at the source line that writes it
    source = tmp_path / "mod.py"
    source.write_text('"""A module.\n\nSee [the nothing][pkg.mod.Nothing].\n"""\n')
    in_docstring = (
        f"mkdocs_autorefs: reference/core.md: from {source}:1: (pkg.mod) "
        "Could not find cross-reference target 'pkg.mod.Nothing'"
    )
    assert build_docs.locate(in_docstring, docs) == [f"{source}:3: {in_docstring}"]
    # a docstring's warning (griffe places it) comes back as it is
    griffe = "griffe: src/pkg/mod.py:12: Parameter 'x' does not appear in the function signature"
    assert build_docs.locate(griffe, docs) == [griffe]


def test_missing_dependencies_are_named_with_the_command(tmp_path: Path) -> None:
    reqs = tmp_path / "requirements.txt"
    reqs.write_text("# comment\nmkdocs-no-such-theme==1.0\npytest==0.0.1\n")
    missing = build_docs.missing_requirements(reqs)
    assert missing[0] == "mkdocs-no-such-theme==1.0 (not installed)"
    assert missing[1].startswith("pytest==0.0.1 (found ")
    advice = build_docs.install_advice(missing)
    assert (
        "mkdocs-no-such-theme==1.0" in advice and "pip install -r docs/requirements.txt" in advice
    )


def wide_code_lines(html: str, width: int = CONTENT_COLUMN) -> list[str]:
    """Each line of a rendered code block (``<pre>``) wider than ``width`` characters."""
    wide = []
    for block in _PRE.finditer(html):
        text = unescape(re.sub(r"<[^>]+>", "", block.group(1)))
        wide += [line for line in text.splitlines() if len(line.rstrip()) > width]
    return wide


def test_a_wide_code_line_is_found() -> None:
    html = (
        '<p>x</p><pre><code><span class="n">short</span>\n'
        + "y" * (CONTENT_COLUMN + 1)
        + "\n&lt;"
        + "z" * (CONTENT_COLUMN - 1)
        + "</code></pre>"
    )
    assert wide_code_lines(html) == ["y" * (CONTENT_COLUMN + 1)]


def test_no_code_line_scrolls_sideways_at_1280_px(built: Built) -> None:
    """Code blocks and signatures fit the content column: wrap commands, comments above."""
    assert built.result.ok
    site = built.site
    wide = []
    for page in sorted(site.rglob("*.html")):
        if "assets" in page.relative_to(site).parts:
            continue
        for line in wide_code_lines(page.read_text()):
            wide.append(f"{page.relative_to(site)}: {len(line.rstrip())}: {line.strip()[:60]}")
    assert not wide, f"{len(wide)} code lines wider than {CONTENT_COLUMN} characters:\n" + (
        "\n".join(wide)
    )


def test_the_hook_reference_documents_each_object_once(built: Built) -> None:
    assert built.result.ok
    hooks = (built.site / "reference" / "hooks.html").read_text()
    headings = re.findall(r'<h\d id="(gymprecice\.[\w.]+)" class="doc doc-heading"', hooks)
    names = [h.rsplit(".", 1)[1] for h in headings]
    assert "LaunchSpec" in names and "gymprecice_launch_solver" in names, names
    twice = sorted({n for n in names if names.count(n) > 1})
    assert not twice, f"documented twice on the hook reference: {twice}"


def test_api_signatures_are_formatted(built: Built) -> None:
    """A long signature is laid out one parameter a line (mkdocstrings formats it with ruff)."""
    assert built.result.ok
    core = unescape(re.sub(r"<[^>]+>", "", (built.site / "reference" / "core.html").read_text()))
    assert "Adapter(\n    options: " in core, "the Adapter's signature is not formatted"
