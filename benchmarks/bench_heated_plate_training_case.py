"""Benchmark of the heated plate's training case against HeatedPlate-v0: cost and fidelity.

For HeatedPlate-v0 (12,013 fluid cells, serial-implicit with Aitken, 0.01 s windows) and
variants of its training case (:func:`gymprecice_tutorials.heated_plate.fast.fast_case_files`:
825 fluid cells; explicit or implicit coupling; 0.01 s or 0.05 s windows), one episode
from held-out start 1 with the heater held at 310 K (uncontrolled) and one with the heater
stepped to 330 K (the response a controller acts through). Prints, side by side, the
wall-clock of each episode (reset with 0.3 s of settling, then 20 steps) and the largest
and mean difference of the mean interface temperature from HeatedPlate-v0's, step by step.

Run: ``python benchmarks/bench_heated_plate_training_case.py`` (needs preCICE and OpenFOAM
with the adapter). Prints figures; not a test.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

#: (label, fast_case_files keywords; None: HeatedPlate-v0's own case)
VARIANTS: tuple[tuple[str, dict | None], ...] = (
    ("HeatedPlate-v0 (12,013 cells, implicit, 0.01 s)", None),
    ("training case (825 cells, explicit, 0.01 s)", {}),
    ("825 cells, implicit, 0.01 s", {"explicit": False}),
    ("825 cells, explicit, 0.05 s", {"window": 0.05}),
    ("825 cells, implicit, 0.05 s", {"window": 0.05, "explicit": False}),
)
END_TIME = 2.3


def episode(files: dict[str, str], name: str, heater: float, root: str) -> tuple[float, list]:
    """Wall-clock and interface temperatures of one constant-heater episode."""
    from gymprecice_tutorials.case_files import write_case_files
    from gymprecice_tutorials.heated_plate.environment import HeatedPlateEnv, run_constant

    env = HeatedPlateEnv(write_case_files(name, files, root), run_root=root)
    try:
        started = time.perf_counter()
        result = run_constant(env, heater, seed=1)
        return time.perf_counter() - started, list(result["temperature"])
    finally:
        env.close()


def main() -> int:
    import gymprecice  # noqa: F401  (registers the ids)
    from gymprecice_tutorials.heated_plate.environment import case_files
    from gymprecice_tutorials.heated_plate.fast import fast_case_files

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--heaters", default="310,330", help="constant heaters (K)")
    args = parser.parse_args()
    heaters = [float(h) for h in args.heaters.split(",")]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-plate-") as root:
        for label, keywords in VARIANTS:
            files = (
                case_files("openfoam", END_TIME)
                if keywords is None
                else fast_case_files(END_TIME, **keywords)
            )
            for heater in heaters:
                wall, temperatures = episode(files, f"variant-{len(rows)}", heater, root)
                rows.append((label, heater, wall, np.asarray(temperatures)))
                print(f"  {label}, heater {heater:g} K: {wall:.1f} s", flush=True)
    reference = {heater: t for label, heater, _, t in rows if label == VARIANTS[0][0]}
    print()
    print("| case | heater | episode wall-clock | max abs(T - T_full) | mean abs(T - T_full) |")
    print("| --- | --- | --- | --- | --- |")
    for label, heater, wall, temperatures in rows:
        gap = np.abs(temperatures - reference[heater])
        print(f"| {label} | {heater:g} K | {wall:.1f} s | {gap.max():.3f} K | {gap.mean():.3f} K |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
