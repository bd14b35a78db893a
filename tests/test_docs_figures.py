"""The figures the documentation quotes come from the result files, through one mechanism.

scripts/docs_macros.py reads the shipped policies' ``policy.json``, the benchmarks'
``results.json`` and the set-up's timings (docs/results/), and the pages that quote them
write ``{{ ... }}`` instead of the number. These tests check the reading, that a changed
result file changes the figure, and that no page types a figure a result file holds:
every headline figure (each benchmarked controller's score, each seed's where the file
keeps them, the times to the drag floor, the training runs' costs, the set-up's total
times) is looked for, written by hand, in every page's source and the README, and found
ones fail naming the page, the line and the macro that quotes it.
"""

from __future__ import annotations

import importlib.util
import json
import math
import re
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

#: every page whose source could type a figure: the site's pages and the README.
#: docs/changelog.md is CHANGELOG.md, the record of what each change measured then, and
#: docs/results/ holds the result files themselves
SOURCES = [
    *sorted(
        str(path.relative_to(ROOT))
        for path in (ROOT / "docs").rglob("*.md")
        if path.name != "changelog.md" and "results" not in path.relative_to(ROOT / "docs").parts
    ),
    "README.md",
]

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
    assert macros.score("jet-cylinder-fast-utd4", "SAC", results).startswith("96.8 % [")
    path = results / "benchmark-jet-cylinder-fast-utd4.json"
    data = json.loads(path.read_text())
    sac = next(c for c in data["controllers"] if c["label"] == "SAC")
    sac["metrics"]["settled_floor_fraction"]["median"] = {"value": 0.9, "low": 0.8, "high": 1.0}
    path.write_text(json.dumps(data))
    assert macros.score("jet-cylinder-fast-utd4", "SAC", results) == "90.0 % [80.0 %, 100.0 %]"
    with pytest.raises(KeyError, match="no controller 'TD3'"):
        macros.score("jet-cylinder-fast-utd4", "TD3", results)
    ttf = macros.time_to_floor("sac-overlap", 0.95, results)
    assert ttf == {
        "median": "11 min 50 s",
        "low": "9 min 57 s",
        "high": "not reached",
        "reached": "3 of 5",
        "seeds": ["9 min 57 s", "11 min 46 s", "11 min 50 s", "not reached", "not reached"],
    }


def test_a_typed_run_s_kept_model_and_its_times_are_read_from_its_results_file(
    tmp_path: Path,
) -> None:
    results = tmp_path / "results"
    shutil.copytree(macros.RESULTS, results)
    (model,) = macros.kept_models("train-sh-fresh", results)
    assert model["steps"] == "1,600" and model["saved"] == "5 min 33 s"
    assert model["settled"] == "96.9 %" and model["per_start"] == ["96.7 %", "97.0 %"]
    # the pre-run ran beside the set-up: the training started at the pre-run's end
    assert macros.typed_run("train-sh-fresh", results) == {
        "setup": "44 s",
        "prerun": "25 s",
        "before": "1 min 07 s",
        "whole": "19 min 14 s",
    }
    # the run before it, kept in history/: the set-up, then the pre-run
    earlier = macros.typed_run("history/train-sh-fresh-before-uv", results)
    assert earlier["before"] == "2 min 30 s" and earlier["setup"] == "1 min 43 s"
    path = results / "time-to-floor-jet-cylinder-fast-train-sh-fresh.json"
    data = json.loads(path.read_text())
    data["typed"]["prerun_done_seconds"] = 60
    data["runs"][0]["checkpoints"][-1]["settled_floor_fraction"] = 0.95
    path.write_text(json.dumps(data))
    assert macros.typed_run("train-sh-fresh", results)["before"] == "1 min"
    assert macros.kept_models("train-sh-fresh", results)[0]["settled"] == "95.0 %"
    del data["typed"]["prerun_done_seconds"]
    path.write_text(json.dumps(data))
    assert macros.typed_run("train-sh-fresh", results)["before"] == "1 min 09 s"


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
        macros.score("history/jet-cylinder-fast", "SAC").split(" [")[0],
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
    row = next(line for line in text.splitlines() if line.startswith("| jet cylinder"))
    tampered = text.replace(row, row.replace(" %", "0 %", 1), 1)  # one figure edited
    assert tampered != text
    assert module.with_table(tampered, macros.results_table()) == text


