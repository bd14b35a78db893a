"""The environment a lab command runs: a registered id, its lab card, and the card's defaults.

Every command takes any Gymnasium id that an installed package registers through
``gymprecice_register_environments`` (or the short ``name`` its card gives it) and reads
what it needs beyond the Gymnasium API from that env's card
(:class:`gymprecice.card.EnvCard`). :class:`LabEnv` is that pair, with the names the
commands read; where the card leaves a field out, the command uses the default derived
from the env (:func:`default_frequency`, the zero action clipped into the action box
as "uncontrolled", seeds as starts...), and a run's directory is
``runs/<name>/<command>`` without ``--out`` (:func:`default_out`). A
command that needs a field the card lacks asks :meth:`LabEnv.require`, which refuses in
one line naming the field and how to declare it, before anything is made on disk.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gymprecice.plugin.card import CardError, EnvCard, Reference, card_for, find_env, registered_ids

__all__ = [
    "LabEnv",
    "LabEnvError",
    "Refused",
    "default_frequency",
    "default_out",
    "find_lab_env",
    "lab_envs",
    "names_where",
]


class Refused(SystemExit):
    """A command refused before it makes anything: its one line said on stderr now, exit
    status 2 (a usage error). ``str()`` is the line, for callers that report it again."""

    def __init__(self, message: str) -> None:
        print(message, file=sys.stderr)
        super().__init__(2)
        self.message = message

    def __str__(self) -> str:
        return self.message


class LabEnvError(ValueError):
    """An env a command cannot run: unknown id, a refused card, a field it needs missing.
    The text is one line, without the command's name."""


@dataclass(frozen=True)
class LabEnv:
    """One registered environment as the lab sees it: its id and its lab card."""

    env_id: str
    card: EnvCard

    @property
    def name(self) -> str:
        """The command-line name: the card's ``name``, else the id."""
        return self.card.name or self.env_id

    @property
    def entry_point(self) -> Any:
        """What Gymnasium builds the env from (``"module:Class"`` or a callable)."""
        import gymnasium

        return gymnasium.spec(self.env_id).entry_point

    @property
    def description(self) -> str:
        return self.card.description or self.env_id

    @property
    def double(self) -> bool:
        return self.card.double

    @property
    def recipe(self) -> bool:
        """Whether the env takes ``episode_time`` (``--episode-time``)."""
        return self.card.episode_time

    @property
    def rollout_time(self) -> float | None:
        return self.card.rollout_time

    @property
    def open_loop_frequency(self) -> float | None:
        """The card's forcing frequency (``None``: :func:`default_frequency` of the env)."""
        return self.card.open_loop_frequency

    @property
    def action_unit(self) -> str:
        return self.card.action_unit

    @property
    def action_bound(self) -> float | None:
        return self.card.action_bound

    @property
    def objective(self) -> str | None:
        return self.card.objective

    @property
    def maximize(self) -> bool:
        return self.card.maximize

    @property
    def objective_label(self) -> str:
        """How figures name the objective they plot (lower is better): the card's metric,
        said negated where the card says ``maximize``; without one, the negated mean
        reward (what :func:`gymprecice_lab.rollouts.sweep.objective` ranks on)."""
        if not self.objective:
            return "mean reward, negated (lower is better)"
        if self.maximize:
            return f"{self.objective}, negated (lower is better)"
        return f"{self.objective} (lower is better)"

    def action_label(self, what: str = "action") -> str:
        """``what`` with the card's action unit (``"constant action (m^3/s)"``); bare
        where the card names no unit."""
        return f"{what} ({self.action_unit})" if self.action_unit else what

    @property
    def baseline_kwargs(self) -> tuple[tuple[str, Any], ...]:
        """The env keyword arguments of the uncontrolled setting (card ``uncontrolled``)."""
        return tuple(self.card.uncontrolled.items())

    @property
    def held_out_starts(self) -> bool:
        return self.card.held_out_starts

    @property
    def feedback_signal(self) -> str | None:
        return self.card.feedback_signal

    @property
    def feedback_law(self) -> str | None:
        return self.card.feedback_law

    @property
    def shipped_policy(self) -> str | None:
        return self.card.shipped_policy

    @property
    def reference(self) -> Reference | None:
        return self.card.reference

    @property
    def solver_checks(self) -> tuple[str, ...]:
        return self.card.solver_checks

    def checks_for(self, kwargs: Mapping[str, Any] | None) -> tuple[str, ...]:
        """The doctor checks the env made with ``kwargs`` needs (card ``solver_checks``,
        or its ``solver_checks_with`` entry that the keyword arguments match)."""
        return self.card.checks_for(kwargs or {})

    @property
    def episode_metrics(self) -> tuple[str, ...]:
        """The ``info["metrics"]`` entries whose episode means training records in every
        Monitor file (``mean_<name>`` columns): the card's ``objective``, then its
        ``metrics``, each once."""
        names = [self.card.objective] if self.card.objective else []
        return tuple(dict.fromkeys([*names, *self.card.metrics]))

    def require(self, field_name: str, command: str) -> Any:
        """The card's ``field_name``; :class:`LabEnvError` naming the field and how to
        declare it when the card leaves it out."""
        try:
            return self.card.require(field_name, command, self.env_id)
        except CardError as exc:
            raise LabEnvError(str(exc)) from None


def find_lab_env(name: str) -> LabEnv:
    """The env ``name`` names: a card's short name, a registered id, or an id without its
    namespace. :class:`LabEnvError`: no installed package registers it (the message lists
    the registered ids), or its package's card was refused (the refusal)."""
    try:
        env_id, card = find_env(name)
    except KeyError as exc:
        raise LabEnvError(str(exc.args[0])) from None
    except CardError as exc:
        raise LabEnvError(str(exc)) from None
    return LabEnv(env_id, card)


def lab_envs() -> list[LabEnv]:
    """Every registered env whose card was not refused, in registration order."""
    out = []
    for env_id in registered_ids():
        try:
            out.append(LabEnv(env_id, card_for(env_id)))
        except CardError:
            continue
    return out


def names_where(field_name: str) -> str:
    """The names of the registered envs whose card declares ``field_name`` (for messages)."""
    having = [env.name for env in lab_envs() if getattr(env.card, field_name) not in (None, False)]
    return ", ".join(having) or "none installed"


def default_frequency(env: Any) -> float:
    """A forcing frequency (Hz) for an env whose card names none: a tenth of its action
    rate (``1 / dt`` of the built env), else 1 Hz."""
    inner = getattr(env, "unwrapped", env)
    for attr in ("action_time", "dt"):
        value = getattr(inner, attr, None)
        if isinstance(value, (int, float)) and value > 0:
            return 0.1 / float(value)
    return 1.0


def default_out(env: LabEnv, command: str) -> Path:
    """``runs/<env name>/<command>``: where a command writes without ``--out``."""
    return Path("runs") / env.name / command
