"""The trajectory figure: ``q``, ``qd`` and ``qdd`` against time, in three stacked axes.

One line per column of ``q`` (a legend of the joint names), each limit the trajectory was timed
within as a shaded band beyond it in the joint's colour (position limits on ``q``, velocity
limits ``±vel_limits`` on ``qd``, acceleration limits ``±acc_limits`` on ``qdd``), and, where a
path stopped early, a vertical line labelled with the fraction reached and the reason.
Velocities and accelerations the trajectory does not hold are differentiated from ``q`` (and
``qd``) by second-order finite differences (:func:`numpy.gradient` on the sample times), and
the axis label says so.

Drawn on a bare :class:`matplotlib.figure.Figure` with the Agg canvas, matplotlib imported when
called: no pyplot, no window, the user's backend untouched, and no file written here (the
command line saves it).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from poekin.io.trajectory import Trajectory

__all__ = ["BAND_GID", "STOP_GID", "derivatives", "trajectory_figure"]

FloatArray = NDArray[np.float64]

#: The ``gid`` of every limit band and of the stop line and its label (for tests, and an SVG's
#: element ids).
BAND_GID = "limit-band"
STOP_GID = "stop"

_FIGSIZE_IN = (11.0, 8.5)
_STOP_COLOR = "#c0392b"
_SHARED_COLOR = "0.45"  # a band that several joints share
_BAND_ALPHA = 0.2
_PAD = 0.08  # of the data's span, above and below it


def derivatives(trajectory: Trajectory) -> tuple[FloatArray, FloatArray, bool, bool]:
    """``qd`` and ``qdd`` ``(K, n)`` of ``trajectory``: its own where it holds them, else by
    finite differences (``qd`` from ``q``, ``qdd`` from ``qd``), and whether each was
    differentiated."""
    t = trajectory.t
    qd_fd = trajectory.qd is None
    qd = (
        np.gradient(trajectory.q, t, axis=0, edge_order=2)
        if trajectory.qd is None
        else trajectory.qd
    )
    qdd_fd = trajectory.qdd is None
    qdd = np.gradient(qd, t, axis=0, edge_order=2) if trajectory.qdd is None else trajectory.qdd
    return np.asarray(qd, np.float64), np.asarray(qdd, np.float64), qd_fd, qdd_fd


def _limit_range(lower: FloatArray, upper: FloatArray) -> tuple[float, float]:
    """The finite limits' range (nan, nan for none)."""
    finite = [float(v) for v in (*lower, *upper) if math.isfinite(v)]
    return (min(finite), max(finite)) if finite else (math.nan, math.nan)


def _bands(
    ax: Axes, t: FloatArray, lower: FloatArray, upper: FloatArray, colors: list[Any]
) -> None:
    """Shade beyond each finite limit, to the edge of the view (set before): one band per
    distinct value, in its joint's colour, grey where several joints share it."""
    bottom, top = ax.get_ylim()
    for side, edge in ((lower, bottom), (upper, top)):
        for limit in sorted({float(v) for v in side if math.isfinite(v)}):
            joints = [j for j, v in enumerate(side) if v == limit]
            color = colors[joints[0]] if len(joints) == 1 else _SHARED_COLOR
            far = min(edge, limit) if side is lower else max(edge, limit)
            ax.fill_between(
                [t[0], t[-1]],
                limit,
                far,
                facecolor=color,
                edgecolor=color,
                alpha=_BAND_ALPHA,
                linewidth=0.8,
                gid=BAND_GID,
            )
    ax.set_ylim(bottom, top)


def _view(ax: Axes, values: FloatArray, limits: tuple[float, float]) -> None:
    """The y range: the data's, padded, and the limits' when they lie near it (within half the
    data's span), so a band shows where the motion reaches a limit."""
    lo, hi = float(values.min()), float(values.max())
    span = max(hi - lo, 1e-9 * max(abs(lo), abs(hi), 1.0))
    for limit in limits:
        if math.isfinite(limit) and lo - span / 2 <= limit <= hi + span / 2:
            lo, hi = min(lo, limit), max(hi, limit)
    span = hi - lo if hi > lo else span
    ax.set_ylim(lo - _PAD * span, hi + _PAD * span)