def test_the_results_table_follows_a_changed_result_file(tmp_path: Path) -> None:
    shutil.copytree(macros.RESULTS, tmp_path / "results")
    path = tmp_path / "results" / "benchmark-heated-plate-fast-tuned.json"
    data = json.loads(path.read_text())
    for entry in data["controllers"]:
        if entry["label"] == "SAC":
            entry["metrics"]["objective"]["mean"]["value"] = 0.123
            entry["metrics"]["objective"]["scores"][0] = [0.5, 0.5, 0.5]  # above the PID
    path.write_text(json.dumps(data))
    table = macros.results_table(tmp_path / "results")
    assert "4,000 actions 0.123 K" in table
    assert "| 4 of 5 | PID 0.298 K |" in table  # the seed above the PID is counted out
    assert "0.123 K" not in macros.results_table()


def test_the_training_table_is_written_from_each_seeds_training_record(tmp_path: Path) -> None:
    table = macros.training_table("jet-cylinder-fast-settled", "SAC", (1600, 4000))
    lines = table.splitlines()
    assert lines[0].startswith("| seed | held out | kept model: step |")
    assert "validation at 1,600 | validation at 4,000 |" in lines[0]
    assert len(lines) == 2 + 5  # a row per seed
    shutil.copytree(macros.RESULTS, tmp_path / "results")
    path = tmp_path / "results" / "benchmark-jet-cylinder-fast-settled.json"
    data = json.loads(path.read_text())
    data["training"]["SAC seed 0"]["kept"].update(timesteps=1234, training_seconds=61.0)
    path.write_text(json.dumps(data))
    row = macros.training_table("jet-cylinder-fast-settled", "SAC", (), tmp_path / "results")
    assert "| 0 | 100.8 % | 1,234 | 97.2 % | 1 min 01 s |" in row
    del data["training"]
    path.write_text(json.dumps(data))
    with pytest.raises(KeyError, match="records no training per seed"):
        macros.training_table("jet-cylinder-fast-settled", "SAC", (), tmp_path / "results")


def test_a_benchmark_key_names_its_results_file() -> None:
    """A key is a file of docs/results/; ``history/<key>``, an earlier recipe's headline
    summary in docs/results/history/. Every quoted key has its file, and a message names
    the file it read."""
    assert macros.benchmark_path("two-flaps-fast") == (
        macros.RESULTS / "benchmark-two-flaps-fast.json"
    )
    assert macros.benchmark_path("history/jet-cylinder-fast") == (
        macros.RESULTS / "history" / "benchmark-jet-cylinder-fast.json"
    )
    for key in macros.HEADLINES:
        assert macros.benchmark_path(key).is_file(), f"{key}: no results file"
    assert macros.score("history/jet-cylinder-fast", "SAC") == "88.9 % [87.2 %, 92.7 %]"
    where = re.escape("docs/results/history/benchmark-jet-cylinder-fast.json")
    with pytest.raises(KeyError, match=f"{where} has no controller 'TD3'"):
        macros.score("history/jet-cylinder-fast", "TD3")


