"""One entry point for every source: Menagerie names, MJCF and URDF files, and verify on URDF."""

from __future__ import annotations

import pathlib
import warnings

import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet

import poekin
from poekin import InputError, UnknownFrameError
from poekin.cli import main

URDF = pathlib.Path(__file__).parents[1] / "data" / "urdf"


def test_load_tree_reads_urdf_itself() -> None:
    tree = poekin.load_tree(URDF / "two_arms.urdf")
    expected = poekin.tree_from_urdf(URDF / "two_arms.urdf")
    assert tree.joint_names == expected.joint_names
    qpos = poekin.sample_qpos(tree, 20, seed=0)
    assert_close("two_arms", tree.fk(qpos), expected.fk(qpos), 0.0)
    floating = poekin.load_tree(str(URDF / "serial_arm.urdf"), floating_base=True)
    assert floating.joint_types[0] == "free" and floating.nq == 7 + 6


def test_floating_base_is_for_urdf_only() -> None:
    with pytest.raises(InputError, match="floating_base applies to URDF"):
        poekin.load_tree(load_quiet("universal_robots_ur5e"), floating_base=True)


def test_load_urdf_chain_defaults_to_the_only_leaf() -> None:
    chain = poekin.load(URDF / "serial_arm.urdf")
    assert chain.frame == "tool0" and chain.n_joints == 6
    tree = poekin.load_tree(URDF / "serial_arm.urdf")
    q = poekin.sample_qpos(tree, 50, seed=1)
    assert_close("tool0", chain.fk(q), tree.fk(q)[:, tree.frame_index("tool0")], 1e-14)
    with pytest.raises(UnknownFrameError, match="end links, so name the end frame"):
        poekin.load(URDF / "two_arms.urdf")


@pytest.mark.filterwarnings("ignore::poekin.URDFLimitsWarning", "ignore::poekin.MuJoCoWarning")
@pytest.mark.parametrize(
    "name",
    [
        "serial_arm",
        "two_arms",
        "world_floating",
        "package_meshes",
        "gripper_mimic_later",
        "limits",
        "ros_package",
        "bullet_spherical",
    ],
)
def test_verify_urdf_against_mujocos_compile(name: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)  # package:// meshes
        loaded = poekin.load_model(URDF / f"{name}.urdf")
    report = poekin.verify(loaded, all_frames=True, samples=300, seed=2)
    assert report.passed
    assert set(report.frame_errors) == set(poekin.load_tree(loaded).frame_names)
    assert "tree FK" in report.pos_err
    for method in report.pos_err:
        assert report.pos_err[method].max() <= MJ_TOL, method
        assert report.ori_err[method].max() <= MJ_TOL, method


def test_verify_urdf_frame_on_the_command_line(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["verify", str(URDF / "two_arms.urdf"), "--frame", "right_finger_b"])
    out = capsys.readouterr().out
    assert code == 0
    assert "frame 'right_finger_b'" in out and "space PoE" in out and "PASS" in out


def test_unused_urdf_limits_are_one_note_on_the_command_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = main(["verify", str(URDF / "limits.urdf"), "--within-limits"])
    err = capsys.readouterr().err.splitlines()
    assert code == 0
    assert all(line.startswith("poekin: note: ") for line in err), err
    ours = [line for line in err if "unlimited, as in MuJoCo" in line]
    assert len(ours) == 1 and "limits.urdf: 7 joints are unlimited" in ours[0]
    mujocos = [line for line in err if "MuJoCo: joint 'equal' has equal lower and upper" in line]
    assert len(mujocos) == 1


def test_mimic_followers_get_their_own_mujoco_qpos() -> None:
    tree = poekin.load_tree(URDF / "two_arms.urdf")
    qpos = poekin.sample_qpos(tree, 10, seed=3)
    full = tree.full_qpos(qpos)
    assert full.shape == (10, len(tree.joint_names))
    for k, mimic in enumerate(tree.mimics):
        if mimic is not None:
            leader = tree.joint_names.index(mimic.leader)
            expected = mimic.multiplier * qpos[:, tree.qpos_adr[leader]] + mimic.offset
            assert_close(tree.joint_names[k], full[:, tree.full_qpos_adr[k]], expected, 0.0)
    assert np.array_equal(tree.full_qpos_adr[:3], tree.qpos_adr[:3])
