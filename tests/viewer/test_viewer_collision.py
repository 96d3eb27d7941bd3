"""The viewer's collision view: which shapes are red and where the witness points are, checked
against MuJoCo's own collision detector (``mj_collision``) and distance (``mj_geomDistance``)
after MuJoCo's own FK (``mj_kinematics``), on a model where MuJoCo places the obstacles; the
shapes' poses against ``geom_xpos``/``geom_xmat``; the triangles against the shapes; the page's
nodes through the Python handle (no browser); the obstacle file and ``poekin view
--collision``."""

from __future__ import annotations

import json
import math
import pathlib
import sysconfig
import warnings
from collections.abc import Iterator

import mujoco
import numpy as np
import pytest
from helpers import assert_close, assert_one_error_line, load_quiet, run
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin.collision import Box, Mesh, Sphere, model_of
from poekin.errors import InputError, ModelError
from poekin.viewer import panel
from poekin.viewer.collision import (
    CollisionScene,
    collision_scene,
    read_obstacles,
    shapes,
)

pytest.importorskip("trimesh")

TOL = 1e-12  # poses: poekin's FK against MuJoCo's
GJK_TOL = 1e-6  # MuJoCo's convex tolerance: the cylinder's witness points
# the UR5e standing at the edge of a table (docs/collision.md), and a ball held at its flange
TABLE = Box([0.3, 0.4, 0.02], pose=[-0.55, 0.0, -0.02, 1.0, 0.0, 0.0, 0.0], name="table")
HELD = Sphere(0.03, pose=[0.0, 0.0, 0.06, 1.0, 0.0, 0.0, 0.0], frame="attachment_site")
# the elbow folded down: the forearm 23 mm into the table, nothing else within 20 mm
FOREARM_DOWN = np.array([0.3, -0.25, 2.1, -0.6, -1.5708, 0.0])
CLEAR = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])  # upright, the wrist over the base


@pytest.fixture(scope="module")
def tree() -> poekin.Tree:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load_tree("universal_robots_ur5e")


@pytest.fixture(scope="module")
def scene(tree: poekin.Tree) -> CollisionScene:
    return collision_scene(tree, [TABLE, HELD])


@pytest.fixture(scope="module")
def reference(tree: poekin.Tree) -> mujoco.MjModel:
    """The UR5e's kinematics compile with the table as a geom of the world and the ball as a
    geom of the attachment site's body, both colliding (contype and conaffinity 1)."""
    spec = poekin.io.sources.kinematics_spec("universal_robots_ur5e")
    base = load_quiet("universal_robots_ur5e").model
    site = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SITE, "attachment_site")
    at = np.eye(4)
    at[:3, :3] = poekin.quat_to_rotation(base.site_quat[site])
    at[:3, 3] = base.site_pos[site]
    wrist = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, int(base.site_bodyid[site]))
    for parent, pose, name, kind, size in (
        (spec.worldbody, TABLE.pose, "table", mujoco.mjtGeom.mjGEOM_BOX, TABLE.half_sizes),
        (spec.body(wrist), at @ HELD.pose, "sphere1", mujoco.mjtGeom.mjGEOM_SPHERE, [0.03, 0, 0]),
    ):
        body = parent.add_body(pos=pose[:3, 3], quat=poekin.rotation_to_quat(pose[:3, :3]))
        body.add_geom(type=kind, name=name, size=size, contype=1, conaffinity=1)
    return spec.compile()


