"""Tree.distances, min_distance and in_collision against MuJoCo on the same model.

MuJoCo is the reference twice over: ``mj_collision`` (its contacts with ``dist < 0`` are the
colliding pairs) and ``mj_geomDistance`` called here on MuJoCo's own FK (``mj_kinematics`` of
the qpos), with obstacles added to the model's spec as geoms by this file. Closed forms
(sphere against a capsule's segment) and coal through Pinocchio are the others.
"""

from __future__ import annotations

import itertools
import math
import pathlib
import sysconfig

import mujoco
import numpy as np
import pytest
from helpers import load_quiet, pinocchio_q, ur5e_obstacles
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin.collision import Box, Capsule, Mesh, Plane, Sphere, model_of
from poekin.errors import InputError, UnknownFrameError

PRIMITIVE_TOL = 1e-9  # the bound for primitive pairs
N_CONFIGS = 300
CYLINDER = mujoco.mjtGeom.mjGEOM_CYLINDER  # measured by GJK: its points to MuJoCo's tolerance


def _ur5e() -> poekin.Tree:
    return poekin.load_tree(load_quiet("universal_robots_ur5e"))


@pytest.fixture(scope="module")
def ur5e_tree() -> poekin.Tree:
    return _ur5e()


def _collision_geoms(model: mujoco.MjModel) -> list[int]:
    return [g for g in range(model.ngeom) if model.geom_contype[g] or model.geom_conaffinity[g]]


def mj_reference(
    model: mujoco.MjModel, qpos: np.ndarray, pairs: list[tuple[int, int]]
) -> tuple[np.ndarray, np.ndarray]:
    """``(n, P)`` distances and ``(n, P, 2, 3)`` witness points by ``mj_geomDistance`` after
    MuJoCo's own ``mj_kinematics`` of each qpos, on MuJoCo geom ids."""
    data = mujoco.MjData(model)
    dist = np.empty((len(qpos), len(pairs)))
    points = np.empty((len(qpos), len(pairs), 2, 3))
    fromto = np.zeros(6)
    for c, row in enumerate(qpos):
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        for p, (a, b) in enumerate(pairs):
            dist[c, p] = mujoco.mj_geomDistance(model, data, a, b, math.inf, fromto)
            points[c, p] = fromto.reshape(2, 3)
    return dist, points


def mj_colliding(model: mujoco.MjModel, qpos: np.ndarray) -> list[set[frozenset[int]]]:
    """Per configuration, the geom pairs that ``mj_collision`` finds penetrating."""
    data = mujoco.MjData(model)
    out = []
    for row in qpos:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        out.append({frozenset(map(int, c.geom)) for c in data.contact if c.dist < 0})
    return out


def test_ur5e_self_collision_matches_mj_collision_and_mj_geom_distance(
    ur5e_tree: poekin.Tree,
) -> None:
    """Random configurations over the joint ranges: the same colliding pairs as
    mj_collision's contacts, distances and witness points within 1e-9 of mj_geomDistance on
    MuJoCo's FK for the capsules (MuJoCo's closed form), within its convex tolerance for the
    cylinder (GJK and EPA)."""
    reference = load_quiet("universal_robots_ur5e").model
    qpos = poekin.sample_qpos(ur5e_tree, N_CONFIGS, seed=3, within_limits=True)
    found = ur5e_tree.distances(qpos)
    ids = _collision_geoms(reference)
    pairs = [(ids[a], ids[b]) for a, b in model_of(ur5e_tree).pairs.tolist()]
    dist, points = mj_reference(reference, qpos, pairs)
    _assert_distances(reference, pairs, found.distance, dist)
    gjk = [k for k, (a, b) in enumerate(pairs) if CYLINDER in reference.geom_type[[a, b]]]
    err = np.abs(found.points - points).max(axis=(-1, -2))
    apart = found.distance > 0
    # apart, GJK: near-parallel surfaces leave the points less certain than the distance
    assert err[:, gjk][apart[:, gjk]].max() < 1e-5
    # sunk in: the points of the deepest penetration, where MuJoCo's EPA falls short
    assert err[:, gjk][~apart[:, gjk]].max(initial=0.0) < 1e-4
    err[:, gjk] = 0.0
    same = err <= PRIMITIVE_TOL
    for c, p in zip(*np.nonzero(~same), strict=True):  # parallel axes: no one closest pair
        _assert_on_parallel_surfaces(reference, qpos[c], pairs[p], found.points[c, p])
    assert same.mean() > 0.9
    ours = [{frozenset(pairs[p]) for p in np.flatnonzero(row < 0)} for row in found.distance]
    assert ours == mj_colliding(reference, qpos)
    rate = np.mean(ur5e_tree.in_collision(qpos))
    assert 0.1 < rate < 0.25  # 16.7% of 10,000 (benchmarks/bench_collision.py); the issue: 17%
    np.testing.assert_array_equal(ur5e_tree.min_distance(qpos), found.distance.min(axis=-1))


