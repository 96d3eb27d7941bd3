"""The verification figure: how far each FK method is from MuJoCo, on log axes.

Drawn on a bare :class:`matplotlib.figure.Figure` with the Agg canvas, so making a plot never
imports :mod:`matplotlib.pyplot`, never opens a window and never changes the user's backend.
"""

from __future__ import annotations

import math
import os
import pathlib
import textwrap
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.legend_handler import HandlerTuple
from matplotlib.lines import Line2D

from poekin.chain import Chain
from poekin.dh import joint_lines
from poekin.errors import InputError
from poekin.io.fileio import check_writable, figure_format, save_figure
from poekin.verification._labels import Label, directions_away, place_labels, screen_direction
from poekin.verification.diagnose import Diagnosis

__all__ = ["plot_diagnosis", "plot_errors"]

FloatArray = npt.NDArray[np.float64]

_FIGSIZE_IN = (13.0, 4.5)
_DPI = 150
_N_BINS = 40
# Where exact zeros go when nothing positive gives a scale (a log axis has no zero).
_DEFAULT_FLOOR = 1e-18
_LINESTYLES = ("-", "--", ":", "-.")
_MARKERS = ("o", "x", "+", "s", "^", "v", "D")
_TOL_STYLE: dict[str, Any] = {"color": "0.25", "linestyle": (0, (5, 3)), "linewidth": 1.0}
_PASS_COLOR = "#1a7f37"  # a green
_FAIL_COLOR = "#c62828"  # a red


def _as_errors(name: str, kind: str, values: npt.ArrayLike) -> FloatArray:
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise InputError(f"{kind} errors of {name!r} must have shape (N,), got {a.shape}")
    if np.any(a < 0):
        raise InputError(f"{kind} errors of {name!r} must be >= 0, got min {float(np.min(a))}")
    return a


def _floor(arrays: Sequence[FloatArray]) -> float:
    """A decade below the smallest positive finite value (``1e-18`` if there is none)."""
    pos = [a[np.isfinite(a) & (a > 0)] for a in arrays]
    smallest = min((float(p.min()) for p in pos if p.size), default=None)
    if smallest is None:
        return _DEFAULT_FLOOR
    return float(10.0 ** (math.floor(math.log10(smallest)) - 1))


def _shown(a: FloatArray, floor: float) -> FloatArray:
    """The finite values of ``a`` (all >= 0), with exact zeros moved up to ``floor``."""
    f = a[np.isfinite(a)]
    return np.maximum(f, floor)


def _pow10(x: float) -> str:
    """``1e-18`` for a power of ten (the floors), ``%.2g`` otherwise."""
    e = round(math.log10(x))
    return f"1e{e}" if math.isclose(x, 10.0**e, rel_tol=1e-9) else f"{x:.2g}"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _fmt(x: float) -> str:
    return "0" if x == 0 else f"{x:.2g}"


def _stats_label(name: str, a: FloatArray) -> str:
    f = a[np.isfinite(a)]
    if not f.size:
        return f"{name}  (no finite values)"
    return f"{name}  max {_fmt(float(f.max()))}  med {_fmt(float(np.median(f)))}"


def _extent(arrays: Sequence[FloatArray]) -> list[float]:
    """``[min, max]`` over the non-empty arrays, ``[]`` if all are empty."""
    nonempty = [a for a in arrays if a.size]
    if not nonempty:
        return []
    return [min(float(a.min()) for a in nonempty), max(float(a.max()) for a in nonempty)]


def _log_bins(arrays: Sequence[FloatArray]) -> FloatArray:
    """``_N_BINS`` log-spaced edges from the smallest to the largest value (all > 0)."""
    nonempty = [a for a in arrays if a.size]
    lo = min((float(a.min()) for a in nonempty), default=_DEFAULT_FLOOR)
    hi = max((float(a.max()) for a in nonempty), default=_DEFAULT_FLOOR)
    if hi <= lo * 1.01:  # one value, or nearly: half a decade either side
        lo, hi = lo / math.sqrt(10.0), hi * math.sqrt(10.0)
    edges = np.logspace(math.log10(lo), math.log10(hi), _N_BINS + 1)
    edges[0], edges[-1] = lo, hi  # logspace may round the ends past the data
    return edges


