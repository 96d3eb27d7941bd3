"""Pose paths between two poses, at path parameters ``s`` (0 at ``T0``, 1 at ``T1``).

* :func:`screw_path`: the screw motion ``T(s) = T0 exp(log(T0^-1 T1) s)`` (Modern Robotics
  9.2.2), the body frame turning about and sliding along one fixed screw axis;
* :func:`line_path`: the decoupled straight line, the origin on the segment ``p0 + s (p1 -
  p0)`` and the rotation ``R0 exp(log(R0^T R1) s)`` (slerp), as a UR's ``movel`` moves the tool.

and their velocities: :func:`screw_path_twist` and :func:`line_path_twist` give the twist per
unit of ``s``, ``V_s = dT/ds`` as a twist ``[w; v]``, and its derivative ``V_ss = dV_s/ds``, in
the body frame (``T^-1 dT/ds``, the default) or the space frame (``dT/ds T^-1``). Under a time
scaling ``s(t)`` (:func:`poekin.motion.scaling`) the twist and its rate of change in that frame
are ``V = V_s sd`` and ``Vdot = V_s sdd + V_ss sd^2``.

Along the screw path both twists are constant (``V_ss = 0``); along the line the angular part
is constant and the linear part turns with the body (body frame) or with the lever arm to the
moving origin (space frame). The origin's own velocity, ``dp/ds = p1 - p0`` on the line, is
``R v`` of the body twist.

Shapes: ``T0, T1 (..., 4, 4)`` and ``s (...)`` broadcast together; poses come out
``(..., 4, 4)``, twists ``(..., 6)``. A rotation of exactly pi between ``T0`` and ``T1`` has two
shortest ways round: :func:`poekin.log_so3` picks one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.errors import InputError, did_you_mean

__all__ = ["FRAMES", "line_path", "line_path_twist", "screw_path", "screw_path_twist"]

FloatArray = NDArray[np.float64]

FRAMES = ("body", "space")  # the frames a path's twists are given in


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


def _frame(frame: object, func: str) -> str:
    if frame not in FRAMES:
        raise InputError(
            f"{func}: unknown frame {frame!r} for the twists; {did_you_mean(str(frame), FRAMES)}"
        )
    return str(frame)


def screw_path_twist(
    T0: ArrayLike, T1: ArrayLike, s: ArrayLike, *, frame: str = "body"
) -> tuple[FloatArray, FloatArray]:
    """The twist of :func:`screw_path` per unit of ``s``, and its derivative in ``s``.

    Both are constant along a screw motion: the body twist is ``log(T0^-1 T1)``, the space twist
    ``Ad(T0) log(T0^-1 T1)``, and ``V_ss = 0``.

    Args:
        T0: start poses ``(..., 4, 4)``.
        T1: end poses ``(..., 4, 4)``.
        s: path parameters ``(...)``.
        frame: ``"body"`` (``T^-1 dT/ds``) or ``"space"`` (``dT/ds T^-1``).

    Returns:
        ``(V_s, V_ss)``, twists ``[w; v]`` ``(..., 6)`` each (rad and m per unit of ``s``).

    Raises:
        InputError: as :func:`screw_path`, or an unknown frame.
    """
    func = "screw_path_twist"
    which = _frame(frame, func)
    a, b, u = _inputs(T0, T1, s, func)
    xi = lie.log_se3(lie.inverse(a) @ b)
    if which == "space":
        xi = (lie.adjoint(a) @ xi[..., None])[..., 0]
    V: FloatArray = np.array(np.broadcast_to(xi, (*u.shape, 6)), dtype=np.float64)
    return V, np.zeros_like(V)


def line_path_twist(
    T0: ArrayLike, T1: ArrayLike, s: ArrayLike, *, frame: str = "body"
) -> tuple[FloatArray, FloatArray]:
    """The twist of :func:`line_path` per unit of ``s``, and its derivative in ``s``.

    With ``w = log(R0^T R1)``, ``dp = p1 - p0`` and the pose ``(R, p)`` at ``s``: the body twist
    is ``[w; R^T dp]``, its derivative ``[0; -w x R^T dp]``; the space twist is ``[R0 w;
    dp - R0 w x p]``, its derivative ``[0; -R0 w x dp]``.

    Args:
        T0: start poses ``(..., 4, 4)``.
        T1: end poses ``(..., 4, 4)``.
        s: path parameters ``(...)``.
        frame: ``"body"`` (``T^-1 dT/ds``) or ``"space"`` (``dT/ds T^-1``).

    Returns:
        ``(V_s, V_ss)``, twists ``[w; v]`` ``(..., 6)`` each (rad and m per unit of ``s``).

    Raises:
        InputError: as :func:`screw_path`, or an unknown frame.
    """
    func = "line_path_twist"
    which = _frame(frame, func)
    a, b, u = _inputs(T0, T1, s, func)
    R0 = a[..., :3, :3]
    w = lie.log_so3(np.swapaxes(R0, -1, -2) @ b[..., :3, :3])
    dp = b[..., :3, 3] - a[..., :3, 3]
    if which == "body":
        R = R0 @ lie.exp_so3(w * u[..., None])
        v = (np.swapaxes(R, -1, -2) @ dp[..., None])[..., 0]
        dv = -np.cross(w, v)
    else:
        w = (R0 @ w[..., None])[..., 0]
        p = a[..., :3, 3] + u[..., None] * dp
        v = dp - np.cross(w, p)
        dv = -np.cross(w, dp)
    V: FloatArray = np.concatenate([w, v], axis=-1, dtype=np.float64)
    dV: FloatArray = np.concatenate([np.zeros_like(w), dv], axis=-1, dtype=np.float64)
    return V, dV
