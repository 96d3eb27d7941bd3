"""The viewer's IK mode as pure computation (poekin.viewer.ik, panel.ik_text): what the scene
shows for a target (the configuration, success, the residual, the closed-form solutions drawn as
ghosts), each configuration checked with MuJoCo's mj_forward and the joint limits, never by the
solver's own residual."""

from __future__ import annotations

import functools
from typing import Any

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet, mj_pose
from test_tree import _two_link

import poekin
from poekin import lie
from poekin.errors import InputError
from poekin.ik import IKResult
from poekin.ik._angles import within_limits
from poekin.io.import_mujoco import tree_from_model
from poekin.tree import Mimic
from poekin.viewer import ik, panel
from poekin.viewer.scene import Subject, make_subject

TOL = 1e-10  # the solver's tolerances


@functools.cache
def robot(name: str, frame: str | None = None) -> tuple[Any, Subject]:
    loaded = load_quiet(name)
    return loaded, make_subject(tree_from_model(loaded.model, robot=loaded.robot), frame)


def ur5e() -> tuple[Any, Subject]:
    return robot("universal_robots_ur5e")


def within(subject: Subject, qpos: np.ndarray) -> bool:
    return bool(np.all(within_limits(subject.chain_q(qpos), subject.chain.limits)))


def mj_errors(loaded: Any, subject: Subject, T: np.ndarray, qpos: np.ndarray) -> np.ndarray:
    """``(N, 2)`` position and orientation errors of the end frame at each ``(N, nq)`` qpos,
    from mj_forward."""
    got = mj_pose(loaded.model, np.reshape(qpos, (-1, subject.nq)), subject.frame)
    pos, ori = poekin.pose_errors(np.broadcast_to(T, got.shape), got)
    return np.stack([pos, ori], axis=-1)


def random_qpos(subject: Subject, rng: np.random.Generator) -> np.ndarray:
    lo, hi = subject.chain.limits.T
    x = subject.qpos0
    x[list(subject.chain.qpos_indices or ())] = rng.uniform(lo, hi)
    return x


# --- a target the arm reaches -----------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_dragged_target_is_solved_from_the_configuration_shown(seed: int) -> None:
    """A small drag: the first attempt, from the configuration shown, reaches it; the arm
    stays on its branch (the configuration that made the target, not another solution)."""
    loaded, subject = ur5e()
    rng = np.random.default_rng(seed)
    q_true = random_qpos(subject, rng)
    T = mj_pose(loaded.model, q_true[None], subject.frame)[0]
    start = q_true + rng.uniform(-0.05, 0.05, subject.nq)
    shown = ik.reach(subject, start, T)
    assert shown.how == "current" and shown.success
    assert within(subject, shown.qpos)
    pos, ori = mj_errors(loaded, subject, T, shown.qpos)[0]
    assert pos <= TOL + MJ_TOL and ori <= TOL + MJ_TOL
    assert abs(shown.pos_err - pos) <= MJ_TOL and abs(shown.ori_err - ori) <= MJ_TOL
    assert ik.same_configuration(subject, shown.qpos, q_true)  # its branch, to 1e-6
    assert_close("target", shown.target, T, 0.0)


def test_every_closed_form_solution_is_a_ghost_checked_by_mujoco() -> None:
    loaded, subject = ur5e()
    q_true = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T = mj_pose(loaded.model, q_true[None], subject.frame)[0]
    shown = ik.reach(subject, q_true + 0.01, T)
    sols = shown.solutions
    assert sols.shape == (8, 6)  # this pose: all eight branches within the UR5e's limits
    errors = mj_errors(loaded, subject, T, sols)
    assert errors.max() <= TOL + MJ_TOL
    assert all(within(subject, x) for x in sols)
    # distinct configurations, the generating one among them, and it is the one shown
    same = ik.same_configuration(subject, sols[:, None], sols[None])
    assert np.array_equal(same, np.eye(8, dtype=bool))
    assert ik.same_configuration(subject, sols[shown.current], q_true)
    assert ik.same_configuration(subject, sols[shown.current], shown.qpos)
    assert shown.ghosts == [k for k in range(8) if k != shown.current]


def test_a_target_another_branch_reaches_needs_a_restart() -> None:
    """From a configuration whose first attempt fails (found by trying, seeded), the solver
    restarts and the arm jumps to a branch that reaches the target."""
    loaded, subject = ur5e()
    rng = np.random.default_rng(0)
    for _ in range(200):
        start, q_true = random_qpos(subject, rng), random_qpos(subject, rng)
        T = mj_pose(loaded.model, q_true[None], subject.frame)[0]
        if not subject.chain.ik(T, start, max_attempts=1).success:
            break
    else:
        pytest.fail("no start whose first attempt fails")
    shown = ik.reach(subject, start, T)
    assert shown.how == "restart" and shown.success and within(subject, shown.qpos)
    assert mj_errors(loaded, subject, T, shown.qpos).max() <= TOL + MJ_TOL


# --- a target out of reach ------------------------------------------------------------------


