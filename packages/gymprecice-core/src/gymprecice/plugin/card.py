"""An environment's lab card: what training, evaluation and benchmarking need beyond Gymnasium.

The Gymnasium API says how to step an env; it does not say which number to compare
controllers on, which starts training must never see, what "uncontrolled" means, or which
classical controller is the one to beat. A package declares that once, when it registers
the env, as a field of the registration::

    from gymprecice.plugin.card import EnvCard
    from gymprecice.plugin.hookspecs import hookimpl


    @hookimpl
    def gymprecice_register_environments(register):
        register(
            "mylab/Channel-v0",
            "my_package.env:ChannelEnv",
            card=EnvCard(name="channel", objective="mean_tip_displacement"),
        )

Every field has a default derived from the env itself, so an env registered without a
card gets one too (:func:`card_for`): the objective is the negated mean reward, the starts
are seeds, "uncontrolled" is the zero action clipped into the action box (in the env's
own units), the other baselines are constants and sinusoids over the action box, and
figures are labelled from the spaces. A command that needs a field the card
leaves out (``time-to-floor`` without a ``reference``) says which field and how to
declare it, before it makes anything.

A card is checked when it is registered; a malformed one (a field of the wrong type) is
refused then, naming the package and the field (:class:`CardError`), and the lab reports
that refusal for the env instead of running with a guess.

This module is part of core so that declaring a card needs core alone: the lab
(``gymprecice-lab``) reads cards; environment packages never import it.
"""

from __future__ import annotations

import importlib
import itertools
import math
import re
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

__all__ = [
    "CardError",
    "EnvCard",
    "FeedbackLaw",
    "Reference",
    "card_for",
    "card_package",
    "declared_cards",
    "find_env",
    "load_object",
    "record_card",
    "refused_cards",
    "registered_ids",
]

#: a grid of a feedback law's parameters: each name with the values to try, in order
Grid = dict[str, list[float]]


class CardError(ValueError):
    """A lab card that cannot be used: a field of the wrong type, or one a command needs
    that the card does not declare. The text names the env (or package) and the field."""


@dataclass(frozen=True)
class Reference:
    """A physical reference for the objective: where it is uncontrolled and the best it can
    physically reach (a cylinder's *drag floor*: the drag of the steady symmetric flow).

    A controller's *fraction of the floor* is how much of the drop between them it takes,
    ``(uncontrolled - value) / (uncontrolled - floor)`` of the mean of ``metric``
    (``info["metrics"][metric]``): 1 is the whole drop. *Settled* values leave out the
    first ``settle_time`` seconds of an episode. ``gymprecice time-to-floor`` and the
    benchmark's fraction columns read it.
    """

    metric: str
    uncontrolled: float
    floor: float
    settle_time: float = 0.0
    #: how tables and figures name the reference ("drag floor")
    label: str = "floor"

    def check(self) -> None:
        """:class:`CardError` naming the field whose value is not of its type."""
        _check_fields(self, "Reference")
        if self.uncontrolled == self.floor:
            raise CardError("Reference: 'uncontrolled' and 'floor' must differ")

    def fraction(self, value: float) -> float:
        """The fraction of the drop from uncontrolled to the floor that ``value`` reaches."""
        return (self.uncontrolled - value) / (self.uncontrolled - self.floor)


@dataclass(frozen=True)
class FeedbackLaw:
    """A family of classical feedback controllers that an env names as its textbook one.

    ``build(space, settings)`` returns a controller for one point of the family: called
    as ``controller(obs, t)`` with the env's own observation (never normalised) and
    returning an action in its own units, with optional ``reset()`` at each episode's
    start and ``observe(info)`` after each step. ``grid`` is the documented tuning
    sweep's grid, the default of ``gymprecice sweep --feedback-grid``.
    """

    name: str
    summary: str
    grid: tuple[tuple[str, tuple[float, ...]], ...]
    build: Callable[[Any, Mapping[str, float]], Any]

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.grid)

    def default_grid(self) -> Grid:
        return {name: [float(v) for v in values] for name, values in self.grid}

    def parse_grid(self, text: str, flag: str = "--feedback-grid") -> Grid:
        """``"kp=2,3;ki=25,50"`` -> the law's grid with those values (others: defaults).

        Assignments are separated by ``;`` or spaces; an unknown parameter, a missing
        ``=`` or a value that is not a finite number is an error naming ``flag`` (the
        option the text came from) and the law's parameters."""
        grid = self.default_grid()
        tight = re.sub(r"\s*([=,])\s*", r"\1", text)  # "kp = 2, 3" is "kp=2,3"
        for item in tight.replace(";", " ").split():
            name, sep, values = item.partition("=")
            if not sep or name not in grid:
                raise ValueError(
                    f"{flag} takes NAME=V1,V2,... for the {self.name} law's "
                    f"parameters ({', '.join(self.parameters)}); got {item!r}"
                )
            try:
                numbers = [float(v) for v in values.split(",") if v.strip()]
            except ValueError:
                numbers = []
            if not numbers or not all(math.isfinite(v) for v in numbers):
                raise ValueError(
                    f"{flag} {name}= needs comma-separated finite numbers, got {values!r}"
                )
            grid[name] = numbers
        return grid

    def grid_text(self, grid: Grid) -> str:
        """``grid`` as ``--feedback-grid`` takes it, every parameter named."""
        return ";".join(f"{n}={','.join(f'{v:g}' for v in grid[n])}" for n in self.parameters)

    def points(self, grid: Grid) -> list[dict[str, float]]:
        """Every combination of the grid's values, the last parameter varying fastest."""
        names = self.parameters
        return [
            dict(zip(names, values, strict=True))
            for values in itertools.product(*(grid[n] for n in names))
        ]

    def label(self, settings: Mapping[str, float]) -> str:
        """``pid-kp3-ki50-kd1``: one point of the family, as tables and run dirs name it."""
        return "-".join([self.name, *(f"{n}{settings[n]:g}" for n in self.parameters)])


