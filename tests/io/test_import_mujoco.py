"""Chains derived from MuJoCo models agree with mj_forward, on Menagerie and on random models."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet, mj_frame_pose

from poekin import ModelError, UnknownFrameError, chain_from_model, load, sample_joint_values
from poekin.io.import_mujoco import find_frame, site_and_body_names, tree_from_model

N_SAMPLES = 1000


def check_against_mujoco(model: mujoco.MjModel, frame: str | None, seed: int = 0) -> None:
    """fk and fk_body of the derived chain equal mj_forward's frame pose on random q."""
    chain = chain_from_model(model, frame)
    kind, fid, _ = find_frame(model, chain.frame)
    q = sample_joint_values(chain, N_SAMPLES, seed=seed)  # prismatic: within limits or +-1 m
    data = mujoco.MjData(model)
    expected = np.empty((N_SAMPLES, 4, 4))
    for k in range(N_SAMPLES):
        data.qpos[:] = model.qpos0
        data.qpos[list(chain.qpos_indices or ())] = q[k]
        mujoco.mj_forward(model, data)
        expected[k] = mj_frame_pose(model, data, kind, fid)
    assert_close(f"{chain.frame}: space PoE", chain.fk(q), expected, MJ_TOL)
    assert_close(f"{chain.frame}: body PoE", chain.fk_body(q), expected, MJ_TOL)


def _all_sites(robot: str) -> list[tuple[str, str]]:
    sites, _ = site_and_body_names(load_quiet(robot).model)
    return [(robot, s) for s in sites]


MENAGERIE_FRAMES = [
    ("universal_robots_ur5e", None),
    *_all_sites("franka_fr3"),
    *_all_sites("universal_robots_ur10e"),
    *_all_sites("ufactory_lite6"),
    *_all_sites("rethink_robotics_sawyer"),
    ("franka_emika_panda", "hand"),
    ("franka_emika_panda", "left_finger"),  # a slide joint at the end
    ("trs_so_arm100", "Moving_Jaw"),
    ("aloha", "left/gripper"),
    ("aloha", "right/left_finger_link"),
]


@pytest.mark.parametrize(("robot", "frame"), MENAGERIE_FRAMES)
def test_menagerie_chains_match_mj_forward(robot: str, frame: str | None) -> None:
    check_against_mujoco(load_quiet(robot).model, frame)


def test_ur5e_chain_shape() -> None:
    chain = load("universal_robots_ur5e")
    assert chain.frame == "attachment_site"
    assert chain.joint_names[0] == "shoulder_pan_joint"
    assert chain.joint_types == ("revolute",) * 6
    assert chain.qpos_indices == tuple(range(6))
    assert_close("elbow limits", chain.limits[2], [-3.1415, 3.1415], 0.0)


def _random_chain_xml(rng: np.random.Generator, n_bodies: int) -> str:
    """A serial MJCF chain with the features that trip hand-written FK: non-zero ``ref``, slide
    joints, off-centre joint anchors, euler/quat body offsets, several joints in one body,
    non-unit axes (MuJoCo normalises them), and a site with its own offset."""

    def vec(k: int, s: float = 0.3) -> str:
        return " ".join(f"{x:.6f}" for x in rng.uniform(-s, s, size=k))

    body = f'<site name="tip" pos="{vec(3)}" euler="{vec(3, 3.0)}"/>'
    for i in reversed(range(n_bodies)):
        joints = ""
        for k in range(int(rng.integers(1, 3))):
            kind = "slide" if rng.random() < 0.3 else "hinge"
            axis = vec(3, 2.0)
            ref = f"{rng.uniform(-1.5, 1.5):.6f}" if rng.random() < 0.5 else "0"
            joints += (
                f'<joint name="j{i}_{k}" type="{kind}" axis="{axis}" pos="{vec(3)}" ref="{ref}"/>'
            )
        orient = f'euler="{vec(3, 3.0)}"' if i % 2 else f'quat="{vec(4, 1.0)} "'
        body = (
            f'<body name="b{i}" pos="{vec(3)}" {orient}>{joints}'
            f'<geom size="0.05" mass="1"/>{body}</body>'
        )
    return f"<mujoco><worldbody>{body}</worldbody></mujoco>"


@pytest.mark.parametrize("seed", range(20))
def test_random_models_match_mj_forward(seed: int) -> None:
    rng = np.random.default_rng(seed)
    model = mujoco.MjModel.from_xml_string(_random_chain_xml(rng, int(rng.integers(1, 8))))
    check_against_mujoco(model, "tip", seed)
    check_against_mujoco(model, "b0", seed)