def _notes(raw: Sequence[FloatArray], floor: float) -> str:
    """Panel text for the values that cannot be drawn as they are."""
    n_zero = sum(int(np.count_nonzero(a == 0)) for a in raw)
    n_bad = sum(int(np.count_nonzero(~np.isfinite(a))) for a in raw)
    lines = []
    if n_zero:
        lines.append(f"{_count(n_zero, 'exact zero')} shown at {_pow10(floor)}")
    if n_bad:
        lines.append(f"{n_bad} NaN/inf not shown")
    return "\n".join(lines)


def _log_limits(values: Sequence[float], decades: float = 2.0) -> tuple[float, float]:
    """Log-axis limits around the positive finite ``values``, with a margin, and at least
    ``decades`` wide (centred), so that there are labelled major ticks."""
    v = [x for x in values if math.isfinite(x) and x > 0]
    lo, hi = (min(v), max(v)) if v else (_DEFAULT_FLOOR, _DEFAULT_FLOOR)
    margin = 10.0 ** max(0.15, 0.04 * math.log10(hi / lo))  # 4 % of the span each side
    lo, hi = lo / margin, hi * margin
    span = math.log10(hi / lo)
    if span < decades:
        pad = 10.0 ** ((decades - span) / 2)
        lo, hi = lo / pad, hi * pad
    return lo, hi


def _legend(ax: Axes, note: str) -> None:
    """The legend, with ``note`` (what is drawn where it does not belong) as its title."""
    ax.legend(
        loc="best",
        fontsize=8,
        framealpha=0.9,
        title=note or None,
        title_fontsize=8,
        alignment="left",
    )


def _histogram(
    ax: Axes,
    errors: Mapping[str, FloatArray],
    *,
    xlabel: str,
    unit: str,
    tol: float | None,
) -> None:
    raw = list(errors.values())
    floor = _floor(raw)
    shown = [_shown(a, floor) for a in raw]
    bin_edges: list[float] = _log_bins(shown).tolist()
    for i, (name, a, s) in enumerate(zip(errors, raw, shown, strict=True)):
        color = f"C{i % 10}"
        ls = _LINESTYLES[i % len(_LINESTYLES)]
        ax.hist(s, bins=bin_edges, histtype="stepfilled", color=color, alpha=0.12, linewidth=0)
        ax.hist(
            s,
            bins=bin_edges,
            histtype="step",
            color=color,
            linestyle=ls,
            linewidth=1.6,
            label=_stats_label(name, a),
        )
    if tol is not None:
        ax.axvline(tol, **_TOL_STYLE, label=f"tol {tol:g} {unit}")
    ax.set_xscale("log")
    ax.set_xlim(_log_limits([bin_edges[0], bin_edges[-1], *([tol] if tol is not None else [])]))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("count")
    ax.set_ylim(0, ax.get_ylim()[1] * 1.35)  # headroom for the legend and the note
    _legend(ax, _notes(raw, floor))
    ax.grid(True, which="major", axis="x", alpha=0.3)


