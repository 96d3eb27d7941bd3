"""What the viewer draws (poekin.viewer.scene, panel): every frame, screw axis, PoE partial
product and DH frame against the tree's own FK and Jacobian, or the textbook product of matrix
exponentials, at 1e-12."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from helpers import assert_close, load_quiet
from scipy.spatial.transform import Rotation

import poekin
from poekin import lie
from poekin.errors import InputError, ModelError
from poekin.viewer import panel, scene

TOL = 1e-12
ROBOTS = ["universal_robots_ur5e", "unitree_go2", "aloha"]


@pytest.fixture(scope="module", params=ROBOTS)
def subject(request: pytest.FixtureRequest) -> scene.Subject:
    tree = poekin.load_tree(load_quiet(request.param))
    return scene.make_subject(tree)


def _qpos(subject: scene.Subject, seed: int) -> np.ndarray:
    assert subject.tree is not None
    return poekin.sample_qpos(subject.tree, 1, seed=seed)[0]


def _chain_joints(subject: scene.Subject) -> list[int]:
    assert subject.tree is not None
    return [subject.tree.joint_names.index(j) for j in subject.chain.joint_names]


def _zeroed_after(subject: scene.Subject, qpos: np.ndarray, k: int) -> np.ndarray:
    """qpos with the chain's joints after the k-th at 0."""
    assert subject.tree is not None
    out = qpos.copy()
    for j in _chain_joints(subject)[k:]:
        out[subject.tree.qpos_adr[j]] = 0.0
    return out


def test_default_frames() -> None:
    ur5e = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    go2 = poekin.load_tree(load_quiet("unitree_go2"))
    assert scene.default_frame(ur5e) == "attachment_site"
    # the go2's only site (imu) sits on the floating base: no joint moves it relative to it
    assert scene.default_frame(go2) == "FL_calf"
    s = scene.make_subject(go2, "RR_calf")
    assert s.base_body == go2.body_names.index("base") and s.chain.joint_names[0] == "RR_hip_joint"


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_end_frame_screws_and_points_against_the_tree(subject: scene.Subject, seed: int) -> None:
    tree = subject.tree
    assert tree is not None
    qpos = _qpos(subject, seed)
    snap = scene.snapshot(subject, qpos)
    T_all = tree.fk(qpos)
    assert_close("bodies", snap.bodies, T_all[: len(tree.body_names)], 0.0)
    assert_close("T(q)", snap.T, T_all[tree.frame_index(subject.frame)], TOL)
    # S_i(q) = Ad(T_{i-1}) S_i is the space Jacobian's column of joint i: the tree's own kernel
    J = tree.jacobian(qpos, subject.frame, "space")
    columns = [tree.dof_names().index(j) for j in subject.chain.joint_names]
    assert_close("S_i(q)", snap.screws, J[:, columns].T, TOL)
    # B_i(q) = Ad(T^-1) S_i(q), the body Jacobian's column
    Jb = tree.jacobian(qpos, subject.frame, "body")
    assert_close("B_i(q)", snap.body_screws, Jb[:, columns].T, TOL)
    # each drawn point lies on its axis (v = -w x p for a pure rotation) at the joint's anchor
    for S, p, k in zip(snap.screws, snap.points, _chain_joints(subject), strict=True):
        if scene.screw_kind(S) == "revolute":
            assert_close("point on axis", -np.cross(S[:3], p), S[3:], TOL)
        body = T_all[tree.joint_bodies[k]]
        anchor = body[:3, :3] @ tree.joint_anchors[k] + body[:3, 3]
        assert_close("anchor", p, anchor, TOL)


