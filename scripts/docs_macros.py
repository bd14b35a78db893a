"""The measured figures the documentation quotes, read from the result files that hold them.

mkdocs-macros (``plugins: macros`` in mkdocs.yml) calls :func:`define_env` once per build.
A page that sets ``render_macros: true`` in its front matter can then write, instead of a
number typed by hand::

    {{ cost("perpendicular-flap-fast") }}            1 h 1 min
    {{ shipped["perpendicular-flap-fast"].means.mean_mean_tip_displacement | round(4) }}
    {{ score("history/jet-cylinder-fast", "SAC") }}  88.9 % [87.2 %, 92.7 %]
    {{ seed_means("two-flaps-fast", "SAC, shared policy") }}
    {{ time_to_floor("sac-overlap", 0.95).median }}  11 min 50 s
    {{ setup.fresh }}                                7 min 40 s

The figures come from:

* ``packages/gymprecice-tutorials/src/gymprecice_tutorials/policies/*/policy.json``: each
  shipped policy's training run and evaluation, written by ``gymprecice ship-policy``;
* ``docs/results/benchmark-<key>.json``: ``gymprecice benchmark``'s ``results.json``
  (the headline controllers of each environment's benchmark), every score per seed and
  start; ``docs/results/history/benchmark-<key>.json``, the key ``history/<key>``: the
  headline summaries of earlier recipes' benchmarks, written before a results file kept
  every score (:func:`benchmark_path`);
* ``docs/results/time-to-floor-jet-cylinder-fast-<recipe>.json``: the ``summary`` of
  ``gymprecice time-to-floor``'s ``time_to_floor.json``;
* ``docs/results/setup.json``: the set-up's steps timed on a fresh machine.

Rerunning one of those commands and copying its file over the old one updates every page
that quotes it; no page holds the number itself. A name that is not there fails the
build (``on_undefined: strict``), naming the page. :func:`headline_figures` lists the
figures a page must quote, never type, and :func:`typed_figures` finds them typed by hand
in a page's source (tests/test_docs_figures.py runs it on every page and the README).

Three more things are read, not written: the version every page shows in its footer
(``{{ version }}``: gymprecice-core's, from its installed metadata, else its
pyproject.toml), the command reference (``{{ command_reference() }}``), written from
the ``gymprecice`` command line's own parsers by scripts/docs_commands.py, and the
registered environments' facts (``{{ env_table("gymprecice/Quickstart-v0") }}``: each
one's lab card and spaces, for the gallery).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import math
import re
import statistics
from pathlib import Path
from typing import Any, NamedTuple

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
POLICIES = ROOT / "packages" / "gymprecice-tutorials" / "src" / "gymprecice_tutorials" / "policies"

#: each benchmark's headline metric, the statistic quoted and how a value is written, by
#: its key (:func:`benchmark_path`): "history/..." are earlier recipes' headline summaries
HEADLINES: dict[str, tuple[str, str, str]] = {
    "history/jet-cylinder-fast": ("settled_floor_fraction", "median", "percent"),
    # the kept models chosen on the settled drag: results.json as the benchmark wrote it
    "jet-cylinder-fast-settled": ("settled_floor_fraction", "median", "percent"),
    # the same with 8 gradient steps per batch (update-to-data ratio 4)
    "jet-cylinder-fast-utd4": ("settled_floor_fraction", "median", "percent"),
    # utd4 on the feedback law (base_feedback), stopped at 95 % of the floor on validation
    "jet-cylinder-fast-residual": ("settled_floor_fraction", "median", "percent"),
    # the same, stopped at 97 %, up to 6,000 actions
    "jet-cylinder-fast-residual-97": ("settled_floor_fraction", "median", "percent"),
    # the same validated over 10 s every 1,600 actions: the recipe of scripts/train.sh
    "jet-cylinder-fast-residual-10s": ("settled_floor_fraction", "median", "percent"),
    # 16,000 actions, the kept models: results.json as the benchmark wrote it
    "rotating-cylinder-fast": ("settled_floor_fraction", "median", "percent"),
    # SAC with 8 gradient steps a batch, stopped at 90 %: runs/rotating-cylinder-fast/benchmark-utd4
    "rotating-cylinder-fast-utd4": ("settled_floor_fraction", "median", "percent"),
    # the first five seeds, 4,000 actions, final models: the headline figures only
    "history/rotating-cylinder-fast-4k": ("settled_floor_fraction", "median", "percent"),
    "history/perpendicular-flap-fast": ("mean_tip_displacement", "mean", "{:.4f} m"),
    # SAC with scripts/flap-sac.yml: results.json as the benchmark wrote it
    "perpendicular-flap-fast-sac": ("objective", "mean", "{:.4f} m"),
    "history/heated-plate-fast": ("mean_tracking_error", "mean", "{:.3f} K"),
    # observation="integral": results.json as the benchmark wrote it
    "heated-plate-fast-integral": ("objective", "mean", "{:.3f} K"),
    # the integral, and the recipe `gymprecice tune` found (scripts/plate-sac-tuned.yml)
    "heated-plate-fast-tuned": ("objective", "mean", "{:.3f} K"),
    # the classical baselines alone on the same starts (`benchmark --seeds 0`)
    "heated-plate-fast-baselines": ("objective", "mean", "{:.3f} K"),
    # results.json as the benchmark wrote it: the env's objective under "objective"
    "two-flaps-fast": ("objective", "mean", "{:.5f} m"),
    "two-flaps-fast-one-controller": ("objective", "mean", "{:.5f} m"),
    # the classical baselines alone, with the flaps' feedback law (`benchmark --seeds 0`)
    "two-flaps-fast-baselines": ("objective", "mean", "{:.5f} m"),
    # the shared policy on top of the damping law (base_damping=20), its kept models
    "two-flaps-fast-residual": ("objective", "mean", "{:.5f} m"),
}


def benchmark_path(key: str, results: Path = RESULTS) -> Path:
    """The results file of the benchmark ``key``: ``results/benchmark-{key}.json``; a key
    ``folder/name`` is ``results/folder/benchmark-{name}.json``, so that
    ``history/jet-cylinder-fast`` is ``docs/results/history/benchmark-jet-cylinder-fast.json``
    (an earlier recipe's headline summary)."""
    folder, _, name = key.rpartition("/")
    return results / folder / f"benchmark-{name}.json"


def _source(path: Path) -> str:
    """``path`` as messages and figures name it: from the repository's root where it lies
    in the repository (``docs/results/benchmark-two-flaps-fast.json``)."""
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def clock(seconds: float) -> str:
    """``11 min 50 s``, ``1 h 14 min`` (an hour or more is given to the minute)."""
    if not math.isfinite(seconds):
        return "not reached"
    seconds = round(seconds)
    if seconds >= 3600:
        hours, minutes = divmod(round(seconds / 60), 60)
        return f"{hours} h {minutes} min" if minutes else f"{hours} h"
    minutes, rest = divmod(seconds, 60)
    if not minutes:
        return f"{rest} s"
    return f"{minutes} min {rest:02d} s" if rest else f"{minutes} min"


def thousands(n: float) -> str:
    """``48,000``."""
    return f"{round(n):,}"


def _write(value: float, how: str, units: bool = True) -> str:
    if how == "percent":
        return f"{100 * value:.1f} %"
    return how.format(value) if units else how.split(" ", 1)[0].format(value)


def _load(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise RuntimeError(f"{path.relative_to(ROOT)}: cannot read the figures: {exc}") from exc


def shipped_figures(policy: dict[str, Any]) -> dict[str, Any]:
    """What a page says about one shipped policy, from its ``policy.json``."""
    training = policy["training"]
    evaluation = policy["evaluation"]
    figures = {
        "algo": policy["algorithm"].upper(),
        "actions": thousands(training["timesteps"]),
        "run_actions": thousands(max(training["timesteps_requested"] or 0, training["timesteps"])),
        "training": clock(training["wall_clock_seconds"]),
        "n_envs": training["n_envs"],
        "command": training["command"],
        "evaluation_seconds": evaluation["episode_time"],
    }
    # each evaluated metric's mean over the evaluation's episodes (its first start on)
    figures["means"] = {name: stats["mean"] for name, stats in evaluation["over_episodes"].items()}
    change = evaluation.get("change_percent") or {}
    if "mean_Cd" in change:
        figures["drag_drop"] = f"{-change['mean_Cd']:.1f} %"
    return figures


def shipped(policies: Path = POLICIES) -> dict[str, dict[str, Any]]:
    """Each shipped policy's figures, by name (``jet-cylinder-fast``)."""
    return {
        path.parent.name: shipped_figures(_load(path))
        for path in sorted(policies.glob("*/policy.json"))
    }


def score(
    env: str,
    controller: str,
    results: Path = RESULTS,
    units: bool = True,
    interval: bool = True,
) -> str:
    """A benchmarked controller's headline figure with its interval: ``88.9 % [87.2 %, 92.7 %]``.

    ``units=False`` leaves the unit out (a table whose header names it):
    ``0.0350 [0.0306, 0.0397]``; a percentage keeps its ``%``. ``interval=False`` gives
    the figure alone: ``88.9 %``."""
    metric, statistic, how = HEADLINES[env]
    entry = _controller(env, controller, results)
    stat = entry["metrics"][metric][statistic]
    text = _write(stat["value"], how, units)
    if entry["runs"] > 1 and interval:
        low, high = _write(stat["low"], how, units), _write(stat["high"], how, units)
        text += f" [{low}, {high}]"
    return text


def _controller(env: str, controller: str, results: Path) -> dict[str, Any]:
    """A controller's entry in the benchmark ``env``'s results file: a baseline by its kind
    ("best sinusoid") or its whole label ("best sinusoid: sine-...")."""
    path = benchmark_path(env, results)
    data = _load(path)
    for entry in data["controllers"]:
        if entry["label"] == controller or entry["label"].startswith(f"{controller}: "):
            return entry
    labels = [entry["label"] for entry in data["controllers"]]
    raise KeyError(f"{_source(path)} has no controller {controller!r}: {labels}")


def below(
    env: str, controller: str, other: str, other_env: str | None = None, results: Path = RESULTS
) -> str:
    """How far one benchmarked controller's headline value lies below another's, in per
    cent of the other's, from the same results file or ``other_env``'s (a benchmark of the
    same env run without baselines against its baselines' file):
    ``below("history/perpendicular-flap-fast", "PPO", "best sinusoid")`` is ``18 %``. A figure a
    page would otherwise compute and type by hand."""
    ratio = _headline_value(env, controller, results) / _headline_value(
        other_env or env, other, results
    )
    return f"{100.0 * (1.0 - ratio):.0f} %"


def seed_means(env: str, controller: str, results: Path = RESULTS) -> str:
    """A benchmarked controller's score per seed (its mean over the starts), in seed
    order: ``0.230, 0.230, 0.243, 0.307 and 0.252 K``; from a results file that keeps
    every score (the newer form)."""
    metric, _, how = HEADLINES[env]
    path = benchmark_path(env, results)
    data = _load(path)
    for entry in data["controllers"]:
        if entry["label"] == controller:
            means = [sum(row) / len(row) for row in entry["metrics"][metric]["scores"]]
            texts = [_write(m, how) for m in means]
            unit = texts[-1].split(" ", 1)[1] if " " in texts[-1] else ""
            numbers = [t.split(" ", 1)[0] for t in texts]
            return f"{', '.join(numbers[:-1])} and {numbers[-1]}" + (f" {unit}" if unit else "")
    raise KeyError(f"{_source(path)} has no controller {controller!r}")


def kept_after(env: str, controller: str = "SAC", results: Path = RESULTS) -> dict[str, Any]:
    """When each seed's kept model was saved, in training time (summed over a resumed
    run's segments), from a results file that records the training: ``median``, ``low``
    and ``high`` over the seeds, and ``seeds`` in seed order."""
    path = benchmark_path(env, results)
    records = _load(path).get("training")
    if not records:
        raise KeyError(f"{_source(path)} records no training per seed")
    algo = controller.split(",", 1)[0]
    seconds = [
        float((record.get("kept") or {})["training_seconds"])
        for label, record in sorted(records.items())
        if label.startswith(f"{algo} seed ")
    ]
    return {
        "median": clock(statistics.median(seconds)),
        "low": clock(min(seconds)),
        "high": clock(max(seconds)),
        "seeds": [clock(s) for s in seconds],
    }


def _validation_at(curve: list[list[float]], steps: int) -> float | None:
    """The validation score at ``steps`` actions (the last validation at or before it)."""
    before = [score for step, score in curve if step <= steps]
    return before[-1] if before else None


def training_table(
    env: str,
    controller: str,
    at: tuple[int, ...] = (),
    results: Path = RESULTS,
) -> str:
    """Each seed's training, from a results file that records it (``training``, written
    by ``gymprecice benchmark``): its held-out score (the kept model's, mean over the
    starts), the step the kept model comes from and its validation score, its time into
    training and the whole training's; with ``at``, the validation score at those steps
    (was the budget enough?)."""
    metric, _, how = HEADLINES[env]
    path = benchmark_path(env, results)
    data = _load(path)
    records = data.get("training")
    if not records:
        raise KeyError(f"{_source(path)} records no training per seed")
    scores = _controller(env, controller, results)["metrics"][metric]["scores"]
    algo = controller.split(",", 1)[0]
    head = [
        "seed",
        "held out",
        "kept model: step",
        "its validation",
        "trained until it",
        "whole training",
    ]
    head += [f"validation at {thousands(n)}" for n in at]
    rows = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for seed, row in enumerate(scores):
        record = records[f"{algo} seed {seed}"]
        kept = record.get("kept") or {}
        curve = record.get("validations") or []

        def written(value: float | None) -> str:
            return "" if value is None else _write(value, how)

        def seconds(value: float | None) -> str:
            return "" if value is None else clock(value)

        cells = [
            str(seed),
            _write(sum(row) / len(row), how),
            thousands(kept["timesteps"]) if kept else "",
            written(kept.get("value")),
            seconds(kept.get("training_seconds")),
            seconds(record.get("training_seconds")),
        ]
        trained_to = int(record.get("timesteps") or 0)
        # a run stopped before a step (--stop-at) has no validation there
        cells += [
            written(_validation_at(curve, n)) if not trained_to or n <= trained_to else ""
            for n in at
        ]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)


def _time_to_floor_file(recipe: str, results: Path) -> Path:
    """``time-to-floor-jet-cylinder-fast-<recipe>.json``; ``history/<recipe>`` is an earlier
    one's, kept in ``history/``."""
    folder, _, name = recipe.rpartition("/")
    return results / folder / f"time-to-floor-jet-cylinder-fast-{name}.json"


def time_to_floor(recipe: str, fraction: float, results: Path = RESULTS) -> dict[str, Any]:
    """The median time to a fraction of the drag floor: ``median``, ``low``, ``high``,
    ``reached``, and ``seeds``, each seed's time in seed order (``not reached``)."""
    data = _load(_time_to_floor_file(recipe, results))
    entry = data["summary"][f"{fraction:g}"]
    reached = entry["runs"] - entry.get("not_reached", 0)
    return {
        "median": clock(entry["median"]),
        "low": clock(entry["low"]),
        "high": clock(entry["high"]),
        "reached": f"{reached} of {entry['runs']}",
        "seeds": [clock(seconds) for seconds in entry["seconds"]],
    }


def kept_models(recipe: str, results: Path = RESULTS) -> list[dict[str, Any]]:
    """Each run's model that ``gymprecice time-to-floor`` evaluated last (the kept one),
    in run order: its ``steps``, when it was saved (``saved``, from the typed command),
    the fraction of the floor it takes once settled (``settled``, over the held-out
    starts) and from each start (``per_start``)."""
    data = _load(_time_to_floor_file(recipe, results))
    models = []
    for run in data["runs"]:
        last = run["checkpoints"][-1]
        models.append(
            {
                "steps": thousands(last["steps"]),
                "saved": clock(last["seconds"]),
                "settled": _write(last["settled_floor_fraction"], "percent"),
                "per_start": [_write(f, "percent") for f in last["per_start"]],
            }
        )
    return models


def typed_run(recipe: str, results: Path = RESULTS) -> dict[str, str]:
    """A command typed on a fresh machine whose kept model ``time-to-floor`` evaluated:
    its set-up's time (``setup``), its case's pre-run's (``prerun``), how long after the
    command its training could start (``before``: the pre-run's end where the record has
    it, ``prerun_done_seconds``, the pre-run having run beside the set-up; else the set-up
    and the pre-run one after the other) and the whole command's (``whole``, the
    evaluation included), from the ``typed`` record of its results file."""
    typed = _load(_time_to_floor_file(recipe, results))["typed"]
    setup, prerun = typed["setup_seconds"], typed["prerun_seconds"]
    before = typed.get("prerun_done_seconds", setup + prerun)
    return {
        "setup": clock(setup),
        "prerun": clock(prerun),
        "before": clock(before),
        "whole": clock(typed["whole_command_seconds"]),
    }


def cost(name: str, policies: Path = POLICIES) -> str:
    """What a recorded training run took on the wall-clock: the run of the shipped policy
    ``name`` (its ``policy.json``): ``cost("perpendicular-flap-fast")`` is ``1 h 1 min``,
    PPO for 20,000 actions on two environments, the command of
    ``bash scripts/train.sh --flap``."""
    path = policies / name / "policy.json"
    if not path.is_file():
        names = sorted(p.parent.name for p in policies.glob("*/policy.json"))
        raise KeyError(f"no recorded training run {name!r}: the shipped policies are {names}")
    return clock(_load(path)["training"]["wall_clock_seconds"])


# -- the figures a page must quote, never type -------------------------------------------


class Figure(NamedTuple):
    """A headline figure of a result file, as pages show it, and how to quote it (a named
    tuple: mkdocs-macros loads this module without a name in ``sys.modules``, which a
    dataclass needs)."""

    #: the figure as the macro writes it: ``88.9 % [87.2 %, 92.7 %]``
    text: str
    #: the file that holds it, from the repository's root
    source: str
    #: the macro that writes it: ``score("history/jet-cylinder-fast", "SAC")``
    macro: str
    #: the ways a page could type it by hand
    pattern: re.Pattern[str]


_UNITS = {"%": r"\s?%", "m": r"\s?m(?![\w²³/])", "K": r"\s?K(?!\w)"}
#: the spans a page quotes through: ``{{ ... }}`` and ``{% ... %}``
_MACRO = re.compile(r"\{\{.*?\}\}|\{%.*?%\}", re.S)
#: an interval as pages write one: ``[0.281, 0.329]``, ``[87.2 %, 92.7 %]``
_INTERVAL = re.compile(r"\[\s*[-\u2212]?\d[^\[\]\n]*?,[^\[\]\n]*\]")


def _number(text: str) -> str:
    """``text`` (a number) as a pattern that finds it alone, not as a part of a longer
    number: 0.306 is not found in 0.3061 or 10.306."""
    return rf"(?<![\d.]){re.escape(text)}(?!\d|\.\d)"


def _significant(number: str) -> int:
    """The significant digits of a written number: 3 for ``0.0350``, 1 for ``0.1``."""
    return len(re.sub(r"\D", "", number).lstrip("0"))


def _clock_pattern(text: str) -> re.Pattern[str]:
    """A duration as typed, not as part of a longer one (``1 h 14 min`` is not in
    ``1 h 14 min 13 s``, ``14 min 05 s`` not in ``1 h 14 min 05 s``)."""
    return re.compile(rf"(?<![\d.,])(?<!h )(?<!min ){re.escape(text)}(?!\s?\d)")


def _score_figures(env: str, entry: dict[str, Any], results: Path, source: str) -> list[Figure]:
    """A controller's headline: its value and interval, with or without units, and its
    value with its unit where it has three significant digits or more (fewer, as
    ``0.1 %``, is too common a number to tell apart)."""
    metric, statistic, how = HEADLINES[env]
    stat = entry["metrics"][metric][statistic]
    unit = "%" if how == "percent" else how.rsplit(" ", 1)[1]
    number = [
        _write(stat[k], how, units=False).removesuffix(" %") for k in ("value", "low", "high")
    ]
    with_unit = rf"(?:{_UNITS[unit]})?"
    # a baseline by its kind: "best sinusoid", not "best sinusoid: sine-c0.5-a1-f1.2"
    label = entry["label"].split(": ", 1)[0]
    macro = f'score("{env}", "{label}")'
    text = score(env, entry["label"], results)
    patterns = []
    if entry["runs"] > 1:
        value, low, high = (_number(n) for n in number)
        patterns.append(rf"{value}{with_unit}\**\s*\[\s*{low}{with_unit},\s*{high}{with_unit}\s*\]")
    if _significant(number[0]) >= 3:
        # the value alone; typed_figures skips it inside another figure's interval
        patterns.append(rf"(?P<lone>{_number(number[0])}{_UNITS[unit]})")
    return [Figure(text, source, macro, re.compile("|".join(patterns)))] if patterns else []


def headline_figures(results: Path = RESULTS, policies: Path = POLICIES) -> list[Figure]:
    """Every headline figure of the result files: each benchmarked controller's score (and
    each seed's, where the file keeps them), the times to the drag floor, the shipped
    policies' training times and the set-up's total times. A duration is one only when it
    has two parts (``11 min 50 s``): ``16 s`` alone is too common to tell apart."""
    figures: list[Figure] = []
    for env in HEADLINES:
        path = benchmark_path(env, results)
        metric, _, how = HEADLINES[env]
        for entry in _load(path)["controllers"]:
            figures += _score_figures(env, entry, results, _source(path))
            if entry["runs"] > 1 and "scores" in entry["metrics"][metric]:
                # each seed's mean, in seed order: "0.230, 0.230, 0.243, 0.307 and 0.252 K"
                text = seed_means(env, entry["label"], results)
                unit = "%" if how == "percent" else how.rsplit(" ", 1)[1]
                first, rest = text.removesuffix(f" {unit}").split(", ", 1)
                pattern = re.compile(f"{_number(first)}, {re.escape(rest)}(?:{_UNITS[unit]})?")
                macro = f'seed_means("{env}", "{entry["label"]}")'
                figures.append(Figure(text, _source(path), macro, pattern))

    def durations(source: Path, quoted: dict[str, str]) -> None:
        """The durations of ``source``, by the macro that writes each."""
        for macro, text in quoted.items():
            if text.count(" ") >= 3:  # two parts: "9 min 57 s", "1 h 1 min"
                figures.append(Figure(text, _source(source), macro, _clock_pattern(text)))

    earlier = results.glob("history/time-to-floor-jet-cylinder-fast-*.json")
    for path in sorted([*results.glob("time-to-floor-jet-cylinder-fast-*.json"), *earlier]):
        recipe = path.stem.removeprefix("time-to-floor-jet-cylinder-fast-")
        if path.parent.name == "history":
            recipe = f"history/{recipe}"
        for fraction in _load(path)["summary"]:
            summary = time_to_floor(recipe, float(fraction), results)
            macro = f'time_to_floor("{recipe}", {fraction})'
            durations(path, {f"{macro}.{key}": summary[key] for key in ("median", "low", "high")})
    for path in sorted(policies.glob("*/policy.json")):
        durations(path, {f'cost("{path.parent.name}")': cost(path.parent.name, policies)})
    setup = setup_figures(results)
    # the totals; a step's time alone ("1 min 20 s") is as common as a number gets
    keys = ("fresh", "without_debian", "ci", "ci_second")
    durations(results / "setup.json", {f"setup.{key}": setup[key] for key in keys})
    return figures


def typed_figures(text: str, figures: list[Figure]) -> list[tuple[int, list[Figure], str]]:
    """``(line, figures, what is written)`` for each figure that ``text`` (a page's
    Markdown) types by hand, outside ``{{ ... }}`` and ``{% ... %}``: ``figures`` are the
    ones it could be (``11 min 50 s`` is two of the files' figures)."""
    masked = _MACRO.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
    # the bounds of intervals: a value alone inside one is another figure's bound
    bounds = [m.span() for m in _INTERVAL.finditer(masked)]
    found: dict[tuple[int, int], list[Figure]] = {}
    for figure in figures:
        for match in figure.pattern.finditer(masked):
            start = match.start()
            if match.groupdict().get("lone") and any(a < start < b for a, b in bounds):
                continue
            found.setdefault(match.span(), []).append(figure)
    # a value alone inside a longer match ("0.306 K" of "0.306 K [0.281, 0.329]") is that one
    spans = [s for s in found if not any(o != s and o[0] <= s[0] and s[1] <= o[1] for o in found)]
    return [
        (masked.count("\n", 0, span[0]) + 1, found[span], masked[span[0] : span[1]])
        for span in sorted(spans)
    ]


class ResultRow(NamedTuple):
    """One task of the README's results table: the learnt controller the project's
    recipe keeps (name, file, label), the best classical controller (name, file,
    label), the file of the uncontrolled run, and whether a higher value is better."""

    task: str
    learnt: tuple[str, str, str]
    classical: tuple[str, str, str]
    uncontrolled: str
    higher_is_better: bool


#: the results table's rows, each naming its results files by key (:func:`benchmark_path`);
#: the variants and earlier recipes are on the benchmark page
RESULT_ROWS: list[ResultRow] = [
    ResultRow(
        "jet cylinder: share of the drag floor once settled (higher is better)",
        (
            "SAC on the feedback law, validated over 10 s, stopped at 97 %",
            "jet-cylinder-fast-residual-10s",
            "SAC",
        ),
        ("feedback law", "jet-cylinder-fast-utd4", "best feedback"),
        "jet-cylinder-fast-utd4",
        True,
    ),
    ResultRow(
        "rotating cylinder: the same",
        ("SAC, 8 gradient steps a batch, stopped at 90 %", "rotating-cylinder-fast-utd4", "SAC"),
        ("feedback law", "rotating-cylinder-fast-utd4", "best feedback"),
        "rotating-cylinder-fast-utd4",
        True,
    ),
    ResultRow(
        "flap: mean tip displacement (lower is better)",
        ("SAC, 4,800 actions", "perpendicular-flap-fast-sac", "SAC"),
        ("sinusoid", "perpendicular-flap-fast-sac", "best sinusoid"),
        "perpendicular-flap-fast-sac",
        False,
    ),
    ResultRow(
        "heated plate: mean tracking error (lower is better)",
        ("SAC seeing the integrated error, 4,000 actions", "heated-plate-fast-tuned", "SAC"),
        ("PID", "heated-plate-fast-baselines", "best feedback"),
        "heated-plate-fast-baselines",
        False,
    ),
    ResultRow(
        "two flaps: mean tip displacement of both (lower is better)",
        (
            "SAC on the damping law, one policy both flaps share, 1,600 actions",
            "two-flaps-fast-residual",
            "SAC, shared policy",
        ),
        ("feedback of each tip's velocity", "two-flaps-fast-baselines", "best feedback"),
        "two-flaps-fast-baselines",
        False,
    ),
]


def _headline_value(env: str, controller: str, results: Path) -> float:
    metric, statistic, _ = HEADLINES[env]
    entry = _controller(env, controller, results)
    return float(entry["metrics"][metric][statistic]["value"])


def seeds_better(row: ResultRow, results: Path = RESULTS) -> str:
    """On how many seeds the learnt controller beats the best classical one: ``5 of 5``.

    A seed's score is its mean over the held-out starts (a results file that keeps every
    score, the newer form); the classical controller's is its value over the same starts
    (it runs once: no seed to vary)."""
    _, env, label = row.learnt
    metric, _, _ = HEADLINES[env]
    scores = _controller(env, label, results)["metrics"][metric].get("scores")
    if not scores:
        path = _source(benchmark_path(env, results))
        raise KeyError(f"{path} keeps no score per seed of {label!r}")
    _, classical_env, classical_label = row.classical
    classical = _headline_value(classical_env, classical_label, results)
    means = [sum(seed) / len(seed) for seed in scores]
    better = sum((m > classical) if row.higher_is_better else (m < classical) for m in means)
    return f"{better} of {len(means)}"


def results_table(results: Path = RESULTS) -> str:
    """The benchmarks' headline figures as one short Markdown table (the README's): each
    task's learnt controller (the kept models of its recipe) over seeds with its 95 %
    interval, on how many seeds it beats the best classical controller, that controller
    and the uncontrolled run, from the result files."""
    rows = [
        "| task | learnt, over seeds | seeds better than the classical "
        "| best classical | uncontrolled |",
        "| --- | --- | --- | --- | --- |",
    ]
    for row in RESULT_ROWS:
        name, env, label = row.learnt
        classical_name, classical_env, classical_label = row.classical
        rows.append(
            f"| {row.task} | {name} {score(env, label, results)} | {seeds_better(row, results)} "
            f"| {classical_name} {score(classical_env, classical_label, results)} "
            f"| {score(row.uncontrolled, 'uncontrolled', results)} |"
        )
    return "\n".join(rows)


def setup_figures(results: Path = RESULTS) -> dict[str, Any]:
    """The set-up's times on a fresh machine and a second time, and its steps as a table."""
    data = _load(results / "setup.json")
    rows = ["| step | fresh machine | second run |", "| --- | --- | --- |"]
    rows += [
        f"| {s['step']} | {clock(s['fresh_seconds'])} | {s['second_run']} |" for s in data["steps"]
    ]
    return {
        "fresh": clock(data["setup_seconds"] + data["debian_packages_seconds"]),
        "debian": clock(data["debian_packages_seconds"]),
        "without_debian": clock(data["setup_seconds"]),
        "second": clock(data["setup_second_run_seconds"]),
        "ci": clock(data["ci_seconds"]),
        "ci_second": clock(data["ci_second_run_seconds"]),
        "measured_on": data["measured_on"],
        "table": "\n".join(rows),
    }


# -- the environments, from their registration --------------------------------------------


def _box(space: Any, unit: str = "") -> str:
    """``(151,)`` float32, unbounded; ``(1,)`` in [-2.5e-05, 2.5e-05] m³/s."""
    import numpy as np

    shape = f"`{tuple(space.shape)}` {np.dtype(space.dtype).name}"
    low, high = np.unique(space.low), np.unique(space.high)
    if np.all(np.isinf(low)) and np.all(np.isinf(high)):
        return f"{shape}, unbounded"
    if len(low) == 1 and len(high) == 1:
        bounds = f"in [{low[0]:g}, {high[0]:g}]" + (f" {unit}" if unit else "")
        return f"{shape} {bounds}"
    return f"{shape}, bounds per entry"


#: keyword arguments env_facts makes an env with where its defaults need what a site's
#: build does not have: FSI3's registered env starts from a library of starts that a long
#: coupled run builds, and made from rest (``starts=None``) it has the same spaces
_FACTS_KWARGS: dict[str, dict[str, Any]] = {"gymprecice/TurekHronFSI3-v0": {"starts": None}}


def env_facts(env_id: str) -> dict[str, str]:
    """What the registration of ``env_id`` says of it: its lab card's fields and its
    spaces, read from an instance that starts nothing (the test double where the card
    offers one; an env starts its solvers in ``reset``, never when it is made)."""
    import tempfile

    import gymnasium

    import gymprecice  # noqa: F401  (registers the ids)
    from gymprecice.plugin.card import card_for

    card = card_for(env_id)
    with tempfile.TemporaryDirectory() as run_root:
        kwargs = {"double": True} if card.double else dict(_FACTS_KWARGS.get(env_id, {}))
        env = gymnasium.make(env_id, run_root=run_root, disable_env_checker=True, **kwargs)
        try:
            observation, action = env.observation_space, env.action_space
        finally:
            env.close()
    if card.objective is None:  # the negated mean reward, lower is better
        objective = "the mean reward per action, higher is better"
    else:
        better = "higher" if card.maximize else "lower"
        objective = f'`{card.objective}` (in `info["metrics"]`), {better} is better'
    if card.reference is not None:
        objective += f"; also the share of the {card.reference.label} it takes"
    return {
        "name": f"`{card.name}`" if card.name else "",
        "description": card.description,
        "observation": _box(observation),
        "action": _box(action, card.action_unit),
        "objective": objective,
        "held_out_starts": "yes" if card.held_out_starts else "no: the starts are seeds",
        "double": "yes (`--double`)" if card.double else "no",
    }


#: env_table's rows: the label and the key of env_facts
_FACT_ROWS = (
    ("command-line name", "name"),
    ("what it is", "description"),
    ("observation", "observation"),
    ("action", "action"),
    ("ranked on", "objective"),
    ("held-out starts", "held_out_starts"),
    ("test double", "double"),
)


def env_table(*env_ids: str) -> str:
    """A Markdown table of the registered environments ``env_ids``, one column each: the
    facts of :func:`env_facts`, so that a page cannot drift from the registration."""
    facts = [env_facts(env_id) for env_id in env_ids]
    ids = [env_id.split("/", 1)[-1] for env_id in env_ids]
    rows = ["| | " + " | ".join(f"`{i}`" for i in ids) + " |"]
    rows.append("| --- |" + " --- |" * len(ids))
    for label, key in _FACT_ROWS:
        cells = [fact[key].replace("|", "\\|") for fact in facts]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def version() -> str:
    """gymprecice-core's version: its installed metadata, else its pyproject.toml."""
    try:
        return importlib.metadata.version("gymprecice-core")
    except importlib.metadata.PackageNotFoundError:
        pyproject = (ROOT / "packages" / "gymprecice-core" / "pyproject.toml").read_text()
        found = re.search(r'^version\s*=\s*"([^"]+)"', pyproject, re.MULTILINE)
        if found is None:
            raise RuntimeError("packages/gymprecice-core/pyproject.toml names no version") from None
        return found.group(1)


def command_reference() -> str:
    """Every ``gymprecice`` command, from its parser (scripts/docs_commands.py)."""
    path = Path(__file__).with_name("docs_commands.py")
    spec = importlib.util.spec_from_file_location("docs_commands", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.command_reference()


def define_env(env: Any) -> None:
    """mkdocs-macros' entry point: the figures as variables, the look-ups as macros, and
    the version in every page's footer."""
    env.variables["version"] = version()
    env.conf["copyright"] = f"gymprecice {env.variables['version']}"
    env.variables["shipped"] = shipped()
    env.variables["setup"] = setup_figures()
    env.macro(command_reference)
    env.macro(kept_models)
    env.macro(typed_run)
    env.macro(score)
    env.macro(results_table)
    env.macro(seed_means)
    env.macro(training_table)
    env.macro(below)
    env.macro(time_to_floor)
    env.macro(kept_after)
    env.macro(cost)
    env.macro(env_table)
    env.filter(clock)
    env.filter(thousands)
