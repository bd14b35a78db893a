"""Validation of the flap's coupled simulation against preCICE's published tip series.

Runs ``PerpendicularFlap-v0`` with ``setup="precice"`` (preCICE's own perpendicular-flap
tutorial, :mod:`.precice_setup`) uncontrolled, the inflow held at 10 m/s, with the deal.II
solid, the FEniCS solid or both, and compares the tip's watch-point series with preCICE's
published one (:data:`~.tip_figures.PUBLISHED`) figure by figure, each within its stated
tolerance (:data:`~.tip_figures.TOLERANCE`)::

    python -m gymprecice_tutorials.perpendicular_flap.validate [--solid dealii|fenics|both]
        [--smoke] [--end-time S] [--reference LOG] [--out DIR] [--json FILE] [--figure PNG]

The full run simulates the tutorial's 5 s. ``--smoke`` stops at 1.2 s and compares the
first peak and its time only (CI). ``--reference`` compares with a preCICE watch-point
log instead of the published series, e.g. ``precice-Solid-watchpoint-Flap-Tip.log`` of
preCICE's reference results. Exits 1 when a figure misses its tolerance, 2 on bad input.
Needs the real stack (OpenFOAM, preCICE and the solid).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time as clock
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice_tutorials.perpendicular_flap.tip_figures import (
    RELATIVE,
    TOLERANCE,
    TipFigures,
    published_series,
    tip_figures,
)

__all__ = ["compare", "main", "run_uncontrolled"]

#: simulated seconds of the full run (the tutorial's) and of the smoke run
FULL_END = 5.0
SMOKE_END = 1.2
#: the figures a smoke run compares (the others need the whole run)
SMOKE_FIGURES = ("first_peak", "first_peak_time")
#: the inflow of preCICE's tutorial (m/s)
INFLOW = 10.0


def run_uncontrolled(
    solid: str, end_time: float = FULL_END, run_root: str | Path | None = None
) -> tuple[np.ndarray, float]:
    """Run preCICE's setup with ``solid`` to ``end_time`` (at most the tutorial's 5 s);
    the tip's watch-point rows ``(time, dx, dy)`` and the run's wall-clock (s)."""
    from gymprecice_tutorials.perpendicular_flap.environment import PerpendicularFlapEnv

    started = clock.monotonic()
    env = PerpendicularFlapEnv(solid=solid, setup="precice", run_root=run_root)
    try:
        env.reset(seed=0)
        action = np.array([INFLOW], dtype=np.float32)
        while env.time < end_time - 1e-9:
            *_, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        tip = env.open_output(env.SOLID, "watchpoint", point=env.WATCH_POINT)
        tip.read_new()
        rows = np.column_stack([tip.field("Time"), tip.field("Displacement")])
    finally:
        env.close()
    return rows[rows[:, 0] <= end_time + 1e-9], clock.monotonic() - started


def read_watch_point_log(path: Path) -> np.ndarray:
    """Rows ``(time, dx, dy)`` of a preCICE watch-point log (its ``Time`` and
    ``Displacement0/1`` columns)."""
    lines = path.read_text().splitlines()
    header = lines[0].split()
    try:
        columns = [header.index(name) for name in ("Time", "Displacement0", "Displacement1")]
    except ValueError:
        raise ValueError(
            f"{path}: not a preCICE watch-point log (no Time and Displacement0/1 "
            f"columns in its header {header})"
        ) from None
    table = np.array([[float(v) for v in line.split()] for line in lines[1:] if line.strip()])
    return table[:, columns]


def compare(
    figures: TipFigures, reference: TipFigures, names: Sequence[str] = TipFigures._fields
) -> dict[str, dict[str, Any]]:
    """Each figure of ``names``: the run's, the reference's, the difference, the
    tolerance (relative ones as a share of the reference) and whether it is within."""
    table = {}
    for name in names:
        ours, ref = getattr(figures, name), getattr(reference, name)
        bound = getattr(TOLERANCE, name) * (abs(ref) if getattr(RELATIVE, name) else 1.0)
        within = bool(math.isfinite(ours) and abs(ours - ref) <= bound)
        table[name] = {
            "run": ours,
            "reference": ref,
            "difference": ours - ref,
            "tolerance": bound,
            "within": within,
        }
    return table


def _table(results: dict[str, dict[str, dict[str, Any]]]) -> str:
    units = {"first_peak_time": "s", "period": "s"}
    names = next(iter(results.values())).keys()
    head = "| figure | reference | " + " | ".join(results) + " | tolerance |"
    lines = [head, "|" + " --- |" * (len(results) + 3)]
    for name in names:
        unit = units.get(name, "m")
        ref = next(iter(results.values()))[name]
        cells = [
            f"{r[name]['run']:.4f} ({r[name]['difference']:+.4f}"
            f"{'' if r[name]['within'] else ', OUT'})"
            for r in results.values()
        ]
        lines.append(
            f"| {name} ({unit}) | {ref['reference']:.4f} | "
            + " | ".join(cells)
            + f" | ±{ref['tolerance']:.4f} |"
        )
    return "\n".join(lines)


def _plot(series: dict[str, np.ndarray], reference: np.ndarray, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.2))
    ax.plot(reference[:, 0], reference[:, 1], "k.", ms=2.5, label="preCICE, published")
    for label, rows in series.items():
        ax.plot(rows[:, 0], rows[:, 1], lw=1.4, label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("flap tip x-displacement (m)")
    ax.grid(alpha=0.3)
    fig.legend(loc="lower center", ncol=len(series) + 1, frameon=False)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m gymprecice_tutorials.perpendicular_flap.validate`` (module docstring)."""
    parser = argparse.ArgumentParser(
        prog="python -m gymprecice_tutorials.perpendicular_flap.validate",
        description=__doc__.split("\n\n")[0],
    )
    parser.add_argument("--solid", choices=("dealii", "fenics", "both"), default="dealii")
    parser.add_argument("--smoke", action="store_true", help="to 1.2 s, the first peak only")
    parser.add_argument("--end-time", type=float, help="simulated seconds (at most 5)")
    parser.add_argument("--reference", type=Path, help="a preCICE watch-point log to compare with")
    parser.add_argument(
        "--out", type=Path, help="where the runs are made (default: a temporary one)"
    )
    parser.add_argument(
        "--json", type=Path, help="write the comparison here (and its table beside, as .md)"
    )
    parser.add_argument("--figure", type=Path, help="draw the series overlaid here")
    args = parser.parse_args(argv)
    end = args.end_time or (SMOKE_END if args.smoke else FULL_END)
    if not 0.0 < end <= FULL_END:
        parser.error(f"--end-time must lie in (0, {FULL_END:g}] s, got {end:g}")
    if args.reference is not None:
        if not args.reference.is_file():
            parser.error(f"--reference {args.reference}: no such file")
        reference_rows = read_watch_point_log(args.reference)[:, :2]
        source = str(args.reference)
    else:
        reference_rows, source = published_series(), "preCICE's published figure"
    names = SMOKE_FIGURES if end < FULL_END else TipFigures._fields
    reference = tip_figures(*reference_rows[reference_rows[:, 0] <= end + 1e-9].T)
    solids = ("dealii", "fenics") if args.solid == "both" else (args.solid,)
    results, series, costs = {}, {}, {}
    for solid in solids:
        root = None if args.out is None else args.out / solid
        if root is None:
            import tempfile

            root = Path(tempfile.mkdtemp(prefix=f"flap-validation-{solid}-"))
        rows, seconds = run_uncontrolled(solid, end, root)
        series[f"OpenFOAM-{solid}"] = rows[:, :2]
        costs[solid] = round(seconds, 1)
        try:
            figures = tip_figures(rows[:, 0], rows[:, 1])
        except ValueError as exc:  # no peak at all: every figure fails, and says why
            print(f"{solid}: {exc}", file=sys.stderr)
            figures = TipFigures(*[float("nan")] * len(TipFigures._fields))
        results[solid] = compare(figures, reference, names)
    ok = all(row["within"] for table in results.values() for row in table.values())
    title = f"tip x-displacement of preCICE's perpendicular flap to t = {end:g} s, against {source}"
    print(title)
    print(_table(results))
    cost = "wall-clock: " + ", ".join(f"{s} {c:g} s" for s, c in costs.items())
    print(cost)
    print("every figure within its tolerance" if ok else "a figure misses its tolerance")
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                {
                    "setup": "PerpendicularFlap-v0, setup='precice', inflow 10 m/s",
                    "end_time": end,
                    "reference": source,
                    "figures": results,
                    "wall_clock_s": costs,
                    "within": ok,
                },
                indent=2,
            )
            + "\n"
        )
        args.json.with_suffix(".md").write_text(f"{title}\n\n{_table(results)}\n\n{cost}\n")
    if args.figure is not None:
        _plot(series, reference_rows, args.figure)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
