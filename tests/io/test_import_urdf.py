"""Trees from URDF files: poses checked by hand, every body against MuJoCo compiling the same
URDF and against Pinocchio reading it, fixed links, mimic joints (leaders before and after),
limits as MuJoCo reads them, meshes that do not exist, floating bases, files as ROS packages
ship them, and the errors: one line for each malformed file."""

from __future__ import annotations

import logging
import pathlib
import re
import sys

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, pinocchio_q

from poekin import ModelError, URDFError
from poekin._extras import install_command
from poekin.errors import MissingExtraError
from poekin.io.import_urdf import FLOATING_BASE, URDFLimitsWarning, tree_from_urdf
from poekin.io.sources import _mujoco_warnings
from poekin.tree import Mimic, Tree
from poekin.verification.verify import sample_qpos

# limits.urdf's note is checked once, in test_unusable_limits_are_unlimited_as_in_mujoco
pytestmark = pytest.mark.filterwarnings("ignore::poekin.io.import_urdf.URDFLimitsWarning")
DATA = pathlib.Path(__file__).parents[1] / "data" / "urdf"
N_SAMPLES = 1000
HAND_TOL = 1e-14  # closed form vs tree.fk: a few roundings of numbers of order 1

# (fixture, floating_base): every URDF fixture, and the serial arm on a floating base.
MUJOCO_CASES = [
    ("serial_arm.urdf", False),
    ("serial_arm.urdf", True),
    ("two_arms.urdf", False),
    ("planar_2link.urdf", False),
    ("package_meshes.urdf", False),
    ("world_floating.urdf", False),
    ("gripper_mimic_later.urdf", False),
    ("limits.urdf", False),
    ("ros_package.urdf", False),
    ("bullet_spherical.urdf", False),
]
# Pinocchio (urdfdom) refuses a revolute or prismatic joint without <limit>, as limits.urdf has,
# and the spherical joint type
PINOCCHIO_CASES = [c for c in MUJOCO_CASES if c[0] not in ("limits.urdf", "bullet_spherical.urdf")]


def Rx(a: float) -> np.ndarray:
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def Ry(a: float) -> np.ndarray:
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def Rz(a: float) -> np.ndarray:
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation of the unit quaternion ``q = (w, x, y, z)``."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def compile_with_mujoco(path: pathlib.Path, floating_base: bool | str) -> mujoco.MjModel:
    """MuJoCo's model of the same URDF, one body per link: the recipe ``poekin verify`` needs.

    fusestatic=False keeps fixed-joint links as bodies (MuJoCo's URDF default fuses them, and
    the root link too, into their parents); the meshes go, since MuJoCo opens ``package://``
    URIs as files when it compiles; boundmass/boundinertia give massless moving links (their
    mass lived in a deleted mesh or was never given) the mass MuJoCo insists on.
    ``floating_base``: add a free joint named so (True: FLOATING_BASE) to the root link.
    """
    with _mujoco_warnings():  # e.g. limits.urdf's lower = upper: no MUJOCO_LOG.TXT here
        spec = mujoco.MjSpec.from_file(str(path))
    spec.compiler.fusestatic = False
    spec.compiler.boundmass = 1e-6
    spec.compiler.boundinertia = 1e-9
    for geom in list(spec.geoms):
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
            spec.delete(geom)
    for mesh in list(spec.meshes):
        spec.delete(mesh)
    if floating_base:
        name = floating_base if isinstance(floating_base, str) else FLOATING_BASE
        spec.worldbody.first_body().add_freejoint(name=name)
    return spec.compile()


def random_qpos(tree: Tree, n: int, seed: int) -> np.ndarray:
    """``(n, nq)``: hinges in [-2 pi, 2 pi], slides within limits (else +-1 m), ball joints a
    random, unnormalised quaternion, free joints one at a random position."""
    rng = np.random.default_rng(seed)
    q = np.empty((n, tree.nq))
    for k, kind in enumerate(tree.joint_types):
        if tree.mimics[k] is not None:
            continue
        a = int(tree.qpos_adr[k])
        if kind in ("free", "ball"):
            if kind == "free":
                q[:, a : a + 3] = rng.uniform(-2.0, 2.0, size=(n, 3))
                a += 3
            q[:, a : a + 4] = rng.normal(size=(n, 4)) * rng.uniform(0.1, 10.0, size=(n, 1))
        elif kind == "revolute":
            q[:, a] = rng.uniform(-2 * np.pi, 2 * np.pi, size=n)
        else:
            lo, hi = tree.joint_limits[k]
            limited = np.isfinite(lo) and np.isfinite(hi)
            q[:, a] = rng.uniform(lo, hi, size=n) if limited else rng.uniform(-1, 1, n)
    return q


def joint_positions(tree: Tree, qpos: np.ndarray, joints: tuple[int, ...]) -> np.ndarray:
    """``(n, len(joints))`` hinge/slide positions of ``joints``, followers from their leader."""
    out = np.empty((qpos.shape[0], len(joints)))
    for col, k in enumerate(joints):
        mimic = tree.mimics[k]
        leader = qpos[:, tree.qpos_adr[k]]
        out[:, col] = leader if mimic is None else mimic.multiplier * leader + mimic.offset
    return out


