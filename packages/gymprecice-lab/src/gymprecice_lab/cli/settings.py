"""The parsed command line turned into the command's settings: where the Namespace stops.

argparse hands a command an ``argparse.Namespace``: untyped, open to any attribute, and
different in what it holds from one command to the next. The lab's work never sees one:
:func:`from_namespace` builds the command's frozen settings dataclass from it once
(:class:`~gymprecice_lab.training.command_settings.TrainSettings`, ...), and the command
and everything it calls read typed fields. The conversion is by name, strict both ways:
an option the settings class has no field for, or a field no option fills (and that has
no default for the commands without that option), is a ``TypeError`` here, at once, not
an attribute missing hours into a run. A list the parser gives becomes a tuple (the
settings are frozen).

The settings classes are imported when a command runs, as its work is
(:mod:`gymprecice_lab.cli.command`): listing ``gymprecice --help`` loads none of them.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
from collections.abc import Sequence
from typing import Any

__all__ = ["SETTINGS", "settings_class", "from_namespace", "from_argv"]

#: Each lab command's settings class: (module, class name), imported when needed.
SETTINGS: dict[str, tuple[str, str]] = {
    "train": ("gymprecice_lab.training.command_settings", "TrainSettings"),
    "tune": ("gymprecice_lab.training.command_settings", "TuneSettings"),
    **dict.fromkeys(
        ("evaluate", "baseline", "open-loop", "feedback"),
        ("gymprecice_lab.rollouts.command_settings", "RolloutSettings"),
    ),
    "sweep": ("gymprecice_lab.rollouts.command_settings", "SweepSettings"),
    "compare": ("gymprecice_lab.rollouts.command_settings", "CompareSettings"),
    "plot": ("gymprecice_lab.rollouts.command_settings", "PlotSettings"),
    "benchmark": ("gymprecice_lab.benchmarking.command_settings", "BenchmarkSettings"),
    "time-to-floor": ("gymprecice_lab.benchmarking.command_settings", "TimeToFloorSettings"),
    "ship-policy": ("gymprecice_lab.policies.command_settings", "ShipSettings"),
}

#: What the ``gymprecice`` parser sets besides the command's options.
_PARSER_OWN = frozenset({"command", "func"})


def settings_class(command: str) -> type:
    """The settings class of the lab command ``command``."""
    module, name = SETTINGS[command]
    return getattr(importlib.import_module(module), name)  # type: ignore[no-any-return]


def from_namespace(command: str, ns: argparse.Namespace) -> Any:
    """``command``'s settings from its parsed command line ``ns``."""
    cls = settings_class(command)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    given = {k: v for k, v in vars(ns).items() if k not in _PARSER_OWN}
    unknown = sorted(set(given) - set(fields))
    if unknown:
        raise TypeError(f"{cls.__name__} has no field for the option(s) {', '.join(unknown)}")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in given.items()}
    if "command" in fields:
        values["command"] = command
    return cls(**values)


def from_argv(argv: Sequence[str]) -> Any:
    """The settings of ``gymprecice ARGV``, parsed as the command line parses it (a lab
    command run from another: ``benchmark`` checks a seed's ``train`` flags so)."""
    from gymprecice_lab.common.command_runs import parse_command

    ns = parse_command(argv)
    return from_namespace(ns.command, ns)