def _scatter(
    ax: Axes,
    pos_err: Mapping[str, FloatArray],
    ori_err: Mapping[str, FloatArray],
    *,
    pos_tol: float | None,
    ori_tol: float | None,
) -> None:
    pos_floor, ori_floor = _floor(list(pos_err.values())), _floor(list(ori_err.values()))
    for i, name in enumerate(pos_err):
        p, o = pos_err[name], ori_err[name]
        ok = np.isfinite(p) & np.isfinite(o)
        marker = _MARKERS[i % len(_MARKERS)]
        color = f"C{i % 10}"
        # Hollow or line markers, so that coinciding points of two methods both show.
        style: dict[str, Any] = (
            {"color": color}
            if marker in ("x", "+")
            else {"facecolors": "none", "edgecolors": color}
        )
        ax.scatter(
            np.maximum(p[ok], pos_floor),
            np.maximum(o[ok], ori_floor),
            s=18,
            marker=marker,
            linewidths=0.9,
            alpha=0.7,
            label=name,
            **style,
        )
    if pos_tol is not None:
        ax.axvline(pos_tol, **_TOL_STYLE, label="tol")
    if ori_tol is not None:
        ax.axhline(ori_tol, **_TOL_STYLE, label=None if pos_tol is not None else "tol")
    ax.set_xscale("log")
    ax.set_yscale("log")
    xs = [_shown(a, pos_floor) for a in pos_err.values()]
    ys = [_shown(a, ori_floor) for a in ori_err.values()]
    ax.set_xlim(_log_limits([*_extent(xs), *([pos_tol] if pos_tol is not None else [])]))
    ax.set_ylim(_log_limits([*_extent(ys), *([ori_tol] if ori_tol is not None else [])]))
    ax.set_xlabel("position error [m]")
    ax.set_ylabel("orientation error [rad]")
    # A point with a zero coordinate sits on that axis' floor.
    n_pz = sum(int(np.count_nonzero(a == 0)) for a in pos_err.values())
    n_oz = sum(int(np.count_nonzero(a == 0)) for a in ori_err.values())
    parts = []
    if n_pz:
        parts.append(f"{_count(n_pz, 'zero position error')} shown at {_pow10(pos_floor)}")
    if n_oz:
        parts.append(f"{_count(n_oz, 'zero orientation error')} shown at {_pow10(ori_floor)}")
    _legend(ax, "\n".join(parts))
    ax.grid(True, which="major", alpha=0.3)


def plot_errors(
    pos_err: Mapping[str, npt.ArrayLike],
    ori_err: Mapping[str, npt.ArrayLike],
    *,
    title: str,
    path: str | os.PathLike[str],
    pos_tol: float | None = None,
    ori_tol: float | None = None,
    passed: bool | None = None,
) -> pathlib.Path:
    """Save the verification figure: error histograms and a position/orientation scatter.

    Three panels: (a) histogram of position error per method, (b) histogram of orientation
    error per method, both on a log x-axis with log-spaced bins spanning the data, their
    legends giving each method's max and median; (c) position vs orientation error per sample,
    log-log, one colour per method. Exact zeros cannot sit on a log axis: they are drawn at a
    floor one decade below the smallest positive value (``1e-18`` if none is positive), and
    each panel says how many there are. Tolerances, when given, are dashed lines labelled
    ``tol``. The figure is about 13 x 4.5 in at 150 dpi.

    Args:
        pos_err: ``{method: (N,) position errors [m]}``, e.g. ``{"space PoE": ..., "body PoE":
            ...}``; values >= 0. NaN/inf are left out and counted in the panel text.
        ori_err: ``{method: (N,) orientation errors [rad]}``, same keys and lengths.
        title: the figure title.
        path: where to write the figure, in the format its suffix names (``.png``, ``.pdf``,
            ``.svg``, ``.jpg``...: :data:`poekin.io.fileio.FIGURE_FORMATS`); its folder must
            exist and take new files (checked first). An existing file is overwritten.
        pos_tol: position tolerance [m] to draw, or ``None``.
        ori_tol: orientation tolerance [rad] to draw, or ``None``.
        passed: the verdict, said under the title (``PASS``/``FAIL`` and the tolerances, in
            green or red), or ``None`` for none.

    Returns:
        ``path`` as a :class:`pathlib.Path`.

    Raises:
        InputError: the two mappings have different keys or lengths, an array is not 1-D, the
            suffix names no figure format, or the file cannot be written there
            (:func:`poekin.io.fileio.cannot_write` says why; checked before any drawing).
    """
    p = pathlib.Path(path)
    figure_format(p, "plot")
    check_writable(p, "the plot")
    if list(pos_err) != list(ori_err):
        raise InputError(
            f"pos_err and ori_err must have the same methods in the same order, "
            f"got {list(pos_err)} and {list(ori_err)}"
        )
    pos = {k: _as_errors(k, "position", v) for k, v in pos_err.items()}
    ori = {k: _as_errors(k, "orientation", v) for k, v in ori_err.items()}
    for k in pos:
        if pos[k].shape != ori[k].shape:
            raise InputError(
                f"{k!r} has {pos[k].size} position errors but {ori[k].size} orientation errors"
            )

    fig = Figure(figsize=_FIGSIZE_IN, dpi=_DPI)
    FigureCanvasAgg(fig)
    ax_pos, ax_ori, ax_sc = fig.subplots(1, 3)
    _histogram(ax_pos, pos, xlabel="position error [m]", unit="m", tol=pos_tol)
    _histogram(ax_ori, ori, xlabel="orientation error [rad]", unit="rad", tol=ori_tol)
    _scatter(ax_sc, pos, ori, pos_tol=pos_tol, ori_tol=ori_tol)
    ax_pos.set_title("(a) position error", fontsize=10)
    ax_ori.set_title("(b) orientation error", fontsize=10)
    ax_sc.set_title("(c) per sample", fontsize=10)
    if passed is None:
        fig.suptitle(title)
    else:
        fig.suptitle(title, y=0.99)
        tolerances = ", ".join(
            f"{tol:g} {unit}" for tol, unit in ((pos_tol, "m"), (ori_tol, "rad")) if tol
        )
        verdict = "PASS" if passed else "FAIL"
        within = "within" if passed else "outside"
        fig.text(
            0.5,
            0.915,
            f"{verdict}: {within} tolerances {tolerances}" if tolerances else verdict,
            ha="center",
            fontsize=12,
            fontweight="bold",
            color=_PASS_COLOR if passed else _FAIL_COLOR,
        )
    fig.tight_layout(rect=(0, 0, 1, 0.93 if passed is not None else 1))
    return save_figure(fig, p, dpi=_DPI, what="plot")