def mujoco_body_poses(model: mujoco.MjModel, tree: Tree, qpos: np.ndarray) -> np.ndarray:
    """``(n, nb, 4, 4)`` MuJoCo's pose of each tree body (by name) after ``mj_kinematics``,
    each MuJoCo joint (by name) set from the tree's qpos; followers set by hand."""
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in tree.body_names]
    adr = [model.jnt_qposadr[model.joint(name).id] for name in tree.joint_names]
    hinges = [k for k, t in enumerate(tree.joint_types) if t in ("revolute", "prismatic")]
    quats = {k: 7 if t == "free" else 4 for k, t in enumerate(tree.joint_types) if k not in hinges}
    positions = joint_positions(tree, qpos, tuple(hinges))
    out = np.zeros((qpos.shape[0], len(ids), 4, 4))
    out[..., 3, 3] = 1.0
    for i in range(qpos.shape[0]):
        for k, size in quats.items():
            data.qpos[adr[k] : adr[k] + size] = qpos[i, tree.qpos_adr[k] : tree.qpos_adr[k] + size]
        data.qpos[[adr[k] for k in hinges]] = positions[i]
        mujoco.mj_kinematics(model, data)
        out[i, :, :3, :3] = data.xmat[ids].reshape(-1, 3, 3)
        out[i, :, :3, 3] = data.xpos[ids]
    return out


# --- by hand --------------------------------------------------------------------------------


def test_planar_two_link_matches_closed_form() -> None:
    tree = tree_from_urdf(DATA / "planar_2link.urdf")
    l1, l2, height = 0.4, 0.3, 0.5
    q = np.random.default_rng(0).uniform(-2 * np.pi, 2 * np.pi, size=(200, 2))
    T = tree.fk(q)
    for (q1, q2), poses in zip(q, T, strict=True):
        forearm = poses[tree.frame_index("forearm")]
        tool = poses[tree.frame_index("tool")]
        elbow = np.array([l1 * np.cos(q1), l1 * np.sin(q1), height])
        tip = elbow + np.array([l2 * np.cos(q1 + q2), l2 * np.sin(q1 + q2), 0.0])
        assert_close("forearm position", forearm[:3, 3], elbow, HAND_TOL)
        assert_close("forearm rotation", forearm[:3, :3], Rz(q1 + q2), HAND_TOL)
        assert_close("tool position", tool[:3, 3], tip, HAND_TOL)
        rpy = Rz(0.5) @ Ry(-0.2) @ Rx(0.3)  # URDF rpy = (0.3, -0.2, 0.5): fixed axes X, Y, Z
        assert_close("tool rotation", tool[:3, :3], Rz(q1 + q2) @ rpy, HAND_TOL)


def test_rpy_rotation_written_out() -> None:
    """tool0's rpy = (0.25, 0.5, -0.75) as the explicit product of the three matrices."""
    tree = tree_from_urdf(DATA / "serial_arm.urdf")
    r, p, y = 0.25, 0.5, -0.75
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    expected = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    tool = tree.body_names.index("tool0")
    assert_close("tool0 body_rot", tree.body_rot[tool], expected, HAND_TOL)
    assert_close("tool0 body_pos", tree.body_pos[tool], [0, 0, 0.12], 0.0)


def test_serial_arm_joints() -> None:
    tree = tree_from_urdf(DATA / "serial_arm.urdf")
    assert tree.robot == "serial_arm"
    assert tree.joint_types == ("revolute",) * 6
    s = np.sqrt(0.5)
    axes = [[0, 0, 1], [1, 0, 0], [0, 0.6, 0.8], [0, 0, -1], [s, s, 0], [0, 1, 0]]
    assert_close("axes (j2: default x; j3, j5: normalised)", tree.joint_axes, axes, 2e-16)
    assert_close("anchors", tree.joint_anchors, np.zeros((6, 3)), 0.0)
    assert_close("refs", tree.joint_refs, np.zeros(6), 0.0)
    limits = [[-3.1, 3.1], [-2, 2], [-2.5, 2.5], [-np.inf, np.inf], [-2, 2], [-6.28, 6.28]]
    np.testing.assert_array_equal(tree.joint_limits, limits)  # j4 is continuous
    assert tree.qpos_layout() == "qpos = [j1, j2, j3, j4, j5, j6]"


def test_label_overrides_robot_name() -> None:
    assert tree_from_urdf(DATA / "serial_arm.urdf", robot="arm.urdf").robot == "arm.urdf"


def test_fixed_links_stay_frames() -> None:
    tree = tree_from_urdf(DATA / "two_arms.urdf")
    flange, tool = tree.frame_index("left_flange"), tree.frame_index("left_tool")
    assert tree.body_parents[tool] == flange
    assert tree.body_names[tree.body_parents[flange]] == "left_wrist"
    assert "left_flange_joint" not in tree.joint_names
    q = random_qpos(tree, 50, seed=1)
    T = tree.fk(q)
    offset = np.eye(4)
    offset[:3, :3] = Rz(0.3) @ Ry(0.2) @ Rx(0.1)
    offset[:3, 3] = [0.01, 0, 0.1]
    assert_close("tool = flange @ origin", T[:, tool], T[:, flange] @ offset, 1e-15)