def _labels(reference: mujoco.MjModel, tree: poekin.Tree) -> list[str]:
    """Each reference geom's name in the scene: the collision geoms (contype 1) in order as
    poekin names them, the obstacles by name, the visual geoms ``visual<g>``."""
    robot = iter(model_of(tree).geom_names)
    out = []
    for g in range(reference.ngeom):
        name = mujoco.mj_id2name(reference, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
        if name in ("table", "sphere1"):
            out.append(name)
        elif reference.geom_contype[g]:
            out.append(next(robot))
        else:
            out.append(f"visual{g}")
    return out


def _mj_state(
    reference: mujoco.MjModel, labels: list[str], qpos: np.ndarray, pairs: list[tuple[str, str]]
) -> tuple[set[str], np.ndarray, np.ndarray, mujoco.MjData]:
    """MuJoCo at ``qpos``: the geoms of the contacts mj_collision finds penetrating, and each
    pair's mj_geomDistance and witness points; where a capsule or cylinder meets the table (a
    box), coal's instead (MuJoCo's EPA stops short of such a depth, by centimetres, even to a
    positive distance, so that mj_collision misses the contact; tests/collision/test_query.py)."""
    data = mujoco.MjData(reference)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(reference, data)
    mujoco.mj_collision(reference, data)
    box = int(mujoco.mjtGeom.mjGEOM_BOX)

    def into_box(g1: int, g2: int) -> bool:
        types = {int(reference.geom_type[g1]), int(reference.geom_type[g2])}
        return box in types and len(types) == 2

    red = {
        labels[int(g)]
        for c in data.contact
        if c.dist < 0 and not into_box(*map(int, c.geom))
        for g in c.geom
    }
    index = {name: g for g, name in enumerate(labels)}
    dist = np.empty(len(pairs))
    points = np.empty((len(pairs), 2, 3))
    fromto = np.zeros(6)
    for p, (a, b) in enumerate(pairs):
        dist[p] = mujoco.mj_geomDistance(reference, data, index[a], index[b], math.inf, fromto)
        points[p] = fromto.reshape(2, 3)
        if into_box(index[a], index[b]) and dist[p] < 0.05:
            dist[p], points[p] = _coal_pair(reference, data, index[a], index[b])
            if dist[p] < 0:
                red |= {a, b}
    return red, dist, points, data


def _coal_pair(
    model: mujoco.MjModel, data: mujoco.MjData, g1: int, g2: int
) -> tuple[float, np.ndarray]:
    """The signed distance and witness points of two geoms (capsule, cylinder or box) by coal,
    at MuJoCo's poses."""
    coal = pytest.importorskip("coal")

    def shape(g: int) -> object:
        r, h, z = model.geom_size[g]
        kind = int(model.geom_type[g])
        if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
            return coal.Capsule(r, 2 * h)
        if kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
            return coal.Cylinder(r, 2 * h)
        return coal.Box(2 * r, 2 * h, 2 * z)

    def pose(g: int) -> object:
        return coal.Transform3s(data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g])

    request, result = coal.DistanceRequest(), coal.DistanceResult()
    request.enable_signed_distance = True
    d = coal.distance(shape(g1), pose(g1), shape(g2), pose(g2), request, result)
    return float(d), np.array([result.getNearestPoint1(), result.getNearestPoint2()])


def test_the_scene_is_the_models_geoms_then_the_obstacles(scene: CollisionScene) -> None:
    assert scene.names[-2:] == ("table", "sphere1") and scene.n_robot == 9
    assert scene.kinds == ("capsule",) * 8 + ("cylinder", "box", "sphere")
    # self, the table with each geom, the ball with each but its wrist_3 and wrist_2 (its
    # parent), the ball with the table
    assert len(scene.pairs) == 21 + 9 + 6 + 1
    for (a, b), (i, j) in zip(scene.pairs, scene.pair_shapes.tolist(), strict=True):
        assert (scene.names[i], scene.names[j]) == (a, b)


@pytest.mark.parametrize(
    ("qpos", "red"),
    [(FOREARM_DOWN, {"forearm_link#1", "table"}), (CLEAR, set())],
    ids=["forearm-in-the-table", "clear"],
)
def test_red_shapes_are_what_mj_collision_finds(
    scene: CollisionScene,
    reference: mujoco.MjModel,
    tree: poekin.Tree,
    qpos: np.ndarray,
    red: set[str],
) -> None:
    labels = _labels(reference, tree)
    state = scene.state(qpos)
    mj_red, dist, points, _ = _mj_state(reference, labels, qpos, list(scene.pairs))
    ours = {scene.names[k] for k in np.flatnonzero(state.colliding)}
    assert ours == mj_red == red
    near = [p for p in range(len(dist)) if dist[p] < state.margin]
    assert sorted(state.near.tolist()) == near
    assert_close("near distances", state.near_distance, dist[state.near], 1e-9)
    assert_close("witness points", state.witness, points[state.near], GJK_TOL)


