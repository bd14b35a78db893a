"""Overhead of the multi-agent layer against the single-agent env, on the same coupled run.

Runs the chaos case (Adapter, coupling worker, the preCICE double, a scripted solver
process) with

* :class:`gymprecice.testing.chaos.CylinderEnv`: one agent, one action for both jets;
* :class:`gymprecice.testing.two_jets.TwoJetsEnv`: the same physics as two agents (a
  PettingZoo ``ParallelEnv``), each jet one agent, given the same action,

episodes interleaved, and prints side by side the median wall time of one step of each,
and the multi-agent layer's own time per step: what the ``ParallelEnv`` adds to the
episode runner (checking and joining the action dict, splitting per agent in every window,
checking the observation and reward dicts, building the five result dicts), measured
directly rather than as the difference of two noisy step times. It is given in
microseconds and as a fraction of the multi-agent step. Target: < 1 % of a step.

Two solvers: one that answers at once (the bare coupling: the worst case for a relative
overhead) and one that sleeps ``--sleep`` seconds per time step (an emulated CFD step;
a real one takes 0.1 to 10 s).

Usage: ``python benchmarks/bench_multiagent.py [--steps 200] [--sleep 0.005]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("GYMPRECICE_DISABLE_PLUGINS", "1")

from gymprecice.env.core import Adapter
from gymprecice.multiagent import MultiAgentAdapter
from gymprecice.testing.chaos import CylinderEnv, write_case
from gymprecice.testing.two_jets import TwoJetsEnv

STEPS_PER_EPISODE = 50
WINDOWS_PER_STEP = 2
WINDOW = 0.01


class _Clock:
    """Seconds spent in chosen methods, and calls, accumulated per step (wrappers on an object)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}

    def wrap(self, owner: Any, name: str) -> None:
        original: Callable[..., Any] = getattr(owner, name)
        seconds, calls = self.seconds, self.calls
        seconds[name], calls[name] = 0.0, 0

        def timed(*args: Any, **kwargs: Any) -> Any:
            started = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                seconds[name] += time.perf_counter() - started
                calls[name] += 1

        setattr(owner, name, timed)

    def take(self) -> tuple[dict[str, float], dict[str, int]]:
        out = dict(self.seconds), dict(self.calls)
        for key in self.seconds:
            self.seconds[key], self.calls[key] = 0.0, 0
        return out


def _wrapper_cost(repeat: int = 20000) -> float:
    """Seconds one timed call adds outside the interval it measures (subtracted below)."""

    class Target:
        def noop(self) -> None:
            pass

    bare = Target()
    timed = Target()
    _Clock().wrap(timed, "noop")
    best = []
    for target in (bare, timed):
        started = time.perf_counter()
        for _ in range(repeat):
            target.noop()
        best.append((time.perf_counter() - started) / repeat)
    return max(0.0, best[1] - best[0])


#: each answer of the env's view to the runner, and the user's method it asks
ANSWERS = {
    "_get_action": "agent_action",
    "_get_observation": "observations",
    "_get_reward": "rewards",
    "_get_terminated": "terminations",
}


def _layer_clock(env: TwoJetsEnv) -> _Clock:
    """Time the runner's step, the view's answers and the user's methods, on this env only."""
    clock = _Clock()
    clock.wrap(env._gymprecice, "step")  # the runner's whole step, user methods included
    view = env._view
    for answer, method in ANSWERS.items():
        # the view's answers (layer code + the user's code inside them), looked up by the
        # runner on each call; the user's own methods, as the view holds them
        clock.wrap(view, answer)
        clock.wrap(view.methods, method)
    return clock


def _layer_seconds(outer: float, t: dict[str, float], calls: dict[str, int], cost: float) -> float:
    """The multi-agent layer's own seconds in one step (see the module docstring).

    Around the runner: ``outer - runner step``. Inside it, each of the view's answers minus
    the user code it calls: ``_get_action - agent_action`` (split, per-agent dicts,
    foreign-key check), ``_get_observation - observations`` and ``_get_reward - rewards``
    (the dicts' checks), ``_get_terminated - terminations``. The timers' own cost that
    falls in these differences (one per user call, each timed inside an answer, and one
    for the runner's step) is taken out.
    """
    around = outer - t["step"]
    inside = sum(t[answer] - t[method] for answer, method in ANSWERS.items())
    timers = sum(calls[method] for method in ANSWERS.values()) + calls["step"]
    return around + inside - timers * cost


def _run(case: Path, runs: Path, steps: int, cost: float) -> dict[str, list[float]]:
    single = CylinderEnv(str(case), 0, run_root=str(runs / "single"))
    multi = TwoJetsEnv(str(case), 0, run_root=str(runs / "multi"))
    clock = _layer_clock(multi)
    times: dict[str, list[float]] = {"single": [], "multi": [], "layer": []}
    action = np.array([0.3], dtype=np.float32)
    try:
        done = 0
        while done < steps:
            single.reset(seed=done)
            multi.reset(seed=done)
            clock.take()
            for _ in range(STEPS_PER_EPISODE):
                started = time.perf_counter()
                single.step(action)
                times["single"].append(time.perf_counter() - started)
                actions = {agent: action for agent in multi.agents}
                started = time.perf_counter()
                multi.step(actions)
                outer = time.perf_counter() - started
                times["multi"].append(outer)
                times["layer"].append(_layer_seconds(outer, *clock.take(), cost))
                done += 1
    finally:
        single.close()
        multi.close()
    # the first steps of a run pay imports and caches
    return {key: values[5:] for key, values in times.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="steps per env and solver")
    parser.add_argument(
        "--sleep", type=float, default=0.005, help="emulated solver seconds per time step"
    )
    args = parser.parse_args(argv)
    assert issubclass(TwoJetsEnv, MultiAgentAdapter) and issubclass(CylinderEnv, Adapter)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"gymprecice multi-agent overhead: {os.cpu_count()} cores, load average {load:.1f}, "
        f"{args.steps} steps per env, {WINDOWS_PER_STEP} windows per step, python "
        f"{sys.version.split()[0]}"
    )
    header = (
        f"{'solver':<28}{'single-agent step':>18}{'two-agent step':>16}"
        f"{'layer per step':>16}{'layer / step':>14}"
    )
    print(header)
    print("-" * len(header))
    worst = 0.0
    cost = _wrapper_cost()
    for label, sleep in (
        ("answers at once", 0.0),
        (f"sleeps {args.sleep * 1e3:g} ms/step", args.sleep),
    ):
        with tempfile.TemporaryDirectory(prefix="gp-bench-ma-") as tmp:
            work = Path(tmp)
            case = write_case(
                work / "case",
                work / "faults",
                end_time=STEPS_PER_EPISODE * WINDOWS_PER_STEP * WINDOW,
                window=WINDOW,
                windows_per_step=WINDOWS_PER_STEP,
                step_sleep=sleep,
            )
            times = _run(case, work / "runs", args.steps, cost)
        single = statistics.median(times["single"])
        multi = statistics.median(times["multi"])
        layer = statistics.median(times["layer"])
        share = layer / multi
        worst = max(worst, share)
        print(
            f"{label:<28}{single * 1e3:>15.3f} ms{multi * 1e3:>13.3f} ms"
            f"{layer * 1e6:>13.1f} us{share:>13.2%}"
        )
    print(f"(the timers' own cost, {cost * 1e6:.2f} us per timed call, is subtracted)")
    print(
        f"target: layer < 1 % of a step; worst here {worst:.2%} ({'met' if worst < 0.01 else 'missed'})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
