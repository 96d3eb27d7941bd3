"""Explain why a hand-typed parameter set disagrees with a model: :func:`diagnose`.

The user's parameters (a PoE chain or a DH table) are compared with the model's chain:

1. The errors a user sees: ``T_model(q)`` against ``T_yours(q)`` on random ``q``, and at
   ``q = 0``.
2. The best base alignment ``B = T_modelbase_yourbase``, so that ``T_model ~ B T_yours``. It is
   found by consensus: the rotation and shift on which most joint axes agree, so that one wrong
   joint cannot drag the base with it. A shift along joint 1's axis is not a base shift but a
   different first link length (``d1``), and is reported as such.
3. Joint by joint, after alignment: joint type, axis flipped, axis tilted (angle), axis line
   offset (distance from the model's joint point to your axis line).
4. Link lengths and twists: both chains as DH tables (your table's convention if you gave one,
   else standard), row by row.
5. The home pose ``M``: translation and rotation deltas.
6. Bisection: starting from your aligned parameters, replace one part at a time by the model's,
   always the one that removes the most error, until the errors vanish. For a DH table the parts
   are its rows and the tool. For a PoE set they are the screws and ``M``, or the rows and tool
   of both chains' DH tables when that explains the difference in fewer steps (a wrong first
   link moves every later screw, but only one row).

Lengths are metres, angles radians; messages also give degrees.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.chain import Chain
from poekin.dh import (
    NEAR_PARALLEL_SIN,
    PARALLEL_SIN,
    Convention,
    DHTable,
    dh_from_chain,
    joint_lines,
)
from poekin.errors import InputError
from poekin.verification.verify import (
    check_sample_memory,
    pose_errors,
    sample_joint_values,
    whole_number,
)

if TYPE_CHECKING:
    from poekin.io.sources import LoadedModel
    from poekin.tree import Tree

__all__ = ["BisectStep", "Diagnosis", "Finding", "diagnose", "joint_differences"]

FloatArray = NDArray[np.float64]

DEFAULT_TOL = 1e-6  # m and rad: far above float rounding (~1e-14), far below typed-in mm
# Consensus thresholds for the base alignment: a joint "agrees" with a candidate base when its
# axis is within this angle / its axis line within this distance. Loose enough for values typed
# to four digits, tight enough that a wrong link (mm and up) or a flipped axis does not agree.
_AGREE_ANGLE = 0.02
_AGREE_DIST = 1e-4
_FLIP_ANGLE = 0.02  # an axis within this of the reversed direction counts as flipped
_BISECT_SAMPLES = 200
_SAME = 1e-12  # parts of two parameter sets that differ by less are the same part
_SMALL = 0.005  # differences below this (m, rad), a calibration's size, are printed in mm, mrad


@dataclasses.dataclass(frozen=True)
class Finding:
    """One difference between your parameters and the model's.

    ``kind`` is one of ``base_rotation``, ``base_shift``, ``joint_type``, ``axis_flipped``,
    ``axis_tilted``, ``axis_offset``, ``link_length``, ``link_twist``, ``near_parallel``,
    ``home_position``, ``home_rotation``. ``joint`` is a 0-based joint index (None for base and
    M; for ``near_parallel``, the first of two joints whose axes are nearly parallel, so that
    their DH lengths are not compared); ``value`` the size of the difference (m or rad);
    ``message`` says it in plain words.
    """

    kind: str
    message: str
    joint: int | None = None
    value: float = 0.0


@dataclasses.dataclass(frozen=True)
class BisectStep:
    """After replacing ``part`` by the model's: the errors left. ``part`` is ``"M"`` or a joint
    (PoE), or ``"tool"`` or a row with the parameters it changes (DH)."""

    part: str
    joint: int | None
    max_pos_err_m: float
    max_ori_err_rad: float


@dataclasses.dataclass(frozen=True, eq=False)
class Diagnosis:
    """The outcome of :func:`diagnose`. ``matches`` is True when your FK agrees with the
    model's within the tolerances on every sample (no alignment allowed)."""

    yours: Chain
    model: Chain
    aligned: Chain
    base: FloatArray
    findings: tuple[Finding, ...]
    symptoms: tuple[str, ...]
    bisect: tuple[BisectStep, ...]
    convention: Convention
    samples: int
    seed: int
    pos_tol: float
    ori_tol: float
    max_pos_err_m: float
    max_ori_err_rad: float
    home_pos_err_m: float
    home_ori_err_rad: float
    aligned_max_pos_err_m: float
    aligned_max_ori_err_rad: float

    @property
    def matches(self) -> bool:
        return self.max_pos_err_m <= self.pos_tol and self.max_ori_err_rad <= self.ori_tol

    def joint_labels(self) -> dict[int, str]:
        """Short labels of the joints with findings, for a figure: ``{index: "flipped"}``."""
        labels: dict[int, list[str]] = {}
        short = {
            "joint_type": "type",
            "axis_flipped": "flipped",
            "axis_tilted": "tilted",
            "axis_offset": "offset",
        }
        for f in self.findings:
            if f.joint is not None and f.kind in short:
                text = short[f.kind]
                if f.kind in ("axis_tilted", "axis_offset"):
                    text += f" {f.value:.3g}" + (" m" if f.kind == "axis_offset" else " rad")
                labels.setdefault(f.joint, []).append(text)
        return {j: ", ".join(t) for j, t in labels.items()}

    @property
    def base_aligned(self) -> bool:
        """Whether a base alignment other than the identity reduced the errors (else your base
        is compared as it is)."""
        return not np.array_equal(self.base, np.eye(4))

    def placement(self, aligned: bool) -> str:
        """Where your parameters are drawn, in words, for a figure that draws them ``aligned``
        or not: after the base alignment only where it reduced the errors
        (:attr:`base_aligned`), as :meth:`report` says."""
        if not aligned:
            return "as given"
        if self.base_aligned:
            return "after aligning your base to the model's"
        return "as given: aligning your base does not reduce the error"

    @property
    def unattributed(self) -> tuple[float, float] | None:
        """The errors (m, rad) that the bisection left above the tolerances once every part that
        differs was replaced, or None if it reached them."""
        if self.matches or not self.bisect:
            return None
        last = self.bisect[-1]
        if last.max_pos_err_m <= self.pos_tol and last.max_ori_err_rad <= self.ori_tol:
            return None
        return last.max_pos_err_m, last.max_ori_err_rad

    def report(self) -> list[str]:
        """The findings as ``poekin diagnose`` prints them, one line each."""
        errs = f"max error {_sig(self.max_pos_err_m)} m, {_sig(self.max_ori_err_rad)} rad"
        if self.matches:
            return [f"MATCH: {errs}, within {self.pos_tol:g} m, {self.ori_tol:g} rad"]
        if self.base_aligned:
            after = (
                f"after aligning the base: {_sig(self.aligned_max_pos_err_m)} m, "
                f"{_sig(self.aligned_max_ori_err_rad)} rad"
            )
        else:
            after = "aligning the base does not reduce it, so your base is compared as it is"
        lines = [
            f"MISMATCH: {errs} (at q = 0: {_sig(self.home_pos_err_m)} m, "
            f"{_sig(self.home_ori_err_rad)} rad); {after}",
            f"differences (above {self.pos_tol:g} m, {self.ori_tol:g} rad):",
            *(f"  - {f.message}" for f in self.findings),
        ]
        if self.symptoms:
            lines += ["what the errors point to:", *(f"  - {t}" for t in self.symptoms)]
        if self.bisect:
            width = max(len(step.part) for step in self.bisect)
            lines.append(
                "bisection: replace one part at a time by the model's (largest gain first):"
            )
            lines += [
                f"  {k}. {step.part:{width}}  -> max error {_sig(step.max_pos_err_m)} m, "
                f"{_sig(step.max_ori_err_rad)} rad"
                for k, step in enumerate(self.bisect, 1)
            ]
        if self.unattributed is not None:
            p, r = self.unattributed
            lines.append(
                f"  what is left ({_sig(p)} m, {_sig(r)} rad) is not attributed to any one part: "
                "the parts differ by less than 1e-12 each"
            )
        return lines

    def summary(self) -> dict[str, Any]:
        """The JSON object printed by ``poekin diagnose --json``."""
        return {
            "yours": self.yours.robot,
            "model": self.model.robot,
            "frame": self.model.frame,
            "matches": self.matches,
            "samples": self.samples,
            "seed": self.seed,
            "pos_tol": self.pos_tol,
            "ori_tol": self.ori_tol,
            "max_pos_err_m": self.max_pos_err_m,
            "max_ori_err_rad": self.max_ori_err_rad,
            "home_pos_err_m": self.home_pos_err_m,
            "home_ori_err_rad": self.home_ori_err_rad,
            "aligned_max_pos_err_m": self.aligned_max_pos_err_m,
            "aligned_max_ori_err_rad": self.aligned_max_ori_err_rad,
            "base": self.base.tolist(),
            "findings": [dataclasses.asdict(f) for f in self.findings],
            "symptoms": list(self.symptoms),
            "bisect": [dataclasses.asdict(s) for s in self.bisect],
            "unattributed": self.unattributed,
            "base_aligned": self.base_aligned,
            "convention": self.convention,
        }


