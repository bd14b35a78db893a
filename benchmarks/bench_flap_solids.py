"""The flap's two solids, deal.II and FEniCS, side by side: the uncontrolled swing's figures.

One uncontrolled episode of PerpendicularFlapFast-v0 (1 s held-out gust, 3 s of the
reference inflow) with each solid, and the figures of
:mod:`gymprecice_tutorials.perpendicular_flap.swing`: the first peak of the tip's ``dx``
and its time, the period, the mean tip displacement; then their differences against
:data:`~gymprecice_tutorials.perpendicular_flap.swing.SOLID_AGREEMENT`, the bounds that
``tests/test_flap_solids_real.py`` holds them to, and each run's wall-clock.

``--alpha AM AF`` runs the FEniCS solid with other generalized-alpha parameters (the
preCICE tutorial's are ``0.2 0.4``), to see what a difference of time integration does.

Run: ``python benchmarks/bench_flap_solids.py [--start K] [--alpha AM AF]`` (needs the
real stack: preCICE, OpenFOAM with the adapter, the deal.II adapter's ``elasticity``, the
FEniCS solver environment). Prints figures; it is not a test.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ALPHA_LINE = "alpha_m, alpha_f = 0.0, 0.0"


def fenics_with_alpha(run_root: Path, alpha: tuple[float, float], start: int):
    """The uncontrolled swing of the FEniCS solid with generalized-alpha ``alpha``."""
    from gymprecice_tutorials.case_files import write_case_files
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv
    from gymprecice_tutorials.perpendicular_flap.swing import swing_figures
    from gymprecice_tutorials.perpendicular_flap.training_case import fast_case_files

    files = fast_case_files(4.0, solid="fenics")
    script = files["solid-fenics/solid.py"]
    if script.count(ALPHA_LINE) != 1:
        raise SystemExit(f"solid.py no longer has {ALPHA_LINE!r}: update this benchmark")
    files["solid-fenics/solid.py"] = script.replace(
        ALPHA_LINE, f"alpha_m, alpha_f = {alpha[0]!r}, {alpha[1]!r}"
    )
    case = write_case_files("perpendicular-flap-fast-fenics-alpha", files, run_root)
    env = PerpendicularFlapFastEnv(case, solid="fenics", uncontrolled=True, run_root=run_root)
    try:
        env.reset(seed=start, options={"split": "eval", "start": start})
        while True:
            *_, terminated, truncated, _ = env.step(np.array([2.0], np.float32))
            if terminated or truncated:
                break
        tip = env.open_output(env.SOLID, "watchpoint", point=env.WATCH_POINT)
        t, d = tip.field("Time"), tip.field("Displacement")
    finally:
        env.close()
    return swing_figures(t, d[:, 0], np.linalg.norm(d, axis=1), env.settle_time)


def main(argv: list[str] | None = None) -> int:
    from gymprecice_tutorials.perpendicular_flap.swing import SOLID_AGREEMENT, uncontrolled_swing

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start", type=int, default=0, help="held-out gust (0, 1 or 2)")
    parser.add_argument("--alpha", type=float, nargs=2, metavar=("AM", "AF"), default=None)
    args = parser.parse_args(argv)
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    runs = {}
    with tempfile.TemporaryDirectory() as root:
        for solid in ("dealii", "fenics"):
            started = time.perf_counter()
            if solid == "fenics" and args.alpha is not None:
                figures = fenics_with_alpha(Path(root) / solid, tuple(args.alpha), args.start)
            else:
                figures, _ = uncontrolled_swing(solid, Path(root) / solid, args.start)
            runs[solid] = (figures, time.perf_counter() - started)
    label = "fenics" if args.alpha is None else f"fenics a={args.alpha[0]:g},{args.alpha[1]:g}"
    print(f"held-out gust {args.start}, uncontrolled, PerpendicularFlapFast-v0")
    print(f"{'figure':<20}{'dealii':>10}{label:>22}{'difference':>12}{'bound':>8}")
    dealii, fenics = runs["dealii"][0], runs["fenics"][0]
    for name, bound in SOLID_AGREEMENT._asdict().items():
        a, b = getattr(dealii, name), getattr(fenics, name)
        verdict = "" if abs(a - b) <= bound else "  OUT"
        print(f"{name:<20}{a:>10.5f}{b:>22.5f}{abs(a - b):>12.5f}{bound:>8g}{verdict}")
    print(
        f"wall-clock per run (case set-up, 1 s gust, 3 s episode): deal.II "
        f"{runs['dealii'][1]:.1f} s, FEniCS {runs['fenics'][1]:.1f} s; load average after: "
        f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