def test_random_configurations_red_as_mj_collision_and_near_as_mj_geom_distance(
    scene: CollisionScene, reference: mujoco.MjModel, tree: poekin.Tree
) -> None:
    """200 configurations within the joint limits (a fifth collide with themselves, many reach
    through the table): the red shapes are the geoms of mj_collision's penetrating contacts,
    the near pairs those mj_geomDistance puts within the margin, closest first."""
    labels = _labels(reference, tree)
    qpos = poekin.sample_qpos(tree, 200, seed=5, within_limits=True)
    hits = same = total = 0
    for margin, x in zip(np.tile([0.0, 0.02, 0.1], 67), qpos, strict=False):
        state = scene.state(x, margin)
        mj_red, dist, points, _ = _mj_state(reference, labels, x, list(scene.pairs))
        assert {scene.names[k] for k in np.flatnonzero(state.colliding)} == mj_red
        hits += bool(mj_red)
        clear_of_margin = np.abs(dist - margin) > 1e-9
        near = set(state.near.tolist())
        assert {p for p in np.flatnonzero(clear_of_margin) if dist[p] < margin} == {
            p for p in near if clear_of_margin[p]
        }
        assert np.all(np.diff(state.near_distance) >= 0)  # closest first
        # the witness points: MuJoCo's, or (a capsule parallel to a face, where no pair of
        # points is the only closest one) another pair the same distance apart
        off = np.abs(state.witness - points[state.near]).max(axis=(-1, -2)) > GJK_TOL
        gap = np.linalg.norm(state.witness[:, 1] - state.witness[:, 0], axis=-1)
        # (the distance itself against MuJoCo and coal: tests/collision/test_query.py)
        assert_close("gap", gap[off], np.abs(state.near_distance[off]), 1e-9)
        same += int(np.count_nonzero(~off))
        total += len(off)
    assert 40 < hits < 160
    # most points are MuJoCo's (or coal's): the rest are parallel faces, or a depth's points where
    # the references stop short of it
    assert same > 0.85 * total


def test_panel_text_names_the_pair_and_its_depth(
    scene: CollisionScene, reference: mujoco.MjModel, tree: poekin.Tree
) -> None:
    state = scene.state(FOREARM_DOWN)
    _, dist, _, _ = _mj_state(reference, _labels(reference, tree), FOREARM_DOWN, list(scene.pairs))
    depth = dist[scene.pairs.index(("forearm_link#1", "table"))]
    text = panel.collision_text(scene, state, query_s=1e-3)
    assert text.startswith("**IN COLLISION**: 1 of 37 pairs penetrates (red)")
    assert "9 geoms, 2 obstacles; witness points of the pairs closer than 20 mm; query 1 ms" in text
    assert f"forearm_link#1 / table: {depth * 1e3:.1f} mm  COLLIDES" in text
    free = panel.collision_text(scene, scene.state(CLEAR, 0.0))
    assert free.startswith("**collision-free**: none of 37 pairs penetrates")
    assert free.endswith("no pair closer than 0 mm")


def test_panel_lists_the_closest_pairs_only(scene: CollisionScene) -> None:
    state = scene.state(FOREARM_DOWN, 0.1)  # 10 cm: many pairs
    assert len(state.near) > panel.COLLISION_ROWS
    rows = panel.collision_text(scene, state).split("```")[1].strip().splitlines()
    assert len(rows) == panel.COLLISION_ROWS + 1
    assert rows[-1] == f"... and {len(state.near) - panel.COLLISION_ROWS} more"


@settings(max_examples=15, deadline=None)
@given(
    shape=st.sampled_from([(), (1,), (3, 1, 2)]),
    seed=st.integers(0, 2**31 - 1),
)
def test_poses_are_mujocos_geom_frames(
    scene: CollisionScene,
    reference: mujoco.MjModel,
    tree: poekin.Tree,
    shape: tuple[int, ...],
    seed: int,
) -> None:
    """Each shape's pose, batched, against MuJoCo's geom_xpos and geom_xmat (the ball: its
    body's frame, MuJoCo placing it on the wrist)."""
    qpos = poekin.sample_qpos(tree, max(1, math.prod(shape)), seed=seed).reshape(*shape, tree.nq)
    poses = scene.poses(qpos)
    assert poses.shape == (*shape, len(scene.names), 4, 4)
    labels = _labels(reference, tree)
    data = mujoco.MjData(reference)
    flat = poses.reshape(-1, len(scene.names), 4, 4)
    for x, drawn in zip(qpos.reshape(-1, tree.nq), flat, strict=True):
        data.qpos[:] = x
        mujoco.mj_kinematics(reference, data)
        for k, name in enumerate(scene.names):
            g = labels.index(name)
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
            assert_close(name, drawn[k], T, TOL)


def _segment_distance(points: np.ndarray, half_length: float) -> np.ndarray:
    """Each point's distance from the segment z in [-h, h] on the z axis."""
    z = np.clip(points[:, 2], -half_length, half_length)
    return np.linalg.norm(points - np.stack([0 * z, 0 * z, z], axis=1), axis=1)


