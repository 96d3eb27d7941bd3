"""The verification figure: how far each FK method is from MuJoCo, on log axes.

Drawn on a bare :class:`matplotlib.figure.Figure` with the Agg canvas, so making a plot never
imports :mod:`matplotlib.pyplot`, never opens a window and never changes the user's backend.
"""

from __future__ import annotations

import math
import os
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from poekin.errors import InputError

__all__ = ["plot_errors"]

FloatArray = npt.NDArray[np.float64]

_FIGSIZE_IN = (13.0, 4.5)
_DPI = 150
_N_BINS = 40
# Where exact zeros go when nothing positive gives a scale (a log axis has no zero).
_DEFAULT_FLOOR = 1e-18
_LINESTYLES = ("-", "--", ":", "-.")
_MARKERS = ("o", "x", "+", "s", "^", "v", "D")
_TOL_STYLE: dict[str, Any] = {"color": "0.25", "linestyle": (0, (5, 3)), "linewidth": 1.0}


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
) -> pathlib.Path:
    """Save the verification figure as a PNG: error histograms and a position/orientation scatter.

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
        path: where to write the PNG (PNG whatever the suffix); its directory must exist.
            An existing file is overwritten.
        pos_tol: position tolerance [m] to draw, or ``None``.
        ori_tol: orientation tolerance [rad] to draw, or ``None``.

    Returns:
        ``path`` as a :class:`pathlib.Path`.

    Raises:
        FileNotFoundError: the directory of ``path`` does not exist.
        InputError: the two mappings have different keys or lengths, or an array is not 1-D.
        OSError: the file cannot be written (left to the caller).
    """
    p = pathlib.Path(path)
    if not p.parent.is_dir():
        raise FileNotFoundError(
            f"cannot write the plot to {p}: directory {p.parent} does not exist; "
            "create it or choose another path"
        )
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
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(p, format="png", dpi=_DPI)
    return p
