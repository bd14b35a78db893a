"""The held-out starts of an environment: the starts training never sees.

An env that keeps some starts out of training (the fast cylinders' held-out snapshots,
the flap's held-out gusts) names them in a ``held_out_starts`` property and takes the
k-th with ``reset(options={"split": "eval", "start": k})``. Evaluating from *every* one
of them, rather than from the one a seed happens to draw, is what makes an evaluation
comparable between controllers and seeds: every controller meets the same starts.

The lab card says which kind an env is (:class:`gymprecice.card.EnvCard`'s
``held_out_starts``), not the property alone: an env whose card leaves the flag out has
seeds as its starts, whatever its property holds: ``evaluate --all-starts``, ``sweep``
and ``benchmark`` run its first :data:`SEED_STARTS` seeds of the held-out split
(``reset(seed=s, options={"split": "eval"})``), labelled ``seed s``, the same for every
controller. A card that declares the flag for an env without the property is refused
(:class:`StartsError`). An env built outside the registry (no ``env.spec``) has no card:
its property alone decides.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

__all__ = [
    "SEED_STARTS",
    "VALIDATION_SEED",
    "HeldOutStarts",
    "StartsError",
    "ValidationStarts",
    "describe_starts",
    "evaluation_starts",
    "held_out_starts",
    "seed_start_label",
    "start_options",
    "validation_options",
    "validation_starts",
]

#: how many seeds stand for the starts of an env without held-out starts
SEED_STARTS = 5

#: the first seed of the validation starts the lab derives for an env that declares none:
#: far from the seeds that stand for held-out starts (``0 .. SEED_STARTS - 1``) and from
#: the training envs' seeds (the run's ``--seed`` plus the env's index)
VALIDATION_SEED = 1_000_003

#: how many validation starts the lab derives for an env that declares none
DERIVED_VALIDATION_STARTS = 3


class StartsError(ValueError):
    """A lab card that declares held-out starts for an env that names none."""


def held_out_starts(env: gym.Env) -> tuple[str, ...]:
    """Labels of ``env``'s held-out starts, in index order (empty when it has none).

    The env's lab card decides whether it has any (``held_out_starts``); the labels are
    its ``held_out_starts`` property. :class:`StartsError` when the card declares them
    and the env names none."""
    labels = tuple(getattr(env.unwrapped, "held_out_starts", ()) or ())
    env_id = _registered_id(env)
    if env_id is None:
        return labels
    from gymprecice.plugin.card import card_for

    if not card_for(env_id).held_out_starts:
        return ()
    if not labels:
        raise StartsError(
            f"the lab card of {env_id} declares held_out_starts=True, but the env names no "
            "held-out starts: give its class a held_out_starts property (their labels, in "
            "the order reset(options={'split': 'eval', 'start': k}) takes them), or drop "
            "the card field to evaluate from seeds"
        )
    return labels


def _registered_id(env: gym.Env) -> str | None:
    """The id ``env`` was made from (``None``: built outside the registry)."""
    spec = getattr(env.unwrapped, "spec", None) or getattr(env, "spec", None)
    return getattr(spec, "id", None)


def start_options(episode: int, starts: int) -> dict[str, Any]:
    """Reset options of ``episode``: the held-out split, start ``episode % starts`` when the
    env has held-out starts (every start in turn), else a start drawn by the seed."""
    options: dict[str, Any] = {"split": "eval"}
    if starts:
        options["start"] = episode % starts
    return options


def describe_starts(count: int, held_out: bool) -> str:
    """What ``count`` starts are, for a line of text: ``"3 held-out start(s)"``, or for an
    env whose card declares none, the seeds that stand for them."""
    if held_out:
        return f"{count} held-out start(s)"
    return (
        f"{count} seeded start(s) of the evaluation split (the env declares no held-out "
        "starts; each start is drawn by its reset seed)"
    )


def seed_start_label(seed: int) -> str:
    """The label of the start that seed ``seed`` draws (an env without held-out starts)."""
    return f"seed {seed}"


def evaluation_starts(env: gym.Env, seed: int = 0) -> tuple[str, ...]:
    """The starts every controller is evaluated from: ``env``'s held-out starts, else the
    seeds ``seed .. seed + SEED_STARTS - 1`` (their labels)."""
    return held_out_starts(env) or tuple(seed_start_label(seed + k) for k in range(SEED_STARTS))


def validation_starts(env: gym.Env) -> tuple[str, ...]:
    """Labels of the starts that choose among models (the model a training run keeps).

    An env whose lab card declares ``validation_starts`` names them in its
    ``validation_starts`` property and takes ``reset(options={"split": "validation",
    "start": k})``: disjoint from its held-out starts and from what training draws.

    An env that declares none gets :data:`DERIVED_VALIDATION_STARTS` seeds from
    :data:`VALIDATION_SEED` on, labelled ``validation seed s``: of the evaluation split
    where the env has no held-out starts (its test starts are that split's first seeds,
    never these), else of the training split, since every start of its evaluation split
    is held out; the training envs never reset with these seeds. The held-out starts
    never choose a model: no path here reads them.
    """
    env_id = _registered_id(env)
    labels = tuple(getattr(env.unwrapped, "validation_starts", ()) or ())
    declared = labels if env_id is None else ()
    if env_id is not None:
        from gymprecice.plugin.card import card_for

        if card_for(env_id).validation_starts:
            if not labels:
                raise StartsError(
                    f"the lab card of {env_id} declares validation_starts=True, but the env "
                    "names no validation starts: give its class a validation_starts "
                    "property (their labels, in the order reset(options={'split': "
                    "'validation', 'start': k}) takes them), or drop the card field to "
                    "let the lab derive them from seeds"
                )
            declared = labels
    if declared:
        return declared
    return tuple(f"validation seed {VALIDATION_SEED + k}" for k in range(DERIVED_VALIDATION_STARTS))


def _declares_validation(env: gym.Env) -> bool:
    """Whether ``env``'s validation starts are its own (not derived from seeds)."""
    env_id = _registered_id(env)
    if env_id is None:
        return bool(getattr(env.unwrapped, "validation_starts", ()) or ())
    from gymprecice.plugin.card import card_for

    return card_for(env_id).validation_starts


