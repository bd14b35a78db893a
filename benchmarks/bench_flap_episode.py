"""Benchmark of one episode of the flap's training case: where its time goes, and what a
second environment on the second core costs.

1. **Cost split.** One uncontrolled episode of PerpendicularFlapFast-v0 (1 s gust, 3 s
   episode) from a held-out start, then the preCICE profiling files that each participant
   wrote (``precice-profiling/<Participant>-0-1.txt``, preCICE's "fundamental" events):
   per participant its own work (``solver.advance``: between two ``advance`` calls), the
   time in ``advance`` (waiting for the others, data exchange, mapping, quasi-Newton) and
   the set-up (``initialize``), and the coupling iterations per window
   (``precice-Fluid-iterations.log``).
2. **One environment against two.** The wall-clock of that episode alone, beside the
   same episode run by two environments at once (two processes): with serial-implicit
   coupling the fluid and the solid mostly wait for each other, so a second environment
   should cost little.

``--solid fenics`` runs the FEniCS solid instead of deal.II's (its profiling file lies in
``solid-fenics/``); ``--alone`` skips the second part.

Run: ``python benchmarks/bench_flap_episode.py [--solid dealii|fenics] [--alone]`` (needs
the real stack: preCICE, OpenFOAM with the adapter, the deal.II adapter's ``elasticity`` or
the FEniCS solver environment). Prints figures; it is not a test.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import re
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np


def profile_totals(path: Path) -> dict[str, float]:
    """Seconds per event name of one preCICE profiling file (events ``N``/``B``/``E``)."""
    names: dict[str, str] = {}
    open_at: dict[str, list[int]] = defaultdict(list)
    totals: dict[str, float] = defaultdict(float)
    for line in path.read_text().splitlines():
        match = re.match(r"^([NBE])(\d+):(.*)$", line)
        if not match:
            continue
        kind, ident, rest = match.groups()
        if kind == "N":
            names[ident] = rest
        elif kind == "B":
            open_at[ident].append(int(rest))
        elif open_at[ident]:
            totals[names.get(ident, ident)] += (int(rest) - open_at[ident].pop()) / 1e6
    return dict(totals)


def episode(run_root: str, seed: int = 0, solid: str = "dealii") -> tuple[float, Path]:
    """One uncontrolled episode from held-out start ``seed``; (wall-clock s, env dir)."""
    import gymprecice  # noqa: F401  (registers the ids)
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    env = PerpendicularFlapFastEnv(run_root=run_root, uncontrolled=True, solid=solid)
    try:
        env.reset(seed=0, options={"split": "eval"})  # prepares the case (mesh) once
        started = time.perf_counter()
        env.reset(seed=seed, options={"split": "eval"})
        while True:
            *_, terminated, truncated, _ = env.step(np.array([2.0], np.float32))
            if terminated or truncated:
                break
        return time.perf_counter() - started, env.env_dir
    finally:
        env.close()


def _episode_in_process(args: tuple[str, int, str]) -> float:
    return episode(*args)[0]


def main(argv: list[str] | None = None) -> int:
    from gymprecice_tutorials.perpendicular_flap.packaged_case import SOLIDS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solid", choices=sorted(SOLIDS), default="dealii")
    parser.add_argument("--alone", action="store_true", help="skip the two-environment run")
    args = parser.parse_args(argv)
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"solid: {args.solid}; load average before: {load}")
    with tempfile.TemporaryDirectory() as root:
        alone, env_dir = episode(str(Path(root) / "alone"), 0, args.solid)
        print(f"one episode (1 s gust + 3 s), one environment: {alone:.1f} s wall-clock")
        print(
            f"{'participant':<12}{'own work':>10}{'in advance':>12}{'initialize':>12}{'total':>9}"
        )
        for participant, folder in (
            ("Fluid", "fluid-openfoam"),
            ("Solid", SOLIDS[args.solid]),
            ("Controller", "."),
        ):
            files = sorted((env_dir / folder / "precice-profiling").glob(f"{participant}-*.txt"))
            if not files:
                print(f"{participant:<12} no profiling file")
                continue
            t = profile_totals(files[-1])
            print(
                f"{participant:<12}{t.get('solver.advance', 0):>9.2f}s"
                f"{t.get('advance', 0):>11.2f}s{t.get('initialize', 0):>11.2f}s"
                f"{t.get('_GLOBAL', 0):>8.2f}s"
            )
        iterations = env_dir / "fluid-openfoam" / "precice-Fluid-iterations.log"
        if iterations.is_file():
            rows = np.loadtxt(iterations, skiprows=1, ndmin=2)
            print(
                f"coupling iterations per window: mean {rows[:, 2].mean():.2f}, "
                f"max {rows[:, 2].max():.0f} over {len(rows)} windows"
            )
        load = " ".join(f"{x:.1f}" for x in os.getloadavg())
        print(f"load average after: {load}")
        if args.alone:
            return 0
        with multiprocessing.get_context("spawn").Pool(2) as pool:
            started = time.perf_counter()
            pair = pool.map(
                _episode_in_process,
                [(str(Path(root) / f"pair{i}"), 0, args.solid) for i in (0, 1)],
            )
            both = time.perf_counter() - started
        print(
            f"two environments at once: episodes {pair[0]:.1f} s and {pair[1]:.1f} s "
            f"(pool wall-clock {both:.1f} s with each one's mesh set-up); one alone {alone:.1f} s; "
            f"throughput x{2 * alone / max(pair):.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
