"""Calibration: fit a chain to the robot you measured, and say what the data can tell apart.

>>> import poekin
>>> plan = poekin.plan_poses("universal_robots_ur5e", 50)        # (50, 6) configurations
>>> # ... move the robot to each, measure the flange with a tracker: T_meas (50, 4, 4) ...
>>> result = poekin.calibrate("universal_robots_ur5e", plan, T_meas)
>>> result.robot.fk(q)          # the measured frame in the robot's base frame, for encoder q
>>> result.chain.fk(q)          # the same in the tracker's frame: result.base @ robot.fk(q)

* :mod:`~.model`: the parametrisation (PoE with local corrections, complete and minimal);
* :mod:`~.fit`: registration and Levenberg-Marquardt over the identifiable combinations;
* :mod:`~.identify`: rank, condition number, observability, unidentified directions, advice;
* :mod:`~.plan`: poses chosen for identifiability (greedy D-optimal design);
* :mod:`~.report`: :class:`Calibration`, the outcome;
* :mod:`~.simulate`: a robot that differs from its model, measured by MuJoCo (a truth to try
  all this on).
"""

from __future__ import annotations

import functools
import os
import warnings
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin._blas import one_thread
from poekin.calibration.fit import (
    _MAD,
    LOSSES,
    Fit,
    Loss,
    fit,
    initial_state,
    leave_out,
)
from poekin.calibration.identify import (
    advice,
    minimum_poses,
    observability,
    predicted,
    recommended_poses,
    unidentified,
)
from poekin.calibration.model import (
    CalibrationModel,
    Measure,
    as_chain,
    expected_identifiable,
    model_of,
)
from poekin.calibration.plan import plan_poses
from poekin.calibration.report import Calibration, Change
from poekin.chain import Chain, as_joint_values, real_array
from poekin.errors import CalibrationWarning, InputError
from poekin.verification.verify import pose_errors

if TYPE_CHECKING:
    from poekin.io.sources import LoadedModel

__all__ = [
    "LOSSES",
    "Calibration",
    "CalibrationModel",
    "Change",
    "calibrate",
    "check_measurements",
    "expected_identifiable",
    "plan_poses",
]

FloatArray = NDArray[np.float64]
_UNIT = 1e-6  # a rotation block must be orthonormal to this (as Chain's home pose)
_WORKSPACE, _SEED = 100, 20261125  # configurations that judge the calibrated chain