@pytest.mark.slow
def test_ur5e_10000_configurations_collide_as_mj_collision_says(ur5e_tree: poekin.Tree) -> None:
    """The issue's 10,000 random configurations: the same colliding pairs as mj_collision,
    the distances as mj_geomDistance's on MuJoCo's FK (:func:`_assert_distances`)."""
    reference = load_quiet("universal_robots_ur5e").model
    qpos = poekin.sample_qpos(ur5e_tree, 10_000, seed=11, within_limits=True)
    found = ur5e_tree.distances(qpos)
    ids = _collision_geoms(reference)
    pairs = [(ids[a], ids[b]) for a, b in model_of(ur5e_tree).pairs.tolist()]
    dist, _ = mj_reference(reference, qpos, pairs)
    _assert_distances(reference, pairs, found.distance, dist)
    ours = [{frozenset(pairs[p]) for p in np.flatnonzero(row < 0)} for row in found.distance]
    assert ours == mj_colliding(reference, qpos)
    # where MuJoCo's depth falls short most, coal (an independent EPA) is within 1e-5 of
    # poekin's, and no deeper: an EPA's estimate of a depth only grows toward it
    gap = dist - found.distance
    for c, k in np.argwhere(gap > 1e-6)[np.argsort(-gap[gap > 1e-6])][:20]:
        theirs = _coal(ur5e_tree, [], qpos[c], k)
        assert found.distance[c, k] <= theirs + 1e-9 and theirs - found.distance[c, k] < 1e-5


def _assert_distances(
    model: mujoco.MjModel, pairs: list[tuple[int, int]], found: np.ndarray, expected: np.ndarray
) -> None:
    """Capsule pairs (MuJoCo's closed form) within 1e-9; pairs with the cylinder, which MuJoCo
    measures by GJK and EPA, within its convex tolerance (1e-6)."""
    gjk = [k for k, (a, b) in enumerate(pairs) if CYLINDER in model.geom_type[[a, b]]]
    exact = np.setdiff1d(np.arange(len(pairs)), gjk)
    np.testing.assert_allclose(found[:, exact], expected[:, exact], rtol=0, atol=PRIMITIVE_TOL)
    ours, theirs = found[:, gjk], expected[:, gjk]
    apart = (ours > 0) & (theirs > 0)
    np.testing.assert_allclose(ours[apart], theirs[apart], rtol=0, atol=1e-6)
    # sunk in: MuJoCo's EPA stops short of the depth (coal's agrees with poekin's: see
    # test_ur5e_10000_configurations...), never by more than 2 mm, and never past it
    assert np.all(ours[~apart] <= theirs[~apart] + 1e-6)
    assert np.all(theirs[~apart] - ours[~apart] < 2e-3)