def _volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The volume a closed triangle mesh encloses, faces wound outward (positive)."""
    v = vertices[faces].astype(np.float64)
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6)


def test_shapes_are_the_geoms_that_collide(scene: CollisionScene) -> None:
    """Capsules: every vertex a radius from the segment; the cylinder on its surface; the
    box's corners at its half sizes; the ball a radius from its centre; each closed and
    wound outward (the page draws front faces)."""
    geometry = model_of(scene.tree)
    drawn = shapes(scene)
    assert [s.name for s in drawn] == list(scene.names)
    assert [s.obstacle for s in drawn] == [False] * 9 + [True, True]
    for k, shape in enumerate(drawn):
        v = shape.vertices.astype(np.float64)
        if shape.kind == "capsule":
            r, h = geometry.geom_sizes[k][:2]
            assert_close(shape.name, _segment_distance(v, h), np.full(len(v), r), 1e-6)
        elif shape.kind == "cylinder":
            r, h = geometry.geom_sizes[k][:2]
            side = np.isclose(np.hypot(v[:, 0], v[:, 1]), r, atol=1e-6)
            assert np.all(side | np.isclose(np.abs(v[:, 2]), h) | (np.hypot(v[:, 0], v[:, 1]) < r))
            assert np.isclose(np.abs(v[:, 2]).max(), h)
        elif shape.kind == "box":
            assert_close("box", np.abs(v), np.broadcast_to(TABLE.half_sizes, v.shape), 1e-7)
        else:
            assert_close("ball", np.linalg.norm(v, axis=1), np.full(len(v), 0.03), 1e-6)
        assert _volume(v, shape.faces) > 0


def test_a_mesh_is_its_convex_hull(tree: poekin.Tree) -> None:
    """A cube's eight corners and a point inside: the hull MuJoCo collides (its corners, the
    cube's volume), placed as the obstacle's vertices were given (off centre)."""
    corners = np.array([[x, y, z] for x in (0, 0.1) for y in (0, 0.1) for z in (0, 0.2)])
    offset = np.array([0.3, 0.2, 0.1])
    cube = Mesh(np.vstack([corners, [[0.05, 0.05, 0.05]]]) + offset)
    (drawn,) = shapes(collision_scene(tree, [cube]))[-1:]
    assert drawn.name == "mesh0" and drawn.kind == "mesh"
    used = drawn.vertices[np.unique(drawn.faces)]
    assert_close("hull corners", np.sort(used, axis=0), np.sort(corners + offset, axis=0), 1e-6)
    assert math.isclose(_volume(drawn.vertices, drawn.faces), 0.1 * 0.1 * 0.2, rel_tol=1e-5)


def test_urdf_meshes_are_drawn_as_their_hulls() -> None:
    """The Panda's STL collision meshes (example-robot-data): each drawn hull encloses the
    volume scipy's Qhull finds for the same vertices."""
    spatial = pytest.importorskip("scipy.spatial")
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    robots = site / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
    if not robots.is_dir():
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    panda = poekin.load_tree(robots / "panda_description" / "urdf" / "panda.urdf")
    drawn = shapes(collision_scene(panda))
    meshes = [s for s in drawn if s.kind == "mesh"]
    assert len(meshes) == 9
    for shape in meshes:
        hull = spatial.ConvexHull(shape.vertices.astype(np.float64)).volume
        assert math.isclose(_volume(shape.vertices, shape.faces), hull, rel_tol=1e-6), shape.name


def test_a_plane_is_a_square(tree: poekin.Tree) -> None:
    from poekin.collision import Plane

    (floor,) = shapes(collision_scene(tree, [Plane(pose=[0, 0, -0.1, 1, 0, 0, 0])]))[-1:]
    assert floor.kind == "plane" and len(floor.faces) == 2
    assert_close("square", np.abs(floor.vertices), [[1.0, 1.0, 0.0]] * 4, 0.0)


def test_scene_and_state_bad_input(tree: poekin.Tree, scene: CollisionScene) -> None:
    with pytest.raises(
        InputError, match=r"^the collision margin must be a finite distance >= 0 \(m\), got -0.01$"
    ):
        scene.state(CLEAR, -0.01)
    with pytest.raises(InputError, match=r"^the collision margin must be a number \(m\), got str$"):
        scene.state(CLEAR, "wide")  # type: ignore[arg-type]
    with pytest.raises(
        InputError, match=r"^one configuration of 6 qpos values, got shape \(2, 6\)$"
    ):
        scene.state(np.stack([CLEAR, CLEAR]))
    with pytest.raises(poekin.UnknownFrameError, match="did you mean 'attachment_site'"):
        collision_scene(tree, [Sphere(0.1, frame="atachment_site")])
    with pytest.raises(InputError, match="obstacle name 'table' is taken"):
        collision_scene(tree, [TABLE, Box([0.1, 0.1, 0.1], name="table")])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        fr3 = poekin.load_tree("franka_fr3")
    with pytest.raises(ModelError, match=r"needs 8 mesh file\(s\) that are missing"):
        collision_scene(fr3)


