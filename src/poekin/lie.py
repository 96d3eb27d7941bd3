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
  promoted to float64 (NumPy) or the library's default float. A wrong trailing shape raises
  :class:`~poekin.errors.InputError`.
* NumPy arrays, JAX arrays and PyTorch tensors are all taken, and the result is of the
  input's library, on its device (:mod:`poekin.arrays`): one implementation, written entry
  by entry (:mod:`poekin._pose`) with the library's array-API namespace. NumPy input is
  checked for NaN and inf; JAX and PyTorch input is not (no check on traced values).
* Everything is vectorised. Branches (small angle, near pi) are chosen element-wise with
  ``where`` and every division has a safe denominator, so a batch that mixes tiny,
  ordinary and near-pi angles is handled correctly and emits no floating-point warnings.
  Both sides of every ``where`` are finite and every norm has a finite gradient at zero, so
  ``jax.grad`` and PyTorch's autograd give finite derivatives everywhere, at the identity and
  exactly at pi included (where ``log`` jumps, so its derivative there is finite but no side's).

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

from poekin import _pose, arrays
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
    "rotation_to_rpy",
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
# log_so3 and log_se3 refuse a NumPy rotation block R with |R^T R - I| above this (float64;
# float32 gets the square root of its epsilon), as a hand-typed pose is good to ~1e-6.
_RIGID_TOL = 1e-6
# rotation_to_rpy: below this cos(pitch) the rotation counts as gimbal-locked (pitch +-pi/2).
_GIMBAL_LOCK = 1e-12


# --------------------------------------------------------------------------------------------
# input handling


def _as_float_array(x: ArrayLike, trailing: tuple[int, ...], func: str, name: str) -> Array:
    """``x`` as a floating array whose trailing shape is ``trailing``; else ``InputError``.

    NumPy (and anything NumPy converts) must be finite; a JAX array or PyTorch tensor stays
    one, cast to its library's default float if it holds integers, its values unchecked."""
    kind = arrays.kind_of(x)
    if kind is not None:
        xp = arrays.namespace(kind)
        try:
            dtype = arrays.float_dtype(xp, [x])
        except InputError:
            raise InputError(
                f"{func}: {name} must be a real numeric array, got dtype {x.dtype}"  # type: ignore[union-attr]
            ) from None
        arr: Any = arrays.convert(x, xp, dtype, x)
    else:
        arr = np.asarray(x)
        if arr.dtype.kind in "biu":
            arr = arr.astype(np.float64)
        elif arr.dtype.kind != "f":
            raise InputError(f"{func}: {name} must be a real numeric array, got dtype {arr.dtype}")
    k = len(trailing)
    shape = tuple(arr.shape)
    if len(shape) < k or shape[len(shape) - k :] != trailing:
        expected = "(..., " + ", ".join(str(n) for n in trailing) + ")"
        raise InputError(f"{func}: expected {name} of shape {expected}, got shape {shape}")
    if kind is None and not np.all(np.isfinite(arr)):
        raise InputError(f"{func}: {name} contains NaN or inf; every value must be finite")
    return arr  # type: ignore[no-any-return]


def _check_rigid(M: Any, func: str, name: str) -> None:
    """Raise :class:`InputError` unless every NumPy ``M`` (``(..., 3, 3)`` or ``(..., 4, 4)``)
    is a rotation, or a rigid transform ``[[R, p], [0, 0, 0, 1]]``: ``R^T R = I`` to
    ``_RIGID_TOL`` (or the square root of the dtype's epsilon, if larger), ``det R > 0``. JAX
    and PyTorch values are not checked (no check on traced values)."""
    if arrays.kind_of(M) is not None or M.size == 0:
        return
    tol = max(_RIGID_TOL, float(np.sqrt(np.finfo(M.dtype).eps)))
    R = M[..., :3, :3]
    off = np.max(np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)), axis=(-2, -1))
    flipped = np.linalg.det(R) <= 0
    bottom = np.zeros(off.shape)
    if M.shape[-1] == 4:
        bottom = np.max(np.abs(M[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])), axis=-1)
    bad = (off > tol) | flipped | (bottom > tol)
    if not np.any(bad):
        return
    first = tuple(int(i) for i in np.argwhere(bad)[0])
    at = f"{name}[{', '.join(map(str, first))}]" if first else name
    if off[first] > tol or flipped[first]:
        block = "its rotation block" if M.shape[-1] == 4 else "it"
        why = (
            f"{block} is not orthonormal with det +1 (max |R^T R - I| = "
            f"{float(off[first]):.3g}, det R = {float(np.linalg.det(R[first])):.3g})"
        )
    else:
        why = f"its last row is {M[first][3].tolist()}, not [0, 0, 0, 1]"
    what = "a rigid transform [[R, p], [0, 0, 0, 1]]" if M.shape[-1] == 4 else "a rotation"
    raise InputError(f"{func}: {at} is not {what}: {why}")