def test_partial_products_against_the_tree(subject: scene.Subject) -> None:
    """T_k is the end frame with the chain's joints after k at 0: the tree poses that too."""
    tree = subject.tree
    assert tree is not None
    qpos = _qpos(subject, 7)
    snap = scene.snapshot(subject, qpos)
    index = tree.frame_index(subject.frame)
    assert snap.partial.shape == (subject.n_joints + 1, 4, 4)
    for k in range(subject.n_joints + 1):
        expected = tree.fk(_zeroed_after(subject, qpos, k))[index]
        # a floating base moves with qpos only, not with the chain's joints
        assert_close(f"T_{k}", snap.partial[k], expected, TOL)
    assert_close("T_n = T(q)", snap.partial[-1], snap.T, 0.0)
    assert_close("T_0 = M on the base", snap.partial[0], snap.home, TOL)


def test_a_bare_chain_is_the_product_of_matrix_exponentials() -> None:
    chain = poekin.lynch_park_ur5_chain()
    s = scene.make_subject(chain)
    q = np.array([0.3, -1.1, 0.7, 2.0, -0.4, 1.3])
    snap = scene.snapshot(s, q)
    product = np.eye(4)
    for k in range(6):
        assert_close(f"link {k}", snap.bodies[k], product, TOL)
        assert_close(f"T_{k}", snap.partial[k], product @ chain.home, TOL)
        product = product @ lie.matrix_exp_se3(chain.screws[k], q[k])
    assert_close("T(q)", snap.T, product @ chain.home, TOL)
    assert s.body_names == ("base", "link1", "link2", "link3", "link4", "link5", "link6")
    assert s.frame_names[-1] == "ee" and snap.frames.shape == (8, 4, 4)
    with pytest.raises(InputError, match="one end frame"):
        scene.make_subject(chain, "flange")


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_frames_sit_on_the_joint_axes(subject: scene.Subject, convention: str) -> None:
    qpos = _qpos(subject, 11)
    snap = scene.snapshot(subject, qpos)
    table = subject.dh(convention)  # type: ignore[arg-type]
    frames = scene.dh_frames(subject, table, qpos)
    assert frames.shape == (subject.n_joints + 2, 4, 4)
    assert_close("DH end frame", frames[-1], snap.T, TOL)
    # joint i turns about z of frame i-1 (standard) or frame i (modified), at the current q
    shift = 0 if convention == "standard" else 1
    for i, S in enumerate(snap.screws):
        F = frames[i + shift]
        w = S[:3] if np.any(S[:3]) else S[3:]
        assert_close(f"z of DH frame {i + shift}", F[:3, 2], w, 1e-11)
        if np.any(S[:3]):
            assert_close("origin on the axis", -np.cross(S[:3], F[:3, 3]), S[3:], 1e-11)


def test_floating_chain_poses_below_the_base() -> None:
    go2 = poekin.load_tree(load_quiet("unitree_go2"))
    chain, base = scene.floating_chain(go2, "FL_calf")
    assert base == 0 and chain.joint_names == ("FL_hip_joint", "FL_thigh_joint", "FL_calf_joint")
    qpos = poekin.sample_qpos(go2, 20, seed=5)
    T_all = go2.fk(qpos)
    q = qpos[:, [go2.qpos_adr[go2.joint_names.index(j)] for j in chain.joint_names]]
    assert_close("T_world_base chain.fk(q)", T_all[:, 0] @ chain.fk(q), T_all[:, 3], TOL)
    fixed, none = scene.floating_chain(
        poekin.load_tree(load_quiet("universal_robots_ur5e")), "wrist_1_link"
    )
    assert none is None and fixed.n_joints == 4


def test_floating_chain_refuses_a_mimic_joint_below_the_base(tmp_path: object) -> None:
    tree = poekin.load_tree("tests/data/urdf/two_arms.urdf", floating_base=True)
    mimicked = [k for k, m in enumerate(tree.mimics) if m is not None]
    assert mimicked
    frame = tree.body_names[int(tree.joint_bodies[mimicked[0]])]
    with pytest.raises(ModelError, match="mimic joint"):
        scene.floating_chain(tree, frame)