#: the statistics each metric of a benchmark's results file gives, each with its interval
STATISTICS = ("mean", "median", "iqm")
#: the benchmarks' results files, every score per seed and start; and the headline
#: summaries of earlier recipes, which keep no score
BENCHMARKS = sorted(macros.RESULTS.glob("benchmark-*.json"))
HISTORY = sorted((macros.RESULTS / "history").glob("benchmark-*.json"))


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def schema_problems(data: dict) -> list[str]:
    """What a benchmark's results file lacks of the one schema (none when it keeps it):
    each controller has ``label``, ``kind``, ``runs`` and ``metrics``; each metric its
    ``scores``, a list per run of one score per held-out start, and its ``mean``,
    ``median`` and ``iqm``, each with ``value``, ``low`` and ``high``. Other keys
    (``restarts``, ``training``) may be there too."""
    starts = data.get("held_out_starts")
    if not isinstance(starts, list) or not starts:
        return ["no list of held_out_starts"]
    controllers = data.get("controllers")
    if not isinstance(controllers, list) or not controllers:
        return ["no list of controllers"]
    problems = []
    for entry in controllers:
        label = entry.get("label", "a controller")
        missing = [key for key in ("label", "kind", "runs", "metrics") if key not in entry]
        if missing:
            problems.append(f"{label}: no {', '.join(missing)}")
            continue
        runs = entry["runs"]
        if not isinstance(runs, int) or runs < 1 or not entry["metrics"]:
            problems.append(f"{label}: runs {runs!r}, metrics {list(entry['metrics'])}")
            continue
        for metric, stats in entry["metrics"].items():
            where = f"{label}, {metric}"
            scores = stats.get("scores")
            if not isinstance(scores, list) or len(scores) != runs:
                problems.append(f"{where}: scores is not a list of {runs} runs")
            elif not all(
                isinstance(row, list) and len(row) == len(starts) and all(map(_is_number, row))
                for row in scores
            ):
                problems.append(f"{where}: a run's scores are not one number per held-out start")
            for name in STATISTICS:
                stat = stats.get(name)
                if not isinstance(stat, dict) or not all(
                    _is_number(stat.get(key)) for key in ("value", "low", "high")
                ):
                    problems.append(f"{where}: no {name} with value, low and high")
    return problems


@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda path: path.name)
def test_every_benchmark_file_keeps_each_score_per_seed_and_start(path: Path) -> None:
    problems = schema_problems(json.loads(path.read_text()))
    assert not problems, f"{path.relative_to(ROOT)}: " + "; ".join(problems)


def test_a_headline_summary_or_a_lost_score_fails_the_schema() -> None:
    """The check can fail: on each earlier recipe's headline summary, and on a file of
    the schema that loses one start's score."""
    assert BENCHMARKS and HISTORY
    for path in HISTORY:
        problems = schema_problems(json.loads(path.read_text()))
        assert any("scores is not a list" in problem for problem in problems), path.name
    data = json.loads((macros.RESULTS / "benchmark-two-flaps-fast-residual.json").read_text())
    assert not schema_problems(data)
    metrics = data["controllers"][0]["metrics"]
    next(iter(metrics.values()))["scores"][0].pop()
    (problem,) = schema_problems(data)
    assert "not one number per held-out start" in problem


