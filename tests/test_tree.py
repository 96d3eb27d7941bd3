"""Trees: every body and site of a model against mj_kinematics, all joint types, chains of a
tree, mimic joints, and the errors a user sees."""

from __future__ import annotations

import dataclasses
import pathlib

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin import InputError, ModelError, UnknownFrameError, lie
from poekin.io.import_mujoco import tree_from_model
from poekin.tree import Mimic, Tree
from poekin.verification.verify import sample_qpos

MENAGERIE = [
    "universal_robots_ur5e",
    "universal_robots_ur10e",
    "franka_emika_panda",
    "franka_fr3",
    "ufactory_lite6",
    "rethink_robotics_sawyer",
    "trs_so_arm100",
    "unitree_g1",
    "unitree_go2",
    "aloha",
]
N_SAMPLES = 10_000  # issue #4: every frame on 10,000 random qpos
BATCH_SHAPES = [(), (1,), (3, 1, 2, 1)]

# A model that uses every feature MuJoCo resolves at compile time: default classes, childclass,
# euler / axisangle / xyaxes frames in degrees, non-unit axes, joint anchors, non-zero ref,
# several joints in one body, ball and free joints, sites on the world and on bodies, a mocap
# body, and a second free-floating tree.
FEATURES_XML = """
<mujoco>
  <compiler angle="degree"/>
  <default>
    <joint axis="0 1 1" damping="1"/>
    <default class="slider"><joint type="slide" axis="1 0 0.5" range="-0.3 0.2"/></default>
    <default class="arm"><joint pos="0 0 0.05" ref="15"/><geom size="0.02"/></default>
  </default>
  <worldbody>
    <site name="world_site" pos="0.1 0.2 0.3" euler="10 20 30"/>
    <body name="base" pos="0.1 0 0.2" euler="0 0 45" childclass="arm">
      <joint name="yaw" type="hinge" axis="0 0 2"/>
      <geom/>
      <body name="upper" pos="0 0.1 0.3" axisangle="1 1 0 30">
        <joint name="pitch"/>
        <joint name="extend" class="slider" ref="0.05"/>
        <geom/>
        <body name="wrist" pos="0.2 0 0" xyaxes="0 1 0 -1 0 0">
          <joint name="wrist_ball" type="ball" pos="0.01 0.02 0.03"/>
          <geom/>
          <site name="tool" pos="0 0 0.1" quat="0.5 0.5 0.5 0.5"/>
          <body name="finger" pos="0.05 0 0">
            <joint name="finger_slide" class="slider"/>
            <joint name="finger_roll" type="hinge" axis="1 0 0" ref="-40"/>
            <geom/>
          </body>
        </body>
      </body>
    </body>
    <body name="floater" pos="1 2 3" quat="0 1 0 0">
      <freejoint name="float"/>
      <geom size="0.1"/>
      <body name="pendulum" pos="0 0 -0.4">
        <joint name="swing" type="hinge" axis="1 0 0" pos="0 0 0.4"/>
        <geom size="0.05"/>
        <site name="bob"/>
      </body>
    </body>
    <body name="target" mocap="true" pos="0 0 1"><site name="target_site"/></body>
  </worldbody>
</mujoco>
"""


