"""Draw a :class:`~gymprecice.case_sketch.CaseSketch` as a PNG or SVG (matplotlib, Agg).

One picture per case: the whole domain in metres (axis labels, ticks and a scale bar),
each solver's region filled in its own colour, the boundary patches coloured by kind
(inlet, outlet, wall, symmetry, coupling interface, actuator) and named on the picture,
the probes, the controller's vertices and the preCICE watch points as markers; a legend
lists every patch by kind and what the coupling does there. Where the actuators and
interfaces are small beside the domain (jets on a cylinder in a long channel), a second
panel shows them enlarged, with a frame in the first panel saying where.

Names are placed where they overlap no other name: beside the patch on the domain's
side first (a cylinder's names go into the flow, not into the cylinder), farther out
when that place is taken, and tied to the patch by a thin line when they had to move.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gymprecice.env.rendering import MissingRenderDependency
from gymprecice.plugin.sketch import FORMATS
from gymprecice.tools.case_sketch import CaseSketch, DrawnPatch

__all__ = ["FORMATS", "KIND_STYLES", "detail_box", "draw_sketch"]


@dataclass(frozen=True)
class KindStyle:
    colour: str
    width: float
    label: str
    dashes: str = "-"


#: how each patch kind is drawn (an Okabe-Ito palette: told apart with colour-blindness)
KIND_STYLES = {
    "actuator": KindStyle("#d55e00", 3.2, "actuator"),
    "interface": KindStyle("#e69f00", 2.6, "coupling interface"),
    "inlet": KindStyle("#0072b2", 2.2, "inlet"),
    "outlet": KindStyle("#cc79a7", 2.2, "outlet"),
    "wall": KindStyle("#222222", 1.4, "wall"),
    "symmetry": KindStyle("#777777", 1.2, "symmetry", "--"),
    "patch": KindStyle("#999999", 1.2, "other patch", ":"),
}
#: markers of the points the sketch shows
POINT_STYLES = {
    "probe": {"marker": "o", "s": 7, "color": "#009e73", "zorder": 5},
    "controller reads": {"marker": "x", "s": 22, "color": "#56b4e9", "zorder": 6, "lw": 1.2},
    "controller writes": {
        "marker": "o",
        "s": 9,
        "facecolor": "none",
        "edgecolor": "#d55e00",
        "zorder": 6,
        "lw": 1.0,
    },
    "watch point": {
        "marker": "*",
        "s": 140,
        "color": "#f0e442",
        "edgecolor": "black",
        "zorder": 7,
        "lw": 0.8,
    },
}
_REGION_COLOURS = ("#dceaf7", "#f5e6d3", "#e3f1e0", "#eee3f2")
#: the detail panel appears when the actuators and interfaces span less than this
#: fraction of the domain's larger side
DETAIL_FRACTION = 0.25
_WIDTH_IN = 8.0
_DPI = 110
_FONT = 8


def _bounds(arrays: Sequence[np.ndarray]) -> np.ndarray:
    points = np.concatenate([np.asarray(a).reshape(-1, 2) for a in arrays])
    return np.array([points.min(axis=0), points.max(axis=0)])


def detail_box(sketch: CaseSketch) -> np.ndarray | None:
    """The enlarged panel's ``[[x0, y0], [x1, y1]]``, or ``None`` (no panel needed).

    Around the actuators and interfaces, padded by their size on every side (a jet's
    cylinder is then in the panel whole), when they are small beside the domain.
    """
    domain = _bounds([p.segments for p in sketch.patches])
    focus = [p.segments for p in sketch.patches if p.kind in ("actuator", "interface")]
    if not focus:
        return None
    box = _bounds(focus)
    size = float(np.max(box[1] - box[0]))
    if size >= DETAIL_FRACTION * float(np.max(domain[1] - domain[0])):
        return None
    pad = max(size, 0.02 * float(np.max(domain[1] - domain[0])))
    centre = box.mean(axis=0)
    half = np.maximum(0.5 * (box[1] - box[0]) + pad, pad * 1.5)
    half[:] = max(half)  # square: the panel sits beside the legend
    low = np.maximum(centre - half, domain[0])
    high = np.minimum(centre + half, domain[1])
    return np.array([low, high])


def _nice(length: float) -> float:
    """A round length near a fifth of ``length`` (1, 2 or 5 times a power of ten)."""
    target = length / 5.0
    power = 10.0 ** np.floor(np.log10(target))
    for step in (1.0, 2.0, 5.0, 10.0):
        if step * power >= target * 0.75:
            return float(step * power)
    return float(10.0 * power)


def _region_path(loops: Sequence[np.ndarray]) -> Any:
    """One compound path: the outer loop counter-clockwise, holes clockwise."""
    from matplotlib.path import Path as MplPath

    vertices, codes = [], []
    for index, loop in enumerate(loops):
        x, y = loop[:, 0], loop[:, 1]
        area = 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        if (index == 0) != (area > 0):
            loop = loop[::-1]
        vertices.extend([*loop, loop[0]])
        codes.extend([MplPath.MOVETO] + [MplPath.LINETO] * (len(loop) - 1) + [MplPath.CLOSEPOLY])
    return MplPath(np.asarray(vertices), codes)


def _inside(sketch: CaseSketch, point: np.ndarray) -> bool:
    """Whether ``point`` lies in some solver's region (in its outer loop, in no hole)."""
    from matplotlib.path import Path as MplPath

    for region in sketch.regions:
        outer, *holes = region.loops
        if MplPath(outer).contains_point(point) and not any(
            MplPath(h).contains_point(point) for h in holes
        ):
            return True
    return False


