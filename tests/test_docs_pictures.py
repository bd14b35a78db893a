"""The docs' flow pictures are made by scripts/docs_pictures.py, named under each picture.

On the test double (no solvers): a snapshot is an env's ``render()`` frame, a still is a
video's last frame, and ``--stack`` puts a side-by-side frame's panels one above the other
without their colour bars. The pages and scripts/make_docs_pictures.sh must agree on which
picture each command makes.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
imageio = pytest.importorskip("imageio.v2", reason="the render extra: gymprecice-core[render]")
pytest.importorskip("matplotlib", reason="the render extra: gymprecice-core[render]")


def _load():
    spec = importlib.util.spec_from_file_location(
        "docs_pictures", ROOT / "scripts/docs_pictures.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


pictures = _load()


@pytest.fixture(scope="module")
def frame(tmp_path_factory) -> np.ndarray:
    """A jet cylinder frame on the double, as ``snapshot`` writes it."""
    png = tmp_path_factory.mktemp("snap") / "jet.png"
    pictures.snapshot("JetCylinderFast-v0", png, steps=2, double=True)
    return np.asarray(imageio.imread(png))


def test_a_snapshot_is_the_envs_frame(frame) -> None:
    height, width, channels = frame.shape
    # 640 wide, as high as the channel's aspect asks (gymprecice.rendering.frame_height)
    assert (width, channels) == (640, 3) and frame.dtype == np.uint8
    assert 0.3 * width <= height <= 1.25 * width and height % 16 == 0
    assert frame.var() > 100.0


def test_stack_puts_the_panels_one_above_the_other_without_colour_bars(frame) -> None:
    red = np.array([255, 0, 0], np.uint8)
    right = frame.copy()
    middle = frame.shape[0] // 2
    right[middle - 5 : middle + 5, 315:325] = red  # inside the plot: tells the panels apart
    stacked = pictures.stacked(np.concatenate([frame, right], axis=1), 2)
    height, width, _ = stacked.shape
    assert width < 640, "the colour bars (right of the plot) are cut"
    assert height < 2 * frame.shape[0], "the white band between title and plot is cut"
    is_red = (stacked == red).all(axis=2)
    assert not is_red[: height // 2].any() and is_red[height // 2 :].sum() == 100
    # the plot itself is kept whole: the axes' two horizontal spines in each half
    for half in (stacked[: height // 2], stacked[height // 2 :]):
        assert ((half.sum(axis=2) < 150).mean(axis=1) > 0.5).sum() >= 2


def test_stack_refuses_a_frame_without_a_plot() -> None:
    with pytest.raises(SystemExit, match="no plot frame"):
        pictures.stacked(np.full((100, 200, 3), 255, np.uint8), 2)


def test_a_still_is_the_last_frame(tmp_path: Path) -> None:
    frames = [np.full((64, 96, 3), value, np.uint8) for value in (0, 90, 250)]
    video = tmp_path / "v.gif"
    imageio.mimwrite(video, frames, duration=100, loop=0)
    png = pictures.still(video, tmp_path / "still.png")
    assert abs(int(np.asarray(imageio.imread(png))[..., :3].mean()) - 250) <= 2


def test_every_field_picture_on_a_page_is_made_by_the_script() -> None:
    script = (ROOT / "scripts/make_docs_pictures.sh").read_text()
    made = set(re.findall(r"^gymprecice/\S+ ([\w-]+) \d+$", script, re.M))
    pages = {}
    for page in sorted((ROOT / "docs/tutorials").glob("*.md")):
        for name in re.findall(r"assets/field-([\w-]+)\.png\)", page.read_text()):
            pages[name] = page
            text = page.read_text()
            assert f"docs/assets/field-{name}.png" in text, f"{page.name}: no command under it"
    assert set(pages) <= made, f"pictures no command makes: {set(pages) - made}"
    for name in made:
        assert (ROOT / f"docs/assets/field-{name}.png").is_file(), name


def test_every_case_sketch_on_a_page_is_made_by_the_script_and_named_under_it() -> None:
    """Each tutorial page shows its case's sketch with the `gymprecice sketch` command that
    makes it; scripts/make_docs_pictures.sh makes the same pictures with the same envs, the
    command parses, and each picture is small enough for a page."""
    from gymprecice.tools.cli import build_parser

    script = (ROOT / "scripts/make_docs_pictures.sh").read_text()
    made = dict((name, env) for env, name in re.findall(r"^([\w-]+) ([\w-]+)$", script, re.M))
    shown = {}
    for page in sorted((ROOT / "docs/tutorials").glob("*.md")):
        text = page.read_text()
        for name in re.findall(r"\]\(\.\./assets/sketch-([\w-]+)\.png\)", text):
            command = re.search(
                rf"```bash\n(gymprecice sketch [\w-]+ \\\n\s+--out docs/assets/sketch-{name}"
                r"\.png)\n```",
                text,
            )
            assert command, f"{page.name}: no `gymprecice sketch` command under sketch-{name}"
            argv = command.group(1).replace("\\\n", " ").split()
            args = build_parser().parse_args(argv[1:])
            assert args.command == "sketch" and made.get(name) == args.env, (page.name, name)
            shown[name] = page.name
    assert set(shown) == set(made), "a sketch the script makes but no page shows, or back"
    assert len(shown) == len(list((ROOT / "docs/tutorials").glob("*.md"))), "one per page"
    for name in made:
        picture = ROOT / f"docs/assets/sketch-{name}.png"
        assert picture.is_file() and picture.stat().st_size < 200_000, name
