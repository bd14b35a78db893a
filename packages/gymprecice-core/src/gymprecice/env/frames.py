"""What ``Adapter.render()`` asks of the solvers, and the frame it returns.

An env names the fields to draw in ``render_fields`` (``{solver: field or fields}``); they
are checked against the configuration at reset (each rendering solver is told which fields
to write, and how often: once per action), and at render time read from each solver's
plugin (``gymprecice_read_field``) at the current coupling time and drawn by
:class:`~gymprecice.rendering.FrameRenderer`, the env's overlay on top. The same quantity
of several solvers (two flaps' displacement) is drawn as one layer (:func:`shared_layers`).
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from gymprecice.env import lifecycle
from gymprecice.env.config import GymPreciceConfig
from gymprecice.env.coupled_run import CoupledRun
from gymprecice.plugin.errors import ConfigError
from gymprecice.plugin.fields import Field, Overlay
from gymprecice.plugin.manager import solver_kinds

__all__ = ["Frames", "checked_render_mode", "field_requests", "shared_layers"]


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


def shared_layers(layers: Sequence[tuple[str, Field]]) -> list[tuple[str, Field]]:
    """``layers`` (``("solver/name", Field)``) as a frame of several participants shows them.

    Solvers of the same kind hand over the same quantity under the same label (two
    deal.II flaps: ``displacement``, ``|u| [m]`` twice). Fields of one name and label
    that all carry their own triangles are drawn as one layer (``"upstream+downstream/
    displacement"``): one colour bar and one colour scale for all of them, so the flaps
    compare at a glance. Any label still shown twice (fields without triangles, which
    one triangulation would bridge) gets its solver's name in front, so the colour bars
    tell whose field they are.
    """
    groups: dict[tuple[str, str], list[int]] = {}
    for index, (label, field) in enumerate(layers):
        if field.triangles is not None:
            groups.setdefault((field.name, field.label or label), []).append(index)
    joined: dict[int, tuple[str, Field]] = {}
    dropped: set[int] = set()
    for members in groups.values():
        if len(members) > 1:
            joined[members[0]] = _joined([layers[i] for i in members])
            dropped.update(members[1:])
    out = [joined.get(i, layer) for i, layer in enumerate(layers) if i not in dropped]
    shown = Counter(field.label or label for label, field in out)
    named = []
    for label, field in out:
        text = field.label or label
        if shown[text] > 1:
            field = dataclasses.replace(field, label=f"{label.split('/', 1)[0]} {text}")
        named.append((label, field))
    return named


def _joined(layers: Sequence[tuple[str, Field]]) -> tuple[str, Field]:
    """One field of several solvers' meshes, their triangles renumbered."""
    fields = [field for _, field in layers]
    offsets = np.cumsum([0] + [len(f.points) for f in fields[:-1]])
    same_width = len({f.values.shape[1:] for f in fields}) == 1
    moved = any(f.displacement is not None for f in fields)
    first = fields[0]
    joined = Field(
        first.name,
        max(f.time for f in fields),
        np.concatenate([f.points for f in fields]),
        np.concatenate([f.values if same_width else f.scalar for f in fields]),
        triangles=np.concatenate(
            [f.triangles + k for f, k in zip(fields, offsets, strict=True)]  # type: ignore[operator]
        ),
        displacement=(
            np.concatenate(
                [
                    f.displacement if f.displacement is not None else np.zeros_like(f.points)
                    for f in fields
                ]
            )
            if moved
            else None
        ),
        label=first.label,
    )
    solvers = "+".join(label.split("/", 1)[0] for label, _ in layers)
    return f"{solvers}/{first.name}", joined


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
        size: tuple[int, int | None],
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
                    exited=run.session is None,  # the episode is over: its solvers are gone
                )
                layers.append((f"{solver}/{name}", field))
        if self._renderer is None:
            from gymprecice.env.rendering import FrameRenderer

            self._renderer = FrameRenderer(*size)
        return self._renderer.draw(shared_layers(layers), overlay(), title)
