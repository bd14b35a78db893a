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
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_tutorials.environments import TutorialEnv, find_environment

__all__ = ["Controller", "Margin", "compare_command", "margin", "read_runs"]


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


def _env_of(run: Path) -> tuple[TutorialEnv, dict[str, Any]]:
    try:
        manifest = json.loads((run / "manifest.json").read_text())
        return find_environment(manifest["settings"]["env_id"]), manifest
    except (OSError, ValueError, KeyError) as exc:
        raise SystemExit(
            f"gymprecice compare: {run} is not the output of a gymprecice command "
            f"(its manifest.json: {exc})"
        ) from None


def read_runs(runs: list[Path]) -> tuple[TutorialEnv, list[Controller], list[Controller]]:
    """(env, open-loop candidates from sweeps, evaluated controllers) of ``runs``."""
    envs, seeds, candidates, evaluated = set(), set(), [], []
    for run in runs:
        env, manifest = _env_of(run)
        envs.add(env.name)
        seeds.add(manifest.get("seeds", {}).get("seed"))
        if (run / "sweep.csv").is_file():
            with (run / "sweep.csv").open() as handle:
                for row in csv.DictReader(handle):
                    starts = sorted(k for k in row if k.startswith("start_"))
                    values = tuple(float(row[k]) for k in starts if row[k] != "")
                    candidates.append(Controller(row["label"], row["kind"], values))
        elif (run / "summary.json").is_file():
            summary = json.loads((run / "summary.json").read_text())
            key = f"mean_{env.objective}" if env.objective else None
            values = tuple(
                float(e[key]) if key else -float(e["return"]) / max(1, int(e["steps"]))
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
    return find_environment(envs.pop()), candidates, evaluated


def _best(candidates: list[Controller], kind: str) -> Controller | None:
    of_kind = [c for c in candidates if c.kind == kind]
    return min(of_kind, key=lambda c: c.mean) if of_kind else None


def compare_command(args: argparse.Namespace) -> int:
    """``gymprecice compare RUN... [--out DIR]``."""
    missing = [str(r) for r in args.runs if not r.is_dir()]
    if missing:
        print(f"gymprecice compare: no such run directory: {', '.join(missing)}", file=sys.stderr)
        return 2
    env, candidates, evaluated = read_runs(list(args.runs))
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
    titles = dict(
        zip(
            ("uncontrolled", "constant", "sinusoid", "feedback"),
            ("uncontrolled", "best constant", "best sinusoid", "best feedback"),
        )
    )
    objective = (env.objective or "negated mean reward").replace("_", " ")
    n = max(len(c.objectives) for c in [*references, *evaluated])
    lines = [
        f"Objective: {objective} (lower is better), per held-out start of {env.env_id}.",
        "",
        "| controller | " + " | ".join(f"start {k}" for k in range(n)) + " | mean ± std |",
        "| --- | " + " | ".join("---" for _ in range(n)) + " | --- |",
    ]
    for c in [*references, *evaluated]:
        name = f"{titles.get(c.kind, c.kind)}: {c.label}" if c in references else c.label
        cells = " | ".join(f"{v:.4g}" for v in c.objectives)
        lines.append(f"| {name} | {cells} | {c.mean:.4g} ± {c.std:.2g} |")
    record: dict[str, Any] = {
        "env_id": env.env_id,
        "objective": env.objective,
        "references": {
            titles[r.kind]: r.__dict__ | {"mean": r.mean, "std": r.std} for r in references
        },
        "controllers": {},
    }
    for c in evaluated:
        lines += ["", f"Margins of {c.label} (per start, % of the reference):", ""]
        margins = {}
        for ref in references:
            m = margin(c, ref)
            per_start = ", ".join(f"{v:+.1f}" for v in m.per_start)
            verdict = "clear" if m.clear else "NOT clear"
            lines.append(
                f"- vs {titles[ref.kind]} ({ref.label}): {m.mean:+.1f} % ± {m.spread:.1f} "
                f"({per_start}); {verdict}"
            )
            margins[titles[ref.kind]] = {
                "reference": ref.label,
                "per_start_percent": list(m.per_start),
                "mean_percent": m.mean,
                "spread_percent": m.spread,
                "clear": m.clear,
            }
        record["controllers"][c.label] = {
            "objectives": list(c.objectives),
            "mean": c.mean,
            "std": c.std,
            "margins": margins,
        }
    text = "\n".join(lines) + "\n"
    out = args.out or Path(args.runs[0]).parent / "compare"
    out.mkdir(parents=True, exist_ok=True)
    (out / "compare.md").write_text(text)
    (out / "compare.json").write_text(json.dumps(record, indent=2) + "\n")
    print(text, end="")
    print(f"gymprecice compare: wrote {out / 'compare.md'} and compare.json")
    return 0