def test_prismatic_limits_and_bodies_follow_joint_order() -> None:
    tree = tree_from_urdf(DATA / "two_arms.urdf")
    # links are listed right arm first; the joints, and so the bodies, left arm first
    assert tree.body_names[:2] == ("torso", "left_shoulder")
    assert tree.body_names[6] == "right_shoulder"
    k = tree.joint_names.index("left_extend")
    assert tree.joint_types[k] == "prismatic"
    np.testing.assert_array_equal(tree.joint_limits[k], [-0.05, 0.25])


def test_mimic_chain_resolved_to_independent_joint() -> None:
    tree = tree_from_urdf(DATA / "two_arms.urdf")
    mimics = dict(zip(tree.joint_names, tree.mimics, strict=True))
    assert mimics["right_finger_a_joint"] == Mimic("right_grip", 0.05, 0.001)
    b = mimics["right_finger_b_joint"]  # -2 * (0.05 grip + 0.001) + 0.01
    assert b is not None and b.leader == "right_grip"
    assert_close("chained multiplier, offset", [b.multiplier, b.offset], [-0.1, 0.008], 1e-17)
    assert mimics["right_finger_tip_joint"] == Mimic("right_grip", 1.0, 0.0)
    assert (tree.nq, len(tree.joint_names)) == (6, 9)
    grip = tree.qpos_adr[tree.joint_names.index("right_grip")]
    assert tree.qpos_adr[tree.joint_names.index("right_finger_b_joint")] == grip


def test_followers_before_their_leader() -> None:
    """Finger joints listed (and so in the body order) before the joint that drives them:
    qpos holds the independent joints in body order, every follower takes its leader's entry."""
    tree = tree_from_urdf(DATA / "gripper_mimic_later.urdf")
    assert tree.qpos_layout() == "qpos = [arm_joint, wrist_joint, drive]"
    mimics = dict(zip(tree.joint_names, tree.mimics, strict=True))
    assert mimics["left_finger_joint"] == Mimic("drive", 0.02, 0.001)
    assert mimics["knuckle_joint"] == Mimic("drive", -1.0, 0.1)
    assert mimics["tip_joint"] == Mimic("drive", -0.5, 0.05)  # 0.5 * (-1 drive + 0.1)
    drive = tree.joint_names.index("drive")
    assert drive > tree.joint_names.index("knuckle_joint")
    assert all(tree.qpos_adr[k] == 2 for k, m in enumerate(tree.mimics) if m is not None)
    assert tree.dof_names() == ("arm_joint", "wrist_joint", "drive")


def test_spherical_joint_is_a_ball_joint() -> None:
    """Bullet's spherical joint, as MuJoCo reads it: a ball joint, qpos a quaternion wxyz."""
    tree = tree_from_urdf(DATA / "bullet_spherical.urdf")
    assert tree.joint_types == ("revolute", "ball")
    assert tree.qpos_layout() == "qpos = [waist_joint, hip (ball: qw qx qy qz)]"
    model = compile_with_mujoco(DATA / "bullet_spherical.urdf", floating_base=False)
    np.testing.assert_array_equal(tree.qpos0, model.qpos0)


@pytest.mark.parametrize(
    "contents",
    [
        '<visual><origin xyz="0 1"/><geometry><box size="1 1 1"/></geometry></visual>',
        '<visual><origin xyz="0 0 1"/></visual>',  # no <geometry>
    ],
)
def test_link_contents_are_not_read(tmp_path: pathlib.Path, contents: str) -> None:
    """Flawed geometry or inertia that MuJoCo and Pinocchio let pass (yourdfpy refused each):
    poekin reads links' names only."""
    path = tmp_path / "robot.urdf"
    text = _urdf(_joint("ja", "revolute", "base", "a", '<limit lower="-1" upper="1"/>'), "base")
    path.write_text(text.replace("</robot>", f'<link name="a">{contents}</link></robot>'))
    tree = tree_from_urdf(path)
    model = compile_with_mujoco(path, floating_base=False)
    q = random_qpos(tree, 20, seed=9)
    assert_close("MuJoCo", tree.fk(q), mujoco_body_poses(model, tree, q), MJ_TOL)


def test_package_meshes_are_never_opened(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.DEBUG, logger="yourdfpy"):
        tree = tree_from_urdf(DATA / "package_meshes.urdf")
    assert not caplog.records, "yourdfpy looked for a mesh"
    assert tree.body_names == ("base_link", "arm", "hand")
    assert_close("arm offset", tree.body_pos[1], [0, 0, 0.1], 0.0)


def test_floating_base_layout() -> None:
    fixed = tree_from_urdf(DATA / "serial_arm.urdf")
    tree = tree_from_urdf(DATA / "serial_arm.urdf", floating_base=True)
    assert tree.joint_names == (FLOATING_BASE, *fixed.joint_names)
    assert (tree.joint_types[0], tree.joint_bodies[0], tree.nq) == ("free", 0, 13)
    np.testing.assert_array_equal(tree.qpos0[:7], [0, 0, 0, 1, 0, 0, 0])
    q = random_qpos(tree, 20, seed=2)
    T_base = np.eye(4)
    quat = q[:, 3:7] / np.linalg.norm(q[:, 3:7], axis=1, keepdims=True)
    for i in range(20):
        T_base[:3, :3] = _quat_matrix(quat[i])
        T_base[:3, 3] = q[i, :3]
        assert_close(
            "floating tree = base @ fixed tree", tree.fk(q[i]), T_base @ fixed.fk(q[i, 7:]), 1e-14
        )