@dataclass(frozen=True, eq=True)
class EnvCard:
    """What the lab needs to know of an environment beyond the Gymnasium API.

    Every field is optional; the comment above each says its default and which commands
    read it (docs: "Lab reference").
    """

    #: a short command-line name (``gymprecice train channel``); default: the id alone
    name: str | None = None
    #: one line for listings and figure titles; default: the id
    description: str = ""
    #: the ``info["metrics"]`` entry that sweep, benchmark and compare rank controllers
    #: on; default ``None``: the negated mean reward
    objective: str | None = None
    #: whether a larger objective is better (default: lower is better, as drag or error)
    maximize: bool = False
    #: further ``info["metrics"]`` entries that evaluate's tables and figures report
    metrics: tuple[str, ...] = ()
    #: whether the env keeps starts out of training: it has a ``held_out_starts``
    #: property (their labels) and takes ``reset(options={"split": "eval", "start": k})``;
    #: default: starts are seeds (evaluate and benchmark draw them from seeds)
    held_out_starts: bool = False
    #: whether the env keeps a second set of starts for *choosing* among models (the
    #: model a training run keeps): it has a ``validation_starts`` property (their labels)
    #: and takes ``reset(options={"split": "validation", "start": k})``; they are disjoint
    #: from the held-out starts and from anything training draws, so the held-out starts
    #: judge a controller without having chosen it. Default: none declared, and the lab
    #: derives them (:func:`gymprecice_lab.starts.validation_starts`)
    validation_starts: bool = False
    #: env keyword arguments of the uncontrolled (reference) setting, where no action
    #: means it; default: none, the zero action clipped into the action box (in the
    #: env's own units) stands for "uncontrolled" (baseline, sweep, benchmark)
    uncontrolled: Mapping[str, Any] = field(default_factory=dict)
    #: the ``info["metrics"]`` entry that ``gymprecice feedback`` feeds back (``--signal``)
    feedback_signal: str | None = None
    #: ``"module:attribute"`` of the env's own :class:`FeedbackLaw` (a PID, ...) that
    #: sweep and benchmark tune instead of a signal fed back
    feedback_law: str | None = None
    #: a physical reference for the objective (a drag floor): time-to-floor needs it
    reference: Reference | None = None
    #: ``"package:folder"`` holding the package's shipped policies, one folder each
    #: (``gymprecice policies``, ``--policy shipped``)
    policies: str | None = None
    #: the shipped policy ``--policy shipped`` means (default: the one named after ``name``)
    shipped_policy: str | None = None
    #: id or name of a cheaper case of the same task to train on (documentation, benchmark)
    training_case: str | None = None
    #: whether the env takes ``double=True``: the same task on gymprecice's preCICE test
    #: double (fake solvers), which ``--double`` selects
    double: bool = False
    #: whether the env takes ``episode_time=`` (``--episode-time``)
    episode_time: bool = False
    #: evaluate's default simulated seconds per episode (default: the env's own episode)
    rollout_time: float | None = None
    #: ``gymprecice open-loop``'s and the baselines' forcing frequency in Hz (default:
    #: a tenth of the action rate, or 1 Hz)
    open_loop_frequency: float | None = None
    #: the action's unit for figures (default: none, "action")
    action_unit: str = ""
    #: the action's bound for figures (default: the action space's)
    action_bound: float | None = None
    #: the ``gymprecice doctor`` checks the env needs on real solvers: a failed check
    #: counts when its name, in lower case, starts with one of these (``"openfoam"``
    #: covers OpenFOAM and its preCICE adapter); default: pyprecice, and every check the
    #: doctor marks required. Commands stop in one line when one is missing (``--double``
    #: needs none)
    solver_checks: tuple[str, ...] = ()
    #: the checks that replace ``solver_checks`` where the env is made with one keyword
    #: argument's value, keyed ``"keyword=value"``: ``{"solid=fenics": ("pyprecice",
    #: "openfoam", "fenics")}`` for an env whose ``solid="fenics"`` runs another solver;
    #: the first key that the env's keyword arguments match wins (default: none)
    solver_checks_with: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    #: the agents of a joint multi-agent env (:class:`gymprecice.multiagent.JointEnv`),
    #: one per row of its observation and action, in row order: ``train --shared-policy``
    #: trains one policy that every agent shares (each row is one agent's sample), and the
    #: lab runs such a policy on every row; default: none, one controller for the env
    agents: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # Plain containers, so a card pickles (Ray tasks, worker processes). Field types are
        # checked by check(), which registration calls: a card built with a wrong type in a
        # package's hook is then refused for that env alone, naming the package and field,
        # instead of breaking the hook and leaving the env unregistered.
        if isinstance(self.uncontrolled, Mapping):
            object.__setattr__(self, "uncontrolled", dict(self.uncontrolled))
        if isinstance(self.solver_checks_with, Mapping):
            checks = {
                key: tuple(value) if isinstance(value, list) else value
                for key, value in self.solver_checks_with.items()
            }
            object.__setattr__(self, "solver_checks_with", checks)
        for listed in ("metrics", "solver_checks", "agents"):
            if isinstance(getattr(self, listed), list):
                object.__setattr__(self, listed, tuple(getattr(self, listed)))

    def check(self) -> None:
        """:class:`CardError` naming the first field whose value is not of its type."""
        _check_fields(self, "EnvCard")
        if self.reference is not None:
            self.reference.check()
        for key, checks in self.solver_checks_with.items():
            keyword, sep, _ = str(key).partition("=")
            if not (isinstance(key, str) and sep and keyword.strip()) or not _is_instance(
                checks, tuple[str, ...]
            ):
                raise CardError(
                    "EnvCard field 'solver_checks_with' maps 'keyword=value' to a tuple of "
                    f"check names, got {key!r}: {checks!r}"
                )
        for spec_field in ("feedback_law", "policies"):
            value = getattr(self, spec_field)
            if value is not None and ":" not in value:
                raise CardError(
                    f"EnvCard field {spec_field!r} is 'package.module:attribute' "
                    f"(or 'package:folder' for policies), got {value!r}"
                )

    def require(self, field_name: str, command: str, env_id: str) -> Any:
        """The value of ``field_name``; :class:`CardError` naming the field and how to
        declare it when the card leaves it out."""
        value = getattr(self, field_name)
        if value is None or value == () or value is False:
            raise CardError(
                f"{command} needs the lab card field {field_name!r} of {env_id}, "
                f"which its package does not declare: pass card=EnvCard({field_name}=...) "
                f"to register() in its gymprecice_register_environments hook (docs: Lab "
                f"reference)"
            )
        return value

    def checks_for(self, kwargs: Mapping[str, Any]) -> tuple[str, ...]:
        """The ``solver_checks`` of the env made with ``kwargs``: the first entry of
        ``solver_checks_with`` whose ``keyword=value`` they match, else ``solver_checks``."""
        for key, checks in self.solver_checks_with.items():
            keyword, _, value = key.partition("=")
            keyword, value = keyword.strip(), value.strip()
            if keyword in kwargs and str(kwargs[keyword]) == value:
                return tuple(checks)
        return self.solver_checks