def _assert_on_parallel_surfaces(
    model: mujoco.MjModel, qpos: np.ndarray, pair: tuple[int, int], points: np.ndarray
) -> None:
    """Where two capsules' witness points differ from MuJoCo's, their axes are parallel (a
    whole segment of closest points), and each point is on its geom's
    side: at its radius from its axis (MuJoCo's FK)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    axes = [data.geom_xmat[g].reshape(3, 3)[:, 2] for g in pair]
    assert np.linalg.norm(np.cross(*axes)) < 1e-6, pair
    for g, axis, point in zip(pair, axes, points, strict=True):
        off = point - data.geom_xpos[g]
        from_axis = np.linalg.norm(off - np.dot(off, axis) * axis)
        assert abs(from_axis - model.geom_size[g, 0]) < PRIMITIVE_TOL


def test_witness_points_are_the_distance_apart(ur5e_tree: poekin.Tree) -> None:
    found = ur5e_tree.distances(poekin.sample_qpos(ur5e_tree, 50, seed=4))
    gap = np.linalg.norm(found.points[..., 1, :] - found.points[..., 0, :], axis=-1)
    np.testing.assert_allclose(gap, np.abs(found.distance), atol=1e-12)


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_batch_shapes(ur5e_tree: poekin.Tree, shape: tuple[int, ...]) -> None:
    n = int(np.prod(shape, dtype=int))
    flat = poekin.sample_qpos(ur5e_tree, n, seed=5)
    qpos = flat.reshape(*shape, 6)
    found = ur5e_tree.distances(qpos)
    P = len(found.pairs)
    assert found.distance.shape == (*shape, P)
    assert found.points.shape == (*shape, P, 2, 3)
    assert ur5e_tree.in_collision(qpos).shape == shape
    assert ur5e_tree.min_distance(qpos).shape == shape
    np.testing.assert_array_equal(found.distance.reshape(n, P), ur5e_tree.distances(flat).distance)
    assert not found.distance.flags.writeable


def _segment_point(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(a + t * (b - a) - p))


@settings(max_examples=40, deadline=None)
@given(
    centre=st.tuples(*[st.floats(-0.8, 0.8)] * 3),
    radius=st.floats(0.01, 0.3),
    seed=st.integers(0, 1000),
)
def test_sphere_obstacle_against_the_capsules_closed_form(
    centre: tuple[float, float, float], radius: float, seed: int
) -> None:
    """A sphere obstacle and each UR5e capsule: the distance from the sphere's centre to the
    capsule's segment, less both radii (the segment from the geom's pose in MuJoCo's FK)."""
    tree = _cached_tree()
    reference = load_quiet("universal_robots_ur5e").model
    data = mujoco.MjData(reference)
    qpos = poekin.sample_qpos(tree, 1, seed=seed)[0]
    data.qpos[:] = qpos
    mujoco.mj_kinematics(reference, data)
    c = np.array(centre)
    found = tree.distances(qpos, [Sphere(radius, pose=[*centre, 1.0, 0.0, 0.0, 0.0])])
    ids = _collision_geoms(reference)
    for k, g in enumerate(ids):
        if reference.geom_type[g] != mujoco.mjtGeom.mjGEOM_CAPSULE:
            continue
        axis = data.geom_xmat[g].reshape(3, 3)[:, 2] * reference.geom_size[g, 1]
        r = reference.geom_size[g, 0]
        expected = _segment_point(data.geom_xpos[g] - axis, data.geom_xpos[g] + axis, c)
        p = found.pairs.index((model_of(tree).geom_names[k], "sphere0"))
        assert abs(found.distance[p] - (expected - r - radius)) < PRIMITIVE_TOL


_TREES: dict[str, poekin.Tree] = {}


def _cached_tree() -> poekin.Tree:
    if "ur5e" not in _TREES:
        _TREES["ur5e"] = _ur5e()
    return _TREES["ur5e"]


def _cube(half: float) -> np.ndarray:
    return np.array(
        [[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    )


def _obstacles() -> list[object]:
    turn = np.eye(4)
    turn[:3, :3] = poekin.exp_so3(np.array([0.3, -0.4, 0.5]))
    turn[:3, 3] = [0.4, -0.2, 0.3]
    held = np.eye(4)
    held[:3, 3] = [0.0, 0.0, 0.05]
    return [
        Box([0.6, 0.6, 0.02], pose=[0.0, 0.0, -0.05, 1.0, 0.0, 0.0, 0.0], name="table"),
        Sphere(0.1, pose=turn),
        Capsule(0.05, 0.2, pose=turn @ np.diag([1.0, -1.0, -1.0, 1.0])),
        Plane(pose=[0.0, 0.0, -0.3, 1.0, 0.0, 0.0, 0.0]),
        Mesh(_cube(0.07) + np.array([0.01, 0.0, 0.02]), pose=[-0.3, 0.3, 0.4, 0.0, 1.0, 0.0, 0.0]),
        Box([0.03, 0.03, 0.05], pose=held, frame="attachment_site", name="tool"),
    ]


def _reference_with(obstacles: list[object], tree: poekin.Tree) -> mujoco.MjModel:
    """The UR5e's kinematics compile with the obstacles as geoms of their frames' bodies,
    placed by MuJoCo (a site's pose composed by hand from the compiled model)."""
    spec = poekin.io.sources.kinematics_spec("universal_robots_ur5e")
    base = load_quiet("universal_robots_ur5e").model
    types = {
        Box: mujoco.mjtGeom.mjGEOM_BOX,
        Sphere: mujoco.mjtGeom.mjGEOM_SPHERE,
        Capsule: mujoco.mjtGeom.mjGEOM_CAPSULE,
        Plane: mujoco.mjtGeom.mjGEOM_PLANE,
        Mesh: mujoco.mjtGeom.mjGEOM_MESH,
    }
    for k, o in enumerate(obstacles):
        pose = np.asarray(o.pose)  # type: ignore[attr-defined]
        if o.frame is None:  # type: ignore[attr-defined]
            parent = spec.worldbody
        else:
            site = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SITE, o.frame)  # type: ignore[attr-defined]
            body = int(base.site_bodyid[site])
            parent = spec.body(mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, body))
            T = np.eye(4)
            T[:3, :3] = poekin.quat_to_rotation(base.site_quat[site])
            T[:3, 3] = base.site_pos[site]
            pose = T @ pose
        body = parent.add_body(pos=pose[:3, 3], quat=poekin.rotation_to_quat(pose[:3, :3]))
        geom = body.add_geom(type=types[type(o)], name=f"obstacle{k}", contype=0, conaffinity=0)
        if isinstance(o, Box):
            geom.size = o.half_sizes
        elif isinstance(o, Sphere):
            geom.size = [o.radius, 0, 0]
        elif isinstance(o, Capsule):
            geom.size = [o.radius, o.half_length, 0]
        elif isinstance(o, Plane):
            geom.size = [1, 1, 1]
        else:
            spec.add_mesh(name=f"mesh{k}", uservert=np.asarray(o.vertices).ravel().tolist())  # type: ignore[attr-defined]
            geom.meshname = f"mesh{k}"
    return spec.compile()