def test_world_root_link_is_the_world() -> None:
    tree = tree_from_urdf(DATA / "world_floating.urdf")
    assert "world" not in tree.body_names
    assert tree.body_names[0] == "base" and tree.body_parents[0] == -1
    assert tree.joint_names[0] == "base_float" and tree.joint_types[0] == "free"
    expected = [0, 0, 0.4, np.cos(0.1), 0, 0, np.sin(0.1)]  # origin xyz, rpy (0, 0, 0.2)
    assert_close("qpos0 of the floating joint = its origin", tree.qpos0[:7], expected, 2e-16)


@pytest.mark.parametrize(
    "before", [b"\n", b"\n  \n\t", b"\r\n\r\n", b"\xef\xbb\xbf\n", b"\xef\xbb\xbf"]
)
def test_blank_lines_before_the_xml_declaration(tmp_path: pathlib.Path, before: bytes) -> None:
    """Accepted as MuJoCo and Pinocchio accept them (their XML reader, tinyxml2, skips them),
    with or without a UTF-8 byte order mark, and MuJoCo reads the same robot."""
    path = tmp_path / "blank_first.urdf"
    path.write_bytes(before + (DATA / "serial_arm.urdf").read_bytes())
    tree, expected = tree_from_urdf(path), tree_from_urdf(DATA / "serial_arm.urdf")
    assert tree.joint_names == expected.joint_names
    q = random_qpos(tree, 50, seed=5)
    assert_close("same poses", tree.fk(q), expected.fk(q), 0.0)
    model = compile_with_mujoco(path, floating_base=False)
    assert_close("MuJoCo", tree.fk(q), mujoco_body_poses(model, tree, q), MJ_TOL)


@pytest.mark.parametrize("variant", ["CRLF", "BOM CRLF", "CR", "tabs and newlines in numbers"])
def test_line_endings_and_spaces(tmp_path: pathlib.Path, variant: str) -> None:
    """Windows (and old Mac) line endings, a byte order mark, and numbers split by tabs and
    newlines (XML reads them as spaces; so does MuJoCo, not Pinocchio): the same robot as MuJoCo
    reads it."""
    text = (DATA / "ros_package.urdf").read_text()
    if variant == "tabs and newlines in numbers":
        text = text.replace('xyz="-0.425 0 0"', 'xyz="-0.425\t0\n\t0"')
    else:
        text = text.replace("\n", "\r" if variant == "CR" else "\r\n")
    path = tmp_path / "variant.urdf"
    path.write_bytes(b"\xef\xbb\xbf" * ("BOM" in variant) + text.encode())
    tree, expected = tree_from_urdf(path), tree_from_urdf(DATA / "ros_package.urdf")
    q = random_qpos(tree, 50, seed=8)
    assert_close("same poses", tree.fk(q), expected.fk(q), 0.0)
    model = compile_with_mujoco(path, floating_base=False)
    assert_close("MuJoCo", tree.fk(q), mujoco_body_poses(model, tree, q), MJ_TOL)


