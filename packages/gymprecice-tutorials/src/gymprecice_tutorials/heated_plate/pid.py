"""The classical answer to a thermal setpoint: a PI(D) heater, tuned by a sweep.

:class:`PIDController` maps HeatedPlate-v0's observation (the interface temperature's
error and its change over the last step) to a heater temperature::

    heater = 310 K - kp e - kd de + I,    I <- clip(I - ki e dt)

with ``dt`` the action time (0.1 s) and the integral clipped so the heater stays within
its range (no wind-up). :func:`sweep` runs every ``(kp, ki, kd)`` of a grid on a few
*training* starts (never the held-out ones), ranks them by the mean tracking error plus
the actuation cost (the negated mean reward), and :func:`main` evaluates the best one,
the uncontrolled plate, constant heaters and any trained policy (``--policy``) on the
held-out starts, all in one table and one figure:

    python -m gymprecice_tutorials.heated_plate.pid --solid openfoam --out runs/plate-pid
    python -m gymprecice_tutorials.heated_plate.pid --sweep-on fast --policy shipped

``--sweep-on fast`` sweeps on the training case (HeatedPlateFast-v0, 3.5 s an episode
instead of 57 s) and evaluates on HeatedPlate-v0: the same split as a trained policy's.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.card import FeedbackLaw
from gymprecice_tutorials.heated_plate.environment import (
    ACTION_TIME,
    EVAL_STARTS,
    HEATER_RANGE,
    REFERENCE_HEATER,
    HeatedPlateEnv,
)

__all__ = ["PID_LAW", "PIDController", "Rollout", "plot", "rollout", "sweep"]


@dataclass
class PIDController:
    """A PI(D) heater with a clipped integral (see the module docstring)."""

    kp: float
    ki: float
    kd: float = 0.0
    integral: float = 0.0

    def reset(self) -> None:
        self.integral = 0.0

    def __call__(self, obs: np.ndarray, t: float | None = None) -> np.ndarray:
        """The heater for observation ``obs`` (``t``, the time, is not used: a PID sees
        only the error, as ``gymprecice sweep`` calls every controller with both)."""
        error, change = float(obs[0]), float(obs[1])
        low, high = (h - REFERENCE_HEATER for h in HEATER_RANGE)
        self.integral = float(np.clip(self.integral - self.ki * error * ACTION_TIME, low, high))
        heater = REFERENCE_HEATER - self.kp * error - self.kd * change + self.integral
        return np.array([np.clip(heater, *HEATER_RANGE)], dtype=np.float32)


def _pid_for(space: Any, settings: Mapping[str, float]) -> PIDController:
    """One PID of the law, for an env acting on the heater in kelvin (its own units)."""
    low, high = (float(np.ravel(b)[0]) for b in (space.low, space.high))
    if (low, high) != HEATER_RANGE:
        raise ValueError(
            f"the PID heater acts on the heater's range {HEATER_RANGE} K, the env's action "
            f"box is ({low:g}, {high:g}): run it on the env's own action space"
        )
    return PIDController(settings["kp"], settings["ki"], settings.get("kd", 0.0))


#: the heated plate's classical baseline for ``gymprecice sweep`` and ``benchmark``: the
#: grid of the tuning sweep in docs/training.md (40 gains; its best: kp 3, ki 50, kd 1)
PID_LAW = FeedbackLaw(
    "pid",
    "heater = 310 K - kp e - kd de + I, I <- clip(I - ki e dt)",
    (("kp", (2, 3, 4, 6)), ("ki", (25, 50, 75, 100, 150)), ("kd", (0, 1))),
    _pid_for,
)


@dataclass
class Rollout:
    """One episode of one controller: its mean tracking error, mean reward, time series."""

    label: str
    seed: int
    split: str
    tracking_error: float
    mean_reward: float
    #: the mean ``|heater - 310 K|`` (K): what the reward's actuation cost weighs
    actuation: float
    time: list[float]
    temperature: list[float]
    heater: list[float]
    setpoint: float


def rollout(
    env: HeatedPlateEnv,
    controller: Callable[[np.ndarray], np.ndarray],
    *,
    seed: int,
    split: str,
    label: str,
) -> Rollout:
    """Run one episode of ``controller`` (obs -> action) from start ``seed`` of ``split``."""
    if hasattr(controller, "reset"):
        controller.reset()
    obs, _ = env.reset(seed=seed, options={"split": split})
    times, temperatures, heaters, errors, rewards = [], [], [], [], []
    while True:
        obs, reward, terminated, truncated, info = env.step(controller(obs))
        metrics = info["metrics"]
        times.append(env.time)
        temperatures.append(metrics["interface_temperature"])
        heaters.append(metrics["heater_temperature"])
        errors.append(metrics["tracking_error"])
        rewards.append(float(reward))
        if terminated or truncated:
            break
    return Rollout(
        label,
        seed,
        split,
        float(np.mean(errors)),
        float(np.mean(rewards)),
        float(np.mean(np.abs(np.asarray(heaters) - REFERENCE_HEATER))),
        times,
        temperatures,
        heaters,
        env.start.setpoint,
    )


def constant(heater: float) -> Callable[[np.ndarray], np.ndarray]:
    return lambda _obs: np.array([heater], dtype=np.float32)


def sweep(
    env: HeatedPlateEnv,
    grid: Sequence[tuple[float, float, float]],
    seeds: Sequence[int],
    say: Callable[[str], None] = print,
) -> list[tuple[tuple[float, float, float], float, float]]:
    """``[(gains, mean tracking error, mean reward)]`` on training starts, best first."""
    results = []
    for gains in grid:
        runs = [
            rollout(env, PIDController(*gains), seed=s, split="train", label=str(gains))
            for s in seeds
        ]
        error = float(np.mean([r.tracking_error for r in runs]))
        reward = float(np.mean([r.mean_reward for r in runs]))
        say(
            f"  kp={gains[0]:g} ki={gains[1]:g} kd={gains[2]:g}: error {error:.4f} K, "
            f"reward {reward:.4f}"
        )
        results.append((tuple(gains), error, reward))
    return sorted(results, key=lambda r: -r[2])


def plot(results: Path, out: Path) -> Path:
    """Interface and heater temperature against time, every controller on every held-out
    start of ``results`` (the ``pid.json`` that :func:`main` writes), one column a start."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    saved = json.loads(Path(results).read_text())
    runs, settle = saved["evaluation"], float(saved.get("settle_time", 0.3))
    seeds = sorted({r["seed"] for r in runs})
    labels = list(dict.fromkeys(r["label"] for r in runs))
    fig, axes = plt.subplots(2, len(seeds), figsize=(4.2 * len(seeds), 6), sharex=True)
    axes = np.asarray(axes).reshape(2, len(seeds))
    for col, seed in enumerate(seeds):
        for label in labels:
            (run,) = [r for r in runs if r["seed"] == seed and r["label"] == label]
            axes[0, col].plot(run["time"], run["temperature"], label=label)
            axes[1, col].plot(run["time"], run["heater"], label=label)
        setpoint = next(r["setpoint"] for r in runs if r["seed"] == seed)
        axes[0, col].axhline(setpoint, color="k", linestyle=":", label="setpoint")
        start = EVAL_STARTS[seed]
        for row in (0, 1):
            axes[row, col].axvline(settle + start.step_time, color="grey", linewidth=0.8)
        axes[0, col].set_title(
            f"held-out start {seed}: inflow 0.1 -> {start.velocity:g} m/s at "
            f"t = {settle + start.step_time:g} s",
            fontsize=9,
        )
        axes[1, col].set_xlabel("time (s)")
    axes[0, 0].set_ylabel("mean interface temperature (K)")
    axes[1, 0].set_ylabel("heater temperature (K)")
    axes[0, -1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv: Sequence[str] | None = None) -> int:  # pragma: no cover - runs solvers
    """Sweep PI(D) gains on training starts, then evaluate on the held-out starts."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--solid", default="openfoam", choices=["openfoam", "fenics"])
    parser.add_argument("--double", action="store_true", help="on the test double")
    parser.add_argument("--kp", default="0,1,2", help="comma-separated proportional gains")
    parser.add_argument("--ki", default="5,10,20", help="integral gains (1/s)")
    parser.add_argument("--kd", default="0", help="derivative gains")
    parser.add_argument("--seeds", default="0", help="training starts of the sweep")
    parser.add_argument("--constants", default="305,310,315,320", help="constant heaters (K)")
    parser.add_argument(
        "--sweep-on",
        choices=["full", "fast"],
        default="full",
        help="sweep on HeatedPlate-v0 itself or on its training case HeatedPlateFast-v0",
    )
    parser.add_argument(
        "--policy",
        action="append",
        default=[],
        metavar="SPEC",
        help="a trained policy to evaluate beside the baselines (repeatable): shipped, a "
        "shipped name, a training directory or model .zip",
    )
    parser.add_argument("--out", default="gymprecice-runs/heated-plate-pid")
    args = parser.parse_args(argv)
    floats = lambda text: [float(v) for v in text.split(",") if v]  # noqa: E731
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    policies = {}
    if args.policy:  # a trained policy, as the lab evaluates one (gymprecice-lab)
        from gymprecice_lab.policies.shipped import PolicyController

        # labelled by the last part of the spec: runs/heated-plate-fast/sac -> "policy sac"
        policies = {
            f"policy {Path(spec).name}": PolicyController(spec, "heated-plate", HEATER_RANGE)
            for spec in args.policy
        }
    env = HeatedPlateEnv(solid=args.solid, double=args.double, run_root=out / "runs")
    started = time.perf_counter()
    try:
        grid = list(itertools.product(floats(args.kp), floats(args.ki), floats(args.kd)))
        where = "HeatedPlateFast-v0" if args.sweep_on == "fast" else "HeatedPlate-v0"
        print(f"sweep of {len(grid)} gains on training starts {args.seeds} of {where}:")
        if args.sweep_on == "fast":
            from gymprecice_tutorials.heated_plate.fast import HeatedPlateFastEnv

            sweep_env = HeatedPlateFastEnv(double=args.double, run_root=out / "runs")
            try:
                ranked = sweep(sweep_env, grid, [int(s) for s in args.seeds.split(",")])
            finally:
                sweep_env.close()
        else:
            ranked = sweep(env, grid, [int(s) for s in args.seeds.split(",")])
        best = ranked[0][0]
        print(f"best: kp={best[0]:g} ki={best[1]:g} kd={best[2]:g}")
        controllers: dict[str, Any] = {
            "uncontrolled": constant(REFERENCE_HEATER),
            **{f"constant {h:g} K": constant(h) for h in floats(args.constants)},
            f"PID kp={best[0]:g} ki={best[1]:g} kd={best[2]:g}": PIDController(*best),
            **policies,
        }
        evaluated = []
        for label, controller in controllers.items():
            runs = [
                rollout(env, controller, seed=s, split="eval", label=label)
                for s in range(len(EVAL_STARTS))
            ]
            evaluated += runs
            errors = [r.tracking_error for r in runs]
            rewards = [r.mean_reward for r in runs]
            print(
                f"{label:<28} tracking error {np.mean(errors):.4f} ± {np.std(errors):.4f} K "
                f"({', '.join(f'{e:.3f}' for e in errors)}), mean reward "
                f"{np.mean(rewards):.4f}, actuation "
                f"{np.mean([r.actuation for r in runs]):.2f} K"
            )
    finally:
        env.close()
    (out / "pid.json").write_text(
        json.dumps(
            {
                "sweep": [{"gains": g, "error": e, "reward": r} for g, e, r in ranked],
                "best": best,
                "evaluation": [asdict(r) for r in evaluated],
                "wall_s": time.perf_counter() - started,
                "settle_time": env.settle_time,
                "solid": args.solid,
                "sweep_on": args.sweep_on,
                "policies": args.policy,
            },
            indent=1,
        )
    )
    print(f"{time.perf_counter() - started:.0f} s; results in {out / 'pid.json'}")
    print(f"figure: {plot(out / 'pid.json', out / 'pid.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