def mj_frames(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """``(N, nbody - 1 + nsite, 4, 4)`` body then site poses from mj_kinematics."""
    data = mujoco.MjData(model)
    nb = model.nbody - 1
    out = np.zeros((len(qpos), nb + model.nsite, 4, 4))
    out[..., 3, 3] = 1.0
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[k, :nb, :3, :3] = data.xmat[1:].reshape(nb, 3, 3)
        out[k, :nb, :3, 3] = data.xpos[1:]
        out[k, nb:, :3, :3] = data.site_xmat.reshape(-1, 3, 3)
        out[k, nb:, :3, 3] = data.site_xpos
    return out


def check_tree(model: mujoco.MjModel, qpos: np.ndarray, what: str) -> None:
    tree = tree_from_model(model)
    expected = mj_frames(model, qpos)
    got = tree.fk(qpos)
    for f, name in enumerate(tree.frame_names):
        assert_close(f"{what} / {name}", got[:, f], expected[:, f], MJ_TOL)


@pytest.fixture(scope="module")
def features() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(FEATURES_XML)


# --- against MuJoCo -----------------------------------------------------------------------------


@pytest.mark.parametrize("robot", MENAGERIE)
def test_menagerie_every_frame_matches_mj_kinematics(robot: str) -> None:
    model = load_quiet(robot).model
    tree = poekin.load_tree(load_quiet(robot))
    assert (tree.nq, tree.nv, tree.n_frames) == (model.nq, model.nv, model.nbody - 1 + model.nsite)
    assert list(tree.qpos_adr) == list(model.jnt_qposadr)
    check_tree(model, sample_qpos(tree, N_SAMPLES, seed=4), robot)


def test_features_model_matches_mj_kinematics(features: mujoco.MjModel) -> None:
    tree = tree_from_model(features)
    assert tree.joint_types == (
        "revolute",
        "revolute",
        "prismatic",
        "ball",
        "prismatic",
        "revolute",
        "free",
        "revolute",
    )
    check_tree(features, sample_qpos(tree, 2000, seed=1), "features")


@pytest.mark.parametrize("scale", [1e-3, 0.7, 3.0, 1e4])
def test_unnormalised_quaternions_mean_what_mujoco_makes_of_them(
    features: mujoco.MjModel, scale: float
) -> None:
    tree = tree_from_model(features)
    qpos = sample_qpos(tree, 500, seed=2)
    for k, kind in enumerate(tree.joint_types):
        a = tree.qpos_adr[k] + (3 if kind == "free" else 0)
        if kind in ("ball", "free"):
            qpos[:, a : a + 4] *= scale
    check_tree(features, qpos, f"quaternions x {scale}")


def test_zero_quaternion_is_the_identity_as_in_mujoco(features: mujoco.MjModel) -> None:
    tree = tree_from_model(features)
    qpos = sample_qpos(tree, 3, seed=3)
    ball = tree.qpos_adr[tree.joint_names.index("wrist_ball")]
    free = tree.qpos_adr[tree.joint_names.index("float")]
    qpos[:, ball : ball + 4] = 0.0
    qpos[:, free + 3 : free + 7] = [0.0, 0.0, 0.0, 1e-16]
    check_tree(features, qpos, "zero quaternions")


def test_default_qpos_is_mujocos_home(features: mujoco.MjModel) -> None:
    tree = tree_from_model(features)
    assert_close("qpos0", tree.qpos0, features.qpos0, 0.0)
    check_tree(features, tree.qpos0[None], "qpos0")


# --- shapes -------------------------------------------------------------------------------------


@pytest.mark.parametrize("batch", BATCH_SHAPES)
def test_fk_keeps_batch_axes(features: mujoco.MjModel, batch: tuple[int, ...]) -> None:
    tree = tree_from_model(features)
    n = int(np.prod(batch))
    flat = sample_qpos(tree, n, seed=5)
    T = tree.fk(flat.reshape(*batch, tree.nq))
    assert T.shape == (*batch, tree.n_frames, 4, 4)
    assert_close("batched vs flat", T.reshape(n, tree.n_frames, 4, 4), tree.fk(flat), 0.0)


def test_empty_batch_returns_empty(features: mujoco.MjModel) -> None:
    tree = tree_from_model(features)
    assert tree.fk(np.zeros((0, tree.nq))).shape == (0, tree.n_frames, 4, 4)


def test_integer_and_float32_qpos_are_accepted(features: mujoco.MjModel) -> None:
    tree = tree_from_model(features)
    q = np.round(sample_qpos(tree, 4, seed=6))
    assert_close("int qpos", tree.fk(q.astype(int)), tree.fk(q), 0.0)
    assert_close("float32 qpos", tree.fk(q.astype(np.float32)), tree.fk(q), 0.0)


@pytest.mark.parametrize(
    ("qpos", "message"),
    [
        (
            np.zeros(5),
            r"expected 17 qpos values .* qpos = \[yaw, pitch, extend, "
            r"wrist_ball \(ball: qw qx qy qz\)",
        ),
        ([0.0] * 16 + [np.nan], "NaN or inf"),
        (["a"] * 17, "must be numbers"),
        (np.array([None] * 17), "must be numbers, got None"),
        (np.zeros(17) + 1j, "must be real numbers, got complex numbers"),
    ],
)
def test_bad_qpos_is_an_input_error(features: mujoco.MjModel, qpos: object, message: str) -> None:
    tree = tree_from_model(features)
    with pytest.raises(InputError, match=message):
        tree.fk(qpos)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=message):
        tree.jacobian(qpos, "finger")  # type: ignore[arg-type]


