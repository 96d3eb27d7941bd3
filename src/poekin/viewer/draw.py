"""``poekin draw``: the viewer's scene as a static matplotlib figure, for reports and autograders.

The same :mod:`poekin.viewer.scene` computation as the browser viewer: the robot as its stand-in
skeleton (links between joint anchors), each joint's screw axis at ``q`` as a line through its
axis point with an arrow, labelled ``S_i`` (space form) or ``B_i`` (body form), the world frame,
the end frame ``T(q)`` and the home pose ``M`` (dashed); with a parameter set, your arm in orange
with the end-frame error in the title; with ``all_frames``, every body and site as a small triad.

Drawn on a bare :class:`~matplotlib.figure.Figure` (no pyplot, no change of backend), like
:mod:`poekin.verification.plotting`.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from poekin.chain import Chain
from poekin.dh import DHTable
from poekin.errors import InputError
from poekin.io.fileio import check_writable, figure_format, save_figure
from poekin.verification._labels import Label, directions_away, place_labels, screen_direction
from poekin.verification.plotting import _MODEL_COLOR, _YOURS_COLOR, draw_triad
from poekin.viewer.scene import (
    FORMS,
    Comparison,
    Form,
    Ghost,
    Snapshot,
    Subject,
    ghost,
    screw_kind,
    skeleton,
    snapshot,
)

__all__ = ["draw", "figure"]

FloatArray = NDArray[np.float64]
_FIGSIZE_IN = (9.0, 7.5)
_DPI = 120
_LINK_COLOR = "#8a9bb8"
_ELEV, _AZIM = 25.0, -60.0


def _screws(
    ax: Any,
    screws: FloatArray,
    points: FloatArray,
    labels: list[str],
    color: str,
    length: float,
    *,
    width: float,
) -> list[Label]:
    """Each axis as a line through its point with an arrow (from ``-0.6 L`` to ``L``; a slide
    from its point on); its label goes beyond the arrow's tip, where that is free."""
    out = []
    for S, p, label in zip(screws, points, labels, strict=True):
        kind = screw_kind(S)
        d = S[:3] if kind != "prismatic" else S[3:] / np.linalg.norm(S[3:])
        start = p if kind == "prismatic" else p - 0.6 * length * d
        ax.quiver(
            *start,
            *(d * (length + (p - start) @ d)),
            color=color,
            linewidth=width,
            arrow_length_ratio=0.18,
            linestyle="--" if kind == "prismatic" else "-",
            zorder=5,
        )
        if not label:
            continue
        text = label + (" (slide)" if kind == "prismatic" else "")
        if kind == "pitched":
            text += f" (pitch {float(S[:3] @ S[3:]):.3g} m/rad)"
        style = {"color": color, "fontsize": 9, "fontweight": "bold", "zorder": 6}
        away = directions_away([-_on_screen(d)])
        out.append(Label(ax, text, style, at=p + length * d, directions=away, offset_pt=3.0))
    return out


def _on_screen(v: FloatArray) -> FloatArray:
    return screen_direction(v, _ELEV, _AZIM)


def _frame_label(ax: Any, T: FloatArray, text: str, **style: Any) -> Label:
    """A label by the origin of frame ``T``, away from its three axes."""
    away = directions_away([_on_screen(T[:3, k]) for k in range(3)])
    return Label(ax, text, {"fontsize": 9, "zorder": 6, **style}, at=T[:3, 3], directions=away)


