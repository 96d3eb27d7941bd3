"""Text labels on a figure placed so that none overlaps another label, a tick label, a title,
a legend or a marked point.

Each label is tried next to its anchor at growing distances, in the screen directions it
prefers first. It must stay inside its axes and overlap nothing (if no position manages, the
one that overlaps least wins); among the positions that manage, the one nearest its anchor that
covers least of the drawing's lines is taken. A label that ends up far from its anchor gets a
thin leader line back to it. Labels are placed once their axes are laid out (limits, view,
figure layout), in axes coordinates, so the placement holds at any dpi and in any format.

Shared by the diagnosis figure (:mod:`poekin.verification.plotting`) and ``poekin draw``
(:mod:`poekin.viewer.draw`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.text import Text
from matplotlib.transforms import Bbox
from mpl_toolkits.mplot3d import proj3d
from numpy.typing import NDArray

__all__ = [
    "Label",
    "directions_away",
    "drawn_texts",
    "place_labels",
    "screen_direction",
    "text_box",
]

FloatArray = NDArray[np.float64]
HAlign = Literal["left", "center", "right"]
VAlign = Literal["bottom", "center", "top"]
# A position to try: where (axes fraction), the alignment, the distance from the anchor (px).
Candidate = tuple[FloatArray, HAlign, VAlign, float]

# Distances tried from the anchor, beyond a label's offset, in points, nearest first.
_STEPS_PT = (0.0, 5.0, 10.0, 18.0, 28.0, 42.0, 60.0, 85.0, 120.0)
_LEADER_AFTER = 2.5  # a label farther than this many offsets from its anchor gets a leader
_GAP_PT = 1.5  # clear space kept around every label and point, in points
_POINT_PT = 3.0  # half the side of the square kept clear around a marked point, in points
_N_DIRECTIONS = 16
_CORNER_INSET = 0.015  # a label put in a corner of its axes' room: this far in (fraction)
# The cost of a position: pixels from its anchor, plus this much per pixel of line it covers
# (a label may move four pixels farther to leave one pixel of line free; a boxed label, which
# hides what it covers behind its box, a fifth of a pixel) ...
_LINE_COST = 4.0
_BOXED_LINE_COST = 0.2
_AXIS_LINE_COST = 50.0  # per pixel of an axis line or tick mark: labels stay off the axes
_CROSSING_COST = 50.0  # per pixel of its leader line across a text
# ... and, far above both, this much per square pixel it overlaps texts, points, or leaves its
# axes: what makes a position unusable.
_OVERLAP_COST = 1e4


@dataclasses.dataclass(frozen=True)
class Label:
    """A text to place: beside the 3-D point ``at`` of the 3-D axes ``ax`` (data coordinates),
    ``offset_pt`` points away on screen, or, with ``at`` None, in a corner of ``ax``.

    Attributes:
        directions: screen directions (right, up) to try, best first (:func:`directions_away`);
            none: all 16, up and to the right first.
        style: keyword arguments of the text (``color``, ``fontsize``, ``bbox``, ...).
    """

    ax: Any
    text: str
    style: Mapping[str, Any]
    at: FloatArray | None = None
    directions: tuple[FloatArray, ...] = ()
    offset_pt: float = 5.0


def screen_direction(v: FloatArray, elev: float, azim: float) -> FloatArray:
    """The 2-D direction (right, up) in which the 3-D direction ``v`` shows on screen in an
    orthographic view from elevation ``elev`` and azimuth ``azim`` (degrees, matplotlib's)."""
    el, az = math.radians(elev), math.radians(azim)
    right = np.array([-math.sin(az), math.cos(az), 0.0])
    up = np.array([-math.sin(el) * math.cos(az), -math.sin(el) * math.sin(az), math.cos(el)])
    return np.array([float(v @ right), float(v @ up)])


def _all_directions() -> list[FloatArray]:
    angles = [math.radians(45.0 + 360.0 / _N_DIRECTIONS * k) for k in range(_N_DIRECTIONS)]
    return [np.array([math.cos(a), math.sin(a)]) for a in angles]


def directions_away(obstacles: Sequence[FloatArray]) -> tuple[FloatArray, ...]:
    """The 16 screen directions ordered from the farthest in angle from every non-zero 2-D
    direction in ``obstacles`` (lines leaving the anchor, say) to the nearest; up and to the
    right first among equals."""
    angles = [math.atan2(o[1], o[0]) for o in obstacles if math.hypot(o[0], o[1]) > 1e-9]

    def clearance(d: FloatArray) -> float:
        a = math.atan2(d[1], d[0])
        return min((abs(math.remainder(a - b, 2 * math.pi)) for b in angles), default=0.0)

    return tuple(sorted(_all_directions(), key=clearance, reverse=True))


def text_box(text: Text, renderer: Any) -> Bbox:
    """The display extent of ``text``, its box (``bbox=...``) included."""
    box = text.get_window_extent(renderer)
    patch = text.get_bbox_patch()
    if patch is None:
        return box
    text.update_bbox_position_size(renderer)
    return Bbox.union([box, patch.get_window_extent(renderer)])


def _axes_of(ax: Any) -> list[Any]:
    """The x, y (and z) axis of ``ax``."""
    return [ax.xaxis, ax.yaxis, *([ax.zaxis] if hasattr(ax, "zaxis") else [])]


def _in_view(tick: Any, axis: Any) -> bool:
    lo, hi = sorted(axis.get_view_interval())
    pad = 1e-9 * max(1.0, abs(hi - lo))
    return bool(lo - pad <= tick.get_loc() <= hi + pad)


def drawn_texts(fig: Figure) -> list[Text]:
    """Every text the figure draws, with something in it: titles, axis labels, the labels of
    the ticks in view (those out of view are not drawn, though they exist), legends, and the
    texts of the figure and its axes."""
    hidden: set[int] = set()
    for ax in fig.axes:
        for axis in _axes_of(ax):
            for tick in [*axis.get_major_ticks(), *axis.get_minor_ticks()]:
                if not _in_view(tick, axis):
                    hidden.update((id(tick.label1), id(tick.label2)))
    return [
        t
        for t in fig.findobj(Text)
        if isinstance(t, Text) and t.get_visible() and t.get_text().strip() and id(t) not in hidden
    ]


def _display(ax: Any, at: FloatArray) -> FloatArray:
    """Where the 3-D point ``at`` of ``ax`` shows on screen, in display pixels."""
    x, y, _ = proj3d.proj_transform(float(at[0]), float(at[1]), float(at[2]), ax.get_proj())
    return np.asarray(ax.transData.transform((x, y)), dtype=np.float64)


def _room(ax: Any) -> Bbox:
    """The room the figure gives ``ax``, in display pixels: a 3-D box with an aspect is drawn
    in less, and its drawing and tick labels may reach beyond that."""
    return ax.get_position(original=True).transformed(ax.figure.transFigure)  # type: ignore[no-any-return]


def _alignment(d: FloatArray) -> tuple[HAlign, VAlign]:
    """Alignment that makes a text grow away from its anchor in direction ``d``."""
    ha: HAlign = "left" if d[0] > 0.35 else "right" if d[0] < -0.35 else "center"
    va: VAlign = "bottom" if d[1] > 0.35 else "top" if d[1] < -0.35 else "center"
    return ha, va


def _extents(boxes: Sequence[Bbox]) -> FloatArray:
    """``(K, 4)``: ``x0, y0, x1, y1`` of each box."""
    return np.array([b.extents for b in boxes], dtype=np.float64).reshape(-1, 4)


def _overlap(box: Bbox, others: FloatArray) -> float:
    """The area of ``box`` that the boxes ``others`` (``(K, 4)`` extents) cover, summed."""
    w = np.minimum(box.x1, others[:, 2]) - np.maximum(box.x0, others[:, 0])
    h = np.minimum(box.y1, others[:, 3]) - np.maximum(box.y0, others[:, 1])
    return float(np.sum(np.clip(w, 0.0, None) * np.clip(h, 0.0, None)))


def _outside(box: Bbox, bounds: Bbox) -> float:
    """The area of ``box`` outside ``bounds``."""
    return box.width * box.height - _overlap(box, _extents([bounds]))


def _candidates(label: Label, px_per_pt: float) -> list[Candidate]:
    """Positions to try, nearest first: in axes fraction, with the alignment, and their
    distance from the anchor in pixels."""
    ax = label.ax
    to_axes = ax.transAxes.inverted()
    if label.at is None:
        room = _room(ax)
        dx, dy = _CORNER_INSET * room.width, _CORNER_INSET * room.height
        x0, x1, y0, y1 = room.x0 + dx, room.x1 - dx, room.y0 + dy, room.y1 - dy
        corners: list[tuple[float, float, HAlign, VAlign]] = [
            (x0, y0, "left", "bottom"),
            (x0, y1, "left", "top"),
            (x1, y0, "right", "bottom"),
            (x1, y1, "right", "top"),
        ]
        return [(to_axes.transform((x, y)), ha, va, 0.0) for x, y, ha, va in corners]
    anchor = _display(ax, label.at)
    out: list[Candidate] = []
    for step in _STEPS_PT:
        distance = (label.offset_pt + step) * px_per_pt
        for d in label.directions or tuple(_all_directions()):
            xy = anchor + d * distance
            out.append((np.asarray(to_axes.transform(xy)), *_alignment(d), distance))
    return out


def _segments(artists: Sequence[Any]) -> FloatArray:
    """``(M, 2, 2)``: the line segments that ``artists`` (lines and line collections) draw, in
    display pixels (after a draw, which projects 3-D lines)."""
    out = []
    for artist in artists:
        if not artist.get_visible():
            continue
        if isinstance(artist, Line2D):
            if artist.get_linestyle() in ("None", "none", "", " "):
                continue
            paths = [artist.get_path()]
        else:
            paths = list(artist.get_paths())
        transform = artist.get_transform()
        for path in paths:
            for poly in path.to_polygons(closed_only=False):
                xy = transform.transform(poly)
                if len(xy) >= 2:
                    out.append(np.stack([xy[:-1], xy[1:]], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 2, 2))


def _axis_marks(ax: Any) -> list[Any]:
    """The lines of ``ax``'s axes: each axis line and the marks of the ticks in view."""
    marks = []
    for axis in _axes_of(ax):
        marks.append(axis.line)
        for tick in axis.get_major_ticks():
            if _in_view(tick, axis):
                marks += [tick.tick1line, tick.tick2line]
    return marks


def _covered(boxes: FloatArray, segments: FloatArray) -> float:
    """The length (pixels) of ``segments`` ``(M, 2, 2)`` inside the boxes ``(K, 4)``, summed
    over every box and segment (Liang-Barsky clipping)."""
    if not len(segments) or not len(boxes):
        return 0.0
    p0, d = segments[None, :, 0], segments[None, :, 1] - segments[None, :, 0]  # (1, M, 2)
    t_lo = np.zeros((len(boxes), len(segments)))
    t_hi = np.ones((len(boxes), len(segments)))
    for k in range(2):
        lo, hi = boxes[:, None, k], boxes[:, None, k + 2]  # (K, 1)
        moving = np.abs(d[..., k]) > 1e-12
        safe = np.where(moving, d[..., k], 1.0)
        a, b = (lo - p0[..., k]) / safe, (hi - p0[..., k]) / safe
        inside = (p0[..., k] >= lo) & (p0[..., k] <= hi)
        t_lo = np.maximum(t_lo, np.where(moving, np.minimum(a, b), np.where(inside, 0.0, 2.0)))
        t_hi = np.minimum(t_hi, np.where(moving, np.maximum(a, b), np.where(inside, 1.0, -1.0)))
    length = np.linalg.norm(d[0], axis=-1)  # (M,)
    return float(np.sum(np.clip(t_hi - t_lo, 0.0, None) * length))


def place_labels(
    fig: Figure,
    labels: Sequence[Label],
    *,
    points: Sequence[tuple[Any, FloatArray]] = (),
    leader_color: str = "0.45",
) -> list[Text]:
    """Add ``labels`` to ``fig`` as axes texts, in order (earlier ones get the better places),
    each where it overlaps no text already drawn or placed and no marked point, inside the room
    the figure gives its axes.

    Args:
        fig: a figure whose axes are laid out (drawn here, without rendering, to find where its
            texts and lines are).
        labels: what to place.
        points: ``(ax, (N, 3))`` 3-D points to keep clear (joint dots, frame origins).
        leader_color: the colour of a leader line.

    Returns:
        The texts added, in the order of ``labels``.
    """
    fig.draw_without_rendering()  # lays out the ticks and 3-D projections; no pixels
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    px_per_pt = fig.dpi / 72.0
    gap = _GAP_PT * px_per_pt
    texts = _extents([text_box(t, renderer) for t in drawn_texts(fig)])  # + the labels placed
    half = _POINT_PT * px_per_pt
    spots = _extents(
        [
            Bbox.from_extents(x - half, y - half, x + half, y + half)
            for ax, pts in points
            for x, y in (_display(ax, p) for p in np.asarray(pts, np.float64).reshape(-1, 3))
        ]
    )
    axes = {id(label.ax): label.ax for label in labels}.values()
    lines = {id(ax): _segments([*ax.lines, *ax.collections]) for ax in axes}  # not the grid
    marks = {id(ax): _segments(_axis_marks(ax)) for ax in axes}
    placed = []
    for label in labels:
        ax = label.ax
        text = ax.text2D if hasattr(ax, "text2D") else ax.text
        t: Text = text(0.0, 0.0, label.text, transform=ax.transAxes, clip_on=False, **label.style)
        bounds = _room(ax).padded(-gap)
        line_cost = _BOXED_LINE_COST if "bbox" in label.style else _LINE_COST
        anchor = None if label.at is None else _display(ax, label.at)
        far = _LEADER_AFTER * label.offset_pt * px_per_pt  # a leader from here on
        best: tuple[float, Bbox, Candidate] | None = None
        for candidate in _candidates(label, px_per_pt):
            if best is not None and candidate[3] >= best[0]:
                break  # farther than the cost of the best: none after it can beat it
            _put(t, candidate)
            box = text_box(t, renderer).padded(gap)
            unusable = _overlap(box, texts) + _overlap(box, spots) + _outside(box, bounds)
            cost = _OVERLAP_COST * unusable + candidate[3]
            cost += line_cost * _covered(_extents([box]), lines[id(ax)])
            cost += _AXIS_LINE_COST * _covered(_extents([box]), marks[id(ax)])
            if anchor is not None and candidate[3] > far:  # its leader must cross no text
                leader = _leader_ends(anchor, box.padded(-gap))[None]
                cost += _CROSSING_COST * _covered(texts, leader)
            if best is None or cost < best[0]:
                best = (cost, box, candidate)
        assert best is not None  # there is always a candidate
        _, box, candidate = best
        _put(t, candidate)
        texts = np.vstack([texts, _extents([box])])
        if anchor is not None and candidate[3] > far:
            ends = _leader_ends(anchor, box.padded(-gap))
            _leader(ax, ends, label, leader_color)
            lines[id(ax)] = np.concatenate([lines[id(ax)], ends[None]])  # later labels avoid it
        placed.append(t)
    return placed


def _leader_ends(anchor: FloatArray, box: Bbox) -> FloatArray:
    """``(2, 2)``: a leader from ``anchor`` to the nearest point of ``box`` (display pixels)."""
    return np.vstack([anchor, np.clip(anchor, [box.x0, box.y0], [box.x1, box.y1])])


def _put(t: Text, candidate: Candidate) -> None:
    xy, ha, va, _ = candidate
    t.set_position((float(xy[0]), float(xy[1])))
    t.set_horizontalalignment(ha)
    t.set_verticalalignment(va)


def _leader(ax: Any, ends: FloatArray, label: Label, color: str) -> None:
    """A thin line between the display points ``ends``, in the label's colour."""
    xy = ax.transAxes.inverted().transform(ends)
    line = Line2D(
        xy[:, 0],
        xy[:, 1],
        transform=ax.transAxes,
        color=label.style.get("color", color),
        linewidth=0.6,
        alpha=0.7,
        zorder=float(label.style.get("zorder", 6.0)) - 0.01,
    )
    ax.add_artist(line)