def _ns(a: Any) -> Any:
    """The namespace of an array that :func:`_as_float_array` returned."""
    kind = arrays.kind_of(a)
    return np if kind is None else arrays.namespace(kind)


def _vec(v: Any) -> _pose.Vec:
    return (v[..., 0], v[..., 1], v[..., 2])


def _mat(M: Any) -> _pose.Mat:
    return tuple(tuple(M[..., i, j] for j in range(3)) for i in range(3))  # type: ignore[return-value]


def _zeros(entry: Any, xp: Any) -> Any:
    """Zeros of an entry's shape, dtype and device."""
    return xp.zeros_like(entry)


def _vec_array(v: _pose.Vec, xp: Any, like: Any) -> Array:
    return _pose.stack(v, (3,), xp, like)  # type: ignore[no-any-return]


def _mat_array(R: _pose.Mat, xp: Any, like: Any) -> Array:
    return _pose.stack([e for row in R for e in row], (3, 3), xp, like)  # type: ignore[no-any-return]


def _atan2(xp: Any) -> Any:
    return getattr(xp, "atan2", None) or xp.arctan2


def _homogeneous(R: _pose.Mat, p: _pose.Vec, xp: Any, like: Any) -> Array:
    """Poses ``[[R, p], [0, 1]]`` ``(..., 4, 4)`` from entries."""
    return _pose.to_array((R, p), "4x4", xp, like)  # type: ignore[no-any-return]


def homogeneous(R: ArrayLike, p: ArrayLike) -> Array:
    """Poses ``[[R, p], [0, 1]]``: ``R (..., 3, 3)``, ``p (..., 3) -> (..., 4, 4)``."""
    M = _as_float_array(R, (3, 3), "homogeneous", "R")
    v = _as_float_array(p, (3,), "homogeneous", "p")
    xp, _ = arrays.namespace_of([M, v], "homogeneous: R and p")
    if xp is not np:
        dtype = arrays.float_dtype(xp, [M, v])
        anchor = M if arrays.kind_of(M) else v
        M, v = arrays.convert(M, xp, dtype, anchor), arrays.convert(v, xp, dtype, anchor)
    else:
        dtype = np.result_type(M, v)
        M, v = M.astype(dtype, copy=False), v.astype(dtype, copy=False)
    return _homogeneous(_mat(M), _vec(v), xp, _zeros(M[..., 0, 0], xp))


# --------------------------------------------------------------------------------------------
# scalar coefficients (element-wise over t >= 0)


def _sin_over_t(t: Any, xp: Any = np) -> Any:
    """``sin(t)/t``."""
    small = t < _SMALL_ANGLE
    t2 = t * t
    series = 1 - t2 / 6 * (1 - t2 / 20)
    return xp.where(small, series, xp.sin(t) / xp.where(small, 1.0, t))


def _one_minus_cos_over_t2(t: Any, xp: Any = np) -> Any:
    """``(1 - cos t)/t^2``, computed as ``0.5 (sin(t/2)/(t/2))^2`` (no cancellation)."""
    half = _sin_over_t(t / 2, xp)
    return half * half / 2


def _t_minus_sin_over_t3(t: Any, xp: Any = np) -> Any:
    """``(t - sin t)/t^3``."""
    small = t < _SERIES_ANGLE
    t2 = t * t
    series = 1 / 6 - t2 / 120 * (1 - t2 / 42 * (1 - t2 / 72 * (1 - t2 / 110)))
    safe_t = xp.where(small, 1.0, t)
    return xp.where(small, series, (safe_t - xp.sin(safe_t)) / safe_t**3)


