"""poekin.ik._angles: whole turns into the limits, checked against a brute-force search."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
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


# --- poekin.wrap (issue 26) --------------------------------------------------------------------

UR5E_LIKE = None


def _ur5e() -> object:
    global UR5E_LIKE
    if UR5E_LIKE is None:
        from helpers import load_quiet

        import poekin

        UR5E_LIKE = poekin.load(load_quiet("universal_robots_ur5e"))
    return UR5E_LIKE


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from([(), (1,), (3, 1, 2)]),
    st.integers(0, 2**32 - 1),
    st.booleans(),
)
def test_wrap_keeps_the_pose_and_is_nearest_within_the_limits(
    shape: tuple[int, ...], seed: int, referenced: bool
) -> None:
    """The same pose (FK to 1e-12), inside the limits, and no whole turn of any joint brings
    it nearer the reference (0 without one) within the limits: checked by trying every turn."""
    import poekin

    chain = _ur5e()
    rng = np.random.default_rng(seed)
    q = rng.uniform(-12.0, 12.0, (*shape, 6))
    ref = rng.uniform(-7.0, 7.0, (*shape, 6)) if referenced else None
    got = poekin.wrap(q, chain, ref)
    assert got.shape == q.shape
    inside = within_limits(q, chain.limits)
    np.testing.assert_allclose(chain.fk(got), chain.fk(q), atol=1e-12)
    target = np.zeros_like(q) if ref is None else ref
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    for k in range(-3, 4):
        other = got + k * TWO_PI
        allowed = (other >= lo) & (other <= hi)
        assert not np.any(allowed & (np.abs(other - target) < np.abs(got - target) - 1e-12))
    assert within_limits(got, chain.limits)[inside].all()


def test_wrap_leaves_prismatic_joints_and_refuses_bad_values() -> None:
    import pytest

    import poekin

    screws = np.array([[0, 0, 0, 1, 0, 0], [0, 0, 1, 0, 0, 0.0]])
    limits = np.array([[-10.0, 10.0], [-7.0, 7.0]])
    chain = poekin.Chain(["slide", "turn"], ["prismatic", "revolute"], screws, np.eye(4), limits)
    assert np.array_equal(poekin.wrap([7.0, 7.0], chain), [7.0, 7.0 - TWO_PI])
    assert np.array_equal(poekin.wrap([7.0, 0.1], chain, [0.0, 6.0]), [7.0, 0.1 + TWO_PI])
    with pytest.raises(poekin.InputError, match="NaN or inf"):
        poekin.wrap([0.0, np.nan], chain)
    with pytest.raises(poekin.InputError, match="does not broadcast"):
        poekin.wrap(np.zeros((3, 2)), chain, np.zeros((2, 2)))