def test_jacobian_and_manipulability(subject: scene.Subject) -> None:
    tree = subject.tree
    assert tree is not None
    qpos = _qpos(subject, 3)
    for convention in ("space", "body", "world"):
        J, names = scene.jacobian(subject, qpos, convention)  # type: ignore[arg-type]
        full = tree.jacobian(qpos, subject.frame, convention)  # type: ignore[arg-type]
        if subject.base_body is None:
            columns = [tree.dof_names().index(n) for n in names]
            assert_close(convention, J, full[:, columns], TOL)
        else:
            assert names == tree.dof_names()
            assert_close(convention, J, full, 0.0)
    sigma, w = scene.manipulability(J)
    assert np.all(np.diff(sigma) <= 0)
    if J.shape[1] >= 6:
        assert math.isclose(w, math.sqrt(abs(np.linalg.det(J @ J.T))), rel_tol=1e-9, abs_tol=1e-12)
    with pytest.raises(InputError, match="did you mean 'body'"):
        scene.jacobian(subject, qpos, "bodi")  # type: ignore[arg-type]


def test_pose_summary_against_scipy() -> None:
    rng = np.random.default_rng(0)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=3).as_matrix()
    T[:3, 3] = rng.normal(size=3)
    s = scene.pose_summary(T)
    assert s["quat_wxyz"][0] >= 0
    assert_close("quat", lie.quat_to_rotation(s["quat_wxyz"]), T[:3, :3], 1e-15)
    # scipy's extrinsic "xyz" is R = Rz(yaw) Ry(pitch) Rx(roll)
    assert_close("rpy", s["rpy"], Rotation.from_matrix(T[:3, :3]).as_euler("xyz"), 1e-12)
    assert_close("position", s["position"], T[:3, 3], 0.0)


def test_skeleton_links_join_the_joint_anchors() -> None:
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    s = scene.make_subject(tree)
    qpos = poekin.sample_qpos(tree, 1, seed=2)[0]
    snap = scene.snapshot(s, qpos)
    ends = []
    for seg in scene.skeleton(s):
        T = snap.bodies[seg.body]
        ends += [T[:3, :3] @ np.array(p) + T[:3, 3] for p in (seg.a, seg.b)]
    ends_arr = np.array(ends)
    for p in snap.points:  # every joint anchor is where two links meet
        assert np.sum(np.linalg.norm(ends_arr - p, axis=1) < 1e-12) >= 2
    assert any(np.linalg.norm(ends_arr - snap.T[:3, 3], axis=1) < 1e-12)  # up to the site


def test_controls_and_slider_ranges() -> None:
    go2 = scene.make_subject(poekin.load_tree(load_quiet("unitree_go2")))
    c = scene.controls(go2)
    assert [x.kind for x in c[:2]] == ["free", "revolute"] and c[0].adr == 0 and c[1].adr == 7
    assert (c[1].lower, c[1].upper) == tuple(go2.tree.joint_limits[1])  # type: ignore[union-attr]
    bare = scene.controls(scene.make_subject(poekin.lynch_park_ur5_chain()))
    assert {(x.lower, x.upper) for x in bare} == {(-2 * math.pi, 2 * math.pi)}


