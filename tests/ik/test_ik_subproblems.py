"""poekin.ik.subproblems: each subproblem against a construction.

An answer is made from random angles (rotations by SciPy, not by the code under test), then
solved: the equation must hold at every returned angle where ``exists``, and the angle used to
make it must be among those returned. Batch shapes (), (1,) and (3, 1, 2), with some inputs
shared (unbatched) across the batch.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from poekin.errors import InputError
from poekin.ik import subproblems as sp

SHAPES = st.sampled_from([(), (1,), (3, 1, 2)])
SEEDS = st.integers(0, 2**32 - 1)
TOL = 1e-12


def rot(k: np.ndarray, theta: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``rot(k, theta) p`` by SciPy, broadcast over the leading axes."""
    k, theta, p = (np.array(a) for a in np.broadcast_arrays(k, np.asarray(theta)[..., None], p))
    R = Rotation.from_rotvec((k * theta).reshape(-1, 3))
    return np.asarray(R.apply(p.reshape(-1, 3))).reshape(p.shape)


def unit(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    v = rng.normal(size=(*shape, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def angles(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return rng.uniform(-np.pi, np.pi, shape)


def same_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(np.angle(np.exp(1j * (a - b))))


@settings(max_examples=60, deadline=None)
@given(SEEDS, SHAPES, st.booleans())
def test_sp1(seed: int, shape: tuple[int, ...], shared_axis: bool) -> None:
    rng = np.random.default_rng(seed)
    k = unit(rng, () if shared_axis else shape)
    p1 = rng.normal(size=(*shape, 3))
    theta = angles(rng, shape)
    p2 = rot(k, theta, p1)
    out = sp.sp1(p1, p2, k)
    assert out.theta.shape == shape and out.exists.shape == shape
    assert out.exists.all()
    assert np.allclose(rot(k, out.theta, p1), p2, atol=1e-12)
    off_axis = np.linalg.norm(np.cross(np.broadcast_to(k, p1.shape), p1), axis=-1) > 1e-3
    assert np.all(same_angle(out.theta, theta)[off_axis] < 1e-9)


@settings(max_examples=40, deadline=None)
@given(SEEDS, SHAPES)
def test_sp1_without_exact_solution(seed: int, shape: tuple[int, ...]) -> None:
    """A longer p2: no exact solution; the least-squares angle is the one a fine search finds."""
    rng = np.random.default_rng(seed)
    k, p1 = unit(rng, shape), rng.normal(size=(*shape, 3))
    p2 = 1.5 * rot(k, angles(rng, shape), p1) + 0.3 * k
    out = sp.sp1(p1, p2, k)
    assert not out.exists.any()
    grid = np.linspace(-np.pi, np.pi, 3601)
    miss = np.linalg.norm(rot(k[..., None, :], grid, p1[..., None, :]) - p2[..., None, :], axis=-1)
    best = np.linalg.norm(rot(k, out.theta, p1) - p2, axis=-1)
    assert np.all(best <= miss.min(axis=-1) + 1e-12)


@settings(max_examples=60, deadline=None)
@given(SEEDS, SHAPES)
def test_sp2(seed: int, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(seed)
    k1, k2 = unit(rng, shape), unit(rng, shape)
    t1, t2 = angles(rng, shape), angles(rng, shape)
    p2 = rng.normal(size=(*shape, 3))
    p1 = rot(k1, -t1, rot(k2, t2, p2))  # rot(k1, t1) p1 = rot(k2, t2) p2
    out = sp.sp2(p1, p2, k1, k2)
    assert out.theta1.shape == (*shape, 2) and out.exists.shape == shape
    assert out.exists.all()
    lhs = rot(k1[..., None, :], out.theta1, p1[..., None, :])
    rhs = rot(k2[..., None, :], out.theta2, p2[..., None, :])
    assert np.allclose(lhs, rhs, atol=1e-11)
    gaps = np.maximum(same_angle(out.theta1, t1[..., None]), same_angle(out.theta2, t2[..., None]))
    found = gaps.min(axis=-1)
    assert np.all(found < 1e-7)


@settings(max_examples=60, deadline=None)
@given(SEEDS, SHAPES, st.booleans())
def test_sp3(seed: int, shape: tuple[int, ...], shared: bool) -> None:
    rng = np.random.default_rng(seed)
    k = unit(rng, () if shared else shape)
    p1 = rng.normal(size=(3,) if shared else (*shape, 3))
    p2 = rng.normal(size=(*shape, 3))
    theta = angles(rng, shape)
    dist = np.linalg.norm(rot(k, theta, p1) - p2, axis=-1)
    out = sp.sp3(p1, p2, k, dist)
    assert out.theta.shape == (*shape, 2) and out.exists.shape == shape
    assert out.exists.all()
    kk = np.broadcast_to(k, (*shape, 3))[..., None, :]
    pp1 = np.broadcast_to(p1, (*shape, 3))[..., None, :]
    got = np.linalg.norm(rot(kk, out.theta, pp1) - p2[..., None, :], axis=-1)
    assert np.allclose(got, dist[..., None], atol=1e-11)
    assert np.all(same_angle(out.theta, theta[..., None]).min(axis=-1) < 1e-7)


@settings(max_examples=60, deadline=None)
@given(SEEDS, SHAPES)
def test_sp4(seed: int, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(seed)
    h, k = unit(rng, shape), unit(rng, shape)
    p = rng.normal(size=(*shape, 3))
    theta = angles(rng, shape)
    d = np.sum(h * rot(k, theta, p), axis=-1)
    out = sp.sp4(h, p, k, d)
    assert out.theta.shape == (*shape, 2) and out.exists.shape == shape
    assert out.exists.all()
    got = np.sum(h[..., None, :] * rot(k[..., None, :], out.theta, p[..., None, :]), axis=-1)
    assert np.allclose(got, d[..., None], atol=1e-11)
    assert np.all(same_angle(out.theta, theta[..., None]).min(axis=-1) < 1e-7)


@settings(max_examples=40, deadline=None)
@given(SEEDS, SHAPES)
def test_out_of_reach(seed: int, shape: tuple[int, ...]) -> None:
    """Planes past the circle, spheres too big or too small, circles that do not meet: no
    exact solution, finite least-squares angles (the point nearest the plane or sphere)."""
    rng = np.random.default_rng(seed)
    h, k, p = unit(rng, shape), unit(rng, shape), rng.normal(size=(*shape, 3))
    reach = np.linalg.norm(np.cross(k, p), axis=-1) * np.linalg.norm(np.cross(k, h), axis=-1)
    top = np.sum(h * k, axis=-1) * np.sum(k * p, axis=-1)
    out = sp.sp4(h, p, k, top + reach + 1e-6)
    assert not out.exists.any() and np.all(np.isfinite(out.theta))
    height = np.sum(h[..., None, :] * rot(k[..., None, :], out.theta, p[..., None, :]), axis=-1)
    assert np.allclose(height, (top + reach)[..., None], atol=1e-11)  # the nearest point
    p2 = rng.normal(size=(*shape, 3))
    far = np.linalg.norm(p, axis=-1) + np.linalg.norm(p2, axis=-1) + 0.1
    three = sp.sp3(p, p2, k, far)
    assert not three.exists.any() and np.all(np.isfinite(three.theta))
    big = sp.sp2(p, 2.0 * p, k, unit(rng, shape))
    assert not big.exists.any() and np.all(np.isfinite(big.theta1 + big.theta2))


def test_a_point_on_the_axis() -> None:
    """Every angle solves it (or none does): 0 for subproblem 1, 0 and pi for 3 and 4."""
    k = np.array([0.0, 0.0, 1.0])
    assert sp.sp1(2 * k, 2 * k, k) == (0.0, True)
    four = sp.sp4([1.0, 0.0, 0.0], 3 * k, k, 0.0)
    np.testing.assert_array_equal(four.theta, [0.0, np.pi])
    assert four.exists
    assert not sp.sp4([1.0, 0.0, 0.0], 3 * k, k, 0.5).exists
    three = sp.sp3(2 * k, [0.0, 0.0, 1.0], k, 1.0)
    np.testing.assert_array_equal(three.theta, [0.0, np.pi])
    assert three.exists
    two = sp.sp2(k, [1.0, 0.0, 0.0], k, [0.0, 1.0, 0.0])  # p1 on k1: turn p2 up to it
    assert two.exists
    np.testing.assert_allclose(
        rot(np.array([0.0, 1.0, 0.0]), two.theta2, np.array([1.0, 0.0, 0.0])), [k, k], atol=1e-15
    )


def test_tangent_roots_stay_exact() -> None:
    """A plane tangent to the circle, up to rounding: one root twice, on the plane."""
    k, h = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    for t in np.linspace(-3, 3, 13):
        p = np.array([np.cos(t), np.sin(t), 0.4])
        out = sp.sp4(h, p, k, 1.0)
        assert out.exists
        assert np.allclose(out.theta, -t, atol=1e-7)
        assert np.allclose(rot(k, out.theta, p)[:, 0], 1.0, atol=1e-15)


def test_bad_shapes() -> None:
    with pytest.raises(InputError, match=r"shape \(\.\.\., 3\)"):
        sp.sp1([1.0, 0.0], [1.0, 0.0], [0.0, 0.0, 1.0])
