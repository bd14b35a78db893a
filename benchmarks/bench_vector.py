"""Benchmark of the fault-tolerant vector env against SB3's SubprocVecEnv, side by side.

Runs real gymprecice envs (:class:`gymprecice.testing.chaos.CylinderEnv`: Adapter,
coupling worker, the preCICE double and a scripted solver process each) in

* :class:`gymprecice.sb3.ResilientSubprocVecEnv` (this project), and
* :class:`stable_baselines3.common.vec_env.SubprocVecEnv` (the baseline, same envs),

and prints, in one run:

* throughput (env steps per second) with 1, 2 and 4 envs, on a null solver (answers at
  once) and on a solver that sleeps 10 ms per time step (an emulated CFD step), with the
  scaling efficiency ``throughput(n) / (n * throughput(1))``;
* the vector env's own overhead per env step (round trip seen by the learner minus the
  time of ``env.step`` in the worker, from the telemetry), as a fraction of the emulated
  solver step, and the difference of the wall time per batch step against the baseline;
* the reset time of 1 env against N concurrent resets.

Targets: overhead <= 1 % of the solver step, N concurrent resets <= 1.2 x one reset,
>= 90 % linear scaling up to the number of cores.

Usage: ``python benchmarks/bench_vector.py [--steps 200] [--envs 1 2 4] [--sleep 0.01]``.
The numbers depend on the machine and its load (printed in the header): every process
of an env (worker, coupling worker, solver) needs CPU time, so more envs than cores
cannot scale linearly on the null solver.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

WARMUP = 10


class SleepEnv(gym.Env):
    """A plain Gymnasium env whose step (and reset) sleeps like a solver.

    It isolates the vector env from the Adapter's processes, which compete for the CPU.
    """

    observation_space = gym.spaces.Box(-1.0, 1.0, (5,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)

    def __init__(self, step_s: float, reset_s: float) -> None:
        self.step_s, self.reset_s = step_s, reset_s

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        time.sleep(self.reset_s)
        return np.zeros(5, np.float32), {}

    def step(self, action: Any):
        time.sleep(self.step_s)
        info = {"timing": {"wait_s": self.step_s}}
        return np.zeros(5, np.float32), 0.0, False, False, info


def _env_fns(case: Path, runs: Path, n: int) -> list[Callable[[], Any]]:
    from gymprecice.testing.chaos import CylinderEnv

    return [
        functools.partial(CylinderEnv, str(case), i, run_root=str(runs), read_outputs=False)
        for i in range(n)
    ]


def _make(kind: str, fns: list[Callable[[], Any]], log_dir: Path) -> Any:
    if kind == "gymprecice":
        from gymprecice.learners.sb3 import ResilientSubprocVecEnv

        return ResilientSubprocVecEnv(fns, log_dir=log_dir, step_timeout=120, reset_timeout=300)
    from stable_baselines3.common.vec_env import SubprocVecEnv

    return SubprocVecEnv(fns, start_method="forkserver")


def _throughput(kind: str, case: Path | float, work: Path, n: int, steps: int) -> dict[str, float]:
    if isinstance(case, Path):
        tag = f"{kind}-{case.name}-{n}"
        fns = _env_fns(case, work / "runs" / tag, n)
    else:
        tag = f"{kind}-plain-{n}"
        fns = [functools.partial(SleepEnv, case, 0.0) for _ in range(n)]
    venv = _make(kind, fns, work / "logs" / tag)
    try:
        venv.reset()
        actions = np.zeros((n, 1), dtype=np.float32)
        for _ in range(WARMUP):
            venv.step(actions)
        telemetry = getattr(venv, "telemetry", None)
        if telemetry is not None:
            telemetry.drain()
        started = time.perf_counter()
        for _ in range(steps):
            _, _, dones, _ = venv.step(actions)
            assert not dones.any(), "an episode ended during the measurement"
        elapsed = time.perf_counter() - started
        out = {"steps_per_s": n * steps / elapsed, "batch_s": elapsed / steps}
        if telemetry is not None:
            drained = telemetry.drain()
            out["overhead_p50_s"] = drained["vector_overhead_s_p50"]
            out["overhead_mean_s"] = drained["vector_overhead_s_mean"]
            out["env_step_s"] = drained["env_step_s_mean"]
        return out
    finally:
        venv.close()


def _resets(case: Path | float, work: Path, n: int, repeat: int) -> float:
    if isinstance(case, Path):
        tag = f"reset-{n}"
        fns = _env_fns(case, work / "runs" / tag, n)
    else:
        tag = f"reset-plain-{n}"
        fns = [functools.partial(SleepEnv, 0.0, case) for _ in range(n)]
    venv = _make("gymprecice", fns, work / "logs" / tag)
    try:
        venv.reset()  # first reset prepares the run directories
        times = []
        for _ in range(repeat):
            started = time.perf_counter()
            venv.reset()
            times.append(time.perf_counter() - started)
        return statistics.median(times)
    finally:
        venv.close()


def _row(label: str, values: list[str]) -> str:
    return f"  {label:<34}" + "".join(f"{v:>12}" for v in values)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=200, help="batch steps measured per run")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--sleep", type=float, default=0.01, help="emulated solver step (s)")
    parser.add_argument("--reset-repeat", type=int, default=3)
    args = parser.parse_args(argv)
    os.environ.setdefault("GYMPRECICE_DISABLE_PLUGINS", "1")  # faster solver starts
    from gymprecice.testing.chaos import write_case

    cores = os.cpu_count() or 1
    windows = WARMUP + args.steps + 5
    with tempfile.TemporaryDirectory(prefix="bench-vector-") as tmp:
        work = Path(tmp)
        cases: dict[str, Path | float] = {
            "null solver": write_case(
                work / "null",
                work / "faults",
                end_time=windows * 0.01,
                windows_per_step=1,
                flow="gymprecice.testing.flows:NullFlow",
                write_outputs=False,
            ),
            f"{args.sleep * 1e3:g} ms solver": write_case(
                work / "sleep",
                work / "faults",
                end_time=windows * 0.01,
                windows_per_step=1,
                step_sleep=args.sleep,
                write_outputs=False,
            ),
            f"plain env, {args.sleep * 1e3:g} ms step": args.sleep,
        }
        results: dict[tuple[str, str, int], dict[str, float]] = {}
        for label, case in cases.items():
            for n in args.envs:
                for kind in ("gymprecice", "sb3"):
                    results[label, kind, n] = _throughput(kind, case, work, n, args.steps)
                    print(
                        f"  measured {label}, {kind}, {n} env(s): "
                        f"{results[label, kind, n]['steps_per_s']:.1f} env steps/s",
                        file=sys.stderr,
                        flush=True,
                    )
        sleep_case = cases[f"{args.sleep * 1e3:g} ms solver"]
        reset_n = sorted({1, min(cores, max(args.envs)), max(args.envs)})
        reset_times = {n: _resets(sleep_case, work, n, args.reset_repeat) for n in reset_n}
        plain_resets = {n: _resets(0.5, work, n, args.reset_repeat) for n in reset_n}

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print()
    print(
        f"gymprecice vector env benchmark: {cores} cores, load average {load:.1f}, "
        f"{args.steps} batch steps per run, env = Adapter + coupling worker + preCICE double "
        "+ solver process"
    )
    print()
    print(_row("throughput [env steps/s]", [f"n={n}" for n in args.envs] + ["scaling"]))
    for label in cases:
        for kind, name in (("gymprecice", "ResilientSubprocVecEnv"), ("sb3", "SB3 SubprocVecEnv")):
            rates = [results[label, kind, n]["steps_per_s"] for n in args.envs]
            base = rates[0] / args.envs[0]
            scaling = [
                f"{100 * r / (n * base):.0f}%" for r, n in zip(rates, args.envs) if n > args.envs[0]
            ]
            print(_row(f"{label}: {name}", [f"{r:.1f}" for r in rates] + ["/".join(scaling)]))
    print()
    sleep_label = f"{args.sleep * 1e3:g} ms solver"
    plain_label = f"plain env, {args.sleep * 1e3:g} ms step"
    for label in (sleep_label, plain_label):
        _overheads(label, results, args.envs, args.sleep)
    print()
    for label, times in (
        (f"Adapter env, {sleep_label}", reset_times),
        ("plain env, reset sleeps 0.5 s", plain_resets),
    ):
        one = times[1]
        print(f"  reset ({label}): 1 env {one:.2f} s", end="")
        for n in reset_n[1:]:
            print(f"; {n} concurrent {times[n]:.2f} s ({times[n] / one:.2f}x)", end="")
        print()
    print()
    overhead = results[plain_label, "gymprecice", args.envs[0]]["overhead_p50_s"] / args.sleep
    vs_sb3 = (
        results[sleep_label, "gymprecice", args.envs[0]]["batch_s"]
        - results[sleep_label, "sb3", args.envs[0]]["batch_s"]
    ) / args.sleep
    within_cores = [n for n in args.envs if 1 < n <= cores]
    scaling = [
        results[sleep_label, "gymprecice", n]["steps_per_s"]
        / (n * results[sleep_label, "gymprecice", 1]["steps_per_s"])
        for n in within_cores
        if 1 in args.envs
    ]
    n_reset = reset_n[1] if len(reset_n) > 1 else 1
    checks = [
        (
            "overhead <= 1% of the solver step (p50 round trip - env.step, plain env, 1 env)",
            overhead <= 0.01,
            f"{overhead:.2%}",
        ),
        (
            "wall time per step vs SB3 SubprocVecEnv <= +1% of the solver step (Adapter, 1 env)",
            vs_sb3 <= 0.01,
            f"{vs_sb3:+.2%}",
        ),
        (
            f"{n_reset} concurrent resets <= 1.2x one reset (Adapter env)",
            reset_times[n_reset] / reset_times[1] <= 1.2,
            f"{reset_times[n_reset] / reset_times[1]:.2f}x",
        ),
        (
            f"{max(reset_n)} concurrent resets <= 1.2x one reset (plain env: the vector env alone)",
            plain_resets[max(reset_n)] / plain_resets[1] <= 1.2,
            f"{plain_resets[max(reset_n)] / plain_resets[1]:.2f}x",
        ),
        (
            f">= 90% linear scaling up to {cores} cores ({sleep_label})",
            all(s >= 0.9 for s in scaling),
            "/".join(f"{s:.0%}" for s in scaling) or "n/a",
        ),
    ]
    print("  targets:")
    for text, ok, value in checks:
        print(f"    [{'met' if ok else 'MISSED'}] {text}: {value}")
    return 0


def _overheads(
    label: str, results: dict[tuple[str, str, int], dict[str, float]], envs: list[int], step: float
) -> None:
    print(f"  vector env overhead per env step, {label} (round trip - env.step in the worker):")
    for n in envs:
        ours = results[label, "gymprecice", n]
        theirs = results[label, "sb3", n]
        delta = ours["batch_s"] - theirs["batch_s"]
        print(
            f"    n={n}: p50 {ours['overhead_p50_s'] * 1e6:.0f} us "
            f"({100 * ours['overhead_p50_s'] / step:.2f}% of the solver step), "
            f"mean {ours['overhead_mean_s'] * 1e6:.0f} us "
            f"({100 * ours['overhead_mean_s'] / step:.2f}%); wall time per batch step vs "
            f"SB3 {delta * 1e6:+.0f} us ({100 * delta / step:+.2f}% of the solver step)"
        )


if __name__ == "__main__":
    sys.exit(main())