# --- chains of a tree ---------------------------------------------------------------------------


def _chain_frames(tree: Tree) -> list[str]:
    kinds = {"ball", "free"}
    return [
        f
        for f in tree.frame_names
        if not any(tree.joint_types[k] in kinds for k in tree.path_joints(f))
    ]


@pytest.mark.parametrize("robot", ["aloha", "franka_emika_panda", "trs_so_arm100"])
def test_every_chain_of_a_tree_equals_the_tree(robot: str) -> None:
    tree = poekin.load_tree(load_quiet(robot))
    qpos = sample_qpos(tree, 300, seed=7)
    T = tree.fk(qpos)
    for frame in _chain_frames(tree):
        chain = tree.chain(frame)
        q = qpos[:, list(chain.qpos_indices or ())]
        assert_close(
            f"{robot} / {frame}: space", chain.fk(q), T[:, tree.frame_index(frame)], MJ_TOL
        )
        assert_close(
            f"{robot} / {frame}: body", chain.fk_body(q), T[:, tree.frame_index(frame)], MJ_TOL
        )


def test_chain_behind_a_free_joint_points_to_load_tree() -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    with pytest.raises(ModelError, match=r"free joint; .*load_tree"):
        tree.chain("imu")
    with pytest.raises(ModelError, match="load_tree"):
        poekin.load(load_quiet("unitree_go2"), "FL_calf")


def test_chain_behind_a_ball_joint_is_refused(features: mujoco.MjModel) -> None:
    with pytest.raises(ModelError, match="'wrist_ball' on the path to 'tool' is a ball joint"):
        tree_from_model(features).chain("tool")


def test_chain_of_a_hinge_after_the_world_site(features: mujoco.MjModel) -> None:
    tree = tree_from_model(features)
    chain = tree.chain("upper")
    assert chain.joint_names == ("yaw", "pitch", "extend")
    assert chain.joint_types == ("revolute", "revolute", "prismatic")
    qpos = sample_qpos(tree, 200, seed=8)
    q = qpos[:, list(chain.qpos_indices or ())]
    assert_close("upper", chain.fk(q), tree.fk(qpos)[:, tree.frame_index("upper")], MJ_TOL)
    world = tree.chain("world_site")
    assert world.n_joints == 0
    assert_close(
        "world_site",
        world.fk(np.zeros(0)),
        tree.fk(tree.qpos0)[tree.frame_index("world_site")],
        0.0,
    )


def test_unknown_frame_suggests_the_near_miss(features: mujoco.MjModel) -> None:
    with pytest.raises(UnknownFrameError, match="did you mean 'finger'"):
        tree_from_model(features).frame_index("fingr")


def test_a_model_with_nothing_to_pose_is_refused(tmp_path: pathlib.Path) -> None:
    """An empty worldbody: one line (it crashed in the kernel's builder). A world site alone
    is a frame, and is posed."""
    path = tmp_path / "empty.xml"
    path.write_text("<mujoco><worldbody/></mujoco>")
    with pytest.raises(InputError, match="the model has no body and no site: no frame to pose"):
        poekin.load_tree(path)
    path.write_text('<mujoco><worldbody><site name="s" pos="1 2 3"/></worldbody></mujoco>')
    tree = poekin.load_tree(path)
    assert_close("world site", tree.fk(np.zeros(0))[0, :3, 3], [1.0, 2.0, 3.0], 0.0)