# --- the diagnosis figure -----------------------------------------------------------------------

_DIAG_FIGSIZE_IN = (14.0, 7.0)
_DIAG_DPI = 120
_MODEL_COLOR = "#1f5fa8"  # a blue
_YOURS_COLOR = "#f07f0a"  # an orange
_TRIAD_COLORS = ("#d62728", "#2ca02c", "#5a4fcf")  # x, y, z (z violet-blue, not the model's)
_TAG_COLOR = "0.35"
_ELEV, _AZIM = 25.0, -60.0
_ARROW_FRAC = 0.13  # axis arrows: this fraction of the drawing's extent
_YOURS_ARROW = 0.7  # your arrows are shorter, so that the model's show beyond them
_TRIAD_FRAC = 0.07  # frame triads
_NEAR_FRAC = 0.03  # points closer than this (fraction of the extent) share one tag
_MARGIN_FRAC = 0.05
_ZOOM = 1.22  # of the 3-D box in its panel (matplotlib's default leaves much space)
_WRAP = 28  # characters per line of a finding label
_DOWN = np.array([0.0, -1.0])  # notes at a base frame go below it
_BOX: dict[str, Any] = {
    "boxstyle": "round,pad=0.25",
    "facecolor": "white",
    "linewidth": 0.8,
    "alpha": 0.92,
}


def _screen_dir(v: FloatArray) -> FloatArray:
    """The 2-D direction (right, up) in which the 3-D direction ``v`` shows on screen."""
    return screen_direction(v, _ELEV, _AZIM)


def _tag(ax: Any, at: FloatArray, text: str, obstacles: Sequence[FloatArray], color: str) -> Label:
    """A small joint or frame tag (``J3``, ``M``) beside ``at``, away from ``obstacles``."""
    style = {"color": color, "fontsize": 7.5, "zorder": 6}
    return Label(ax, text, style, at=at, directions=directions_away(obstacles), offset_pt=4.0)


