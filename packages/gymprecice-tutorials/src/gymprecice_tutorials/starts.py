"""The held-out starts of an environment: the starts training never sees.

An env that keeps some starts out of training (the fast cylinders' held-out snapshots,
the flap's held-out gusts) names them in a ``held_out_starts`` property and takes the
k-th with ``reset(options={"split": "eval", "start": k})``. Evaluating from *every* one
of them, rather than from the one a seed happens to draw, is what makes an evaluation
comparable between controllers and seeds: every controller meets the same starts.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

__all__ = [
    "HeldOutStarts",
    "NoHeldOutStarts",
    "held_out_starts",
    "require_held_out_starts",
    "start_options",
]


class NoHeldOutStarts(ValueError):
    """The environment has no held-out starts to evaluate on."""


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


def require_held_out_starts(env: gym.Env, env_info: Any) -> tuple[str, ...]:
    """``env``'s held-out starts; :class:`NoHeldOutStarts` naming the envs that have them."""
    starts = held_out_starts(env)
    if not starts:
        from gymprecice_tutorials.environments import ENVIRONMENTS

        having = ", ".join(e.name for e in ENVIRONMENTS.values() if e.held_out_starts)
        raise NoHeldOutStarts(
            f"{env_info.name} has no held-out starts (its episodes all start from one "
            f"state, which training sees too), so an evaluation on it cannot be told from "
            f"one on the training data; use an env with held-out starts ({having}), or give "
            f"your case a snapshot library (the OpenFOAM solver option 'snapshots')"
        )
    return starts


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
