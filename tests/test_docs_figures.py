"""The figures the documentation quotes come from the result files, through one mechanism.

scripts/docs_macros.py reads the shipped policies' ``policy.json``, the benchmarks'
``results.json`` and the set-up's timings (docs/results/), and the pages that quote them
write ``{{ ... }}`` instead of the number. These tests check the reading, that a changed
result file changes the figure, and that the pages that quote a figure do not also type it.
"""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load_macros():
    spec = importlib.util.spec_from_file_location(
        "docs_macros", ROOT / "scripts" / "docs_macros.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


macros = _load_macros()

#: the pages that quote the headline figures, and so must never type them
QUOTING = [
    "docs/index.md",
    "docs/get-started.md",
    "docs/training.md",
    "docs/tutorials/jet-cylinder.md",
    "docs/tutorials/rotating-cylinder.md",
]


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(16, "16 s"), (80, "1 min 20 s"), (710, "11 min 50 s"), (4426.1, "1 h 14 min"), (3600, "1 h")],
)
def test_a_duration_is_written_as_the_pages_write_it(seconds: float, text: str) -> None:
    assert macros.clock(seconds) == text
    assert macros.clock(float("inf")) == "not reached"


def test_the_shipped_jet_policy_is_read_from_its_policy_file() -> None:
    jet = macros.shipped()["jet-cylinder-fast"]
    policy = json.loads((macros.POLICIES / "jet-cylinder-fast" / "policy.json").read_text())
    assert jet["algo"] == policy["algorithm"].upper()
    assert jet["training"] == macros.clock(policy["training"]["wall_clock_seconds"])
    assert jet["drag_drop"] == f"{-policy['evaluation']['change_percent']['mean_Cd']:.1f} %"


def test_a_rerun_changes_every_quoted_figure(tmp_path: Path) -> None:
    """Copying a new results file over the old one is all a rerun needs."""
    results = tmp_path / "results"
    shutil.copytree(macros.RESULTS, results)
    assert macros.score("jet-cylinder-fast", "SAC", results).startswith("88.9 % [")
    path = results / "benchmark-jet-cylinder-fast.json"
    data = json.loads(path.read_text())
    sac = next(c for c in data["controllers"] if c["label"] == "SAC")
    sac["metrics"]["settled_floor_fraction"]["median"] = {"value": 0.9, "low": 0.8, "high": 1.0}
    path.write_text(json.dumps(data))
    assert macros.score("jet-cylinder-fast", "SAC", results) == "90.0 % [80.0 %, 100.0 %]"
    with pytest.raises(KeyError, match="no controller 'TD3'"):
        macros.score("jet-cylinder-fast", "TD3", results)
    ttf = macros.time_to_floor("sac-overlap", 0.95, results)
    assert ttf == {
        "median": "11 min 50 s",
        "low": "9 min 57 s",
        "high": "not reached",
        "reached": "3 of 5",
    }


def test_the_set_up_table_is_written_from_its_timings() -> None:
    setup = macros.setup_figures()
    assert setup["fresh"] == "7 min 40 s" and setup["second"] == "16 s"
    assert setup["table"].startswith("| step | fresh machine | second run |\n| --- |")


@pytest.mark.parametrize("page", QUOTING)
def test_a_quoting_page_does_not_type_its_figures(page: str) -> None:
    text = (ROOT / page).read_text()
    assert text.startswith("---\nrender_macros: true\n---\n"), f"{page}: no render_macros"
    typed = [
        macros.shipped()["jet-cylinder-fast"]["training"],
        macros.time_to_floor("sac-overlap", 0.95)["median"],
        macros.setup_figures()["fresh"],
        macros.score("jet-cylinder-fast", "SAC").split(" [")[0],
    ]
    found = [figure for figure in typed if figure in text]
    assert not found, f"{page} types {found}: quote them ({{{{ ... }}}}, scripts/docs_macros.py)"


def test_the_readmes_results_table_is_the_one_the_result_files_give() -> None:
    """The README has no macros: scripts/readme_results.py writes its table from
    docs/results/, and a table edited by hand, or a result file replaced without
    rewriting it, fails here."""
    spec = importlib.util.spec_from_file_location(
        "readme_results", ROOT / "scripts" / "readme_results.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--check"]) == 0
    text = (ROOT / "README.md").read_text()
    tampered = text.replace("| SAC 88.9 %", "| SAC 98.9 %", 1)
    assert tampered != text
    assert module.with_table(tampered, macros.results_table()) == text


def test_the_results_table_follows_a_changed_result_file(tmp_path: Path) -> None:
    shutil.copytree(macros.RESULTS, tmp_path / "results")
    path = tmp_path / "results" / "benchmark-heated-plate-fast.json"
    data = json.loads(path.read_text())
    for entry in data["controllers"]:
        if entry["label"] == "SAC":
            entry["metrics"]["mean_tracking_error"]["mean"]["value"] = 0.123
    path.write_text(json.dumps(data))
    assert "SAC 0.123 K" in macros.results_table(tmp_path / "results")
    assert "SAC 0.123 K" not in macros.results_table()
