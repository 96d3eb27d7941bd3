"""The calibration figure: residuals per pose before and after, and what changed per joint.

Drawn on a bare :class:`matplotlib.figure.Figure` with the Agg canvas (as
:mod:`poekin.verification.plotting`): no pyplot, no window, the user's backend untouched.
"""

from __future__ import annotations

import os
import pathlib
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from poekin.io.fileio import figure_format

if TYPE_CHECKING:
    from poekin.calibration.report import Calibration

__all__ = ["calibration_figure", "plot_calibration"]

_FIGSIZE_IN = (13.0, 8.0)
_DPI = 130
_BEFORE, _AFTER, _HELD = "0.55", "#1f5fa8", "#f07f0a"
_BARS = ("#1f5fa8", "#f07f0a", "#2ca02c")
_PARTIAL = "not all identified (other values fit as well)"


def _residuals(ax: Axes, result: Calibration, k: int, unit: str) -> None:
    """Per pose: the registered model's error, the calibrated chain's, and held out (log y)."""
    poses = np.arange(result.poses)
    series: list[tuple[str, Any, str, str]] = [
        ("model, registered", result.before[k], _BEFORE, "o"),
        ("calibrated", result.after[k], _AFTER, "."),
    ]
    if result.heldout is not None:
        series.append((f"held out ({result.folds}-fold)", result.heldout[k], _HELD, "x"))
    floor = 1e-12
    for label, values, color, marker in series:
        v = np.maximum(np.asarray(values) * 1e3, floor)
        rms = float(np.sqrt(np.mean(np.asarray(values) ** 2))) * 1e3
        ax.plot(poses, v, marker, color=color, ms=5, label=f"{label}: RMS {rms:.3g} {unit}")
    ax.set_yscale("log")
    ax.set_xlabel("pose")
    ax.set_ylabel(f"{'position' if k == 0 else 'orientation'} error [{unit}]")
    ax.grid(True, which="major", alpha=0.3)
    # below the axes: the before and after points sit at the top and the bottom of the panel
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)


def _changes(ax: Axes, result: Calibration) -> None:
    """Grouped bars per joint (and the tool): axis tilt, axis line offset, encoder offset.

    The joints set the scale: a tool offset far beyond it (a target mounted centimetres off
    the flange) is cut at the top and its value written on it. A joint with combinations left
    unidentified is hatched: its values are one of several that fit the data as well."""
    changes = result.changes()
    labels = [
        f"J{c.joint + 1}\n{result.nominal.joint_names[c.joint]}" if c.joint is not None else "tool"
        for c in changes
    ]
    x = np.arange(len(changes))
    width = 0.26
    values = np.array(
        [[0.0 if np.isnan(c.tilt_mrad) else c.tilt_mrad, c.offset_mm, c.encoder] for c in changes]
    )
    partial = {result.model.params[k].joint for k in result.undetermined}
    top = max(float(np.max(np.abs(values[:-1]), initial=0.0)), 1e-3)  # the joints'
    top = max(top, min(float(np.max(np.abs(values[-1]))), 3.0 * top))
    labels_bars = (
        "axis tilt (tool: turn) [mrad]",
        "axis line offset (tool: shift) [mm]",
        "encoder offset [mrad, mm]",
    )
    limit = 1.25 * top
    for k in range(3):
        shown = np.clip(values[:, k], -limit, limit)
        bars = ax.bar(x + (k - 1) * width, shown, width, color=_BARS[k], label=labels_bars[k])
        for bar, c, v in zip(bars, changes, values[:, k], strict=True):
            if c.joint in partial:
                bar.set_hatch("//")
                bar.set_edgecolor("white")
            if abs(v) > limit:  # cut: write its value on it
                ax.text(
                    bar.get_x() + bar.get_width() / 2,
                    np.sign(v) * limit * 0.97,
                    f"{v:.3g} {('mrad', 'mm', c.encoder_unit)[k]}",
                    ha="center",
                    va="top" if v > 0 else "bottom",
                    rotation=90,
                    fontsize=8,
                    color="white",
                )
    ax.axhline(0.0, color="0.3", linewidth=0.8)
    ax.set_xticks(x)
    ax.set_xticklabels(labels, fontsize=8)
    ax.set_ylabel("change from the model [mm, mrad]")
    ax.grid(True, axis="y", alpha=0.3)
    handles, _ = ax.get_legend_handles_labels()
    if partial:
        handles.append(Patch(facecolor="0.6", hatch="//", edgecolor="white", label=_PARTIAL))
    ax.legend(handles=handles, fontsize=8, loc="upper left", framealpha=0.9, ncol=4)
    ax.set_ylim(-1.3 * top, 1.5 * top)  # room for the legend above the bars


def calibration_figure(result: Calibration, *, title: str) -> Figure:
    """The calibration figure: (a) position error per pose, (b) orientation error per pose
    (pose data), each for the model registered to the measuring frame, the calibrated chain, and
    each pose held out of its fit; (c) each joint's calibrated change from the model. About
    13 x 8 in at 130 dpi, on the Agg canvas."""
    fig = Figure(figsize=_FIGSIZE_IN, dpi=_DPI)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(2, 2, height_ratios=(1.0, 1.0))
    pose = result.measure == "pose"
    ax_pos = fig.add_subplot(grid[0, 0] if pose else grid[0, :])
    _residuals(ax_pos, result, 0, "mm")
    ax_pos.set_title("(a) position error per pose", fontsize=10)
    if pose:
        ax_ori = fig.add_subplot(grid[0, 1])
        _residuals(ax_ori, result, 1, "mrad")
        ax_ori.set_title("(b) orientation error per pose", fontsize=10)
    ax_ch = fig.add_subplot(grid[1, :])
    _changes(ax_ch, result)
    ax_ch.set_title(
        f"({'c' if pose else 'b'}) calibrated changes from the model "
        "(joint 1's axis and offset are in the base)",
        fontsize=10,
    )
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_calibration(
    result: Calibration, path: str | os.PathLike[str], *, title: str
) -> pathlib.Path:
    """Save :func:`calibration_figure` in the format the suffix of ``path`` names."""
    p = pathlib.Path(path)
    file_format = figure_format(p, "plot")
    calibration_figure(result, title=title).savefig(p, format=file_format, dpi=_DPI)
    return p
