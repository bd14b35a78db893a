"""The environment gallery (docs/gallery.md) shows every registered environment.

Each tutorial environment the tutorials' plugin registers appears in exactly one of the
page's ``env_table(...)`` calls, which write its facts from its registration when the site
is built (scripts/docs_macros.py); each task has an inline animation and a still that
scripts/make_docs_pictures.sh makes (a task of :data:`NOT_ANIMATED_YET`, its case's
sketch instead), and a link to its tutorial page; the page is in the site's navigation. The facts a table shows are those of the registered env: its lab card
and the spaces of an env made without starting a solver.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ROOT / "docs" / "gallery.md"


def _load_macros():
    spec = importlib.util.spec_from_file_location(
        "docs_macros", ROOT / "scripts" / "docs_macros.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


macros = _load_macros()


#: tasks whose animation cannot be made yet, and why: their section shows the case's
#: sketch, which scripts/make_docs_pictures.sh makes, until the script's animation line
#: for them has run (then drop the task from here)
NOT_ANIMATED_YET: dict[str, str] = {}


def _sections() -> dict[str, str]:
    """Each ``## `` section of the gallery by its heading."""
    parts = re.split(r"^## (.+)$", GALLERY.read_text(), flags=re.M)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def _tutorial_ids() -> list[str]:
    from gymprecice.plugin.card import card_package, registered_ids

    return [env_id for env_id in registered_ids() if card_package(env_id) == "tutorials"]


def test_every_registered_environment_is_in_one_table() -> None:
    text = GALLERY.read_text()
    assert text.startswith("---\nrender_macros: true\n---\n")
    shown = [
        env_id
        for call in re.findall(r"\{\{ env_table\(([^)]*)\) \}\}", text)
        for env_id in re.findall(r'"([^"]+)"', call)
    ]
    ids = _tutorial_ids()
    assert len(ids) >= 10
    assert sorted(shown) == sorted(ids), "each registered env in exactly one env_table(...)"


@pytest.mark.parametrize("heading", sorted(_sections()))
def test_each_task_has_its_picture_its_tutorial_and_its_cost(heading: str) -> None:
    section = _sections()[heading]
    script = (ROOT / "scripts" / "make_docs_pictures.sh").read_text()
    # an animation inline, a frame per action, that the script's table makes
    videos = re.findall(
        r'<video src="assets/anim-([\w-]+)\.mp4" poster="(assets/[\w.-]+\.png)"', section
    )
    if heading in NOT_ANIMATED_YET:
        assert not videos, f"{heading}: animated now: drop it from NOT_ANIMATED_YET"
        (name,) = re.findall(r"\]\(assets/sketch-([\w-]+)\.png\)", section)
        assert (ROOT / "docs" / "assets" / f"sketch-{name}.png").is_file(), name
        assert re.search(rf"^[\w-]+ {name}$", script, re.M), f"sketch-{name}.png: not made"
        assert re.search(rf"^\S+ {name} \S+ (evaluate|baseline)$", script, re.M), (
            f"anim-{name}.mp4: scripts/make_docs_pictures.sh does not make it"
        )
        pictures = []
    else:
        assert len(videos) == 1, f"{heading}: no animation (or more than one)"
        ((name, poster),) = videos
        assert (ROOT / "docs" / "assets" / f"anim-{name}.mp4").is_file(), name
        assert re.search(rf"^\S+ {name} \S+ (evaluate|baseline)$", script, re.M), (
            f"anim-{name}.mp4: scripts/make_docs_pictures.sh does not make it"
        )
        pictures = [*re.findall(r"\]\((assets/[\w.-]+\.png)\)", section), poster]
    for picture in pictures:
        assert (ROOT / "docs" / picture).is_file(), picture
        assert f"docs/{picture}" in script or re.search(
            rf"^gymprecice/\S+ {Path(picture).stem.removeprefix('field-')} \d+$", script, re.M
        ), f"{picture}: scripts/make_docs_pictures.sh does not make it"
    tutorials = re.findall(r"\]\((tutorials/[\w-]+\.md)\)", section)
    assert tutorials and all((ROOT / "docs" / t).is_file() for t in tutorials), heading
    assert "**Cost.**" in section and "**Objective.**" in section, heading


def test_the_gallery_is_in_the_navigation() -> None:
    assert "Gallery: gallery.md" in (ROOT / "mkdocs.yml").read_text()


def test_a_table_says_what_the_registered_env_is(tmp_path: Path) -> None:
    import gymnasium

    from gymprecice.plugin.card import card_for

    env_id = "gymprecice/TwoFlapsFast-v0"
    facts = macros.env_facts(env_id)
    card = card_for(env_id)
    env = gymnasium.make(env_id, double=True, run_root=tmp_path, disable_env_checker=True)
    try:
        assert facts["observation"] == f"`{env.observation_space.shape}` float32, unbounded"
        low, high = env.action_space.low.min(), env.action_space.high.max()
        assert facts["action"] == (
            f"`{env.action_space.shape}` float32 in [{low:g}, {high:g}] {card.action_unit}"
        )
    finally:
        env.close()
    assert facts["name"] == f"`{card.name}`" and facts["description"] == card.description
    table = macros.env_table(env_id, "gymprecice/JetCylinderFast-v0")
    header, rule, *rows = table.splitlines()
    assert header == "| | `TwoFlapsFast-v0` | `JetCylinderFast-v0` |" and rule.count("---") == 3
    assert len(rows) == len(macros._FACT_ROWS)
    assert "| action | `(2, 1)` float32 in [-1, 1] x 10 m/s | `(1,)` float32 in" in table
    assert "also the share of the drag floor it takes" in table