# --- the obstacle file ----------------------------------------------------------------------------


def _write(tmp_path: pathlib.Path, data: object, name: str = "obstacles.json") -> pathlib.Path:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data), encoding="utf-8")
    return path


def test_an_obstacle_file_reads_every_kind(tmp_path: pathlib.Path) -> None:
    stl = tmp_path / "parts" / "cube.stl"
    stl.parent.mkdir()
    import trimesh

    trimesh.creation.box(extents=[0.1, 0.1, 0.1]).export(stl)
    path = _write(
        tmp_path,
        [
            {
                "type": "box",
                "half_sizes": [0.3, 0.4, 0.02],
                "pose": [-0.55, 0, -0.02, 1, 0, 0, 0],
                "name": "table",
            },
            {"type": "sphere", "radius": 0.03, "frame": "attachment_site"},
            {"type": "capsule", "radius": 0.02, "half_length": 0.1, "pose": np.eye(4).tolist()},
            {"type": "plane"},
            {"type": "mesh", "file": "parts/cube.stl", "pose": [0.4, 0, 0.05, 1, 0, 0, 0]},
            {"type": "mesh", "vertices": np.eye(4, 3).tolist()},
        ],
    )
    box, ball, capsule, plane, part, tetra = read_obstacles(path)
    assert isinstance(box, Box) and box.half_sizes == (0.3, 0.4, 0.02) and box.name == "table"
    assert_close("table pose", box.pose, TABLE.pose, 0.0)
    assert isinstance(ball, Sphere) and ball.frame == "attachment_site"
    assert capsule.half_length == 0.1 and type(plane).__name__ == "Plane"  # type: ignore[union-attr]
    assert isinstance(part, Mesh) and part.vertices.shape == (8, 3)
    assert_close("cube", np.abs(part.vertices), np.full((8, 3), 0.05), 1e-7)
    assert isinstance(tetra, Mesh) and tetra.vertices.shape == (4, 3)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (
            "[{",
            "obstacles bad.json is not JSON: Expecting property name enclosed in double quotes at "
            "line 1",
        ),
        (
            {"type": "box"},
            'obstacles bad.json must hold a JSON list of obstacles, [{"type": "box", ...}, ...], '
            "got dict",
        ),
        ([3], 'obstacles bad.json: obstacle 0 must be an object with a "type", got 3'),
        (
            [{"type": "cube"}],
            "obstacles bad.json: obstacle 0 has type 'cube': Valid names: 'box', 'sphere', "
            "'capsule', 'plane', 'mesh'",
        ),
        (
            [{"half_sizes": [1, 1, 1]}],
            "obstacles bad.json: obstacle 0 has type None: Valid names: 'box', ",
        ),
        (
            [{"type": "box", "size": [1, 1, 1]}],
            "obstacles bad.json: box 0 has no field 'size': Valid names: 'half_sizes', 'pose', "
            "'frame', 'name'",
        ),
        (
            [{"type": "sphere", "pose": [0, 0, 0, 1, 0, 0, 0]}],
            "obstacles bad.json: sphere 0 needs 'radius'",
        ),
        ([{"type": "mesh"}], "obstacles bad.json: mesh 0 needs 'vertices' (or \"file\")"),
        (
            [{"type": "box", "half_sizes": [0.3, -0.4, 0.02]}],
            "obstacles bad.json: obstacle 0: Box: half size along y must be a finite size > 0 "
            "(m), got -0.4",
        ),
        (
            [
                {"type": "sphere", "radius": 0.1},
                {"type": "sphere", "radius": 0.1, "pose": [0, 0, 0, 1, 0, 0]},
            ],
            "obstacles bad.json: obstacle 1: Sphere: pose must be a (4, 4) rigid transform or 7 "
            "numbers",
        ),
        (
            [
                {
                    "type": "capsule",
                    "radius": 0.1,
                    "half_length": 0.1,
                    "pose": [0, 0, "nan", 1, 0, 0, 0],
                }
            ],
            "obstacles bad.json: obstacle 0: Capsule: pose contains NaN or inf: give finite "
            "numbers",
        ),
        (
            [{"type": "mesh", "file": "x.stl", "vertices": []}],
            'obstacles bad.json: mesh 0 has both "file" and "vertices": give one',
        ),
        (
            [{"type": "mesh", "file": "nowhere.stl"}],
            "obstacles bad.json: obstacle 0: Mesh: no mesh file ",
        ),
        (
            [{"type": "mesh", "file": "bad.json"}],
            "obstacles bad.json: obstacle 0: Mesh: bad.json is not a mesh file",
        ),
    ],
    ids=[
        "not-json",
        "not-a-list",
        "not-an-object",
        "unknown-type",
        "no-type",
        "unknown-field",
        "missing-field",
        "mesh-without-vertices",
        "negative-size",
        "bad-pose",
        "nan-pose",
        "file-and-vertices",
        "no-mesh-file",
        "not-a-mesh",
    ],
)
def test_a_bad_obstacle_file_is_one_clear_error(
    tmp_path: pathlib.Path, content: object, message: str
) -> None:
    path = _write(tmp_path, content, "bad.json")
    with pytest.raises(InputError) as caught:
        read_obstacles(path)
    assert str(caught.value).startswith(message), str(caught.value)
    assert "\n" not in str(caught.value)