class _Labeller:
    """Places names on one panel so that no two overlap and none leaves the panel."""

    def __init__(self, ax: Any, sketch: CaseSketch) -> None:
        self.ax, self.sketch = ax, sketch
        self.fig = ax.figure
        self.taken: list[Any] = []
        self.renderer = self.fig.canvas.get_renderer()

    def _free(self, text: Any) -> bool:
        box = text.get_window_extent(self.renderer).expanded(1.04, 1.08)
        frame = self.ax.get_window_extent(self.renderer)
        inside = (
            box.x0 >= frame.x0 and box.x1 <= frame.x1 and box.y0 >= frame.y0 and box.y1 <= frame.y1
        )
        return inside and not any(box.overlaps(other) for other in self.taken)

    def place(self, name: str, anchors: Sequence[tuple[np.ndarray, np.ndarray]], colour: str):
        """Name a thing at the first free place beside one of its ``(point, normal)``."""
        ax = self.ax
        span = np.diff(ax.get_xlim())[0]
        probe = 0.01 * span
        tries = []
        for distance in (5, 16, 30, 48):
            for point, normal in anchors:
                toward = normal if _inside(self.sketch, point + probe * normal) else -normal
                for direction in (toward, -toward):
                    tries.append((point, direction, distance))
        for point, direction, distance in tries:
            offset = direction * distance
            text = ax.annotate(
                name,
                xy=point,
                xytext=offset,
                textcoords="offset points",
                ha="center"
                if abs(direction[0]) < 0.5
                else ("left" if direction[0] > 0 else "right"),
                va="center"
                if abs(direction[1]) < 0.5
                else ("bottom" if direction[1] > 0 else "top"),
                fontsize=_FONT,
                color=colour,
                fontweight="bold",
                zorder=9,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85},
                arrowprops=(
                    {"arrowstyle": "-", "color": colour, "lw": 0.7, "shrinkA": 0, "shrinkB": 1}
                    if distance > 16
                    else None
                ),
                annotation_clip=False,
            )
            if self._free(text):
                self.taken.append(text.get_window_extent(self.renderer).expanded(1.04, 1.08))
                return text
            text.remove()
        return None