def test_obstacles_match_mj_geom_distance_on_mujocos_own_model(ur5e_tree: poekin.Tree) -> None:
    """Every obstacle kind, world-fixed and held at the attachment site, against MuJoCo's
    distance on a model where MuJoCo places them; the held tool is never paired with the
    wrist_3 link it is attached to (nor, through welding, its parent's geoms)."""
    obstacles = _obstacles()
    reference = _reference_with(obstacles, ur5e_tree)
    qpos = poekin.sample_qpos(ur5e_tree, 40, seed=6, within_limits=True)
    found = ur5e_tree.distances(qpos, obstacles)
    ids = {name: g for g, name in enumerate(_names(reference, ur5e_tree, obstacles))}
    pairs = [(ids[a], ids[b]) for a, b in found.pairs]
    dist, _ = mj_reference(reference, qpos, pairs)
    mesh = [k for k, (a, b) in enumerate(found.pairs) if "mesh4" in (a, b)]
    box_box = [k for k, (a, b) in enumerate(found.pairs) if {a, b} == {"table", "tool"}]
    kinds = _pair_kinds(ur5e_tree, obstacles)
    cylinder = [k for k, pair in enumerate(kinds) if "cylinder" in pair]  # GJK, both sides
    exact = np.setdiff1d(np.arange(len(pairs)), mesh + box_box + cylinder)
    # a capsule or cylinder sunk into a box: MuJoCo's depth falls short (by 0.16 m here, even
    # to a positive distance), coal's is poekin's; apart, or any other kind, MuJoCo's is exact
    into_box = np.zeros_like(found.distance, dtype=bool)
    for k, pair in enumerate(kinds):
        if "box" in pair and set(pair) & {"capsule", "cylinder"}:
            into_box[:, k] = (found.distance[:, k] < 0) | (dist[:, k] < 0)
    assert into_box.any()  # the table catches the arm in some configurations
    for c, k in zip(*np.nonzero(into_box), strict=True):  # coal's EPA on a cylinder: to 1e-6
        tol = 1e-6 if "cylinder" in kinds[k] else 1e-9
        assert found.distance[c, k] == pytest.approx(
            _coal(ur5e_tree, obstacles, qpos[c], k), abs=tol
        )
    dist = np.where(into_box, found.distance, dist)
    np.testing.assert_allclose(found.distance[:, exact], dist[:, exact], atol=PRIMITIVE_TOL)
    np.testing.assert_allclose(found.distance, dist, atol=1e-6)  # GJK: MuJoCo's tolerance
    tool_pairs = {frozenset(p) for p in found.pairs if "tool" in p}
    assert frozenset(("wrist_3_link", "tool")) not in tool_pairs
    assert frozenset(("wrist_2_link#0", "tool")) not in tool_pairs
    assert frozenset(("forearm_link#1", "tool")) in tool_pairs
    assert frozenset(("table", "tool")) in tool_pairs
    assert not any({"table", "sphere1"} == set(p) for p in found.pairs)  # both fixed