def _inverse_v_coefficient(t: Any, xp: Any = np) -> Any:
    """``(1 - (t/2) cot(t/2))/t^2``: the ``W^2`` coefficient of ``V^{-1}``; 1/pi^2 at t = pi."""
    small = t < _SERIES_ANGLE
    t2 = t * t
    # 1/12 + t^2/720 + t^4/30240 + t^6/1209600 + t^8/47900160 + 691 t^10/1307674368000
    series = 1 / 12 + t2 * (
        1 / 720
        + t2 * (1 / 30240 + t2 * (1 / 1209600 + t2 * (1 / 47900160 + t2 * 691 / 1307674368000)))
    )
    safe_t = xp.where(small, 1.0, t)
    half = safe_t / 2
    direct = (1 - half * xp.cos(half) / xp.sin(half)) / (safe_t * safe_t)
    return xp.where(small, series, direct)


def _t_over_sin_t(t: Any, sin_t: Any, xp: Any = np) -> Any:
    """``t/sin(t)`` given both ``t`` and (a computed) ``sin t``; Taylor series near 0."""
    small = t < _SMALL_ANGLE
    t2 = t * t
    series = 1 + t2 / 6 * (1 + t2 * 7 / 60)
    # sin t is exactly 0 at t = pi; log_so3 takes the symmetric-part branch there.
    return xp.where(small, series, t / xp.where(small | (sin_t == 0), 1.0, sin_t))


def _scaled(M: _pose.Mat, a: Any) -> _pose.Mat:
    return tuple(tuple(a * e for e in row) for row in M)  # type: ignore[return-value]


def _plus(A: _pose.Mat, B: _pose.Mat) -> _pose.Mat:
    return tuple(
        tuple(x + y for x, y in zip(ra, rb, strict=True)) for ra, rb in zip(A, B, strict=True)
    )  # type: ignore[return-value]


# --------------------------------------------------------------------------------------------
# hat / vee


def hat_so3(omega: ArrayLike) -> Array:
    """Skew-symmetric matrix ``[omega]`` with ``[omega] x = omega x x``.

    Shapes: ``omega (..., 3) -> (..., 3, 3)``.
    """
    w = _as_float_array(omega, (3,), "hat_so3", "omega")
    xp = _ns(w)
    return _mat_array(_pose.hat(_vec(w)), xp, _zeros(w[..., 0], xp))


def _vee(M: _pose.Mat) -> _pose.Vec:
    return ((M[2][1] - M[1][2]) / 2, (M[0][2] - M[2][0]) / 2, (M[1][0] - M[0][1]) / 2)


def vee_so3(Omega: ArrayLike) -> Array:
    """Vector of the antisymmetric part ``(Omega - Omega^T)/2``; inverse of :func:`hat_so3`.

    Shapes: ``Omega (..., 3, 3) -> (..., 3)``. Exact for exactly skew-symmetric input.
    """
    M = _as_float_array(Omega, (3, 3), "vee_so3", "Omega")
    xp = _ns(M)
    return _vec_array(_vee(_mat(M)), xp, _zeros(M[..., 0, 0], xp))


def hat_se3(xi: ArrayLike) -> Array:
    """``4 x 4`` matrix ``[[hat(w), v], [0, 0]]`` of the twist ``xi = [w; v]``.

    Shapes: ``xi (..., 6) -> (..., 4, 4)``.
    """
    x = _as_float_array(xi, (6,), "hat_se3", "xi")
    xp = _ns(x)
    W = _pose.hat((x[..., 0], x[..., 1], x[..., 2]))
    entries = [e for i in range(3) for e in (*W[i], x[..., 3 + i])] + [0.0] * 4
    return _pose.stack(entries, (4, 4), xp, _zeros(x[..., 0], xp))  # type: ignore[no-any-return]


def vee_se3(Xi: ArrayLike) -> Array:
    """Twist ``[w; v]`` of ``Xi = [[hat(w), v], [0, 0]]``; inverse of :func:`hat_se3`.

    Shapes: ``Xi (..., 4, 4) -> (..., 6)``. ``w`` is read from the antisymmetric part of
    the upper-left block, the bottom row is ignored.
    """
    M = _as_float_array(Xi, (4, 4), "vee_se3", "Xi")
    xp = _ns(M)
    entries = [*_vee(_mat(M[..., :3, :3])), M[..., 0, 3], M[..., 1, 3], M[..., 2, 3]]
    return _pose.stack(entries, (6,), xp, _zeros(M[..., 0, 0], xp))  # type: ignore[no-any-return]