def _anchors(patch: DrawnPatch, box: np.ndarray | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Points along the patch (inside ``box``), its middle first, each with its unit normal."""
    segments = patch.segments
    mids = segments.mean(axis=1)
    if box is not None:
        keep = np.all((mids >= box[0]) & (mids <= box[1]), axis=1)
        segments, mids = segments[keep], mids[keep]
    if not len(mids):
        return []
    # along the patch: by angle about its centre for a closed curve, else along its length
    centre = mids.mean(axis=0)
    span = mids.max(axis=0) - mids.min(axis=0)
    along = mids[:, int(np.argmax(span))]
    if np.linalg.norm(centre - mids, axis=1).min() > 0.25 * float(np.max(span)):
        along = np.arctan2(*(mids - centre).T[::-1])
    order = np.argsort(along)
    picks = [order[min(len(order) - 1, int(f * len(order)))] for f in _ALONG]
    out = []
    for k in dict.fromkeys(int(i) for i in picks):
        tangent = segments[k, 1] - segments[k, 0]
        length = float(np.linalg.norm(tangent)) or 1.0
        normal = np.array([-tangent[1], tangent[0]]) / length
        out.append((mids[k], normal))
    return out


#: where along a patch its name is tried, in turn (fractions of its length)
_ALONG = (0.5, 0.3, 0.7, 0.15, 0.85, 0.02, 0.98)


def _draw_panel(ax: Any, sketch: CaseSketch, box: np.ndarray) -> None:
    from matplotlib.collections import LineCollection
    from matplotlib.patches import PathPatch

    for index, region in enumerate(sketch.regions):
        colour = _REGION_COLOURS[index % len(_REGION_COLOURS)]
        ax.add_patch(PathPatch(_region_path(region.loops), fc=colour, ec="none", zorder=0))
    order = list(KIND_STYLES)
    for patch in sorted(sketch.patches, key=lambda p: -order.index(p.kind)):
        style = KIND_STYLES[patch.kind]
        ax.add_collection(
            LineCollection(
                patch.segments,
                colors=style.colour,
                linewidths=style.width,
                linestyles=style.dashes,
                capstyle="butt",
                zorder=2 + (len(order) - order.index(patch.kind)) * 0.1,
            )
        )
    for points in sketch.points:
        ax.scatter(points.points[:, 0], points.points[:, 1], **POINT_STYLES[points.kind])
    pad = 0.03 * float(np.max(box[1] - box[0]))
    ax.set_xlim(box[0][0] - pad, box[1][0] + pad)
    ax.set_ylim(box[0][1] - pad, box[1][1] + pad)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]", fontsize=_FONT)
    ax.set_ylabel("y [m]", fontsize=_FONT)
    ax.tick_params(labelsize=_FONT - 1)
    _scale_bar(ax, *(box[1] - box[0]))


def _label_panel(ax: Any, sketch: CaseSketch, box: np.ndarray, names: Sequence[DrawnPatch]):
    """Name the watch points and ``names``'s patches in one panel, laid out already."""
    pad = 0.03 * float(np.max(box[1] - box[0]))
    labeller = _Labeller(ax, sketch)
    inner = np.array([box[0] - pad * 0.5, box[1] + pad * 0.5])
    for points in sketch.points:
        for point, name in zip(points.points, points.names):
            if np.all((point >= inner[0]) & (point <= inner[1])):
                labeller.place(name, [(point, np.array([0.0, 1.0]))], "black")
    named: set[tuple[str, tuple[float, ...]]] = set()
    for patch in names:
        # two solvers' sides of one interface (the plate's CHT patch) are named once
        where = (patch.name, tuple(np.round(_bounds([patch.segments]).ravel() / pad, 1)))
        if where not in named:
            named.add(where)
            labeller.place(patch.name, _anchors(patch, inner), KIND_STYLES[patch.kind].colour)


def _scale_bar(ax: Any, width: float, height: float) -> None:
    """A bar of a round length above the panel's top right corner, out of the domain."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    length = _nice(width)
    ax.add_artist(
        AnchoredSizeBar(
            ax.transData,
            length,
            f"{length:g} m",
            loc="lower right",
            bbox_to_anchor=(1.0, 1.0),
            bbox_transform=ax.transAxes,
            pad=0.1,
            borderpad=0.2,
            sep=2,
            frameon=False,
            size_vertical=0.008 * max(height, 0.2 * width),
            fontproperties={"size": _FONT - 1},
        )
    )


def _legend(ax: Any, sketch: CaseSketch, columns: int) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = []
    for index, region in enumerate(sketch.regions):
        colour = _REGION_COLOURS[index % len(_REGION_COLOURS)]
        handles.append(Patch(fc=colour, ec="#bbbbbb", label=f"domain of {region.label}"))
    several = len({p.solver for p in sketch.patches}) > 1
    for kind, style in KIND_STYLES.items():
        patches = [p for p in sketch.patches if p.kind == kind]
        if not patches:
            continue
        roles = {p.role for p in patches}
        names = [f"{p.solver}: {p.name}" if several else p.name for p in patches]
        if len(roles) > 1:  # each patch says what the coupling does on it
            names = [f"{n} ({p.role})" if p.role else n for n, p in zip(names, patches)]
        text = f"{style.label}: {', '.join(dict.fromkeys(names))}"
        if len(roles) == 1 and patches[0].role:
            text += f" ({patches[0].role})"
        handles.append(
            Line2D([], [], color=style.colour, lw=style.width, ls=style.dashes, label=text)
        )
    for points in sketch.points:
        style = dict(POINT_STYLES[points.kind])
        marker_size = float(np.sqrt(style.pop("s")))
        handles.append(
            Line2D(
                [],
                [],
                ls="",
                marker=style.pop("marker"),
                markersize=marker_size,
                markerfacecolor=style.get("facecolor", style.get("color")),
                markeredgecolor=style.get("edgecolor", style.get("color")),
                label=points.label,
            )
        )
    if sketch.undrawn:
        handles.append(
            Line2D(
                [],
                [],
                ls="",
                label=f"not drawn (their plugin draws no sketch): {', '.join(sketch.undrawn)}",
            )
        )
    ax.axis("off")
    ax.legend(
        handles=handles,
        loc="upper left",
        ncol=columns,
        fontsize=_FONT,
        frameon=False,
        handlelength=2.2,
        borderaxespad=0.0,
    )


def draw_sketch(sketch: CaseSketch, path: str | Path, *, dpi: int = _DPI) -> Path:
    """Write ``sketch`` to ``path`` (``.png`` or ``.svg``); returns the path."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        from matplotlib.figure import Figure
        from matplotlib.patches import Rectangle
    except ImportError as exc:  # pragma: no cover - matplotlib is in the render extra
        raise MissingRenderDependency(
            "sketching needs matplotlib: pip install 'gymprecice-core[render]'"
        ) from exc
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"{path}: a sketch is written as {' or '.join(FORMATS)}")
    if not sketch.patches:
        raise ValueError("nothing to draw: the sketch has no patches")
    domain = _bounds([p.segments for p in sketch.patches])
    detail = detail_box(sketch)
    extent = domain[1] - domain[0]
    main_height = min(_WIDTH_IN * 0.85 * extent[1] / extent[0] + 0.7, 6.0)
    legend_rows = (
        len(sketch.regions)
        + len(sketch.points)
        + len({p.kind for p in sketch.patches})
        + bool(sketch.undrawn)
    )
    if detail is None:
        mosaic, heights = [["main"], ["legend"]], [main_height, 0.2 * legend_rows + 0.1]
    else:
        mosaic, heights = [["main", "main"], ["detail", "legend"]], [main_height, 3.4]
    fig = Figure(figsize=(_WIDTH_IN, sum(heights) + 0.5), dpi=dpi, layout="constrained")
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    axes = fig.subplot_mosaic(mosaic, height_ratios=heights)
    fig.suptitle(sketch.title, fontsize=_FONT + 2)
    inside = []
    if detail is not None:
        mids = [p.segments.mean(axis=1) for p in sketch.patches]
        inside = [
            p
            for p, m in zip(sketch.patches, mids)
            if np.all((m >= detail[0]) & (m <= detail[1]), axis=1).mean() > 0.5
        ]
    outside = [p for p in sketch.patches if p not in inside]
    _legend(axes["legend"], sketch, 1)
    _draw_panel(axes["main"], sketch, domain)
    if detail is not None:
        size = detail[1] - detail[0]
        axes["main"].add_patch(
            Rectangle(detail[0], size[0], size[1], fill=False, ec="#555555", lw=0.9, ls="--")
        )
        axes["detail"].set_title("enlarged: the dashed frame above", fontsize=_FONT, loc="left")
        _draw_panel(axes["detail"], sketch, detail)
    # lay the panels out once, then keep them still: names are placed in display units
    fig.canvas.draw()
    fig.set_layout_engine("none")
    _label_panel(axes["main"], sketch, domain, outside)
    if detail is not None:
        _label_panel(axes["detail"], sketch, detail, inside)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, format=path.suffix.lower()[1:], facecolor="white")
    return path
