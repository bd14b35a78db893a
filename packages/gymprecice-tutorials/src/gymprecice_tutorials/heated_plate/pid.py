"""The classical answer to a thermal setpoint: a PI(D) heater.

:class:`PIDController` maps HeatedPlate-v0's observation (the interface temperature's
error and its change over the last step) to a heater temperature::

    heater = 310 K - kp e - kd de + I,    I <- clip(I - ki e dt)

with ``dt`` the action time (0.1 s) and the integral clipped so the heater stays within
its range (no wind-up).

:data:`PID_LAW` is that family as the plate's classical feedback law (its lab card's
``feedback_law``), with the grid of the documented tuning sweep. The lab runs it like
any env's own law::

    gymprecice sweep heated-plate-fast --starts validation --feedback-grid "kp=2,3;ki=25,50"
    gymprecice feedback heated-plate --law "kp=3;ki=50;kd=1" --all-starts
    gymprecice benchmark heated-plate-fast        # the best point beside the learned ones

``python -m gymprecice_tutorials.heated_plate.pid`` (the command earlier docs give) runs
those commands for the plate, each printed before it runs (:func:`main`): the gains tuned
on the validation starts of the training case (``--sweep-on fast``) or of HeatedPlate-v0,
never the held-out ones; then the uncontrolled plate, constant heaters, the tuned PID and
any trained policy (``--policy``) on HeatedPlate-v0's held-out starts, compared in one
table (``compare.md``) and drawn (``plots/``)::

    python -m gymprecice_tutorials.heated_plate.pid --sweep-on fast --policy shipped
"""

from __future__ import annotations

import argparse
import json
import shlex
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.plugin.card import FeedbackLaw
from gymprecice_tutorials.heated_plate.environment import (
    ACTION_TIME,
    HEATER_RANGE,
    REFERENCE_HEATER,
)

__all__ = ["PID_LAW", "PIDController", "lab_commands", "main"]


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

#: the constant heaters of the held-out sweep: 300 to 340 K every 5 K
CONSTANT_HEATERS = 9


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m gymprecice_tutorials.heated_plate.pid",
        description="Tune the plate's PID on validation starts, then run it, the uncontrolled "
        "plate, constant heaters and trained policies on HeatedPlate-v0's held-out starts: "
        "the lab's gymprecice sweep, evaluate, compare and plot, each printed as it runs.",
    )
    parser.add_argument("--solid", default="openfoam", choices=["openfoam", "fenics"])
    parser.add_argument("--double", action="store_true", help="on the test double")
    parser.add_argument("--kp", default="0,1,2", help="comma-separated proportional gains")
    parser.add_argument("--ki", default="5,10,20", help="integral gains (1/s)")
    parser.add_argument("--kd", default="0", help="derivative gains")
    parser.add_argument(
        "--seeds",
        default="0",
        help="comma-separated; as many validation starts tune the gains (the env's "
        "validation starts, not training seeds, since the lab tunes there)",
    )
    parser.add_argument(
        "--constants",
        default="305,310,315,320",
        help="constant heaters (K): any runs the lab's nine, 300 to 340 K every 5 K; empty: none",
    )
    parser.add_argument(
        "--sweep-on",
        choices=["full", "fast"],
        default="full",
        help="tune on HeatedPlate-v0 itself or on its training case HeatedPlateFast-v0",
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
    return parser


def lab_commands(args: argparse.Namespace, point: str) -> list[list[str]]:
    """The ``gymprecice`` commands after the tuning sweep, for the PID ``point``
    (``"kp=3;ki=50;kd=1"``): the held-out sweep, one ``evaluate`` per policy, ``compare``
    and ``plot`` (each an argv without the leading ``gymprecice``)."""
    out = Path(args.out)
    held_out = ["--double"] if args.double else []
    if args.solid != "openfoam":
        held_out += ["--env-kwargs", json.dumps({"solid": args.solid})]
    sweep = out / "sweep"
    constants = CONSTANT_HEATERS if args.constants.strip() else 0
    # NAME=VALUE: an empty value stays one argument
    sweep_grid = [f"--feedback-grid={point}", "--constants", str(constants), "--amplitudes="]
    commands = [["sweep", "heated-plate", *sweep_grid, "--out", str(sweep), *held_out]]
    policies: list[str] = []
    for spec in args.policy:
        name = f"policy-{Path(spec).name}"
        while str(out / name) in policies:  # two runs/…/sac: policy-sac, policy-sac-2
            name = f"{name}-{len(policies) + 1}"
        policies.append(str(out / name))
        evaluate = ["evaluate", "heated-plate", "--policy", spec, "--all-starts"]
        commands.append([*evaluate, "--out", policies[-1], *held_out])
    label = "feedback-" + PID_LAW.label(_values(point))  # the sweep's run of the PID
    commands.append(["compare", str(sweep), *policies, "--out", str(out)])
    baseline = ["--baseline", str(sweep / "uncontrolled")]
    commands.append(["plot", str(sweep / label), *policies, *baseline, "--out", str(out / "plots")])
    return commands


def _values(point: str) -> dict[str, float]:
    """``"kp=3;ki=50;kd=1"`` -> ``{"kp": 3.0, "ki": 50.0, "kd": 1.0}``."""
    return {k: v[0] for k, v in PID_LAW.parse_grid(point).items()}


def main(argv: Sequence[str] | None = None) -> int:
    """Tune the PID, then evaluate it beside the baselines and policies, with the lab's
    commands (the ``gymprecice`` command line; gymprecice-lab provides them)."""
    from gymprecice.tools.cli import main as gymprecice

    args = _parser().parse_args(argv)
    out = Path(args.out)

    def run(command: list[str]) -> int:
        print(f"$ gymprecice {shlex.join(command)}", flush=True)
        return gymprecice(command)

    starts = max(1, len([s for s in args.seeds.split(",") if s.strip()]))
    grid = f"kp={args.kp};ki={args.ki};kd={args.kd}"
    tune_on = "heated-plate-fast" if args.sweep_on == "fast" else "heated-plate"
    tune = [
        "sweep",
        tune_on,
        "--starts",
        "validation",
        "--episodes",
        str(starts),
        "--constants",
        "0",
        "--amplitudes=",
        f"--feedback-grid={grid}",
        "--out",
        str(out / "tune"),
    ]
    if args.double:
        tune.append("--double")
    if args.solid != "openfoam" and tune_on == "heated-plate":
        tune += ["--env-kwargs", json.dumps({"solid": args.solid})]
    status = run(tune)
    if status:
        return status
    best = json.loads((out / "tune" / "sweep.json").read_text())["best_feedback"]
    point = ";".join(f"{name}={float(best[name]):g}" for name in PID_LAW.parameters)
    print(f"best on the validation starts: {point}", flush=True)
    for command in lab_commands(args, point):
        status = run(command)
        if status:
            return status
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
