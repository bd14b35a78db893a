"""The documentation site builds strictly (mkdocs.yml) and says where a problem is.

The build itself is scripts/build_docs.py: ``mkdocs build --strict`` into ``site/`` (ignored
by git), with every warning placed at ``docs/PAGE.md:LINE``. Where the site's dependencies
are missing the build test skips naming them, and fails under GYMPRECICE_REQUIRE_REAL=1
(CI), whose set-up installs them.
"""

from __future__ import annotations

import importlib.util
import os
import re
import sys
import time
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


@pytest.mark.timeout(120)
def test_the_site_builds_strictly_in_under_a_minute() -> None:
    missing = build_docs.missing_requirements()
    if missing:
        advice = build_docs.install_advice(missing)
        if os.environ.get("GYMPRECICE_REQUIRE_REAL", "0") not in ("", "0"):
            pytest.fail(advice)
        pytest.skip(advice)
    started = time.monotonic()
    result = build_docs.build()
    took = time.monotonic() - started
    assert result.ok, "\n".join(result.problems) or result.output
    assert took < 60, f"the site took {took:.0f} s to build"
    site = ROOT / "site"
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
