"""The measured figures the documentation quotes, read from the result files that hold them.

mkdocs-macros (``plugins: macros`` in mkdocs.yml) calls :func:`define_env` once per build.
A page that sets ``render_macros: true`` in its front matter can then write, instead of a
number typed by hand::

    {{ shipped["jet-cylinder-fast"].training }}      1 h 14 min
    {{ shipped["perpendicular-flap-fast"].means.mean_mean_tip_displacement | round(4) }}
    {{ score("jet-cylinder-fast", "SAC") }}          88.9 % [87.2 %, 92.7 %]
    {{ time_to_floor("sac-overlap", 0.95).median }}  11 min 50 s
    {{ setup.fresh }}                                7 min 40 s

The figures come from:

* ``packages/gymprecice-tutorials/src/gymprecice_tutorials/policies/*/policy.json``: each
  shipped policy's training run and evaluation, written by ``gymprecice ship-policy``;
* ``docs/results/benchmark-<env>.json``: ``gymprecice benchmark``'s ``results.json``
  (the headline controllers of each environment's benchmark);
* ``docs/results/time-to-floor-jet-cylinder-fast-<recipe>.json``: the ``summary`` of
  ``gymprecice time-to-floor``'s ``time_to_floor.json``;
* ``docs/results/setup.json``: the set-up's steps timed on a fresh machine.

Rerunning one of those commands and copying its file over the old one updates every page
that quotes it; no page holds the number itself. A name that is not there fails the
build (``on_undefined: strict``), naming the page.

Two more things are read, not written: the version every page shows in its footer
(``{{ version }}``: gymprecice-core's, from its installed metadata, else its
pyproject.toml), and the command reference (``{{ command_reference() }}``), written from
the ``gymprecice`` command line's own parsers by scripts/docs_commands.py.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import math
import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
POLICIES = ROOT / "packages" / "gymprecice-tutorials" / "src" / "gymprecice_tutorials" / "policies"

#: each benchmark's headline metric, the statistic quoted and how a value is written
HEADLINES: dict[str, tuple[str, str, str]] = {
    "jet-cylinder-fast": ("settled_floor_fraction", "median", "percent"),
    "rotating-cylinder-fast": ("settled_floor_fraction", "median", "percent"),
    "perpendicular-flap-fast": ("mean_tip_displacement", "mean", "{:.4f} m"),
    "heated-plate-fast": ("mean_tracking_error", "mean", "{:.3f} K"),
    # observation="integral": results.json as the benchmark wrote it
    "heated-plate-fast-integral": ("objective", "mean", "{:.3f} K"),
    # results.json as the benchmark wrote it: the env's objective under "objective"
    "two-flaps-fast": ("objective", "mean", "{:.5f} m"),
    "two-flaps-fast-one-controller": ("objective", "mean", "{:.5f} m"),
}


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


def _write(value: float, how: str) -> str:
    if how == "percent":
        return f"{100 * value:.1f} %"
    return how.format(value)


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


def score(env: str, controller: str, results: Path = RESULTS) -> str:
    """A benchmarked controller's headline figure with its interval: ``88.9 % [87.2 %, 92.7 %]``."""
    metric, statistic, how = HEADLINES[env]
    data = _load(results / f"benchmark-{env}.json")
    for entry in data["controllers"]:
        # a baseline by its kind ("best sinusoid") or its whole label ("best sinusoid: sine-...")
        if entry["label"] == controller or entry["label"].startswith(f"{controller}: "):
            stat = entry["metrics"][metric][statistic]
            text = _write(stat["value"], how)
            if entry["runs"] > 1:
                text += f" [{_write(stat['low'], how)}, {_write(stat['high'], how)}]"
            return text
    labels = [entry["label"] for entry in data["controllers"]]
    raise KeyError(f"docs/results/benchmark-{env}.json has no controller {controller!r}: {labels}")