def test_ref_offset_is_handled() -> None:
    xml = """<mujoco><compiler angle="radian"/><worldbody><body name="b" pos="0 0 1">
      <joint name="j" axis="0 0 1" ref="0.7"/><geom size=".1"/>
      <site name="s" pos="1 0 0"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    chain = chain_from_model(model)
    # The XML pose is the pose at q = ref, so at q = 0 the site is turned back by -0.7 rad.
    assert_close("home p", chain.home[:3, 3], [np.cos(-0.7), np.sin(-0.7), 1.0], 1e-15)
    check_against_mujoco(model, None)


def test_default_frame_needs_exactly_one_site() -> None:
    panda = load_quiet("franka_emika_panda").model
    with pytest.raises(UnknownFrameError, match=r"no sites.*'hand'"):
        chain_from_model(panda)


def test_unknown_frame_suggests_near_miss() -> None:
    ur5e = load_quiet("universal_robots_ur5e").model
    with pytest.raises(
        UnknownFrameError, match=r"'atachment_site'.*did you mean 'attachment_site'"
    ):
        chain_from_model(ur5e, "atachment_site")


def test_site_and_body_frames() -> None:
    ur5e = load_quiet("universal_robots_ur5e").model
    assert find_frame(ur5e, "attachment_site")[0] == "site"
    kind, fid, name = find_frame(ur5e, "wrist_3_link")
    assert (kind, name) == ("body", "wrist_3_link")
    assert ur5e.body(fid).name == "wrist_3_link"


@pytest.mark.parametrize("joint", ["ball", "free"])
def test_ball_or_free_joint_on_path_is_refused(joint: str) -> None:
    xml = f"""<mujoco><worldbody><body name="b"><joint type="{joint}" name="bad"/>
      <geom size=".1"/><site name="s"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(ModelError, match=f"'bad'.*{joint} joint.*hinge and slide"):
        chain_from_model(model)


def test_unnamed_joints_get_names() -> None:
    xml = """<mujoco><worldbody><body><joint axis="1 0 0"/><geom size=".1"/>
      <site name="s"/></body></worldbody></mujoco>"""
    chain = chain_from_model(mujoco.MjModel.from_xml_string(xml))
    assert chain.joint_names == ("joint0",)


# Sites the compiler finds on their body's frame or inertial frame, to its own tolerance (1e-9 m
# and rad here): MuJoCo then copies that frame (site_sameframe 1-4) instead of applying the
# site's offset, and so must poekin.
SAMEFRAME_XML = """<mujoco><worldbody>
<body name="a" pos="0.1 0.2 0.3" euler="0.3 0.2 0.1"><joint type="hinge" axis="0 1 0"/>
  <inertial pos="0.05 0.02 0.01" quat="0.9 0.1 0.3 0.2" mass="1" diaginertia="0.1 0.2 0.3"/>
  <site name="at_body" pos="0 0 1e-9" euler="0 0 1e-9"/>
  <site name="body_rot" pos="0.3 0 0" euler="0 0 1e-9"/>
  <site name="at_inertia" pos="0.05 0.02 0.01" quat="0.9 0.1 0.3 0.2"/>
  <site name="inertia_rot" pos="0.4 0 0" quat="0.9 0.1 0.3 0.2"/>
  <site name="own_frame" pos="0.4 0 0" quat="0.9 0.3 0.1 0.2"/>
</body></worldbody></mujoco>"""


def test_sites_on_their_body_or_inertial_frame_pose_as_mujoco_does() -> None:
    model = mujoco.MjModel.from_xml_string(SAMEFRAME_XML)
    assert sorted(model.site_sameframe) == [0, 1, 2, 3, 4], "every sameframe case is here"
    tree = tree_from_model(model)
    qpos = np.random.default_rng(0).uniform(-np.pi, np.pi, (200, 1))
    data = mujoco.MjData(model)
    got = tree.fk(qpos)
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        for s in range(model.nsite):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s)
            f = tree.frame_index(name)
            assert_close(f"{name} position", got[k, f, :3, 3], data.site_xpos[s], 1e-15)
            rot = data.site_xmat[s].reshape(3, 3)
            assert_close(f"{name} rotation", got[k, f, :3, :3], rot, 1e-15)