def _pair_kinds(tree: poekin.Tree, obstacles: list[object]) -> list[tuple[str, str]]:
    """The kinds of the two shapes of each pair of ``tree.distances``'s scene, in its order."""
    from poekin.collision import query

    scene = query._scene(tree, model_of(tree), query.as_obstacles(obstacles), ())
    kinds, _, _ = query._shapes(scene, len(scene.frame))
    return [(kinds[i], kinds[j]) for i, j in scene.pairs.tolist()]


def _coal(tree: poekin.Tree, obstacles: list[object], qpos: np.ndarray, k: int) -> float:
    """Pair ``k``'s signed distance by coal (capsule, cylinder and box only), on poekin's FK
    of the geoms' poses."""
    coal = pytest.importorskip("coal")
    from poekin.collision import query

    collision = model_of(tree)
    scene = query._scene(tree, collision, query.as_obstacles(obstacles), ())
    frames = np.concatenate([tree.fk(qpos), tree.base[None], np.eye(4)[None]])
    poses = frames[scene.frame] @ scene.local
    kinds, sizes, _ = query._shapes(scene, len(poses))
    make = {
        "capsule": lambda s: coal.Capsule(s[0], 2 * s[1]),
        "cylinder": lambda s: coal.Cylinder(s[0], 2 * s[1]),
        "box": lambda s: coal.Box(*(2 * s)),
    }
    i, j = scene.pairs[k]
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    request.enable_signed_distance = True
    return float(
        coal.distance(
            make[kinds[i]](sizes[i]),
            coal.Transform3s(poses[i][:3, :3], poses[i][:3, 3]),
            make[kinds[j]](sizes[j]),
            coal.Transform3s(poses[j][:3, :3], poses[j][:3, 3]),
            request,
            result,
        )
    )


