"""The renderer keeps its figure between frames: a kept frame is the frame drawn afresh.

A frame after the first only hands the kept artists new values and redraws them over the
saved background; these tests hold that it draws exactly what a new renderer draws from
the same fields, including a moving geometry and a colour bar whose limits widen, and
that the figure is not rebuilt.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from gymprecice.env.rendering import FrameRenderer, hole_mask
from gymprecice.plugin.fields import Field, Overlay, grid_points

VARIANCE_FLOOR = 100.0


def _layers(t: float, spread: float) -> list[tuple[str, Field]]:
    """A channel's speed and a bending flap standing in it, at time ``t``."""
    points, triangles = grid_points(np.linspace(-2, 2, 41), np.linspace(0, 2, 21))
    speed = spread * (1.0 + np.sin(points[:, 0] * 2 + t) * points[:, 1])
    fluid = Field("U", t, points, speed, triangles=triangles, label="|U|")
    flap_points, flap_triangles = grid_points([-0.05, 0.05], np.linspace(0, 1, 6))
    bend = np.column_stack([0.2 * np.sin(t) * flap_points[:, 1] ** 2, np.zeros(12)])
    flap = Field("d", t, flap_points, bend, triangles=flap_triangles, displacement=bend)
    return [("fluid/U", fluid), ("solid/d", flap)]


def _overlay(t: float) -> Overlay:
    return Overlay(text=[f"jet {t:.1f}"], arrows=[(-2.0, 1.0, 0.3 * (1 + t), 0.0)])


def test_a_kept_frame_is_the_frame_a_new_renderer_draws() -> None:
    kept = FrameRenderer(320, 240)
    kept.draw(_layers(0.0, 1.0), _overlay(0.0), "t = 0")
    figure_axes = list(kept._figure.axes)
    second = kept.draw(_layers(1.0, 3.0), _overlay(1.0), "t = 1")  # the colour bar widens
    third = kept.draw(_layers(1.0, 3.0), _overlay(1.0), "t = 1")
    new = FrameRenderer(320, 240)
    new._scales = copy.deepcopy(kept._scales)  # the colour scales the episode widened to
    fresh = new.draw(_layers(1.0, 3.0), _overlay(1.0), "t = 1")
    assert kept._figure.axes == figure_axes  # not rebuilt
    assert second.var() > VARIANCE_FLOOR
    np.testing.assert_array_equal(second, fresh)
    np.testing.assert_array_equal(third, fresh)  # blitted over the kept background


def test_a_growing_field_widens_its_colour_scale_with_headroom() -> None:
    renderer = FrameRenderer(320, 240)
    points, triangles = grid_points([0.0, 1.0, 2.0], [0.0, 1.0])
    for top in (1.0, 1.05, 1.1):
        renderer.draw([("T", Field("T", 0.0, points, np.linspace(0, top, 6), triangles))])
    scale = renderer._scales["T"]
    assert scale.low == 0.0 and scale.high == pytest.approx(1.05 + 0.105)


def test_other_layers_rebuild_the_figure() -> None:
    renderer = FrameRenderer(320, 240)
    renderer.draw(_layers(0.0, 1.0), None, "")
    fluid_only = renderer.draw(_layers(0.0, 1.0)[:1], None, "")
    assert len(renderer._figure.axes) == 2  # the axes and one colour bar
    np.testing.assert_array_equal(
        fluid_only, FrameRenderer(320, 240).draw(_layers(0.0, 1.0)[:1], None, "")
    )


def test_a_stretched_boundary_layer_keeps_its_triangles_and_a_hole_stays_masked() -> None:
    """Cell centres 10:1 along a wall: their nearest neighbours lie across the layer, but no
    triangle of the layer bridges anything; the cylinder's hole is still cut out."""
    from matplotlib.tri import Triangulation

    x, y = np.linspace(0.0, 1.0, 21), np.linspace(0.0, 0.05, 11)  # 0.05 by 0.005: 10:1
    layer = np.stack(np.meshgrid(x, y), axis=-1).reshape(-1, 2)
    triangles = np.asarray(Triangulation(layer[:, 0], layer[:, 1]).triangles)
    assert hole_mask(layer, triangles) is None
    angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    rings = [r * np.stack([np.cos(angles), np.sin(angles)], 1) for r in (1.0, 1.1, 1.2, 1.3)]
    ring = np.concatenate(rings)
    triangles = np.asarray(Triangulation(ring[:, 0], ring[:, 1]).triangles)
    mask = hole_mask(ring, triangles)
    kept = ring[triangles[~mask]].mean(axis=1)
    assert np.linalg.norm(kept, axis=1).min() > 0.95