def _is_param_set(spec: str | os.PathLike[str]) -> bool:
    """Whether ``spec`` names a parameter set (a named set, or a .json/.yaml/.yml file), not a
    model (a Menagerie name, an MJCF or URDF file)."""
    from poekin.io.paramfile import FILE_SUFFIXES
    from poekin.io.params import PARAM_SETS

    text = os.fspath(spec)
    return text in PARAM_SETS or os.path.splitext(text)[1].lower() in FILE_SUFFIXES


def _yours(yours: object) -> Chain | DHTable:
    if isinstance(yours, Chain | DHTable):
        return yours
    if isinstance(yours, str | os.PathLike):
        from poekin.io.paramfile import load_params

        return load_params(yours)
    raise InputError(
        f"your parameters must be a Chain, a DHTable, or the name or file of a parameter set, "
        f"not a {type(yours).__name__}"
    )


def _model_chain(model: object, frame: str | None) -> Chain:
    if isinstance(model, Chain):
        return model
    if isinstance(model, str | os.PathLike) and _is_param_set(model):
        from poekin.io.paramfile import load_params

        if frame is not None:
            raise InputError(
                f"frame={frame!r} picks a model's end frame; the parameter set "
                f"{os.fspath(model)!r} has one end frame: leave frame out"
            )
        params = load_params(model)
        return params.to_chain() if isinstance(params, DHTable) else params
    from poekin.io.loading import default_frame, load
    from poekin.io.sources import LoadedModel
    from poekin.tree import Tree

    if isinstance(model, Tree):
        return model.chain(frame if frame is not None else default_frame(model))
    if isinstance(model, str | os.PathLike | LoadedModel):
        return load(model, frame)
    raise InputError(
        f"the model must be a Chain, a Tree, a Menagerie robot name or a model path, not a "
        f"{type(model).__name__}"
    )