def test_no_obstacle_file(tmp_path: pathlib.Path) -> None:
    with pytest.raises(
        InputError, match=r"^obstacles none.json: cannot read it: No such file or directory$"
    ):
        read_obstacles(tmp_path / "none.json")


# --- the page, through the Python handle ----------------------------------------------------------

viser = pytest.importorskip("viser")

from poekin.viewer.app import Viewer, view  # noqa: E402


@pytest.fixture(scope="module")
def viewer() -> Iterator[Viewer]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        v = view(
            "universal_robots_ur5e",
            collision=True,
            obstacles=[TABLE, HELD],
            port=0,
            open_browser=False,
        )
    yield v
    v.close()


def _red(v: Viewer) -> set[str]:
    scene = v.collision_scene
    assert scene is not None
    return {
        scene.names[v._nodes[n].index]
        for n in v.node_names("collision_geom") + v.node_names("obstacle")
        if tuple(v.node(n).color) == (225, 20, 20)
    }


def test_the_page_draws_the_shapes_where_mujoco_puts_them(
    viewer: Viewer, reference: mujoco.MjModel
) -> None:
    tree = viewer.subject.tree
    assert tree is not None
    labels = _labels(reference, tree)
    for x in poekin.sample_qpos(tree, 3, seed=11):
        viewer.q = x
        data = mujoco.MjData(reference)
        data.qpos[:] = x
        mujoco.mj_kinematics(reference, data)
        drawn = {**viewer.node_poses("collision_geom"), **viewer.node_poses("obstacle")}
        assert viewer.collision_scene is not None
        assert len(drawn) == len(viewer.collision_scene.names) == 11
        for name, T in drawn.items():
            g = labels.index(viewer.collision_scene.names[viewer._nodes[name].index])
            assert_close(name, T[:3, 3], data.geom_xpos[g], TOL)
            assert_close(name, T[:3, :3], data.geom_xmat[g].reshape(3, 3), TOL)


def _witness_drawn(v: Viewer) -> tuple[np.ndarray, np.ndarray]:
    """The witness spheres shown, ``(2K, 6)``: position and colour, and the lines ``(K, 2,
    3)`` (K: the pairs within the margin); none while hidden."""
    balls, lines = v.node("/collision/witness/points"), v.node("/collision/witness/lines")
    if not balls.visible:
        assert not lines.visible
        return np.zeros((0, 6)), np.zeros((0, 2, 3))
    shown = np.asarray(balls.batched_scales) > 0
    k = int(shown.sum()) // 2
    assert np.all(shown[: 2 * k]) and not np.any(shown[2 * k :])
    drawn = np.hstack([balls.batched_positions, balls.batched_colors])[: 2 * k]
    return drawn, np.asarray(lines.points[:k], dtype=np.float64)


def test_the_page_colours_the_pair_and_draws_its_witness_points(
    viewer: Viewer, reference: mujoco.MjModel
) -> None:
    tree = viewer.subject.tree
    assert tree is not None and viewer.collision_scene is not None
    viewer.set_option("collision margin [mm]", 20.0)
    viewer.q = FOREARM_DOWN
    pairs = list(viewer.collision_scene.pairs)
    mj_red, dist, points, _ = _mj_state(reference, _labels(reference, tree), FOREARM_DOWN, pairs)
    assert _red(viewer) == mj_red == {"forearm_link#1", "table"}
    depth = dist[pairs.index(("forearm_link#1", "table"))]
    p = pairs.index(("forearm_link#1", "table"))
    # the only pair within 20 mm: its two spheres (yellow: it penetrates) and its line
    balls, line = _witness_drawn(viewer)
    # the page takes positions in float32: 6e-8 m at the UR5e's reach
    assert_close("sphere on the forearm, on the table", balls[:, :3], points[p], 1e-6)
    assert np.all(balls[:, 3:] == [255, 215, 0])
    assert_close("line", line, points[p][None], 1e-6)
    label = viewer.node("/collision/depth0")
    assert label.visible and label.text == f"{depth * 1e3:.1f} mm"
    assert_close("label", label.position, points[p].mean(axis=0), 1e-6)
    assert "forearm_link#1 / table" in viewer.texts()["collision"]
    viewer.q = CLEAR
    assert _red(viewer) == set() and not viewer.node("/collision/depth0").visible
    _, dist, points, _ = _mj_state(reference, _labels(reference, tree), CLEAR, pairs)
    near = np.flatnonzero(dist < 0.02)
    balls, line = _witness_drawn(viewer)
    order = np.argsort(dist[near])
    assert_close("witness, clear", line, points[near[order]], 1e-6)
    assert np.all(balls[:, 3:] == [255, 120, 0])  # apart: orange
    assert viewer.texts()["collision"].startswith("**collision-free**")


