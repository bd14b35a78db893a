"""The benchmark's input, checked before anything trains, and the error it fails with.

A benchmark runs for hours; a typo in ``--algo``, a training flag an algorithm does not
have, an algorithm that cannot act in the env's action space or a baseline grid that
cannot be swept would otherwise surface only after every seed has trained. Every check
here raises :class:`BenchmarkError`, the one way the command fails (its other modules
raise it too: a failed seed, a settings clash on a resume, an unreachable cluster).
"""

from __future__ import annotations

import dataclasses
import shlex
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from gymprecice_lab.benchmarking.command_settings import BenchmarkSettings
from gymprecice_lab.common.command_runs import CommandFailed
from gymprecice_lab.common.registered_env import LabEnv
from gymprecice_lab.training.hyperparams import ALGORITHMS, OFF_POLICY

__all__ = [
    "DEFAULT_FEEDBACK_GAINS",
    "BenchmarkError",
    "check_algorithm_fits",
    "check_baselines_fit",
    "check_grids",
    "parse_algorithms",
    "parse_train_args",
    "resolve_feedback",
]


class BenchmarkError(CommandFailed):
    """Bad input or a failed seed: one line on stderr, exit status 2 (input) or 1."""

    def __init__(self, message: str, status: int = 2) -> None:
        super().__init__("benchmark", message, status)


# -- parsing and checks ---------------------------------------------------------------------


def parse_algorithms(text: str) -> list[str]:
    """``"ppo,sac"`` -> ``["ppo", "sac"]``; unknown or repeated names are refused."""
    algos = [a.strip().lower() for a in text.split(",") if a.strip()]
    unknown = [a for a in algos if a not in ALGORITHMS]
    if not algos or unknown:
        raise BenchmarkError(
            f"--algo {text!r}: {'unknown ' + ', '.join(unknown) if unknown else 'none given'}; "
            f"choose from {', '.join(ALGORITHMS)} (comma-separated)"
        )
    if len(set(algos)) != len(algos):
        raise BenchmarkError(f"--algo {text!r} names an algorithm twice")
    return algos


def parse_train_args(given: Sequence[str], algos: Sequence[str]) -> dict[str, list[str]]:
    """``--train-args`` values (``"FLAGS"`` for every algorithm, ``"ALGO: FLAGS"`` for one)
    as each algorithm's extra ``gymprecice train`` arguments."""
    out: dict[str, list[str]] = {algo: [] for algo in algos}
    for text in given:
        head, sep, rest = text.partition(":")
        if sep and head.strip().lower() in ALGORITHMS and not head.strip().startswith("-"):
            algo = head.strip().lower()
            if algo not in out:
                raise BenchmarkError(
                    f"--train-args {text!r} is for {algo}, which --algo does not name"
                )
            out[algo] += shlex.split(rest)
        else:
            for algo in algos:
                out[algo] += shlex.split(text)
    owned = {"--algo", "--seed", "--out", "--timesteps", "--n-envs", "--fresh", "--double"}
    for algo, flags in out.items():
        clash = sorted({f.split("=", 1)[0] for f in flags} & owned)
        if clash:
            raise BenchmarkError(
                f"--train-args for {algo} sets {', '.join(clash)}, which the benchmark sets "
                "itself; use the benchmark's own option"
            )
    return out


def check_algorithm_fits(algo: str, space: gym.Space) -> None:
    """Refuse an algorithm that cannot act in ``space`` (before anything trains)."""
    box = isinstance(space, gym.spaces.Box)
    if algo in OFF_POLICY:
        if not box:
            raise BenchmarkError(
                f"--algo {algo}: {algo.upper()} acts only in a continuous Box action space; "
                f"this env's is {space}; use --algo ppo"
            )
        if not (np.all(np.isfinite(space.low)) and np.all(np.isfinite(space.high))):
            raise BenchmarkError(
                f"--algo {algo}: {algo.upper()} squashes its actions into the action bounds, "
                f"and this env's Box is unbounded ({space}); bound the action space or use "
                "--algo ppo"
            )
    elif not isinstance(
        space,
        (gym.spaces.Box, gym.spaces.Discrete, gym.spaces.MultiDiscrete, gym.spaces.MultiBinary),
    ):
        raise BenchmarkError(
            f"--algo {algo}: {algo.upper()} cannot act in this env's action space {space}"
        )


def check_baselines_fit(space: gym.Space) -> None:
    """Refuse the classical baselines where they cannot act: each forcing is a fraction of
    a bounded Box action space."""
    if not (
        isinstance(space, gym.spaces.Box)
        and np.all(np.isfinite(space.low))
        and np.all(np.isfinite(space.high))
    ):
        raise BenchmarkError(
            f"the classical baselines (constants, sinusoids, feedback) need a bounded Box "
            f"action space, this env's is {space}; add --no-baselines"
        )


#: the lift feedback's gains where ``--feedback-gains`` is not given (an env whose
#: classical feedback is a signal fed back, as the cylinders' lift)
DEFAULT_FEEDBACK_GAINS = "-2,-1,1,2"


def resolve_feedback(benchmark: BenchmarkSettings, env: LabEnv) -> BenchmarkSettings:
    """``benchmark`` with the feedback baseline's defaults filled in: the lift's gains for
    an env fed back a signal; the grid of the env's own law (``--feedback-grid``, its
    documented grid unless given, written out so that ``benchmark.json`` records every
    point) for one that names a law. The other kind's options are refused rather than
    ignored."""
    from gymprecice_lab.rollouts.feedback import own_law_grid

    try:
        law, grid = own_law_grid(
            env.name, env.feedback_law, benchmark.feedback_gains, benchmark.feedback_grid
        )
    except ValueError as exc:
        raise BenchmarkError(str(exc)) from None
    if law is None:
        if benchmark.feedback_gains is not None:
            return benchmark
        # no signal to feed back (card field 'feedback_signal'): no feedback baseline
        has_signal = benchmark.feedback_signal or env.feedback_signal
        gains = DEFAULT_FEEDBACK_GAINS if has_signal else ""
        return dataclasses.replace(benchmark, feedback_gains=gains)
    return dataclasses.replace(
        benchmark,
        feedback_gains="",
        feedback_grid=law.grid_text(grid) if grid is not None else "",
    )


def check_grids(benchmark: BenchmarkSettings, env: LabEnv) -> None:
    """The sweep's grids, checked now rather than after every seed has trained."""
    from gymprecice_lab.rollouts.sweep import parse_grid

    if benchmark.amplitudes.strip():  # empty: no sinusoids
        parse_grid(benchmark.amplitudes, "amplitudes")
    if not 0.0 <= benchmark.centre <= 1.0:
        raise BenchmarkError(
            f"--centre is a fraction of the action box, 0 to 1; got {benchmark.centre}"
        )
    if any(f <= 0 for f in parse_grid(benchmark.frequencies, "frequencies")):
        raise BenchmarkError("--frequencies must be positive (Hz)")
    if benchmark.feedback_gains:
        parse_grid(benchmark.feedback_gains, "feedback-gains")
        delays = parse_grid(benchmark.feedback_delays, "feedback-delays")
        if any(d < 0 or d != int(d) for d in delays):
            raise BenchmarkError("--feedback-delays are whole numbers of actions >= 0")
        if not (benchmark.feedback_signal or env.feedback_signal):
            raise BenchmarkError(
                f"{env.name} has no default feedback signal; pass --feedback-signal NAME "
                "(one of the metrics in its steps' info['metrics']) or --feedback-gains '' "
                "(no feedback baseline)"
            )
