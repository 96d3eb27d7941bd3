"""poekin.ik._angles: whole turns into the limits, checked against a brute-force search."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from poekin.ik._angles import TWO_PI, within_limits, wrap_into_limits

finite = st.floats(-30.0, 30.0, allow_nan=False)


def _brute(q: float, lo: float, hi: float) -> float:
    """The value among q + 2 pi k, |k| <= 10, inside [lo, hi] with the smallest |k| (q itself
    if none is)."""
    for k in sorted(range(-10, 11), key=abs):
        if lo <= q + k * TWO_PI <= hi:
            return q if k == 0 else q + k * TWO_PI
    return q


@given(finite, finite, st.floats(0.0, 15.0))
def test_a_limited_angle_moves_by_the_fewest_turns(q: float, lo: float, width: float) -> None:
    hi = lo + width
    lim = np.array([[lo, hi]])
    got = float(wrap_into_limits(np.array([q]), lim, np.array([True]))[0])
    expected = _brute(q, lo, hi)
    assert abs(got - expected) <= 1e-12 * max(1.0, abs(q))
    if got != q:
        assert lo <= got <= hi
        assert abs(round((got - q) / TWO_PI) * TWO_PI - (got - q)) < 1e-9


@given(finite)
def test_an_unlimited_angle_comes_back_in_minus_pi_pi(q: float) -> None:
    lim = np.array([[-np.inf, np.inf]])
    got = float(wrap_into_limits(np.array([q]), lim, np.array([True]))[0])
    assert -np.pi < got <= np.pi
    assert abs(np.sin(got) - np.sin(q)) < 1e-12 and abs(np.cos(got) - np.cos(q)) < 1e-12
    if -np.pi < q <= np.pi:
        assert got == q  # bit for bit


def test_prismatic_values_and_angles_inside_never_move() -> None:
    lim = np.array([[-1.0, 1.0], [-np.pi, np.pi], [-np.inf, np.inf]])
    q = np.array([[5.0, 0.3, 0.2], [-7.0, -3.0, -np.pi]])
    got = wrap_into_limits(q, lim, np.array([False, True, True]))
    np.testing.assert_array_equal(got[:, :2], q[:, :2])  # bit for bit
    assert got[1, 2] == np.pi  # -pi is pi in (-pi, pi]
    assert within_limits(got, lim).tolist() == [False, False]
    assert within_limits(got[:, 1:], lim[1:]).tolist() == [True, True]


def test_batch_shapes_are_kept_and_the_input_is_not_changed() -> None:
    lim = np.array([[-np.pi, np.pi]] * 2)
    for shape in [(), (1,), (3, 1, 2)]:
        q = np.full((*shape, 2), 4.0)
        got = wrap_into_limits(q, lim, np.array([True, True]))
        assert got.shape == q.shape and np.all(q == 4.0)
        np.testing.assert_allclose(got, 4.0 - TWO_PI)