def test_load_tree_from_a_path(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "features.xml"
    path.write_text(FEATURES_XML)
    tree = poekin.load_tree(path)
    assert tree.robot == "features.xml"
    assert repr(tree) == "Tree('features.xml', 7 bodies, 8 joints, 4 sites, nq=17, nv=15)"
    described = tree.describe()
    assert described["joints"][3] == {
        "name": "wrist_ball",
        "type": "ball",
        "body": "wrist",
        "qpos_adr": 3,
    }


def test_a_chain_from_a_base_body_is_the_pose_relative_to_it(go2: Tree) -> None:
    """go2's leg from its floating base: T_base_foot, whatever the base's free joint does."""
    chain = go2.chain("FL_calf", base="base")
    assert chain.joint_names == ("FL_hip_joint", "FL_thigh_joint", "FL_calf_joint")
    qpos = sample_qpos(go2, 200, seed=21)
    expected = go2.pose(qpos, "FL_calf", relative_to="base")
    assert_close("T_base_foot", chain.fk(qpos[:, list(chain.qpos_indices)]), expected, 1e-14)
    arm = poekin.load_tree(load_quiet("aloha"))
    whole, part = arm.chain("left/gripper"), arm.chain("left/gripper", base="left/upper_arm_link")
    q = sample_qpos(arm, 50, seed=22)
    assert part.joint_names == whole.joint_names[2:]
    relative = arm.pose(q, "left/gripper", relative_to="left/upper_arm_link")
    assert_close("T_upper_arm_gripper", part.fk(q[:, list(part.qpos_indices)]), relative, 1e-14)


def test_a_base_off_the_path_or_unknown_is_refused(go2: Tree) -> None:
    with pytest.raises(ModelError, match="body 'FR_hip' is not on the path from the world"):
        go2.chain("FL_calf", base="FR_hip")
    with pytest.raises(UnknownFrameError, match="no body named 'bse': did you mean 'base'"):
        go2.chain("FL_calf", base="bse")


# --- mimic joints and hand-built trees ----------------------------------------------------------


def _two_link(mimics: tuple[Mimic | None, ...]) -> Tree:
    return Tree(
        body_names=("a", "b"),
        body_parents=[-1, 0],
        body_pos=[[0.0, 0.0, 0.1], [0.3, 0.0, 0.0]],
        body_rot=[np.eye(3), np.eye(3)],
        joint_names=("j1", "j2"),
        joint_types=("revolute", "revolute"),
        joint_bodies=[0, 1],
        joint_axes=[[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]],
        joint_anchors=np.zeros((2, 3)),
        joint_refs=np.zeros(2),
        joint_limits=[[-np.inf, np.inf]] * 2,
        mimics=mimics,
        site_names=("tip",),
        site_bodies=[1],
        site_pos=[[0.2, 0.0, 0.0]],
        site_rot=[np.eye(3)],
    )


def test_mimic_follower_is_multiplier_times_leader_plus_offset() -> None:
    free = _two_link((None, None))
    mimic = _two_link((None, Mimic("j1", multiplier=-2.0, offset=0.25)))
    assert (mimic.nq, mimic.nv, free.nq) == (1, 1, 2)
    q1 = np.linspace(-3, 3, 13)
    expected = free.fk(np.stack([q1, -2.0 * q1 + 0.25], axis=-1))
    assert_close("mimic", mimic.fk(q1[:, None]), expected, 0.0)
    # hand check: planar two-link arm, tip at l1 (cos q1, sin q1) + l2 (cos(q1+q2), sin(q1+q2))
    q2 = -2.0 * q1 + 0.25
    tip = mimic.fk(q1[:, None])[:, mimic.frame_index("tip"), :3, 3]
    hand = np.stack(
        [0.3 * np.cos(q1) + 0.2 * np.cos(q1 + q2), 0.3 * np.sin(q1) + 0.2 * np.sin(q1 + q2)], -1
    )
    assert_close("tip x, y", tip[:, :2], hand, 1e-15)
    assert_close("tip z", tip[:, 2], np.full(13, 0.1), 0.0)
    chain = mimic.chain("tip")  # the follower becomes an independent chain joint
    assert chain.qpos_indices is None
    assert_close("chain", chain.fk(np.stack([q1, q2], -1)), expected[:, 2], 1e-15)


def test_a_follower_may_come_before_its_leader() -> None:
    """The follower j1 is the parent joint of its leader j2: qpos holds j2 alone, and the
    Jacobian column of j2 holds both joints' motion, as the derivative of fk says."""
    mimic = _two_link((Mimic("j2", multiplier=-2.0, offset=0.25), None))
    free = _two_link((None, None))
    assert (mimic.nq, mimic.nv, tuple(mimic.qpos_adr)) == (1, 1, (0, 0))
    assert mimic.qpos_layout() == "qpos = [j2]"
    q2 = np.linspace(-3, 3, 13)
    full = np.stack([-2.0 * q2 + 0.25, q2], axis=-1)
    assert_close("full_qpos", mimic.full_qpos(q2[:, None]), full, 0.0)
    assert_close("fk", mimic.fk(q2[:, None]), free.fk(full), 0.0)
    assert_close("numpy fk", mimic._fk_numpy(q2[:, None]), free._fk_numpy(full), 0.0)
    J = free.jacobian(full, "tip")
    tip = mimic.frame_index("tip")
    for J_mimic in (
        mimic.jacobian(q2[:, None], "tip"),
        mimic._jacobian_numpy(q2[:, None], tip, "world"),
    ):
        assert_close("jacobian", J_mimic[..., 0], -2.0 * J[..., 0] + J[..., 1], 1e-15)


def _random_chain_tree(rng: np.random.Generator, n: int, mimics: list[Mimic | None]) -> Tree:
    """A serial tree of ``n`` hinges and slides with random offsets and axes."""
    axes = rng.normal(size=(n, 3))
    return Tree(
        body_names=tuple(f"b{k}" for k in range(n)),
        body_parents=np.arange(n) - 1,
        body_pos=rng.uniform(-0.5, 0.5, (n, 3)),
        body_rot=[lie.exp_so3(w) for w in rng.normal(size=(n, 3))],
        joint_names=tuple(f"j{k}" for k in range(n)),
        joint_types=tuple(rng.choice(["revolute", "prismatic"], n).tolist()),
        joint_bodies=np.arange(n),
        joint_axes=axes / np.linalg.norm(axes, axis=1, keepdims=True),
        joint_anchors=rng.uniform(-0.1, 0.1, (n, 3)),
        joint_refs=np.zeros(n),
        joint_limits=[[-np.inf, np.inf]] * n,
        mimics=mimics,
    )


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 7))
def test_followers_anywhere_move_as_their_leaders_say(seed: int, n: int) -> None:
    """Random followers of random leaders, before or after them: fk is the tree without mimics
    at the expanded positions, and each Jacobian column the sum of the columns of its joints."""
    rng = np.random.default_rng(seed)
    follows = rng.random(n) < 0.5
    follows[rng.integers(n)] = False  # at least one leader
    leaders = np.flatnonzero(~follows)
    mimics: list[Mimic | None] = [
        Mimic(f"j{rng.choice(leaders)}", float(rng.uniform(-2, 2)), float(rng.uniform(-1, 1)))
        if f
        else None
        for f in follows
    ]
    tree = _random_chain_tree(np.random.default_rng(seed), n, mimics)
    free = _random_chain_tree(np.random.default_rng(seed), n, [None] * n)
    q = rng.uniform(-3, 3, (5, len(leaders)))
    full = np.empty((5, n))
    to_tree = np.zeros((n, len(leaders)))  # d full / d q
    for k, mimic in enumerate(mimics):
        column = np.searchsorted(leaders, k if mimic is None else int(mimic.leader[1:]))
        scale, offset = (1.0, 0.0) if mimic is None else (mimic.multiplier, mimic.offset)
        full[:, k] = scale * q[:, column] + offset
        to_tree[k, column] = scale
    assert tree.nq == tree.nv == len(leaders)
    assert_close("full_qpos", tree.full_qpos(q), full, 0.0)
    assert_close("fk", tree.fk(q), free.fk(full), 0.0)
    for frame in tree.frame_names:
        expected = free.jacobian(full, frame) @ to_tree
        assert_close(frame, tree.jacobian(q, frame), expected, 1e-13)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"body_parents": [1, -1]}, "must come before it"),
        ({"joint_types": ("revolute", "screw")}, "unknown type 'screw'"),
        ({"joint_axes": [[0.0, 0.0, 2.0], [0.0, 0.0, 1.0]]}, "'j1' must be a unit vector"),
        ({"mimics": (None, Mimic("j0"))}, "mimics 'j0', which is no joint: .*Valid names: 'j1'"),
        ({"mimics": (Mimic("j2"), Mimic("j1"))}, "'j1' mimics 'j2', which mimics 'j1' itself"),
        ({"mimics": (Mimic("j1"), None)}, "'j1' mimics 'j1', which mimics 'j1' itself: a leader"),
        ({"body_rot": [np.eye(3), 2 * np.eye(3)]}, "body_rot of 'b' is not a rotation"),
        ({"joint_types": ("revolute", "free")}, "free joint 'j2' must be the only joint"),
        ({"joint_limits": [[1.0, -1.0]] * 2}, "lower <= upper"),
        ({"site_bodies": [5]}, "site_bodies must be body indices"),
        ({"body_pos": np.zeros((3, 3))}, r"body_pos must have shape \(2, 3\)"),
    ],
)
def test_invalid_trees_are_refused(change: dict[str, object], message: str) -> None:
    fields = {
        f.name: getattr(_two_link((None, None)), f.name) for f in dataclasses.fields(Tree) if f.init
    }
    fields.update(change)
    with pytest.raises(InputError, match=message):
        Tree(**fields)  # type: ignore[arg-type]