def _note(
    ax: Any,
    at: FloatArray,
    text: str,
    obstacles: Sequence[FloatArray],
    color: str,
    *,
    offset_pt: float = 8.0,
    directions: tuple[FloatArray, ...] = (),
) -> Label:
    """A boxed, bold finding label (a joint's, the base's, M's) beside ``at``."""
    style = {
        "color": color,
        "fontsize": 9,
        "fontweight": "bold",
        "bbox": {**_BOX, "edgecolor": color},
        "zorder": 7,
    }
    return Label(
        ax,
        text,
        style,
        at=at,
        directions=directions or directions_away(obstacles),
        offset_pt=offset_pt,
    )


def draw_triad(
    ax: Any,
    T: FloatArray,
    length: float,
    *,
    dashed: bool = False,
    width: float = 1.6,
    zorder: float = 4.0,
) -> None:
    """The x, y, z axes of the frame ``T`` as short red, green, blue lines (thinner and dashed
    for a frame drawn as a ghost). Shared by the diagnosis figure and :mod:`poekin.viewer.draw`.
    """
    o = T[:3, 3]
    for k, color in enumerate(_TRIAD_COLORS):
        tip = o + length * T[:3, k]
        ax.plot(
            [o[0], tip[0]],
            [o[1], tip[1]],
            [o[2], tip[2]],
            color=color,
            linewidth=width * (0.7 if dashed else 1.0),
            linestyle=(0, (2, 1.5)) if dashed else "-",
            zorder=zorder,
        )


def _path(chain: Chain, base: FloatArray) -> FloatArray:
    """``(n + 2, 3)``: the base origin, the joint points, the end-frame origin."""
    return np.vstack([base[:3, 3], joint_lines(chain)[1], chain.home[:3, 3]])


def _skeleton(
    ax: Any, chain: Chain, base: FloatArray, arrow: float, triad: float, *, mine: bool
) -> None:
    """Base-to-tip polyline through the joint points, joint dots, axis arrows and end-frame
    triad of ``chain`` (its base frame at ``base``). The model is drawn wide, pale and
    underneath, yours narrow, dashed and on top, so that both show where they coincide."""
    color = _YOURS_COLOR if mine else _MODEL_COLOR
    dirs, points = joint_lines(chain)
    path = _path(chain, base)
    z = 3.0 if mine else 2.0
    ax.plot(
        path[:, 0],
        path[:, 1],
        path[:, 2],
        color=color,
        linewidth=1.5 if mine else 4.5,
        linestyle=(0, (4, 2)) if mine else "-",
        alpha=1.0 if mine else 0.3,
        solid_capstyle="round",
        zorder=z,
    )
    if chain.n_joints:
        ax.quiver(
            points[:, 0],
            points[:, 1],
            points[:, 2],
            dirs[:, 0],
            dirs[:, 1],
            dirs[:, 2],
            length=arrow * (_YOURS_ARROW if mine else 1.0),
            normalize=True,
            arrow_length_ratio=0.3,
            color=color,
            linewidth=1.6 if mine else 3.2,
            zorder=z + 0.1,
        )
        ax.plot(
            points[:, 0],
            points[:, 1],
            points[:, 2],
            linestyle="none",
            marker="o",
            markersize=3.5 if mine else 7.5,
            markerfacecolor=color if mine else "white",
            markeredgecolor=color,
            markeredgewidth=0.8 if mine else 1.8,
            zorder=z + 0.2,
        )
    draw_triad(ax, chain.home, triad, dashed=mine, zorder=z + 0.3)


def _span(points: FloatArray) -> float:
    """The largest x, y or z range of ``points``; 1 m if they all coincide."""
    span = float(np.max(points.max(axis=0) - points.min(axis=0)))
    return span if span > 1e-9 else 1.0


def _tips(chain: Chain, base: FloatArray, arrow: float, triad: float) -> FloatArray:
    """The ends of everything drawn for ``chain`` away from its points: arrows and triads."""
    dirs, points = joint_lines(chain)
    ends = [points + arrow * dirs]
    for T in (base, chain.home):
        ends.append(T[:3, 3] + triad * T[:3, :3].T)
    return np.vstack(ends)


