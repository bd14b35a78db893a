"""``gymprecice train | tune | evaluate | baseline | open-loop | feedback | sweep | compare
| benchmark | time-to-floor | plot | ship-policy | policies``.

Added to the ``gymprecice`` command line by the lab's plugin. ENV is any environment id
that an installed package registers (or the short name its lab card gives it,
:mod:`gymprecice.card`); what a command needs beyond the Gymnasium API it reads from that
card. Every command that runs
an environment writes into one output directory (``--out``, default
``runs/<env>/<command>``) its results and a ``manifest.json`` (versions, solver checks,
case file hashes, seeds, command line), so the directory alone says how it was made::

    gymprecice train jet-cylinder --n-envs 4 --timesteps 100000
    gymprecice tune jet-cylinder-fast --algo sac --trials 12     # Optuna, resumable
    gymprecice evaluate jet-cylinder --episode-time 10
    gymprecice baseline jet-cylinder --episode-time 10
    gymprecice open-loop jet-cylinder --amplitude 0.5 --frequency 3
    gymprecice feedback jet-cylinder-fast --gain 2 --delay 3 --all-starts
    gymprecice sweep perpendicular-flap-fast            # uncontrolled, constants, sinusoids
    gymprecice benchmark jet-cylinder-fast --seeds 5 --algo ppo,sac --workers 2
    gymprecice time-to-floor runs/jet-cylinder-fast/train   # its kept model's share of the floor
    gymprecice compare runs/perpendicular-flap-fast/sweep runs/perpendicular-flap-fast/evaluate
    gymprecice plot runs/jet-cylinder/train runs/jet-cylinder/evaluate \\
        --baseline runs/jet-cylinder/baseline
    gymprecice ship-policy runs/jet-cylinder/train --name jet-cylinder \\
        --evaluation runs/jet-cylinder/evaluate
    gymprecice evaluate jet-cylinder --policy shipped     # no training needed

``--double`` runs any of them against gymprecice's preCICE test double with a scripted
fake flow (seconds, no solver needed). Without it a command stops at once, in one line,
when ``gymprecice doctor`` does not find what the environment needs
(``--require-solvers``: with the doctor's whole report).

This package only composes the parsers, from the option families of
:mod:`gymprecice_lab.cli.options`, a module per command family (:mod:`.training`,
:mod:`.rollouts`, :mod:`.benchmark`, :mod:`.results`; :mod:`.command` runs them); the
work is imported when a command runs, so listing ``gymprecice --help`` never loads torch
or matplotlib.
"""

from __future__ import annotations

import argparse
from typing import Any

from gymprecice_lab.cli import benchmark, results, rollouts, training
from gymprecice_lab.cli.command import Command

__all__ = ["add_commands"]


def add_commands(sub: Any) -> None:
    """Add the lab's sub-commands to ``gymprecice``'s argparse sub-parsers."""
    for command in _commands():
        parser = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description,
            formatter_class=argparse.ArgumentDefaultsHelpFormatter,  # every default shown
        )
        for each in command.options:
            each.add_to(parser)
        parser.set_defaults(func=command.run)


def _commands() -> list[Command]:
    return [
        *training.commands(),
        *rollouts.commands(),
        *benchmark.commands(),
        *results.commands(),
    ]
