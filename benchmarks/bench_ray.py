"""Benchmark of the Ray backend against the local pool, side by side, and a cluster projection.

Runs the same envs through :class:`gymprecice.sb3.ResilientSubprocVecEnv` twice, once with
its envs as local worker processes and once as Ray actors (a local Ray instance), and
prints, in one run:

* throughput (env steps per second) with 1, 2 and 4 envs on an emulated solver that
  sleeps 10 ms per step: real gymprecice envs (Adapter, coupling worker, preCICE double,
  solver process) and a plain env whose step sleeps (the backends alone);
* Ray's overhead per batch step against the local pool, in % (target: at most 5 %), and
  the scaling ``throughput(n) / (n * throughput(1))`` (target: at least 90 % up to the
  cores available);
* the projected wall-clock of the full jet-cylinder recipe (docs/training.md: 1,250
  episodes of 2 s, 2 min 16 s each on one env of 2 MPI ranks) on N nodes of 16 cores,
  from that per-episode cost and the measured Ray overhead.

Usage: ``python benchmarks/bench_ray.py [--steps 200] [--envs 1 2 4] [--sleep 0.01]``.
Ray gets as many logical CPUs as the largest env count, so envs beyond the machine's
cores share them (and cannot scale linearly); the header prints cores and load.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_vector import WARMUP, SleepEnv, _env_fns

#: the jet-cylinder recipe of docs/training.md
EPISODES = 1250
EPISODE_S = 2 * 60 + 16
ACTIONS_PER_EPISODE = 80
CORES_PER_ENV = 2


def _make(backend: str, fns: list[Callable[[], Any]], log_dir: Path) -> Any:
    from gymprecice.learners.sb3 import ResilientSubprocVecEnv

    chosen: Any = None
    if backend == "ray":
        from gymprecice.vector.ray import RayBackend

        chosen = RayBackend(num_cpus=1)
    return ResilientSubprocVecEnv(
        fns, log_dir=log_dir, step_timeout=120, reset_timeout=300, backend=chosen
    )


def _throughput(backend: str, case: Path | float, work: Path, n: int, steps: int) -> float:
    if isinstance(case, Path):
        tag = f"{backend}-{case.name}-{n}"
        fns = _env_fns(case, work / "runs" / tag, n)
    else:
        tag = f"{backend}-plain-{n}"
        fns = [functools.partial(SleepEnv, case, 0.0) for _ in range(n)]
    venv = _make(backend, fns, work / "logs" / tag)
    try:
        venv.reset()
        actions = np.zeros((n, 1), dtype=np.float32)
        for _ in range(WARMUP):
            venv.step(actions)
        started = time.perf_counter()
        for _ in range(steps):
            _, _, dones, _ = venv.step(actions)
            assert not dones.any(), "an episode ended during the measurement"
        return n * steps / (time.perf_counter() - started)
    finally:
        venv.close()


def _row(label: str, values: list[str]) -> str:
    return f"  {label:<38}" + "".join(f"{v:>11}" for v in values)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=200, help="batch steps measured per run")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--sleep", type=float, default=0.01, help="emulated solver step (s)")
    parser.add_argument("--nodes", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    args = parser.parse_args(argv)
    os.environ.setdefault("GYMPRECICE_DISABLE_PLUGINS", "1")  # faster solver starts
    import ray

    from gymprecice.testing.chaos import write_case

    ray.init(num_cpus=max(args.envs), include_dashboard=False, log_to_driver=False)
    cores = os.cpu_count() or 1
    windows = WARMUP + args.steps + 5
    label_solver = f"{args.sleep * 1e3:g} ms solver"
    label_plain = f"plain env, {args.sleep * 1e3:g} ms step"
    results: dict[tuple[str, str, int], float] = {}
    try:
        with tempfile.TemporaryDirectory(prefix="bench-ray-") as tmp:
            work = Path(tmp)
            cases: dict[str, Path | float] = {
                label_solver: write_case(
                    work / "sleep",
                    work / "faults",
                    end_time=windows * 0.01,
                    windows_per_step=1,
                    step_sleep=args.sleep,
                    write_outputs=False,
                ),
                label_plain: args.sleep,
            }
            for label, case in cases.items():
                for n in args.envs:
                    for backend in ("local", "ray"):
                        rate = _throughput(backend, case, work, n, args.steps)
                        results[label, backend, n] = rate
                        print(f"  measured {label}, {backend}, {n} env(s): {rate:.1f} steps/s",
                              file=sys.stderr, flush=True)  # fmt: skip
    finally:
        ray.shutdown()

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\ngymprecice Ray backend benchmark: {cores} cores, load average {load:.1f}, "
          f"{args.steps} batch steps per run\n")  # fmt: skip
    print(_row("throughput [env steps/s]", [f"n={n}" for n in args.envs] + ["scaling"]))
    overheads: dict[str, list[float]] = {}
    for label in (label_solver, label_plain):
        for backend in ("local", "ray"):
            rates = [results[label, backend, n] for n in args.envs]
            base = rates[0] / args.envs[0]
            scaling = [
                f"{100 * r / (n * base):.0f}%" for r, n in zip(rates, args.envs) if n > args.envs[0]
            ]
            print(_row(f"{label}: {backend}", [f"{r:.1f}" for r in rates] + ["/".join(scaling)]))
        overheads[label] = [
            100 * (results[label, "local", n] / results[label, "ray", n] - 1) for n in args.envs
        ]
        print(_row(f"{label}: Ray overhead per step", [f"{o:+.1f}%" for o in overheads[label]]))
    print()
    within = [i for i, n in enumerate(args.envs) if n <= cores]
    overhead = max(overheads[label_solver][i] for i in within) if within else math.nan
    print(
        f"  Ray overhead per step, {label_solver}, envs <= cores: {overhead:+.1f}% (target <= 5%)"
    )
    n0 = args.envs[0]
    extra_s = max(
        0.0, n0 / results[label_solver, "ray", n0] - n0 / results[label_solver, "local", n0]
    )
    print(f"  Ray's extra time per step (n={n0}): {extra_s * 1e3:.2f} ms")
    episode_s = EPISODE_S + ACTIONS_PER_EPISODE * extra_s
    print(
        f"\nprojection: jet-cylinder recipe, {EPISODES} episodes of {EPISODE_S} s + "
        f"{ACTIONS_PER_EPISODE} steps x {extra_s * 1e3:.2f} ms of Ray = {episode_s:.1f} s "
        f"({100 * (episode_s / EPISODE_S - 1):.2f}%), one env = {CORES_PER_ENV} cores, "
        "learner time ignored"
    )
    for nodes in args.nodes:
        envs = nodes * 16 // CORES_PER_ENV
        rounds = math.ceil(EPISODES / envs)
        hours = rounds * episode_s / 3600
        print(f"  {nodes:>3} node(s) x 16 cores: {envs:>4} envs, {rounds:>4} episode rounds, "
              f"{hours:6.1f} h")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
