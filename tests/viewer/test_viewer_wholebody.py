"""The viewer's whole-body IK mode as pure computation (poekin.viewer.wholebody,
panel.wholebody_text): the targets a drag asks for, the solve from the configuration shown,
what is shown when the targets are out of reach. Every configuration is checked with MuJoCo's
mj_forward against the targets and with the joint limits, never by the solver's residual."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet, mj_pose

import poekin
from poekin import lie
from poekin.errors import HeldFramesError, InputError, UnknownFrameError
from poekin.io.import_mujoco import tree_from_model
from poekin.tree import Tree
from poekin.viewer import panel, wholebody
from poekin.viewer.wholebody import Handles, WholeBodyReach

TOL = 1e-10  # the solver's tolerances: a held frame is met to this
HANDS = ("left_elbow_roll_link", "right_elbow_roll_link")  # the G1's palms
FEET = ("left_foot", "right_foot")


@functools.cache
def g1() -> tuple[Any, Tree, Handles]:
    loaded = load_quiet("unitree_g1")
    tree = tree_from_model(loaded.model, robot=loaded.robot)
    return loaded, tree, wholebody.check_handles(tree, [*HANDS, *FEET], FEET)


def mj_errors(loaded: Any, shown: WholeBodyReach) -> dict[str, tuple[float, float]]:
    """Each handle's frame's position and orientation error at ``shown.qpos``, from
    mj_forward."""
    out = {}
    for frame in shown.handles.frames:
        got = mj_pose(loaded.model, shown.qpos[None], frame)[0]
        pos, ori = poekin.pose_errors(shown.targets[frame], got)
        out[frame] = (float(pos), float(ori))
    return out


def assert_valid(tree: Tree, qpos: np.ndarray) -> None:
    """Every hinge and slide within its limits, the floating base's quaternion unit."""
    for k, kind in enumerate(tree.joint_types):
        a = tree.qpos_adr[k]
        if kind in ("revolute", "prismatic"):
            lo, hi = tree.joint_limits[k]
            assert lo - 1e-12 <= qpos[a] <= hi + 1e-12, tree.joint_names[k]
        elif kind == "free":
            assert abs(np.linalg.norm(qpos[a + 3 : a + 7]) - 1.0) < 1e-12


def moved(T: np.ndarray, dp: list[float], dw: list[float] | None = None) -> np.ndarray:
    out = np.array(T)
    out[:3, 3] += dp
    if dw is not None:
        out[:3, :3] = out[:3, :3] @ lie.exp_so3(dw)
    return out


# --- the handles --------------------------------------------------------------------------


def test_handles_are_checked_against_the_tree() -> None:
    _, tree, handles = g1()
    assert handles.frames == (*HANDS, *FEET) and handles.hold == FEET
    assert handles.soft == HANDS
    # one comma-separated string, as the command line gives it; the held ones in the
    # handles' order
    got = wholebody.check_handles(tree, " right_foot, left_foot ,head,", "head, right_foot")
    assert got == Handles(("right_foot", "left_foot", "head"), ("right_foot", "head"))
    assert wholebody.check_handles(tree, ["head"]).hold == ()
    with pytest.raises(UnknownFrameError, match="no site or body named 'left_fot': did you mean"):
        wholebody.check_handles(tree, "left_fot,right_foot")
    with pytest.raises(InputError, match="held frame 'pelvis' has no handle"):
        wholebody.check_handles(tree, FEET, ["pelvis"])
    with pytest.raises(InputError, match="frames names 'head' twice"):
        wholebody.check_handles(tree, ["head", "head"])
    with pytest.raises(InputError, match="at least one frame"):
        wholebody.check_handles(tree, ",")


