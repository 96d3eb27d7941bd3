"""The batched GJK and EPA (poekin.collision.gjk) against MuJoCo's mj_geomDistance (its own
GJK and EPA, nativeccd) on random poses and sizes, and against references of their own where
MuJoCo's is not exact: coal (hpp-fcl's successor) for overlapping capsules, and the
point-to-ellipsoid distance by a root of its secular equation for a sphere in an ellipsoid."""

from __future__ import annotations

import coal
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mj_geoms import GeomPair, mj_distances, random_poses, random_sizes
from scipy.optimize import brentq

from poekin.collision import gjk
from poekin.collision import primitives as prim
from poekin.errors import InputError

# MuJoCo's GJK stops within its ccd_tolerance (1e-6); ours within 1e-10: apart, the two agree
# to 1e-9 (measured worst 9e-10, ellipsoids), and MuJoCo's witness points to 7e-6.
APART_TOL = 1e-6
POINTS_TOL = 2e-5
# Overlapping polytopes: both EPAs end on the exact face (measured 8e-17).
POLYTOPE_TOL = 1e-9
# Overlapping curved shapes: MuJoCo's EPA stops short by up to 4e-6 on these draws where ours
# agrees with coal to 4e-10 (capsule-cylinder); on more draws by up to 1.5e-3 (cylinders,
# benchmarks/bench_distance.py's 10,000, ours within 1e-6 of coal), and by up to 4e-3 on
# ellipsoids, which are therefore checked against the exact point-ellipsoid distance instead.
CURVED_TOL = 1e-5
EXACT_TOL = 1e-8

APART = [
    ("capsule", "box"),
    ("box", "box"),
    ("cylinder", "cylinder"),
    ("capsule", "cylinder"),
    ("cylinder", "box"),
    ("sphere", "ellipsoid"),
    ("ellipsoid", "ellipsoid"),
    ("ellipsoid", "box"),
    ("capsule", "ellipsoid"),
    ("cylinder", "ellipsoid"),
]


