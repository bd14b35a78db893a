"""The fixed controllers of the rollout commands: the uncontrolled flow, a sinusoid, and
the point of an env's own feedback law that ``gymprecice feedback --law`` runs.

A controller is ``controller(observation, time) -> action``; one with a ``reset()``
method has it called at every episode's start, one with ``observe(info)`` sees every
step's ``info`` (how a feedback law measures its signal,
:mod:`gymprecice_lab.rollouts.feedback`). The loop that runs them is
:mod:`gymprecice_lab.rollouts.rollout`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.plugin.card import FeedbackLaw, load_object
from gymprecice_lab.common.registered_env import LabEnv

__all__ = ["Controller", "law_point", "sine_controller", "zero_controller"]


#: ``controller(observation, time) -> action`` (in the env's own action space)
Controller = Callable[[Any, float], Any]


def zero_controller(space: gym.Space) -> Controller:
    """The uncontrolled flow: the zero action clipped into the action box (the box's
    nearest bound where zero lies outside it), in the env's own units."""
    if isinstance(space, gym.spaces.Box):
        action = np.clip(np.zeros(space.shape), space.low, space.high).astype(space.dtype)
    else:
        raise TypeError(f"baseline needs a Box action space, got {space}")
    return lambda obs, t: action


def sine_controller(
    space: gym.Space,
    amplitude: float,
    frequency: float,
    phase: float = 0.0,
    centre: float = 0.5,
) -> Controller:
    """``centre + amplitude * half_range * sin(2 pi f t + phase)`` on every action dimension,
    clipped to the box; ``centre`` is a fraction of the box (0.5: its middle)."""
    if not isinstance(space, gym.spaces.Box):
        raise TypeError(f"open-loop needs a Box action space, got {space}")
    centre = space.low + centre * (space.high - space.low)
    half = (space.high - space.low) / 2.0

    def act(obs: Any, t: float) -> np.ndarray:
        value = centre + amplitude * half * math.sin(2.0 * math.pi * frequency * t + phase)
        return np.clip(value, space.low, space.high).astype(space.dtype)

    return act


def law_point(env_info: LabEnv, text: str | None) -> tuple[FeedbackLaw, dict[str, float]] | None:
    """``gymprecice feedback --law "kp=3;ki=50;kd=1"``: the env's own feedback law and the
    one point of it to run (``None``: the env's feedback is a signal fed back). Checked
    before any env is built; a ``ValueError`` says what is missing."""
    if env_info.feedback_law is None:
        if text:
            raise ValueError(
                f"{env_info.name} has no feedback law of its own for --law (lab card field "
                "'feedback_law'); its classical feedback is a signal fed back (--signal, "
                "--gain, --delay)"
            )
        return None
    law = load_object(env_info.feedback_law, "feedback_law")
    example = law.grid_text({n: [v[0]] for n, v in law.default_grid().items()})
    if not text:
        raise ValueError(
            f"{env_info.name}'s classical feedback is its {law.name} law ({law.summary}); "
            f'pass --law with one value of each parameter, e.g. --law "{example}" '
            f"(`gymprecice sweep {env_info.name}` tunes it)"
        )
    grid = law.parse_grid(text, "--law")
    several = [n for n in law.parameters if len(grid[n]) != 1]
    if several:
        raise ValueError(
            f"--law runs one {law.name} controller: give {', '.join(several)} one value "
            f'each, e.g. --law "{example}" (`gymprecice sweep` tunes a grid)'
        )
    (point,) = law.points(grid)
    return law, point
