"""poekin.wholebody.qp: the levels' step under held rows and a box, against independent
solvers: SciPy's bounded least squares (BVLS) without held rows, and the QP solver daqp
(through qpsolvers, as mink uses it) with them; the posture's level against the same
problem without it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from poekin.wholebody import qp

FloatArray = NDArray[np.float64]
HOLD_DAMPING = 1e-18  # poekin.wholebody.solve.FLOOR: level 1 as ik_step poses it


def _problem(seed: int, n: int, mh: int, ms: int) -> tuple[FloatArray, ...]:
    """One random problem, batch 1: held rows ``A (1, mh, n)`` that ``x = 0`` meets, soft rows
    ``C, d`` and a box around 0 (some entries unbounded below)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(1, mh, n))
    C = rng.normal(size=(1, ms, n))
    d = 2 * rng.normal(size=(1, ms))
    lo = -rng.uniform(0.05, 1.0, (1, n))
    hi = rng.uniform(0.05, 1.0, (1, n))
    lo[rng.random((1, n)) < 0.2] = -np.inf
    return A, np.zeros((1, mh)), C, d, lo, hi


def _step(
    problem: tuple[FloatArray, ...],
    lam: float,
    posture: FloatArray | None = None,
    weights: FloatArray | None = None,
) -> qp.Step:
    A, b, C, d, lo, hi = problem
    return qp.step(A, b, C, d, lo, hi, np.full(1, HOLD_DAMPING), np.full(1, lam), posture, weights)


def _in_box(x: FloatArray, lo: FloatArray, hi: FloatArray) -> bool:
    return bool(np.all(x >= lo) and np.all(x <= hi))


# derandomized: a fresh clone draws the same problems every run
@settings(max_examples=80, deadline=None, derandomize=True)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(2, 10),
    st.integers(1, 8),
    st.floats(1e-6, 1e-2),
)
def test_box_least_squares_against_bvls(seed: int, n: int, ms: int, lam: float) -> None:
    """No held rows: ``min |C x - d|^2 + lam |x|^2`` in the box, BVLS's optimum."""
    from scipy.optimize import lsq_linear

    problem = _problem(seed, n, 0, ms)
    _, _, C, d, lo, hi = problem
    x = _step(problem, lam).x[0]
    M = np.vstack([C[0], np.sqrt(lam) * np.eye(n)])
    r = np.concatenate([d[0], np.zeros(n)])
    ref = lsq_linear(M, r, bounds=(lo[0], hi[0]), method="bvls", tol=1e-14).x
    cost, best = np.sum((M @ x - r) ** 2), np.sum((M @ ref - r) ** 2)
    assert _in_box(x, lo, hi)
    assert cost <= best * (1 + 1e-10) + 1e-15
    assert np.abs(x - ref).max() < 1e-6


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(4, 12),
    st.integers(1, 3),
    st.integers(1, 6),
    st.floats(1e-4, 1e-2),
    st.booleans(),
)
def test_held_rows_and_box_against_daqp(
    seed: int, n: int, mh: int, ms: int, lam: float, pinned: bool
) -> None:
    """``A x = 0`` exactly, then ``min |C x - d|^2 + lam |x|^2`` in the box: daqp's minimiser
    (the problem ``ik_step`` poses, with a damping that keeps daqp's Hessian well
    conditioned); ``pinned``: two entries' bounds meet at 0 (joints at a limit whose velocity
    the step cannot use), never free in the multipliers."""
    qpsolvers = pytest.importorskip("qpsolvers")
    problem = _problem(seed, n, mh, ms)
    A, _, C, d, lo, hi = problem
    if pinned:
        lo[0, :2] = hi[0, :2] = 0.0
    x = _step(problem, lam).x[0]
    H = C[0].T @ C[0] + lam * np.eye(n)
    ref = qpsolvers.solve_qp(
        H, -C[0].T @ d[0], A=A[0], b=np.zeros(mh), lb=lo[0], ub=hi[0], solver="daqp"
    )
    assert ref is not None
    assert _in_box(x, lo, hi)
    assert np.abs(A[0] @ x).max() < 1e-12
    assert np.abs(x - ref).max() < 1e-6


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(3, 10),
    st.integers(0, 2),
    st.integers(1, 6),
    st.booleans(),
)
def test_posture_changes_neither_level_above(
    seed: int, n: int, mh: int, ms: int, weighted: bool
) -> None:
    """With a posture (equal or unequal weights) the held rows are met and the soft cost is
    that of the same step without it: level 3 moves in what the box and levels 1 and 2 leave.
    (With unequal weights and nothing left to move in, the weighted fit once magnified
    rounding into a move of order 1, and the box then fixed entries level 2 needed.)"""
    problem = _problem(seed, n, mh, ms)
    A, _, C, d, lo, hi = problem
    rng = np.random.default_rng(seed + 1)
    posture = rng.normal(size=(1, n))
    weights = rng.uniform(0.1, 2.0, n) if weighted else None
    lam = 1e-12
    without = _step(problem, lam).x[0]
    found = _step(problem, lam, posture, weights)
    x = found.x[0]
    assert _in_box(x, lo, hi)
    if mh:
        assert np.abs(A[0] @ x).max() < 1e-12
    cost, best = np.sum((C[0] @ x - d[0]) ** 2), np.sum((C[0] @ without - d[0]) ** 2)
    assert cost <= best * (1 + 1e-9) + 1e-12


