"""The closed-form distances (poekin.collision.primitives) against MuJoCo's mj_geomDistance on
random poses and sizes, separated and overlapping (MuJoCo's functions for these pairs are
closed forms too, so they agree to rounding); batched over shapes; JAX and PyTorch gradients
against central differences."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from array_libs import LIBRARIES, load
from hypothesis import given, settings
from hypothesis import strategies as st
from mj_geoms import mj_distances, random_poses, random_sizes

from poekin.collision import primitives as prim
from poekin.errors import InputError

TOL = 1e-12  # both are closed forms; measured worst 7e-16 over 2,000 draws a pair
PAIRS = {
    ("sphere", "sphere"): prim.sphere_sphere,
    ("sphere", "capsule"): prim.sphere_capsule,
    ("capsule", "capsule"): prim.capsule_capsule,
    ("sphere", "box"): prim.sphere_box,
    ("sphere", "cylinder"): prim.sphere_cylinder,
}
PLANES = {
    "sphere": prim.plane_sphere,
    "capsule": prim.plane_capsule,
    "box": prim.plane_box,
    "cylinder": prim.plane_cylinder,
    "ellipsoid": prim.plane_ellipsoid,
}
CASES = [(k1, k2, f) for (k1, k2), f in PAIRS.items()] + [
    ("plane", k, f) for k, f in PLANES.items()
]
IDS = [f"{k1}-{k2}" for k1, k2, _ in CASES]


def _call(kind1: str, f: object, T1: object, S1: object, T2: object, S2: object) -> prim.Distance:
    if kind1 == "plane":
        return f(T1, T2, S2)  # type: ignore[operator, no-any-return]
    return f(T1, S1, T2, S2)  # type: ignore[operator, no-any-return]


@pytest.mark.parametrize(("kind1", "kind2", "f"), CASES, ids=IDS)
def test_closed_forms_are_mujocos_distances_and_points(kind1: str, kind2: str, f: object) -> None:
    rng = np.random.default_rng(len(kind1) + 7 * len(kind2))
    n = 400
    T1, T2 = random_poses(rng, (n,)), random_poses(rng, (n,))
    S1, S2 = random_sizes(rng, (n,)), random_sizes(rng, (n,))
    ref, ref_points = mj_distances(kind1, T1, S1, kind2, T2, S2)
    assert (ref < 0).sum() > 20 and (ref > 0).sum() > 20  # both sides of contact drawn
    found = _call(kind1, f, T1, S1, T2, S2)
    assert found.distance.shape == (n,) and found.points.shape == (n, 2, 3)
    np.testing.assert_allclose(found.distance, ref, rtol=0, atol=TOL)
    np.testing.assert_allclose(found.points, ref_points, rtol=0, atol=TOL)
    gap = np.linalg.norm(found.points[:, 1] - found.points[:, 0], axis=-1)
    np.testing.assert_allclose(gap, np.abs(found.distance), rtol=0, atol=TOL)


def test_parallel_capsules_overlapping_along_their_axis() -> None:
    """Parallel segments have a line of closest pairs: the distance is the axes' distance, and
    the points returned are one of the pairs (on the segments' common stretch)."""
    T1, T2 = np.eye(4), np.eye(4)
    T2[:3, 3] = [0.3, 0.0, 0.05]
    size = np.array([0.1, 0.2, 0.0])
    found = prim.capsule_capsule(T1, size, T2, size)
    ref, _ = mj_distances("capsule", T1, size, "capsule", T2, size)
    assert abs(found.distance - 0.1) < 1e-15 and abs(ref - 0.1) < 1e-15
    p1, p2 = found.points
    assert abs(p1[0] - 0.1) < 1e-15 and abs(p2[0] - 0.2) < 1e-15 and abs(p1[2] - p2[2]) < 1e-15
    assert -0.15 <= p1[2] <= 0.2
    T2[:3, :3] = np.diag([1.0, -1.0, -1.0])  # antiparallel: the same
    assert abs(prim.capsule_capsule(T1, size, T2, size).distance - 0.1) < 1e-15


def test_concentric_spheres_give_a_finite_direction() -> None:
    T = np.eye(4)
    found = prim.sphere_sphere(T, [0.1], T, [0.2])
    assert found.distance == pytest.approx(-0.3, abs=1e-15)
    assert np.all(np.isfinite(found.points))
    assert abs(np.linalg.norm(found.points[1] - found.points[0]) - 0.3) < 1e-15


@settings(max_examples=20, deadline=None)
@given(
    shape=st.sampled_from([(), (1,), (3, 1, 2)]),
    case=st.sampled_from(range(len(CASES))),
    seed=st.integers(0, 2**32 - 1),
)
def test_batch_shapes_broadcast_and_each_entry_is_mujocos(
    shape: tuple[int, ...], case: int, seed: int
) -> None:
    kind1, kind2, f = CASES[case]
    rng = np.random.default_rng(seed)
    size_shape = shape[1:] if shape else ()  # sizes broadcast against the poses
    T1, T2 = random_poses(rng, shape), random_poses(rng, shape)
    S1, S2 = random_sizes(rng, size_shape), random_sizes(rng, size_shape)
    found = _call(kind1, f, T1, S1, T2, S2)
    assert found.distance.shape == shape and found.points.shape == (*shape, 2, 3)
    ref, ref_points = mj_distances(kind1, T1, S1, kind2, T2, S2)
    np.testing.assert_allclose(found.distance, ref, rtol=0, atol=TOL)
    np.testing.assert_allclose(found.points, ref_points, rtol=0, atol=TOL)


def test_numpy_computes_in_float64() -> None:
    T = np.eye(4, dtype=np.float32)
    found = prim.capsule_capsule(T, np.array([0.1, 0.2], np.float32), T, np.array([1, 1]))
    assert found.distance.dtype == np.float64 and found.points.dtype == np.float64


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: prim.sphere_sphere(np.eye(3), [0.1], np.eye(4), [0.1]), "pose1 of shape"),
        (lambda: prim.sphere_sphere(np.eye(4), [-0.1], np.eye(4), [0.1]), r">= 0 \(m\), got -0.1"),
        (lambda: prim.capsule_capsule(np.eye(4), [0.1], np.eye(4), [0.1, 0.2]), "need 2 entries"),
        (lambda: prim.sphere_box(np.full((4, 4), np.nan), [0.1], np.eye(4), [1, 1, 1]), "NaN"),
        (lambda: prim.plane_box(np.eye(4), np.eye(4), [0.1, np.inf, 0.1]), "finite and >= 0"),
        (lambda: prim.sphere_sphere(np.eye(4), ["a"], np.eye(4), [0.1]), "real numbers"),
    ],
    ids=["pose-shape", "negative", "too-few", "nan-pose", "inf-size", "strings"],
)
def test_bad_input_is_one_clear_error(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        call()  # type: ignore[operator]
    assert "\n" not in str(info.value)


def _capsule_distance_numpy(x: np.ndarray, T1: np.ndarray, T2: np.ndarray) -> float:
    """The capsule-capsule distance with the first capsule moved by ``x[:3]`` and its radius
    and half length ``x[3:]``: the function the gradients are checked on."""
    T = T1.copy()
    T[:3, 3] += x[:3]
    return float(prim.capsule_capsule(T, x[3:], T2, [0.05, 0.1]).distance)


def _central(f: object, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    out = np.zeros_like(x)
    for k in range(len(x)):
        e = np.zeros_like(x)
        e[k] = h
        out[k] = (f(x + e) - f(x - e)) / (2 * h)  # type: ignore[operator]
    return out


@pytest.mark.parametrize(
    "library", [pytest.param(lib, marks=pytest.mark.slow) for lib in LIBRARIES]
)
def test_capsule_gradients_match_central_differences(library: str) -> None:  # 7 to 13 s each
    """d(distance)/d(position, radius, half length) of a capsule pair, by the library's
    reverse mode (under jax.jit for JAX), against central differences of the NumPy distance;
    apart and overlapping."""
    lib = load(library)
    rng = np.random.default_rng(3)
    T1, T2 = random_poses(rng, (2,)), random_poses(rng, (2,))
    T2[1, :3, 3] = T1[1, :3, 3] + 0.02  # the second pair overlaps
    x0 = np.array([0.0, 0.0, 0.0, 0.08, 0.15])
    basis = np.zeros((3, 4, 4))
    basis[[0, 1, 2], [0, 1, 2], 3] = 1.0  # pose + sum_k x_k basis_k: moved by x[:3]
    E, other = lib.asarray(basis), lib.asarray([0.05, 0.1])
    for k in range(2):
        expected = _central(lambda x, k=k: _capsule_distance_numpy(x, T1[k], T2[k]), x0)
        A, B = lib.asarray(T1[k]), lib.asarray(T2[k])

        def dist(x: Any, A: Any = A, B: Any = B) -> Any:
            pose = A + (x[:3, None, None] * E).sum(0)
            return prim.capsule_capsule(pose, x[3:], B, other).distance

        def grad(x: Any, dist: Any = dist) -> Any:
            return lib.grad(dist, x)

        if library == "jax":
            grad = lib.module.jit(grad)
        got = lib.numpy(grad(lib.asarray(x0)))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-8)
        value = float(lib.numpy(dist(lib.asarray(x0))))
        assert abs(value - _capsule_distance_numpy(x0, T1[k], T2[k])) < 1e-15