def test_parse_errors_after_blank_lines_name_the_right_line(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "broken.urdf"
    path.write_text('\n\n<?xml version="1.0"?>\n<robot name="r">\n<link name="a">\n</robot>\n')
    with pytest.raises(ModelError, match="mismatched tag: line 6, column 2"):
        tree_from_urdf(path)


# --- against MuJoCo -------------------------------------------------------------------------


@pytest.mark.parametrize(("fixture", "floating_base"), MUJOCO_CASES)
def test_same_bodies_joints_and_qpos_order_as_mujoco(fixture: str, floating_base: bool) -> None:
    tree = tree_from_urdf(DATA / fixture, floating_base=floating_base)
    model = compile_with_mujoco(DATA / fixture, floating_base)
    bodies = tuple(model.body(i).name for i in range(1, model.nbody))
    joints = tuple(model.joint(j).name for j in range(model.njnt))
    assert tree.body_names == bodies
    assert tree.joint_names == joints
    parents = tuple(model.body_parentid[1:] - 1)
    assert tuple(tree.body_parents) == parents
    independent = [j for j, m in enumerate(tree.mimics) if m is None]
    mj_adr = model.jnt_qposadr[independent]
    assert np.all(np.diff(mj_adr) > 0), "independent joints in the same qpos order"
    if all(m is None for m in tree.mimics):
        np.testing.assert_array_equal(tree.qpos_adr, model.jnt_qposadr)
        assert tree.nq == model.nq


@pytest.mark.parametrize(("fixture", "floating_base"), MUJOCO_CASES)
def test_every_body_matches_mujoco(fixture: str, floating_base: bool) -> None:
    tree = tree_from_urdf(DATA / fixture, floating_base=floating_base)
    model = compile_with_mujoco(DATA / fixture, floating_base)
    q = random_qpos(tree, N_SAMPLES, seed=3)
    expected = mujoco_body_poses(model, tree, q)
    T = tree.fk(q)
    for b, name in enumerate(tree.body_names):
        assert_close(f"{fixture}: {name}", T[:, b], expected[:, b], MJ_TOL)


@pytest.mark.parametrize(("fixture", "floating_base"), MUJOCO_CASES)
def test_limits_are_mujocos(fixture: str, floating_base: bool) -> None:
    """MuJoCo's range where MuJoCo limits the joint, else unlimited: ``sample_qpos`` and
    ``--within-limits`` then sample what a model verified against MuJoCo allows."""
    tree = tree_from_urdf(DATA / fixture, floating_base=floating_base)
    model = compile_with_mujoco(DATA / fixture, floating_base)
    hinges = [k for k, t in enumerate(tree.joint_types) if t != "free"]
    expected = np.where(model.jnt_limited[hinges, None], model.jnt_range[hinges], [-np.inf, np.inf])
    np.testing.assert_array_equal(tree.joint_limits[hinges], expected)


def test_unusable_limits_are_unlimited_as_in_mujoco() -> None:
    """One note names the joints whose <limit> gives no range (limits.urdf has one of each
    kind), and says why."""
    with pytest.warns(URDFLimitsWarning) as notes:
        tree = tree_from_urdf(DATA / "limits.urdf")
    assert len(notes) == 1
    note = str(notes[0].message)
    assert note.startswith(f"{DATA / 'limits.urdf'}: 7 joints are unlimited, as in MuJoCo (")
    assert "\n" not in note
    assert """'bullet_no_limit': <limit lower="1" upper="-1">, Bullet's "no limit";""" in note
    assert note.endswith("; and 4 more)")
    limits = dict(zip(tree.joint_names, tree.joint_limits.tolist(), strict=True))
    assert limits.pop("normal") == [-1.0, 2.0]
    assert limits.pop("slide") == [-0.2, 0.3]
    assert all(lower_upper == [-np.inf, np.inf] for lower_upper in limits.values())
    q = sample_qpos(tree, 200, seed=0, within_limits=True)
    assert np.ptp(q[:, tree.joint_names.index("equal")]) > 6, "samples [-2 pi, 2 pi]"


@pytest.mark.parametrize(
    ("joint", "why"),
    [
        ('<limit lower="0" upper="0" effort="1" velocity="1"/>', '<limit lower="0" upper="0">'),
        ('<limit effort="1" velocity="1"/>', "<limit> without lower and upper, which the URDF"),
        ('<limit upper="1" effort="1" velocity="1"/>', "<limit> with upper only"),
        ("", "no <limit>"),
    ],
)
def test_each_unusable_limit_is_named(tmp_path: pathlib.Path, joint: str, why: str) -> None:
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf(_joint("jl", "prismatic", "base", "a", joint), "base a"))
    with pytest.warns(
        URDFLimitsWarning, match=f"1 joint is unlimited, as in MuJoCo \\('jl': {re.escape(why)}"
    ):
        tree = tree_from_urdf(path)
    np.testing.assert_array_equal(tree.joint_limits, [[-np.inf, np.inf]])


def test_usable_limits_give_no_note(recwarn: pytest.WarningsRecorder) -> None:
    for fixture in ("serial_arm.urdf", "two_arms.urdf", "gripper_mimic_later.urdf"):
        tree_from_urdf(DATA / fixture)
    assert not recwarn.list


@pytest.mark.parametrize(
    ("fixture", "frame"),
    [
        ("serial_arm.urdf", "tool0"),
        ("serial_arm.urdf", "link3"),
        ("two_arms.urdf", "left_tool"),
        ("two_arms.urdf", "right_finger_tip"),  # two followers on the path
        ("planar_2link.urdf", "tool"),
        ("package_meshes.urdf", "hand"),
        ("gripper_mimic_later.urdf", "tool"),  # a follower before its leader on the path
        ("gripper_mimic_later.urdf", "right_finger"),
        ("ros_package.urdf", "tool0"),
    ],
)
def test_chain_matches_tree_and_mujoco(fixture: str, frame: str) -> None:
    tree = tree_from_urdf(DATA / fixture)
    chain = tree.chain(frame)
    q = random_qpos(tree, N_SAMPLES, seed=4)
    T_chain = chain.fk(joint_positions(tree, q, tree.path_joints(frame)))
    b = tree.frame_index(frame)
    assert_close(f"{frame}: chain vs tree", T_chain, tree.fk(q)[:, b], MJ_TOL)
    expected = mujoco_body_poses(compile_with_mujoco(DATA / fixture, False), tree, q)
    assert_close(f"{frame}: chain vs MuJoCo", T_chain, expected[:, b], MJ_TOL)


# --- against Pinocchio ----------------------------------------------------------------------


@pytest.mark.parametrize(("fixture", "floating_base"), PINOCCHIO_CASES)
def test_every_link_matches_pinocchio(fixture: str, floating_base: bool) -> None:
    """Pinocchio reads the URDF with its own parser (urdfdom), orders the joints its own way
    (children by joint name), and gives each link a frame: every link's pose on random qpos."""
    import pinocchio as pin

    path = str(DATA / fixture)
    tree = tree_from_urdf(path, floating_base=floating_base)
    model = pin.buildModelFromUrdf(path, *([pin.JointModelFreeFlyer()] if floating_base else []))
    assert model.njoints - 1 == len(tree.joint_names)
    data = model.createData()
    qpos = random_qpos(tree, 300, seed=7)
    frames = [model.getFrameId(name, pin.FrameType.BODY) for name in tree.body_names]
    expected = np.empty((len(qpos), len(frames), 4, 4))
    for n, q in enumerate(pinocchio_q(model, tree, qpos)):
        pin.framesForwardKinematics(model, data, q)
        expected[n] = [data.oMf[f].homogeneous for f in frames]
    assert_close(fixture, tree.fk(qpos), expected, MJ_TOL)