def test_ghost_of_a_parameter_set() -> None:
    model = scene.make_subject(poekin.load_tree(load_quiet("universal_robots_ur5e")))
    lynch = poekin.lynch_park_ur5_chain()
    comparison = scene.compare(model, lynch, "lynch-park-ur5")
    assert any(f.kind == "base_rotation" for f in comparison.diagnosis.findings)
    q = np.array([0.4, -1.0, 1.2, -0.3, 0.9, 0.2])
    snap = scene.snapshot(model, q)
    as_given = scene.ghost(comparison, snap, aligned=False)
    assert_close("your T", as_given.T, lynch.fk(q), TOL)
    pos, ori = poekin.pose_errors(model.chain.fk(q), lynch.fk(q))
    assert math.isclose(as_given.pos_err, float(pos), rel_tol=1e-12)
    assert math.isclose(as_given.ori_err, float(ori), rel_tol=1e-9)
    aligned = scene.ghost(comparison, snap, aligned=True)
    assert_close("aligned T", aligned.T, comparison.diagnosis.aligned.fk(q), TOL)
    assert aligned.ori_err < 1e-9 < aligned.pos_err  # only link lengths differ once aligned
    assert_close("your screws", as_given.screws, lynch.jacobian_space(q).T, TOL)
    with pytest.raises(InputError, match="6 joints but"):
        scene.compare(
            scene.make_subject(poekin.load_tree(load_quiet("franka_fr3")), "attachment_site"), lynch
        )


def test_axis_pose_and_nearest_point() -> None:
    for d in ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 2.0, -0.5]):
        T = scene.axis_pose([1.0, 2.0, 3.0], d)
        assert_close("z", T[:3, 2], np.array(d) / np.linalg.norm(d), 1e-15)
        assert_close("rotation", T[:3, :3] @ T[:3, :3].T, np.eye(3), 1e-15)
    S = np.array([0.0, 0.0, 1.0, 0.5, -0.2, 0.0])  # along z through w x v, as v = -w x p
    p = np.cross(S[:3], S[3:])
    foot = scene.nearest_point(S, p + np.array([0, 0, 3.0]), [1.0, 1.0, 1.0])
    assert_close("foot", foot, [p[0], p[1], 1.0], 1e-15)
    slide = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    assert_close("slide", scene.nearest_point(slide, np.ones(3), np.zeros(3)), np.ones(3), 0.0)


def test_screw_kinds() -> None:
    assert scene.screw_kind(np.array([0, 0, 1, 0, 0, 0.0])) == "revolute"
    assert scene.screw_kind(np.array([0, 0, 1, 0, 0, 0.1])) == "pitched"
    assert scene.screw_kind(np.array([0, 0, 0, 0, 0, 1.0])) == "prismatic"


# --- the panel's texts ---------------------------------------------------------------------------


def _block(text: str) -> np.ndarray:
    body = re.search(r"```\n(.*?)\n```", text, re.S)
    assert body is not None
    return np.array([[float(x) for x in line.split()] for line in body.group(1).splitlines()])


def test_pose_and_jacobian_texts_print_the_numbers() -> None:
    s = scene.make_subject(poekin.load_tree(load_quiet("universal_robots_ur5e")))
    q = np.array([0.1, -1.2, 1.3, 0.4, -0.5, 2.0])
    snap = scene.snapshot(s, q)
    text = panel.pose_text(snap.T, s.frame)
    assert "**T(q) = T_world_attachment_site**" in text
    assert_close("printed T", _block(text), s.chain.fk(q), 5e-7)
    J, names = scene.jacobian(s, q, "body")
    sigma, w = scene.manipulability(J)
    jt = panel.jacobian_text(J, names, "body", sigma, w)
    assert_close("printed J", _block(jt), s.chain.jacobian_body(q), 5e-5)
    assert "columns: shoulder_pan_joint" in jt and "singular values" in jt
    poe = panel.poe_text(s, snap, 2, "space")
    assert "T2 = e^[S1]q1 · e^[S2]q2 · M" in poe and "joints 3..6 held at 0" in poe
    assert "T2 = M · e^[B1]q1 · e^[B2]q2" in panel.poe_text(s, snap, 2, "body")
    assert "q1 = 5.7296 deg" in panel.poe_text(s, snap, 6, "space", "deg")
    table = panel.screws_text(s, snap, "body")
    assert "| B1 | shoulder_pan_joint |" in table and "| S1 |" not in table
    dh = panel.dh_text(s.dh("modified"))
    assert "modified (Craig)" in dh and "| 6 | wrist_3_joint (R) |" in dh
