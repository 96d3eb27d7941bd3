"""The step of a whole-body solve: least squares in levels, under equality rows and a box.

One batched NumPy function, :func:`step`, serves both :func:`poekin.wholebody.solve` (one
Levenberg-Marquardt iteration) and :func:`poekin.wholebody.ik_step` (one control tick). For
each batch entry it finds ``x (n,)`` that

1. meets the held rows ``A x = b`` (in the least-squares sense where they cannot all be met,
   damped by ``lam_hold``): the particular solution of least norm;
2. then minimises ``|C x - d|^2 + lam_soft |x - x_hold|^2`` over the null space of ``A``;
3. then moves toward ``posture`` in what null space of ``A`` and ``C`` is left, as far as that
   space allows: the move there nearest ``posture`` in the norm ``sum w_i x_i^2`` of the
   posture's weights (equal weights: the orthogonal projection), which changes neither level
   above;
4. with every bounded entry within ``lo <= x <= hi``: an active set. An entry that leaves its
   box is held at its bound (a row ``x_i = bound`` joins level 1) and the levels are solved
   again; an entry held where the first-order optimality condition (the Lagrangian's
   gradient, with the held rows' multipliers) says it would move back inside is released.

Null spaces come from one SVD per level (a singular value below ``RANK_TOL`` times the
largest, or below the absolute floor, counts as zero), so the batch runs in lock-step:
every array is ``(B, ...)`` and an entry's result does not depend on the others'.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["RANK_TOL", "Step", "step"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

RANK_TOL = 1e-9  # a singular value below this times the largest (or 1) is a null direction
_BOUND_TOL = 1e-12  # an entry this far past its bound is outside
_RELEASE_TOL = 1e-12  # a held entry's multiplier of the wrong sign beyond this is released


class Step(NamedTuple):
    """:func:`step`'s answer: ``x (B, n)``, ``at_bound (B, n)``, the entries held at a
    bound, and ``posture_move (B,)``, the size of level 3's part of ``x``."""

    x: FloatArray
    at_bound: BoolArray
    posture_move: FloatArray


def _bmv(M: FloatArray, v: FloatArray) -> FloatArray:
    out: FloatArray = np.einsum("bij,bj->bi", M, v)
    return out


def _bmtv(M: FloatArray, v: FloatArray) -> FloatArray:
    out: FloatArray = np.einsum("bji,bj->bi", M, v)
    return out