# --- errors ---------------------------------------------------------------------------------


def _urdf(joints: str, links: str = "base a b") -> str:
    """A URDF with the given links and joint elements."""
    link_xml = "".join(f'<link name="{name}"/>' for name in links.split())
    return f'<robot name="r">{link_xml}{joints}</robot>'


def _joint(name: str, kind: str, parent: str, child: str, extra: str = "") -> str:
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
        f'<child link="{child}"/>{extra}</joint>'
    )


CHAIN = _joint("ja", "continuous", "base", "a")
ERROR_CASES = {
    "bad XML": ("<robot name='r'><link name='a'></robot>", "not well-formed XML"),
    "MJCF": ("<mujoco><worldbody/></mujoco>", "not a URDF: the root element is <mujoco>"),
    "not a robot": ("<html/>", "not a URDF"),
    "xacro": (
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:macro name="m"/>'
        "</robot>",
        "robot.urdf: a xacro file, not URDF yet (it has <xacro:macro>); expand it first with "
        "ROS's xacro: xacro ",
    ),
    "xacro undeclared": (
        '<robot name="r"><xacro:include filename="arm.xacro"/></robot>',
        "a xacro file, not URDF yet (it has <xacro:...> elements)",
    ),
    "xacro attribute": (
        '<robot name="r" xmlns:x="http://ros.org/wiki/xacro"><link name="a" x:if="1"/></robot>',
        "(it has the attribute xacro:if of <link>)",
    ),
    "xacro find": (
        '<robot name="r"><link name="base"><visual><geometry>'
        '<mesh filename="$(find my_robot)/base.stl"/></geometry></visual></link></robot>',
        "(it has $(find my_robot) in <mesh filename>)",
    ),
    "xacro arg": (
        _urdf(_joint("ja", "fixed", "base", "a", '<origin xyz="$(arg x) 0 0"/>'), "base a"),
        "(it has $(arg x) in <origin xyz>)",
    ),
    "xacro property": (
        _urdf(_joint("ja", "fixed", "base", "a", '<origin rpy="0 0 ${pi/2}"/>'), "base a"),
        "(it has ${pi/2} in <origin rpy>)",
    ),
    "xacro optenv": (
        _urdf(_joint("ja", "fixed", "base", "a", '<origin xyz="$(optenv X 0) 0 0"/>'), "base a"),
        "(it has $(optenv X 0) in <origin xyz>)",
    ),
    "no child": (
        _urdf('<joint name="j" type="fixed"><parent link="base"/></joint>'),
        "joint 'j' has no <child",
    ),
    "unnamed link": ('<robot name="r"><link/></robot>', "a <link> has no 'name'"),
    "no link": ('<robot name="r"/>', "no link to pose (a link named 'world' is the world"),
    "unnamed joint": (
        _urdf('<joint type="fixed"><parent link="base"/><child link="a"/></joint>'),
        "a <joint> has no 'name' attribute; add it",
    ),
    "joint without type": (
        _urdf('<joint name="j"><parent link="base"/><child link="a"/></joint>'),
        "joint 'j' has no 'type' attribute; add it",
    ),
    "link twice": (_urdf("", "base a a"), "links named more than once: ['a']; rename them"),
    "joint twice": (
        _urdf(_joint("j", "fixed", "base", "a") + _joint("j", "fixed", "a", "b")),
        "joints named more than once: ['j']; rename them",
    ),
    "every link a child": (
        _urdf(_joint("ja", "fixed", "a", "b") + _joint("jb", "fixed", "b", "a"), "a b"),
        "no root link: the joints form a cycle through every link",
    ),
    "world alone": ('<robot name="r"><link name="world"/></robot>', "no link to pose"),
    "planar": (_urdf(_joint("jp", "planar", "base", "a"), "base a"), "joint 'jp' is planar"),
    "zero axis": (
        _urdf(_joint("jz", "continuous", "base", "a", '<axis xyz="0 0 0"/>'), "base a"),
        "joint 'jz' has a zero <axis xyz> (length 0, under MuJoCo's 1e-7); give the direction",
    ),
    "tiny axis": (  # 5.9e-8^2 + 8e-8^2 < 1e-14: "axis too small" in MuJoCo
        _urdf(_joint("jz", "prismatic", "base", "a", '<axis xyz="5.9e-8 8e-8 0"/>'), "base a"),
        "joint 'jz' has a zero <axis xyz> (length 9.94e-08, under MuJoCo's 1e-7)",
    ),
    "bad number": (
        _urdf(_joint("jn", "continuous", "base", "a", '<origin xyz="0 x 0"/>'), "base a"),
        """joint 'jn': <origin xyz="0 x 0">: 'x' is not a finite number; give 3 numbers""",
    ),
    "NaN origin": (
        _urdf(_joint("jn", "continuous", "base", "a", '<origin rpy="nan 0 0"/>'), "base a"),
        "'nan' is not a finite number; give 3 numbers (roll pitch yaw)",
    ),
    "overflow": (
        _urdf(_joint("jo", "fixed", "base", "a", '<origin xyz="1e999 0 0"/>'), "base a"),
        "'1e999' is not a finite number; give 3 numbers (x y z)",
    ),
    "rpy of 4": (
        _urdf(_joint("jr", "fixed", "base", "a", '<origin rpy="0.1 0.2 0.3 0.4"/>'), "base a"),
        """joint 'jr': <origin rpy="0.1 0.2 0.3 0.4"> has 4 numbers; give 3 numbers (roll pitch""",
    ),
    "xyz of 4": (
        _urdf(_joint("jx", "revolute", "base", "a", '<origin xyz="0 0 1 0"/>'), "base a"),
        """joint 'jx': <origin xyz="0 0 1 0"> has 4 numbers; give 3 numbers (x y z)""",
    ),
    "xyz of 2": (
        _urdf(_joint("jx", "revolute", "base", "a", '<origin xyz="0 1"/>'), "base a"),
        """<origin xyz="0 1"> has 2 numbers; give 3""",
    ),
    "axis with commas": (
        _urdf(_joint("jc", "continuous", "base", "a", '<axis xyz="0,0,1"/>'), "base a"),
        """joint 'jc': <axis xyz="0,0,1">: '0,0,1' is not a finite number; give 3 numbers""",
    ),
    "axis without xyz": (
        _urdf(_joint("ja", "prismatic", "base", "a", "<axis/>"), "base a"),
        """joint 'ja': <axis> has no xyz; give <axis xyz="x y z">, or remove <axis> for the""",
    ),
    **{
        f"two <{tag}>": (
            _urdf(
                _joint("j2", "revolute", "base", "a", repeat) + _joint("jb", "revolute", "a", "b"),
            ),
            f"joint 'j2' has 2 <{tag}> elements; keep one",
        )
        for tag, repeat in [  # _joint gives one <parent> and one <child>
            ("parent", '<parent link="base"/>'),
            ("child", '<child link="a"/>'),
            ("origin", '<origin xyz="0 0 1"/>' * 2),
            ("axis", '<axis xyz="0 0 1"/>' * 2),
            ("limit", '<limit lower="-1" upper="1"/>' * 2),
            ("mimic", '<mimic joint="jb"/>' * 2),
        ]
    },
    "mimic without joint": (
        _urdf(CHAIN + _joint("jb", "continuous", "a", "b", '<mimic multiplier="2"/>')),
        "joint 'jb': <mimic> has no joint; name the joint it follows",
    ),
    "mimic multiplier of 2": (
        _urdf(CHAIN + _joint("jb", "continuous", "a", "b", '<mimic joint="ja" multiplier="2 3"/>')),
        """joint 'jb': <mimic multiplier="2 3"> has 2 numbers; give one number""",
    ),
    "limit not a number": (
        _urdf(CHAIN + _joint("jb", "revolute", "a", "b", '<limit lower="-pi" upper="1"/>')),
        """joint 'jb': <limit lower="-pi">: '-pi' is not a finite number; give one number""",
    ),
    "effort not a number": (  # not read by poekin, but yourdfpy reads it
        _urdf(_joint("ja", "revolute", "base", "a", '<limit effort="x"/>'), "base a"),
        "malformed URDF (ValueError: could not convert string to float: 'x')",
    ),
    "mimic of itself": (
        _urdf(CHAIN + _joint("jb", "continuous", "a", "b", '<mimic joint="jb"/>')),
        "mimic joints form a cycle: jb -> jb",
    ),
    "unknown type": (_urdf(_joint("ju", "hinge", "base", "a"), "base a"), "a URDF joint is one of"),
    "unknown link": (_urdf(_joint("ja", "fixed", "base", "c")), "link 'c', which is not defined"),
    "two parents": (
        _urdf(CHAIN + _joint("jb", "fixed", "base", "a")),
        "link 'a' is the child of both joints 'ja' and 'jb'",
    ),
    "two roots": (_urdf(CHAIN), "2 root links (no joint's child): ['base', 'b']"),
    "cycle": (
        _urdf(
            CHAIN + _joint("jb", "fixed", "c", "b") + _joint("jc", "fixed", "b", "c"), "base a b c"
        ),
        "links ['b', 'c'] are not reachable",
    ),
    "deep floating": (
        _urdf(CHAIN + _joint("jf", "floating", "a", "b")),
        "floating joint 'jf' hangs below link 'a'",
    ),
    "mimic unknown joint": (
        _urdf(CHAIN + _joint("jb", "continuous", "a", "b", '<mimic joint="jaa"/>')),
        "joint 'jb' mimics 'jaa', which is not a joint: did you mean 'ja'?",
    ),
    "mimic spherical joint": (
        _urdf(
            _joint("ja", "spherical", "base", "a")
            + _joint("jb", "continuous", "a", "b", '<mimic joint="ja"/>')
        ),
        "joint 'jb' mimics 'ja', but 'ja' is a spherical joint; mimic joints must be revolute,",
    ),
    "mimic fixed joint": (
        _urdf(
            _joint("ja", "fixed", "base", "a")
            + _joint("jb", "continuous", "a", "b", '<mimic joint="ja"/>')
        ),
        "but 'ja' is a fixed joint",
    ),
    "mimic cycle": (
        _urdf(
            _joint("ja", "continuous", "base", "a", '<mimic joint="jb"/>')
            + _joint("jb", "continuous", "a", "b", '<mimic joint="ja"/>')
        ),
        "mimic joints form a cycle: ja -> jb -> ja",
    ),
}


