"""From one RL action to the data the controller writes in each time window of a step.

An action is first checked against the action space (refused if it has the wrong shape or
is not finite, clipped to a Box's bounds), then spread over the step's windows by the
configured :class:`~gymprecice.actions.ActionSchedule`, and each window's value is turned by
the user's ``_get_action`` into data on every written interface, checked against the
interface's vertices and the data's dimension.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from gymprecice.env.actions import ActionSchedule
from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.returned_values import find_written
from gymprecice.env.values import DataRef
from gymprecice.plugin.solver import InterfaceGeometry

__all__ = ["ActionShaper"]

log = logging.getLogger("gymprecice.core")

#: The user's ``_get_action(value, write_var_list)``.
GetAction = Callable[[Any, list[DataRef]], Mapping[Any, Any]]


class ActionShaper:
    """One env's actions: checked, spread over windows, and turned into written data."""

    def __init__(self, config: GymPreciceConfig, write_refs: Sequence[DataRef]) -> None:
        actions = config.model.actions
        self.schedule = ActionSchedule(actions.scheme, actions.windows, actions.filter_alpha)
        self._precice = config.precice
        self._write_refs = list(write_refs)
        self._clipping_reported = False

    def checked(self, action: Any, space: gym.Space, env_index: int) -> Any:
        """Refuse an action the action space cannot hold; clip one outside its bounds.

        A wrong shape would be spread and written as something else, and one NaN makes
        every later observation NaN, so both raise ``ValueError``. Values outside a Box's
        bounds are clipped to them, as Gymnasium's ``ClipAction`` does, and the first
        clipping of the env is logged.
        """
        if not isinstance(space, gym.spaces.Box):
            return action
        try:
            values = np.asarray(action, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"env {env_index}: the action {action!r} is not numeric; the action space "
                f"is {space}"
            ) from None
        if values.shape != space.shape:
            raise ValueError(
                f"env {env_index}: the action has shape {values.shape}, but the action "
                f"space {space} expects shape {space.shape}"
            )
        if not np.all(np.isfinite(values)):
            raise ValueError(
                f"env {env_index}: the action {values.tolist()} is not finite (NaN or "
                "infinity); check the policy's output"
            )
        clipped = np.clip(values, space.low, space.high)
        if np.array_equal(clipped, values):
            return action
        if not self._clipping_reported:
            self._clipping_reported = True
            log.warning(
                "env %d: action %s is outside the action space's bounds [%s, %s] and was "
                "clipped (reported once per env)",
                env_index,
                values.tolist(),
                space.low.tolist(),
                space.high.tolist(),
            )
        return clipped.astype(space.dtype)

    def windows_left(self, time: float, dt: float | None, end_time: float | None) -> int:
        """Windows the next step spans: all of them, or what is left until the end time.

        A last partial window counts as one (preCICE shortens it); a remainder below a
        millionth of a window is rounding noise in ``time``, not a window.
        """
        n = self.schedule.windows
        if end_time is None or not dt:
            return n
        left = math.ceil((end_time - time) / dt - 1e-6)
        return max(1, min(n, left))

    def frame_interval(self, window: float | None) -> float | None:
        """Coupling time of one action (``window``: the configured time window size)."""
        return None if not window else window * self.schedule.windows

    def written(
        self,
        value: Any,
        get_action: GetAction,
        geometry: Callable[[], Mapping[str, InterfaceGeometry]],
    ) -> dict[tuple[str, str], np.ndarray]:
        """The data of one window: ``_get_action(value, write_var_list)``, checked.

        ``geometry()`` is the env's interface geometry, whose vertex counts the data must
        match.
        """
        if not self._write_refs:
            return {}
        produced = get_action(value, list(self._write_refs))
        out: dict[tuple[str, str], np.ndarray] = {}
        for ref in self._write_refs:
            array = find_written(produced, ref, self._write_refs)
            if array is None:
                raise KeyError(
                    f"_get_action returned no data for {ref} (interface {ref.interface!r}, data "
                    f"{ref.data!r}); return a dict keyed by the entries of write_var_list"
                )
            n = len(geometry()[ref.interface].coordinates)
            out[(ref.mesh, ref.data)] = self._shaped(ref, array, n)
        return out

    def _shaped(self, ref: DataRef, array: Any, n: int) -> np.ndarray:
        width = self._precice.data_dimension(ref.data, ref.mesh)
        values = np.asarray(array, dtype=float)
        expected = (n,) if width == 1 else (n, width)
        if values.shape != expected:
            try:
                values = values.reshape(expected)
            except ValueError:
                raise ValueError(
                    f"_get_action gave {ref} with shape {values.shape}; expected {expected} "
                    f"({n} vertices of interface {ref.interface!r}"
                    + (")" if width == 1 else f", {width}-D vector data)")
                ) from None
        return values
