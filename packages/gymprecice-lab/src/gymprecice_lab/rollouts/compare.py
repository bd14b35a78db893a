"""``gymprecice compare``: a controller against the uncontrolled flow and the best open loop.

Reads what other commands wrote, runs nothing:

* ``gymprecice sweep`` outputs (``sweep.csv``): the uncontrolled flow, constants and
  sinusoids, each with its objective on every held-out start; several sweeps (say,
  sinusoids about two centres) pool into one set of candidates;
* ``gymprecice evaluate`` / ``baseline`` / ``open-loop`` outputs (``summary.json``): one
  controller each, its objective per episode (episode k ran held-out start k).

and writes ``compare.md`` and ``compare.json`` under ``--out``: every controller's
objective per start and its mean ± standard deviation over the starts, and for each
evaluated controller its *margin* against the uncontrolled flow, the best constant and
the best sinusoid (chosen by mean objective): per start ``100 (ref - x) / ref`` %, their
mean and their standard deviation (the spread). A margin is *clear* when its mean exceeds
its spread and it is positive on every start.

``--video FILE`` also puts the videos of the runs side by side, start by start: the
uncontrolled flow (a ``baseline`` run made with ``--video``) beside each controlled one
(``evaluate`` and the other runs made with ``--video``), from the same start
(:func:`side_by_side_videos`).
"""

from __future__ import annotations

import csv
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_lab.common.registered_env import LabEnv, find_lab_env
from gymprecice_lab.rollouts.command_settings import CompareSettings
from gymprecice_lab.rollouts.video import VideoError, check_video_path, side_by_side

__all__ = [
    "Controller",
    "Margin",
    "compare_command",
    "margin",
    "read_runs",
    "side_by_side_videos",
]


@dataclass(frozen=True)
class Controller:
    """A controller's objective on each held-out start (lower is better)."""

    label: str
    kind: str
    objectives: tuple[float, ...]

    @property
    def mean(self) -> float:
        return float(np.mean(self.objectives))

    @property
    def std(self) -> float:
        return float(np.std(self.objectives))


@dataclass(frozen=True)
class Margin:
    """How much lower ``controller``'s objective is than ``reference``'s, in % of it."""

    reference: str
    per_start: tuple[float, ...]

    @property
    def mean(self) -> float:
        return float(np.mean(self.per_start))

    @property
    def spread(self) -> float:
        return float(np.std(self.per_start))

    @property
    def clear(self) -> bool:
        return self.mean > self.spread and min(self.per_start) > 0


def margin(controller: Controller, reference: Controller) -> Margin:
    """Per-start margin of ``controller`` over ``reference`` (both on the same starts)."""
    if len(controller.objectives) != len(reference.objectives):
        raise SystemExit(
            f"gymprecice compare: {controller.label} ran {len(controller.objectives)} starts, "
            f"{reference.label} {len(reference.objectives)}; run both with the same --episodes"
        )
    ref, ours = np.asarray(reference.objectives), np.asarray(controller.objectives)
    return Margin(reference.label, tuple(float(v) for v in 100.0 * (ref - ours) / ref))


def _env_of(run: Path) -> tuple[LabEnv, dict[str, Any]]:
    try:
        manifest = json.loads((run / "manifest.json").read_text())
        return find_lab_env(manifest["settings"]["env_id"]), manifest
    except (OSError, ValueError, KeyError) as exc:
        raise SystemExit(
            f"gymprecice compare: {run} is not the output of a gymprecice command "
            f"(its manifest.json: {exc})"
        ) from None