def _names(model: mujoco.MjModel, tree: poekin.Tree, obstacles: list[object]) -> list[str]:
    """The reference model's geom labels: poekin's geom names in order for the collision
    geoms, obstacles by their poekin names."""
    robot = list(model_of(tree).geom_names)
    out, k = [], 0
    labels = [o.name or f"{type(o).__name__.lower()}{j}" for j, o in enumerate(obstacles)]  # type: ignore[attr-defined]
    for g in range(model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        if name.startswith("obstacle"):
            out.append(labels[int(name[len("obstacle") :])])
        elif model.geom_contype[g]:
            out.append(robot[k])
            k += 1
        else:
            out.append(f"visual{g}")
    return out


def test_in_collision_with_a_table_and_a_margin(ur5e_tree: poekin.Tree) -> None:
    table = Box([0.6, 0.6, 0.02], pose=[0.0, 0.0, -0.05, 1.0, 0.0, 0.0, 0.0])
    qpos = poekin.sample_qpos(ur5e_tree, 60, seed=7)
    found = ur5e_tree.distances(qpos, [table])
    for margin in (0.0, 0.01, -0.005):
        np.testing.assert_array_equal(
            ur5e_tree.in_collision(qpos, [table], margin=margin),
            (found.distance < margin).any(axis=-1),
        )
    near = ur5e_tree.distances(qpos, [table], margin=0.05)
    far = found.distance >= 0.05
    assert np.all(np.isinf(near.distance[far])) and np.all(np.isnan(near.points[far]))
    np.testing.assert_array_equal(near.distance[~far], found.distance[~far])


def _panda() -> pathlib.Path:
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    found = site / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
    if not found.is_dir():
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return found / "panda_description" / "urdf" / "panda.urdf"


def test_urdf_meshes_against_coal_through_pinocchio() -> None:
    """The Panda's STL meshes (as convex hulls, which MuJoCo collides) and finger boxes:
    every pair's distance against coal's (Pinocchio's geometry model), where both are apart
    by more than MuJoCo's convex tolerance allows to matter."""
    pin = pytest.importorskip("pinocchio")
    coal = pytest.importorskip("coal")
    path = _panda()
    tree = poekin.load_tree(path)
    model, geometry, _ = pin.buildModelsFromUrdf(str(path), package_dirs=[str(path.parents[4])])
    for obj in geometry.geometryObjects:
        if isinstance(obj.geometry, coal.BVHModelBase):
            obj.geometry.buildConvexHull(True, "Qt")
            obj.geometry = obj.geometry.convex
    index = {}
    for k, obj in enumerate(geometry.geometryObjects):
        link, _, j = obj.name.rpartition("_")
        index[link, int(j)] = k
    names = model_of(tree).geom_names
    ours = {name: index[name.partition("#")[0], int(name.partition("#")[2] or 0)] for name in names}
    qpos = poekin.sample_qpos(tree, 20, seed=8, within_limits=True)
    found = tree.distances(qpos)
    for a, b in found.pairs:
        geometry.addCollisionPair(pin.CollisionPair(ours[a], ours[b]))
    data, gdata = model.createData(), geometry.createData()
    qs = pinocchio_q(model, tree, qpos)
    for c in range(len(qpos)):
        pin.updateGeometryPlacements(model, data, geometry, gdata, qs[c])
        pin.computeDistances(geometry, gdata)
        theirs = np.array([r.min_distance for r in gdata.distanceResults])
        apart = (theirs > 1e-4) & (found.distance[c] > 1e-4)
        np.testing.assert_allclose(found.distance[c][apart], theirs[apart], atol=1e-5)
        assert np.array_equal(found.distance[c] < -1e-4, theirs < -1e-4)
    # in_collision's short cuts (the boxes first, the meshes only where they are clear, each
    # configuration's pairs up to its first hit, the bounding spheres) change no answer
    hits = {m: tree.in_collision(qpos, margin=m) for m in (0.0, 0.03)}
    for margin, hit in hits.items():
        np.testing.assert_array_equal(hit, (found.distance < margin).any(axis=-1))
    assert 0 < hits[0.0].sum() < len(qpos)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Box([0.1, -0.2, 0.1]), "Box: half size along y must be a finite size > 0"),
        (lambda: Box([0.1, 0.2]), "Box: half_sizes must be 3 numbers"),
        (lambda: Sphere(-1.0), "Sphere: radius must be a finite size > 0 (m), got -1.0"),
        (lambda: Sphere(float("nan")), "Sphere: radius must be a finite size > 0"),
        (lambda: Capsule(0.1, 0.0), "Capsule: half_length must be a finite size > 0"),
        (lambda: Sphere(0.1, pose=np.full((4, 4), np.nan)), "Sphere: pose contains NaN"),
        (lambda: Plane(pose=np.diag([1.0, 2.0, 1.0, 1.0])), "Plane: pose is not a rigid"),
        (lambda: Plane(pose=np.diag([1.0, 1.0, -1.0, 1.0])), "Plane: pose is not a rigid"),
        (lambda: Box([0.1] * 3, pose=np.eye(3)), "Box: pose must be a (4, 4) rigid transform"),
        (lambda: Sphere(0.1, pose=[0, 0, 0, 2, 0, 0, 0]), "the quaternion qw qx qy qz has norm"),
        (lambda: Sphere(0.1, frame=""), "frame must be a body or site name"),
        (lambda: Mesh(np.zeros((3, 3))), "vertices must be an (n, 3) array with n >= 4"),
        (lambda: Mesh(_cube(0.1) * [1, 1, 0]), "Mesh: the vertices lie in a plane"),
        (lambda: Mesh(np.full((4, 3), np.inf)), "Mesh: the vertices contain NaN or inf"),
        (lambda: Mesh(object()), "Mesh: give a mesh file's path or an (n, 3) array"),
        (lambda: Mesh("no/such/file.stl"), "Mesh: no mesh file 'no/such/file.stl'"),
    ],
)
def test_bad_obstacles(make: object, message: str) -> None:
    with pytest.raises(InputError, match=_literal(message)) as info:
        make()  # type: ignore[operator]
    assert "\n" not in str(info.value)


def _literal(text: str) -> str:
    import re

    return re.escape(text)