# -- the registry of declared cards ------------------------------------------------------

#: env id -> (card, declaring package)
_cards: dict[str, tuple[EnvCard, str]] = {}
#: env id -> why its declared card was refused
_refused: dict[str, str] = {}
#: env id -> the package that registered it, card or not (the ids ``find_env`` knows)
_packages: dict[str, str] = {}


def record_card(env_id: str, card: Any, package: str) -> EnvCard | None:
    """Note that ``package`` registered ``env_id``; check and keep its ``card``, if any
    (called by :mod:`gymprecice.registration` for every id a plugin registers).

    ``card`` is an :class:`EnvCard`, a mapping of its fields, or ``None`` (no card: every
    field's default). A malformed card raises :class:`CardError` naming the package and
    the field, and is remembered as refused."""
    _packages.setdefault(env_id, package)
    if card is None:
        return None
    try:
        if isinstance(card, Mapping):
            unknown = sorted(set(card) - {f.name for f in fields(EnvCard)})
            if unknown:
                raise CardError(
                    f"unknown EnvCard field {unknown[0]!r} (fields: "
                    f"{', '.join(f.name for f in fields(EnvCard))})"
                )
            card = EnvCard(**card)
        elif not isinstance(card, EnvCard):
            raise CardError(f"card= takes an EnvCard or a mapping, got {type(card).__name__}")
        card.check()
    except (CardError, TypeError) as exc:
        message = f"the lab card of {env_id} from package {package!r} is refused: {exc}"
        _refused[env_id] = message
        raise CardError(message) from None
    _cards[env_id] = (card, package)
    _refused.pop(env_id, None)
    return card


