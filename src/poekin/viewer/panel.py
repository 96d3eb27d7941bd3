"""The viewer panel's texts, as Markdown: formatting of :mod:`poekin.viewer.scene` results only
(no viser), so they are tested without a browser.

Matrices are printed in fenced code blocks, one row a line, with a fixed number of decimals:
``T(q)`` with :data:`POSE_DIGITS`, the Jacobian with :data:`JACOBIAN_DIGITS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from poekin.dh import DHTable
from poekin.io.trajectory import Trajectory
from poekin.viewer.collision import CollisionScene, CollisionState
from poekin.viewer.ik import IKSupport, Reach
from poekin.viewer.scene import (
    Comparison,
    Form,
    Ghost,
    Snapshot,
    Subject,
    format_matrix,
    pose_summary,
    screw_kind,
)
from poekin.viewer.wholebody import WholeBodyReach

__all__ = [
    "COLLISION_ROWS",
    "JACOBIAN_DIGITS",
    "POSE_DIGITS",
    "collision_text",
    "compare_text",
    "dh_text",
    "ik_text",
    "jacobian_text",
    "poe_text",
    "pose_text",
    "q_text",
    "residual_words",
    "screws_text",
    "solution_label",
    "trajectory_text",
    "wholebody_text",
]

FloatArray = NDArray[np.float64]
Unit = Literal["rad", "deg"]
POSE_DIGITS = 6
JACOBIAN_DIGITS = 4
COLLISION_ROWS = 8  # the closest pairs listed (every one within the margin is drawn)
_SYMBOL = {"space": "S", "body": "B"}


def _numbers(values: Sequence[float] | FloatArray, digits: int) -> str:
    return ", ".join(f"{float(x) + 0.0:.{digits}f}" for x in values)


def _block(lines: Sequence[str]) -> str:
    return "```\n" + "\n".join(lines) + "\n```"


def q_text(subject: Subject, q: FloatArray, unit: Unit = "rad") -> str:
    """The chain's joint values, ``q1 .. qn``, hinges in ``unit``, slides in m."""
    parts = []
    for i, (kind, value) in enumerate(zip(subject.chain.joint_types, q, strict=True)):
        shown = math.degrees(value) if kind == "revolute" and unit == "deg" else float(value)
        parts.append(f"q{i + 1} = {shown + 0.0:.4f} {'m' if kind == 'prismatic' else unit}")
    return ", ".join(parts) if parts else "no joints"


def pose_text(T: FloatArray, frame: str, digits: int = POSE_DIGITS) -> str:
    """``T(q)`` as a 4x4 block, then its position, quaternion ``wxyz`` and roll-pitch-yaw."""
    s = pose_summary(T)
    rpy = s["rpy"]
    return "\n\n".join(
        [
            f"**T(q) = T_world_{frame}**",
            _block(format_matrix(T, digits)),
            f"position [m]: `{_numbers(s['position'], digits)}`",
            f"quaternion wxyz: `{_numbers(s['quat_wxyz'], digits)}`",
            f"roll, pitch, yaw [rad]: `{_numbers(rpy, digits)}` "
            f"(deg: `{_numbers([math.degrees(a) for a in rpy], 3)}`; "
            "R = Rz(yaw) Ry(pitch) Rx(roll))",
        ]
    )


_CONVENTION_WORDS = {
    "space": "J_s: the twist in the world frame, rows [w; v]",
    "body": "J_b: the twist in the end frame, rows [w; v]",
    "world": "rows [w; v_frame] in world coordinates: v_frame is the end frame origin's "
    "velocity (mj_jacSite)",
}


def jacobian_text(
    J: FloatArray,
    columns: Sequence[str],
    convention: str,
    sigma: FloatArray,
    manipulability: float,
    digits: int = JACOBIAN_DIGITS,
) -> str:
    """The Jacobian as a block, its columns, singular values, manipulability and condition."""
    cond = float(sigma[0] / sigma[-1]) if sigma.size and sigma[-1] > 0 else math.inf
    return "\n\n".join(
        [
            f"**Jacobian ({convention})**, {J.shape[0]} x {J.shape[1]}: "
            + _CONVENTION_WORDS[convention],
            _block(format_matrix(J, digits)),
            f"columns: {', '.join(columns)}",
            f"singular values: `{_numbers(sigma, digits)}`",
            f"manipulability (product of the singular values): `{manipulability:.{digits}g}`; "
            f"condition number: `{cond:.4g}`",
        ]
    )


