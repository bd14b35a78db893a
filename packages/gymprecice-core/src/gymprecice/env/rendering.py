"""Core draws: the fields of every participant in one frame, as an ``HxWx3`` uint8 array.

:class:`FrameRenderer` draws the :class:`~gymprecice.fields.Field` layers an env's solvers
hand over (``gymprecice_read_field``) into one pair of axes, in physical coordinates, so a
fluid and its flap, or a fluid and its plate, appear where they are; each layer gets its
own colour bar. The env's :class:`~gymprecice.fields.Overlay` (the actuators' state) is
drawn on top.

Why matplotlib (Agg): it draws unstructured triangle meshes (``tripcolor``) without a
display, its ``Triangulation`` can be kept and reused, and the tutorials already need it;
PyVista/VTK would be faster on big 3-D meshes but weighs hundreds of MB and needs an
off-screen OpenGL. The expensive part of a frame on an unstructured mesh is the Delaunay
triangulation of the points, so it is made once per layer and reused while the points
stay the same (a moving geometry reuses the connectivity at its new positions). Colour
limits only widen over an episode, so a video does not flicker; they widen with some
headroom, so a growing field does not change its colour bar at every frame.

Building a figure (axes, ticks, colour bars) costs far more than drawing the fields, so
the figure is built once per set of layers and kept: a frame only hands the field
artists their new values (``set_array``; a new triangulation only where the points
moved) and redraws them over a saved image of everything else (Agg blitting). That image
is redrawn only when a colour bar's limits widen or the axes' limits change
(``benchmarks/bench_render.py`` measures a frame).

A frame's shape follows the drawn domain: its width is fixed and, unless the env fixes
the height too, its height is chosen at the first frame (:func:`frame_height`) so that
the domain, at its own aspect ratio, fills the space beside the colour bars: a wide
channel gets a wide frame instead of white bands above and below it. The height is then
kept for every later frame (a video, RecordVideo's too, needs one size), clamped to
:data:`MIN_HEIGHT` to :data:`MAX_HEIGHT` times the width, and a multiple of
:data:`SIZE_STEP` pixels, which video encoders take as it is.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gymprecice.plugin.fields import Field, Overlay

__all__ = ["FrameRenderer", "MissingRenderDependency", "frame_height"]

#: A triangle bridges a hole of the domain (a cylinder, a slit) and is masked when its
#: longest edge is longer than this many times the distance from each of its corners to
#: that corner's nearest neighbour...
HOLE_EDGE_FACTOR = 6.0
#: ...and than this many times their spacing along the mesh's coarser direction, so that
#: cells stretched along a wall keep their triangles, whatever the stretch.
HOLE_SPACING_FACTOR = 2.5
_SEQUENTIAL = ("viridis", "inferno", "cividis", "magma")
#: When a field leaves its colour scale, the scale widens this fraction of its span past
#: the new values (the first frame's scale is tight).
HEADROOM = 0.1
#: A frame's height (when the env leaves it to the domain): at least and at most these
#: fractions of its width (a very wide channel still gets room for its colour bars; a
#: tall domain gets a frame no taller than this)...
MIN_HEIGHT = 0.3
MAX_HEIGHT = 1.25
#: ...and a multiple of this many pixels: even, as libx264's yuv420p needs, and whole
#: macro blocks, which imageio's ffmpeg writer would otherwise resize to.
SIZE_STEP = 16
#: The space around the axes, in pixels at 100 dpi: the y and x tick labels, the title
#: above, the right edge; each colour bar takes :data:`_BAR_SLOT` (bar, ticks, label).
_LEFT, _BOTTOM, _TOP, _RIGHT = 44, 24, 26, 12
_BAR_SLOT, _BAR_WIDTH, _BAR_GAP = 62, 12, 8


class MissingRenderDependency(ImportError):
    """matplotlib is not installed: rendering needs ``gymprecice-core[render]``."""


@dataclass
class _Mesh:
    """A layer's kept triangulation: the points it was made for and its triangles."""

    key: str
    triangles: np.ndarray
    mask: np.ndarray | None