# --------------------------------------------------------------------------------------------
# SO(3)


def _exp_so3(w: _pose.Vec, xp: Any) -> tuple[_pose.Mat, Any, _pose.Mat, _pose.Mat]:
    """Rodrigues' ``R``, with ``t = |w|``, ``W`` and ``W^2`` for :func:`exp_se3`."""
    t = _pose.norm(w, xp)
    W = _pose.hat(w)
    W2 = _pose.mat_mat(W, W)
    R = _plus(
        _plus(_pose.IDENTITY, _scaled(W, _sin_over_t(t, xp))),
        _scaled(W2, _one_minus_cos_over_t2(t, xp)),
    )
    return R, t, W, W2


def exp_so3(omega: ArrayLike) -> Array:
    """Rotation ``exp([omega])`` by Rodrigues' formula.

    ``R = I + sin(t)/t W + (1 - cos t)/t^2 W^2`` with ``W = hat(omega)``, ``t = |omega|``.
    Shapes: ``omega (..., 3) -> (..., 3, 3)``.
    """
    w = _as_float_array(omega, (3,), "exp_so3", "omega")
    xp = _ns(w)
    return _mat_array(_exp_so3(_vec(w), xp)[0], xp, _zeros(w[..., 0], xp))


def _trace(M: _pose.Mat) -> Any:
    return M[0][0] + M[1][1] + M[2][2]


def rotation_angle(R: ArrayLike) -> Array:
    """Geodesic angle of a rotation, in ``[0, pi]``.

    ``atan2(|vee(R - R^T)|/2, (tr R - 1)/2)``: accurate near 0 and near pi. The orientation
    error between ``R_a`` and ``R_b`` is ``rotation_angle(R_a @ R_b^T)``.
    Shapes: ``R (..., 3, 3) -> (...)``.
    """
    M = _as_float_array(R, (3, 3), "rotation_angle", "R")
    xp = _ns(M)
    entries = _mat(M)
    sin_t = _pose.norm(_vee(entries), xp)
    cos_t = (_trace(entries) - 1) / 2
    angle: Array = _atan2(xp)(sin_t, cos_t)
    return angle


def _log_so3(M: _pose.Mat, xp: Any) -> _pose.Vec:
    u = _vee(M)  # sin(t) a
    sin_t = _pose.norm(u, xp)
    cos_t = (_trace(M) - 1) / 2
    t = _atan2(xp)(sin_t, cos_t)

    # ordinary and small angles: omega = (t / sin t) u
    coefficient = _t_over_sin_t(t, sin_t, xp)
    from_antisymmetric = tuple(coefficient * e for e in u)

    # large angles: axis from the symmetric part, its column with the largest diagonal entry
    B = tuple(
        tuple((M[i][j] + M[j][i]) / 2 - (cos_t if i == j else 0.0) for j in range(3))
        for i in range(3)
    )
    d = (B[0][0], B[1][1], B[2][2])
    first = ((d[0] >= d[1]) & (d[0] >= d[2]), (d[1] > d[0]) & (d[1] >= d[2]))
    column = tuple(
        xp.where(first[0], B[i][0], xp.where(first[1], B[i][1], B[i][2])) for i in range(3)
    )
    length = _pose.norm(column, xp)
    safe = xp.where(length > 0, length, 1.0)
    axis = tuple(e / safe for e in column)
    dot = (axis[0] * u[0] + axis[1] * u[1]) + axis[2] * u[2]
    signed_t = xp.where(dot < 0, -t, t)
    from_symmetric = tuple(signed_t * e for e in axis)

    large = cos_t < 0
    return tuple(
        xp.where(large, s, a) for s, a in zip(from_symmetric, from_antisymmetric, strict=True)
    )  # type: ignore[return-value]