def trajectory_figure(
    trajectory: Trajectory, *, deg: bool = False, title: str | None = None
) -> Figure:
    """The figure of ``trajectory``: ``q``, ``qd`` and ``qdd`` against ``t`` in three stacked
    axes sharing the time axis.

    Args:
        trajectory: the :class:`~poekin.io.trajectory.Trajectory`.
        deg: show every column in degrees (rad otherwise): for arms whose joints all turn.
        title: the figure's title; default: the robot, the samples and the duration.

    Returns:
        A :class:`matplotlib.figure.Figure` on the Agg canvas: ``fig.axes`` are the ``q``,
        ``qd`` and ``qdd`` axes, each with one line per column; the limit bands are its
        ``fill_between`` collections with ``gid`` :data:`BAND_GID` (one per distinct finite
        limit value and side: joints that share a limit share its band), the stop line and
        its label have ``gid`` :data:`STOP_GID`.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t, q = trajectory.t, trajectory.q
    qd, qdd, qd_fd, qdd_fd = derivatives(trajectory)
    scale = 180.0 / math.pi if deg else 1.0
    unit = "deg" if deg else "rad"
    fig = Figure(figsize=_FIGSIZE_IN, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 1, sharex=True)
    n = trajectory.n
    cmap = colormaps["tab10" if n <= 10 else "tab20"]
    colors = [cmap(j % cmap.N) for j in range(n)]
    names = trajectory.column_names()
    pos = trajectory.pos_limits
    rows: list[tuple[FloatArray, str, FloatArray | None, FloatArray | None]] = [
        (q, f"q [{unit}]", None if pos is None else pos[:, 0], None if pos is None else pos[:, 1]),
        (qd, f"qd [{unit}/s]" + (" (finite differences)" if qd_fd else ""), None, None),
        (qdd, f"qdd [{unit}/s²]" + (" (finite differences)" if qdd_fd else ""), None, None),
    ]
    for k, lim in ((1, trajectory.vel_limits), (2, trajectory.acc_limits)):
        if lim is not None:
            values, label, _, _ = rows[k]
            rows[k] = (values, label, -lim, lim)
    for ax, (values, label, lower, upper) in zip(axes, rows, strict=True):
        shown = values * scale
        for j in range(n):
            ax.plot(t, shown[:, j], color=colors[j], lw=1.4, label=names[j])
        if lower is not None and upper is not None:
            lower, upper = lower * scale, upper * scale
            _view(ax, shown, _limit_range(lower, upper))
            _bands(ax, t, lower, upper, colors)
        else:
            _view(ax, shown, (math.nan, math.nan))
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.set_xlim(t[0], t[-1])
    axes[-1].set_xlabel("t [s]")
    axes[0].legend(
        loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False, title="joints"
    )
    stop = trajectory.stop_time
    if stop is not None:
        for ax in axes:
            ax.axvline(stop, color=_STOP_COLOR, lw=1.6, gid=STOP_GID)
        right = stop > t[0] + 0.6 * (t[-1] - t[0])
        axes[0].annotate(
            trajectory.stop_words(),
            xy=(stop, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(-6 if right else 6, -6),
            textcoords="offset points",
            ha="right" if right else "left",
            va="top",
            fontsize=9,
            color=_STOP_COLOR,
            bbox={"boxstyle": "round,pad=0.3", "fc": "white", "ec": _STOP_COLOR, "alpha": 0.9},
            gid=STOP_GID,
        )
    robot = trajectory.robot or "trajectory"
    fig.suptitle(
        title
        if title is not None
        else f"{robot}: {len(t)} samples over {trajectory.duration:.3g} s"
    )
    return fig