def _draw(seed: int, n: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    return (
        random_poses(rng, (n,)),
        random_sizes(rng, (n,)),
        random_poses(rng, (n,)),
        random_sizes(rng, (n,)),
    )


@pytest.mark.parametrize(("kind1", "kind2"), APART, ids=[f"{a}-{b}" for a, b in APART])
def test_separated_pairs_are_mujocos_distance(kind1: str, kind2: str) -> None:
    T1, S1, T2, S2 = _draw(len(kind1) * 31 + len(kind2), 200)
    ref, ref_points = mj_distances(kind1, T1, S1, kind2, T2, S2)
    found = gjk.gjk(kind1, T1, S1, kind2, T2, S2)
    apart = ref > 0
    assert apart.sum() > 50
    err = np.abs(found.distance - ref)[apart]
    assert err.max() <= APART_TOL, err.max()
    assert np.abs(found.points - ref_points)[apart].max() <= POINTS_TOL
    gap = np.linalg.norm(found.points[:, 1] - found.points[:, 0], axis=-1)
    np.testing.assert_allclose(gap, np.abs(found.distance), rtol=0, atol=1e-12)
    assert np.all((found.distance < 0) == ~apart)  # the same pairs overlap


@pytest.mark.parametrize(
    ("kind1", "kind2", "tol"),
    [
        ("box", "box", POLYTOPE_TOL),
        ("cylinder", "cylinder", CURVED_TOL),
        ("cylinder", "box", CURVED_TOL),
        ("capsule", "cylinder", CURVED_TOL),
        ("ellipsoid", "box", CURVED_TOL),
    ],
)
def test_overlapping_pairs_are_mujocos_depth(kind1: str, kind2: str, tol: float) -> None:
    T1, S1, T2, S2 = _draw(len(kind1) * 17 + len(kind2), 120)
    ref, _ = mj_distances(kind1, T1, S1, kind2, T2, S2)
    found = gjk.gjk(kind1, T1, S1, kind2, T2, S2)
    deep = ref < 0
    assert deep.sum() > 15
    assert np.abs(found.distance - ref)[deep].max() <= tol
    gap = np.linalg.norm(found.points[:, 1] - found.points[:, 0], axis=-1)
    np.testing.assert_allclose(gap, np.abs(found.distance), rtol=0, atol=1e-12)


def _coal_shape(kind: str, s: np.ndarray) -> object:
    if kind == "capsule":
        return coal.Capsule(s[0], 2 * s[1])  # coal's lengths are whole, MuJoCo's halves
    if kind == "cylinder":
        return coal.Cylinder(s[0], 2 * s[1])
    return coal.Box(*(2 * s))


def _coal_distance(kind1: str, T1: np.ndarray, S1: np.ndarray, kind2: str, T2, S2) -> float:
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    request.enable_signed_distance = True
    request.gjk_tolerance = 1e-12
    poses = [coal.Transform3s(T[:3, :3], T[:3, 3]) for T in (T1, T2)]
    coal.distance(
        _coal_shape(kind1, S1), poses[0], _coal_shape(kind2, S2), poses[1], request, result
    )
    return float(result.min_distance)


@pytest.mark.parametrize("kind2", ["box", "cylinder"])
def test_overlapping_capsules_against_coal(kind2: str) -> None:
    """MuJoCo's capsule-box is not the signed distance when the capsule's segment enters the
    box (it reports less depth, by up to 0.1 m here); coal's GJK-EPA is, and ours agrees. On
    a cylinder coal's EPA stops short by up to 4.3e-7 (ours is deeper, and an EPA's depth is a
    lower bound: its polytope lies inside the shapes' difference)."""
    T1, S1, T2, S2 = _draw(5 + len(kind2), 150)
    found = gjk.gjk("capsule", T1, S1, kind2, T2, S2)
    checked = 0
    for k in np.flatnonzero(found.distance < 0):
        ref = _coal_distance("capsule", T1[k], S1[k], kind2, T2[k], S2[k])
        if ref < -1.0:  # coal's EPA failed (it returns -DBL_MAX): not a reference
            continue
        assert abs(found.distance[k] - ref) <= (EXACT_TOL if kind2 == "box" else 1e-6)
        checked += 1
    assert checked > 20


def _point_ellipsoid(q: np.ndarray, radii: np.ndarray) -> float:
    """The signed distance of the local point ``q`` to the ellipsoid ``radii``: the nearest
    surface point is ``x_i = a_i^2 q_i / (a_i^2 + t)`` for the root ``t`` of
    ``sum (a_i q_i / (a_i^2 + t))^2 = 1`` in ``(-min a_i^2, inf)`` (Eberly)."""
    a2 = radii**2

    def f(t: float) -> float:
        return float(np.sum((radii * q / (a2 + t)) ** 2) - 1)

    lo = -a2.min() * (1 - 1e-15)
    hi = max(np.linalg.norm(q) * radii.max(), 1e-3)
    while f(hi) > 0:
        hi *= 2
    t = brentq(f, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=500)
    x = a2 * q / (a2 + t)
    sign = 1.0 if np.sum((q / radii) ** 2) > 1 else -1.0
    return sign * float(np.linalg.norm(x - q))


def test_sphere_in_ellipsoid_against_the_exact_distance() -> None:
    T1, S1, T2, S2 = _draw(11, 200)
    found = gjk.gjk("sphere", T1, S1, "ellipsoid", T2, S2)
    checked = 0
    for k in range(len(T1)):
        q = T2[k, :3, :3].T @ (T1[k, :3, 3] - T2[k, :3, 3])
        ref = _point_ellipsoid(q, S2[k]) - S1[k, 0]
        assert abs(found.distance[k] - ref) <= EXACT_TOL, (k, found.distance[k], ref)
        checked += ref < 0
    assert checked > 20


def _hull_points(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.normal(size=(n, 3)) * [0.1, 0.06, 0.15]


@pytest.mark.parametrize("other", ["sphere", "capsule", "box", "cylinder", "mesh"])
def test_meshes_are_their_convex_hulls_as_mujoco_collides_them(other: str) -> None:
    rng = np.random.default_rng(len(other))
    vertices = _hull_points(rng, 40)
    pair = GeomPair("mesh", other, vertices)
    n = 60
    T1, T2 = random_poses(rng, (n,)), random_poses(rng, (n,))
    S2 = random_sizes(rng, (n,))
    dist, found = np.zeros(n), np.zeros(n)
    for k in range(n):
        pair.set((T1[k], T2[k]), (np.zeros(3), S2[k]))
        dist[k], _ = pair.distance()
        mesh = pair.mesh_world_vertices(0)  # MuJoCo's vertices, in its frame of the mesh
        if other == "mesh":
            found[k] = gjk.gjk(
                "mesh", np.eye(4), mesh, "mesh", np.eye(4), pair.mesh_world_vertices(1)
            ).distance
        else:
            found[k] = gjk.distance("mesh", np.eye(4), mesh, other, T2[k], S2[k]).distance
    assert (dist < 0).sum() > 5 and (dist > 0).sum() > 5
    tol = np.where(dist > 0, APART_TOL, POLYTOPE_TOL if other in ("box", "mesh") else CURVED_TOL)
    assert np.all(np.abs(found - dist) <= tol), np.abs(found - dist).max()


def test_plane_and_mesh() -> None:
    rng = np.random.default_rng(2)
    vertices = _hull_points(rng, 30)
    pair = GeomPair("plane", "mesh", vertices)
    for T1, T2 in zip(random_poses(rng, (20,)), random_poses(rng, (20,)), strict=True):
        pair.set((T1, T2), (np.zeros(3), np.zeros(3)))
        ref, ref_points = pair.distance()
        mesh = pair.mesh_world_vertices(1)
        found = gjk.distance("plane", T1, None, "mesh", np.eye(4), mesh)
        assert abs(found.distance - ref) < 1e-14
        np.testing.assert_allclose(found.points, ref_points, rtol=0, atol=1e-14)
        back = gjk.distance("mesh", np.eye(4), mesh, "plane", T1, None)
        np.testing.assert_array_equal(back.points, found.points[::-1])


def test_distance_takes_the_closed_form_in_either_order() -> None:
    T1, S1, T2, S2 = _draw(4, 50)
    direct = prim.sphere_box(T1, S1, T2, S2)
    swapped = gjk.distance("box", T2, S2, "sphere", T1, S1)
    np.testing.assert_array_equal(swapped.distance, direct.distance)
    np.testing.assert_array_equal(swapped.points, direct.points[:, ::-1])
    plane = gjk.distance("capsule", T1, S1, "plane", T2, None)
    np.testing.assert_array_equal(plane.distance, prim.plane_capsule(T2, T1, S1).distance)
    # no closed form: GJK, in the order given
    ref, _ = mj_distances("box", T2, S2, "capsule", T1, S1)
    found = gjk.distance("box", T2, S2, "capsule", T1, S1)
    apart = ref > 0
    assert np.abs(found.distance - ref)[apart].max() < APART_TOL


@settings(max_examples=12, deadline=None)
@given(
    shape=st.sampled_from([(), (1,), (3, 1, 2)]),
    pair=st.sampled_from([("cylinder", "box"), ("box", "box"), ("capsule", "ellipsoid")]),
    seed=st.integers(0, 2**32 - 1),
)
def test_batch_shapes_broadcast(shape: tuple[int, ...], pair: tuple[str, str], seed: int) -> None:
    rng = np.random.default_rng(seed)
    T1, T2 = random_poses(rng, shape), random_poses(rng, shape)
    S1, S2 = random_sizes(rng, shape[1:] if shape else ()), random_sizes(rng, ())
    found = gjk.gjk(pair[0], T1, S1, pair[1], T2, S2)
    assert found.distance.shape == shape and found.points.shape == (*shape, 2, 3)
    ref, _ = mj_distances(pair[0], T1, S1, pair[1], T2, S2)
    tol = np.where(ref > 0, APART_TOL, POLYTOPE_TOL if pair == ("box", "box") else 1e-2)
    assert np.all(np.abs(found.distance - ref) <= tol)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: gjk.gjk("cone", np.eye(4), [1], "box", np.eye(4), [1, 1, 1]), "unknown shape"),
        (lambda: gjk.gjk("box", np.eye(4), [1, -1, 1], "box", np.eye(4), [1, 1, 1]), ">= 0"),
        (lambda: gjk.gjk("box", np.eye(4), [1, 1], "box", np.eye(4), [1, 1, 1]), "need 3"),
        (
            lambda: gjk.gjk("mesh", np.eye(4), np.ones((4, 2)), "box", np.eye(4), [1, 1, 1]),
            r"\(V, 3\)",
        ),
        (lambda: gjk.gjk("box", np.eye(4)[:3], [1, 1, 1], "box", np.eye(4), [1, 1, 1]), "pose1"),
        (
            lambda: gjk.gjk("box", np.full((4, 4), np.nan), [1, 1, 1], "box", np.eye(4), [1, 1, 1]),
            "NaN",
        ),
        (lambda: gjk.distance("plane", np.eye(4), None, "plane", np.eye(4), None), "two planes"),
        (
            lambda: gjk.distance("torus", np.eye(4), [1], "box", np.eye(4), [1, 1, 1]),
            "unknown shape",
        ),
        (lambda: gjk.gjk("plane", np.eye(4), None, "box", np.eye(4), [1, 1, 1]), "use distance"),
    ],
    ids=[
        "kind",
        "negative",
        "too-few",
        "vertices",
        "pose-shape",
        "nan",
        "planes",
        "dispatch",
        "plane-box",
    ],
)
def test_bad_input_is_one_clear_error(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        call()  # type: ignore[operator]
    assert "\n" not in str(info.value)