def read_runs(runs: list[Path]) -> tuple[LabEnv, list[Controller], list[Controller]]:
    """(env, open-loop candidates from sweeps, evaluated controllers) of ``runs``."""
    envs, seeds, candidates, evaluated = set(), set(), [], []
    for run in runs:
        env, manifest = _env_of(run)
        envs.add(env.name)
        seeds.add(manifest.get("seeds", {}).get("seed"))
        if manifest.get("settings", {}).get("starts") == "validation":
            raise SystemExit(
                f"gymprecice compare: {run} ran on the env's validation starts (gymprecice "
                "sweep --starts validation), not the held-out ones the others ran on: run its "
                "best point on the held-out starts (gymprecice sweep with that one point, or "
                "gymprecice feedback --law) and compare that"
            )
        if (run / "sweep.csv").is_file():
            with (run / "sweep.csv").open() as handle:
                for row in csv.DictReader(handle):
                    starts = sorted(k for k in row if k.startswith("start_"))
                    values = tuple(float(row[k]) for k in starts if row[k] != "")
                    candidates.append(Controller(row["label"], row["kind"], values))
        elif (run / "summary.json").is_file():
            summary = json.loads((run / "summary.json").read_text())
            key = f"mean_{env.objective}" if env.objective else None
            sign = -1.0 if key and env.maximize else 1.0  # lower is better in every table
            values = tuple(
                sign * float(e[key]) if key else -float(e["return"]) / max(1, int(e["steps"]))
                for e in summary["episodes"]
            )
            evaluated.append(Controller(run.name, manifest.get("command", "run"), values))
        else:
            raise SystemExit(
                f"gymprecice compare: {run} has neither sweep.csv (gymprecice sweep) nor "
                "summary.json (gymprecice evaluate, baseline, open-loop)"
            )
    if len(envs) > 1:
        raise SystemExit(f"gymprecice compare: the runs come from different envs: {sorted(envs)}")
    if len(seeds) > 1:
        raise SystemExit(
            f"gymprecice compare: the runs started from different seeds {sorted(map(str, seeds))}: "
            "the held-out starts differ; run them all with the same --seed"
        )
    return find_lab_env(envs.pop()), candidates, evaluated


def _videos(run: Path) -> tuple[str, dict[int, Path]]:
    """A run's command and its episodes' videos by start (``{}``: made without --video)."""
    try:
        summary = json.loads((run / "summary.json").read_text())
        command = json.loads((run / "manifest.json").read_text()).get("command", "run")
    except (OSError, ValueError):
        return "run", {}
    videos = {
        int(e.get("start", e["episode"])): Path(e["video"])
        for e in summary.get("episodes", [])
        if e.get("video")
    }
    return command, videos


def side_by_side_videos(runs: list[Path], video: Path) -> list[Path]:
    """The uncontrolled run's video beside each controlled run's, for every common start.

    Written to ``video`` (one start in common) or ``video`` with ``-start-K`` before its
    suffix. Raises :class:`VideoError` naming the command that makes what is missing.
    """
    uncontrolled: list[tuple[str, dict[int, Path]]] = []
    controlled: list[tuple[str, dict[int, Path]]] = []
    for run in runs:
        command, videos = _videos(run)
        if videos:
            (uncontrolled if command == "baseline" else controlled).append((run.name, videos))
    if not uncontrolled or not controlled:
        missing = "uncontrolled (baseline)" if not uncontrolled else "controlled (evaluate)"
        raise VideoError(
            f"--video: none of the runs is an {missing} run made with --video; run e.g. "
            "`gymprecice baseline ENV --video --out DIR` and `gymprecice evaluate ENV "
            "--video --out DIR` (same --seed, or --all-starts) and pass both directories"
        )
    panels = [uncontrolled[0], *controlled]
    starts = sorted(set.intersection(*(set(videos) for _, videos in panels)))
    if not starts:
        raise VideoError(
            "--video: the uncontrolled and the controlled runs have no start in common; run "
            "them with the same --seed and --episodes, or both with --all-starts"
        )
    labels = ["uncontrolled", *(f"controlled: {name}" for name, _ in controlled)]
    written = []
    for start in starts:
        out = (
            video
            if len(starts) == 1
            else video.with_name(f"{video.stem}-start-{start}{video.suffix}")
        )
        written.append(side_by_side(out, [videos[start] for _, videos in panels], labels))
    return written


def _best(candidates: list[Controller], kind: str) -> Controller | None:
    of_kind = [c for c in candidates if c.kind == kind]
    return min(of_kind, key=lambda c: c.mean) if of_kind else None


