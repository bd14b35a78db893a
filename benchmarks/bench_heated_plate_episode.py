"""Benchmark of one HeatedPlate-v0 episode with each plate: its cost and its physics.

For the OpenFOAM plate (laplacianFoam) and then the FEniCS plate (the FEniCS script in its
solver environment), one uncontrolled episode (heater at the tutorial's 310 K; 0.3 s of
settling, 2 s episode) from held-out start 0, then:

1. **Cost split.** The wall-clock of the reset (solvers launched, coupling set up, 0.3 s
   of settling) and of the whole episode, and per participant, from the preCICE profiling
   files each wrote (``precice-profiling/<Participant>-*.txt``): its own work
   (``solver.advance``), the time in ``advance`` (waiting for the others, exchange,
   mapping, Aitken) and ``initialize``; and the coupling iterations per window.
2. **Same physics.** The mean interface temperature after each step, and the fluid's
   watch point ``Plate-Middle`` (temperature and heat flux at x = 0.5 on the interface,
   every window), compared between the two plates.

Run: ``python benchmarks/bench_heated_plate_episode.py`` (needs the real stack: preCICE,
OpenFOAM with the adapter, and ``gymprecice install fenics``). Prints figures; not a test.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_flap_episode import profile_totals


def episode(solid: str, run_root: str) -> dict:
    import gymprecice  # noqa: F401  (registers the ids)
    from gymprecice.plugin.watchpoints import WatchPointLog, watch_point_file_name
    from gymprecice_tutorials.heated_plate.environment import SOLIDS, HeatedPlateEnv

    env = HeatedPlateEnv(solid=solid, uncontrolled=True, run_root=run_root)
    try:
        started = time.perf_counter()
        obs, _ = env.reset(seed=0, options={"split": "eval"})
        reset_s = time.perf_counter() - started
        temperatures = [float(obs[0]) + env.start.setpoint]
        while True:
            *_, terminated, truncated, info = env.step(np.array([310.0], np.float32))
            temperatures.append(info["metrics"]["interface_temperature"])
            if terminated or truncated:
                break
        wall = time.perf_counter() - started
        env_dir = env.env_dir
    finally:
        env.close()
    log = WatchPointLog(env_dir / "fluid-openfoam" / watch_point_file_name("Fluid", "Plate-Middle"))
    log.read_new()
    profiles = {}
    for participant, folder in (
        ("Fluid", "fluid-openfoam"),
        ("Solid", SOLIDS[solid]),
        ("Controller", "."),
    ):
        files = sorted((env_dir / folder / "precice-profiling").glob(f"{participant}-*.txt"))
        profiles[participant] = profile_totals(files[-1]) if files else {}
    rows = np.loadtxt(
        env_dir / "fluid-openfoam" / "precice-Fluid-iterations.log", skiprows=1, ndmin=2
    )
    return {
        "wall": wall,
        "reset": reset_s,
        "T": np.asarray(temperatures),
        "time": log.field("Time"),
        "wp_T": log.field("Temperature"),
        "wp_q": log.field("Heat-Flux"),
        "profiles": profiles,
        "iterations": (rows[:, 2].mean(), rows[:, 2].max(), len(rows)),
    }


def main() -> int:
    results = {}
    with tempfile.TemporaryDirectory() as root:
        for solid in ("openfoam", "fenics"):
            r = results[solid] = episode(solid, str(Path(root) / solid))
            print(
                f"{solid} plate: episode {r['wall']:.1f} s wall-clock (reset with settling "
                f"{r['reset']:.1f} s); coupling iterations per window: mean "
                f"{r['iterations'][0]:.2f}, max {r['iterations'][1]:.0f} over {r['iterations'][2]}"
            )
            print(
                f"  {'participant':<12}{'own work':>10}{'in advance':>12}{'initialize':>12}{'total':>9}"
            )
            for participant, t in r["profiles"].items():
                print(
                    f"  {participant:<12}{t.get('solver.advance', 0):>9.2f}s"
                    f"{t.get('advance', 0):>11.2f}s{t.get('initialize', 0):>11.2f}s"
                    f"{t.get('_GLOBAL', 0):>8.2f}s"
                )
    a, b = results["openfoam"], results["fenics"]
    print("mean interface temperature (K) after settling and each step:")
    print("  openfoam", np.round(a["T"], 4).tolist())
    print("  fenics  ", np.round(b["T"], 4).tolist())
    print(f"  max |difference| {np.max(np.abs(a['T'] - b['T'])):.4f} K")
    n = min(len(a["time"]), len(b["time"]))
    late = a["time"][:n] >= 0.3 - 1e-9  # the episode, after settling
    dT = np.abs(a["wp_T"][:n] - b["wp_T"][:n])[late]
    dq = np.abs(a["wp_q"][:n] - b["wp_q"][:n])[late]
    q = np.abs(a["wp_q"][:n][late]).max()
    print(
        f"watch point Plate-Middle over the episode: max |dT| {dT.max():.4f} K, max |dq| "
        f"{dq.max():.2f} W/m² ({100 * dq.max() / q:.3f} % of max |q| {q:.0f} W/m²)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
