"""What the data can and cannot tell apart: rank, conditioning, observability, advice.

* :func:`observability`: the identification Jacobian at the fitted robot, its rows the measured
  numbers in millimetres (orientation times the chain's reach, :func:`~.model.reach`), its
  columns the free corrections in units of ``prior_m`` and ``prior_rad``. Its condition number,
  and the observability index O1 of Borm & Menq (numbered O1 by Sun & Hollerbach, 2008): the
  geometric mean of the singular values over the square root of the number of poses, in
  millimetres of measured motion per unit of correction. Pose planning
  (:mod:`~.plan`) maximises the same product (D-optimal design).
* :func:`unidentified`: the combinations :func:`~.fit.fit` left at the model's values, in words.
* :func:`advice`: warnings that say how many more poses are needed and which joints to move.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from poekin.calibration.fit import Fit
from poekin.calibration.model import CalibrationModel, State, words

__all__ = [
    "Direction",
    "Observability",
    "advice",
    "describe",
    "minimum_poses",
    "observability",
    "recommended_poses",
    "scaled_jacobian",
    "unidentified",
]

FloatArray = NDArray[np.float64]

_NUMBERS_PER_PARAMETER = 2  # recommended: twice as many measured numbers as parameters
_SHARE = 0.3  # a correction is named in a direction when its share is this of the largest
_STILL_RAD = 0.2  # a revolute joint that spans less than this (rad) in the data barely moved
_STILL_M = 0.02  # likewise a prismatic joint (m)


@dataclasses.dataclass(frozen=True)
class Observability:
    """Singular values of the scaled identification Jacobian, its condition number and O1."""

    singular: FloatArray
    condition_number: float
    o1: float


@dataclasses.dataclass(frozen=True)
class Direction:
    """A combination of corrections the data cannot determine: the corrections it involves
    (indices into the model's parameters, largest share first) and its standard error had it
    been fitted (in prior units: 1 means as large as the prior)."""

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
    units = np.array([prior_m if model.params[k].unit == "m" else prior_rad for k in keys])
    return np.asarray(rows * units * 1e3, dtype=np.float64)


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


def unidentified(model: CalibrationModel, fitted: Fit) -> list[Direction]:
    """The robot combinations that the fit left at the model's values (its basis is smaller
    than the free set), largest share first."""
    free = list(model.free)
    kept = fitted.basis.shape[1] - 6
    out = []
    for k in range(kept, len(free) - 6):
        v = fitted.directions[k]
        order = np.argsort(-np.abs(v))
        big = [free[6 + j] for j in order if abs(v[j]) >= _SHARE * abs(v[order[0]])][:4]
        s = float(fitted.singular[k])
        out.append(Direction(tuple(big), fitted.sigma / s if s > 0 else float("inf")))
    return out


def minimum_poses(model: CalibrationModel) -> int:
    """The fewest poses that can be fitted: more measured numbers than free parameters."""
    return len(model.free) // model.rows_per_pose + 1


def recommended_poses(model: CalibrationModel) -> int:
    """Twice as many measured numbers as free parameters."""
    return -(-_NUMBERS_PER_PARAMETER * len(model.free) // model.rows_per_pose)


def _still(model: CalibrationModel, q: FloatArray) -> dict[int, float]:
    """Joints that barely moved in the data: index -> the range they span."""
    span = np.ptp(q, axis=0)
    out = {}
    for i, kind in enumerate(model.chain.joint_types):
        if span[i] < (_STILL_RAD if kind == "revolute" else _STILL_M):
            out[i] = float(span[i])
    return out


def _joint_list(model: CalibrationModel, joints: Sequence[int]) -> str:
    names = [f"{i + 1} ({model.chain.joint_names[i]})" for i in joints]
    label = "joint" if len(names) == 1 else "joints"
    return f"{label} " + (
        names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    )


def describe(model: CalibrationModel, direction: Direction) -> str:
    """A direction in words: ``"joint 6 (wrist_3_joint)'s encoder offset and the tool's shift
    along its x move the tool alike"``."""
    what = words(model, direction.params)
    verb = "moves" if len(direction.params) == 1 else "move"
    if len(direction.params) == 1:
        return f"{what} {verb} the tool too little to be measured"
    return f"{what} {verb} the tool alike"


def advice(
    model: CalibrationModel, q: FloatArray, directions: Sequence[Direction], source: str
) -> list[str]:
    """Warnings for too few or too similar poses: how many more, which joints to move.
    ``source`` names the model in the suggested planning command."""
    out = []
    n = len(q)
    recommended = recommended_poses(model)
    plan = f"poekin calibrate {source} --plan {max(recommended, 2 * n)}"
    if n < recommended:
        out.append(
            f"{n} poses for {len(model.free)} parameters: measure at least {recommended - n} "
            f"more ({recommended} give twice as many measured numbers as parameters; "
            f"plan them with '{plan}')"
        )
    if directions:
        joints = {model.params[k].joint for d in directions for k in d.params}
        involved = sorted(j for j in joints if j is not None)
        still = _still(model, q)
        move = [i for i in involved if i in still] or sorted(still)
        parts = [_joint_list(model, involved)] if involved else []
        groups = {model.params[k].group for d in directions for k in d.params}
        parts += [f"the {g}" for g in ("tool", "base") if g in groups]
        count = len(directions)
        text = (
            f"the poses leave {count} combination{'s' if count > 1 else ''} of parameters "
            f"unidentified, kept at the model's values (corrections of {' and '.join(parts)})"
        )
        if move:
            spans = ", ".join(
                f"{still[i]:.2g} {'rad' if model.chain.joint_types[i] == 'revolute' else 'm'}"
                for i in move
            )
            text += f"; move {_joint_list(model, move)} over a wider range (now {spans})"
        else:
            text += f"; measure more varied poses, e.g. planned with '{plan}'"
        out.append(text)
    return out