#: how a reference is named in the table, by its kind
_TITLES = {
    "uncontrolled": "uncontrolled",
    "constant": "best constant",
    "sinusoid": "best sinusoid",
    "feedback": "best feedback",
}


def _table(env: LabEnv, references: list[Controller], evaluated: list[Controller]) -> list[str]:
    """The objective of every controller on each start, the references first (Markdown)."""
    objective = (env.objective or "negated mean reward").replace("_", " ")
    n = max(len(c.objectives) for c in [*references, *evaluated])
    lines = [
        f"Objective: {objective} (lower is better), per held-out start of {env.env_id}.",
        "",
        "| controller | " + " | ".join(f"start {k}" for k in range(n)) + " | mean ± std |",
        "| --- | " + " | ".join("---" for _ in range(n)) + " | --- |",
    ]
    for c in [*references, *evaluated]:
        name = f"{_TITLES.get(c.kind, c.kind)}: {c.label}" if c in references else c.label
        cells = " | ".join(f"{v:.4g}" for v in c.objectives)
        lines.append(f"| {name} | {cells} | {c.mean:.4g} ± {c.std:.2g} |")
    return lines


def _margins(
    c: Controller, references: list[Controller]
) -> tuple[list[str], dict[str, dict[str, Any]]]:
    """``c``'s margin over each reference: a line each, and their record."""
    lines, margins = [], {}
    for ref in references:
        m = margin(c, ref)
        per_start = ", ".join(f"{v:+.1f}" for v in m.per_start)
        verdict = "clear" if m.clear else "NOT clear"
        lines.append(
            f"- vs {_TITLES[ref.kind]} ({ref.label}): {m.mean:+.1f} % ± {m.spread:.1f} "
            f"({per_start}); {verdict}"
        )
        margins[_TITLES[ref.kind]] = {
            "reference": ref.label,
            "per_start_percent": list(m.per_start),
            "mean_percent": m.mean,
            "spread_percent": m.spread,
            "clear": m.clear,
        }
    return lines, margins


def compare_command(settings: CompareSettings) -> int:
    """``gymprecice compare RUN... [--out DIR]``."""
    missing = [str(r) for r in settings.runs if not r.is_dir()]
    if missing:
        print(f"gymprecice compare: no such run directory: {', '.join(missing)}", file=sys.stderr)
        return 2
    video = settings.video
    if video is not None:
        try:
            check_video_path(video)
        except VideoError as exc:
            print(f"gymprecice compare: {exc}", file=sys.stderr)
            return 2
    env, candidates, evaluated = read_runs(list(settings.runs))
    references = [
        ref
        for ref in (
            _best(candidates, "uncontrolled"),
            _best(candidates, "constant"),
            _best(candidates, "sinusoid"),
            _best(candidates, "feedback"),
        )
        if ref is not None
    ]
    lines = _table(env, references, evaluated)
    record: dict[str, Any] = {
        "env_id": env.env_id,
        "objective": env.objective,
        "references": {
            _TITLES[r.kind]: r.__dict__ | {"mean": r.mean, "std": r.std} for r in references
        },
        "controllers": {},
    }
    for c in evaluated:
        said, margins = _margins(c, references)
        lines += ["", f"Margins of {c.label} (per start, % of the reference):", "", *said]
        record["controllers"][c.label] = {
            "objectives": list(c.objectives),
            "mean": c.mean,
            "std": c.std,
            "margins": margins,
        }
    text = "\n".join(lines) + "\n"
    out = settings.out or Path(settings.runs[0]).parent / "compare"
    out.mkdir(parents=True, exist_ok=True)
    (out / "compare.md").write_text(text)
    (out / "compare.json").write_text(json.dumps(record, indent=2) + "\n")
    print(text, end="")
    print(f"gymprecice compare: wrote {out / 'compare.md'} and compare.json")
    if video is not None:
        try:
            videos = side_by_side_videos(list(settings.runs), video)
        except VideoError as exc:
            print(f"gymprecice compare: {exc}", file=sys.stderr)
            return 2
        print(f"gymprecice compare: wrote {', '.join(str(v) for v in videos)}")
    return 0