# --- geometry helpers ---------------------------------------------------------------------------


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v), dtype=np.float64)


def _angle(u: FloatArray, v: FloatArray) -> float:
    """Angle between unit vectors, accurate near 0 and pi."""
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), u @ v))


def _sig(x: float) -> str:
    return f"{x:.3g}"


def _deg(x: float) -> str:
    """An angle in degrees: one decimal, or two significant digits below 0.1 deg."""
    deg = float(np.degrees(x))
    return f"{deg:.2g} deg" if abs(deg) < 0.1 else f"{deg:.1f} deg"


def _both(yours: float, model: float, digits: int) -> tuple[str, str]:
    """``yours`` and ``model`` with ``digits`` significant digits, or as many more as it takes
    for two different numbers to print differently (``1.5708`` vs ``1.5707963``)."""
    yours, model = (0.0 if abs(x) < _SAME else x + 0.0 for x in (yours, model))
    for k in range(digits, 18):
        a, b = f"{yours:.{k}g}", f"{model:.{k}g}"
        if a != b or yours == model:
            return a, b
    return a, b


def _radians(x: float) -> str:
    """An angle in rad, or below 5 mrad in mrad."""
    return f"{x * 1000:.3g} mrad" if x < _SMALL else f"{x:.4g} rad"


def _angle_text(x: float) -> str:
    """An angle in rad (or mrad), then in degrees."""
    return f"{_radians(x)} ({_deg(x)})"


def _length_text(x: float) -> str:
    """A length in m, or below 5 mm in mm."""
    return f"{x * 1000:.3g} mm" if x < _SMALL else f"{x:.4g} m"


def _vec(v: FloatArray, digits: int = 4) -> str:
    return "[" + ", ".join(f"{round(float(x), digits) + 0.0:+.{digits}f}" for x in v) + "]"


def _axis_angle(R: FloatArray) -> tuple[FloatArray, float]:
    w = np.asarray(lie.log_so3(R), dtype=np.float64)
    theta = float(np.linalg.norm(w))
    return (w / theta if theta > 0 else np.array([0.0, 0.0, 1.0])), theta


def _moved(chain: Chain, B: FloatArray, *, robot: str | None = None) -> Chain:
    """``chain`` with its base frame placed at ``B`` in another frame."""
    screws = (np.asarray(lie.adjoint(B)) @ chain.screws.T).T
    return dataclasses.replace(
        chain,
        screws=screws,
        home=B @ chain.home,
        robot=chain.robot if robot is None else robot,
        qpos_indices=None,
    )


def _triad(u1: FloatArray, u2: FloatArray, k1: FloatArray, k2: FloatArray) -> FloatArray:
    """The rotation taking ``u1`` onto ``k1`` and the plane of ``(u1, u2)`` onto ``(k1, k2)``."""

    def frame(a: FloatArray, b: FloatArray) -> FloatArray:
        y = _unit(np.cross(a, b))
        return np.column_stack([a, y, np.cross(a, y)])

    return np.asarray(frame(k1, k2) @ frame(u1, u2).T, dtype=np.float64)