def seed_means(env: str, controller: str, results: Path = RESULTS) -> str:
    """A benchmarked controller's score per seed (its mean over the starts), in seed
    order: ``0.230, 0.230, 0.243, 0.307 and 0.252 K``; from a results file that keeps
    every score (the newer form)."""
    metric, _, how = HEADLINES[env]
    data = _load(results / f"benchmark-{env}.json")
    for entry in data["controllers"]:
        if entry["label"] == controller:
            means = [sum(row) / len(row) for row in entry["metrics"][metric]["scores"]]
            texts = [_write(m, how) for m in means]
            unit = texts[-1].split(" ", 1)[1] if " " in texts[-1] else ""
            numbers = [t.split(" ", 1)[0] for t in texts]
            return f"{', '.join(numbers[:-1])} and {numbers[-1]}" + (f" {unit}" if unit else "")
    raise KeyError(f"docs/results/benchmark-{env}.json has no controller {controller!r}")


def time_to_floor(recipe: str, fraction: float, results: Path = RESULTS) -> dict[str, str]:
    """The median time to a fraction of the drag floor: ``median``, ``low``, ``high``, ``reached``."""
    data = _load(results / f"time-to-floor-jet-cylinder-fast-{recipe}.json")
    entry = data["summary"][f"{fraction:g}"]
    reached = entry["runs"] - entry.get("not_reached", 0)
    return {
        "median": clock(entry["median"]),
        "low": clock(entry["low"]),
        "high": clock(entry["high"]),
        "reached": f"{reached} of {entry['runs']}",
    }


#: the results table's rows: the task and objective, the learnt controllers (prefix,
#: file, label), the best classical controller (prefix, file, label), the uncontrolled
#: run's file; each file is docs/results/benchmark-<file>.json
RESULT_ROWS: list[tuple[str, list[tuple[str, str, str]], tuple[str, str, str], str]] = [
    (
        "jet cylinder: share of the drag floor (higher is better)",
        [("SAC", "jet-cylinder-fast", "SAC"), ("PPO", "jet-cylinder-fast", "PPO")],
        ("feedback law", "jet-cylinder-fast", "best feedback"),
        "jet-cylinder-fast",
    ),
    (
        "rotating cylinder: the same",
        [("SAC", "rotating-cylinder-fast", "SAC")],
        ("feedback law", "rotating-cylinder-fast", "best feedback"),
        "rotating-cylinder-fast",
    ),
    (
        "flap: mean tip displacement (lower is better)",
        [("PPO", "perpendicular-flap-fast", "PPO")],
        ("sinusoid", "perpendicular-flap-fast", "best sinusoid"),
        "perpendicular-flap-fast",
    ),
    (
        "heated plate: mean tracking error (lower is better)",
        [
            ("SAC", "heated-plate-fast", "SAC"),
            ("SAC seeing the integrated error", "heated-plate-fast-integral", "SAC"),
        ],
        ("PID", "heated-plate-fast", "best PID"),
        "heated-plate-fast",
    ),
    (
        "two flaps: mean tip displacement of both (lower is better)",
        [("SAC, one policy for both flaps", "two-flaps-fast", "SAC, shared policy")],
        ("sinusoid", "two-flaps-fast", "best sinusoid"),
        "two-flaps-fast",
    ),
]


def results_table(results: Path = RESULTS) -> str:
    """The benchmarks' headline figures as one short Markdown table (the README's): each
    task's learnt controllers over seeds, its best classical controller and the
    uncontrolled run, with 95 % intervals over seeds, from the result files."""
    rows = [
        "| task | learnt, over seeds | best classical | uncontrolled |",
        "| --- | --- | --- | --- |",
    ]
    for task, learnt, (name, env, label), uncontrolled in RESULT_ROWS:
        learnt_text = "; ".join(f"{n} {score(e, c, results)}" for n, e, c in learnt)
        classical = f"{name} {score(env, label, results)}"
        rows.append(
            f"| {task} | {learnt_text} | {classical} | "
            f"{score(uncontrolled, 'uncontrolled', results)} |"
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
    env.macro(score)
    env.macro(results_table)
    env.macro(seed_means)
    env.macro(time_to_floor)
    env.filter(clock)
    env.filter(thousands)
