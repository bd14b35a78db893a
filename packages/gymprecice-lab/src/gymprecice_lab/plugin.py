"""The lab's gymprecice plugin: ``gymprecice train | evaluate | baseline | open-loop |
feedback | sweep | compare | benchmark | time-to-floor | plot | ship-policy | policies``.

Loaded through the ``gymprecice`` entry point on every ``import gymprecice``: it adds
parsers only; a command's work (SB3, torch, matplotlib) is imported when it runs.
"""

from __future__ import annotations

from typing import Any

from gymprecice.plugin.hookspecs import hookimpl

__all__ = ["gymprecice_register_commands"]


@hookimpl
def gymprecice_register_commands(subparsers: Any) -> None:
    from gymprecice_lab.cli import add_commands

    add_commands(subparsers)