def declared_cards() -> dict[str, EnvCard]:
    """Every env id whose package declared a card, with that card."""
    _ensure_registered()
    return {env_id: card for env_id, (card, _) in _cards.items()}


def refused_cards() -> dict[str, str]:
    """Env ids whose declared card was refused, with why."""
    _ensure_registered()
    return dict(_refused)


def card_for(env_id: str) -> EnvCard:
    """The card of ``env_id``: the declared one, else every field's default.

    Raises :class:`CardError` when the env's package declared a card that was refused."""
    _ensure_registered()
    if env_id in _refused:
        raise CardError(_refused[env_id])
    entry = _cards.get(env_id)
    return entry[0] if entry else EnvCard()


def card_package(env_id: str) -> str | None:
    """The package that registered ``env_id`` (``None``: no gymprecice plugin did)."""
    _ensure_registered()
    return _packages.get(env_id)


def registered_ids() -> list[str]:
    """Every env id a gymprecice plugin registered, in registration order."""
    _ensure_registered()
    return list(_packages)


def find_env(name: str) -> tuple[str, EnvCard]:
    """Look an env up by short name (a card's ``name``), full id or id without namespace.

    Raises :class:`KeyError` listing every registered gymprecice id when nothing matches."""
    import gymnasium

    _ensure_registered()
    key = name.strip()
    for env_id, (card, _) in _cards.items():
        if key == card.name:
            return env_id, card_for(env_id)
    ids = list(_packages)
    for env_id in ids:
        if key in (env_id, env_id.split("/", 1)[-1]):
            return env_id, card_for(env_id)
    if key in gymnasium.registry:
        return key, card_for(key)
    names = [
        f"{card.name} ({env_id})" if card.name else env_id for env_id, (card, _) in _cards.items()
    ]
    names += [env_id for env_id in ids if env_id not in _cards]
    names += [f"{env_id} (card refused)" for env_id in _refused if env_id not in _cards]
    raise KeyError(
        f"no registered gymprecice environment {name!r}; installed packages register: "
        f"{', '.join(names) or 'none'} (install the package that registers it)"
    )


def load_object(spec: str, field_name: str) -> Any:
    """The object at ``"module:attribute"`` that a card field names; :class:`CardError`
    naming the field when the module cannot be imported or lacks the attribute."""
    module_name, _, attribute = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise CardError(
            f"card field {field_name!r} names {spec!r}, whose module does not import: "
            f"{type(exc).__name__}: {exc}"
        ) from exc
    try:
        value = getattr(module, attribute)
    except AttributeError:
        raise CardError(f"card field {field_name!r}: {module_name} has no {attribute!r}") from None
    if field_name == "feedback_law" and not isinstance(value, FeedbackLaw):
        raise CardError(
            f"card field 'feedback_law': {spec} is a {type(value).__name__}, not a "
            "gymprecice.card.FeedbackLaw"
        )
    return value


def _ensure_registered() -> None:
    """Cards are recorded while the plugins register their envs (on ``import gymprecice``)."""
    import gymprecice  # noqa: F401  (registers every installed plugin's envs and cards)


def _check_fields(obj: Any, kind: str) -> None:
    """Refuse a field whose value is not of its annotated type (ints pass for floats)."""
    hints = typing.get_type_hints(type(obj))
    for f in fields(obj):
        value = getattr(obj, f.name)
        if not _is_instance(value, hints[f.name]):
            raise CardError(
                f"{kind} field {f.name!r} takes {_type_name(hints[f.name])}, got "
                f"{type(value).__name__} {value!r}"
            )


def _is_instance(value: Any, hint: Any) -> bool:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_is_instance(value, arg) for arg in typing.get_args(hint))
    if hint is Any:
        return True
    if hint is type(None):
        return value is None
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if origin is tuple:
        return isinstance(value, (tuple, list)) and all(isinstance(v, str) for v in value)
    if origin is not None:
        if origin is Callable or origin is typing.get_origin(Callable[[], None]):
            return callable(value)
        return isinstance(value, origin)
    return isinstance(value, hint)


def _type_name(hint: Any) -> str:
    if isinstance(hint, type):
        return hint.__name__  # "bool", not "<class 'bool'>"
    return str(hint).replace("typing.", "").replace("collections.abc.", "")
