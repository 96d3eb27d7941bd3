"""Time-optimal path parameterisation by reachability analysis (TOPP-RA; Pham and Pham, "A New
Approach to Time-Optimal Path Parameterization Based on Reachability Analysis", IEEE T-RO
2018) under per-joint velocity and acceleration limits, in NumPy.

A path ``q(s)``, ``s`` on a grid ``s_0 < ... < s_M``; the unknowns are ``x_i = sd_i^2`` and a
constant ``u_i = sdd`` on each stage, ``x_{i+1} = x_i + 2 D_i u_i`` (``D_i = s_{i+1} - s_i``).
The joint acceleration is ``q'(s) u + q''(s) x``, constrained at both ends of each stage (toppra's
"interpolation" discretisation), the velocity ``q'(s) sd`` at each grid point.

Every constraint of a stage is ``p u + q x <= r`` with ``r >= 0`` (rest, ``u = x = 0``, is
feasible), so a stage's 2-D linear programme is solved in closed form: eliminating ``u``
(Fourier-Motzkin) turns each pair of a lower and an upper bound on ``u`` into one bound on
``x``. The stage-only pairs are computed for all stages at once; the pairs with the next
stage's set, ``x + 2 D u <= K_{i+1}``, leave each step of the backward pass (controllable sets
``[0, K_i]``) and of the greedy forward pass a minimum of affine functions of one number.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["peaks", "solve"]

FloatArray = NDArray[np.float64]

_FLAT = 1e-12  # |p| below this (relative to the stage's largest) bounds x only, not u


def _bounds_on_u(
    dq: FloatArray, ddq: FloatArray, acc: FloatArray, D: FloatArray
) -> tuple[tuple[FloatArray, FloatArray, FloatArray], tuple[FloatArray, FloatArray, FloatArray]]:
    """Stage ``i``'s constraints ``p u + q x <= r``, ``(M, m)`` each: the lower bounds on ``u``
    (``p <= 0``; the acceleration at ``s_i`` and at ``s_{i+1}``, one side each, and ``x_{i+1}
    >= 0``) and the upper bounds (``p >= 0``; the other sides). ``p = 0`` (``q'`` flat) bounds
    ``x`` alone."""
    M = len(D)
    d2 = (2.0 * D)[:, None]
    p = np.concatenate([dq[:-1], dq[1:] + d2 * ddq[1:]], axis=1)
    q = np.concatenate([ddq[:-1], ddq[1:]], axis=1)
    p = np.where(np.abs(p) <= _FLAT * np.max(np.abs(p), axis=1, keepdims=True), 0.0, p)
    sign = np.where(p < 0.0, -1.0, 1.0)
    p, q = np.abs(p), q * sign
    r = np.broadcast_to(np.concatenate([acc, acc]), p.shape)
    lower = (
        np.concatenate([-p, -d2], axis=1),
        np.concatenate([-q, -np.ones((M, 1))], axis=1),
        np.concatenate([r, np.zeros((M, 1))], axis=1),
    )
    return lower, (p, q, r)


def solve(
    s: FloatArray, dq: FloatArray, ddq: FloatArray, vel: FloatArray, acc: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The time-optimal ``x = sd^2`` at the grid points and ``u = sdd`` on the stages, at rest
    at both ends.

    Args:
        s: ``(M + 1,)`` the grid, increasing.
        dq, ddq: ``(M + 1, n)`` ``q'(s)`` and ``q''(s)`` at the grid points.
        vel, acc: ``(n,)`` the limits, > 0 (``inf`` in ``vel``: none).

    Returns:
        ``x (M + 1,)`` (0 at both ends) and ``u (M,)``.
    """
    D = np.diff(s)
    M = len(D)
    with np.errstate(divide="ignore"):
        xv = np.min((vel / np.abs(dq)) ** 2, axis=1)  # inf where q' = 0 or no limit
    (Pk, Qk, Rk), (Pl, Ql, Rl) = _bounds_on_u(dq, ddq, acc, D)
    # each pair (lower k, upper l): (Q_k P_l - Q_l P_k) x <= R_k P_l - R_l P_k
    E = Qk[:, :, None] * Pl[:, None, :] - Ql[:, None, :] * Pk[:, :, None]
    F = Rk[:, :, None] * Pl[:, None, :] - Rl[:, None, :] * Pk[:, :, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = F / E
        ratio[~(E > 0.0)] = np.inf
        bound = ratio.reshape(M, -1).min(axis=1)
        only_x = (Pl == 0.0) & (Ql != 0.0)  # |q x| <= r
        bound = np.minimum(bound, np.where(only_x, Rl / np.abs(Ql), np.inf).min(axis=1))
    xhi = np.minimum(xv[:-1], bound)
    d2 = (2.0 * D)[:, None]
    # a lower bound k with x + 2 D u <= K': (2 D Q_k - P_k) x <= 2 D R_k - P_k K'
    Dk = d2 * Qk - Pk
    use = Dk > 0.0
    safe = np.where(use, Dk, 1.0)
    A = np.where(use, -Pk / safe, 0.0)
    B = np.where(use, d2 * Rk / safe, np.inf)
    # an upper bound l on u at x: x + 2 D u <= x (1 - 2 D Q_l / P_l) + 2 D R_l / P_l
    up = Pl > 0.0
    safe = np.where(up, Pl, 1.0)
    G = np.where(up, 1.0 - d2 * Ql / safe, 0.0)
    H = np.where(up, d2 * Rl / safe, np.inf)

    # the two passes, one stage after the other, in Python floats (faster than NumPy on a
    # dozen numbers a stage)
    K = [0.0] * (M + 1)  # at rest at the end
    k = 0.0
    for i, a_i, b_i, hi in zip(
        range(M - 1, 0, -1), A[:0:-1].tolist(), B[:0:-1].tolist(), xhi[:0:-1].tolist(), strict=True
    ):
        k = min(hi, *[a * k + b for a, b in zip(a_i, b_i, strict=True)])
        K[i] = k
    x = [0.0] * (M + 1)  # at rest at the start
    xi = 0.0
    for i, g_i, h_i in zip(range(1, M), G[:-1].tolist(), H[:-1].tolist(), strict=True):
        xi = max(0.0, min(K[i], *[g * xi + h for g, h in zip(g_i, h_i, strict=True)]))
        x[i] = xi
    xs = np.array(x)
    return xs, np.diff(xs) / (2.0 * D)


def peaks(
    D: FloatArray,
    x: FloatArray,
    u: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    dddq: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Each joint's largest ``|qd|`` and ``|qdd|`` over the whole continuous motion, not only
    at the grid points.

    On stage ``i`` (inside one spline interval, so that ``q'''`` is constant there) with ``d = s
    - s_i``: ``x = x_i + 2 u d``, and ``qdd = q' u + q'' x = a0 + a1 d + a2 d^2`` with ``a0 =
    q'_i u + q''_i x_i``, ``a1 = 3 u q''_i + q''' x_i``, ``a2 = 5 u q''' / 2``: its extremes are
    at the ends or at its vertex. ``d(qd^2)/ds = 2 q' qdd``, so ``qd^2`` peaks at the ends or
    where ``qdd = 0``: the quadratic's roots.

    Args:
        D: ``(M,)`` the stages' lengths.
        x: ``(M + 1,)``, u: ``(M,)``: the parameterisation.
        dq, ddq: ``(M + 1, n)`` at the grid points; dddq: ``(M, n)`` on each stage.

    Returns:
        ``(n,)`` the peak ``|qd|`` and ``(n,)`` the peak ``|qdd|``.
    """
    uu, xx, h = u[:, None], x[:-1, None], D[:, None]
    a0 = dq[:-1] * uu + ddq[:-1] * xx
    a1 = 3.0 * uu * ddq[:-1] + dddq * xx
    a2 = 2.5 * uu * dddq

    def at(d: FloatArray) -> tuple[FloatArray, FloatArray]:
        inside = (d > 0.0) & (d < h)
        d = np.where(inside, d, 0.0)
        qdd = (a2 * d + a1) * d + a0
        dq_d = dq[:-1] + ddq[:-1] * d + 0.5 * dddq * d * d
        qd2 = dq_d * dq_d * np.maximum(xx + 2.0 * uu * d, 0.0)
        return np.where(inside, np.abs(qdd), 0.0), np.where(inside, qd2, 0.0)

    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = -a1 / (2.0 * a2)
        disc = np.sqrt(np.maximum(a1 * a1 - 4.0 * a2 * a0, 0.0))
        has = a1 * a1 - 4.0 * a2 * a0 >= 0.0
        qv = -0.5 * (a1 + np.copysign(disc, a1))  # the stable pair of roots
        r1 = np.where(has, np.where(a2 != 0.0, qv / a2, -a0 / a1), np.nan)
        r2 = np.where(has, a0 / qv, np.nan)
    acc_v, _ = at(vertex)
    _, vel_1 = at(r1)
    _, vel_2 = at(r2)
    acc_ends = np.maximum(np.abs(a0), np.abs((a2 * h + a1) * h + a0))
    vel_ends = dq * dq * x[:, None]
    acc_peak = np.maximum(acc_ends, acc_v).max(axis=0)
    vel_peak = np.sqrt(np.maximum(np.maximum(vel_1, vel_2).max(axis=0), vel_ends.max(axis=0)))
    return vel_peak, acc_peak