def log_so3(R: ArrayLike) -> Array:
    """Exponential coordinates ``omega = t a`` of a rotation, with ``t`` in ``[0, pi]``.

    Inverse of :func:`exp_so3`. The angle is ``atan2(sin t, cos t)`` from the antisymmetric
    part and the trace. For ``cos t >= 0`` the axis is ``vee(R)/sin t``; for ``cos t < 0``
    it is the column of ``B = (R + R^T)/2 - cos(t) I = (1 - cos t) a a^T`` with the largest
    diagonal entry, normalised, with its sign matched to ``vee(R)`` (any sign at exactly
    pi). Shapes: ``R (..., 3, 3) -> (..., 3)``.

    Raises:
        InputError: a NumPy ``R`` that is not a rotation (orthonormal to 1e-6, det +1).
    """
    M = _as_float_array(R, (3, 3), "log_so3", "R")
    _check_rigid(M, "log_so3", "R")
    xp = _ns(M)
    return _vec_array(_log_so3(_mat(M), xp), xp, _zeros(M[..., 0, 0], xp))


# --------------------------------------------------------------------------------------------
# SE(3)


def exp_se3(xi: ArrayLike) -> Array:
    """Pose ``exp([xi])`` of the exponential coordinates ``xi = [w; v]``.

    ``[[exp(W), V v], [0, 1]]`` with ``V = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2``,
    ``W = hat(w)``, ``t = |w|``; a pure translation by ``v`` when ``w = 0``.
    Shapes: ``xi (..., 6) -> (..., 4, 4)``.
    """
    x = _as_float_array(xi, (6,), "exp_se3", "xi")
    xp = _ns(x)
    w, v = (x[..., 0], x[..., 1], x[..., 2]), (x[..., 3], x[..., 4], x[..., 5])
    R, t, W, W2 = _exp_so3(w, xp)
    b = _one_minus_cos_over_t2(t, xp)
    V = _plus(_plus(_pose.IDENTITY, _scaled(W, b)), _scaled(W2, _t_minus_sin_over_t3(t, xp)))
    return _homogeneous(R, _pose.mat_vec(V, v), xp, _zeros(x[..., 0], xp))


def log_se3(T: ArrayLike) -> Array:
    """Exponential coordinates ``[w; v]`` of a pose; inverse of :func:`exp_se3`.

    ``w = log_so3(R)`` and ``v = V^{-1} p`` with
    ``V^{-1} = I - W/2 + (1 - (t/2) cot(t/2))/t^2 W^2``, ``t = |w|`` in ``[0, pi]``.
    Shapes: ``T (..., 4, 4) -> (..., 6)``.

    Raises:
        InputError: a NumPy ``T`` that is not a rigid transform: its rotation block not
            orthonormal to 1e-6 with det +1, or its last row not ``[0, 0, 0, 1]``.
    """
    M = _as_float_array(T, (4, 4), "log_se3", "T")
    _check_rigid(M, "log_se3", "T")
    xp = _ns(M)
    w = _log_so3(_mat(M[..., :3, :3]), xp)
    t = _pose.norm(w, xp)
    W = _pose.hat(w)
    V_inv = _plus(
        _plus(_pose.IDENTITY, _scaled(W, -0.5)),
        _scaled(_pose.mat_mat(W, W), _inverse_v_coefficient(t, xp)),
    )
    v = _pose.mat_vec(V_inv, (M[..., 0, 3], M[..., 1, 3], M[..., 2, 3]))
    return _pose.stack([*w, *v], (6,), xp, _zeros(M[..., 0, 0], xp))  # type: ignore[no-any-return]


def adjoint(T: ArrayLike) -> Array:
    """Adjoint ``[[R, 0], [hat(p) R, R]]`` of a pose, acting on twists ``[w; v]``.

    ``T exp(xi) T^{-1} = exp(Ad(T) xi)``. Shapes: ``T (..., 4, 4) -> (..., 6, 6)``.
    """
    M = _as_float_array(T, (4, 4), "adjoint", "T")
    xp = _ns(M)
    R = _mat(M[..., :3, :3])
    pR = _pose.mat_mat(_pose.hat((M[..., 0, 3], M[..., 1, 3], M[..., 2, 3])), R)
    rows = [(*R[i], 0.0, 0.0, 0.0) for i in range(3)] + [(*pR[i], *R[i]) for i in range(3)]
    return _pose.stack([e for row in rows for e in row], (6, 6), xp, _zeros(M[..., 0, 0], xp))  # type: ignore[no-any-return]