def _groups(points: FloatArray, near: float) -> list[list[int]]:
    """Indices of ``points`` grouped by proximity (each joins the first group within ``near``)."""
    groups: list[list[int]] = []
    for i, p in enumerate(points):
        for g in groups:
            if np.linalg.norm(points[g[0]] - p) <= near:
                g.append(i)
                break
        else:
            groups.append([i])
    return groups


def _obstacles(chain: Chain, base: FloatArray, index: int) -> list[FloatArray]:
    """Screen directions of what leaves joint ``index``'s point: its axis arrow and the skeleton
    towards the previous and the next point."""
    dirs, points = joint_lines(chain)
    path = _path(chain, base)
    p = points[index]
    return [
        _screen_dir(dirs[index]),
        _screen_dir(path[index] - p),
        _screen_dir(path[index + 2] - p),
    ]


def _panel(
    ax: Any,
    model: Chain,
    yours: Chain,
    your_base: FloatArray,
    *,
    labels: Mapping[int, str],
    base_note: str,
    home_note: str,
) -> tuple[list[Label], FloatArray]:
    """One 3-D panel: the model's chain and ``yours`` (its base frame at ``your_base``). Returns
    its labels, to place once the figure is laid out, and the points they must keep clear."""
    eye = np.eye(4)
    model_path, your_path = _path(model, eye), _path(yours, your_base)
    extent = _span(np.vstack([model_path, your_path]))
    arrow, triad, near = _ARROW_FRAC * extent, _TRIAD_FRAC * extent, _NEAR_FRAC * extent
    drawn = np.vstack(
        [
            model_path,
            your_path,
            _tips(model, eye, arrow, triad),
            _tips(yours, your_base, arrow, triad),
        ]
    )
    lo, hi = drawn.min(axis=0), drawn.max(axis=0)
    centre, half = (lo + hi) / 2, float(np.max(hi - lo)) / 2 + _MARGIN_FRAC * extent

    _skeleton(ax, model, eye, arrow, triad, mine=False)
    _skeleton(ax, yours, your_base, arrow, triad, mine=True)
    draw_triad(ax, eye, triad, dashed=False, zorder=2.5)
    notes: list[Label] = []  # the finding labels, placed first
    tags: list[Label] = []
    down = directions_away([-_DOWN])  # below first, as notes at a base frame go
    if not np.allclose(your_base, eye, atol=1e-9):
        draw_triad(ax, your_base, triad, dashed=True, zorder=3.5)
        at = your_base[:3, 3]
        notes.append(_note(ax, at, "your base", [], _YOURS_COLOR, directions=down))
    if base_note:
        notes.append(_note(ax, eye[:3, 3], base_note, [], "0.15", directions=down))

    # Tags: grey at the model's joint points (one per group of coinciding points), the finding
    # labels there in the model's colour, orange at your points where they are apart. Each
    # prefers where nothing else leaves its point on screen (no line, no point close by);
    # place_labels then keeps every text clear of the others.
    chains = ((model, eye), (yours, your_base))
    keypoints = np.vstack([model_path, your_path, *(_tips(c, b, arrow, triad) for c, b in chains)])

    def crowd(at: FloatArray) -> list[FloatArray]:
        d = np.linalg.norm(keypoints - at, axis=1)
        close = keypoints[(d > near) & (d < 5 * near)]
        return [_screen_dir(k - at) for k in close]

    _, pm = joint_lines(model)
    _, py = joint_lines(yours)
    for g in _groups(pm, near):
        at = pm[g[0]]
        obstacles = crowd(at)
        for i in g:
            obstacles += _obstacles(model, eye, i) + _obstacles(yours, your_base, i)
        plain = "/".join(f"J{i + 1}" for i in g if i not in labels)
        found = [f"J{i + 1} {labels[i]}" for i in g if i in labels]
        if found:
            text = "\n".join(textwrap.fill(t, _WRAP, subsequent_indent="  ") for t in found)
            notes.append(_note(ax, at, text, obstacles, _MODEL_COLOR))
        if plain:
            tags.append(_tag(ax, at, plain, obstacles, _TAG_COLOR))
    apart = 2 * near  # closer than this, your point is read off the model's tag
    for g in _groups(py, near):
        if all(np.linalg.norm(py[i] - pm[i]) > apart for i in g):
            obstacles = crowd(py[g[0]])
            obstacles += [o for i in g for o in _obstacles(yours, your_base, i)]
            text = "/".join(f"J{i + 1}" for i in g)
            tags.append(_tag(ax, py[g[0]], text, obstacles, _YOURS_COLOR))

    # The end frame: "M" (or the finding about it) beside the model's; yours tagged if apart.
    for path, chain, mine in ((model_path, model, False), (your_path, yours, True)):
        if mine and np.linalg.norm(your_path[-1] - model_path[-1]) <= apart:
            continue
        at = path[-1]
        obstacles = [*crowd(at), _screen_dir(path[-2] - at)]
        obstacles += [_screen_dir(chain.home[:3, k]) for k in range(3)]
        if mine:
            tags.append(_tag(ax, at, "M", obstacles, _YOURS_COLOR))
        elif home_note:
            notes.append(_note(ax, at, home_note, obstacles, "0.15"))
        else:
            tags.append(_tag(ax, at, "M", obstacles, _TAG_COLOR))

    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        set_lim(float(c) - half, float(c) + half)
    ax.set_box_aspect((1, 1, 1), zoom=_ZOOM)
    ax.set_proj_type("ortho")
    ax.view_init(elev=_ELEV, azim=_AZIM)
    ax.set_xlabel("x [m]", labelpad=2)
    ax.set_ylabel("y [m]", labelpad=2)
    ax.set_zlabel("z [m]", labelpad=2)
    ax.tick_params(labelsize=7, pad=0)
    return notes + tags, keypoints


