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
    "HeldOutStarts",
    "StartsError",
    "describe_starts",
    "evaluation_starts",
    "held_out_starts",
    "seed_start_label",
    "start_options",
]

#: how many seeds stand for the starts of an env without held-out starts
SEED_STARTS = 5


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
    from gymprecice.card import card_for

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