def _align_rotation(yours: Chain, model: Chain, du: FloatArray, dk: FloatArray) -> FloatArray:
    """The base rotation on which most joint axes (directions ``du``, ``dk``), then the M axes,
    agree."""
    U = np.vstack([du, yours.home[:3, :3].T])
    K = np.vstack([dk, model.home[:3, :3].T])
    n = yours.n_joints
    candidates = [np.eye(3)]
    for i, j in itertools.combinations(range(len(U)), 2):
        su, sk = np.linalg.norm(np.cross(U[i], U[j])), np.linalg.norm(np.cross(K[i], K[j]))
        if su > 0.1 and sk > 0.1 and abs(_angle(U[i], U[j]) - _angle(K[i], K[j])) < _AGREE_ANGLE:
            candidates.append(_triad(U[i], U[j], K[i], K[j]))

    def score(R: FloatArray) -> tuple[int, int, float, float]:
        ang = np.array([_angle(R @ u, k) for u, k in zip(U, K, strict=True)])
        agree = ang < _AGREE_ANGLE
        spread = float(np.sum(ang[agree] ** 2))
        turn = float(lie.rotation_angle(R))
        return int(agree[:n].sum()), int(agree[n:].sum()), -spread, -turn

    return max(candidates, key=score)


def _align_shift(
    yours: Chain,
    model: Chain,
    R: FloatArray,
    lines_y: tuple[FloatArray, FloatArray],
    lines_m: tuple[FloatArray, FloatArray],
) -> FloatArray:
    """The base shift, normal to the model's joint-1 axis, on which most axis lines agree."""
    (du, pu), (dk, pk) = lines_y, lines_m
    rows = [
        i
        for i in range(model.n_joints)
        if yours.joint_types[i] == model.joint_types[i] == "revolute"
        and _angle(R @ du[i], dk[i]) < _AGREE_ANGLE
    ]
    if not rows or model.n_joints == 0:
        return np.zeros(3)
    e = dk[0]
    E = np.linalg.svd(np.eye(3) - np.outer(e, e))[0][:, :2]  # basis of the plane normal to e
    P = {i: np.eye(3) - np.outer(dk[i], dk[i]) for i in rows}
    rhs = {i: P[i] @ (pk[i] - R @ pu[i]) for i in rows}

    def solve(subset: tuple[int, ...]) -> FloatArray:
        A = np.vstack([P[i] @ E for i in subset])
        b = np.concatenate([rhs[i] for i in subset])
        return np.asarray(E @ np.linalg.lstsq(A, b, rcond=None)[0], dtype=np.float64)

    def residuals(t: FloatArray) -> FloatArray:
        return np.array([np.linalg.norm(P[i] @ t - rhs[i]) for i in rows])

    candidates = [np.zeros(3)]
    for size in (1, 2):
        candidates += [solve(s) for s in itertools.combinations(rows, size)]

    def score(t: FloatArray) -> tuple[int, float]:
        return int(np.sum(residuals(t) < _AGREE_DIST)), -float(np.linalg.norm(t))

    best = max(candidates, key=score)
    agree = tuple(i for i, r in zip(rows, residuals(best), strict=True) if r < _AGREE_DIST)
    return solve(agree) if agree else best


def align_base(yours: Chain, model: Chain) -> FloatArray:
    """``B = T_modelbase_yourbase`` (4, 4) that best aligns your joint axes with the model's.

    Consensus over joints: a few wrong joints do not move it. It has no shift along the model's
    joint-1 axis (that shows up as a different ``d1`` instead).
    """
    lines_y, lines_m = joint_lines(yours), joint_lines(model)
    R = _align_rotation(yours, model, lines_y[0], lines_m[0])
    shift = _align_shift(yours, model, R, lines_y, lines_m)
    return np.asarray(lie.homogeneous(R, shift), dtype=np.float64)


# --- findings -----------------------------------------------------------------------------------


def _base_findings(B: FloatArray, tol_p: float, tol_r: float) -> list[Finding]:
    out = []
    axis, turn = _axis_angle(B[:3, :3])
    if turn > tol_r:
        out.append(
            Finding(
                "base_rotation",
                f"base frame: yours is turned {_deg(turn)} ({turn:.4g} rad) about "
                f"{_vec(axis, 3)} relative to the model's",
                value=turn,
            )
        )
    shift = float(np.linalg.norm(B[:3, 3]))
    if shift > tol_p:
        out.append(
            Finding(
                "base_shift",
                f"base frame: yours is shifted by {shift:.4g} m, {_vec(B[:3, 3])} in the "
                "model's base frame",
                value=shift,
            )
        )
    return out


def joint_differences(yours: Chain, model: Chain) -> tuple[FloatArray, FloatArray]:
    """Per joint, ``(n,)`` each: the angle between your axis and the model's (rad, in
    ``[0, pi]``), and the distance from the model's joint point to your axis line (m; 0 for a
    prismatic joint, whose line has no place), both chains in the same base frame."""
    du, pu = joint_lines(yours)
    dk, pk = joint_lines(model)
    tilt, offset = np.zeros(model.n_joints), np.zeros(model.n_joints)
    for i in range(model.n_joints):
        tilt[i] = _angle(du[i], dk[i])
        if model.joint_types[i] == "revolute":
            r = pk[i] - pu[i]
            offset[i] = float(np.linalg.norm(r - du[i] * (r @ du[i])))
    return tilt, offset


