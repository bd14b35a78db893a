"""The command lines the benchmark gives its sub-commands.

Each piece of the benchmark is another ``gymprecice`` command (train, evaluate, sweep),
run through that command's own parser, so that a seed trained by the benchmark is the
seed ``gymprecice train`` would have trained. The options every piece shares (the
double, the episode length, the env's keyword arguments) are written once, here.
"""

from __future__ import annotations

import json
from pathlib import Path

from gymprecice_lab.benchmarking.command_settings import BenchmarkSettings

__all__ = ["common_options", "sweep_argv", "train_argv"]


def common_options(benchmark: BenchmarkSettings, episode_time: float | None) -> list[str]:
    """The options every sub-command shares: the double, the solvers' check, the episode
    length (``episode_time``: the training's or the evaluations'), the env's arguments."""
    argv = []
    if benchmark.double:
        argv.append("--double")
    if benchmark.require_solvers:
        argv.append("--require-solvers")
    if episode_time is not None:
        argv += ["--episode-time", repr(float(episode_time))]
    if benchmark.env_kwargs:
        argv += ["--env-kwargs", json.dumps(benchmark.env_kwargs)]
    return argv


def train_argv(
    benchmark: BenchmarkSettings, algo: str, seed: int, out: Path, extra: list[str]
) -> list[str]:
    """``gymprecice train`` of one seed of ``algo`` into ``out`` (``extra``: the
    algorithm's ``--train-args``)."""
    return [
        "train",
        benchmark.env,
        "--algo",
        algo,
        "--seed",
        str(seed),
        "--timesteps",
        str(benchmark.timesteps),
        "--n-envs",
        str(benchmark.n_envs),
        "--out",
        str(out),
        "--no-progress-bar",
        *common_options(benchmark, benchmark.episode_time),
        *extra,
    ]


def sweep_argv(benchmark: BenchmarkSettings, starts: int, own_law: bool) -> list[str]:
    """``gymprecice sweep`` of the baselines: the benchmark's grids on its ``starts``
    held-out starts (``own_law``: the env has a feedback law of its own, swept over
    ``--feedback-grid``)."""
    argv = [
        "sweep",
        benchmark.env,
        "--episodes",
        str(starts),
        "--constants",
        str(benchmark.constants),
        # NAME=VALUE: a grid may start with a minus sign
        f"--amplitudes={benchmark.amplitudes}",
        f"--frequencies={benchmark.frequencies}",
        f"--centre={benchmark.centre!r}",
        f"--feedback-gains={benchmark.feedback_gains}",
        f"--feedback-delays={benchmark.feedback_delays}",
        "--workers",
        str(benchmark.workers),
        *common_options(benchmark, benchmark.eval_time),
    ]
    if benchmark.feedback_signal:
        argv.append(f"--feedback-signal={benchmark.feedback_signal}")
    if own_law:
        argv.append(f"--feedback-grid={benchmark.feedback_grid}")
    return argv
