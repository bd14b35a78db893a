"""What ``Adapter.render()`` asks of the solvers, and the frame it returns.

An env names the fields to draw in ``render_fields`` (``{solver: field or fields}``); they
are checked against the configuration at reset (each rendering solver is told which fields
to write, and how often: once per action), and at render time read from each solver's
plugin (``gymprecice_read_field``) at the current coupling time and drawn by
:class:`~gymprecice.rendering.FrameRenderer`, the env's overlay on top.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from gymprecice import lifecycle
from gymprecice.config import GymPreciceConfig
from gymprecice.coupled_run import CoupledRun
from gymprecice.errors import ConfigError
from gymprecice.fields import Field, Overlay
from gymprecice.plugins import solver_kinds

__all__ = ["Frames", "checked_render_mode", "field_requests"]


def checked_render_mode(
    render_mode: str | None, metadata: Mapping[str, Any], cls: type
) -> str | None:
    """``render_mode`` if the env's metadata lists it; else a ValueError naming them."""
    if render_mode is None:
        return None
    modes = list(metadata.get("render_modes", []))
    if render_mode not in modes:
        raise ValueError(
            f"{cls.__name__} does not support render_mode={render_mode!r}; the supported "
            f"render modes are {modes} (metadata['render_modes'])"
        )
    return render_mode


def field_requests(
    cls: type,
    render_mode: str | None,
    render_fields: Mapping[str, str | Sequence[str]],
    config: GymPreciceConfig,
) -> dict[str, tuple[str, ...]]:
    """``render_fields`` checked against the solvers: ``{}`` when not rendering."""
    if render_mode is None:
        return {}
    requests: dict[str, tuple[str, ...]] = {}
    for solver, names in dict(render_fields).items():
        if solver not in config.solvers:
            raise ConfigError(
                f"{cls.__name__}.render_fields names solver {solver!r}, which "
                f"{config.where()} does not define; the solvers are "
                f"{sorted(config.solvers)}"
            )
        requests[solver] = (names,) if isinstance(names, str) else tuple(names)
    if not requests:
        raise ConfigError(
            f"{cls.__name__} has render_mode={render_mode!r} but draws no "
            "field: set render_fields, e.g. {'fluid': 'p'} (solver name: field name)"
        )
    return requests


class Frames:
    """Reads the requested fields of one env's solvers and draws them (renderer kept)."""

    def __init__(self, run: CoupledRun) -> None:
        self._run = run
        self._renderer: Any = None

    def draw(
        self,
        requests: Mapping[str, tuple[str, ...]],
        *,
        time: float,
        window: float | None,
        size: tuple[int, int],
        overlay: Callable[[], Overlay | None],
        title: str,
    ) -> np.ndarray:
        """One frame of the fields in ``requests`` at coupling time ``time``."""
        run = self._run
        layers: list[tuple[str, Field]] = []
        kinds = solver_kinds()
        for solver, names in requests.items():
            ctx = run.solvers[solver]
            for name in names:
                field = lifecycle.read_field(
                    run.hook,
                    ctx,
                    name,
                    time,
                    tolerance=1e-3 * (window or 1.0),
                    timeout=run.timeouts.progress,
                    alive=run.solvers_alive,
                    plugin=kinds[ctx.kind].plugin if ctx.kind in kinds else None,
                )
                layers.append((f"{solver}/{name}", field))
        if self._renderer is None:
            from gymprecice.rendering import FrameRenderer

            self._renderer = FrameRenderer(*size)
        return self._renderer.draw(layers, overlay(), title)