def _joint_findings(
    aligned: Chain, model: Chain, tol_p: float, tol_r: float
) -> tuple[list[Finding], set[int]]:
    out: list[Finding] = []
    flipped: set[int] = set()
    du, _ = joint_lines(aligned)
    dk, _ = joint_lines(model)
    angles, offsets = joint_differences(aligned, model)
    for i, name in enumerate(model.joint_names):
        label = f"joint {i + 1} ({name})"
        if aligned.joint_types[i] != model.joint_types[i]:
            out.append(
                Finding(
                    "joint_type",
                    f"{label}: {aligned.joint_types[i]} in yours, {model.joint_types[i]} "
                    "in the model",
                    joint=i,
                    value=1.0,
                )
            )
            continue
        angle = float(angles[i])
        if angle > np.pi - _FLIP_ANGLE:
            flipped.add(i)
            out.append(
                Finding(
                    "axis_flipped",
                    f"{label}: axis flipped (yours points the opposite way, "
                    f"{_vec(du[i], 3)} vs {_vec(dk[i], 3)}): positive q turns it backwards",
                    joint=i,
                    value=angle,
                )
            )
            angle = np.pi - angle
        if angle > tol_r:
            out.append(
                Finding(
                    "axis_tilted",
                    f"{label}: axis tilted by {_angle_text(angle)}, "
                    f"{_vec(du[i], 3)} vs {_vec(dk[i], 3)}",
                    joint=i,
                    value=angle,
                )
            )
        if model.joint_types[i] == "revolute":
            offset = float(offsets[i])
            if offset > tol_p:
                out.append(
                    Finding(
                        "axis_offset",
                        f"{label}: axis line offset by {_length_text(offset)} (distance from the "
                        "model's joint point to your axis line)",
                        joint=i,
                        value=offset,
                    )
                )
    return out, flipped


def _near_parallel(aligned: Chain, model: Chain) -> list[tuple[int, float, float]]:
    """``(i, tilt in yours, tilt in the model)`` (rad) for each pair of joints ``i, i + 1``
    whose axes are nearly, but not exactly, parallel in either chain (a calibrated arm's)."""
    du, dk = joint_lines(aligned)[0], joint_lines(model)[0]
    out = []
    for i in range(model.n_joints - 1):
        tilts = [float(np.linalg.norm(np.cross(d[i], d[i + 1]))) for d in (du, dk)]
        if any(PARALLEL_SIN <= t < NEAR_PARALLEL_SIN for t in tilts):
            out.append((i, tilts[0], tilts[1]))
    return out


def _from_parallel(tilt: float) -> str:
    if tilt < PARALLEL_SIN:
        return "parallel"
    return f"{_radians(tilt)} from parallel"


def _near_parallel_findings(
    near: list[tuple[int, float, float]], t_y: DHTable, model: Chain, convention: Convention
) -> tuple[list[Finding], set[tuple[str, int]]]:
    """A finding per nearly parallel pair, and the ``("a" | "d", row)`` entries not compared."""
    shift = 1 if convention == "modified" else 0
    names = t_y.param_names()
    out, skip = [], set()
    for i, tilt_y, tilt_m in near:
        entries = [("a", i + shift), ("d", i), ("d", i + 1)]
        skip.update(entries)
        skipped = [names[row][0 if key == "a" else 2] for key, row in entries]
        far = ", ".join(f"{names[row][2]} = {t_y.d[row]:.4g} m" for _, row in entries[1:])
        joints = model.joint_names
        out.append(
            Finding(
                "near_parallel",
                f"joints {i + 1} and {i + 2} ({joints[i]}, {joints[i + 1]}): axes "
                f"{_from_parallel(tilt_y)} in yours, {_from_parallel(tilt_m)} in the model. DH "
                f"puts the common normal of nearly parallel axes far away (yours: {far}), so "
                f"{', '.join(skipped)} are not compared: the axis tilts and offsets say what "
                "differs",
                joint=i,
                value=abs(tilt_y - tilt_m),
            )
        )
    return out, skip