def check_measurements(measured: ArrayLike, n_poses: int) -> FloatArray:
    """``measured`` as ``(N, 4, 4)`` poses or ``(N, 3)`` positions, finite, with rigid poses.

    Raises:
        InputError: another shape or count, NaN or inf, a rotation block that is not
            orthonormal with det +1 (to 1e-6), or a last row other than ``[0, 0, 0, 1]``.
    """
    m = real_array(measured, "the measurements")
    if m.shape not in ((n_poses, 4, 4), (n_poses, 3)):
        raise InputError(
            f"expected {n_poses} measured poses (N, 4, 4) or positions (N, 3), one per row of "
            f"joint readings, got an array of shape {m.shape}"
        )
    bad = ~np.isfinite(m.reshape(n_poses, -1)).all(axis=1)
    if bad.any():
        raise InputError(
            f"measurement {int(np.flatnonzero(bad)[0])} contains NaN or inf; every value must "
            "be finite"
        )
    if m.ndim == 3:
        R = m[:, :3, :3]
        err = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2))
        wrong = (err > _UNIT) | (np.linalg.det(R) < 0)
        if wrong.any():
            k = int(np.flatnonzero(wrong)[0])
            raise InputError(
                f"measured pose {k}: its rotation is not orthonormal with det +1 (off by "
                f"{err[k]:.2g}); a quaternion must be unit length"
            )
        rows = np.abs(m[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > 0
        if rows.any():
            k = int(np.flatnonzero(rows)[0])
            raise InputError(f"measured pose {k}: the last row must be [0, 0, 0, 1]")
    return m


def _errors(measure: Measure, T: FloatArray, measured: FloatArray) -> tuple[FloatArray, FloatArray]:
    if measure == "pose":
        return pose_errors(measured, T)
    pos = np.linalg.norm(measured - T[:, :3, 3], axis=-1)
    return pos, np.full(len(pos), np.nan)


def _check_spread(measured: FloatArray) -> None:
    """The measured points must span a plane at least, or the measuring frame's rotation is
    unknown."""
    p = measured[:, :3, 3] if measured.ndim == 3 else measured
    s = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
    if s[0] == 0 or s[1] < 1e-9 * s[0]:
        raise InputError(
            "the measured positions lie on one line (or one point): the measuring frame's "
            "rotation cannot be found; measure poses that move the tool in more directions"
        )


def calibrate(
    model: Chain | str | os.PathLike[str] | LoadedModel,
    q: ArrayLike,
    measured: ArrayLike,
    *,
    frame: str | None = None,
    sigma_pos: float | None = None,
    sigma_ori: float | None = None,
    loss: Loss = "linear",
    f_scale: float = 3.0,
    prior_m: float = 1e-3,
    prior_rad: float = 1e-2,
    folds: int = 5,
    seed: int = 0,
) -> Calibration:
    """Fit ``model``'s chain to the robot you measured.

    Args:
        model: the nominal chain, or what :func:`poekin.load` takes (a Menagerie name, an MJCF
            or URDF path), with ``frame``.
        q: ``(N, n)`` the joint encoders' readings at each measurement (rad, m).
        measured: ``(N, 4, 4)`` the measured frame's poses, or ``(N, 3)`` its positions, in any
            fixed frame (a laser tracker's, a camera's); metres.
        frame: the end frame when ``model`` is not a chain.
        sigma_pos, sigma_ori: the measurement noise (m per axis, rad per axis): the weights of
            position and orientation residuals. None: estimated from the residuals.
        loss: ``"linear"`` (least squares), or ``"huber"`` / ``"soft_l1"`` to weigh down poses
            whose residual exceeds ``f_scale`` sigmas (outliers are reported either way).
        prior_m, prior_rad: the size of the differences a robot may have from its model: a
            combination of parameters the data determine worse than this is reported as
            unidentified, and fitted only as far as the data say (shrunk toward the model's
            value by this prior; one the data do not see at all keeps the model's value).
        folds: k of the k-fold held-out residual (0: none): each fold's poses predicted by a
            fit to the others (:func:`~.fit.leave_out`).
        seed: the folds' random split.

    Returns:
        The :class:`Calibration`: ``.robot`` is the calibrated robot (FK for encoder readings
        in its own base frame), ``.chain`` the same in the measuring frame, with the
        identifiability report.

    Raises:
        InputError: malformed data: NaN, shapes, a pose that is not rigid, fewer poses than the
            parameters need, all measured points on one line.

    Warns:
        CalibrationWarning: too few poses (how many more), combinations the poses leave
            unidentified or poses that cover the workspace poorly (which joints to move),
            data the model cannot fit (joint order, units, frame), or a fit that did not
            converge.
    """
    with one_thread():  # small matrices: see poekin._blas
        result = _calibrate(
            model,
            q,
            measured,
            frame=frame,
            sigma_pos=sigma_pos,
            sigma_ori=sigma_ori,
            loss=loss,
            f_scale=f_scale,
            prior_m=prior_m,
            prior_rad=prior_rad,
            folds=folds,
            seed=seed,
        )
    for text in result.warnings:
        warnings.warn(text, CalibrationWarning, stacklevel=2)
    return result


def _calibrate(
    model: Chain | str | os.PathLike[str] | LoadedModel,
    q: ArrayLike,
    measured: ArrayLike,
    *,
    frame: str | None,
    sigma_pos: float | None,
    sigma_ori: float | None,
    loss: Loss,
    f_scale: float,
    prior_m: float,
    prior_rad: float,
    folds: int,
    seed: int,
) -> Calibration:
    """:func:`calibrate`, its warnings in the result's ``warnings``."""
    chain = as_chain(model, frame)
    n = chain.n_joints
    q_arr = as_joint_values(q, n, what="joint readings")
    if q_arr.ndim != 2:
        raise InputError(f"joint readings must be (N, {n}), got shape {q_arr.shape}")
    if len(q_arr) == 0:
        raise InputError(
            "no poses to fit (0 joint readings): give the joint readings and measured poses of "
            "the poses you measured (poekin calibrate --plan N proposes them)"
        )
    meas = check_measurements(measured, len(q_arr))
    measure: Measure = "pose" if meas.ndim == 3 else "position"
    cm = model_of(chain, measure)
    need = minimum_poses(cm)
    if len(q_arr) < need:
        raise InputError(
            f"{len(q_arr)} {'poses' if measure == 'pose' else 'positions'} give "
            f"{len(q_arr) * cm.rows_per_pose} measured numbers for {len(cm.free)} parameters: "
            f"measure at least {need} (better {recommended_poses(cm)} or more)"
        )
    _check_spread(meas)
    for name, value in (("sigma_pos", sigma_pos), ("sigma_ori", sigma_ori)):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive number (or None to estimate it)")
    for name, value in (("prior_m", prior_m), ("prior_rad", prior_rad), ("f_scale", f_scale)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a positive number, got {value}")
    if isinstance(folds, bool) or not isinstance(folds, int) or folds < 0 or folds == 1:
        raise InputError(f"folds must be 0 (none) or a whole number from 2, got {folds!r}")
    if folds > len(q_arr):
        raise InputError(
            f"folds={folds} with {len(q_arr)} poses: each fold holds out at least one pose, so "
            f"folds is at most {len(q_arr)} (5 is usual; 0 for none)"
        )
    options = {
        "sigma_pos": sigma_pos,
        "sigma_ori": sigma_ori,
        "loss": loss,
        "f_scale": f_scale,
        "prior_m": prior_m,
        "prior_rad": prior_rad,
    }
    start = initial_state(cm, q_arr, meas)
    fitted = fit(cm, q_arr, meas, start=start, **options)  # type: ignore[arg-type]
    state = fitted.state
    after = _errors(measure, fitted.poses, meas)
    directions = unidentified(cm, fitted, prior_m, prior_rad)
    prediction = predicted(cm, fitted, workspace(chain))
    source = _source_name(model, chain)
    notes = advice(
        cm,
        q_arr,
        directions,
        source,
        state=state,
        residual_rms_m=float(np.sqrt(np.mean(after[0] ** 2))),
        prediction=prediction,
        overstated=_overstated(fitted.residuals, sigma_pos, sigma_ori),
    )
    heldout = None
    if folds:
        heldout = _heldout(cm, len(q_arr), folds, seed, fitted)
        if heldout is None:
            notes.append(
                f"too few poses for a {folds}-fold held-out residual (each fold's fit needs "
                f"{need}): measure more, or pass folds=0"
            )
    if not fitted.converged:
        notes.append(
            f"the fit stopped after {fitted.iterations} iterations without converging; "
            "check the data (outliers, joint order, units)"
        )
    return Calibration(
        chain=cm.calibrated_chain(state),
        nominal=chain,
        model=cm,
        state=state,
        fitted=fitted,
        q=q_arr,
        measured=meas,
        before=_errors(measure, cm.poses(start, q_arr), meas),
        after=after,
        normalised=_normalised(fitted.residuals),
        heldout=heldout,
        observability=observability(cm, state, q_arr, prior_m, prior_rad, jacobian=fitted.jacobian),
        predicted=prediction,
        unidentified=tuple(directions),
        warnings=tuple(notes),
        source=source,
        prior_m=prior_m,
        prior_rad=prior_rad,
        loss=loss,
        f_scale=f_scale,
        folds=folds,
    )


@functools.lru_cache(maxsize=16)
def workspace(chain: Chain) -> FloatArray:
    """``(W, n)`` random configurations within the limits (a revolute joint's within a turn),
    the same for every calibration of ``chain``: where :class:`~.identify.Prediction` judges
    the calibrated chain."""
    from poekin.calibration.plan import sampling_chain
    from poekin.verification.verify import sample_joint_values

    q = np.array(
        sample_joint_values(sampling_chain(chain), _WORKSPACE, seed=_SEED, within_limits=True),
        dtype=np.float64,
    )
    q.flags.writeable = False
    return q


def _normalised(r: FloatArray) -> FloatArray:
    """Each pose's residual in sigmas, RMS over its numbers, with each group's sigma (rotation,
    position) from the median absolute residual: robust, so that outliers stand out whatever
    the loss was."""
    groups = [slice(0, 3), slice(3, 6)] if r.shape[1] == 6 else [slice(0, 3)]
    scaled = np.concatenate(
        [r[:, g] / max(_MAD * float(np.median(np.abs(r[:, g]))), 1e-300) for g in groups], axis=1
    )
    return np.asarray(np.sqrt(np.mean(scaled**2, axis=1)), dtype=np.float64)


def _source_name(model: object, chain: Chain) -> str:
    if isinstance(model, str | os.PathLike):
        return os.fspath(model)
    return chain.robot or "MODEL"


# A noise given this many times the residuals' own spread is overstated: the fit weighs the
# data as that noisy and leaves what they determine well unidentified
_OVERSTATED = 10.0


def _overstated(
    residuals: FloatArray, sigma_pos: float | None, sigma_ori: float | None
) -> str | None:
    """Words for a given noise far above the residuals' spread (``(N, m)`` raw, rad then m),
    or None."""
    said = []
    pos = float(np.sqrt(np.mean(residuals[:, -3:] ** 2)))
    if sigma_pos is not None and sigma_pos > _OVERSTATED * pos:
        said.append(
            f"--sigma-pos (sigma_pos) {sigma_pos * 1e3:.3g} mm is {sigma_pos / pos:.2g} times the "
            f"residuals' spread ({pos * 1e3:.2g} mm per axis)"
        )
    if sigma_ori is not None and residuals.shape[1] == 6:
        ori = float(np.sqrt(np.mean(residuals[:, :3] ** 2)))
        if sigma_ori > _OVERSTATED * ori:
            said.append(
                f"--sigma-ori (sigma_ori) {sigma_ori * 1e3:.3g} mrad is {sigma_ori / ori:.2g} "
                f"times the residuals' spread ({ori * 1e3:.2g} mrad per axis)"
            )
    if not said:
        return None
    return (
        f"{' and '.join(said)}: the fit weighs the data as that noisy, so it leaves unidentified "
        "what they determine well; give your instrument's noise (in metres and radians), or "
        "leave it out to have it estimated from the residuals"
    )


def _heldout(
    cm: CalibrationModel,
    n: int,
    folds: int,
    seed: int,
    fitted: Fit,
) -> tuple[FloatArray, FloatArray] | None:
    """Each pose's errors predicted by a fit on the other folds (:func:`~.fit.leave_out`), or
    None if a fold's fit would have too few poses."""
    from poekin.verification.verify import random_generator

    k = min(folds, n)
    fold = np.empty(n, dtype=int)
    fold[random_generator(seed).permutation(n)] = np.arange(n) % k
    if n - int(np.max(np.bincount(fold))) < minimum_poses(cm):
        return None
    return leave_out(fitted, fold)
