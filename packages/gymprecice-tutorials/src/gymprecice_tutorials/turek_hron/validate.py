"""Validation of the FSI3 case against Turek and Hron's published values.

Runs :class:`~.environment.TurekHronEnv` uncontrolled (the jets shut) from rest under
the benchmark's ramped inflow, records the bar tip's displacement and the drag and
lift at every time window, and compares the periodic state of the last ``--window``
seconds with :data:`~.reference.PUBLISHED`, each figure within its stated tolerance::

    python -m gymprecice_tutorials.turek_hron.validate [--resolution coarse|medium|fine]
        [--time-step S] [--end-time S] [--degree P] [--window S] [--smoke]
        [--solid dealii|fenics] [--load rbf|vertex] [--out DIR] [--json FILE] [--figure PNG]
    python -m gymprecice_tutorials.turek_hron.validate --summarize RESULT.json ...

``--summarize`` prints the mesh and time-step study: one row per result file that
``--json`` wrote, the figures that tell the runs apart. ``--smoke`` runs 0.1 s and checks that the coupled run goes through with every
output in place, comparing nothing (CI). Exits 1 when a figure misses its tolerance
(or the smoke run's outputs do not add up), 2 on bad input. Needs the real stack
(OpenFOAM, preCICE and the deal.II adapter).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time as clock
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_tutorials.turek_hron.case import SOLIDS
from gymprecice_tutorials.turek_hron.mesh import RESOLUTIONS, cell_count
from gymprecice_tutorials.turek_hron.reference import PUBLISHED, oscillation
from gymprecice_tutorials.turek_hron.series import SIGNALS, Series, recorded_series, run_to_end

__all__ = ["Series", "compare", "main", "run_uncontrolled"]

#: simulated seconds of the full run, and the periodic state's window at its end
FULL_END = 8.0
WINDOW = 1.0
SMOKE_END = 0.1


def run_uncontrolled(
    resolution: str,
    time_step: float,
    end_time: float,
    degree: int,
    run_root: Path,
    solid: str = "dealii",
    load: str | None = None,
) -> tuple[Series, float]:
    """The uncontrolled run's series at every time window, and its wall-clock (s)."""
    from gymprecice_tutorials.turek_hron.environment import TurekHronEnv

    started = clock.monotonic()
    env = TurekHronEnv(
        resolution=resolution,
        time_step=time_step,
        end_time=end_time,
        degree=degree,
        solid=solid,
        run_root=run_root,
        solid_settings={"load": load} if load else None,
    )
    try:
        env.reset(seed=0)
        run_to_end(env)
        series = recorded_series(env)
    finally:
        env.close()
    return series, clock.monotonic() - started


def compare(series: Series, window: float) -> dict[str, dict[str, Any]]:
    """Each published figure: the run's, the published one, the error, the tolerance
    and whether the run is within it."""
    table: dict[str, dict[str, Any]] = {}
    for signal in SIGNALS:
        measured = oscillation(series["time"], series[signal], window)
        for part in ("mean", "amplitude", "frequency"):
            figure = PUBLISHED[f"{signal}_{part}"]
            value = float(getattr(measured, part))
            table[f"{signal}_{part}"] = {
                "run": value,
                "published": figure.value,
                "error": figure.error(value) if np.isfinite(value) else None,
                "tolerance": figure.tolerance,
                "kind": figure.kind,
                "within": figure.passes(value),
            }
    return table


_UNITS = {"tip_dx": "mm", "tip_dy": "mm", "drag": "N/m", "lift": "N/m"}


def _table(figures: dict[str, dict[str, Any]]) -> str:
    lines = ["| figure | published | this run | error | tolerance |", "| --- |" + " --- |" * 4]
    for name, row in figures.items():
        signal, part = name.rsplit("_", 1)
        unit = "Hz" if part == "frequency" else _UNITS[signal]
        scale = 1e3 if unit == "mm" else 1.0
        if row["kind"] == "relative":
            error = "n/a" if row["error"] is None else f"{100 * row['error']:.1f} %"
            tolerance = f"{100 * row['tolerance']:g} %"
        else:
            error = "n/a" if row["error"] is None else f"{scale * row['error']:.2f} {unit}"
            tolerance = f"{scale * row['tolerance']:g} {unit}"
        mark = "" if row["within"] else " (out)"
        lines.append(
            f"| {signal} {part} ({unit}) | {scale * row['published']:.4g} | "
            f"{scale * row['run']:.4g} | {error}{mark} | {tolerance} |"
        )
    return "\n".join(lines)