def _length_findings(
    aligned: Chain,
    model: Chain,
    yours_table: DHTable | None,
    convention: Convention,
    flipped: set[int],
    near: list[tuple[int, float, float]],
    tol_p: float,
    tol_r: float,
) -> list[Finding]:
    """Row-by-row DH comparison; the model's table is extracted with the same choices as yours.
    The a and d of nearly parallel axes (``near``) are left out, with a finding that says so."""
    if aligned.joint_types != model.joint_types:
        return []
    t_y = dh_from_chain(aligned, convention)
    t_m = dh_from_chain(model, convention)
    literal = (
        yours_table if yours_table is not None and yours_table.convention == convention else None
    )
    out, skip = _near_parallel_findings(near, t_y, model, convention)
    shift = 1 if convention == "modified" else 0
    lengths, twists = [], []
    for i, (a_name, al_name, d_name, _) in enumerate(t_m.param_names()):
        # a is a distance between axis lines; d is measured along joint i's axis, whose sign
        # flips with a flipped axis (reported already). alpha is meaningless next to a flip.
        near_flip = bool(flipped & ({i - 1, i} if shift else {i, i + 1}))  # alpha's two axes
        if ("a", i) not in skip and abs(t_y.a[i] - t_m.a[i]) > tol_p:
            sign = 1.0
            if (
                literal is not None
                and abs(abs(literal.a[i]) - t_y.a[i]) < 1e-9
                and literal.a[i] < 0
            ):
                sign = -1.0
            lengths.append((a_name, sign * t_y.a[i], sign * t_m.a[i], i))
        if i not in flipped and ("d", i) not in skip and abs(t_y.d[i] - t_m.d[i]) > tol_p:
            lengths.append((d_name, t_y.d[i], t_m.d[i], i))
        dal = abs(np.angle(np.exp(1j * (t_y.alpha[i] - t_m.alpha[i]))))
        if not near_flip and dal > tol_r and abs(dal - np.pi) > _FLIP_ANGLE:
            twists.append((al_name, t_y.alpha[i], t_m.alpha[i], i))
    for name, y, m, i in lengths:
        ys, ms = _both(y, m, 6)
        out.append(
            Finding(
                "link_length",
                f"{name}: {ys} m in yours vs {ms} m in the model ({(y - m) * 1000:+.4g} mm)",
                joint=i,
                value=abs(y - m),
            )
        )
    for name, y, m, i in twists:
        ys, ms = _both(y, m, 6)
        yd, md = _both(float(np.degrees(y)), float(np.degrees(m)), 4)
        out.append(
            Finding(
                "link_twist",
                f"{name}: {ys} rad ({yd} deg) in yours vs {ms} rad ({md} deg) in the model "
                f"({y - m:+.3g} rad)",
                joint=i,
                value=abs(y - m),
            )
        )
    return out


def _home_findings(aligned: Chain, model: Chain, tol_p: float, tol_r: float) -> list[Finding]:
    out = []
    dp = aligned.home[:3, 3] - model.home[:3, 3]
    off = float(np.linalg.norm(dp))
    if off > tol_p:
        delta = f"{_vec(dp * 1000, 3)} mm" if off < _SMALL else _vec(dp)
        out.append(
            Finding(
                "home_position",
                f"home pose M: its origin is off by {_length_text(off)}, yours - model's = "
                f"{delta} in the model's base frame",
                value=off,
            )
        )
    axis, turn = _axis_angle(model.home[:3, :3].T @ aligned.home[:3, :3])
    if turn > tol_r:
        out.append(
            Finding(
                "home_rotation",
                f"home pose M: yours is turned {_angle_text(turn)} about "
                f"{_vec(axis, 3)} (in the end frame) from the model's",
                value=turn,
            )
        )
    return out


# --- errors, bisection, symptoms ----------------------------------------------------------------


def _max_errors(T_ref: FloatArray, T: FloatArray) -> tuple[float, float]:
    """Worst position (m) and orientation (rad) error of poses ``T`` against ``T_ref``."""
    pos, ori = pose_errors(T_ref, T)
    return float(np.max(pos, initial=0.0)), float(np.max(ori, initial=0.0))


# Bisection parts beside the joints (0 .. n-1): the end (M or the DH tool) and the DH base.
_END, _BASE = -1, -2


def _greedy(
    build: Callable[[frozenset[int]], Callable[[FloatArray], FloatArray]],
    label: Callable[[int], str],
    parts: list[int],
    model: Chain,
    q: FloatArray,
    tol_p: float,
    tol_r: float,
) -> list[BisectStep]:
    """Replace ``parts`` (joints ``0..n-1``, :data:`_END`, :data:`_BASE`: only those that
    differ) one at a time, always the one that leaves the least error, until the errors are
    within tolerance or every part is replaced.

    ``build(done)`` gives the FK with the parts in ``done`` taken from the model.
    """
    T_ref = model.fk(q)
    reach = _reach(model)

    def errors(done: frozenset[int]) -> tuple[float, float]:
        return _max_errors(T_ref, build(done)(q))

    done: frozenset[int] = frozenset()
    err = errors(done)
    steps: list[BisectStep] = []
    while len(done) < len(parts) and not (err[0] <= tol_p and err[1] <= tol_r):
        trials = [(errors(done | {p}), p) for p in parts if p not in done]
        err, part = min(trials, key=lambda t: (t[0][0] + reach * t[0][1], t[1]))
        done |= {part}
        steps.append(BisectStep(label(part), None if part < 0 else part, err[0], err[1]))
    return steps