@dataclass
class _Drawn:
    """A layer's triangulation at the positions last drawn, and their fingerprint."""

    key: str
    triangulation: Any


@dataclass
class _Layer:
    """A layer's kept artists: the field (redrawn every frame) and its colour bar."""

    artist: Any
    mappable: Any
    clim: tuple[float, float] = (0.0, 0.0)
    #: the triangulation ``artist`` draws: a new one (moved points) needs a new artist
    tri: Any = None


@dataclass
class _Scene:
    """The kept figure of one set of layers: axes, colour bars, title, overlay artists."""

    labels: tuple[str, ...]
    ax: Any
    layers: dict[str, _Layer]
    title: Any
    overlay: list[Any]
    limits: tuple[float, float, float, float] | None = None
    background: Any = None


@dataclass
class _Scale:
    """A layer's colour map and the limits seen so far."""

    cmap: str
    low: float
    high: float


def frame_height(width: int, extent: tuple[float, float], bars: int = 1, dpi: int = 100) -> int:
    """The height of a ``width``-pixel frame that shows ``extent`` (its width, height).

    The axes take the frame's width less the margins and ``bars`` colour bars; their
    height is that width times the extent's aspect ratio, and the frame adds the
    margins above and below. Clamped to :data:`MIN_HEIGHT` .. :data:`MAX_HEIGHT` times
    ``width`` and rounded up to a multiple of :data:`SIZE_STEP`.
    """
    scale = dpi / 100.0
    span_x, span_y = (max(float(v), 0.0) for v in extent)
    axes_width = width - scale * (_LEFT + _RIGHT + _BAR_SLOT * bars)
    aspect = span_y / span_x if span_x > 0 else 1.0
    wanted = scale * (_TOP + _BOTTOM) + max(axes_width, 1.0) * aspect
    low = int(np.ceil(MIN_HEIGHT * width / SIZE_STEP)) * SIZE_STEP
    high = max(low, int(MAX_HEIGHT * width // SIZE_STEP) * SIZE_STEP)
    height = int(np.ceil(wanted / SIZE_STEP)) * SIZE_STEP
    return min(max(height, low), high)


def _fingerprint(points: np.ndarray) -> str:
    return hashlib.blake2b(np.ascontiguousarray(points).tobytes(), digest_size=16).hexdigest()


def _local_spacing(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Each point's spacing along the mesh's coarser direction: its third-shortest edge.

    In a cell-centre cloud stretched k:1 (a boundary layer) a point's two shortest edges
    run across the stretch and the next ones along it; a point at a hole's rim has its
    ring and outward neighbours before any edge that bridges the hole.
    """
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    length = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    owner = np.concatenate([edges[:, 0], edges[:, 1]])
    lengths = np.concatenate([length, length])
    order = np.lexsort((lengths, owner))
    owner, lengths = owner[order], lengths[order]
    start = np.searchsorted(owner, np.arange(len(points)))
    count = np.bincount(owner, minlength=len(points))
    return lengths[start + np.clip(count - 1, 0, 2)]


def hole_mask(points: np.ndarray, triangles: np.ndarray) -> np.ndarray | None:
    """Mask the triangles of a Delaunay triangulation that bridge a hole in the points.

    Delaunay fills the convex hull, so the cells around a cylinder get joined across it.
    A triangle is masked when its longest edge exceeds :data:`HOLE_EDGE_FACTOR` times
    the largest nearest-neighbour distance of its corners (a Delaunay triangulation
    holds every point's nearest neighbour among its edges) *and*
    :data:`HOLE_SPACING_FACTOR` times their largest spacing along the mesh's coarser
    direction (:func:`_local_spacing`), so that the stretched cells of a boundary layer,
    whose nearest neighbours are close across it, keep their triangles.
    """
    a, b, c = (points[triangles[:, k]] for k in range(3))
    lengths = np.stack(
        [
            np.linalg.norm(a - b, axis=1),
            np.linalg.norm(b - c, axis=1),
            np.linalg.norm(c - a, axis=1),
        ],
        axis=1,
    )
    nearest = np.full(len(points), np.inf)
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        for corner in (i, j):
            np.minimum.at(nearest, triangles[:, corner], lengths[:, k])
    longest = lengths.max(axis=1)
    mask = longest > HOLE_EDGE_FACTOR * np.max(nearest[triangles], axis=1)
    if mask.any():
        spacing = _local_spacing(points, triangles)
        mask &= longest > HOLE_SPACING_FACTOR * np.max(spacing[triangles], axis=1)
    return mask if mask.any() else None


def _limits(
    layers: Sequence[tuple[str, Field]],
) -> tuple[tuple[float, float, float, float], float]:
    """The axes' limits ``(x0, x1, y0, y1)`` around every layer's positions, and the pad."""
    boxes = [(f.positions.min(axis=0), f.positions.max(axis=0)) for _, f in layers]
    low = np.min([b[0] for b in boxes], axis=0)
    high = np.max([b[1] for b in boxes], axis=0)
    pad = 0.02 * float(np.max(high - low) or 1.0)
    limits = (low[0] - pad, high[0] + pad, low[1] - pad, high[1] + pad)
    return tuple(float(v) for v in limits), pad  # type: ignore[return-value]


class FrameRenderer:
    """Draw layers of fields and an overlay into ``height x width`` RGB frames.

    One renderer per env: it keeps each layer's triangulation and colour scale, and the
    figure itself, between frames. ``layers`` are ``(label, Field)`` pairs, drawn in order
    (the first below). ``height=None`` (the default): the first frame chooses it from the
    drawn domain (:func:`frame_height`) and every later frame keeps it (``height`` is
    ``None`` until then).
    """

    def __init__(self, width: int = 640, height: int | None = None, dpi: int = 100) -> None:
        try:
            import matplotlib

            matplotlib.use("Agg", force=False)
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
        except ImportError as exc:  # pragma: no cover - matplotlib is in the render extra
            raise MissingRenderDependency(
                "rendering needs matplotlib: pip install 'gymprecice-core[render]'"
            ) from exc
        if width < 64 or (height is not None and height < 64):
            raise ValueError(f"a frame must be at least 64 x 64 pixels, got {width} x {height}")
        self.width, self.dpi = int(width), int(dpi)
        self.height: int | None = None if height is None else int(height)
        shown = self.width if self.height is None else self.height
        self._figure = Figure(figsize=(self.width / dpi, shown / dpi), dpi=dpi)
        self._canvas = FigureCanvasAgg(self._figure)
        self._meshes: dict[str, _Mesh] = {}
        self._drawn: dict[str, _Drawn] = {}
        self._scales: dict[str, _Scale] = {}
        self._scene: _Scene | None = None

    # -- triangulations and scales -------------------------------------------------------
    def triangulation(self, label: str, field: Field) -> Any:
        """The layer's triangulation at the field's current positions (kept between frames).

        The same object comes back while the positions stay the same, so the drawn
        artist keeps it; a moving geometry gets a new one on the kept connectivity.
        """
        from matplotlib.tri import Triangulation

        positions = field.positions
        moved = field.displacement is not None
        key = _fingerprint(positions) + ("" if field.triangles is None else "+cells")
        drawn = self._drawn.get(label)
        if drawn is not None and drawn.key == key:
            return drawn.triangulation
        if field.triangles is not None:
            mesh = _Mesh(key, field.triangles, None)
        else:
            reference = _fingerprint(field.points) if moved else key
            mesh = self._meshes.get(label)
            if mesh is None or mesh.key != reference:
                made = Triangulation(field.points[:, 0], field.points[:, 1])
                triangles = np.asarray(made.triangles, dtype=np.int64)
                mesh = _Mesh(reference, triangles, hole_mask(field.points, triangles))
                self._meshes[label] = mesh
        tri = Triangulation(positions[:, 0], positions[:, 1], mesh.triangles, mask=mesh.mask)
        self._drawn[label] = _Drawn(key, tri)
        return tri

    def _scale(self, label: str, values: np.ndarray) -> _Scale:
        finite = values[np.isfinite(values)]
        low = float(finite.min()) if finite.size else 0.0
        high = float(finite.max()) if finite.size else 1.0
        scale = self._scales.get(label)
        if scale is None:
            signed = low < 0.0 < high
            cmap = "RdBu_r" if signed else _SEQUENTIAL[len(self._scales) % len(_SEQUENTIAL)]
            scale = self._scales[label] = _Scale(cmap, low, high)
        if low < scale.low or high > scale.high:
            # Widen past the new values, so that a field still growing does not redraw
            # its colour bar (the kept figure's background) at every frame.
            span = max(high, scale.high) - min(low, scale.low)
            if low < scale.low:
                scale.low = low - HEADROOM * span
            if high > scale.high:
                scale.high = high + HEADROOM * span
        if scale.cmap == "RdBu_r":
            bound = max(abs(scale.low), abs(scale.high))
            scale.low, scale.high = -bound, bound
        if scale.high - scale.low < 1e-12 * max(1.0, abs(scale.high)):
            scale.high = scale.low + max(1e-12, 1e-6 * abs(scale.low))
        return scale

    # -- the kept figure -----------------------------------------------------------------
    def _build(
        self, layers: Sequence[tuple[str, Field]], limits: tuple[float, float, float, float]
    ) -> _Scene:
        """Axes, one colour bar per layer and the title, for this set of layers.

        Laid out in pixels: the axes fill the frame but for the margins and the colour
        bars; the domain (``limits``, drawn at its aspect ratio) sits at the axes' left,
        and the colour bars follow it, as tall as it is.
        """
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize

        fig = self._figure
        fig.clear()
        width, height = float(self.width), float(self.height or self.width)
        px = self.dpi / 100.0
        left, bottom = px * _LEFT, px * _BOTTOM
        axes_w = max(width - px * (_LEFT + _RIGHT + _BAR_SLOT * len(layers)), 8.0)
        axes_h = max(height - px * (_TOP + _BOTTOM), 8.0)
        span_x, span_y = limits[1] - limits[0], limits[3] - limits[2]
        aspect = span_y / span_x if span_x > 0 else 1.0
        drawn_h = min(axes_h, aspect * axes_w)
        drawn_w = min(axes_w, axes_h / aspect) if aspect > 0 else axes_w
        ax = fig.add_axes((left / width, bottom / height, axes_w / width, axes_h / height))
        ax.set_autoscale_on(False)
        ax.set_aspect("equal", adjustable="box")
        ax.set_anchor("W")
        ax.tick_params(labelsize=6)
        inset = min(8.0 * px, 0.04 * drawn_h)
        bar_bottom = bottom + (axes_h - drawn_h) / 2 + inset
        bar_height = max(drawn_h - 2 * inset, 8.0)
        kept: dict[str, _Layer] = {}
        for index, (label, field) in enumerate(layers):
            scale = self._scale(label, field.scalar)
            mappable = ScalarMappable(Normalize(scale.low, scale.high), scale.cmap)
            bar_left = left + drawn_w + px * (_BAR_GAP + index * _BAR_SLOT)
            cax = fig.add_axes(
                (
                    bar_left / width,
                    bar_bottom / height,
                    px * _BAR_WIDTH / width,
                    bar_height / height,
                )
            )
            bar = fig.colorbar(mappable, cax=cax)
            bar.ax.tick_params(labelsize=6)
            bar.set_label(field.label or f"{label}", fontsize=7)
            kept[label] = _Layer(artist=None, mappable=mappable)
        title = fig.suptitle("", fontsize=9, y=1.0 - 4.0 * px / height, va="top")
        title.set_animated(True)
        return _Scene(tuple(label for label, _ in layers), ax, kept, title, [])

    def _update_layer(self, scene: _Scene, label: str, field: Field) -> bool:
        """Hand the layer's artist its new values; whether the background must be redrawn."""
        from matplotlib.collections import TriMesh

        layer = scene.layers[label]
        values = field.scalar
        scale = self._scale(label, values)
        stale = False
        if (scale.low, scale.high) != layer.clim:
            layer.mappable.set_clim(scale.low, scale.high)  # the colour bar follows
            layer.clim = (scale.low, scale.high)
            stale = True
        tri = self.triangulation(label, field)
        if layer.tri is not tri:
            if layer.artist is not None:
                layer.artist.remove()
            layer.artist = TriMesh(tri, cmap=layer.mappable.cmap, norm=layer.mappable.norm)
            layer.artist.set_animated(True)
            scene.ax.add_collection(layer.artist, autolim=False)
            layer.tri = tri
        layer.artist.set_array(values)
        return stale

    # -- one frame -----------------------------------------------------------------------
    def draw(
        self,
        layers: Sequence[tuple[str, Field]],
        overlay: Overlay | None = None,
        title: str = "",
    ) -> np.ndarray:
        """One frame: every layer, the overlay and the title, as ``(height, width, 3)`` uint8."""
        if not layers:
            raise ValueError("nothing to draw: no field layers")
        limits, pad = _limits(layers)
        if self.height is None:  # the first frame: the domain decides, once
            extent = (limits[1] - limits[0], limits[3] - limits[2])
            self.height = frame_height(self.width, extent, len(layers), self.dpi)
            self._figure.set_size_inches(self.width / self.dpi, self.height / self.dpi)
        labels = tuple(label for label, _ in layers)
        if self._scene is None or self._scene.labels != labels:
            self._scene = self._build(layers, limits)
        scene = self._scene
        stale = scene.background is None
        for label, field in layers:
            stale = self._update_layer(scene, label, field) or stale
        # A moving mesh shifts its outer cells a little at every frame: the limits' pad
        # keeps such a shift in view, so only a larger one redraws the kept figure.
        if scene.limits is None or not np.allclose(limits, scene.limits, rtol=0, atol=0.25 * pad):
            scene.ax.set_xlim(limits[0], limits[1])
            scene.ax.set_ylim(limits[2], limits[3])
            scene.limits = limits
            stale = True
        for artist in scene.overlay:
            artist.remove()
        scene.overlay = self._draw_overlay(scene.ax, overlay) if overlay is not None else []
        scene.title.set_text(title)
        canvas = self._canvas
        if stale:  # everything but the animated artists, kept as the background
            canvas.draw()
            scene.background = canvas.copy_from_bbox(self._figure.bbox)
        else:
            canvas.restore_region(scene.background)
        for layer in scene.layers.values():
            scene.ax.draw_artist(layer.artist)
        for artist in scene.overlay:
            scene.ax.draw_artist(artist)
        self._figure.draw_artist(scene.title)
        rgba = np.asarray(canvas.buffer_rgba())
        return np.ascontiguousarray(rgba[:, :, :3], dtype=np.uint8)

    @staticmethod
    def _draw_overlay(ax: Any, overlay: Overlay) -> list[Any]:
        """The overlay's artists (animated: drawn over the kept background each frame)."""
        made: list[Any] = []
        for x, y, dx, dy in overlay.arrows:
            if dx == 0 and dy == 0:
                continue
            made.append(
                ax.annotate(
                    "",
                    xy=(x + dx, y + dy),
                    xytext=(x, y),
                    arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.4},
                    annotation_clip=False,
                )
            )
        if overlay.markers:
            points = np.asarray(overlay.markers, dtype=float).reshape(-1, 2)
            made.extend(ax.plot(points[:, 0], points[:, 1], "k.", markersize=2))
        if overlay.text:
            made.append(
                ax.text(
                    0.01,
                    0.98,
                    "\n".join(overlay.text),
                    transform=ax.transAxes,
                    va="top",
                    ha="left",
                    fontsize=7,
                    family="monospace",
                    bbox={"boxstyle": "round", "facecolor": "white", "alpha": 0.8, "lw": 0.5},
                )
            )
        for artist in made:
            artist.set_animated(True)
        return made
