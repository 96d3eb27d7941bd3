"""Lie-group helpers for SO(3) and SE(3): hat/vee, exp/log, adjoint and inverse.

Conventions
-----------
* Twists and exponential coordinates are ordered ``[w; v]`` (angular part first), as in
  Lynch & Park, *Modern Robotics*. ``hat_se3([w; v]) = [[hat(w), v], [0, 0]]``.
* SI units: metres and radians. Poses are homogeneous ``4 x 4`` matrices
  ``[[R, p], [0, 1]]``.
* Every function accepts leading batch axes: vectors are ``(..., 3)`` or ``(..., 6)``,
  matrices ``(..., 3, 3)`` or ``(..., 4, 4)``; the batch axes pass through unchanged.
* A floating input keeps its dtype (float32 in, float32 out); integer or boolean input is
  promoted to float64. A wrong trailing shape raises :class:`~poekin.errors.InputError`.
* Everything is vectorised. Branches (small angle, near pi) are chosen element-wise with
  ``np.where`` and every division has a safe denominator, so a batch that mixes tiny,
  ordinary and near-pi angles is handled correctly and emits no floating-point warnings.

Numerical choices
-----------------
* ``sin(t)/t``, ``(1 - cos t)/t^2`` and ``t/sin(t)`` have no cancellation; a Taylor series
  is used only below ``_SMALL_ANGLE = 1e-3`` (to avoid ``0/0``), where its truncation error
  is below ``1e-20``. ``1 - cos t`` is always computed as ``2 sin^2(t/2)``.
* ``(t - sin t)/t^3`` and ``(1 - (t/2) cot(t/2))/t^2`` lose ``~eps/t^2`` relative accuracy
  to cancellation, so they use Taylor series (five and six terms) below
  ``_SERIES_ANGLE = 0.3``. Measured against exact rational arithmetic the worst relative
  error is then ``~1e-14`` (at the switch), and their ``W^2`` terms are accurate to
  ``~eps`` absolute everywhere.
* Rotation angles come from ``atan2(|vee(R - R^T)|/2, (tr R - 1)/2)``, never ``arccos``,
  so they are accurate near both 0 and pi. For angles above pi/2 (``cos t < 0``) the
  rotation axis of ``log_so3`` is read from the symmetric part of ``R``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import InputError

__all__ = [
    "adjoint",
    "axis_rotation",
    "coordinate_axis",
    "exp_se3",
    "exp_so3",
    "hat_se3",
    "hat_so3",
    "homogeneous",
    "inverse",
    "log_se3",
    "log_so3",
    "matrix_exp_se3",
    "matrix_exp_so3",
    "quat_normalize",
    "quat_to_rotation",
    "rotate",
    "rotate_compose",
    "rotation_angle",
    "rotation_to_quat",
    "vec_to_se3",
    "vec_to_so3",
    "vee_se3",
    "vee_so3",
]

Array = NDArray[np.floating[Any]]

# Below this angle (rad) the cancellation-free coefficients sin(t)/t, (1 - cos t)/t^2 and
# t/sin(t) switch to three-term Taylor series; truncation error there is < 1e-20.
_SMALL_ANGLE = 1e-3
# Below this angle (rad) the cancellation-prone coefficients (t - sin t)/t^3 and
# (1 - (t/2)cot(t/2))/t^2 use Taylor series. Near 0.3 the truncation error of the series and
# the ~eps/t^2 cancellation error of the direct formula are both <~1e-14 relative.
_SERIES_ANGLE = 0.3


# --------------------------------------------------------------------------------------------
# input handling


def _as_float_array(x: ArrayLike, trailing: tuple[int, ...], func: str, name: str) -> Array:
    """``x`` as a finite floating array whose trailing shape is ``trailing``; else
    ``InputError``."""
    arr = np.asarray(x)
    if arr.dtype.kind in "biu":
        arr = arr.astype(np.float64)
    elif arr.dtype.kind != "f":
        raise InputError(f"{func}: {name} must be a real numeric array, got dtype {arr.dtype}")
    k = len(trailing)
    if arr.ndim < k or arr.shape[arr.ndim - k :] != trailing:
        expected = "(..., " + ", ".join(str(n) for n in trailing) + ")"
        raise InputError(f"{func}: expected {name} of shape {expected}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{func}: {name} contains NaN or inf; every value must be finite")
    return arr


def _eye(n: int, like: Array) -> Array:
    """``(n, n)`` identity in the dtype of ``like`` (broadcasts against batches)."""
    return np.eye(n, dtype=like.dtype)


def _transpose(M: Array) -> Array:
    """Swap the last two axes."""
    return np.swapaxes(M, -1, -2)


def _matvec(M: Array, x: Array) -> Array:
    """Batched ``M @ x`` for ``M (..., m, n)`` and ``x (..., n)``."""
    return (M @ x[..., None])[..., 0]


def _homogeneous(R: Array, p: Array) -> Array:
    """Poses ``[[R, p], [0, 1]]`` ``(..., 4, 4)`` from ``R (..., 3, 3)`` and ``p (..., 3)``."""
    batch = np.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    T = np.zeros((*batch, 4, 4), dtype=np.result_type(R, p))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1
    return T


def homogeneous(R: ArrayLike, p: ArrayLike) -> Array:
    """Poses ``[[R, p], [0, 1]]``: ``R (..., 3, 3)``, ``p (..., 3) -> (..., 4, 4)``."""
    return _homogeneous(
        _as_float_array(R, (3, 3), "homogeneous", "R"), _as_float_array(p, (3,), "homogeneous", "p")
    )


# --------------------------------------------------------------------------------------------
# scalar coefficients (element-wise over t >= 0)


def _sin_over_t(t: Array) -> Array:
    """``sin(t)/t``."""
    small = t < _SMALL_ANGLE
    t2 = t * t
    series = 1 - t2 / 6 * (1 - t2 / 20)
    return np.where(small, series, np.sin(t) / np.where(small, 1, t))


def _one_minus_cos_over_t2(t: Array) -> Array:
    """``(1 - cos t)/t^2``, computed as ``0.5 (sin(t/2)/(t/2))^2`` (no cancellation)."""
    half = _sin_over_t(t / 2)
    return half * half / 2


def _t_minus_sin_over_t3(t: Array) -> Array:
    """``(t - sin t)/t^3``."""
    small = t < _SERIES_ANGLE
    t2 = t * t
    series = 1 / 6 - t2 / 120 * (1 - t2 / 42 * (1 - t2 / 72 * (1 - t2 / 110)))
    safe_t = np.where(small, 1, t)
    return np.where(small, series, (safe_t - np.sin(safe_t)) / safe_t**3)


def _inverse_v_coefficient(t: Array) -> Array:
    """``(1 - (t/2) cot(t/2))/t^2``: the ``W^2`` coefficient of ``V^{-1}``; 1/pi^2 at t = pi."""
    small = t < _SERIES_ANGLE
    t2 = t * t
    # 1/12 + t^2/720 + t^4/30240 + t^6/1209600 + t^8/47900160 + 691 t^10/1307674368000
    series = 1 / 12 + t2 * (
        1 / 720
        + t2 * (1 / 30240 + t2 * (1 / 1209600 + t2 * (1 / 47900160 + t2 * 691 / 1307674368000)))
    )
    safe_t = np.where(small, 1, t)
    half = safe_t / 2
    direct = (1 - half * np.cos(half) / np.sin(half)) / (safe_t * safe_t)
    return np.where(small, series, direct)


def _t_over_sin_t(t: Array, sin_t: Array) -> Array:
    """``t/sin(t)`` given both ``t`` and (a computed) ``sin t``; Taylor series near 0."""
    small = t < _SMALL_ANGLE
    t2 = t * t
    series = 1 + t2 / 6 * (1 + t2 * 7 / 60)
    # sin t is exactly 0 at t = pi; log_so3 takes the symmetric-part branch there.
    return np.where(small, series, t / np.where(small | (sin_t == 0), 1, sin_t))


# --------------------------------------------------------------------------------------------
# hat / vee


def hat_so3(omega: ArrayLike) -> Array:
    """Skew-symmetric matrix ``[omega]`` with ``[omega] x = omega x x``.

    Shapes: ``omega (..., 3) -> (..., 3, 3)``.
    """
    w = _as_float_array(omega, (3,), "hat_so3", "omega")
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    zero = np.zeros_like(x)
    rows = [
        np.stack([zero, -z, y], axis=-1),
        np.stack([z, zero, -x], axis=-1),
        np.stack([-y, x, zero], axis=-1),
    ]
    return np.stack(rows, axis=-2)


def vee_so3(Omega: ArrayLike) -> Array:
    """Vector of the antisymmetric part ``(Omega - Omega^T)/2``; inverse of :func:`hat_so3`.

    Shapes: ``Omega (..., 3, 3) -> (..., 3)``. Exact for exactly skew-symmetric input.
    """
    M = _as_float_array(Omega, (3, 3), "vee_so3", "Omega")
    x = (M[..., 2, 1] - M[..., 1, 2]) / 2
    y = (M[..., 0, 2] - M[..., 2, 0]) / 2
    z = (M[..., 1, 0] - M[..., 0, 1]) / 2
    return np.stack([x, y, z], axis=-1)


def hat_se3(xi: ArrayLike) -> Array:
    """``4 x 4`` matrix ``[[hat(w), v], [0, 0]]`` of the twist ``xi = [w; v]``.

    Shapes: ``xi (..., 6) -> (..., 4, 4)``.
    """
    x = _as_float_array(xi, (6,), "hat_se3", "xi")
    Xi = np.zeros((*x.shape[:-1], 4, 4), dtype=x.dtype)
    Xi[..., :3, :3] = hat_so3(x[..., :3])
    Xi[..., :3, 3] = x[..., 3:]
    return Xi


def vee_se3(Xi: ArrayLike) -> Array:
    """Twist ``[w; v]`` of ``Xi = [[hat(w), v], [0, 0]]``; inverse of :func:`hat_se3`.

    Shapes: ``Xi (..., 4, 4) -> (..., 6)``. ``w`` is read from the antisymmetric part of
    the upper-left block, the bottom row is ignored.
    """
    M = _as_float_array(Xi, (4, 4), "vee_se3", "Xi")
    return np.concatenate([vee_so3(M[..., :3, :3]), M[..., :3, 3]], axis=-1)


# --------------------------------------------------------------------------------------------
# SO(3)


def exp_so3(omega: ArrayLike) -> Array:
    """Rotation ``exp([omega])`` by Rodrigues' formula.

    ``R = I + sin(t)/t W + (1 - cos t)/t^2 W^2`` with ``W = hat(omega)``, ``t = |omega|``.
    Shapes: ``omega (..., 3) -> (..., 3, 3)``.
    """
    w = _as_float_array(omega, (3,), "exp_so3", "omega")
    t = np.linalg.norm(w, axis=-1)[..., None, None]
    W = hat_so3(w)
    return _eye(3, w) + _sin_over_t(t) * W + _one_minus_cos_over_t2(t) * (W @ W)


def rotation_angle(R: ArrayLike) -> Array:
    """Geodesic angle of a rotation, in ``[0, pi]``.

    ``atan2(|vee(R - R^T)|/2, (tr R - 1)/2)``: accurate near 0 and near pi. The orientation
    error between ``R_a`` and ``R_b`` is ``rotation_angle(R_a @ R_b^T)``.
    Shapes: ``R (..., 3, 3) -> (...)``.
    """
    M = _as_float_array(R, (3, 3), "rotation_angle", "R")
    sin_t = np.linalg.norm(vee_so3(M), axis=-1)
    cos_t = (np.trace(M, axis1=-2, axis2=-1) - 1) / 2
    angle: Array = np.arctan2(sin_t, cos_t)
    return angle


def log_so3(R: ArrayLike) -> Array:
    """Exponential coordinates ``omega = t a`` of a rotation, with ``t`` in ``[0, pi]``.

    Inverse of :func:`exp_so3`. The angle is ``atan2(sin t, cos t)`` from the antisymmetric
    part and the trace. For ``cos t >= 0`` the axis is ``vee(R)/sin t``; for ``cos t < 0``
    it is the column of ``B = (R + R^T)/2 - cos(t) I = (1 - cos t) a a^T`` with the largest
    diagonal entry, normalised, with its sign matched to ``vee(R)`` (any sign at exactly
    pi). Shapes: ``R (..., 3, 3) -> (..., 3)``.
    """
    M = _as_float_array(R, (3, 3), "log_so3", "R")
    u = vee_so3(M)  # sin(t) a
    sin_t = np.linalg.norm(u, axis=-1)
    cos_t = (np.trace(M, axis1=-2, axis2=-1) - 1) / 2
    t = np.arctan2(sin_t, cos_t)

    # ordinary and small angles: omega = (t / sin t) u
    from_antisymmetric = _t_over_sin_t(t, sin_t)[..., None] * u

    # large angles: axis from the symmetric part
    B = (M + _transpose(M)) / 2 - cos_t[..., None, None] * _eye(3, M)
    k = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
    column = np.take_along_axis(B, k[..., None, None], axis=-1)[..., 0]  # B[..., :, k]
    norm = np.linalg.norm(column, axis=-1, keepdims=True)
    axis = column / np.where(norm > 0, norm, 1)
    sign = np.where(np.sum(axis * u, axis=-1, keepdims=True) < 0, -1, 1).astype(M.dtype)
    from_symmetric = (sign * t[..., None]) * axis

    result: Array = np.where((cos_t < 0)[..., None], from_symmetric, from_antisymmetric)
    return result


# --------------------------------------------------------------------------------------------
# SE(3)


def exp_se3(xi: ArrayLike) -> Array:
    """Pose ``exp([xi])`` of the exponential coordinates ``xi = [w; v]``.

    ``[[exp(W), V v], [0, 1]]`` with ``V = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2``,
    ``W = hat(w)``, ``t = |w|``; a pure translation by ``v`` when ``w = 0``.
    Shapes: ``xi (..., 6) -> (..., 4, 4)``.
    """
    x = _as_float_array(xi, (6,), "exp_se3", "xi")
    w, v = x[..., :3], x[..., 3:]
    t = np.linalg.norm(w, axis=-1)[..., None, None]
    W = hat_so3(w)
    W2 = W @ W
    b = _one_minus_cos_over_t2(t)
    I3 = _eye(3, x)
    R = I3 + _sin_over_t(t) * W + b * W2
    V = I3 + b * W + _t_minus_sin_over_t3(t) * W2
    return _homogeneous(R, _matvec(V, v))


def log_se3(T: ArrayLike) -> Array:
    """Exponential coordinates ``[w; v]`` of a pose; inverse of :func:`exp_se3`.

    ``w = log_so3(R)`` and ``v = V^{-1} p`` with
    ``V^{-1} = I - W/2 + (1 - (t/2) cot(t/2))/t^2 W^2``, ``t = |w|`` in ``[0, pi]``.
    Shapes: ``T (..., 4, 4) -> (..., 6)``.
    """
    M = _as_float_array(T, (4, 4), "log_se3", "T")
    w = log_so3(M[..., :3, :3])
    t = np.linalg.norm(w, axis=-1)[..., None, None]
    W = hat_so3(w)
    V_inv = _eye(3, M) - W / 2 + _inverse_v_coefficient(t) * (W @ W)
    return np.concatenate([w, _matvec(V_inv, M[..., :3, 3])], axis=-1)


def adjoint(T: ArrayLike) -> Array:
    """Adjoint ``[[R, 0], [hat(p) R, R]]`` of a pose, acting on twists ``[w; v]``.

    ``T exp(xi) T^{-1} = exp(Ad(T) xi)``. Shapes: ``T (..., 4, 4) -> (..., 6, 6)``.
    """
    M = _as_float_array(T, (4, 4), "adjoint", "T")
    R = M[..., :3, :3]
    Ad = np.zeros((*M.shape[:-2], 6, 6), dtype=M.dtype)
    Ad[..., :3, :3] = R
    Ad[..., 3:, 3:] = R
    Ad[..., 3:, :3] = hat_so3(M[..., :3, 3]) @ R
    return Ad


def inverse(T: ArrayLike) -> Array:
    """Inverse ``[[R^T, -R^T p], [0, 1]]`` of a pose. Shapes: ``T (..., 4, 4) -> (..., 4, 4)``."""
    M = _as_float_array(T, (4, 4), "inverse", "T")
    R_t = _transpose(M[..., :3, :3])
    return _homogeneous(R_t, -_matvec(R_t, M[..., :3, 3]))


# --------------------------------------------------------------------------------------------
# unit quaternions, wxyz (MuJoCo's order)

# MuJoCo's mjMINVAL: a quaternion shorter than this normalises to the identity.
_QUAT_MIN_NORM = 1e-15


def quat_normalize(quat: ArrayLike) -> Array:
    """Quaternions ``wxyz`` scaled to unit length, exactly as MuJoCo's ``mju_normalize4``.

    A quaternion whose norm is below ``1e-15`` (zero included) becomes the identity
    ``[1, 0, 0, 0]``; one whose norm is within ``1e-15`` of 1 is returned unchanged. This is how
    MuJoCo reads a ball or free joint's ``qpos``, so an unnormalised quaternion means the same
    rotation in poekin and in ``mj_forward``. Shapes: ``(..., 4) -> (..., 4)``.
    """
    qt = _as_float_array(quat, (4,), "quat_normalize", "quat")
    w, x, y, z = (qt[..., k : k + 1] for k in range(4))
    norm = np.sqrt(w * w + x * x + y * y + z * z)  # summed in MuJoCo's order
    tiny = norm < _QUAT_MIN_NORM
    unchanged = np.abs(norm - 1) <= _QUAT_MIN_NORM
    scaled = qt * (1 / np.where(tiny | unchanged, 1, norm))  # as MuJoCo: times 1/norm
    identity = np.array([1, 0, 0, 0], dtype=qt.dtype)
    return np.where(tiny, identity, scaled)


def quat_to_rotation(quat: ArrayLike) -> Array:
    """Rotation matrix of a unit quaternion ``[w, x, y, z]`` (MuJoCo's ``mju_quat2Mat`` formula).

    The quaternion is used as given; see :func:`quat_normalize`.
    Shapes: ``(..., 4) -> (..., 3, 3)``.
    """
    qt = _as_float_array(quat, (4,), "quat_to_rotation", "quat")
    w, x, y, z = (qt[..., k] for k in range(4))
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    wx, wy, wz, xy, xz, yz = w * x, w * y, w * z, x * y, x * z, y * z
    rows = [
        np.stack([ww + xx - yy - zz, 2 * (xy - wz), 2 * (xz + wy)], axis=-1),
        np.stack([2 * (xy + wz), ww - xx + yy - zz, 2 * (yz - wx)], axis=-1),
        np.stack([2 * (xz - wy), 2 * (yz + wx), ww - xx - yy + zz], axis=-1),
    ]
    return np.stack(rows, axis=-2)


def rotation_to_quat(R: ArrayLike) -> Array:
    """Unit quaternion ``[w, x, y, z]`` with ``w >= 0`` of a rotation matrix (Shepperd's method:
    the largest of ``w, x, y, z`` is taken from the diagonal, so no division is ill-conditioned).

    Inverse of :func:`quat_to_rotation` up to the sign of the quaternion.
    Shapes: ``(..., 3, 3) -> (..., 4)``.
    """
    M = _as_float_array(R, (3, 3), "rotation_to_quat", "R")
    d0, d1, d2 = M[..., 0, 0], M[..., 1, 1], M[..., 2, 2]
    a = M[..., 2, 1] - M[..., 1, 2]  # 4 w x
    b = M[..., 0, 2] - M[..., 2, 0]  # 4 w y
    c = M[..., 1, 0] - M[..., 0, 1]  # 4 w z
    xy = M[..., 0, 1] + M[..., 1, 0]  # 4 x y
    xz = M[..., 0, 2] + M[..., 2, 0]  # 4 x z
    yz = M[..., 1, 2] + M[..., 2, 1]  # 4 y z
    diag = np.stack([1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2], -1)
    big = np.sqrt(np.maximum(diag, 0.25)) * 2  # 4 * (the chosen component); >= 1 where chosen
    cases = np.stack(
        [
            np.stack([big[..., 0] / 4, a / big[..., 0], b / big[..., 0], c / big[..., 0]], -1),
            np.stack([a / big[..., 1], big[..., 1] / 4, xy / big[..., 1], xz / big[..., 1]], -1),
            np.stack([b / big[..., 2], xy / big[..., 2], big[..., 2] / 4, yz / big[..., 2]], -1),
            np.stack([c / big[..., 3], xz / big[..., 3], yz / big[..., 3], big[..., 3] / 4], -1),
        ],
        axis=-2,
    )
    k = np.argmax(diag, axis=-1)[..., None, None]
    quat = np.take_along_axis(cases, k, axis=-2)[..., 0, :]
    out: Array = np.where(quat[..., :1] < 0, -quat, quat)
    return out


def rotate(R: Array, v: Array) -> Array:
    """``R @ v`` for ``(..., 3, 3)`` and ``(..., 3)``, summed left to right.

    The FK reference path multiplies with this and :func:`rotate_compose` rather than ``@``,
    so its bits do not depend on the BLAS build, and the compiled kernel, which sums in the
    same order, can be held to it. No validation: for internal use on float arrays.
    """
    out: Array = (R[..., :, 0] * v[..., None, 0] + R[..., :, 1] * v[..., None, 1]) + R[
        ..., :, 2
    ] * v[..., None, 2]
    return out


def rotate_compose(A: Array, B: Array) -> Array:
    """``A @ B`` for ``(..., 3, 3)`` matrices, summed left to right (see :func:`rotate`)."""
    out: Array = (
        A[..., :, 0, None] * B[..., None, 0, :] + A[..., :, 1, None] * B[..., None, 1, :]
    ) + A[..., :, 2, None] * B[..., None, 2, :]
    return out


def coordinate_axis(axis: Array) -> tuple[int, float] | None:
    """``(k, sign)`` if ``axis (3,)`` lies along coordinate axis ``k``, else None.

    Along means its other two entries are exactly zero, as MuJoCo's ``0 0 1`` or a screw
    derived from it is. Rotations about such an axis are written with ``cos`` and ``sin``
    directly (:func:`axis_rotation`) and cost the compiled kernel a third of the flops.
    No validation: for internal use, like :func:`rotate`.
    """
    nonzero = np.flatnonzero(axis)
    if nonzero.size != 1:
        return None
    k = int(nonzero[0])
    return k, float(np.sign(axis[k]))


def axis_rotation(axis: Array, angle: Array) -> Array:
    """``(..., 3, 3)`` rotation by ``angle (...)`` about the unit ``axis (3,)``.

    About a coordinate axis ``k`` (see :func:`coordinate_axis`) the matrix holds ``cos`` and
    ``+-sin`` exactly; about any other axis it is Rodrigues' ``I + sin W + (1 - cos) W^2``.
    The FK reference paths build joint rotations with it; no validation.
    """
    along = coordinate_axis(axis)
    if along is None:
        W = hat_so3(axis)
        s = np.sin(angle)[..., None, None]
        c = (1.0 - np.cos(angle))[..., None, None]
        out: Array = (np.eye(3) + s * W) + c * rotate_compose(W, W)
        return out
    k, sign = along
    a, b = (k + 1) % 3, (k + 2) % 3
    s, c = sign * np.sin(angle), np.cos(angle)
    out = np.zeros((*np.shape(angle), 3, 3))
    out[..., k, k] = 1.0
    out[..., a, a] = c
    out[..., b, b] = c
    out[..., a, b] = -s
    out[..., b, a] = s
    return out


# --------------------------------------------------------------------------------------------
# lab-named wrappers (Modern Robotics style names)


def vec_to_so3(omega: ArrayLike) -> Array:
    """Alias of :func:`hat_so3`: ``(..., 3) -> (..., 3, 3)``."""
    return hat_so3(omega)


def vec_to_se3(twist: ArrayLike) -> Array:
    """Alias of :func:`hat_se3`: twist ``[w; v]`` ``(..., 6) -> (..., 4, 4)``."""
    return hat_se3(twist)


def matrix_exp_so3(omega_theta: ArrayLike) -> Array:
    """Alias of :func:`exp_so3` for the 3-vector ``omega * theta``: ``(..., 3) -> (..., 3, 3)``."""
    return exp_so3(omega_theta)


def matrix_exp_se3(twist: ArrayLike, theta: ArrayLike) -> Array:
    """``exp([S] theta)`` for a unit screw axis ``S = [w; v]`` and joint value ``theta``.

    Shapes: ``twist (..., 6)``, ``theta (...)`` broadcastable with ``twist[..., 0]``
    ``-> (..., 4, 4)``. A pure translation by ``v theta`` when ``w = 0``.
    """
    S = _as_float_array(twist, (6,), "matrix_exp_se3", "twist")
    q = np.asarray(theta)
    if q.dtype.kind not in "biuf":
        raise InputError(f"matrix_exp_se3: theta must be a real numeric array, got {q.dtype}")
    try:
        np.broadcast_shapes(S.shape[:-1], q.shape)
    except ValueError:
        raise InputError(
            f"matrix_exp_se3: expected theta broadcastable to shape {S.shape[:-1]}, "
            f"got shape {q.shape}"
        ) from None
    # a Python scalar theta must not promote a float32 twist (NEP 50 weak scalars)
    dtype = np.result_type(S, theta if isinstance(theta, (int, float)) else q)
    return exp_se3(S.astype(dtype, copy=False) * q.astype(dtype, copy=False)[..., None])