def _differ(a: FloatArray | float, b: FloatArray | float) -> bool:
    """Whether two parts differ by more than rounding (1e-12 in any entry)."""
    return bool(np.max(np.abs(np.asarray(a) - np.asarray(b)), initial=0.0) > _SAME)


def _reach(model: Chain) -> float:
    """A length that turns an angle error into a comparable position error (m per rad)."""
    return max(float(np.linalg.norm(model.home[:3, 3])), 0.1)


def _bisect_screws(
    aligned: Chain, model: Chain, q: FloatArray, tol_p: float, tol_r: float
) -> list[BisectStep]:
    """Bisection for a PoE set: replace one joint's screw (or M) at a time by the model's."""

    def build(done: frozenset[int]) -> Callable[[FloatArray], FloatArray]:
        pick = [i in done for i in range(model.n_joints)]
        return dataclasses.replace(
            aligned,
            screws=np.where(np.array(pick)[:, None], model.screws, aligned.screws),
            joint_types=tuple(
                m if p else y
                for p, m, y in zip(pick, model.joint_types, aligned.joint_types, strict=True)
            ),
            home=model.home if _END in done else aligned.home,
        ).fk

    def label(part: int) -> str:
        return "M" if part == _END else f"joint {part + 1} ({model.joint_names[part]})"

    parts = [
        i
        for i in range(model.n_joints)
        if aligned.joint_types[i] != model.joint_types[i]
        or _differ(aligned.screws[i], model.screws[i])
    ]
    parts += [_END] if _differ(aligned.home, model.home) else []
    return _greedy(build, label, parts, model, q, tol_p, tol_r)


def _bisect_rows(
    aligned: Chain,
    model: Chain,
    convention: Convention,
    q: FloatArray,
    tol_p: float,
    tol_r: float,
) -> list[BisectStep]:
    """Bisection for a DH table: replace one row (or the tool, or the base) at a time by the
    model's.

    Both tables are extracted from the chains with the same choices, so rows correspond.
    """
    t_y, t_m = dh_from_chain(aligned, convention), dh_from_chain(model, convention)
    fields = ("a", "alpha", "d", "theta_offset")

    def build(done: frozenset[int]) -> Callable[[FloatArray], FloatArray]:
        pick = np.array([i in done for i in range(model.n_joints)], dtype=bool)
        rows = {f: np.where(pick, getattr(t_m, f), getattr(t_y, f)) for f in fields}
        return dataclasses.replace(
            t_y,
            **rows,
            tool=t_m.tool if _END in done else t_y.tool,
            base=t_m.base if _BASE in done else t_y.base,
        ).fk

    def changed(part: int) -> list[str]:
        names = t_m.param_names()[part]
        return [
            n
            for n, f in zip(names, fields, strict=True)
            if _differ(getattr(t_y, f)[part], getattr(t_m, f)[part])
        ]

    def label(part: int) -> str:
        if part == _END:
            return "tool"
        if part == _BASE:
            return "base"
        return f"row {part + 1} ({', '.join(changed(part))})"

    parts = [i for i in range(model.n_joints) if changed(i)]
    parts += [_END] if _differ(t_y.tool, t_m.tool) else []
    parts += [_BASE] if _differ(t_y.base, t_m.base) else []
    return _greedy(build, label, parts, model, q, tol_p, tol_r)


def _symptoms(
    max_p: float,
    max_r: float,
    home_p: float,
    home_r: float,
    aligned: tuple[float, float],
    tol_p: float,
    tol_r: float,
) -> list[str]:
    if max_p <= tol_p and max_r <= tol_r:
        return []
    out = []
    if aligned[0] < 0.5 * max_p or aligned[1] < 0.5 * max_r:
        out.append(
            f"aligning the base alone brings the errors from {max_p:.3g} m, {max_r:.3g} rad down "
            f"to {aligned[0]:.3g} m, {aligned[1]:.3g} rad: the base frame is the biggest cause"
        )
    if max_r > 2.5:
        out.append(
            f"orientation errors near pi rad (here {max_r:.3g} rad) point to a flipped joint "
            "axis, or a base or tool frame turned by 180 deg"
        )
    if 0.1 <= max_p <= 2.0:
        out.append(
            f"position errors of tenths of a metre and more (here {max_p:.3g} m) are the size "
            "of a link: they point to a wrong M, a wrong sign of a link length, or a turned base"
        )
    elif max_p < 0.02 and max_p > tol_p:
        out.append(
            f"position errors of millimetres (here {max_p:.3g} m) point to link lengths that "
            "differ slightly, e.g. rounded published values against CAD values"
        )
    if home_p > tol_p or home_r > tol_r:
        out.append(
            f"the pose is already wrong at q = 0 ({home_p:.3g} m, {home_r:.3g} rad): M or the "
            "base frame differs, not only the joint axes"
        )
    else:
        out.append(
            "the pose is right at q = 0 but wrong elsewhere: M is right, the joint axes are not"
        )
    return out