def test_the_box_and_the_margin(viewer: Viewer) -> None:
    viewer.q = FOREARM_DOWN
    viewer.set_option("collision geometry", False)
    assert viewer.collision is None and "collision" not in viewer.texts()
    assert not any(viewer.node(n).visible for n in viewer.node_names("collision_geom"))
    assert all(viewer.node(n).visible for n in viewer.node_names("obstacle"))  # always drawn
    assert len(_witness_drawn(viewer)[0]) == 0
    assert _red(viewer) == set()
    viewer.q = CLEAR  # the ball still rides on the flange
    ball = viewer.node_poses("obstacle")["/collision/g10"]
    assert viewer.subject.tree is not None
    assert_close("ball", ball, viewer.subject.tree.pose(CLEAR, "attachment_site") @ HELD.pose, TOL)
    viewer.set_option("collision geometry", True)
    viewer.set_option("collision margin [mm]", 100.0)
    state = viewer.collision
    assert state is not None and state.margin == pytest.approx(0.1) and len(state.near) > 2
    assert len(_witness_drawn(viewer)[0]) == 2 * len(state.near)
    with pytest.raises(InputError, match=r"'collision margin \[mm\]' takes a number in \[0, 100\]"):
        viewer.set_option("collision margin [mm]", 150.0)
    viewer.set_option("collision margin [mm]", 20.0)


def test_an_ik_drag_queries_again(viewer: Viewer) -> None:
    viewer.q = CLEAR
    T = viewer.snapshot().T
    T[:3, 3] += [0.0, 0.0, -0.05]
    shown = viewer.set_target(T)
    state = viewer.collision
    assert shown.success and state is not None
    np.testing.assert_array_equal(state.qpos, viewer.q)
    viewer.set_option("IK target", False)


def test_playback_queries_at_each_time(tmp_path: pathlib.Path) -> None:
    from poekin.io.trajectory import Trajectory

    t = np.linspace(0.0, 1.0, 11)
    q = CLEAR + np.outer(t, FOREARM_DOWN - CLEAR)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        v = view(
            "universal_robots_ur5e",
            play=Trajectory(t, q, robot="universal_robots_ur5e"),
            collision=True,
            obstacles=TABLE,
            port=0,
            open_browser=False,
        )
    with v:
        v.play_time = 1.0
        assert v.collision is not None and v.collision.n_colliding == 1
        np.testing.assert_array_equal(v.collision.qpos, FOREARM_DOWN)
        v.play_time = 0.0
        assert v.collision is not None and v.collision.n_colliding == 0


def test_a_model_without_its_collision_meshes_says_so() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        with pytest.raises(ModelError, match=r"fr3\.xml: its collision geometry needs 8 mesh file"):
            view("franka_fr3", collision=True, port=0, open_browser=False)
        with view("franka_fr3", port=0, open_browser=False) as v:
            v.set_option("collision geometry", True)  # the box goes off again, saying why
            assert v.options()["collision geometry"] is False and v.collision is None
            assert v._collision_note.content.startswith("**no collision geometry:** fr3.xml: ")


def test_a_bare_parameter_set_has_no_collision_geometry(ur5e: poekin.Chain) -> None:
    with pytest.raises(
        InputError, match=r"^collision needs a model's collision geometry: show a model"
    ):
        view(ur5e, collision=True, port=0, open_browser=False)
    with pytest.raises(InputError, match=r"^collision needs a model's collision geometry"):
        view(ur5e, obstacles=[TABLE], port=0, open_browser=False)
    with view(ur5e, port=0, open_browser=False) as v:
        assert v.node("/robot/b0") is not None
        assert v._collision_input.disabled and v.collision_scene is None