def inverse(T: ArrayLike) -> Array:
    """Inverse ``[[R^T, -R^T p], [0, 1]]`` of a pose. Shapes: ``T (..., 4, 4) -> (..., 4, 4)``."""
    M = _as_float_array(T, (4, 4), "inverse", "T")
    xp = _ns(M)
    R_t = _pose.transpose(_mat(M[..., :3, :3]))
    p = _pose.mat_vec(R_t, (M[..., 0, 3], M[..., 1, 3], M[..., 2, 3]))
    return _homogeneous(R_t, (-p[0], -p[1], -p[2]), xp, _zeros(M[..., 0, 0], xp))


# --------------------------------------------------------------------------------------------
# unit quaternions, wxyz (MuJoCo's order)


def _quat(q: Any) -> tuple[Any, Any, Any, Any]:
    return (q[..., 0], q[..., 1], q[..., 2], q[..., 3])


def quat_normalize(quat: ArrayLike) -> Array:
    """Quaternions ``wxyz`` scaled to unit length, exactly as MuJoCo's ``mju_normalize4``.

    A quaternion whose norm is below ``1e-15`` (zero included) becomes the identity
    ``[1, 0, 0, 0]``; one whose norm is within ``1e-15`` of 1 is returned unchanged. This is how
    MuJoCo reads a ball or free joint's ``qpos``, so an unnormalised quaternion means the same
    rotation in poekin and in ``mj_forward``. Shapes: ``(..., 4) -> (..., 4)``.
    """
    qt = _as_float_array(quat, (4,), "quat_normalize", "quat")
    xp = _ns(qt)
    unit = _pose.quat_normalize(_quat(qt), xp)
    return _pose.stack(unit, (4,), xp, _zeros(qt[..., 0], xp))  # type: ignore[no-any-return]


def quat_to_rotation(quat: ArrayLike) -> Array:
    """Rotation matrix of a unit quaternion ``[w, x, y, z]`` (MuJoCo's ``mju_quat2Mat`` formula).

    The quaternion is used as given; see :func:`quat_normalize`.
    Shapes: ``(..., 4) -> (..., 3, 3)``.
    """
    qt = _as_float_array(quat, (4,), "quat_to_rotation", "quat")
    xp = _ns(qt)
    return _mat_array(_pose.quat_matrix(_quat(qt)), xp, _zeros(qt[..., 0], xp))


def rotation_to_quat(R: ArrayLike) -> Array:
    """Unit quaternion ``[w, x, y, z]`` with ``w >= 0`` of a rotation matrix (Shepperd's method:
    the largest of ``w, x, y, z`` is taken from the diagonal, so no division is ill-conditioned).

    Inverse of :func:`quat_to_rotation` up to the sign of the quaternion.
    Shapes: ``(..., 3, 3) -> (..., 4)``.
    """
    M = _as_float_array(R, (3, 3), "rotation_to_quat", "R")
    xp = _ns(M)
    quat = _pose.rotation_quat(_mat(M), xp)
    return _pose.stack(quat, (4,), xp, _zeros(M[..., 0, 0], xp))  # type: ignore[no-any-return]


def rotation_to_rpy(R: ArrayLike) -> Array:
    """Roll, pitch, yaw ``[r, p, y]`` (rad) of a rotation in URDF's and ROS's fixed-axis
    convention: ``R = Rz(yaw) Ry(pitch) Rx(roll)``, i.e. turned by roll about the fixed x axis,
    then by pitch about the fixed y axis, then by yaw about the fixed z axis (SciPy's extrinsic
    ``Rotation.as_euler("xyz")``). Pitch is in ``[-pi/2, pi/2]``, roll and yaw in ``[-pi, pi]``.
    At pitch ``+-pi/2`` (gimbal lock: only ``yaw - roll`` or ``yaw + roll`` is defined) roll is
    0 and yaw takes the rest. Shapes: ``(..., 3, 3) -> (..., 3)``.
    """
    M = _as_float_array(R, (3, 3), "rotation_to_rpy", "R")
    xp = _ns(M)
    E = _mat(M)
    atan2 = _atan2(xp)
    cos_pitch = _pose.norm((E[0][0], E[1][0]), xp)
    locked = cos_pitch < _GIMBAL_LOCK
    pitch = atan2(-E[2][0], cos_pitch)
    roll = xp.where(locked, 0.0, atan2(E[2][1], E[2][2]))
    yaw = xp.where(locked, atan2(-E[0][1], E[1][1]), atan2(E[1][0], E[0][0]))
    return _vec_array((roll, pitch, yaw), xp, _zeros(M[..., 0, 0], xp))


