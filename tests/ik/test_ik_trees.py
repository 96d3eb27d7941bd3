"""Tree.ik (poekin.ik.trees): one arm of aloha, one leg of go2 under a floating base, each
answer checked with MuJoCo's mj_forward on the whole qpos; the other joints untouched; the
trees this solver refuses, with one clear error each."""

from __future__ import annotations

import doctest
from typing import Any

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_pose
from test_tree import FEATURES_XML, _two_link

import poekin
from poekin.io.import_mujoco import tree_from_model
from poekin.tree import Mimic, Tree

TOL = 1e-10


def check(
    model: mujoco.MjModel,
    tree: Tree,
    T: np.ndarray,
    frame: str,
    held: np.ndarray,
    found: Any,
    *,
    position_only: bool = False,
) -> None:
    """Every target solved, by MuJoCo on the whole qpos; only the path's hinges moved."""
    assert found.success.all(), f"{(~found.success).sum()} not solved"
    pos, ori = poekin.pose_errors(T, mj_pose(model, found.q, frame))
    assert pos.max() <= TOL + MJ_TOL
    if not position_only:
        assert ori.max() <= TOL + MJ_TOL
    path = [int(tree.qpos_adr[k]) for k in tree.path_joints(frame)]
    hinges = [
        a
        for a, k in zip(path, tree.path_joints(frame), strict=True)
        if tree.joint_types[k] == "revolute"
    ]
    others = np.setdiff1d(np.arange(tree.nq), hinges)
    assert np.array_equal(found.q[:, others], held[:, others]), "a joint off the solve moved"
    lo, hi = tree.joint_limits[
        [k for k in tree.path_joints(frame) if tree.joint_types[k] == "revolute"]
    ].T
    assert np.all((found.q[:, hinges] >= lo) & (found.q[:, hinges] <= hi))


def test_one_arm_of_aloha() -> None:
    loaded = load_quiet("aloha")
    tree = poekin.load_tree(loaded)
    truth = poekin.sample_qpos(tree, 30, seed=1, within_limits=True)
    T = mj_pose(loaded.model, truth, "left/gripper")
    held = poekin.sample_qpos(tree, 30, seed=2, within_limits=True)  # the right arm elsewhere
    found = tree.ik(T, "left/gripper", held)
    check(loaded.model, tree, T, "left/gripper", held, found)
    assert found.q.shape == (30, tree.nq)


@pytest.mark.parametrize("position_only", [False, True])
def test_one_leg_of_go2_under_its_floating_base(position_only: bool) -> None:
    loaded = load_quiet("unitree_go2")
    tree = poekin.load_tree(loaded)
    truth = poekin.sample_qpos(tree, 30, seed=3, within_limits=True)
    T = mj_pose(loaded.model, truth, "FR_calf")
    held = poekin.sample_qpos(tree, 30, seed=4, within_limits=True)
    held[:, :7] = truth[:, :7]  # the base where the targets were made: the leg can reach them
    found = tree.ik(T, "FR_calf", held, position_only=position_only)
    check(loaded.model, tree, T, "FR_calf", held, found, position_only=position_only)


def test_warm_start_begins_at_qpos(go2: Tree) -> None:
    qpos = poekin.sample_qpos(go2, 5, seed=5, within_limits=True)
    T = go2.pose(qpos, "RL_calf")
    found = go2.ik(T, "RL_calf", qpos, warm_start=True)  # qpos already solves it
    assert found.success.all() and np.all(found.iterations == 1)
    np.testing.assert_array_equal(found.q, qpos)
    cold = go2.ik(T, "RL_calf", qpos)
    assert cold.success.all() and np.all(cold.iterations > 1)


def test_a_warm_start_outside_the_limits_is_named(go2: Tree) -> None:
    """Issue #26: the start of a warm-started leg far outside its limits (degrees read as
    radians) gets the JointLimitsWarning of chain.ik, at this line."""
    qpos = poekin.sample_qpos(go2, 1, seed=5, within_limits=True)[0]
    T = go2.pose(qpos, "RL_calf")
    start = qpos.copy()
    calf = int(go2.qpos_adr[list(go2.joint_names).index("RL_calf_joint")])
    start[calf] = np.degrees(start[calf])
    with pytest.warns(poekin.JointLimitsWarning, match="q0 is outside.*'RL_calf_joint'") as said:
        found = go2.ik(T, "RL_calf", start, warm_start=True)
    assert said[0].filename == __file__
    assert found.success


@pytest.mark.parametrize("batch", [(), (1,), (3, 1, 2)])
def test_batch_shapes_and_broadcasting(go2: Tree, batch: tuple[int, ...]) -> None:
    n = int(np.prod(batch))
    truth = poekin.sample_qpos(go2, n, seed=6, within_limits=True)
    truth[:, :7] = go2.qpos0[:7]
    T = go2.pose(truth, "FL_calf").reshape(*batch, 4, 4)
    found = go2.ik(T, "FL_calf")  # qpos (nq,): qpos0 for every target
    assert found.q.shape == (*batch, go2.nq) and found.success.shape == batch
    assert found.success.all()


def test_features_tree_bob_below_a_free_joint() -> None:
    """A one-hinge pendulum hanging from a free body: its position only (one joint)."""
    model = mujoco.MjModel.from_xml_string(FEATURES_XML)
    tree = tree_from_model(model)
    truth = poekin.sample_qpos(tree, 10, seed=7, within_limits=True)
    T = mj_pose(model, truth, "bob")
    found = tree.ik(T, "bob", truth, position_only=True)  # the swing from random starts
    check(model, tree, T, "bob", truth, found, position_only=True)


@pytest.mark.parametrize(
    ("frame", "message"),
    [
        ("finger", r"joint 'wrist_ball' \(ball\) follows the hinge or slide joint 'yaw'"),
        ("floater", "no hinge or slide joint on the path to 'floater'"),
    ],
)
def test_paths_the_solver_refuses(frame: str, message: str) -> None:
    tree = tree_from_model(mujoco.MjModel.from_xml_string(FEATURES_XML))
    with pytest.raises(poekin.InputError, match=message):
        tree.ik(np.eye(4), frame)


def test_a_mimic_joint_on_the_path_is_refused() -> None:
    tree = _two_link((None, Mimic("j1", multiplier=-2.0, offset=0.25)))
    with pytest.raises(poekin.InputError, match="joint 'j2' on the path to 'tip' mimics 'j1'"):
        tree.ik(np.eye(4), "tip")


def test_bad_input(go2: Tree) -> None:
    with pytest.raises(poekin.UnknownFrameError, match="did you mean 'FL_calf'"):
        go2.ik(np.eye(4), "FL_calve")
    with pytest.raises(poekin.InputError, match="expected 19 qpos values"):
        go2.ik(np.eye(4), "FL_calf", np.zeros(18))
    with pytest.raises(poekin.InputError, match="warm_start must be True or False"):
        go2.ik(np.eye(4), "FL_calf", warm_start="yes")  # type: ignore[arg-type]
    with pytest.raises(poekin.InputError, match="does not broadcast"):
        go2.ik(np.stack([np.eye(4)] * 3), "FL_calf", np.zeros((2, 19)))
    with pytest.raises(poekin.InputError, match="not a rigid transform"):
        go2.ik(2 * np.eye(4), "FL_calf")


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
def test_the_docstring_examples_run() -> None:
    for method in (poekin.Chain.ik, poekin.Tree.ik):
        runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
        for test in doctest.DocTestFinder().find(method, globs={"poekin": poekin}):
            runner.run(test)
        assert runner.failures == 0 and runner.tries >= 3, method.__qualname__
