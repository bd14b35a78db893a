"""The user guide speaks to users: no words of the team that wrote it.

"The main job", "the target" (of an issue), "the 15-minute target is missed" or "paper
form" mean something only to whoever set those goals; a user reads what a command does
and what it measured. Terms of the field that a newcomer may not know (test double, drag
floor, held-out start, ...) are defined on docs/glossary.md, which these pages link.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the pages checked: the ones a newcomer reads first, the results and the guides
PAGES = [
    "README.md",
    "docs/index.md",
    "docs/get-started.md",
    "docs/glossary.md",
    "docs/contributing.md",
    "docs/training.md",
    "docs/benchmark.md",
    "docs/benchmarks.md",
    "docs/results-history.md",
    "docs/gallery.md",
    "docs/cluster.md",
    "docs/validation.md",
    *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs" / "tutorials").glob("*.md")),
    *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs" / "guides").glob("*.md")),
]
TEAM_WORDS = re.compile(
    r"\bthe main job\b|\bthe target\b|\b\d+-minute target\b|\bpaper form\b|\bissue \d+\b",
    re.IGNORECASE,
)
#: each glossary entry, and the pages that must link it where they first use it
GLOSSARY_LINKS = {
    "test-double": ["docs/index.md", "docs/get-started.md", "docs/tutorials/jet-cylinder.md"],
    "drag-floor": ["docs/index.md", "docs/training.md", "docs/benchmark.md"],
    "held-out-start": ["docs/get-started.md", "docs/training.md", "docs/benchmark.md"],
    "pre-run": ["docs/tutorials/jet-cylinder.md"],
    "scripted-wake": ["docs/get-started.md"],
    "time-window": ["docs/tutorials/jet-cylinder.md"],
    "lab-card": ["docs/index.md"],
}


@pytest.mark.parametrize("page", PAGES)
def test_no_team_words(page: str) -> None:
    text = (ROOT / page).read_text()
    found = [
        f"{page}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0)!r}"
        for m in TEAM_WORDS.finditer(text)
    ]
    assert not found, "say what it is instead:\n" + "\n".join(found)


def test_team_words_are_found() -> None:
    assert TEAM_WORDS.search("as the main job does") and TEAM_WORDS.search("the 15-minute target")
    assert not TEAM_WORDS.search("the targets of the coupling")


@pytest.mark.parametrize("anchor", sorted(GLOSSARY_LINKS))
def test_glossary_terms_are_defined_and_linked(anchor: str) -> None:
    glossary = (ROOT / "docs" / "glossary.md").read_text()
    headings = {
        re.sub(r"[^\w\s-]", "", h.lower()).strip().replace(" ", "-")
        for h in re.findall(r"^#+ (.+)$", glossary, re.M)
    }
    assert anchor in headings, f"docs/glossary.md defines no {anchor!r}"
    for page in GLOSSARY_LINKS[anchor]:
        assert f"glossary.md#{anchor})" in (ROOT / page).read_text(), f"{page} links no {anchor}"
