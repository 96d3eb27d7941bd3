"""Pose paths between two poses, at path parameters ``s`` (0 at ``T0``, 1 at ``T1``).

* :func:`screw_path`: the screw motion ``T(s) = T0 exp(log(T0^-1 T1) s)`` (Modern Robotics
  9.2.2), the body frame turning about and sliding along one fixed screw axis;
* :func:`line_path`: the decoupled straight line, the origin on the segment ``p0 + s (p1 -
  p0)`` and the rotation ``R0 exp(log(R0^T R1) s)`` (slerp), as a UR's ``movel`` moves the tool.

Shapes: ``T0, T1 (..., 4, 4)`` and ``s (...)`` broadcast together; the result is
``(..., 4, 4)``. A rotation of exactly pi between ``T0`` and ``T1`` has two shortest ways round:
:func:`poekin.log_so3` picks one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.errors import InputError

__all__ = ["line_path", "screw_path"]

FloatArray = NDArray[np.float64]


def _inputs(T0: ArrayLike, T1: ArrayLike, s: ArrayLike, func: str) -> tuple[FloatArray, ...]:
    a = np.asarray(T0, dtype=np.float64)
    b = np.asarray(T1, dtype=np.float64)
    for name, arr in (("T0", a), ("T1", b)):
        if arr.shape[-2:] != (4, 4):
            raise InputError(f"{func}: {name} must be poses (..., 4, 4), got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"{func}: {name} has NaN or inf entries; give finite poses")
    u = np.asarray(s, dtype=np.float64)
    if not np.all(np.isfinite(u)):
        raise InputError(f"{func}: s has NaN or inf entries; give finite path parameters")
    try:
        shape = np.broadcast_shapes(a.shape[:-2], b.shape[:-2], u.shape)
    except ValueError:
        raise InputError(
            f"{func}: T0 {a.shape}, T1 {b.shape} and s {u.shape} do not broadcast together "
            "(poses (..., 4, 4), s (...))"
        ) from None
    return (
        np.broadcast_to(a, (*shape, 4, 4)),
        np.broadcast_to(b, (*shape, 4, 4)),
        np.broadcast_to(u, shape),
    )


def screw_path(T0: ArrayLike, T1: ArrayLike, s: ArrayLike) -> FloatArray:
    """The screw motion from ``T0`` to ``T1``: ``T0 exp(log(T0^-1 T1) s)``, ``(..., 4, 4)``.

    Raises:
        InputError: poses that are not ``(..., 4, 4)`` rigid transforms, NaN, or shapes that do
            not broadcast.
    """
    a, b, u = _inputs(T0, T1, s, "screw_path")
    xi = lie.log_se3(lie.inverse(a) @ b)
    out: FloatArray = a @ lie.exp_se3(xi * u[..., None])
    return out


def line_path(T0: ArrayLike, T1: ArrayLike, s: ArrayLike) -> FloatArray:
    """The straight line from ``T0`` to ``T1``: the origin ``p0 + s (p1 - p0)``, the rotation
    ``R0 exp(log(R0^T R1) s)``, ``(..., 4, 4)``.

    Raises:
        InputError: as :func:`screw_path`.
    """
    a, b, u = _inputs(T0, T1, s, "line_path")
    R0 = a[..., :3, :3]
    w = lie.log_so3(np.swapaxes(R0, -1, -2) @ b[..., :3, :3])
    R = R0 @ lie.exp_so3(w * u[..., None])
    p = a[..., :3, 3] + u[..., None] * (b[..., :3, 3] - a[..., :3, 3])
    out: FloatArray = np.asarray(lie.homogeneous(R, p), dtype=np.float64)
    return out