@pytest.mark.parametrize(("text", "phrase"), ERROR_CASES.values(), ids=ERROR_CASES.keys())
def test_errors_are_one_line(tmp_path: pathlib.Path, text: str, phrase: str) -> None:
    path = tmp_path / "robot.urdf"
    path.write_text(text)
    with pytest.raises(URDFError) as info:
        tree_from_urdf(path)
    message = str(info.value)
    assert phrase in message
    assert message.startswith(str(path)) and "\n" not in message


@pytest.mark.parametrize(
    ("name", "expanded"),
    [("robot.urdf", "robot_expanded.urdf"), ("robot.urdf.xacro", "robot.urdf")],
)
def test_xacro_is_expanded_to_a_new_file(tmp_path: pathlib.Path, name: str, expanded: str) -> None:
    """The command given writes a file other than the one read (a shell truncates the output
    file before xacro reads the input)."""
    path = tmp_path / name
    path.write_text('<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro"><xacro:arg/></robot>')
    with pytest.raises(URDFError) as info:
        tree_from_urdf(path)
    assert str(info.value).endswith(f"xacro {path} > {expanded}")


def test_xacro_namespace_left_in_an_expanded_file(tmp_path: pathlib.Path) -> None:
    """xacro's output keeps the namespace declaration on <robot>: that alone is URDF."""
    path = tmp_path / "expanded.urdf"
    text = (DATA / "serial_arm.urdf").read_text()
    path.write_text(text.replace("<robot ", '<robot xmlns:xacro="http://ros.org/wiki/xacro" '))
    assert tree_from_urdf(path).joint_names == tree_from_urdf(DATA / "serial_arm.urdf").joint_names