def test_posture_moves_where_it_can() -> None:
    """Two free entries, one soft row on their sum: the posture's move is along the
    difference, as far as the box allows."""
    C, d = np.array([[[1.0, 1.0]]]), np.array([[1.0]])
    lo, hi = np.full((1, 2), -1.0), np.full((1, 2), 0.75)
    posture = np.array([[1.0, 0.0]])
    found = qp.step(
        np.zeros((1, 0, 2)),
        np.zeros((1, 0)),
        C,
        d,
        lo,
        hi,
        np.ones(1),
        np.full(1, 1e-12),
        posture,
    )
    # level 2: x0 + x1 = 1; level 3: nearest (1, 0) on that line is (1, 0), x0 stops at 0.75
    np.testing.assert_allclose(found.x[0], [0.75, 0.25], rtol=0, atol=1e-12)
    assert found.at_bound[0].tolist() == [True, False]


def test_a_batch_gives_each_entry_its_own_bits() -> None:
    """Five problems of one size solved together and one at a time: the same bits, though
    they fix different entries in different rounds."""
    n, mh, ms = 8, 2, 5
    problems = [_problem(seed, n, mh, ms) for seed in range(5)]
    stacked = [np.concatenate(parts) for parts in zip(*problems, strict=True)]
    rng = np.random.default_rng(9)
    posture = rng.normal(size=(5, n))
    weights = rng.uniform(0.5, 1.5, n)
    lam = np.full(5, 1e-6)
    together = qp.step(*stacked, np.full(5, HOLD_DAMPING), lam, posture, weights)
    assert len({int(k) for k in together.at_bound.sum(axis=1)}) > 1
    for i, problem in enumerate(problems):
        alone = _step(problem, 1e-6, posture[i : i + 1], weights)
        np.testing.assert_array_equal(alone.x[0], together.x[i])
        np.testing.assert_array_equal(alone.at_bound[0], together.at_bound[i])


def test_a_big_batch_shared_over_threads_keeps_its_bits() -> None:
    """A batch big enough for its SVDs to be shared out over two threads: the bits of one."""
    import poekin

    n, mh, ms, B = 8, 2, 5, 4 * qp.SPLIT_MATRICES
    stacked = [
        np.concatenate(parts)
        for parts in zip(*(_problem(s, n, mh, ms) for s in range(B)), strict=True)
    ]
    args = (*stacked, np.full(B, HOLD_DAMPING), np.full(B, 1e-6))
    before = poekin.get_threads()
    try:
        poekin.set_threads(1)
        one = qp.step(*args)
        poekin.set_threads(2)
        two = qp.step(*args)
    finally:
        poekin.set_threads(before)
    np.testing.assert_array_equal(one.x, two.x)
    np.testing.assert_array_equal(one.at_bound, two.at_bound)