def test_follow_puts_every_target_at_its_frame() -> None:
    loaded, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    assert shown.how == "follow" and shown.success and shown.attempts == 0
    assert list(shown.targets) == list(handles.frames)
    for frame in handles.frames:
        assert_close(
            frame, shown.targets[frame], mj_pose(loaded.model, tree.qpos0[None], frame)[0], 1e-12
        )
    assert shown.held_error == 0.0 and shown.worst == (HANDS[0], 0.0, 0.0)
    with pytest.raises(InputError, match=r"qpos must have shape \(44,\)"):
        wholebody.follow(tree, handles, tree.qpos0[:7])


def test_a_drag_asks_for_the_dragged_pose_and_every_other_current_target() -> None:
    _, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    T = moved(shown.targets[HANDS[0]], [0.03, 0.0, 0.05])
    targets = wholebody.targets_after_drag(shown, HANDS[0], T)
    assert list(targets) == list(handles.frames)
    assert np.array_equal(targets[HANDS[0]], T)
    for frame in (HANDS[1], *FEET):
        assert np.array_equal(targets[frame], shown.targets[frame])
    targets[FEET[0]][0, 3] = 9.0  # copies: the shown targets stay
    assert shown.targets[FEET[0]][0, 3] != 9.0
    with pytest.raises(InputError, match="no handle on 'head'"):
        wholebody.targets_after_drag(shown, "head", T)
    with pytest.raises(InputError, match="not a rigid transform"):
        wholebody.targets_after_drag(shown, HANDS[0], 2 * T)
    with pytest.raises(InputError, match=r"one target pose \(4, 4\)"):
        wholebody.targets_after_drag(shown, HANDS[0], np.stack([T, T]))


# --- the solve ------------------------------------------------------------------------------


def test_dragging_a_hand_moves_the_body_and_the_feet_stay_put() -> None:
    """A drag in steps, as the page sends it: each step solved by the first attempt from the
    configuration shown; every frame at its target by MuJoCo, the feet to 1e-10 after every
    step, the other hand where it was."""
    loaded, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    feet = {f: shown.targets[f].copy() for f in FEET}
    other = shown.targets[HANDS[1]].copy()
    start = shown.targets[HANDS[0]].copy()
    for step in range(1, 6):
        T = moved(start, [0.02 * step, 0.0, 0.04 * step], [0.0, -0.1 * step, 0.0])
        before = shown.qpos
        shown = wholebody.drag(tree, shown, HANDS[0], T)
        assert shown.how == "current" and shown.success and shown.attempts == 1
        errors = mj_errors(loaded, shown)
        for frame, (pos, ori) in errors.items():
            assert pos <= TOL + MJ_TOL and ori <= TOL + MJ_TOL, frame
            assert abs(shown.frame_errors[frame][0] - pos) <= MJ_TOL, frame
        for frame in FEET:
            assert np.array_equal(shown.targets[frame], feet[frame])
        assert np.array_equal(shown.targets[HANDS[1]], other)
        assert np.array_equal(shown.targets[HANDS[0]], T)
        assert_valid(tree, shown.qpos)
        assert np.max(np.abs(shown.qpos - before)) < 0.5  # continuous: no jump to a branch
    assert np.max(np.abs(shown.qpos[:3] - tree.qpos0[:3])) > 1e-3  # the pelvis moved too


def test_dragging_a_held_foot_moves_it_exactly() -> None:
    loaded, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    T = moved(shown.targets[FEET[0]], [0.05, 0.02, 0.03], [0.0, 0.0, 0.15])
    shown = wholebody.drag(tree, shown, FEET[0], T)
    assert shown.success
    for frame, (pos, ori) in mj_errors(loaded, shown).items():
        assert pos <= TOL + MJ_TOL and ori <= TOL + MJ_TOL, frame
    assert_valid(tree, shown.qpos)


