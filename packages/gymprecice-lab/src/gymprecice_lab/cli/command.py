"""What a lab sub-command is, and how one runs: its work imported when it runs."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Sequence
from typing import NamedTuple

from gymprecice_lab.cli.options import Option
from gymprecice_lab.cli.settings import from_namespace

__all__ = ["Command", "run"]


class Command(NamedTuple):
    """One sub-command: its one-line help, its description, its options in the order
    ``--help`` shows them, and what runs it."""

    name: str
    help: str
    description: str
    options: Sequence[Option]
    run: Callable[[argparse.Namespace], int]


#: The optional modules a command imports while it runs. They are imported before it
#: writes anything: in an environment where one is missing, gymprecice's command line says
#: in one line what to install, and no output directory is left behind.
_IMPORTS_FIRST: dict[str, tuple[str, ...]] = {
    "train": ("yaml", "stable_baselines3", "torch"),
    "tune": ("yaml", "optuna"),
    "evaluate": ("stable_baselines3",),
    "benchmark": ("yaml", "stable_baselines3", "torch"),
}


def run(command: str, args: argparse.Namespace) -> int:
    """Run ``command``: its optional modules first, then its work, imported now, given the
    command's settings (:func:`gymprecice_lab.cli.settings.from_namespace`), not ``args``."""
    for module in _IMPORTS_FIRST.get(command, ()):
        importlib.import_module(module)
    if command == "policies":  # no options
        from gymprecice_lab.policies.shipped import list_command

        return list_command()
    settings = from_namespace(command, args)
    if command == "train":
        from gymprecice_lab.training.train import train_command

        return train_command(settings)
    if command == "tune":
        from gymprecice_lab.training.tune import tune_command

        return tune_command(settings)
    if command in ("evaluate", "baseline", "open-loop", "feedback"):
        from gymprecice_lab.rollouts.evaluate import rollout_command

        return rollout_command(settings)
    if command == "sweep":
        from gymprecice_lab.rollouts.sweep import sweep_command

        return sweep_command(settings)
    if command == "compare":
        from gymprecice_lab.rollouts.compare import compare_command

        return compare_command(settings)
    if command == "benchmark":
        from gymprecice_lab.benchmarking.command import benchmark_command

        return benchmark_command(settings)
    if command == "time-to-floor":
        from gymprecice_lab.benchmarking.time_to_floor import time_to_floor_command

        return time_to_floor_command(settings)
    if command == "plot":
        from gymprecice_lab.rollouts.plots import plot_command

        return plot_command(settings)
    from gymprecice_lab.policies.ship import ship_command

    return ship_command(settings)