def _damped_solve(
    M: FloatArray, r: FloatArray, lam: FloatArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """``x = V diag(s / (s^2 + lam)) U^T r`` over the range of ``M (B, m, n)`` and the null
    space's orthonormal basis ``N (B, n, n)`` (zero columns where not null), with the null
    mask over ``V``'s rows."""
    B, m, n = M.shape
    U, s, Vt = np.linalg.svd(M, full_matrices=m < n)  # every row of V either way
    k = s.shape[1]
    top = np.maximum(s[:, :1], 1.0) if k else np.ones((B, 1))
    ranged = s > RANK_TOL * top
    gain = np.where(ranged, s / (s * s + lam[:, None]), 0.0)
    x = np.einsum("bki,bk->bi", Vt[:, :k, :], gain * np.einsum("bjk,bj->bk", U[:, :, :k], r))
    null = np.ones((B, n), dtype=bool)
    null[:, :k] = ~ranged
    N = np.swapaxes(Vt, 1, 2) * null[:, None, :]
    return x, N, null


def step(
    A: FloatArray,
    b: FloatArray,
    C: FloatArray,
    d: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    lam_hold: FloatArray,
    lam_soft: FloatArray,
    posture: FloatArray | None = None,
    posture_weights: FloatArray | None = None,
) -> Step:
    """The step of the levels above, batched.

    Args:
        A: ``(B, mh, n)`` held rows and ``b (B, mh)`` their right-hand side.
        C: ``(B, ms, n)`` soft rows (weights applied) and ``d (B, ms)``.
        lo, hi: ``(B, n)`` bounds on ``x`` (``-inf``/``inf`` where none), ``lo <= 0 <= hi``.
        lam_hold, lam_soft: ``(B,)`` damping of levels 1 and 2.
        posture: ``(B, n)`` the move level 3 wants, or None.
        posture_weights: ``(n,)`` weights ``>= 0`` of its entries, or None (all equal).

    Returns:
        :class:`Step`.
    """
    B, n = lo.shape
    fixed = np.zeros((B, n), dtype=bool)
    value = np.zeros((B, n))
    released = np.zeros((B, n), dtype=bool)
    for _ in range(2 * n + 1):
        x, x_soft, x_hold = _levels(
            A, b, C, d, fixed, value, lam_hold, lam_soft, posture, posture_weights
        )
        below = ~fixed & (x < lo - _BOUND_TOL)
        above = ~fixed & (x > hi + _BOUND_TOL)
        outside = below | above
        if np.any(outside):
            # hold every entry that leaves its box at the bound it crosses
            fixed |= outside
            value = np.where(below, lo, np.where(above, hi, value))
            continue
        # release a held entry (one per pass, each at most once: no cycling) whose
        # multiplier says it would move back inside
        release = _to_release(A, C, d, x_soft, x_hold, fixed, value, lo, hi, lam_soft)
        release &= ~released
        if not np.any(release):
            return Step(x, fixed, np.sqrt(np.sum((x - x_soft) ** 2, axis=1)))
        released |= release
        fixed &= ~release
    return Step(x, fixed, np.sqrt(np.sum((x - x_soft) ** 2, axis=1)))


def _levels(
    A: FloatArray,
    b: FloatArray,
    C: FloatArray,
    d: FloatArray,
    fixed: BoolArray,
    value: FloatArray,
    lam_hold: FloatArray,
    lam_soft: FloatArray,
    posture: FloatArray | None,
    weights: FloatArray | None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Levels 1 to 3 with the ``fixed`` entries at ``value``: ``x``, and that of levels 1
    and 2 only, and of level 1 only."""
    free = ~fixed
    fixed_value = np.where(fixed, value, 0.0)
    if A.shape[1] == 0:  # no held rows: level 1 is the held entries alone, its null space theirs
        x_hold = fixed_value
        Z = free[:, None, :] * np.eye(A.shape[2])
    else:
        eye = fixed[:, :, None] * np.eye(A.shape[2])
        M = np.concatenate([A * free[:, None, :], eye], axis=1)
        r = np.concatenate([b - _bmv(A, fixed_value), np.zeros(fixed.shape)], axis=1)
        x1, Z, _ = _damped_solve(M, r, lam_hold)
        x_hold = x1 + fixed_value
    Y = C @ Z
    z, N, _ = _damped_solve(Y, d - _bmv(C, x_hold), lam_soft)
    x_soft = x_hold + _bmv(Z, z)
    if posture is None:
        return x_soft, x_soft, x_hold
    ZN = Z @ N  # an orthonormal basis of what is left (and zero columns)
    p = np.where(fixed, 0.0, posture)
    if weights is None or np.all(weights == weights[0]):
        return x_soft + _bmv(ZN, _bmtv(ZN, p)), x_soft, x_hold
    root = np.sqrt(weights)
    c = _lstsq(root[None, :, None] * ZN, root * p)  # min |W^1/2 (ZN c - p)|
    return x_soft + _bmv(ZN, c), x_soft, x_hold


def _to_release(
    A: FloatArray,
    C: FloatArray,
    d: FloatArray,
    x: FloatArray,
    x_hold: FloatArray,
    fixed: BoolArray,
    value: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    lam_soft: FloatArray,
) -> BoolArray:
    """Per entry, the held entry whose multiplier has the wrong sign the most (level 2's
    Lagrangian ``g + A^T nu + mu = 0``, ``g`` the gradient of level 2's cost; ``nu`` from the
    free entries), or none."""
    if not np.any(fixed):  # none held at a bound, none to release (the multipliers unneeded)
        return np.zeros(fixed.shape, dtype=bool)
    g = _bmtv(C, _bmv(C, x) - d) + lam_soft[:, None] * (x - x_hold)
    free = ~fixed
    At = np.swapaxes(A, 1, 2) * free[:, :, None]
    nu = np.zeros((A.shape[0], A.shape[1]))
    if A.shape[1]:
        nu = _lstsq(At, -g * free)
    residual = g + np.einsum("bji,bj->bi", A, nu)
    at_hi = fixed & (value >= hi)
    at_lo = fixed & (value <= lo) & ~at_hi
    wrong = np.where(at_hi, residual, np.where(at_lo, -residual, -np.inf))
    wrong = np.where(wrong > _RELEASE_TOL * (1.0 + np.abs(g)), wrong, -np.inf)
    worst = np.argmax(wrong, axis=1)
    has = np.isfinite(np.max(wrong, axis=1))
    out: BoolArray = has[:, None] & (np.arange(x.shape[1])[None, :] == worst[:, None])
    return out


def _lstsq(M: FloatArray, r: FloatArray) -> FloatArray:
    """Least-squares solutions of ``M (B, n, m) y = r (B, n)``, of least norm."""
    pinv = np.asarray(np.linalg.pinv(M, rcond=RANK_TOL), dtype=np.float64)
    return _bmv(pinv, r)