@pytest.mark.parametrize("xyz", ["6e-8 8e-8 0", "0 0 2", "0.3 -4 1e3"])
def test_axes_are_normalised_as_in_mujoco(tmp_path: pathlib.Path, xyz: str) -> None:
    """Down to the shortest axis MuJoCo takes (squared length 1e-14)."""
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf(_joint("js", "prismatic", "base", "a", f'<axis xyz="{xyz}"/>'), "base a"))
    model = compile_with_mujoco(path, floating_base=False)
    assert_close("axis", tree_from_urdf(path).joint_axes, model.jnt_axis, 2e-16)


def test_substitutions_for_other_tools_are_not_xacro(tmp_path: pathlib.Path) -> None:
    """What only Gazebo or ros2_control reads may keep $(...) (launch files substitute it):
    MuJoCo and Pinocchio load such a file, and so does poekin."""
    path = tmp_path / "robot.urdf"
    plugin = "<gazebo><plugin><parameters>$(find my_robot)/controllers.yaml</parameters></plugin>"
    path.write_text(_urdf(_joint("ja", "continuous", "base", "a") + plugin + "</gazebo>", "base a"))
    assert tree_from_urdf(path).joint_names == ("ja",)


def test_missing_file(tmp_path: pathlib.Path) -> None:
    with pytest.raises(ModelError, match="no such URDF file; check the path"):
        tree_from_urdf(tmp_path / "nope.urdf")


def test_floating_base_on_world_root_refused() -> None:
    with pytest.raises(ModelError, match="the root link is 'world'"):
        tree_from_urdf(DATA / "world_floating.urdf", floating_base=True)


@pytest.mark.parametrize("kind", ["continuous", "fixed"])
def test_floating_base_name_taken(tmp_path: pathlib.Path, kind: str) -> None:
    """A URDF joint named floating_base (moving or fixed): the free joint takes the first free
    name of floating_base_1, floating_base_2, ..."""
    path = tmp_path / "robot.urdf"
    joints = _joint(FLOATING_BASE, kind, "base", "a") + _joint("floating_base_1", kind, "a", "b")
    path.write_text(_urdf(joints))
    tree = tree_from_urdf(path, floating_base=True)
    moving = (FLOATING_BASE, "floating_base_1") if kind == "continuous" else ()
    assert tree.joint_names == ("floating_base_2", *moving)
    assert tree.joint_types[0] == "free"
    assert tree_from_urdf(path).joint_names == moving
    model = compile_with_mujoco(path, "floating_base_2")
    assert tree.joint_names == tuple(model.joint(j).name for j in range(model.njnt))
    q = random_qpos(tree, 100, seed=6)
    assert_close("MuJoCo", tree.fk(q), mujoco_body_poses(model, tree, q), MJ_TOL)


def test_without_yourdfpy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # import raises ImportError
    with pytest.raises(MissingExtraError) as info:
        tree_from_urdf(DATA / "serial_arm.urdf")
    assert str(info.value) == (
        f"reading serial_arm.urdf needs yourdfpy, which is not installed: {install_command('urdf')}"
    )
