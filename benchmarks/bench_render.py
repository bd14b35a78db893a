"""What ``render_mode="rgb_array"`` costs, side by side with the same episode without it.

    python benchmarks/bench_render.py [--double] [--envs jet,flap,plate] [--episode-time S]

For the jet cylinder (JetCylinderFast-v0), the flap (PerpendicularFlapFast-v0) and the
heated plate (HeatedPlateFast-v0), one episode at a constant action, run twice in one
process: without ``render_mode``, then with it and ``render()`` after every step. Printed
per env:

* the episode's wall-clock without and with rendering (reset and steps, frames included);
* the cost of one frame (the mean of ``render()``: reading the solvers' fields and
  drawing them), in wall-clock and in this process's CPU time (which the machine's other
  load barely changes: compare figures of a busy machine by it);
* the extra disk the solvers write per episode for the frames (the run directory's size
  after the episode, with minus without).

``--double`` runs the test doubles (seconds; no solver needed) instead of the real stack
(OpenFOAM, deal.II: minutes per env on 2 cores). Figures depend on the machine's load;
run it on an idle machine.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gymprecice  # noqa: F401  (registers the ids)

ENVS = {
    "jet": "gymprecice/JetCylinderFast-v0",
    "flap": "gymprecice/PerpendicularFlapFast-v0",
    "plate": "gymprecice/HeatedPlateFast-v0",
}


def _size(root: Path) -> int:
    skip = ".gymprecice-openfoam"  # the stored initial state, the same with and without
    return sum(p.stat().st_size for p in root.rglob("*") if p.is_file() and skip not in p.parts)


def _episode(env_id: str, root: Path, render: bool, kwargs: dict) -> dict[str, float]:
    env = gym.make(
        env_id, run_root=str(root), render_mode="rgb_array" if render else None, **kwargs
    )
    frames: list[float] = []
    cpu: list[float] = []
    try:
        _ = env.unwrapped.run_dir  # prepare outside the timing: the same with and without
        action = np.asarray(
            (env.action_space.low + env.action_space.high) / 2, dtype=env.action_space.dtype
        )
        started = time.perf_counter()
        env.reset(seed=0)
        done = False
        steps = 0
        while True:
            if render:
                t0, c0 = time.perf_counter(), time.process_time()
                env.render()
                frames.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
            if done:
                break
            *_, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
            steps += 1
        seconds = time.perf_counter() - started
        size = _size(Path(env.unwrapped.env_dir))
    finally:
        env.close()
    frame = float(np.mean(frames)) if frames else float("nan")
    frame_cpu = float(np.mean(cpu)) if cpu else float("nan")
    return {
        "seconds": seconds,
        "frame_s": frame,
        "frame_cpu_s": frame_cpu,
        "bytes": size,
        "steps": steps,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--double", action="store_true", help="run on the test doubles")
    parser.add_argument("--envs", default="jet,flap,plate", help="comma-separated: jet,flap,plate")
    parser.add_argument("--episode-time", type=float, default=None, help="simulated seconds")
    args = parser.parse_args()
    kwargs: dict = {"double": True} if args.double else {}
    if args.episode_time is not None:
        kwargs["episode_time"] = args.episode_time
    where = "test double" if args.double else "real solvers"
    print(f"render_mode cost, one episode per env ({where})")
    header = (
        f"{'env':<6} {'actions':>7} {'without [s]':>12} {'with [s]':>10} {'frame [ms]':>11} "
        f"{'frame CPU [ms]':>15} {'extra disk [MB]':>16}"
    )
    print(header)
    print("-" * len(header))
    for name in args.envs.split(","):
        env_id = ENVS[name.strip()]
        with tempfile.TemporaryDirectory(prefix="bench-render-") as tmp:
            plain = _episode(env_id, Path(tmp) / "plain", False, kwargs)
            drawn = _episode(env_id, Path(tmp) / "render", True, kwargs)
        extra = (drawn["bytes"] - plain["bytes"]) / 1e6
        print(
            f"{name:<6} {plain['steps']:>7d} {plain['seconds']:>12.2f} {drawn['seconds']:>10.2f} "
            f"{1e3 * drawn['frame_s']:>11.1f} {1e3 * drawn['frame_cpu_s']:>15.1f} {extra:>16.2f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