def rotate(R: Array, v: Array) -> Array:
    """``R @ v`` for ``(..., 3, 3)`` and ``(..., 3)``, summed left to right.

    The FK reference path multiplies with :mod:`poekin._pose`'s ``mat_vec`` and ``mat_mat``
    rather than ``@``, so its bits do not depend on the BLAS build, and the compiled kernel,
    which sums in the same order, can be held to it. No validation: for internal use on float
    arrays.
    """
    xp = _ns(R)
    Rv = _pose.mat_vec(_mat(R), _vec(v))
    return _vec_array(Rv, xp, _zeros(Rv[0], xp))


def rotate_compose(A: Array, B: Array) -> Array:
    """``A @ B`` for ``(..., 3, 3)`` matrices, summed left to right (see :func:`rotate`)."""
    xp = _ns(A)
    AB = _pose.mat_mat(_mat(A), _mat(B))
    return _mat_array(AB, xp, _zeros(AB[0][0], xp))


def coordinate_axis(axis: Array) -> tuple[int, float] | None:
    """``(k, sign)`` if ``axis (3,)`` lies along coordinate axis ``k``, else None.

    Along means its other two entries are exactly zero, as MuJoCo's ``0 0 1`` or a screw
    derived from it is. Rotations about such an axis are written with ``cos`` and ``sin``
    directly (:func:`axis_rotation`) and cost the compiled kernel a third of the flops.
    No validation: for internal use, like :func:`rotate`; NumPy constants only.
    """
    nonzero = np.flatnonzero(axis)
    if nonzero.size != 1:
        return None
    k = int(nonzero[0])
    return k, float(np.sign(axis[k]))


def axis_rotation(axis: Array, angle: Array) -> Array:
    """``(..., 3, 3)`` rotation by ``angle (...)`` about the unit ``axis (3,)`` (a NumPy
    constant; ``angle`` of any library).

    About a coordinate axis ``k`` (see :func:`coordinate_axis`) the matrix holds ``cos`` and
    ``+-sin`` exactly; about any other axis it is Rodrigues' ``I + sin W + (1 - cos) W^2``.
    No validation.
    """
    xp = _ns(angle)
    th = angle if xp is not np else np.asarray(angle, dtype=np.float64)
    along = coordinate_axis(axis)
    if along is None:
        W = _pose.hat(tuple(float(x) for x in axis))
        R = _pose.rodrigues(W, _pose.mat_mat(W, W), xp.sin(th), 1.0 - xp.cos(th))
    else:
        k, sign = along
        a, b = (k + 1) % 3, (k + 2) % 3
        s, c = sign * xp.sin(th), xp.cos(th)
        rows: list[list[Any]] = [[0.0] * 3 for _ in range(3)]
        rows[k][k] = 1.0
        rows[a][a], rows[b][b], rows[a][b], rows[b][a] = c, c, -s, s
        R = tuple(tuple(row) for row in rows)  # type: ignore[assignment]
    return _mat_array(R, xp, _zeros(th, xp))


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
    xp, kind = arrays.namespace_of([S, theta], "matrix_exp_se3: twist and theta")
    if kind is None:
        q = np.asarray(theta)
        if q.dtype.kind not in "biuf":
            raise InputError(f"matrix_exp_se3: theta must be a real numeric array, got {q.dtype}")
        # a Python scalar theta must not promote a float32 twist (NEP 50 weak scalars)
        dtype = np.result_type(S, theta if isinstance(theta, (int, float)) else q)
        S, q = S.astype(dtype, copy=False), q.astype(dtype, copy=False)
    else:
        anchor = S if arrays.kind_of(S) else theta
        weak = isinstance(theta, (int, float))
        dtype = arrays.float_dtype(xp, [S] if weak else [S, theta])
        S = arrays.convert(S, xp, dtype, anchor)
        q = arrays.convert(theta, xp, dtype, anchor)
    try:
        np.broadcast_shapes(tuple(S.shape[:-1]), tuple(q.shape))
    except ValueError:
        raise InputError(
            f"matrix_exp_se3: expected theta broadcastable to shape {tuple(S.shape[:-1])}, "
            f"got shape {tuple(q.shape)}"
        ) from None
    return exp_se3(S * q[..., None])