def figure(
    subject: Subject,
    qpos: ArrayLike,
    *,
    comparison: Comparison | None = None,
    aligned: bool = False,
    all_frames: bool = False,
    form: Form = "space",
    tips: dict[int, list[Any]] | None = None,
    title: str | None = None,
) -> Figure:
    """The drawing of ``subject`` at ``qpos`` (see the module docstring). Its labels overlap
    neither each other nor the axes' tick labels (:mod:`poekin.verification._labels`).

    Raises:
        InputError: ``qpos`` is not ``nq`` finite numbers, or an unknown ``form``.
    """
    if form not in FORMS:
        raise InputError(f"form must be 'space' or 'body', got {form!r}")
    snap: Snapshot = snapshot(subject, qpos)
    e = subject.extent
    fig = Figure(figsize=_FIGSIZE_IN, dpi=_DPI)
    FigureCanvasAgg(fig)
    ax: Any = fig.add_subplot(1, 1, 1, projection="3d", computed_zorder=False)
    drawn = [
        snap.frames[:, :3, 3],
        snap.points,
        snap.T[None, :3, 3],
        snap.home[None, :3, 3],
        np.zeros((1, 3)),
    ]
    for seg in skeleton(subject, tips):
        T = snap.bodies[seg.body]
        a, b = T[:3, :3] @ np.array(seg.a) + T[:3, 3], T[:3, :3] @ np.array(seg.b) + T[:3, 3]
        ax.plot(
            *np.stack([a, b]).T,
            color=_LINK_COLOR,
            linewidth=7,
            solid_capstyle="round",
            alpha=0.9,
            zorder=2,
        )
    if len(snap.points):
        ax.plot(
            *snap.points.T,
            linestyle="none",
            marker="o",
            markersize=6,
            markerfacecolor="white",
            markeredgecolor=_MODEL_COLOR,
            zorder=3,
        )
    symbol = "S" if form == "space" else "B"
    L = 0.22 * e
    labels = _screws(
        ax,
        snap.screws,
        snap.points,
        [f"{symbol}{i + 1}" for i in range(subject.n_joints)],
        _MODEL_COLOR,
        L,
        width=2.2,
    )
    triad = 0.1 * e
    draw_triad(ax, np.eye(4), 1.3 * triad, width=1.8)
    draw_triad(ax, snap.T, 1.3 * triad, width=2.6)
    draw_triad(ax, snap.home, triad, dashed=True, width=1.8)
    frames = [
        _frame_label(ax, snap.T, f"T(q): {subject.end_name}"),
        _frame_label(ax, snap.home, "M", color="0.3"),
        _frame_label(ax, np.eye(4), "world", color="0.3", fontsize=8),
    ]
    error = ""
    if comparison is not None:
        gh: Ghost = ghost(comparison, snap, aligned=aligned)
        found = comparison.diagnosis.joint_labels()
        stops = np.vstack([gh.links[0][None, :3, 3], gh.points, gh.T[None, :3, 3]])
        ax.plot(
            *stops.T,
            color=_YOURS_COLOR,
            linewidth=2.0,
            linestyle=(0, (4, 2)),
            marker="o",
            markersize=3.5,
            zorder=3.5,
        )
        names = [f"J{i + 1} {found[i]}" if i in found else "" for i in range(gh.screws.shape[0])]
        labels += _screws(ax, gh.screws, gh.points, names, _YOURS_COLOR, 0.7 * L, width=1.4)
        draw_triad(ax, gh.T, triad, dashed=True, width=1.8)
        frames.insert(1, _frame_label(ax, gh.T, f"yours: {comparison.name}", color=_YOURS_COLOR))
        drawn += [stops]
        placed = comparison.diagnosis.placement(aligned)
        error = (
            f"\n{comparison.name} ({placed}): end frame off by {gh.pos_err:.3g} m, "
            f"{gh.ori_err:.3g} rad ({math.degrees(gh.ori_err):.3g} deg)"
        )
    labels += frames
    if all_frames:
        for name, T in zip(subject.frame_names, snap.frames, strict=True):
            draw_triad(ax, T, 0.5 * triad, width=1.0)
            labels.append(_frame_label(ax, T, name, fontsize=6, color="0.35"))
    points = np.vstack(drawn)
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = (lo + hi) / 2, float(np.max(hi - lo)) / 2 + 0.15 * e
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
        set_lim(float(c) - half, float(c) + half)
    ax.set_box_aspect((1, 1, 1), zoom=1.1)
    ax.set_proj_type("ortho")
    ax.view_init(elev=_ELEV, azim=_AZIM)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.tick_params(labelsize=7)
    q = ", ".join(f"{x:.4g}" for x in snap.qpos)
    head = title or f"{subject.name} / {subject.end_name}"
    words = (
        "S_i(q): space form, world coordinates"
        if form == "space"
        else "B_i(q): body form, end-frame coordinates"
    )
    fig.suptitle(f"{head} at q = [{q}]\nscrew axes {words}{error}", fontsize=10)
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.02, top=0.9)
    place_labels(fig, labels, points=[(ax, points)])
    return fig


def draw(
    model: str | os.PathLike[str] | Any,
    qpos: ArrayLike | None = None,
    *,
    path: str | os.PathLike[str] | None = None,
    frame: str | None = None,
    params: str | os.PathLike[str] | Chain | DHTable | None = None,
    aligned: bool = False,
    all_frames: bool = False,
    form: Form = "space",
    base: ArrayLike | None = None,
    tool: ArrayLike | None = None,
) -> Figure:
    """Draw a robot at ``qpos`` (default: its ``qpos0``) with its screw axes; save it to
    ``path`` if given (the suffix decides: :data:`poekin.io.fileio.FIGURE_FORMATS`).

    ``model``, ``params``, ``base`` and ``tool`` are what :func:`poekin.view` takes. An
    existing file at ``path`` is replaced.

    Raises:
        InputError: an unknown suffix or a path that cannot be written (both before any work:
            :func:`poekin.io.fileio.check_writable`), ``aligned`` without ``params``, ``qpos`` of
            the wrong length, ...
    """
    from poekin.viewer.geometry import _geom_tips
    from poekin.viewer.loading import load_params_comparison, load_shown

    if aligned and params is None:
        raise InputError(
            "aligned=True draws your parameters after aligning their base: give params too"
        )
    if path is not None:
        figure_format(path, "drawing")
        check_writable(path, "the drawing")
    shown = load_shown(model, frame, base=base, tool=tool)
    subject = shown.subject
    comparison = load_params_comparison(subject, params)
    tips = _geom_tips(shown.loaded.model, subject) if shown.loaded is not None else None
    fig = figure(
        subject,
        subject.qpos0 if qpos is None else qpos,
        comparison=comparison,
        aligned=aligned,
        all_frames=all_frames,
        form=form,
        tips=tips,
    )
    if path is not None:
        save_figure(fig, path, dpi=_DPI, what="drawing")
    return fig
