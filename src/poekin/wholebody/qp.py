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
4. with every bounded entry within ``lo <= x <= hi``: a primal active set (Nocedal and
   Wright's algorithm 16.3, as :mod:`poekin.ik.step` runs for a chain). From ``x = 0``
   (clipped into the box) each round either moves toward the levels' answer for the free
   entries, the fixed ones held where they are, as far as the box allows (the entry that
   stops the move is fixed at its bound); or, at that answer, releases the fixed entry whose
   multiplier has the wrong sign, level by level (level 1's gradient where the box keeps its
   rows from being met, else level 2's Lagrangian with the held rows' multipliers), or stops
   where none has. Every round keeps ``x`` in the box, and where ``x = 0`` meets the held
   rows (``b = 0``: a control tick) every round meets them, so a step cut short by the
   rounds is still within every bound with the held rows met. The posture's level does not
   release entries: one it takes to a bound stays there.

Each entry's levels are solved in the coordinates of its free entries, with the null spaces
from one SVD per level (a singular value below ``RANK_TOL`` times the largest, or below the
absolute floor, counts as zero). The batch runs in lock-step, every array ``(B, ...)``, and
an entry's result does not depend on the others'.
"""

from __future__ import annotations

import dataclasses
import functools
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from poekin.ik.step import max_rounds
from poekin.kernel._fast import get_threads

__all__ = ["RANK_TOL", "Step", "step"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

RANK_TOL = 1e-9  # a singular value below this times the largest (or 1) is a null direction
_RELEASE_TOL = 1e-12  # a held entry's multiplier of the wrong sign beyond this is released
# level 1's gradient on a fixed entry below this many times its damping's pull is the damping's
DAMPING_SLACK = 100.0
# releases of one entry in one step at most: where the levels' damping makes the multipliers
# and the levels' answer disagree (level 1's damped answer leaving the box where its rows, met,
# would not need to), an entry released would be stopped again at once, for ever
MAX_RELEASES = 2
SPLIT_MATRICES = 16  # matrices per thread at least, for a batch's SVDs to be shared out


@dataclasses.dataclass(frozen=True)
class _Rounds:
    """The active set's state, ``(B, ...)`` arrays changed in place by the rounds: the step
    ``x``, the answers of levels 1 and 2 (``x_soft``) and of level 1 (``x_hold``) at the last
    optimum, the ``fixed`` entries (each at a bound), and whether ``x`` is the ``optimal``
    answer of its free entries (its multipliers are then tested)."""

    x: FloatArray
    x_soft: FloatArray
    x_hold: FloatArray
    fixed: BoolArray
    optimal: BoolArray


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
    M: FloatArray, r: FloatArray, lam: FloatArray, null_space: bool = True
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """``x = V diag(s / (s^2 + lam)) U^T r`` over the range of ``M (B, m, n)`` and the null
    space's orthonormal basis ``N (B, n, n)`` (zero columns where not null), with the null
    mask over ``V``'s rows; without ``null_space``, ``N`` and the mask only where ``m >= n``
    (``V`` whole) and empty ``(B, n, 0)``, ``(B, 0)`` otherwise (a smaller SVD)."""
    B, m, n = M.shape
    whole = null_space and m < n  # every row of V either way
    U, s, Vt = _svd(M, whole)
    k = s.shape[1]
    top = np.maximum(s[:, :1], 1.0) if k else np.ones((B, 1))
    ranged = s > RANK_TOL * top
    gain = np.where(ranged, s / (s * s + lam[:, None]), 0.0)
    x = np.einsum("bki,bk->bi", Vt[:, :k, :], gain * np.einsum("bjk,bj->bk", U[:, :, :k], r))
    if not (whole or m >= n):
        return x, np.zeros((B, n, 0)), np.zeros((B, 0), dtype=bool)
    null = np.ones((B, n), dtype=bool)
    null[:, :k] = ~ranged
    N = np.swapaxes(Vt, 1, 2) * null[:, None, :]
    return x, N, null


def _svd(M: FloatArray, full_matrices: bool) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``numpy.linalg.svd`` of the matrices ``M (B, m, n)``, a big batch shared out over the
    threads :func:`poekin.set_threads` allows (LAPACK runs each matrix alone, without the
    GIL: the same bits however the batch is split)."""
    threads = min(get_threads(), len(M) // SPLIT_MATRICES)
    if threads < 2:
        U, s, Vt = np.linalg.svd(M, full_matrices=full_matrices)
        return U, s, Vt
    parts = list(
        _pool(threads).map(
            lambda part: np.linalg.svd(part, full_matrices=full_matrices),
            np.array_split(M, threads),
        )
    )
    U, s, Vt = (np.concatenate([part[k] for part in parts]) for k in range(3))
    return U, s, Vt


@functools.cache
def _pool(threads: int) -> ThreadPoolExecutor:
    return ThreadPoolExecutor(threads, thread_name_prefix="poekin-qp")


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
    x = np.minimum(np.maximum(0.0, lo), hi)
    pinned = lo >= hi  # an entry whose bounds meet never moves, and is never released
    st = _Rounds(x, x.copy(), x.copy(), pinned.copy(), np.zeros(B, dtype=bool))
    releases = np.zeros((B, n), dtype=np.int64)
    done = np.zeros(B, dtype=bool)
    problem = (A, b, C, d, lo, hi, lam_hold, lam_soft, posture, posture_weights)
    _guess(problem, st)
    for _ in range(max_rounds(n)):
        moving = np.flatnonzero(~done & ~st.optimal)
        testing = np.flatnonzero(~done & st.optimal)
        if moving.size == 0 and testing.size == 0:
            break
        if moving.size:  # toward the free entries' optimum, the fixed ones where they are
            i = moving
            _advance(problem, i, st, _solve(problem, i, st.fixed[i], st.x[i]))
        if testing.size:
            i = testing
            release = _to_release(
                A[i],
                b[i],
                C[i],
                d[i],
                st.x[i],
                st.x_soft[i],
                st.x_hold[i],
                st.fixed[i],
                st.fixed[i] & ~pinned[i] & (releases[i] < MAX_RELEASES),
                hi[i],
                lam_hold[i],
                lam_soft[i],
            )
            some = np.any(release, axis=1)
            releases[i] += release
            st.fixed[i] &= ~release
            st.optimal[i] = ~some
            done[i] = ~some
    return Step(st.x, st.fixed, np.sqrt(np.sum((st.x - st.x_soft) ** 2, axis=1)))


def _solve(
    problem: tuple[Any, ...], i: NDArray[np.intp] | slice, fixed: BoolArray, value: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`_levels` of the entries ``i`` (indices, or every entry) of ``problem``
    (:func:`step`'s arguments) with the ``fixed (len(i), n)`` entries at ``value``."""
    A, b, C, d, _, _, lam_hold, lam_soft, posture, weights = problem
    return _levels(
        A[i],
        b[i],
        C[i],
        d[i],
        fixed,
        value,
        lam_hold[i],
        lam_soft[i],
        None if posture is None else posture[i],
        weights,
    )


def _guess(problem: tuple[Any, ...], st: _Rounds) -> None:
    """The first round, in place: the levels' answer with every entry it takes out of the
    box held at the bound it crosses, where that answer is inside the box (a control tick
    whose velocity limits bind: one more solve, not one per entry); else the first move
    toward the free answer (:func:`_advance`)."""
    lo, hi = problem[4], problem[5]
    first = _solve(problem, slice(None), st.fixed, st.x)
    below, above = ~st.fixed & (first[0] < lo), ~st.fixed & (first[0] > hi)
    crossed = np.flatnonzero(np.any(below | above, axis=1))
    if crossed.size == 0:
        _advance(problem, np.arange(len(st.x)), st, first)
        return
    held = st.fixed[crossed] | below[crossed] | above[crossed]
    at = np.where(below[crossed], lo[crossed], np.where(above[crossed], hi[crossed], st.x[crossed]))
    second = _solve(problem, crossed, held, at)
    # taken where it is inside the box and meets the held rows about as well as the first
    # answer: within twice its residual (what level 1's damping leaves of them moves a little
    # with the entries free), not a residual the entries held leave too few free to remove
    A, b = problem[0][crossed], problem[1][crossed]
    before = np.sqrt(np.sum((_bmv(A, first[0][crossed]) - b) ** 2, axis=1))
    after = np.sqrt(np.sum((_bmv(A, second[0]) - b) ** 2, axis=1))
    size_b = np.sqrt(np.sum(b * b, axis=1))
    inside = np.all((second[0] >= lo[crossed]) & (second[0] <= hi[crossed]), axis=1) & (
        after <= 2.0 * before + _RELEASE_TOL * (1.0 + size_b)
    )
    took = crossed[inside]
    st.x[took], st.x_soft[took], st.x_hold[took] = (answer[inside] for answer in second)
    st.fixed[took] = held[inside]
    st.optimal[took] = True
    rest = np.ones(len(st.x), dtype=bool)
    rest[took] = False
    others = np.flatnonzero(rest)
    if others.size:
        _advance(problem, others, st, (first[0][others], first[1][others], first[2][others]))


def _advance(
    problem: tuple[Any, ...],
    i: NDArray[np.intp],
    st: _Rounds,
    targets: tuple[FloatArray, FloatArray, FloatArray],
) -> None:
    """The entries ``i`` moved toward ``targets`` (their levels' answers, of levels 1 to 3,
    1 and 2, and 1) as far as the box allows, in place. The first entry that would leave it
    stops at its bound and is fixed; an entry that gets there is at an optimum, its levels'
    answers kept."""
    lo, hi = problem[4], problem[5]
    target, t_soft, t_hold = targets
    x_i, lo_i, hi_i = st.x[i], lo[i], hi[i]
    p = target - x_i
    go = ~st.fixed[i] & (p != 0.0)
    room = np.where(p < 0.0, lo_i - x_i, hi_i - x_i)
    ratio = np.where(go, room / np.where(go, p, 1.0), np.inf)
    alpha = np.min(ratio, axis=1, initial=np.inf)  # where the first entry stops the move
    full = alpha >= 1.0
    # every entry that stops it there (those already at a bound the move pushes on, at
    # alpha = 0, all at once) goes to its bound and is fixed
    block = ~full[:, None] & (ratio <= alpha[:, None])
    moved = np.where(full[:, None], target, x_i + np.where(full, 1.0, alpha)[:, None] * p)
    moved = np.where(block, np.where(p < 0.0, lo_i, hi_i), moved)
    st.x[i] = np.minimum(np.maximum(moved, lo_i), hi_i)
    st.fixed[i] |= block
    st.optimal[i] = full
    st.x_soft[i[full]] = t_soft[full]
    st.x_hold[i[full]] = t_hold[full]


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
    and 2 only, and of level 1 only.

    Each entry is solved in the coordinates of its free entries (:func:`_free_levels`), the
    entries with as many free ones side by side: the fixed entries' columns are gone from
    every matrix rather than held by rows of an identity (the same null spaces and solutions,
    in smaller SVDs), and an entry's numbers depend on its own rows only."""
    B, n = fixed.shape
    fixed_value = np.where(fixed, value, 0.0)
    x_hold, x_soft, x = np.empty((B, n)), np.empty((B, n)), np.empty((B, n))
    if B == 0 or np.all(fixed == fixed[0]):  # one free set (one entry; a batch alike): shared
        groups: list[tuple[Any, NDArray[np.intp]]] = [
            (slice(None), np.flatnonzero(~fixed[0]) if B else np.arange(n))
        ]
    else:  # each entry's free entries, in order (a stable sort puts False first)
        free_count = n - np.sum(fixed, axis=1)
        groups = []
        for nf in np.unique(free_count):
            rows = np.flatnonzero(free_count == nf)
            groups.append((rows, np.argsort(fixed[rows], axis=1, kind="stable")[:, :nf]))
    for rows, order in groups:
        moves = _free_levels(
            A[rows],
            b[rows],
            C[rows],
            d[rows],
            order,
            fixed_value[rows],
            lam_hold[rows],
            lam_soft[rows],
            None if posture is None else posture[rows],
            weights,
        )
        total = fixed_value[rows]
        for k, move in enumerate(moves):  # x_hold, then + level 2's move, then + level 3's
            total = _add_at(total, order, move)
            (x_hold, x_soft, x)[k][rows] = total
        if posture is None:
            x[rows] = total
    return x, x_soft, x_hold


def _gather(M: FloatArray, order: NDArray[np.intp]) -> FloatArray:
    """The columns ``order`` of ``M (B, ..., n)``: shared ``(f,)``, or each entry's ``(B,
    f)``."""
    if order.ndim == 1 and len(order) == M.shape[-1]:  # every column, in order (none fixed)
        return M
    if order.ndim == 1:
        shared: FloatArray = M[..., order]
        return shared
    index = order.reshape(len(order), *([1] * (M.ndim - 2)), order.shape[1])
    each: FloatArray = np.take_along_axis(M, index, axis=-1)
    return each


def _add_at(total: FloatArray, order: NDArray[np.intp], move: FloatArray) -> FloatArray:
    """``total (B, n)`` with ``move (B, f)`` added at the columns ``order`` (as
    :func:`_gather`)."""
    if order.ndim == 1 and len(order) == total.shape[-1]:  # every column, in order
        whole: FloatArray = total + move
        return whole
    out: FloatArray = np.array(total)
    if order.ndim == 1:
        out[:, order] = total[:, order] + move
    else:
        np.put_along_axis(out, order, np.take_along_axis(total, order, axis=1) + move, axis=1)
    return out


def _free_levels(
    A: FloatArray,
    b: FloatArray,
    C: FloatArray,
    d: FloatArray,
    order: NDArray[np.intp],
    fixed_value: FloatArray,
    lam_hold: FloatArray,
    lam_soft: FloatArray,
    posture: FloatArray | None,
    weights: FloatArray | None,
) -> list[FloatArray]:
    """:func:`_levels` for entries with the same number ``f`` of free entries, ``order``
    their indices (``(f,)`` shared, or ``(B, f)``): each level's move in those coordinates,
    ``(B, f)`` (level 1's, then 2's, then 3's where there is a posture)."""
    B, f = len(A), order.shape[-1]
    A_free, C_free = _gather(A, order), _gather(C, order)
    if A.shape[1] == 0:  # no held rows: level 1 is the fixed entries alone, the rest free
        x1 = np.zeros((B, f))
        x_hold = fixed_value
        z, N, _ = _damped_solve(C_free, d - _bmv(C, x_hold), lam_soft, posture is not None)
        moves = [x1, z]  # Z = I: its products are the same numbers
        ZN = N
    else:
        x1, Z, _ = _damped_solve(A_free, b - _bmv(A, fixed_value), lam_hold)
        x_hold = _add_at(fixed_value, order, x1)
        z, N, _ = _damped_solve(C_free @ Z, d - _bmv(C, x_hold), lam_soft, posture is not None)
        moves = [x1, _bmv(Z, z)]
        ZN = Z @ N if posture is not None else N  # a basis of what is left (and zero columns)
    if posture is None:
        return moves
    p = _gather(posture, order)
    if weights is None or np.all(weights == weights[0]):
        moves.append(_bmv(ZN, _bmtv(ZN, p)))
        return moves
    root = np.broadcast_to(np.sqrt(weights)[order], (B, f))
    # min |W^1/2 (ZN c - p)|: ZN's columns are unit or zero but for rounding, so a singular
    # value below RANK_TOL times the largest weight is rounding (were it relative to the
    # largest singular value alone, a space left empty would magnify the rounding to a move)
    c = _lstsq(root[:, :, None] * ZN, root * p, RANK_TOL * float(np.max(root, initial=0.0)))
    moves.append(_bmv(ZN, c))
    return moves


def _to_release(
    A: FloatArray,
    b: FloatArray,
    C: FloatArray,
    d: FloatArray,
    x: FloatArray,
    x_soft: FloatArray,
    x_hold: FloatArray,
    fixed: BoolArray,
    releasable: BoolArray,
    hi: FloatArray,
    lam_hold: FloatArray,
    lam_soft: FloatArray,
) -> BoolArray:
    """Per entry at an optimum of its free entries, the fixed entry (of ``fixed``; of those
    ``releasable``) to release, or none, by the levels' multipliers in turn: where level 1's
    multiplier (its cost's gradient) has the wrong sign beyond rounding, the entry is a
    candidate; where it has the right sign, level 1 needs the entry at its bound; where level
    1 is indifferent, level 2's Lagrangian ``g + A^T nu + mu = 0`` says (``g`` the gradient of
    level 2's cost, whose damping pulls a fixed entry toward 0; ``nu`` the held rows'
    multipliers, from the free entries). Of the candidates, the most wrong, level 1's first."""
    B, n = x.shape
    if not np.any(releasable):  # none to release (the multipliers unneeded)
        return np.zeros((B, n), dtype=bool)
    sign = np.where(x >= hi, 1.0, -1.0)  # that of a multiplier that wants the entry inside
    g = _bmtv(C, _bmv(C, x_soft) - d) + lam_soft[:, None] * np.where(fixed, x, x_soft - x_hold)
    if A.shape[1] == 0:  # level 2 alone: its gradient is the multiplier
        wrong = np.where(
            releasable & (sign * g > _RELEASE_TOL * (1.0 + np.abs(g))), sign * g, -np.inf
        )
        return _worst(wrong)
    r1 = _bmv(A, x) - b
    wrong1 = sign * _bmtv(A, r1)  # the gradient of |A x - b|^2 / 2: the rows, not the damping
    size_A = np.sqrt(np.sum(A * A, axis=1))
    size_r1 = np.sqrt(np.sum(r1 * r1, axis=1))[:, None]
    # rounding, and what level 1's damping leaves (its rows met as nearly as the damping lets
    # them: |A_j^T r| ~ lam |x|), is indifference: level 1 decides where the box keeps its
    # rows from being met
    reach = np.max(np.abs(x), axis=1, initial=0.0)[:, None]
    tol1 = _RELEASE_TOL * (1.0 + size_A * size_r1) + DAMPING_SLACK * lam_hold[:, None] * (
        reach * (1.0 + size_A)
    )
    nu = _lstsq(np.swapaxes(A, 1, 2) * ~fixed[:, :, None], -g * ~fixed)
    wrong2 = sign * (g + _bmtv(A, nu))
    first = releasable & (wrong1 > tol1)
    second = releasable & (np.abs(wrong1) <= tol1) & (wrong2 > _RELEASE_TOL * (1.0 + np.abs(g)))
    score = np.where(
        np.any(first, axis=1, keepdims=True),
        np.where(first, wrong1, -np.inf),
        np.where(second, wrong2, -np.inf),
    )
    return _worst(score)


def _worst(score: FloatArray) -> BoolArray:
    """Per row of ``score (B, n)``, its largest finite entry (a mask), or none."""
    worst = np.argmax(score, axis=1)
    has = np.isfinite(np.max(score, axis=1))
    out: BoolArray = has[:, None] & (np.arange(score.shape[1])[None, :] == worst[:, None])
    return out


def _lstsq(M: FloatArray, r: FloatArray, floor: float = 0.0) -> FloatArray:
    """Least-squares solutions of ``M (B, n, m) y = r (B, n)``, of least norm: a singular
    value below ``RANK_TOL`` times the largest, or below ``floor``, counts as zero."""
    if floor == 0.0:
        pinv = np.asarray(np.linalg.pinv(M, rcond=RANK_TOL), dtype=np.float64)
        return _bmv(pinv, r)
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    top = s[:, :1] if s.shape[1] else np.zeros((len(M), 1))
    kept = s > np.maximum(RANK_TOL * top, floor)
    inverse = np.where(kept, 1.0 / np.where(kept, s, 1.0), 0.0)
    return _bmtv(Vt, inverse * _bmtv(U, r))
