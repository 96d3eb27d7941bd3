"""What the data can and cannot tell apart: rank, conditioning, observability, advice.

* :func:`observability`: the identification Jacobian at the fitted robot, its rows the measured
  numbers in millimetres (orientation times the chain's reach, :func:`~.model.reach`), its
  columns the free corrections in units of ``prior_m`` and ``prior_rad``. Its condition number,
  and the observability index O1 of Borm & Menq (numbered O1 by Sun & Hollerbach, 2008): the
  geometric mean of the singular values over the square root of the number of poses, in
  millimetres of measured motion per unit of correction. Pose planning
  (:mod:`~.plan`) maximises the same product (D-optimal design).
* :func:`unidentified`: the combinations :func:`~.fit.fit` left at the model's values, in words.
* :func:`predicted`: how well the calibrated chain predicts poses from its standard errors, at
  the measured configurations and over the workspace.
* :func:`advice`: warnings that say how many more poses are needed and which joints to move.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from poekin.calibration.fit import Fit
from poekin.calibration.model import CalibrationModel, State, alike, words

__all__ = [
    "Direction",
    "Observability",
    "Prediction",
    "advice",
    "describe",
    "minimum_poses",
    "observability",
    "predicted",
    "recommended_poses",
    "scaled_jacobian",
    "undetermined",
    "unidentified",
]

FloatArray = NDArray[np.float64]

_NUMBERS_PER_PARAMETER = 2  # recommended: twice as many measured numbers as parameters
_SHARE = 0.3  # a correction is named in a direction when its share is this of the largest
_STILL_RAD = 0.2  # a revolute joint that spans less than this (rad) in the data barely moved
_STILL_M = 0.02  # likewise a prismatic joint (m)
_NARROW = 0.5  # a joint whose span in the data is less than this part of its range
_COVERAGE = 2.0  # poses whose workspace is predicted this many times worse are too similar
_MISMATCH_M = 0.01  # a fit that misses by more (m RMS) has wrong data, not a different robot
_ON_AXIS_M = 0.01  # a measured point this near the last joint's axis hides that joint's turn
_NULL = 1e-9  # a combination whose gain is below this part of the largest is not seen at all
_PART = 0.1  # a correction this much in the unidentified combinations is not determined


@dataclasses.dataclass(frozen=True)
class Observability:
    """Singular values of the scaled identification Jacobian, its condition number and O1."""

    singular: FloatArray
    condition_number: float
    o1: float


@dataclasses.dataclass(frozen=True)
class Direction:
    """A combination of corrections the data cannot determine: the correction it leads with,
    then those that move the tool like it (indices into the model's parameters), and its
    standard error had it been fitted (in prior units: 1 means as large as the prior; inf when
    the data do not see it at all)."""

    params: tuple[int, ...]
    std_prior: float


def scaled_jacobian(
    model: CalibrationModel,
    state: State,
    q: FloatArray,
    prior_m: float,
    prior_rad: float,
    free: Sequence[int] | None = None,
) -> FloatArray:
    """``(N m, F)`` the identification Jacobian in millimetres (orientation rows times the reach)
    with columns in prior units, over the free corrections (or ``free``)."""
    keys = list(model.free if free is None else free)
    return _in_units(model, model.rows(state, q)[:, keys], keys, prior_m, prior_rad)


def _in_units(
    model: CalibrationModel, rows: FloatArray, keys: Sequence[int], prior_m: float, prior_rad: float
) -> FloatArray:
    """Rows in metres (:meth:`~.model.CalibrationModel.in_metres`) in millimetres, with columns
    ``keys`` in prior units."""
    return np.asarray(rows * model.units(keys, prior_m, prior_rad) * 1e3, dtype=np.float64)


def observability(
    model: CalibrationModel,
    state: State,
    q: FloatArray,
    prior_m: float,
    prior_rad: float,
    *,
    jacobian: FloatArray | None = None,
) -> Observability:
    """See the module docstring. ``jacobian``: the derivatives of the measured numbers at
    ``state`` over the free corrections ``(N, m, F)``, if the caller has them
    (:attr:`~.fit.Fit.jacobian`)."""
    if jacobian is None:
        J = scaled_jacobian(model, state, q, prior_m, prior_rad)
    else:
        J = _in_units(model, model.in_metres(jacobian), model.free, prior_m, prior_rad)
    s = np.linalg.svd(J, compute_uv=False)
    smallest = float(s[-1]) if s.size else 0.0
    cond = float(s[0] / smallest) if smallest > 0 else float("inf")
    with np.errstate(divide="ignore"):
        o1 = float(np.exp(np.mean(np.log(s))) / np.sqrt(len(q))) if s.size else 0.0
    return Observability(np.asarray(s, dtype=np.float64), cond, o1)


#: A condition number above this is singular to rounding: its digits, and O1's, depend on the
#: last bits of the smallest singular value (they differ between vector widths), so the report
#: prints neither (issue 26).
SINGULAR_CONDITION = 1e12


def quality_text(condition_number: float, o1: float) -> str:
    """``condition number C, O1 X`` as a report prints them, three significant digits; for a
    condition number above :data:`SINGULAR_CONDITION` (or inf), ``condition number > 1e12
    (singular to rounding), O1 ~0``, which no rounding changes."""
    if not condition_number <= SINGULAR_CONDITION:
        return "condition number > 1e12 (singular to rounding), O1 ~0"
    return f"condition number {condition_number:.3g}, O1 {o1:.3g}"


def unidentified(
    model: CalibrationModel, fitted: Fit, prior_m: float, prior_rad: float
) -> list[Direction]:
    """The robot combinations that the fit left at the model's values (its basis is smaller
    than the free set), each as the correction it leads with and those that move the tool
    like it.

    The combinations span a subspace, and any basis of it is as right as another; the SVD's is
    a blend of everything in it. Reduced to echelon form (Gauss-Jordan with complete pivoting)
    each has a correction of its own (its pivot, the largest one left). The corrections that
    move the tool like a pivot are found from the weighted identification Jacobian by
    orthogonal matching pursuit (:func:`~.model.alike`), up to 3, as many as it takes to match
    its motion to within the noise; a pivot whose own motion is within the noise moves the tool
    too little to be measured."""
    free = list(model.free)
    kept = fitted.identified
    V = fitted.directions[kept:]  # (k, R): orthonormal rows over the robot corrections
    s = fitted.singular[kept:]
    top = float(fitted.singular[0]) if fitted.singular.size else 0.0
    A = _weighted(model, fitted, prior_m, prior_rad)  # (N m, F): sigmas per prior unit
    norms = np.linalg.norm(A, axis=0)
    unit = A / np.where(norms > 0, norms, 1.0)
    out = []
    for row in _echelon(V):
        lead = 6 + int(np.argmax(np.abs(row)))
        others = [j for j in range(len(free)) if j != lead]
        partners: tuple[int, ...] = ()
        if norms[lead] > fitted.sigma:  # it moves the tool: find what moves it alike
            rtol = fitted.sigma / float(norms[lead])
            partners = alike(unit[:, others], unit[:, lead], [free[j] for j in others], 3, rtol)
        # its standard error had it been fitted: |u| sigma / |A u|, |A u|^2 = sum (s_k c_k)^2
        gain = float(np.linalg.norm(s * (V @ row)))
        size = float(np.linalg.norm(row))
        std = float("inf") if gain <= _NULL * top * size else fitted.sigma * size / gain
        out.append(Direction((free[lead], *partners), std))
    return out


def _weighted(model: CalibrationModel, fitted: Fit, prior_m: float, prior_rad: float) -> FloatArray:
    """The fit's identification Jacobian ``(N m, F)`` in residual sigmas (its weights, robust
    ones included) per prior unit of each free correction."""
    J = fitted.weighted()[1] * model.units(model.free, prior_m, prior_rad)
    return np.asarray(J.reshape(-1, J.shape[-1]), dtype=np.float64)


def undetermined(model: CalibrationModel, fitted: Fit) -> tuple[int, ...]:
    """The free robot corrections the data do not determine: those with at least ``_PART`` of
    their direction (in prior units) in the combinations left unidentified (indices into the
    model's parameters). Their fitted values are one of several that fit the data as well."""
    kept = fitted.identified
    share = np.sum(fitted.directions[kept:] ** 2, axis=0)
    free = list(model.free)
    return tuple(free[6 + j] for j in np.flatnonzero(share >= _PART))


def _echelon(V: FloatArray) -> FloatArray:
    """The rows of ``V`` ``(k, R)`` as the reduced row echelon form of their span: each row 1 at
    its own pivot column and 0 at the others' (pivots: the largest entry left)."""
    M = np.array(V, dtype=np.float64)
    pivots: list[int] = []
    for j in range(len(M)):
        rest = np.abs(M[j:])
        rest[:, pivots] = 0.0
        r, c = np.unravel_index(int(np.argmax(rest)), rest.shape)
        M[[j, j + r]] = M[[j + r, j]]
        M[j] /= M[j, c]
        others = np.arange(len(M)) != j
        M[others] -= np.outer(M[others, c], M[j])
        pivots.append(int(c))
    return M


@dataclasses.dataclass(frozen=True)
class Prediction:
    """How well the calibrated chain predicts poses, from the standard errors of the fitted
    corrections alone (the noise they carry; combinations left unidentified are not counted):
    the RMS position error (m) and orientation error (rad; NaN for positions-only data) at the
    measured configurations and over the workspace (random configurations within the limits).
    """

    measured_m: float
    workspace_m: float
    measured_rad: float
    workspace_rad: float

    @property
    def coverage(self) -> float:
        """How many times worse the workspace is predicted than the measured poses (1 or a
        little more when the poses cover the workspace)."""
        return self.workspace_m / self.measured_m if self.measured_m > 0 else 1.0


def predicted(model: CalibrationModel, fitted: Fit, workspace: FloatArray) -> Prediction:
    """:class:`Prediction` of ``fitted``, over ``workspace`` ``(W, n)`` configurations."""
    _, D = model.jacobian(fitted.state, workspace)
    out = []
    for J in (fitted.jacobian, model.measured(D)[:, :, list(model.free)]):
        var = np.einsum("nif,fg,nig->ni", J, fitted.cov, J)
        pos = float(np.sqrt(np.mean(np.sum(var[:, -3:], axis=1))))
        ori = float(np.sqrt(np.mean(np.sum(var[:, :3], axis=1)))) if var.shape[1] == 6 else np.nan
        out.append((pos, ori))
    (mp, mo), (wp, wo) = out
    return Prediction(mp, wp, mo, wo)


def minimum_poses(model: CalibrationModel) -> int:
    """The fewest poses that can be fitted: more measured numbers than free parameters."""
    return len(model.free) // model.rows_per_pose + 1


def recommended_poses(model: CalibrationModel) -> int:
    """Twice as many measured numbers as free parameters."""
    return -(-_NUMBERS_PER_PARAMETER * len(model.free) // model.rows_per_pose)


def _ranges(model: CalibrationModel) -> FloatArray:
    """Each joint's range to move in (its limits; a revolute joint's at most a turn)."""
    chain = model.chain
    assert chain.limits is not None  # a chain always has limits (+-inf if none)
    span = chain.limits[:, 1] - chain.limits[:, 0]
    revolute = np.array([t == "revolute" for t in chain.joint_types])
    return np.asarray(np.where(revolute, np.minimum(span, 2 * np.pi), span), dtype=np.float64)


def _still(model: CalibrationModel, q: FloatArray) -> list[int]:
    """Joints that barely moved in the data."""
    span = np.ptp(q, axis=0)
    return [
        i
        for i, kind in enumerate(model.chain.joint_types)
        if span[i] < (_STILL_RAD if kind == "revolute" else _STILL_M)
    ]


def _narrow(model: CalibrationModel, q: FloatArray) -> list[int]:
    """Joints that moved over less than ``_NARROW`` of their range, narrowest first."""
    share = np.ptp(q, axis=0) / _ranges(model)
    return [int(i) for i in np.argsort(share) if share[i] < _NARROW]


def _spans(model: CalibrationModel, q: FloatArray, joints: Sequence[int]) -> str:
    """What ``joints`` span in the data, of their ranges: ``"it spans 0 of its 6.28 rad"``,
    ``"they span 0.19 to 0.27 of their 6.28 rad"``."""
    span, ranges = np.ptp(q, axis=0)[list(joints)], _ranges(model)[list(joints)]
    units = {"rad" if model.chain.joint_types[i] == "revolute" else "m" for i in joints}
    unit = units.pop() if len(units) == 1 else "rad or m"
    of = f" {unit}"
    if np.all(np.isfinite(ranges)):
        of = f" of {'its' if len(joints) == 1 else 'their'} {_between(ranges, '.3g', '-')} {unit}"
    return f"{'it spans' if len(joints) == 1 else 'they span'} {_between(span, '.2g', ' to ')}{of}"


def _listed(items: Sequence[str]) -> str:
    """``"a"``, ``"a and b"``, ``"a, b and c"``."""
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _between(values: FloatArray, spec: str, sep: str) -> str:
    """``"0.2"``, or ``"0.19 to 0.27"`` when the values differ as printed."""
    low, high = format(float(values.min()), spec), format(float(values.max()), spec)
    return low if low == high else f"{low}{sep}{high}"


def _moved(model: CalibrationModel, joints: Sequence[int]) -> str:
    """``"joint 4 (wrist_1_joint)"``, or ``"every joint"``."""
    return "every joint" if len(joints) == model.chain.n_joints > 1 else _joint_list(model, joints)


def _joint_list(model: CalibrationModel, joints: Sequence[int]) -> str:
    names = [f"{i + 1} ({model.chain.joint_names[i]})" for i in joints]
    label = "joint" if len(names) == 1 else "joints"
    return f"{label} " + (
        names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    )


def describe(model: CalibrationModel, direction: Direction) -> str:
    """A direction in words: ``"joint 6 (wrist_3_joint)'s encoder offset moves the tool as the
    tool's shift along its x does"``."""
    first, *rest = direction.params
    lead = model.params[first].words
    if not rest:
        return f"{lead} moves the tool too little to be measured"
    return f"{lead} moves the tool as {words(model, rest)} {'does' if len(rest) == 1 else 'do'}"


def _off_axis(model: CalibrationModel, state: State) -> float:
    """Positions-only data: the measured point's distance (m) from the last joint's axis."""
    geo = model.geometry(state.x)
    p = geo.home[:3, 3] - geo.points[-1]
    return float(np.linalg.norm(np.cross(p, geo.dirs[-1])))


def advice(
    model: CalibrationModel,
    q: FloatArray,
    directions: Sequence[Direction],
    source: str,
    *,
    state: State,
    residual_rms_m: float,
    prediction: Prediction,
    overstated: str | None = None,
) -> list[str]:
    """Warnings for too few or too similar poses, with how many more, which joints to move:
    too few poses; a given noise far above the residuals' (``overstated``, its words: then
    nothing else is said); data the model cannot fit (wrong units, joint order or frame:
    likewise); combinations left unidentified (the joints that barely moved, or a point on
    the last joint's axis); poses that cover the workspace poorly (the joints whose range they
    leave out). ``source`` names the model in the suggested planning command; ``state``,
    ``residual_rms_m`` and ``prediction`` are the fit's."""
    out = []
    n = len(q)
    recommended = recommended_poses(model)
    good = max(2 * recommended, n)
    positions = " --positions" if model.measure == "position" else ""
    plan = f"'poekin calibrate {source} --plan {good}{positions}'"
    what = "poses" if model.measure == "pose" else "positions"
    if n < recommended:
        out.append(
            f"{n} {what} for {len(model.free)} parameters: measure at least {recommended - n} "
            f"more ({recommended} give twice as many measured numbers as parameters), better "
            f"{good} or more: {plan} proposes the ones that tell the parameters apart best"
        )
    if overstated is not None:  # the noise given, not the poses, is what went wrong
        out.append(overstated)
        return out
    if residual_rms_m > _MISMATCH_M:
        out.append(
            f"the calibrated chain still misses the measurements by {residual_rms_m * 1e3:.3g} mm "
            "RMS, where a robot differs from its model by millimetres: check the data: the "
            "joint columns' order and units (radians and metres; degrees need --deg), the "
            "frame that was measured (--frame), and that the measurements are in metres"
        )
        return out
    if directions:
        joints = {model.params[k].joint for d in directions for k in d.params}
        involved = sorted(j for j in joints if j is not None)
        parts = [_joint_list(model, involved)] if involved else []
        groups = {model.params[k].group for d in directions for k in d.params}
        parts += [f"the {g}" for g in ("tool", "base") if g in groups]
        count = len(directions)
        text = (
            f"the {what} leave {count} combination{'s' if count > 1 else ''} of parameters "
            f"unidentified, kept at or shrunk toward the model's values (corrections of "
            f"{_listed(parts)})"
        )
        still = _still(model, q)
        move = [i for i in involved if i in still] or still
        last = model.chain.n_joints - 1
        turns = model.chain.joint_types[last] == "revolute"  # a slide moves any point
        distance = _off_axis(model, state) if model.measure == "position" and turns else np.inf
        if move:
            text += (
                f"; move {_moved(model, move)} over a wider range ({_spans(model, q, move)}): "
                "the chain is right only near where "
                + ("it stays" if len(move) == 1 else "they stay")
            )
        elif last in involved and distance < _ON_AXIS_M:
            text += (
                f"; the measured point is {distance * 1e3:.2g} mm from "
                f"{_joint_list(model, [last])}'s axis, so turning that joint hardly moves it: "
                "mount the target a few centimetres off that axis"
            )
        else:
            text += f"; measure more varied {what}, e.g. planned with {plan}"
        out.append(text)
    narrow = _narrow(model, q)
    # too few poses cover the workspace poorly too; that says nothing more unless joints are narrow
    if prediction.coverage > _COVERAGE and (narrow or n >= recommended):
        text = (
            f"the {what} cover the workspace poorly: from the standard errors, the calibrated "
            f"chain predicts the measured configurations to {prediction.measured_m * 1e3:.2g} "
            f"mm RMS but random ones within the limits to {prediction.workspace_m * 1e3:.2g} mm "
            f"({prediction.coverage:.2g} times worse); "
        )
        if narrow:
            text += (
                f"move {_moved(model, narrow)} over a wider range ({_spans(model, q, narrow)}), "
                f"or plan the {what} with {plan}"
            )
        else:
            text += f"measure more varied {what}, e.g. planned with {plan}"
        out.append(text)
    return out
