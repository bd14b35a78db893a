"""What a lab command was asked to do, typed: the environment family every command shares.

The parser's ``argparse.Namespace`` stops at the command line (:mod:`gymprecice_lab.cli`):
each command family gets one frozen dataclass of its options, built once from the parsed
command line (:func:`gymprecice_lab.cli.settings.from_namespace`), and its work reads typed
fields instead of attributes that may or may not be there. The classes live beside the
work that reads them, one ``command_settings`` module per family (training, rollouts,
benchmarking, policies), so that a family's options and its code change together and a
module here never imports a family's; the name ``command_settings`` keeps them apart
from the *recorded* settings of a run (``benchmark.json``, :mod:`gymprecice_lab.benchmarking.settings`,
the hyperparameter file's ``model_ensemble``, :mod:`gymprecice_lab.model_based.settings`).

This module holds what the families share:

* :class:`RunsOnEnv`, the values derived from ENV and ``--out`` (the registered env and
  its lab card, the output directory): each computed once, when first read, and kept.
  They are read inside the command, not when the settings are built, so that an unknown
  env is refused by the command with its own message and exit status, as before;
* :class:`EnvSettings`, the environment family of options (ENV, ``--out``, ``--double``,
  ``--case``, ``--episode-time``, ``--wrap``, ``--env-kwargs`` ...) of ``train``, the
  rollouts and ``sweep``, with the env's constructor keyword arguments derived once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

from gymprecice_lab.common.constructor_kwargs import build_env_kwargs
from gymprecice_lab.common.registered_env import LabEnv, default_out, find_lab_env

__all__ = ["EnvSettings", "RunsOnEnv"]


class RunsOnEnv:
    """The values derived from a command's ENV and ``--out``, each computed once.

    Mixed into a frozen settings dataclass with the fields ``env`` (ENV as typed) and
    ``out`` (``--out``, None: ``runs/<env>/<command>``) and a ``command`` (a field, or
    the class's name for a command of its own)."""

    env: str
    out: Path | None
    command: str

    @cached_property
    def lab_env(self) -> LabEnv:
        """ENV resolved to a registered id and its lab card (a ``LabEnvError`` the
        command reports when no installed package registers it)."""
        return find_lab_env(self.env)

    @cached_property
    def run_dir(self) -> Path:
        """The output directory, absolute: ``--out``, else ``runs/<env>/<command>``."""
        return (self.out or default_out(self.lab_env, self.command)).resolve()


@dataclass(frozen=True, kw_only=True)
class EnvSettings(RunsOnEnv):
    """The environment family: which env, built how, writing where (``train``, the
    rollouts, ``sweep``)."""

    #: the command (its default output directory, ``runs/<env>/<command>``, and its lines)
    command: str
    #: ENV as typed: a registered id or a lab card's short name
    env: str
    #: ``--out`` (None: ``runs/<env>/<command>``)
    out: Path | None
    #: ``--double``: gymprecice's preCICE test double with a scripted fake flow
    double: bool
    #: ``--require-solvers``: the doctor's whole report when a solver is missing
    require_solvers: bool
    #: ``--case``: a case directory of the user's instead of the recipe
    case: Path | None
    #: ``--seed``
    seed: int
    #: ``--episode-time``: simulated seconds per episode (None: the case's, or the card's
    #: rollout_time where ``rollout``)
    episode_time: float | None
    #: whether the command runs a fixed controller over the card's rollout horizon
    #: (evaluate, sweep...) rather than training episodes
    rollout: bool
    #: ``--wrap``: the robustness wrappers, each a parsed ``NAME:KEY=VALUE,...``
    wrap: tuple[dict[str, Any], ...]
    #: ``--env-kwargs``: extra keyword arguments of the environment
    env_kwargs: Mapping[str, Any]

    @cached_property
    def constructor_kwargs(self) -> dict[str, Any]:
        """The env's constructor keyword arguments (:func:`build_env_kwargs`, with its
        refusals), built once; a command that adds to them copies them first."""
        return build_env_kwargs(self, self.lab_env, self.run_dir)