def test_an_unreachable_target_shows_the_best_fit_and_its_residual() -> None:
    loaded, subject = ur5e()
    start = np.array([0.5, -1.2, 1.5, -1.9, -1.5708, 0.0])
    T = mj_pose(loaded.model, start[None], subject.frame)[0]
    T[:3, 3] = [0.9, -0.4, 0.6]  # 1.05 m from the shoulder: the UR5e reaches 0.85 m
    shown = ik.reach(subject, start, T)
    assert shown.how == "best fit" and not shown.success
    assert within(subject, shown.qpos)
    pos, ori = mj_errors(loaded, subject, T, shown.qpos)[0]
    assert 0.1 < pos < 0.5  # stretched towards it
    assert abs(shown.pos_err - pos) <= MJ_TOL and abs(shown.ori_err - ori) <= MJ_TOL
    # no closed-form branch reaches it either: no ghosts
    assert shown.solutions.shape == (0, 6) and shown.current == -1 and shown.ghosts == []
    # the best fit is the first attempt's, from where the drag led (no jump to another branch)
    first = subject.chain.ik(T, start, max_attempts=1)
    assert not first.success and np.array_equal(shown.qpos, first.q)
    text = panel.ik_text(shown, ik.support(subject), position_only=False, solve_s=2e-4)
    assert "**UNREACHABLE**" in text
    assert f"residual: `{pos * 1e3:.4g} mm, {ori * 1e3:.4g} mrad`" in text
    assert "(0.2 ms)" in text and "none in closed form" in text


