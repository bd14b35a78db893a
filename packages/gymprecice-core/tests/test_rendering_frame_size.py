"""A frame's shape follows the drawn domain: a wide channel gets a wide frame, once.

The width is the env's; the height is chosen at the first frame from the domain's aspect
ratio, the margins and the colour bars, clamped and rounded to whole macro blocks (what
video encoders take as it is), and kept for every later frame (RecordVideo and the lab's
video writer need one size). A height the env fixes is kept as it is.
"""

from __future__ import annotations

import numpy as np
import pytest

from gymprecice.env.rendering import MAX_HEIGHT, MIN_HEIGHT, SIZE_STEP, FrameRenderer, frame_height
from gymprecice.plugin.fields import Field, grid_points

#: a pixel of the field's colour map differs from the white around the axes by this much
WHITE = 250


def _channel(length: float, height: float, scale: float = 1.0) -> list[tuple[str, Field]]:
    points, triangles = grid_points(np.linspace(0, length, 45), np.linspace(0, height, 15))
    values = scale * (2.0 + np.sin(points[:, 0])) + points[:, 1]  # positive: viridis
    return [("fluid/U", Field("U", 0.0, points, values, triangles=triangles, label="|U|"))]


def _field_rows(frame: np.ndarray, width: int) -> int:
    """Rows of the frame where the field is drawn (inside the axes' padding, not white)."""
    drawn = frame[:, 70 : width // 2].min(axis=2) < WHITE
    return int(drawn.all(axis=1).sum())


@pytest.mark.parametrize(("length", "height"), [(2.2, 0.41), (6.0, 4.0), (3.0, 0.8), (1.0, 1.0)])
def test_the_height_follows_the_aspect_in_whole_macro_blocks(length, height):
    renderer = FrameRenderer(640)
    assert renderer.height is None  # chosen by the first frame
    frame = renderer.draw(_channel(length, height))
    rows, width = frame.shape[:2]
    assert width == 640 and rows == renderer.height
    assert rows % SIZE_STEP == 0 and MIN_HEIGHT * 640 <= rows <= MAX_HEIGHT * 640
    assert rows == frame_height(640, (length * 1.04, height + 0.04 * length), bars=1)
    # the domain fills the axes' height: the margins, the axes' padding around the domain
    # and the rounding to a macro block are all that is not field
    if rows > MIN_HEIGHT * 640:
        assert rows - _field_rows(frame, width) <= 26 + 24 + 24 + SIZE_STEP


def test_a_wide_channel_gets_a_shorter_frame_than_a_square_domain():
    wide = FrameRenderer(640).draw(_channel(6.0, 1.0))
    square = FrameRenderer(640).draw(_channel(1.0, 1.0))
    assert wide.shape[0] < square.shape[0]
    # the old fixed 640 x 400 frame drew this channel in a band of a quarter of its height
    assert _field_rows(wide, 640) > 0.4 * wide.shape[0]


def test_the_height_is_kept_for_the_episode():
    renderer = FrameRenderer(640)
    first = renderer.draw(_channel(2.2, 0.41))
    later = renderer.draw(_channel(1.0, 1.0, scale=2.0))  # another domain: the size stays
    assert later.shape == first.shape


def test_the_height_is_clamped_and_colour_bars_take_width():
    assert frame_height(640, (100.0, 1.0)) == int(np.ceil(MIN_HEIGHT * 640 / 16)) * 16
    assert frame_height(640, (1.0, 100.0)) == int(MAX_HEIGHT * 640 // 16) * 16
    assert frame_height(640, (1.0, 1.0), bars=2) < frame_height(640, (1.0, 1.0), bars=1)
    for width in (320, 480, 641, 1000):
        assert frame_height(width, (1.7, 1.0)) % SIZE_STEP == 0


def test_a_height_the_env_fixes_is_kept():
    frame = FrameRenderer(320, 240).draw(_channel(6.0, 1.0))
    assert frame.shape == (240, 320, 3)
    with pytest.raises(ValueError, match="at least 64 x 64"):
        FrameRenderer(640, 32)
