"""The held-out starts of an environment: the starts training never sees.

An env that keeps some starts out of training (the fast cylinders' held-out snapshots,
the flap's held-out gusts) names them in a ``held_out_starts`` property and takes the
k-th with ``reset(options={"split": "eval", "start": k})``. Evaluating from *every* one
of them, rather than from the one a seed happens to draw, is what makes an evaluation
comparable between controllers and seeds: every controller meets the same starts.

An env without held-out starts (its card's ``held_out_starts`` left out) has seeds as its
starts: ``evaluate --all-starts``, ``sweep`` and ``benchmark`` run its first
:data:`SEED_STARTS` seeds of the held-out split (``reset(seed=s, options={"split":
"eval"})``), labelled ``seed s``, the same for every controller.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

__all__ = [
    "SEED_STARTS",
    "HeldOutStarts",
    "evaluation_starts",
    "held_out_starts",
    "seed_start_label",
    "start_options",
]

#: how many seeds stand for the starts of an env without held-out starts
SEED_STARTS = 5


def held_out_starts(env: gym.Env) -> tuple[str, ...]:
    """Labels of ``env``'s held-out starts, in index order (empty when it has none)."""
    return tuple(getattr(env.unwrapped, "held_out_starts", ()) or ())


def start_options(episode: int, starts: int) -> dict[str, Any]:
    """Reset options of ``episode``: the held-out split, start ``episode % starts`` when the
    env has held-out starts (every start in turn), else a start drawn by the seed."""
    options: dict[str, Any] = {"split": "eval"}
    if starts:
        options["start"] = episode % starts
    return options


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