def diagnose(
    yours: Chain | DHTable | str | os.PathLike[str],
    model: Chain | Tree | LoadedModel | str | os.PathLike[str] = "universal_robots_ur5e",
    *,
    frame: str | None = None,
    samples: int = 1000,
    seed: int = 0,
    pos_tol: float = DEFAULT_TOL,
    ori_tol: float = DEFAULT_TOL,
) -> Diagnosis:
    """Compare your parameters with the model's and say what differs, joint by joint.

    Args:
        yours: your PoE chain or DH table, for the same joints in the same order, or the name
            or file of one (:func:`poekin.load_params`).
        model: the model's chain (e.g. :func:`poekin.load`), or what :func:`poekin.load` takes
            (a Menagerie robot name, an MJCF or URDF path), or a tree; or another parameter set
            (a name or file :func:`poekin.load_params` reads), e.g. ``"ur5e-dh"``, UR's nominal
            UR5e, to see how a UR calibration file differs from the nominal arm.
        frame: the end frame when ``model`` is a model or a tree (default: the model's only
            site).
        samples, seed: random configurations for the error figures (revolute joints in
            ``[-2 pi, 2 pi]``, prismatic ones within their limits).
        pos_tol, ori_tol: differences below these (m, rad) are not reported.

    Example:
        >>> d = poekin.diagnose("ur5e-dh", "universal_robots_ur5e")
        >>> print("\n".join(d.report()))
    """
    yours = _yours(yours)
    model = _model_chain(model, frame)
    table = yours if isinstance(yours, DHTable) else None
    chain = yours.to_chain() if isinstance(yours, DHTable) else yours
    if chain.n_joints != model.n_joints:
        raise InputError(
            f"your parameters have {chain.n_joints} joints but the model's chain to "
            f"{model.frame!r} has {model.n_joints} ({', '.join(model.joint_names)}); "
            "give one row or screw per joint, base to tip"
        )
    whole_number(samples, "samples", 1)
    check_sample_memory(samples, model.n_joints + 2 * 16)  # q, the model's and your poses
    convention: Convention = table.convention if table is not None else "standard"
    q = sample_joint_values(model, samples, seed=seed)
    T_ref = model.fk(q)
    max_p, max_r = _max_errors(T_ref, chain.fk(q))
    home_p, home_r = _max_errors(model.home, chain.home)
    B = align_base(chain, model)
    aligned = _moved(chain, B)
    al_p, al_r = _max_errors(T_ref, aligned.fk(q))
    reach = _reach(model)
    gain = (max_p + reach * max_r) - (al_p + reach * al_r)
    if gain <= pos_tol + reach * ori_tol:  # no help beyond the tolerances: your base as it is
        B = np.eye(4)
        aligned = _moved(chain, B)
        al_p, al_r = max_p, max_r
    joints, flipped = _joint_findings(aligned, model, pos_tol, ori_tol)
    near = _near_parallel(aligned, model)
    findings = [
        *_base_findings(B, pos_tol, ori_tol),
        *joints,
        *_length_findings(aligned, model, table, convention, flipped, near, pos_tol, ori_tol),
        *_home_findings(aligned, model, pos_tol, ori_tol),
    ]
    q_few = q[:_BISECT_SAMPLES]
    # DH rows are parts to replace only where they are lengths of the arm (no nearly parallel
    # axes, whose rows are the ill-conditioned far-away normals)
    by_rows = chain.joint_types == model.joint_types and not near
    rows = _bisect_rows(aligned, model, convention, q_few, pos_tol, ori_tol) if by_rows else []
    if table is not None and rows:
        steps = rows  # a DH user typed rows: replace rows
    else:  # a PoE user typed screws; a link-by-link account wins when it is shorter
        screws = _bisect_screws(aligned, model, q_few, pos_tol, ori_tol)
        steps = rows if rows and len(rows) < len(screws) else screws
    return Diagnosis(
        yours=chain,
        model=model,
        aligned=aligned,
        base=B,
        findings=tuple(findings),
        symptoms=tuple(_symptoms(max_p, max_r, home_p, home_r, (al_p, al_r), pos_tol, ori_tol)),
        bisect=tuple(steps),
        convention=convention,
        samples=samples,
        seed=seed,
        pos_tol=pos_tol,
        ori_tol=ori_tol,
        max_pos_err_m=max_p,
        max_ori_err_rad=max_r,
        home_pos_err_m=home_p,
        home_ori_err_rad=home_r,
        aligned_max_pos_err_m=al_p,
        aligned_max_ori_err_rad=al_r,
    )