def test_a_target_only_the_closed_form_reaches_takes_the_nearest_solution(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Should the numerical solve miss a target that closed-form branches reach, the arm
    takes the branch nearest the configuration shown (here the numerical solve is made to
    fail)."""
    loaded, subject = ur5e()
    q_true = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T = mj_pose(loaded.model, q_true[None], subject.frame)[0]

    def missing(subject: Subject, x: np.ndarray, *_: Any) -> IKResult:
        no = np.array(False)
        return IKResult(x, no, np.array(1.0), np.array(1.0), np.array(1), np.array(1))

    monkeypatch.setattr(ik, "_solve", missing)
    shown = ik.reach(subject, q_true + 0.02, T)
    assert shown.how == "analytic" and shown.success
    assert ik.same_configuration(subject, shown.qpos, q_true)
    assert mj_errors(loaded, subject, T, shown.qpos).max() <= TOL + MJ_TOL


# --- following the sliders, picking a solution --------------------------------------------------


def test_follow_puts_the_target_at_the_end_frame_with_its_solutions() -> None:
    loaded, subject = ur5e()
    q = np.array([0.5, -1.2, 1.5, -1.9, -1.5708, 0.0])
    shown = ik.follow(subject, q)
    T = mj_pose(loaded.model, q[None], subject.frame)[0]
    assert_close("target at the end frame", shown.target, T, MJ_TOL)
    assert shown.success and shown.how == "follow" and np.array_equal(shown.qpos, q)
    assert len(shown.solutions) >= 2 and ik.same_configuration(
        subject, shown.solutions[shown.current], q
    )
    assert mj_errors(loaded, subject, T, shown.solutions).max() <= TOL + MJ_TOL


def test_picking_a_solution_shows_it_at_the_same_target() -> None:
    loaded, subject = ur5e()
    shown = ik.follow(subject, np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2]))
    k = shown.ghosts[2]
    picked = ik.pick(subject, shown, k)
    assert picked.how == "picked" and picked.success and picked.current == k
    assert np.array_equal(picked.qpos, shown.solutions[k])
    assert_close("same target", picked.target, shown.target, 0.0)
    assert mj_errors(loaded, subject, shown.target, picked.qpos).max() <= TOL + MJ_TOL
    assert picked.ghosts == [j for j in range(len(shown.solutions)) if j != k]
    with pytest.raises(InputError, match=r"no closed-form solution 8: the solutions are 0\.\.7"):
        ik.pick(subject, shown, 8)


# --- the bodies of the ghosts -------------------------------------------------------------------


def test_ghost_bodies_and_anchors_against_mujoco() -> None:
    loaded, subject = ur5e()
    shown = ik.follow(subject, np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2]))
    bodies, anchors = ik.ghost_poses(subject, shown.solutions)
    model, data = loaded.model, mujoco.MjData(loaded.model)
    # the tree's bodies are MuJoCo's but the world (body 0)
    assert bodies.shape == (8, model.nbody - 1, 4, 4) and anchors.shape == (8, 6, 3)
    for x, T, p in zip(shown.solutions, bodies, anchors, strict=True):
        data.qpos[:] = x
        mujoco.mj_forward(model, data)
        assert_close("body positions", T[:, :3, 3], data.xpos[1:], MJ_TOL)
        assert_close("body rotations", T[:, :3, :3], data.xmat[1:].reshape(-1, 3, 3), MJ_TOL)
        assert_close("joint anchors", p, data.xanchor, MJ_TOL)


def poe(chain: poekin.Chain, q: np.ndarray) -> np.ndarray:
    """``e^[S1]q1 ... e^[Sn]qn``, the textbook product."""
    product = np.eye(4)
    for S, x in zip(chain.screws, q, strict=True):
        product = product @ lie.matrix_exp_se3(S, x)
    return product


def test_ghost_links_of_a_bare_chain_are_products_of_exponentials() -> None:
    chain = poekin.lynch_park_ur5_chain()
    subject = make_subject(chain)
    shown = ik.follow(subject, np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2]))
    assert len(shown.solutions) == 8
    assert np.all([within(subject, x) for x in shown.solutions])
    # a target 3 cm away, solved from the configuration shown
    T = chain.fk(shown.qpos)
    T[:3, 3] += [0.03, 0.0, 0.0]
    moved = ik.reach(subject, shown.qpos, T)
    assert moved.how == "current" and moved.success and within(subject, moved.qpos)
    assert_close("reached", poe(chain, moved.qpos) @ chain.home, T, 1e-10)
    bodies, _ = ik.ghost_poses(subject, shown.solutions)
    for q, links in zip(shown.solutions, bodies, strict=True):
        product = np.eye(4)
        for k in range(6):
            assert_close(f"link {k}", links[k], product, 1e-12)
            product = product @ lie.matrix_exp_se3(chain.screws[k], q[k])
        assert_close("solves the target", product @ chain.home, shown.target, 1e-10)


# --- trees ------------------------------------------------------------------------------------


def test_one_arm_of_aloha_moves_the_other_stays() -> None:
    loaded, subject = robot("aloha", "left/gripper")
    assert ik.support(subject) == ik.IKSupport(None, None)
    x = poekin.sample_qpos(subject.tree, 1, seed=3, within_limits=True)[0]  # type: ignore[arg-type]
    moved = list(subject.chain.qpos_indices or ())
    held = np.setdiff1d(np.arange(subject.nq), moved)
    goal = x.copy()
    goal[moved] = random_qpos(subject, np.random.default_rng(3))[moved]
    T = mj_pose(loaded.model, goal[None], subject.frame)[0]
    shown = ik.reach(subject, x, T)
    assert shown.success and within(subject, shown.qpos)
    assert np.array_equal(shown.qpos[held], x[held])
    assert mj_errors(loaded, subject, T, shown.qpos).max() <= TOL + MJ_TOL
    # the closed form applies to this 6-joint arm: each solution a whole qpos, checked
    assert len(shown.solutions) >= 1
    assert np.all(shown.solutions[:, held] == x[held])
    assert mj_errors(loaded, subject, T, shown.solutions).max() <= TOL + MJ_TOL


def test_a_leg_under_a_floating_base_position_only() -> None:
    loaded, subject = robot("unitree_go2", "FL_calf")
    support = ik.support(subject)
    assert support.available and "needs 6 revolute joints" in str(support.analytic)
    x = poekin.sample_qpos(subject.tree, 1, seed=2, within_limits=True)[0]  # type: ignore[arg-type]
    T = mj_pose(loaded.model, x[None], subject.frame)[0]
    start = x.copy()
    start[list(subject.chain.qpos_indices or ())] += 0.1
    shown = ik.reach(subject, start, T, position_only=True)
    assert shown.success and shown.solutions.shape == (0, subject.nq)
    pos = mj_errors(loaded, subject, T, shown.qpos)[0, 0]
    assert pos <= TOL + MJ_TOL
    moved = list(subject.chain.qpos_indices or ())
    assert np.array_equal(np.delete(shown.qpos, moved), np.delete(start, moved))  # base held
    text = panel.ik_text(shown, support, position_only=True)
    assert "position only: the orientation is free" in text and "**target reached**" in text


def test_frames_the_ik_mode_refuses_say_why() -> None:
    _, base = robot("unitree_go2", "base")
    support = ik.support(base)
    assert not support.available
    assert support.numerical == "no hinge or slide joint moves 'base': nothing to solve"
    with pytest.raises(InputError, match="no IK for 'base': no hinge or slide joint"):
        ik.reach(base, base.qpos0, np.eye(4))
    mimic = make_subject(_two_link((None, Mimic("j1", multiplier=-2.0, offset=0.25))), "tip")
    assert "joint 'j2' on the path to 'tip' mimics 'j1'" in str(ik.support(mimic).numerical)
    _, fr3 = robot("franka_fr3")
    support = ik.support(fr3)
    assert support.available and support.analytic is not None
    assert support.analytic.startswith("ik_all needs 6 revolute joints; franka_fr3 has 7")


def test_bad_targets_are_one_input_error() -> None:
    _, subject = ur5e()
    with pytest.raises(InputError, match="not a rigid transform"):
        ik.reach(subject, subject.qpos0, np.diag([1.0, 2.0, 1.0, 1.0]))
    with pytest.raises(InputError, match=r"one target pose \(4, 4\)"):
        ik.reach(subject, subject.qpos0, np.stack([np.eye(4)] * 2))
    with pytest.raises(InputError, match="expected 6 qpos values"):
        ik.reach(subject, np.zeros(5), np.eye(4))
