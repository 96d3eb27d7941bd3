"""The compiled distances (poekin/kernel/_distance.h) against the NumPy reference
(poekin.collision.primitives and gjk), bit for bit: every pair of kinds, apart, touching and
overlapping, parallel capsules, coincident shapes and zero sizes, through gjk.distance, gjk.gjk
and gjk.pair_distances, at this machine's width (the distances are scalar C, the same code at
every width, so CI's runs at the narrower widths leave this file out). The reference is checked
against MuJoCo in tests/collision; here the kernel is checked against it."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

import poekin
from poekin.collision import gjk, primitives
from poekin.errors import InputError

pytestmark = pytest.mark.skipif(not poekin.compiled_kernel(), reason="no compiled kernel")

KINDS = ["plane", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh"]
PAIRS = [(a, b) for a, b in itertools.product(KINDS, KINDS) if not a == b == "plane"]
BATCH_SHAPES = [(), (1,), (3, 1, 2)]


def test_the_kernel_is_there_where_ci_requires_it() -> None:
    if os.environ.get("POEKIN_REQUIRE_COMPILED") == "1":
        assert gjk._kernel is not None


def _poses(rng: np.random.Generator, n: int, spread: float = 0.3) -> np.ndarray:
    """``n`` poses ``(n, 4, 4)``: uniform rotations (unit quaternions), positions uniform in a
    cube of half side ``spread``."""
    w, x, y, z = rng.normal(size=(4, n))
    s = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / s, x / s, y / s, z / s
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, 0, :3] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1)
    T[:, 1, :3] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1)
    T[:, 2, :3] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)
    T[:, :3, 3] = rng.uniform(-spread, spread, (n, 3))
    return T


def _mesh(rng: np.random.Generator) -> np.ndarray:
    return rng.normal(size=(14, 3)) * 0.08


def _size(kind: str, sizes: np.ndarray, mesh: np.ndarray) -> np.ndarray:
    return mesh if kind == "mesh" else sizes


@pytest.fixture
def reference(monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """A function that runs its arguments on the NumPy reference (gjk without the kernel)."""

    def run(f: Any, *args: Any, **kwargs: Any) -> Any:
        with monkeypatch.context() as m:
            m.setattr(gjk, "_kernel", None)
            return f(*args, **kwargs)

    yield run


def _assert_bits(found: primitives.Distance, ref: primitives.Distance) -> None:
    """The same values (``==``: a zero's sign aside, which numpy.maximum's SIMD and scalar
    loops do not agree on either)."""
    assert found.distance.shape == np.shape(ref.distance)
    assert found.points.shape == np.shape(ref.points)
    bad = found.distance != ref.distance
    assert not bad.any(), (np.flatnonzero(bad)[:5], np.abs(found.distance - ref.distance).max())
    assert np.array_equal(found.points, ref.points, equal_nan=True)


def _draws(seed: int, n: int) -> tuple[np.ndarray, ...]:
    """``n`` pairs apart and overlapping (a third of them nearly touching, a tenth coincident)."""
    rng = np.random.default_rng(seed)
    T1, T2 = _poses(rng, n), _poses(rng, n)
    S1, S2 = rng.uniform(0.02, 0.2, (n, 3)), rng.uniform(0.02, 0.2, (n, 3))
    T2[: n // 10, :3, 3] = T1[: n // 10, :3, 3]  # coincident centres
    S1[n // 10 : n // 10 + 5] = 0.0  # points and segments: zero sizes
    return T1, S1, T2, S2, _mesh(rng)


# pairs per pair of kinds, twice (as drawn, then touching): 11,520 in all, and 5 times as
# many in the slow test
N_PAIRS = 120


@pytest.mark.parametrize(("kind1", "kind2"), PAIRS, ids=[f"{a}-{b}" for a, b in PAIRS])
def test_every_pair_of_kinds_gives_the_references_bits(
    kind1: str, kind2: str, reference: Any
) -> None:
    _check_kinds(kind1, kind2, N_PAIRS, reference)


@pytest.mark.slow
def test_many_more_pairs_of_every_kind_give_the_references_bits(reference: Any) -> None:
    for kind1, kind2 in PAIRS:
        _check_kinds(kind1, kind2, 3 * N_PAIRS, reference)


def _check_kinds(kind1: str, kind2: str, n: int, reference: Any) -> None:
    T1, S1, T2, S2, mesh = _draws(len(kind1) * 13 + len(kind2) + n, n)
    args = (kind1, T1, _size(kind1, S1, mesh), kind2, T2, _size(kind2, S2, mesh))
    found = gjk.distance(*args)
    ref = reference(gjk.distance, *args)
    _assert_bits(found, ref)
    assert (ref.distance < 0).sum() > n // 10 and (ref.distance > 0).sum() > n // 10
    # touching: the second shape moved along the witness direction until the gap is ~0
    gap = found.points[:, 1] - found.points[:, 0]
    T2b = T2.copy()
    T2b[:, :3, 3] -= gap * (1 - 1e-12)
    args = (kind1, T1, _size(kind1, S1, mesh), kind2, T2b, _size(kind2, S2, mesh))
    _assert_bits(gjk.distance(*args), reference(gjk.distance, *args))


GJK_PAIRS = [
    ("cylinder", "cylinder"),
    ("capsule", "cylinder"),
    ("box", "box"),
    ("capsule", "capsule"),
    ("sphere", "box"),
    ("ellipsoid", "mesh"),
    ("plane", "mesh"),
    ("mesh", "plane"),
]


@pytest.mark.parametrize(("kind1", "kind2"), GJK_PAIRS, ids=[f"{a}-{b}" for a, b in GJK_PAIRS])
@pytest.mark.parametrize(
    "options",
    [{}, {"depth": False}, {"tol": 1e-6, "max_iter": 7}, {"epa_tol": 1e-5, "epa_faces": 40}],
    ids=["defaults", "no-depth", "coarse", "coarse-epa"],
)
def test_gjk_with_its_options_gives_the_references_bits(
    kind1: str, kind2: str, options: dict[str, Any], reference: Any
) -> None:
    T1, S1, T2, S2, mesh = _draws(len(kind1) + 7 * len(kind2), 100)
    args = (kind1, T1, _size(kind1, S1, mesh), kind2, T2, _size(kind2, S2, mesh))
    _assert_bits(gjk.gjk(*args, **options), reference(gjk.gjk, *args, **options))


def test_parallel_and_crossing_capsules_give_the_references_bits(reference: Any) -> None:
    rng = np.random.default_rng(3)
    n = 2000
    T1 = _poses(rng, n)
    T2 = T1.copy()  # parallel axes, offset across and along them
    T2[:, :3, 3] += rng.normal(size=(n, 3)) * rng.choice([1e-9, 0.05, 0.3], (n, 1))
    T2[n // 2 :, :3, :3] = _poses(rng, n - n // 2)[:, :3, :3]  # and crossing ones
    T2[n // 2 :: 7, :3, 3] = T1[n // 2 :: 7, :3, 3]  # crossing at the centre
    S1, S2 = rng.uniform(0.0, 0.2, (n, 3)), rng.uniform(0.0, 0.2, (n, 3))
    for kinds, m in (
        (("capsule", "capsule"), n),
        (("sphere", "capsule"), n),
        (("capsule", "cylinder"), 200),
    ):
        args = (kinds[0], T1[-m:], S1[-m:], kinds[1], T2[-m:], S2[-m:])
        found = gjk.distance(*args)
        _assert_bits(found, reference(gjk.distance, *args))
    assert (found.distance < 0).mean() > 0.3


@pytest.mark.parametrize("shape", BATCH_SHAPES, ids=str)
def test_batches_broadcast_as_the_reference(shape: tuple[int, ...], reference: Any) -> None:
    rng = np.random.default_rng(4)
    n = int(np.prod(shape, dtype=int))
    T1 = _poses(rng, n).reshape(*shape, 4, 4)
    T2 = _poses(rng, 1)[0]  # one pose against the batch
    S1 = rng.uniform(0.02, 0.2, (*shape, 2))  # a capsule's two entries
    for kind2, S2 in (("cylinder", np.array([0.1, 0.05])), ("box", rng.uniform(0.05, 0.2, 3))):
        args = ("capsule", T1, S1, kind2, T2, S2)
        found = gjk.distance(*args)
        assert found.distance.shape == shape and found.points.shape == (*shape, 2, 3)
        _assert_bits(found, reference(gjk.distance, *args))
        one = gjk.distance(
            "capsule", T1.reshape(-1, 4, 4)[-1], S1.reshape(-1, 2)[-1], kind2, T2, S2
        )
        assert one.distance == found.distance.reshape(-1)[-1]


def _model(rng: np.random.Generator) -> tuple[list[str], np.ndarray, np.ndarray, list[Any]]:
    """Shapes of every kind and all their pairs but plane-plane."""
    kinds = [
        "capsule",
        "capsule",
        "cylinder",
        "sphere",
        "box",
        "mesh",
        "ellipsoid",
        "plane",
        "mesh",
    ]
    sizes = rng.uniform(0.03, 0.15, (len(kinds), 3))
    verts = [_mesh(rng) if k == "mesh" else None for k in kinds]
    pairs = np.array([(a, b) for a, b in itertools.combinations(range(len(kinds)), 2)])
    return kinds, sizes, pairs, verts


@pytest.mark.parametrize("shape", [*BATCH_SHAPES, (40,)], ids=str)
def test_pair_distances_give_the_references_bits(shape: tuple[int, ...], reference: Any) -> None:
    rng = np.random.default_rng(5)
    kinds, sizes, pairs, verts = _model(rng)
    n = int(np.prod(shape, dtype=int))
    poses = _poses(rng, n * len(kinds), 0.25).reshape(*shape, len(kinds), 4, 4)
    found = gjk.pair_distances(kinds, sizes, pairs, poses, verts)
    ref = reference(gjk.pair_distances, kinds, sizes, pairs, poses, verts)
    assert found.distance.shape == (*shape, len(pairs))
    assert found.points.shape == (*shape, len(pairs), 2, 3)
    _assert_bits(found, ref)
    p = 17  # one pair alone: distance() of its two shapes
    a, b = pairs[p]
    one = gjk.distance(
        kinds[a], poses[..., a, :, :], verts[a] if verts[a] is not None else sizes[a],
        kinds[b], poses[..., b, :, :], verts[b] if verts[b] is not None else sizes[b],
    )  # fmt: skip
    assert np.array_equal(one.distance, found.distance[..., p])


@pytest.mark.parametrize("cutoff", [-0.05, 0.0, 0.1])
def test_a_cutoff_reports_only_the_nearer_pairs(cutoff: float, reference: Any) -> None:
    """With a cutoff, a pair at it or beyond is inf (points NaN) and every other pair keeps
    the bits it has without one (the bounding spheres skip only pairs beyond it), on the
    kernel and on the reference alike."""
    rng = np.random.default_rng(8)
    kinds, sizes, pairs, verts = _model(rng)
    poses = _poses(rng, 30 * len(kinds), 0.4).reshape(30, len(kinds), 4, 4)
    whole = gjk.pair_distances(kinds, sizes, pairs, poses, verts)
    cut = gjk.pair_distances(kinds, sizes, pairs, poses, verts, cutoff)
    _assert_bits(cut, reference(gjk.pair_distances, kinds, sizes, pairs, poses, verts, cutoff))
    near = whole.distance < cutoff
    assert 0 < near.sum() < near.size
    assert np.array_equal(cut.distance[near], whole.distance[near])
    assert np.array_equal(cut.points[near], whole.points[near])
    assert np.all(cut.distance[~near] == np.inf) and np.isnan(cut.points[~near]).all()


def test_bounding_radii_are_mujocos() -> None:
    """Each primitive's bounding radius is MuJoCo's geom_rbound for it."""
    import mujoco

    spec = mujoco.MjSpec()
    sizes = {"sphere": [0.1, 0, 0], "capsule": [0.05, 0.2, 0], "cylinder": [0.05, 0.2, 0],
             "box": [0.1, 0.2, 0.3], "ellipsoid": [0.1, 0.3, 0.2]}  # fmt: skip
    for kind, size in sizes.items():
        spec.worldbody.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}"), size=size)
    model = spec.compile()
    radii = gjk.bounding_radii(list(sizes), np.array(list(sizes.values())), [None] * 5)
    assert np.allclose(radii, model.geom_rbound, rtol=1e-15, atol=0)


def test_no_pairs_give_empty_results() -> None:
    rng = np.random.default_rng(6)
    kinds, sizes, _, verts = _model(rng)
    poses = _poses(rng, 2 * len(kinds)).reshape(2, len(kinds), 4, 4)
    found = gjk.pair_distances(kinds, sizes, np.zeros((0, 2), dtype=int), poses, verts)
    assert found.distance.shape == (2, 0) and found.points.shape == (2, 0, 2, 3)


def test_the_kernel_path_refuses_what_the_reference_refuses() -> None:
    T = np.eye(4)
    bad = T.copy()
    bad[0, 3] = np.nan
    with pytest.raises(InputError, match="capsule_capsule: pose1 contains NaN"):
        gjk.distance("capsule", bad, [0.1, 0.1], "capsule", T, [0.1, 0.1])
    with pytest.raises(InputError, match=r"gjk: a cylinder's sizes must be finite and >= 0"):
        gjk.gjk("cylinder", T, [-0.1, 0.1], "box", T, [0.1, 0.1, 0.1])
    with pytest.raises(InputError, match="gjk: a plane goes only with a mesh"):
        gjk.gjk("plane", T, None, "box", T, [0.1, 0.1, 0.1])


def test_torch_keeps_the_array_generic_closed_forms() -> None:
    torch = pytest.importorskip("torch")
    T = torch.eye(4, dtype=torch.float64)
    T2 = T.clone()
    T2[0, 3] = 0.5
    size = torch.tensor([0.1, 0.1], dtype=torch.float64, requires_grad=True)
    found = gjk.distance("capsule", T, size, "capsule", T2, size)
    assert isinstance(found.distance, torch.Tensor)
    found.distance.backward()
    assert size.grad is not None and float(size.grad[0]) == -2.0


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"kinds": ["capsule", "cone"]}, "unknown shape kind 'cone'"),
        ({"sizes": np.ones((3, 3))}, r"expected sizes of shape \(2, k\)"),
        ({"pairs": np.array([[0, 2]])}, "pairs must be indices of the 2 shapes, 0 to 1"),
        ({"pairs": np.array([0, 1])}, r"expected pairs of shape \(P, 2\) of integers"),
        ({"kinds": ["plane", "plane"]}, "shapes 0 and 1 are two planes"),
        ({"poses": np.zeros((3, 4, 4))}, r"expected poses of shape \(..., 2, 4, 4\)"),
        ({"poses": np.full((2, 4, 4), np.nan)}, "poses contain NaN or inf"),
        ({"sizes": -np.ones((2, 3))}, "a capsule's sizes must be finite and >= 0"),
        ({"vertices": [None, np.ones((4, 3))]}, r"give vertices \(V, 3\) for each mesh"),
        ({"cutoff": np.nan}, "cutoff must be a number"),
        ({"cutoff": "far"}, r"cutoff must be a number \(m\), got str"),
        (
            {"kinds": ["capsule", "mesh"], "vertices": [None, np.ones((4, 2))]},
            r"a mesh's vertices must be an array of shape \(V, 3\)",
        ),
    ],
    ids=lambda v: v if isinstance(v, str) else "",
)
def test_pair_distances_bad_input_is_one_clear_error(change: dict[str, Any], message: str) -> None:
    args: dict[str, Any] = {
        "kinds": ["capsule", "capsule"],
        "sizes": np.full((2, 3), 0.1),
        "pairs": np.array([[0, 1]]),
        "poses": np.tile(np.eye(4), (2, 1, 1)),
        "vertices": None,
    }
    args.update(change)
    with pytest.raises(InputError, match=f"^pair_distances: {message}"):
        gjk.pair_distances(**args)