_LENGTH_KINDS = ("link_length", "link_twist")
_MAX_LENGTH_LINES = 8


def _findings_note(
    diagnosis: Diagnosis, head: str, shift_kind: str, shift_word: str, turn_kind: str
) -> str:
    """``head`` then the sizes of the findings of ``shift_kind`` (m) and ``turn_kind`` (rad)."""
    parts = []
    for f in diagnosis.findings:
        if f.kind == turn_kind:
            parts.append(f"turned {math.degrees(f.value):.3g} deg")
        elif f.kind == shift_kind:
            parts.append(f"{shift_word} {f.value:.3g} m")
    return head + ", ".join(parts) if parts else ""


def _base_note(diagnosis: Diagnosis) -> str:
    return _findings_note(diagnosis, "base ", "base_shift", "shifted", "base_rotation")


def _home_note(diagnosis: Diagnosis) -> str:
    return _findings_note(diagnosis, "M: ", "home_position", "off by", "home_rotation")


def _errors_line(p: float, r: float) -> str:
    return f"max error {p:.3g} m, {r:.3g} rad ({math.degrees(r):.3g} deg)"


def _diagnosis_figure(diagnosis: Diagnosis, title: str | None = None) -> Figure:
    """The figure that :func:`plot_diagnosis` saves: two 3-D panels, a legend, a title."""
    d = diagnosis
    fig = Figure(figsize=_DIAG_FIGSIZE_IN, dpi=_DIAG_DPI)
    FigureCanvasAgg(fig)
    left = fig.add_subplot(1, 2, 1, projection="3d", computed_zorder=False)
    right = fig.add_subplot(1, 2, 2, projection="3d", computed_zorder=False)
    eye = np.eye(4)
    left_labels, left_points = _panel(
        left, d.model, d.yours, eye, labels={}, base_note=_base_note(d), home_note=""
    )
    right_labels, right_points = _panel(
        right,
        d.model,
        d.aligned,
        np.asarray(d.base, dtype=np.float64),
        labels=d.joint_labels(),
        base_note="",
        home_note=_home_note(d),
    )
    left.set_title("as given (each in its own base frame)", fontsize=11)
    errors = _errors_line(d.aligned_max_pos_err_m, d.aligned_max_ori_err_rad)
    # what report() says: aligned only where the alignment reduced the errors
    after = " after alignment" if d.base_aligned else ""
    right.set_title(f"{d.placement(True)}\n{errors}{after}", fontsize=11)

    lengths = [f.message.split(" (")[0] for f in d.findings if f.kind in _LENGTH_KINDS]
    if lengths:  # in a corner of the right panel where it covers no tick label nor label
        shown = lengths[:_MAX_LENGTH_LINES]
        if len(lengths) > len(shown):
            shown.append(f"... and {len(lengths) - len(shown)} more")
        box = {"boxstyle": "round", "facecolor": "white", "edgecolor": "0.6"}
        text = "DH link lengths and twists that differ:\n" + "\n".join(shown)
        right_labels.append(Label(right, text, {"fontsize": 8, "bbox": box, "zorder": 7}))

    yours_name = d.yours.robot or "your parameters"
    model_name = d.model.robot or "the model"
    handles: list[Any] = [
        Line2D(
            [],
            [],
            color=_MODEL_COLOR,
            linewidth=2.8,
            marker="o",
            markersize=7.5,
            markerfacecolor="white",
            markeredgewidth=1.8,
        ),
        Line2D(
            [],
            [],
            color=_YOURS_COLOR,
            linewidth=1.5,
            linestyle=(0, (4, 2)),
            marker="o",
            markersize=3.5,
        ),
        tuple(Line2D([], [], color=c, linewidth=1.6) for c in _TRIAD_COLORS),
    ]
    names = [
        f"model: {model_name} / {d.model.frame}",
        f"yours: {yours_name}",
        "x, y, z of the base and end frames (dashed: yours)",
    ]
    fig.legend(
        handles,
        names,
        loc="lower center",
        ncol=3,
        fontsize=9,
        frameon=False,
        handler_map={tuple: HandlerTuple(ndivide=None)},
        title="at q = 0: joint points, joint axes as arrows, base to end frame M",
        title_fontsize=9,
    )
    head = title or f"{yours_name} vs {model_name}: {'match' if d.matches else 'mismatch'}"
    fig.suptitle(
        f"{head}\n{_errors_line(d.max_pos_err_m, d.max_ori_err_rad)} over {d.samples} random q",
        fontsize=12,
    )
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.12, top=0.85, wspace=0.0)
    place_labels(
        fig, [*right_labels, *left_labels], points=[(left, left_points), (right, right_points)]
    )
    return fig


