"""Benchmark of the flap's two observation routes: the watch-point file against preCICE.

PerpendicularFlapFast-v0 can read the tip's state from the solid's watch-point log
(``observe="watchpoint"``, the default) or through preCICE itself
(``observe="precice"``: one-vertex controller meshes at the tip, the solid's displacement
and the fluid's force mapped onto them). This runs the same episodes both ways, the same
actions from the same held-out starts, and prints side by side:

* **cost**: wall-clock per episode (gust and episode, after a first reset that builds the
  mesh), and the seconds per step the controller waited for the solvers (``wait_s``);
* **staleness**: the simulated time of the state each step observes. Both routes see the
  converged state of the step's last window, so they must agree with the env's clock; the
  watch point's row time and the preCICE read time are compared with ``env.time``;
* **agreement**: the largest difference between the two routes' tip displacement at the
  same instant (the preCICE route's nearest solid vertex against the watch point's
  interpolation at the tip), and the ratio of their forces (the fluid's face force
  nearest the tip against the solid's nodal force there).

Run: ``python benchmarks/bench_flap_observation_routes.py [--episodes 3]`` (needs the real
stack). Prints figures; it is not a test.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def run(observe: str, root: str, episodes: int) -> dict[str, list[float]]:
    """``episodes`` episodes from held-out starts 0, 1, ..., a sinusoidal jet centre."""
    from gymprecice_tutorials.perpendicular_flap.fast import PerpendicularFlapFastEnv

    env = PerpendicularFlapFastEnv(run_root=root, observe=observe)
    out: dict[str, list[float]] = {
        "episode_s": [],
        "wait_s": [],
        "lag_s": [],
        "dx_diff": [],
        "force_ratio": [],
    }
    try:
        env.reset(seed=0, options={"split": "eval"})  # builds the mesh once
        for k in range(episodes):
            started = time.perf_counter()
            env.reset(seed=k, options={"split": "eval"})
            step = 0
            while True:
                centre = 2.0 + 0.75 * np.sin(2 * np.pi * 0.6 * step * 0.1)
                obs, _, terminated, truncated, info = env.step(np.array([centre], np.float32))
                step += 1
                out["wait_s"].append(info["timing"]["wait_s"])
                row = env._tip.data[-1:]  # the watch point's last row: what it shows now
                watched_time = float(row[0, 0])
                out["lag_s"].append(env.time - watched_time)
                watched_d = env._tip.field("Displacement", row)[0]
                watched_f = env._tip.field("Force", row)[0]
                out["dx_diff"].append(float(np.max(np.abs(obs[:2] - watched_d))))
                if observe == "precice" and np.linalg.norm(watched_f) > 0:
                    out["force_ratio"].append(
                        float(np.linalg.norm(obs[4:6]) / np.linalg.norm(watched_f))
                    )
                if terminated or truncated:
                    break
            out["episode_s"].append(time.perf_counter() - started)
    finally:
        env.close()
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as root:
        results = {
            observe: run(observe, str(Path(root) / observe), args.episodes)
            for observe in ("watchpoint", "precice")
        }
    print(f"{'':<34}{'watchpoint':>14}{'precice':>14}")
    for label, key, fmt in (
        ("wall-clock per episode (s)", "episode_s", "{:.2f}"),
        ("controller wait per step (s)", "wait_s", "{:.3f}"),
        ("watch point behind env.time (s)", "lag_s", "{:.3f}"),
        ("max |d_obs - d_watchpoint| (m)", "dx_diff", "{:.2e}"),
    ):
        cells = [
            fmt.format(float(np.mean(results[o][key])))
            if key != "dx_diff"
            else fmt.format(float(np.max(results[o][key])))
            for o in ("watchpoint", "precice")
        ]
        print(f"{label:<34}{cells[0]:>14}{cells[1]:>14}")
    spread = np.std(results["watchpoint"]["episode_s"]), np.std(results["precice"]["episode_s"])
    print(f"{'episode spread (s, std)':<34}{spread[0]:>14.2f}{spread[1]:>14.2f}")
    ratios = results["precice"]["force_ratio"]
    if ratios:
        print(
            f"|f| preCICE route / watch point: median {np.median(ratios):.2f} "
            f"(range {min(ratios):.2f} to {max(ratios):.2f})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