def validation_options(env: gym.Env, k: int) -> tuple[int | None, dict[str, Any]]:
    """``(seed, options)`` of the reset that takes validation start ``k`` (mod their
    number) of ``env`` (:func:`validation_starts`)."""
    count = len(validation_starts(env))
    if _declares_validation(env):
        return None, {"split": "validation", "start": k % count}
    split = "train" if held_out_starts(env) else "eval"
    return VALIDATION_SEED + k % count, {"split": split}


class ValidationStarts(gym.Wrapper):
    """Every reset from the validation starts, in turn (:func:`validation_starts`).

    For SB3's ``EvalCallback``, which resets its env with no options: reset k takes
    validation start k (mod their number). Derived starts are seeds: each reset reseeds
    the env with its start's seed, so every evaluation meets the same starts.

    ``part`` of ``parts`` splits the starts between ``parts`` envs that validate side by
    side: this one takes starts ``part, part + parts, ...`` in turn (``parts`` must divide
    their number, so that every round of the same number of episodes per env covers
    every start once whatever the order of the resets).
    """

    def __init__(self, env: gym.Env, part: int = 0, parts: int = 1) -> None:
        super().__init__(env)
        self.labels = validation_starts(env)
        if parts < 1 or len(self.labels) % parts or not 0 <= part < parts:
            raise ValueError(
                f"{len(self.labels)} validation starts cannot be split in {parts} parts"
            )
        self._mine = list(range(part, len(self.labels), parts))
        self._resets = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        k = self._mine[self._resets % len(self._mine)]
        start_seed, start = validation_options(self.env, k)
        self._resets += 1
        return self.env.reset(seed=start_seed, options={**start, **(options or {})})


class HeldOutStarts(gym.Wrapper):
    """Every reset from the held-out split, the held-out starts in turn.

    For an env whose resets the caller does not control (SB3's ``EvalCallback`` resets
    its env with no options): reset k takes held-out start k (mod their number); an env
    without held-out starts gets ``split="eval"`` alone. Options a caller does pass win.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._starts = len(held_out_starts(env))
        self._resets = 0

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        merged = {**start_options(self._resets, self._starts), **(options or {})}
        self._resets += 1
        return self.env.reset(seed=seed, options=merged)