def test_a_target_out_of_reach_shows_the_best_fit_with_the_feet_held() -> None:
    """The hand dragged 60 cm above the head: the first attempt and the restarts miss; the
    robot shows the first attempt's fit, from where it was, the held feet still exact."""
    loaded, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    far = moved(shown.targets[HANDS[0]], [0.0, 0.0, 0.6])
    missed = wholebody.drag(tree, shown, HANDS[0], far)
    assert missed.how == "best fit" and not missed.success
    assert missed.attempts == 1 + wholebody.RESTART_ATTEMPTS
    errors = mj_errors(loaded, missed)
    for frame in FEET:
        assert max(errors[frame]) <= TOL + MJ_TOL, frame
        assert not missed.missed(frame)
    assert missed.missed(HANDS[0]) and errors[HANDS[0]][0] > 0.1
    for frame, (pos, ori) in errors.items():  # what the panel says is what MuJoCo sees
        assert abs(missed.frame_errors[frame][0] - pos) <= MJ_TOL
        assert abs(missed.frame_errors[frame][1] - ori) <= 1e-9
    assert missed.worst[0] == HANDS[0] and missed.held_error <= TOL
    assert_valid(tree, missed.qpos)
    assert np.array_equal(missed.targets[HANDS[0]], far)  # the target stays where it was asked


def test_a_first_attempt_that_misses_is_restarted() -> None:
    """Targets of a configuration far from the one shown (sample 10 of the G1's hinges, the
    base at qpos0): the first attempt misses, a restart reaches them."""
    loaded, tree, handles = g1()
    q = poekin.sample_qpos(tree, 1, seed=10, within_limits=True)[0]
    q[:7] = tree.qpos0[:7]
    poses = tree.fk(q)
    targets = {f: poses[tree.frame_index(f)] for f in handles.frames}
    shown = wholebody.solve(tree, handles, tree.qpos0, targets)
    assert shown.how == "restart" and shown.success
    assert shown.attempts == 1 + wholebody.RESTART_ATTEMPTS
    for frame, (pos, ori) in mj_errors(loaded, shown).items():
        assert pos <= TOL + MJ_TOL and ori <= TOL + MJ_TOL, frame
    assert_valid(tree, shown.qpos)


def test_held_frames_no_configuration_meets_together_are_refused() -> None:
    _, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    apart = moved(shown.targets[FEET[0]], [0.0, 1.5, 0.0])  # 1.5 m to the side
    with pytest.raises(HeldFramesError, match="cannot all be met together"):
        wholebody.drag(tree, shown, FEET[0], apart)


def test_solve_refuses_targets_that_do_not_fit_the_handles() -> None:
    _, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    some = {f: shown.targets[f] for f in FEET}
    with pytest.raises(InputError, match=f"no target for '{HANDS[0]}'"):
        wholebody.solve(tree, handles, tree.qpos0, some)
    with pytest.raises(InputError, match="a target for 'head', which has no handle"):
        wholebody.solve(tree, handles, tree.qpos0, {**shown.targets, "head": np.eye(4)})


# --- the panel --------------------------------------------------------------------------------


def test_the_panel_says_which_frames_are_held_and_the_worst_error() -> None:
    _, tree, handles = g1()
    shown = wholebody.follow(tree, handles, tree.qpos0)
    text = panel.wholebody_text(shown)
    assert "**4** handles; held (met exactly): `left_foot`, `right_foot`" in text
    assert "**every frame reached**" in text and "drag a handle" in text
    assert "| `left_foot` (held) | 0 mm, 0 mrad |" in text
    far = moved(shown.targets[HANDS[0]], [0.0, 0.0, 0.6])
    missed = wholebody.drag(tree, shown, HANDS[0], far)
    text = panel.wholebody_text(missed, solve_s=0.25, note="a note")
    pos, ori = missed.frame_errors[HANDS[0]]
    words = panel.residual_words(pos, ori)
    assert f"**NOT REACHED**: `{HANDS[0]}` missed; the held frames met" in text
    assert f"worst: `{HANDS[0]}` `{words}`" in text
    assert "first attempt's best fit" in text and "3 attempts" in text and "(250 ms)" in text
    assert "a note" in text