def _plot(series: Series, window: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = series["time"]
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True)
    panels = (
        ("tip_dy", 1e3, "bar tip dy (mm)", PUBLISHED["tip_dy_mean"], PUBLISHED["tip_dy_amplitude"]),
        ("lift", 1.0, "lift (N/m)", PUBLISHED["lift_mean"], PUBLISHED["lift_amplitude"]),
    )
    for ax, (name, scale, label, mean, amplitude) in zip(axes, panels, strict=True):
        ax.plot(t, scale * series[name], lw=0.9, label="this run")
        for sign in (-1, 1):
            level = scale * (mean.value + sign * amplitude.value)
            ax.axhline(level, color="k", ls="--", lw=0.8, label="published" if sign < 0 else None)
        ax.axvspan(t[-1] - window, t[-1], color="0.9", zorder=0)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", frameon=False)
    axes[-1].set_xlabel("time (s); shaded: the window compared")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: how the tables name each solid of :data:`~.case.SOLIDS`
SOLID_NAMES = {"dealii": "deal.II", "fenics": "FEniCS"}

#: the study's columns: a figure of :data:`~.reference.PUBLISHED` and its heading
STUDY = (
    ("tip_dy_amplitude", "tip dy amplitude (mm)", 1e3),
    ("tip_dy_frequency", "tip dy frequency (Hz)", 1.0),
    ("tip_dx_mean", "tip dx mean (mm)", 1e3),
    ("drag_mean", "drag mean (N/m)", 1.0),
    ("drag_amplitude", "drag amplitude (N/m)", 1.0),
    ("lift_amplitude", "lift amplitude (N/m)", 1.0),
)


