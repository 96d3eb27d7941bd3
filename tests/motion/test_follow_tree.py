"""Tree.follow (poekin.motion.follow.follow_tree): one frame along a path, the whole body
solved, other frames held. Every sample, and the configurations between samples, are checked
by MuJoCo: its FK (mj_kinematics) on the full qpos, and its own interpolation between two
configurations (mj_differentiatePos, mj_integratePos)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_pose

import poekin
from poekin.errors import InputError, UnknownFrameError
from poekin.motion import line_path

FEET = ("left_foot", "right_foot")
HAND = "left_elbow_roll_link"


@pytest.fixture(scope="module")
def g1() -> tuple[poekin.Tree, mujoco.MjModel]:
    loaded = load_quiet("unitree_g1")
    return poekin.load_tree(loaded), loaded.model


def _between(model: mujoco.MjModel, a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """MuJoCo's configuration a fraction ``t`` of the way from ``a`` to ``b``."""
    v = np.zeros(model.nv)
    mujoco.mj_differentiatePos(model, v, 1.0, a, b)
    q = a.copy()
    mujoco.mj_integratePos(model, q, v, t)
    return q


def test_g1_hand_on_a_line_with_its_feet_held(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, model = g1
    T0 = tree.pose(tree.qpos0, HAND)
    T1 = T0.copy()
    T1[:3, 3] += [0.08, 0.05, 0.06]
    found = tree.follow(lambda s: line_path(T0, T1, s), tree.qpos0, HAND, hold=FEET)
    assert found.done and found.fraction == 1.0 and found.q.shape[1] == tree.nq
    hand = mj_pose(model, found.q, HAND)
    pos, ori = poekin.pose_errors(line_path(T0, T1, found.s), hand)
    assert pos.max() < 1e-9 and ori.max() < 1e-9  # every sample on the line
    for foot in FEET:  # the feet exactly where they stood, at every sample
        start = mj_pose(model, tree.qpos0[None], foot)[0]
        pos, ori = poekin.pose_errors(start, mj_pose(model, found.q, foot))
        assert pos.max() < 1e-10 + MJ_TOL and ori.max() < 1e-10 + MJ_TOL
    # between samples, by MuJoCo's own interpolation: the hand within tol of the line
    for t in (0.25, 0.5, 0.75):
        q = np.array(
            [_between(model, a, b, t) for a, b in zip(found.q[:-1], found.q[1:], strict=True)]
        )
        s = (1 - t) * found.s[:-1] + t * found.s[1:]
        pos, _ = poekin.pose_errors(line_path(T0, T1, s), mj_pose(model, q, HAND))
        assert pos.max() <= 1e-4 * 1.01
    assert 0 < found.max_deviation <= 1e-4


def test_g1_crouches_over_its_held_feet(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    """The pelvis, the floating base's body, on a line 5 cm down and turned a little: the base
    and the legs solved for, the feet held."""
    tree, model = g1
    T0 = tree.pose(tree.qpos0, "pelvis")
    T1 = T0 @ poekin.lie.exp_se3([0.0, 0.0, 0.1, 0.0, 0.0, -0.05])
    found = tree.follow(lambda s: line_path(T0, T1, s), tree.qpos0, "pelvis", hold=FEET)
    assert found.done, found.detail
    pos, ori = poekin.pose_errors(line_path(T0, T1, found.s), mj_pose(model, found.q, "pelvis"))
    assert pos.max() < 1e-9 and ori.max() < 1e-9
    for foot in FEET:
        start = mj_pose(model, tree.qpos0[None], foot)[0]
        pos, ori = poekin.pose_errors(start, mj_pose(model, found.q, foot))
        assert pos.max() < 1e-10 + MJ_TOL and ori.max() < 1e-10 + MJ_TOL
    quats = found.q[:, 3:7]
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0, atol=1e-15)


def test_a_line_out_of_reach_stops_with_the_feet_still_held(
    g1: tuple[poekin.Tree, mujoco.MjModel],
) -> None:
    tree, model = g1
    T0 = tree.pose(tree.qpos0, HAND)
    T1 = T0.copy()
    T1[:3, 3] += [1.5, 0.0, 0.0]  # far beyond the arm's reach with the feet planted
    found = tree.follow(T_path=np.stack([T0, T1]), qpos0=tree.qpos0, frame=HAND, hold=FEET)
    assert not found.done and 0.0 < found.fraction < 1.0
    assert found.reason in ("unreachable", "joint_limit") and found.detail
    # the last sample is real: MuJoCo puts the hand on the line there, the feet where they were
    last = mj_pose(model, found.q[-1:], HAND)[0]
    pos, ori = poekin.pose_errors(poekin.motion.screw_path(T0, T1, found.s[-1]), last)
    assert pos < 1e-9 and ori < 1e-9
    for foot in FEET:
        start = mj_pose(model, tree.qpos0[None], foot)[0]
        pos, _ = poekin.pose_errors(start, mj_pose(model, found.q[-1:], foot)[0])
        assert pos < 1e-10 + MJ_TOL


def test_bad_input(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, _ = g1
    T0 = tree.pose(tree.qpos0, HAND)
    path = np.stack([T0, T0])
    with pytest.raises(UnknownFrameError, match="left_elbow_roll_link"):
        tree.follow(path, tree.qpos0, "left_elbow_rol_link")
    with pytest.raises(InputError, match="both follows the path and is held"):
        tree.follow(path, tree.qpos0, HAND, hold=(HAND,))
    with pytest.raises(InputError, match="qpos0 values"):
        tree.follow(path, tree.qpos0[:5], HAND)
    moved = T0.copy()
    moved[0, 3] += 0.1
    with pytest.raises(InputError, match="from the path's start"):
        tree.follow(np.stack([moved, T0]), tree.qpos0, HAND)
    with pytest.raises(InputError, match="max_step must be a number > 0"):
        tree.follow(path, tree.qpos0, HAND, max_step=0.0)