def test_a_mesh_file_that_is_not_a_mesh(tmp_path: pathlib.Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("not a mesh")
    with pytest.raises(InputError, match=r"Mesh: notes.txt is not a mesh file: MuJoCo reads"):
        Mesh(notes)
    broken = tmp_path / "broken.stl"
    broken.write_bytes(b"solid nothing\nendsolid\n")
    with pytest.raises(InputError, match=r"Mesh: MuJoCo cannot read broken.stl as a mesh: "):
        Mesh(broken)


def test_a_mesh_file_reads_as_its_vertices(tmp_path: pathlib.Path) -> None:
    """An OBJ written here reads back as its vertices, in the file's frame (MuJoCo's compile
    moves a mesh to its centre of mass; the obstacle undoes that), to MuJoCo's float32."""
    cube = _cube(0.05) + np.array([0.3, 0.0, 0.1])
    lines = [f"v {x} {y} {z}" for x, y, z in cube]
    faces = ["f 1 3 4 2", "f 5 6 8 7", "f 1 2 6 5", "f 3 7 8 4", "f 1 5 7 3", "f 2 4 8 6"]
    path = tmp_path / "cube.obj"
    path.write_text("\n".join(lines + faces) + "\n")
    mesh = Mesh(path)
    got = mesh.vertices[np.lexsort(mesh.vertices.T)]
    np.testing.assert_allclose(got, cube[np.lexsort(cube.T)], atol=1e-7)


def test_query_bad_input(ur5e_tree: poekin.Tree) -> None:
    q = np.zeros(6)
    with pytest.raises(UnknownFrameError, match="did you mean 'attachment_site'"):
        ur5e_tree.distances(q, [Sphere(0.1, frame="atachment_site")])
    with pytest.raises(InputError, match="distances: margin must be a number"):
        ur5e_tree.distances(q, margin=float("nan"))
    with pytest.raises(InputError, match=r"obstacles must be poekin\.collision\.Box"):
        ur5e_tree.distances(q, [np.eye(4)])
    with pytest.raises(InputError, match="obstacle name 'wrist_1_link' is taken"):
        ur5e_tree.distances(q, [Sphere(0.1, name="wrist_1_link")])
    with pytest.raises(InputError, match="qpos values"):
        ur5e_tree.distances(np.zeros(5))
    with pytest.raises(InputError, match="in_collision: margin must be a number"):
        ur5e_tree.in_collision(q, margin="far")  # type: ignore[arg-type]


@pytest.mark.parametrize("margin", [0.0, 0.02])
def test_the_kernels_broad_phase_changes_no_answer(
    ur5e_tree: poekin.Tree, margin: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """in_collision (which stops at a configuration's first hit) and distances with a margin
    (which skip pairs whose bounds lie beyond it) on the kernel give the NumPy reference's
    answers, which measure every pair: the same booleans, the same bits, on the UR5e's
    capsules and cylinders with a table, a post, a floor and a ball held by the tool."""
    from poekin.collision import gjk

    scene = [
        *ur5e_obstacles(),
        Plane(pose=[0.0, 0.0, -0.3, 1.0, 0.0, 0.0, 0.0], name="floor"),
    ]
    qpos = poekin.sample_qpos(ur5e_tree, 300, seed=21)
    hit = ur5e_tree.in_collision(qpos, scene, margin=margin)
    near = ur5e_tree.distances(qpos, scene, margin=margin)
    monkeypatch.setattr(gjk, "_kernel", None)
    np.testing.assert_array_equal(hit, ur5e_tree.in_collision(qpos, scene, margin=margin))
    reference = ur5e_tree.distances(qpos, scene, margin=margin)
    np.testing.assert_array_equal(near.distance, reference.distance)
    np.testing.assert_array_equal(near.points, reference.points)
    assert 0.1 < hit.mean() < 0.9
    assert np.isinf(near.distance).mean() > 0.5  # most pairs lie beyond the margin


def test_first_clear_stops_where_the_reference_finds_the_first_clear(
    ur5e_tree: poekin.Tree, monkeypatch: pytest.MonkeyPatch
) -> None:
    """query.first_clear on the kernel (each group's configurations in order, up to the first
    clear one) and on the NumPy reference (every configuration checked, then the first clear
    one taken): the same indices, over groups of every size (empty ones too, and
    configurations after the last group that must not count); MuJoCo's mesh pairs (a mesh
    obstacle) go through hits."""
    from poekin.collision import gjk, query

    scene = [*ur5e_obstacles(), Plane(pose=[0.0, 0.0, -0.3, 1.0, 0.0, 0.0, 0.0], name="floor")]
    qpos = poekin.sample_qpos(ur5e_tree, 400, seed=22)
    frames = np.asarray(ur5e_tree.fk(qpos))
    sizes = np.random.default_rng(5).integers(0, 9, 60)
    groups = np.concatenate([[0], np.cumsum(sizes)])
    assert groups[-1] < len(qpos)
    margin = 0.01
    checked = query.prepare(ur5e_tree, scene)
    got = query.first_clear(checked, frames, margin, groups)
    # the frames as the kernel computes them itself, a block of configurations at a time
    fused = query.frames_of(ur5e_tree, qpos)
    assert isinstance(fused, tuple) == poekin.compiled_kernel()
    np.testing.assert_array_equal(query.first_clear(checked, fused, margin, groups), got)
    np.testing.assert_array_equal(
        query.hits(checked, fused, margin), query.hits(checked, frames, margin)
    )
    hit = ur5e_tree.in_collision(qpos, scene, margin=margin)
    for i, (lo, hi) in enumerate(itertools.pairwise(groups)):  # by hand
        clear = np.flatnonzero(~hit[lo:hi])
        assert got[i] == (lo + clear[0] if len(clear) else -1)
    assert (got >= 0).sum() > 10 and (got[sizes > 0] < 0).sum() > 3  # both outcomes occur
    monkeypatch.setattr(gjk, "_kernel", None)
    np.testing.assert_array_equal(query.first_clear(checked, frames, margin, groups), got)
    block = Mesh(np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T * 0.1)
    meshed = query.prepare(ur5e_tree, [*scene, block])
    flags = query.hits(meshed, frames, margin)
    np.testing.assert_array_equal(
        query.first_clear(meshed, frames, margin, groups), gjk.first_false(flags, groups)
    )


def test_first_false_by_hand() -> None:
    from poekin.collision.gjk import first_false

    flags = np.array([True, False, False, True, True, False, True])
    got = first_false(flags, np.array([0, 3, 3, 5, 6]))
    np.testing.assert_array_equal(got, [1, -1, -1, 5])


def test_a_scene_is_prepared_once_per_set_of_obstacles(ur5e_tree: poekin.Tree) -> None:
    """query.prepare keeps the last scenes of a tree, looked up by the obstacles' values: the
    same obstacles again (new objects) give the same prepared scene; another pose or other
    pairs left out give another; the oldest is dropped beyond PREPARED."""
    from poekin.collision import query

    table = Box((0.5, 0.5, 0.01), pose=[0.0, 0.0, -0.05, 1.0, 0.0, 0.0, 0.0])
    first = query.prepare(ur5e_tree, [table])
    again = Box((0.5, 0.5, 0.01), pose=[0.0, 0.0, -0.05, 1.0, 0.0, 0.0, 0.0])
    assert query.prepare(ur5e_tree, [again]) is first
    moved = query.prepare(ur5e_tree, [Box((0.5, 0.5, 0.01), pose=[0, 0, -0.2, 1, 0, 0, 0])])
    assert moved is not first and moved.local[-1, 2, 3] != first.local[-1, 2, 3]
    ignored = query.prepare(ur5e_tree, [table], [("wrist_3_link", "box0")])
    assert ignored is not first and len(ignored.scene.pairs) < len(first.scene.pairs)
    for k in range(query.PREPARED):
        query.prepare(ur5e_tree, [Sphere(0.01 * (k + 1))])
    assert query.prepare(ur5e_tree, [table]) is not first


def test_a_height_field_is_mujocos_to_measure(tmp_path: pathlib.Path) -> None:
    """A rod swinging over a height field: the pair is MuJoCo's (mj_geomDistance on the same
    poses, within a distmax: MuJoCo measures a height field no farther), distances and
    in_collision alike, with a capsule of the world beside it measured by poekin's kernel."""
    path = tmp_path / "terrain.xml"
    path.write_text(
        """<mujoco>
  <asset><hfield name="ground" nrow="3" ncol="3" size="1 1 0.1 0.1"
    elevation="0 0.5 0 0.5 1 0.5 0 0.5 0"/></asset>
  <worldbody>
    <geom name="ground" type="hfield" hfield="ground"/>
    <geom name="post" type="capsule" fromto="0.5 0 0 0.5 0 0.4" size="0.02"/>
    <body name="link" pos="0 0 0.3">
      <joint name="hinge" axis="0 1 0"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
    </body>
  </worldbody>
</mujoco>""",
        encoding="utf-8",
    )
    tree = poekin.load_tree(path)
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    qpos = np.linspace(-1.5, 1.5, 31)[:, None]
    margin = 0.05  # MuJoCo measures a height field only within a distmax
    found = tree.distances(qpos, margin=margin)
    assert found.pairs == (("ground", "rod"), ("post", "rod"))
    expected = np.empty((len(qpos), 2))
    fromto = np.zeros(6)
    for c, row in enumerate(qpos):
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        for p, g in enumerate((0, 1)):
            expected[c, p] = mujoco.mj_geomDistance(model, data, g, 2, margin, fromto)
    expected[expected >= margin] = np.inf
    np.testing.assert_allclose(found.distance, expected, rtol=0, atol=1e-9)
    assert np.isfinite(found.distance[:, 0]).any() and np.isfinite(found.distance[:, 1]).any()
    for m in (0.0, margin):
        np.testing.assert_array_equal(
            tree.in_collision(qpos, margin=m), (expected < m).any(axis=-1)
        )
    assert 0 < tree.in_collision(qpos).sum() < len(qpos)