def study_table(records: Sequence[dict[str, Any]]) -> str:
    """The mesh and time-step study: a row per run (a ``--json`` record), the published
    values first."""
    head = [
        "run",
        "solid",
        "cells",
        "time step (s)",
        *(label for _, label, _ in STUDY),
        "wall-clock",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    published = [f"{scale * PUBLISHED[name].value:.4g}" for name, _, scale in STUDY]
    lines.append("| published | | | | " + " | ".join(published) + " | |")
    for record in records:
        cells = [
            f"{scale * record['figures'][name]['run']:.4g}"
            + ("" if record["figures"][name]["within"] else " (out)")
            for name, _, scale in STUDY
        ]
        solid = SOLID_NAMES[record.get("solid", "dealii")]  # records before the FEniCS bar
        if record.get("load"):
            solid += f" ({record['load']} load)"
        lines.append(
            f"| {record['resolution']} | {solid} | {record['cells']:,} | "
            f"{record['time_step']:g} | "
            + " | ".join(cells)
            + f" | {record['wall_clock_s'] / 60:.0f} min |"
        )
    return "\n".join(lines)


def _smoke_check(series: Series, time_step: float, end_time: float) -> list[str]:
    """What is missing from a smoke run's outputs (nothing: the run went through)."""
    problems = []
    expected = round(end_time / time_step)
    rows = int(np.sum(series["time"] > 1e-12))
    if rows != expected:
        problems.append(f"the solid's watch point has {rows} windows, not {expected}")
    for name in SIGNALS:
        if not np.all(np.isfinite(series[name])):
            problems.append(f"{name} is not finite")
    if not series["drag"][-1] > 0:
        problems.append(f"the drag at the end is {series['drag'][-1]:.3g} N/m, not positive")
    return problems


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gymprecice_tutorials.turek_hron.validate`` (module docstring)."""
    parser = argparse.ArgumentParser(
        prog="python -m gymprecice_tutorials.turek_hron.validate",
        description=__doc__.split("\n\n")[0],
    )
    parser.add_argument("--resolution", choices=sorted(RESOLUTIONS), default="coarse")
    parser.add_argument("--time-step", type=float, default=1e-3, help="time window (s)")
    parser.add_argument("--end-time", type=float, help=f"simulated seconds ({FULL_END:g})")
    parser.add_argument("--degree", type=int, default=2, help="the solid's polynomial degree")
    parser.add_argument("--window", type=float, default=WINDOW, help="the last seconds compared")
    parser.add_argument(
        "--solid",
        choices=sorted(SOLIDS),
        default="dealii",
        help="the deal.II program, or the FEniCS bar that restarts (solid_checks)",
    )
    parser.add_argument(
        "--load",
        choices=("rbf", "vertex"),
        help="the FEniCS bar's fluid load between the coupling vertices (solid.py; default rbf)",
    )
    parser.add_argument("--smoke", action="store_true", help=f"{SMOKE_END:g} s, no comparison")
    parser.add_argument("--out", type=Path, help="where the run is made (default: temporary)")
    parser.add_argument("--json", type=Path, help="write the comparison here (and .md beside)")
    parser.add_argument("--figure", type=Path, help="draw the tip's dy and the lift here")
    parser.add_argument(
        "--summarize", type=Path, nargs="+", metavar="JSON", help="print the study's table"
    )
    args = parser.parse_args(argv)
    if args.summarize:
        missing = [str(path) for path in args.summarize if not path.is_file()]
        if missing:
            parser.error(f"no such result file: {', '.join(missing)} (write one with --json)")
        print(study_table([json.loads(path.read_text()) for path in args.summarize]))
        return 0
    if args.load and args.solid != "fenics":
        parser.error("--load is the FEniCS bar's (--solid fenics)")
    end = args.end_time or (SMOKE_END if args.smoke else FULL_END)
    if not (args.time_step > 0 and end > 0 and args.degree >= 1):
        parser.error("--time-step and --end-time must be positive, --degree at least 1")
    if not args.smoke and not 0 < args.window < end:
        parser.error(f"--window must lie in (0, {end:g}) s, got {args.window:g}")
    root = args.out or Path(tempfile.mkdtemp(prefix="fsi3-validation-"))
    series, seconds = run_uncontrolled(
        args.resolution, args.time_step, end, args.degree, root, args.solid, args.load
    )
    cells = cell_count(RESOLUTIONS[args.resolution])
    setup = (
        f"FSI3, {args.resolution} mesh ({cells} cells), time step {args.time_step:g} s, "
        f"{SOLID_NAMES[args.solid]} solid of degree {args.degree}"
        + (f" ({args.load} load)" if args.load else "")
        + f", to t = {end:g} s"
    )
    print(setup)
    print(f"wall-clock: {seconds:.0f} s")
    if args.smoke:
        problems = _smoke_check(series, args.time_step, end)
        for problem in problems:
            print(f"smoke run: {problem}", file=sys.stderr)
        print("smoke run: every output in place" if not problems else "smoke run failed")
        return 1 if problems else 0
    figures = compare(series, args.window)
    ok = all(row["within"] for row in figures.values())
    table = _table(figures)
    print(table)
    print("every figure within its tolerance" if ok else "a figure misses its tolerance")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        record = {
            "setup": setup,
            "resolution": args.resolution,
            "cells": cells,
            "time_step": args.time_step,
            "degree": args.degree,
            "solid": args.solid,
            **({"load": args.load} if args.load else {}),
            "end_time": end,
            "window": args.window,
            "reference": "Turek & Hron (2006), FSI3",
            "figures": figures,
            "wall_clock_s": round(seconds, 1),
            "within": ok,
        }
        args.json.write_text(json.dumps(record, indent=2) + "\n")
        cost = f"wall-clock: {seconds:.0f} s"
        args.json.with_suffix(".md").write_text(f"{setup}\n\n{table}\n\n{cost}\n")
    if args.figure is not None:
        _plot(series, args.window, args.figure)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