def poe_text(subject: Subject, snap: Snapshot, k: int, form: Form, unit: Unit = "rad") -> str:
    """The partial product ``T_k`` in the chosen form, the values of its factors, and ``T_k``'s
    origin."""
    n = subject.n_joints
    symbol = _SYMBOL[form]
    factors = [f"e^[{symbol}{i + 1}]q{i + 1}" for i in range(k)]
    product = " · ".join([*factors, "M"] if form == "space" else ["M", *factors])
    rest = (
        f"joints {k + 1}..{n} held at 0"
        if k < n - 1
        else f"joint {n} held at 0"
        if k == n - 1
        else "all joints at q"
    )
    other = "M · e^[B1]q1 ..." if form == "space" else "e^[S1]q1 ... M"
    origin = snap.partial[k][:3, 3]
    base = "" if subject.base_body is None else "T_world_base · "
    return "\n\n".join(
        [
            f"**PoE step k = {k} of {n}**: T{k} = {base}{product}",
            f"({rest}; the same pose as {other}: "
            f"{'T(q)' if k == n else 'M' if k == 0 else 'a partial product'})",
            f"origin of T{k} [m]: `{_numbers(origin, 4)}`",
            q_text(subject, snap.q, unit),
        ]
    )


def screws_text(subject: Subject, snap: Snapshot, form: Form) -> str:
    """Each joint's screw at the current q, ``S_i(q)`` (world) or ``B_i(q)`` (end frame)."""
    symbol = _SYMBOL[form]
    screws = snap.screws if form == "space" else snap.body_screws
    where = (
        "world coordinates: S_i(q) = Ad(T_{i-1}) S_i, column i of J_s(q)"
        if form == "space"
        else "end-frame coordinates: B_i(q), column i of J_b(q); B_i = Ad(M^-1) S_i at q = 0"
    )
    if subject.base_body is not None and form == "space":
        where += " (T_{i-1} includes the floating base)"
    rows = [
        f"{symbol}(q) = [w; v] in {where}. One line in space per joint: the two forms differ "
        "in coordinates only.",
        "",
    ]
    rows += ["| | joint | w | v | kind |", "|---|---|---|---|---|"]
    for i, (name, S) in enumerate(zip(subject.chain.joint_names, screws, strict=True)):
        kind: str = screw_kind(S)
        if kind == "pitched":
            kind = f"pitch {float(S[:3] @ S[3:]):.4g} m/rad"
        rows.append(
            f"| {symbol}{i + 1} | {name} | {_numbers(S[:3], 3)} | {_numbers(S[3:], 3)} | {kind} |"
        )
    return "\n".join(rows)


def dh_text(table: DHTable) -> str:
    """The DH table as a Markdown table, with its convention and notes."""
    std = table.convention == "standard"
    head = (
        "standard (Denavit-Hartenberg): Rz(theta) Tz(d) Tx(a) Rx(alpha)"
        if std
        else "modified (Craig): Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta) Tz(d)"
    )
    a, al = ("a", "alpha") if std else ("a(i-1)", "alpha(i-1)")
    rows = [
        f"**{head}**",
        "",
        f"| i | joint | {a} [m] | {al} [rad] | d [m] | theta_off [rad] |",
        "|---|---|---|---|---|---|",
    ]
    for i, row in enumerate(table.rows()):
        values = [f"{row[k] + 0.0:.4f}" for k in ("a", "alpha", "d", "theta_offset")]
        rows.append(
            f"| {i + 1} | {row['joint']} ({row['joint_type'][0].upper()}) | "
            + " | ".join(values)
            + " |"
        )
    rows += ["", *(f"note: {n}" for n in table.notes)]
    return "\n".join(rows)