def _readme_results_table() -> tuple[str, str]:
    spec = importlib.util.spec_from_file_location(
        "readme_results", ROOT / "scripts" / "readme_results.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.START, module.END


def typed(page: str, text: str, figures: list) -> list[str]:
    """``PAGE:LINE: ...`` for each figure of ``figures`` that ``text`` types by hand. The
    README's results table is written by scripts/readme_results.py from the result
    files (and checked above), so it is left out."""
    if page == "README.md":
        start, end = _readme_results_table()
        head, rest = text.split(start, 1)
        table, tail = rest.split(end, 1)
        text = head + start + re.sub(r"[^\n]", " ", table) + end + tail
    return [
        f"{page}:{line}: {written!r} is {found[0].text} of {found[0].source}: write "
        + " or ".join(f"{{{{ {figure.macro} }}}}" for figure in found)
        + " instead"
        for line, found, written in macros.typed_figures(text, figures)
    ]


@pytest.fixture(scope="module")
def figures() -> list:
    return macros.headline_figures()


def check_page(page: str, text: str, figures: list) -> None:
    """Fail naming each line of ``page`` that types a figure of a result file."""
    found = typed(page, text, figures)
    assert not found, "a figure typed by hand, quote it (scripts/docs_macros.py):\n" + (
        "\n".join(found)
    )


@pytest.mark.parametrize("page", SOURCES)
def test_no_page_types_a_figure_that_a_result_file_holds(page: str, figures: list) -> None:
    check_page(page, (ROOT / page).read_text(), figures)


def test_every_result_file_has_its_headline_figures_looked_for(figures: list) -> None:
    sources = {figure.source for figure in figures}
    for path in sorted(macros.RESULTS.rglob("*.json")):
        name = str(path.relative_to(ROOT))
        if path.name.startswith(("benchmark-", "time-to-floor-", "setup")):
            assert name in sources, f"{name}: no headline figure is looked for"
    for path in sorted(macros.POLICIES.glob("*/policy.json")):
        assert str(path.relative_to(ROOT)) in sources, path


#: a page that types figures of the result files by hand, and quotes others
HAND_WRITTEN = """---
render_macros: true
---

SAC takes 88.9 % [87.2 %, 92.7 %] of the floor, PPO **89.7 [77.9, 95.2]**.
The flap's policy trained in 1 h 1 min; seeds 0.230, 0.230, 0.243, 0.307 and 0.252 K.
The heated plate's PID: 0.298 K. 95 % in a median of 11 min 50 s.
Quoted, not typed: {{ score("history/jet-cylinder-fast", "SAC") }}, {{ cost("two-flaps-fast") }}.
Not these figures: 83.1 % [80.6 %, 88.4 %] (another interval's bound), 0.2985,
1 h 14 min 13 s, 0.1 % and 16 s (too common to tell apart).
"""


def test_a_figure_typed_by_hand_fails_naming_the_page_and_the_line(figures: list) -> None:
    found = typed("docs/example.md", HAND_WRITTEN, figures)
    where = [line.split(": ", 1)[0] for line in found]
    assert (
        where == ["docs/example.md:5"] * 2 + ["docs/example.md:6"] * 2 + ["docs/example.md:7"] * 2
    ), found
    assert found[0] == (
        "docs/example.md:5: '88.9 % [87.2 %, 92.7 %]' is 88.9 % [87.2 %, 92.7 %] of "
        "docs/results/history/benchmark-jet-cylinder-fast.json: write "
        '{{ score("history/jet-cylinder-fast", "SAC") }} instead'
    )
    assert 'cost("perpendicular-flap-fast")' in found[2]
    assert 'seed_means("heated-plate-fast-integral", "SAC")' in found[3]
    assert 'score("history/heated-plate-fast", "best PID")' in found[4]
    assert 'time_to_floor("sac-overlap", 0.95).median' in found[5]
    # the check every page goes through fails on it, naming the page and the line
    with pytest.raises(AssertionError, match=r"docs/example\.md:5: '88\.9 %"):
        check_page("docs/example.md", HAND_WRITTEN, figures)


def test_a_hand_typed_figure_in_the_readme_is_found_outside_its_table(figures: list) -> None:
    text = (ROOT / "README.md").read_text()
    assert not typed("README.md", text, figures)
    start, _ = _readme_results_table()
    tampered = text.replace(start, "SAC takes 88.9 % of the floor.\n\n" + start, 1)
    (found,) = typed("README.md", tampered, figures)
    assert "'88.9 %'" in found and 'score("history/jet-cylinder-fast", "SAC")' in found


def test_the_figures_looked_for_follow_the_result_files(tmp_path: Path) -> None:
    shutil.copytree(macros.RESULTS, tmp_path / "results")
    path = tmp_path / "results" / "history" / "benchmark-jet-cylinder-fast.json"
    data = json.loads(path.read_text())
    sac = next(c for c in data["controllers"] if c["label"] == "SAC")
    sac["metrics"]["settled_floor_fraction"]["median"] = {"value": 0.9, "low": 0.8, "high": 1.0}
    path.write_text(json.dumps(data))
    figures = macros.headline_figures(tmp_path / "results")
    assert typed("page.md", "SAC: 90.0 % [80.0 %, 100.0 %].", figures)
    assert not typed("page.md", "SAC: 88.9 % [87.2 %, 92.7 %].", figures)


def test_a_training_cost_is_read_from_the_policy_that_recorded_it() -> None:
    policy = json.loads((macros.POLICIES / "perpendicular-flap-fast" / "policy.json").read_text())
    assert macros.cost("perpendicular-flap-fast") == macros.clock(
        policy["training"]["wall_clock_seconds"]
    )
    with pytest.raises(KeyError, match="no recorded training run 'flap'"):
        macros.cost("flap")