def test_pose_of_one_frame_relative_to_another() -> None:
    """issue #15: T_a_b(qpos) between any two frames (a go2 calf in its trunk's frame)."""
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    qpos = poekin.sample_qpos(tree, 7, seed=2).reshape(7, 1, 19)
    T = tree.fk(qpos)
    base, calf = tree.frame_index("base"), tree.frame_index("FL_calf")
    assert np.array_equal(tree.pose(qpos, "FL_calf"), T[..., calf, :, :])
    T_base_calf = tree.pose(qpos, "FL_calf", relative_to="base")
    assert T_base_calf.shape == (7, 1, 4, 4)
    # independent: the composition T_world_base T_base_calf gives T_world_calf back
    assert_close("T_world_calf", T[..., base, :, :] @ T_base_calf, T[..., calf, :, :], 1e-15)
    # the calf's pose in the base frame does not depend on where the base is (the free joint)
    moved = qpos.copy()
    moved[..., :7] = [0.3, -2.0, 1.0, 0.5, 0.5, -0.5, 0.5]
    assert_close("base-free", tree.pose(moved, "FL_calf", "base"), T_base_calf, 1e-14)
    with pytest.raises(poekin.UnknownFrameError, match="did you mean 'FL_calf'"):
        tree.pose(qpos, "FL_clf")


def test_qpos_names() -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    names = tree.qpos_names()
    assert len(names) == tree.nq == 19
    assert names[:8] == (
        "joint0[x]", "joint0[y]", "joint0[z]",
        "joint0[qw]", "joint0[qx]", "joint0[qy]", "joint0[qz]",
        "FL_hip_joint",
    )  # fmt: skip