def compare_text(comparison: Comparison, ghost: Ghost, aligned: bool) -> str:
    """The live end-frame error, the verdict and :func:`poekin.diagnose`'s findings."""
    d = comparison.diagnosis
    verdict = "MATCH" if d.matches else "MISMATCH"
    placed = d.placement(aligned) + ("" if aligned else ", on the model's base frame")
    lines = [
        f"**{comparison.name}** vs **{d.model.robot or 'the model'}** / `{d.model.frame}`: "
        f"**{verdict}**",
        f"your arm ({placed}) at this q: end frame off by **{ghost.pos_err:.4g} m** and "
        f"**{ghost.ori_err:.4g} rad** ({math.degrees(ghost.ori_err):.3g} deg)",
        f"over {d.samples} random q: max {d.max_pos_err_m:.3g} m, {d.max_ori_err_rad:.3g} rad; "
        f"after aligning the base: {d.aligned_max_pos_err_m:.3g} m, "
        f"{d.aligned_max_ori_err_rad:.3g} rad",
    ]
    if d.findings:
        lines.append("**differences** (joints in red in the scene):")
        lines += [f"- {f.message}" for f in d.findings]
    if d.symptoms:
        lines.append("**what the errors point to:**")
        lines += [f"- {s}" for s in d.symptoms]
    return "\n\n".join(lines)


_HOW = {
    "current": "solved from the configuration shown",
    "restart": "solved after a restart: the configuration shown could not reach it",
    "analytic": "the closed-form solution nearest the configuration shown",
    "picked": "the closed-form solution picked",
    "follow": "the target is at the end frame: drag it, or type a pose below",
    "best fit": "out of reach: the arm shows its best fit from where it was",
}


def residual_words(pos_err: float, ori_err: float) -> str:
    """A residual in millimetres and milliradians, e.g. ``123.4 mm, 56.78 mrad``."""
    return f"{pos_err * 1e3:.4g} mm, {ori_err * 1e3:.4g} mrad"


def ik_text(
    reach: Reach, ik: IKSupport, *, position_only: bool, solve_s: float | None = None
) -> str:
    """The IK mode's status: reached or not, the residual, how the arm got there, and the
    closed-form solutions (or why there are none)."""
    head = "**target reached**" if reach.success else "**UNREACHABLE**: out of reach"
    residual = f"residual: `{residual_words(reach.pos_err, reach.ori_err)}`"
    if position_only:
        residual += " (position only: the orientation is free)"
    took = "" if solve_s is None else f" ({solve_s * 1e3:.2g} ms)"
    lines = [head, residual, _HOW[reach.how] + took]
    m = len(reach.solutions)
    if ik.analytic is not None:
        lines.append(f"all solutions: no closed form for this chain ({ik.analytic})")
    elif position_only:
        lines.append("all solutions: the closed form needs a whole pose (untick position only)")
    elif m == 0:
        lines.append("all solutions: none in closed form within the limits")
    else:
        others = "; the others are ghosts: pick one below, or click it" if m > 1 else ""
        lines.append(f"all solutions: **{m}** in closed form within the limits{others}")
    return "\n\n".join(lines)


def solution_label(index: int, q: FloatArray, kinds: Sequence[str], unit: Unit = "rad") -> str:
    """A closed-form solution in the picker: its number (as the ghost's label) and its joint
    values, hinges in ``unit`` (2 decimals in rad, 1 in deg)."""
    deg = unit == "deg"
    values = [
        f"{math.degrees(v):.1f}" if deg and k == "revolute" else f"{float(v) + 0.0:.2f}"
        for v, k in zip(q, kinds, strict=True)
    ]
    return f"{index + 1}: " + " ".join(values)


_WHOLEBODY_HOW = {
    "current": "solved from the configuration shown",
    "restart": "solved after a restart: the first attempt, from the configuration shown, missed",
    "follow": "the targets are at their frames: drag a handle",
    "best fit": "the robot shows the first attempt's best fit, from where it was",
}