def plot_diagnosis(
    diagnosis: Diagnosis, path: str | os.PathLike[str], *, title: str | None = None
) -> None:
    """Save a picture of a :func:`~poekin.verification.diagnose.diagnose` result.

    The arm at ``q = 0`` as a 3-D skeleton (base origin, joint points, end-frame origin) with
    each joint's screw axis as an arrow, the model's chain in blue and yours in orange, overlaid:
    on the left each in its own base frame, as given; on the right yours moved by the base
    alignment into the model's base frame, with the joints that differ labelled (``J4
    flipped``) and a different ``M`` or base frame noted. Base and end frames are small x/y/z
    triads. The figure is 14 x 7 in at 120 dpi.

    Args:
        diagnosis: what :func:`~poekin.verification.diagnose.diagnose` returned.
        path: where to write it, in the format its suffix names (``.png``, ``.pdf``, ...:
            :data:`poekin.io.fileio.FIGURE_FORMATS`); an existing file is overwritten.
        title: the figure title; default ``"<yours> vs <model>: match|mismatch"``. A second line
            gives the largest errors.

    Raises:
        InputError: the suffix names no figure format, or the file cannot be written there
            (:func:`poekin.io.fileio.cannot_write` says why; checked before any drawing).
    """
    figure_format(path, "plot")
    check_writable(path, "the plot")
    save_figure(_diagnosis_figure(diagnosis, title), path, dpi=_DIAG_DPI, what="plot")