# --- poekin view --collision ----------------------------------------------------------------------


def _interrupt(monkeypatch: pytest.MonkeyPatch) -> None:
    def interrupt(_: float) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("time.sleep", interrupt)


@pytest.mark.usefixtures("fresh_machine")
def test_view_collision_and_an_obstacle_file(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _interrupt(monkeypatch)
    path = _write(
        tmp_path,
        [
            {
                "type": "box",
                "half_sizes": [0.3, 0.4, 0.02],
                "pose": [-0.55, 0, -0.02, 1, 0, 0, 0],
                "name": "table",
            }
        ],
        "table.json",
    )
    argv = ["view", "--no-browser", "--port", "0", "--obstacles", str(path)]
    code, out, err = run(capsys, *argv, "--collision")
    assert code == 130 and err == "poekin: interrupted\n"
    assert out.endswith(
        "(universal_robots_ur5e, end frame 'attachment_site'; collision: 9 geoms, 1 obstacle, "
        "30 pairs); Ctrl-C to stop\n"
    )
    code, out, _ = run(capsys, *argv)
    assert code == 130 and out.endswith(
        "'attachment_site'; 1 obstacle (checked with --collision)); Ctrl-C to stop\n"
    )


@pytest.mark.usefixtures("fresh_machine")
def test_view_collision_refused_in_one_line(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _write(tmp_path, [{"type": "box", "half_sizes": [0.3, -0.4, 0.02]}], "bad.json")
    code, out, err = run(capsys, "view", "--no-browser", "--port", "0", "--obstacles", str(bad))
    assert code == 2 and out == ""
    assert_one_error_line(
        err,
        "obstacles bad.json: obstacle 0: Box: half size along y must be a finite size > 0 "
        "(m), got -0.4",
    )
    code, out, err = run(capsys, "view", "franka_fr3", "--no-browser", "--port", "0", "--collision")
    assert code == 2 and out == ""
    assert_one_error_line(
        err, "fr3.xml: its collision geometry needs 8 mesh file(s) that are missing"
    )


ARM_ON_A_FLOOR = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="0.5 0.4 0.1"/>
    <body name="link" pos="0 0 0.2">
      <joint name="hinge" axis="0 1 0"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_geom_of_the_world_stands_on_the_base(tmp_path: pathlib.Path) -> None:
    """A floor of the model's world body: drawn at the tree's base (``--base``), as the robot
    is, and as a square of its own size."""
    path = tmp_path / "arm.xml"
    path.write_text(ARM_ON_A_FLOOR, encoding="utf-8")
    base = Box([1, 1, 1], pose=[0.1, -0.2, 0.3, 0.9238795, 0.0, 0.0, 0.3826834]).pose
    arm = poekin.load_tree(path, base=base)
    scene = collision_scene(arm)
    assert scene.names == ("floor", "rod") and scene.owners[0] == -2
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    data.qpos[:] = [0.7]
    mujoco.mj_kinematics(model, data)
    poses = scene.poses([0.7])
    for k in range(2):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = data.geom_xmat[k].reshape(3, 3), data.geom_xpos[k]
        assert_close(scene.names[k], poses[k], base @ T, TOL)
    floor = shapes(scene)[0]
    assert_close("floor", np.abs(floor.vertices), [[0.5, 0.4, 0.0]] * 4, 1e-7)


def test_a_height_field_is_refused(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "terrain.xml"
    path.write_text(
        ARM_ON_A_FLOOR.replace(
            '<geom name="floor" type="plane" size="0.5 0.4 0.1"/>',
            '<geom name="ground" type="hfield" hfield="ground"/>',
        ).replace(
            "<worldbody>",
            '<asset><hfield name="ground" nrow="2" ncol="2" size="1 1 0.1 0.1"/></asset>'
            "<worldbody>",
        ),
        encoding="utf-8",
    )
    scene = collision_scene(poekin.load_tree(path))
    assert scene.kinds == ("hfield", "capsule")
    with pytest.raises(ModelError, match=r"^the viewer cannot draw collision geom 0, a hfield: "):
        shapes(scene)


def test_the_box_reads_the_geometry_when_first_ticked() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        v = view("universal_robots_ur5e", port=0, open_browser=False)
    with v:
        assert v.collision_scene is None and v.options()["collision geometry"] is False
        v.q = FOREARM_DOWN
        v.set_option("collision geometry", True)
        assert v.collision_scene is not None and len(v.node_names("collision_geom")) == 9
        assert v.collision is not None and v.collision.n_colliding == 0  # no table here
        assert all(v.node(n).visible for n in v.node_names("collision_geom"))