def wholebody_text(shown: WholeBodyReach, *, solve_s: float | None = None, note: str = "") -> str:
    """The whole-body IK mode's status: the frames and which are held, reached or not, the
    worst frame's error, how the robot got there, and each frame's error."""
    handles = shown.handles
    held = ", ".join(f"`{f}`" for f in handles.hold) or "none"
    lines = [f"**{len(handles.frames)}** handles; held (met exactly): {held}"]
    if shown.success:
        lines.append("**every frame reached**")
    else:
        missed = [f for f in handles.frames if shown.missed(f)]
        held_ok = all(not shown.missed(f) for f in handles.hold)
        kept = "; the held frames met" if handles.hold and held_ok else ""
        lines.append(f"**NOT REACHED**: {', '.join(f'`{f}`' for f in missed)} missed{kept}")
    frame, pos, ori = shown.worst
    lines.append(f"worst: `{frame}` `{residual_words(pos, ori)}`")
    took = "" if solve_s is None else f" ({solve_s * 1e3:.3g} ms)"
    runs = (
        ""
        if not shown.attempts
        else (
            f"; {shown.attempts} attempt{'s' if shown.attempts > 1 else ''}, "
            f"{shown.iterations} iterations"
        )
    )
    lines.append(_WHOLEBODY_HOW[shown.how] + runs + took)
    if note:
        lines.append(note)
    rows = ["| frame | error |", "|---|---|"]
    for f in handles.frames:
        name = f"`{f}` (held)" if f in handles.hold else f"`{f}`"
        rows.append(f"| {name} | {residual_words(*shown.frame_errors[f])} |")
    lines.append("\n".join(rows))
    return "\n\n".join(lines)


def trajectory_text(trajectory: Trajectory, what: str) -> str:
    """The trajectory played: its samples and duration, the robot it was made for, what its
    columns were read as (``what``: ``"qpos"`` or ``"chain"``), and where its path stopped."""
    made = f" for `{trajectory.robot}`" if trajectory.robot else ""
    read = "the robot's qpos" if what == "qpos" else "the chain's joint values"
    lines = [
        f"**{len(trajectory.t)}** samples over **{trajectory.duration:.6g} s**{made}, "
        f"{trajectory.n} columns: {read}"
    ]
    if trajectory.stopped:
        lines.append(f"**{trajectory.stop_words()}** (the red marker)")
    return "\n\n".join(lines)


def _millimetres(d: float) -> str:
    """A distance (m) in mm: 0.1 mm, or two digits below 0.05 mm (a graze, not 0)."""
    mm = d * 1e3
    return f"{mm:.1f} mm" if abs(mm) >= 0.05 or mm == 0 else f"{mm:.1e} mm"


def collision_text(
    scene: CollisionScene, state: CollisionState, *, query_s: float | None = None
) -> str:
    """Collision at the configuration shown: how many pairs penetrate, then each pair closer
    than the margin (closest first) with its signed distance in mm, the penetrating ones
    marked, and the query's time."""
    n_pairs, n_obstacles = len(scene.pairs), len(scene.obstacles)
    what = f"{scene.n_robot} geoms" + (
        f", {n_obstacles} obstacle{'s' if n_obstacles != 1 else ''}" if n_obstacles else ""
    )
    n = state.n_colliding
    head = (
        f"**IN COLLISION**: {n} of {n_pairs} pairs {'penetrates' if n == 1 else 'penetrate'} (red)"
        if n
        else f"**collision-free**: none of {n_pairs} pairs penetrates"
    )
    margin = f"{state.margin * 1e3:.3g} mm"
    took = "" if query_s is None else f"; query {query_s * 1e3:.2g} ms"
    lines = [head, f"{what}; witness points of the pairs closer than {margin}{took}"]
    rows = [
        f"{a} / {b}: {_millimetres(d)}{'  COLLIDES' if d < 0 else ''}"
        for (a, b), d in zip(
            state.near_pairs[:COLLISION_ROWS],
            state.near_distance[:COLLISION_ROWS].tolist(),
            strict=True,
        )
    ]
    if len(state.near) > COLLISION_ROWS:
        rows.append(f"... and {len(state.near) - COLLISION_ROWS} more")
    lines.append(_block(rows) if rows else f"no pair closer than {margin}")
    return "\n\n".join(lines)
