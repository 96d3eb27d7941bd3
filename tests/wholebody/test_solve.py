"""Tree.ik with a dict of targets (poekin.wholebody): many frames at once, a floating base,
held contacts. Every answer is checked by MuJoCo's mj_forward on the whole qpos; targets are
FK of in-limit configurations, so every set is reachable."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_pose

import poekin
from poekin import HeldFramesError
from poekin.errors import InputError, UnknownFrameError
from poekin.wholebody.space import space

TOL = 1e-9  # the per-frame goal; the solver's own tolerance is 1e-10
HOLD_TOL = 1e-10
G1_FRAMES = ("left_elbow_roll_link", "right_elbow_roll_link", "left_foot", "right_foot", "pelvis")
FEET = {"left_foot", "right_foot"}


def _near(tree: poekin.Tree, n: int, sigma: float, seed: int) -> np.ndarray:
    """``n`` in-limit configurations: qpos0 with every hinge moved by N(0, sigma)."""
    rng = np.random.default_rng(seed)
    sp = space(tree, ())
    q = np.repeat(tree.qpos0[None], n, axis=0)
    q[:, sp.scalar_q] += rng.normal(0.0, sigma, (n, len(sp.scalar_q)))
    return sp.clip(q)


def _targets(tree: poekin.Tree, q: np.ndarray, frames: tuple[str, ...]) -> dict[str, np.ndarray]:
    T = tree.fk(q)
    return {f: T[..., tree.frame_index(f), :, :] for f in frames}


def _mj_errors(
    model: mujoco.MjModel, qpos: np.ndarray, targets: dict[str, np.ndarray], modes: dict[str, str]
) -> dict[str, np.ndarray]:
    """Per frame, the larger of the position and orientation error MuJoCo's FK leaves."""
    out = {}
    for frame, target in targets.items():
        mode = modes.get(frame, "pose")
        T = mj_pose(model, qpos.reshape(-1, qpos.shape[-1]), frame)
        if mode == "position":
            out[frame] = np.linalg.norm(T[:, :3, 3] - target.reshape(-1, 3), axis=1)
            continue
        pos, ori = poekin.pose_errors(target.reshape(-1, 4, 4), T)
        out[frame] = np.maximum(pos, ori)
    return out


@pytest.fixture(scope="module")
def g1() -> tuple[poekin.Tree, mujoco.MjModel]:
    loaded = load_quiet("unitree_g1")
    return poekin.load_tree(loaded), loaded.model


def test_g1_reach_with_planted_feet_checked_by_mujoco(
    g1: tuple[poekin.Tree, mujoco.MjModel],
) -> None:
    tree, model = g1
    q_true = _near(tree, 24, 0.3, seed=1)
    targets = _targets(tree, q_true, G1_FRAMES)
    targets["head"] = tree.fk(q_true)[:, tree.frame_index("head"), :3, 3]
    found = tree.ik(targets, tree.qpos0, hold=FEET, position_only={"head"}, weights={"pelvis": 0.1})
    errors = _mj_errors(model, found.qpos, targets, {"head": "position"})
    for frame in FEET:  # held: met on every entry
        assert errors[frame].max() <= HOLD_TOL + MJ_TOL, frame
    ok = found.success
    assert ok.mean() >= 0.9, f"only {ok.mean():.0%} solved"
    for frame, err in errors.items():
        assert err[ok].max() <= TOL, frame
    # every iterate inside the limits, quaternions unit
    sp = space(tree, ())
    q = found.qpos[:, sp.scalar_q]
    assert np.all((q >= sp.lower) & (q <= sp.upper))
    np.testing.assert_allclose(np.linalg.norm(found.qpos[:, 3:7], axis=1), 1.0, atol=1e-15)


def test_g1_held_feet_stay_exact_when_the_hands_are_out_of_reach(
    g1: tuple[poekin.Tree, mujoco.MjModel],
) -> None:
    tree, model = g1
    q_true = _near(tree, 6, 0.2, seed=2)
    targets = _targets(tree, q_true, ("left_foot", "right_foot", "left_elbow_roll_link"))
    far = np.array(targets["left_elbow_roll_link"])
    far[:, :3, 3] += [3.0, 0.0, 0.0]  # 3 m ahead: no arm gets there with its feet down
    targets["left_elbow_roll_link"] = far
    found = tree.ik(targets, tree.qpos0, hold=FEET, max_attempts=3)
    assert not found.success.any()
    errors = _mj_errors(model, found.qpos, targets, {})
    for frame in FEET:
        assert errors[frame].max() <= HOLD_TOL + MJ_TOL, frame
    assert errors["left_elbow_roll_link"].min() > 1.0
    np.testing.assert_allclose(
        found.frame_errors["left_elbow_roll_link"][0], errors["left_elbow_roll_link"], atol=1e-9
    )


def test_go2_moves_its_body_over_four_held_feet() -> None:
    loaded = load_quiet("unitree_go2")
    tree, model = poekin.load_tree(loaded), loaded.model
    feet = ("FL_calf", "FR_calf", "RL_calf", "RR_calf")
    q_true = _near(tree, 20, 0.3, seed=3)
    targets = _targets(tree, q_true, ("base", *feet))
    start = tree.fk(tree.qpos0)  # feet where they stand, the body elsewhere
    for f in feet:
        targets[f] = np.broadcast_to(start[tree.frame_index(f), :3, 3], (20, 3))
    targets["base"] = np.array(targets["base"])
    # the body moves 3 cm and turns; the feet stay: reachable for most draws only, so the
    # held feet are checked on every entry, the body where success says so
    found = tree.ik(targets, tree.qpos0, hold=set(feet), position_only=set(feet))
    errors = _mj_errors(model, found.qpos, targets, dict.fromkeys(feet, "position"))
    for f in feet:
        assert errors[f].max() <= HOLD_TOL + MJ_TOL, f
    assert found.success.any()
    assert errors["base"][found.success].max() <= TOL


def test_go2_body_reached_with_feet_from_the_same_configuration() -> None:
    loaded = load_quiet("unitree_go2")
    tree, model = poekin.load_tree(loaded), loaded.model
    feet = ("FL_calf", "FR_calf", "RL_calf", "RR_calf")
    q_true = _near(tree, 20, 0.3, seed=4)
    targets = _targets(tree, q_true, ("base",))
    T = tree.fk(q_true)
    for f in feet:
        targets[f] = T[:, tree.frame_index(f), :3, 3]
    found = tree.ik(targets, tree.qpos0, hold=set(feet), position_only=set(feet))
    assert found.success.all()
    errors = _mj_errors(model, found.qpos, targets, dict.fromkeys(feet, "position"))
    for f, err in errors.items():
        assert err.max() <= TOL, f


def test_aloha_both_grippers() -> None:
    loaded = load_quiet("aloha")
    tree, model = poekin.load_tree(loaded), loaded.model
    q_true = poekin.sample_qpos(tree, 40, seed=5, within_limits=True)
    targets = _targets(tree, q_true, ("left/gripper", "right/gripper"))
    found = tree.ik(targets, tree.qpos0)
    assert found.success.all()
    for frame, err in _mj_errors(model, found.qpos, targets, {}).items():
        assert err.max() <= TOL, frame


def test_panda_posture_pulls_toward_qpos_in_the_null_space() -> None:
    loaded = load_quiet("franka_emika_panda")
    tree, model = poekin.load_tree(loaded), loaded.model
    q_true = _near(tree, 20, 0.4, seed=6)
    targets = _targets(tree, q_true, ("hand",))
    free = tree.ik(targets, tree.qpos0, freeze={"finger_joint1"})
    pulled = tree.ik(targets, tree.qpos0, posture=0.5, freeze={"finger_joint1"})
    for found in (free, pulled):
        assert found.success.all()
        assert _mj_errors(model, found.qpos, targets, {})["hand"].max() <= TOL
    arm = slice(0, 7)
    d_free = np.linalg.norm(free.qpos[:, arm] - tree.qpos0[arm], axis=1)
    d_pulled = np.linalg.norm(pulled.qpos[:, arm] - tree.qpos0[arm], axis=1)
    assert np.median(d_pulled) < np.median(d_free)
    np.testing.assert_array_equal(free.qpos[:, 7], tree.qpos0[7])  # frozen: as given


def test_centre_of_mass_target(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, model = g1
    q_true = _near(tree, 8, 0.2, seed=7)
    targets = _targets(tree, q_true, ("left_foot", "right_foot"))
    targets["com"] = tree.com(q_true)
    found = tree.ik(targets, tree.qpos0, hold=FEET | {"com"})
    assert found.success.all()
    data = mujoco.MjData(model)
    for q, c in zip(found.qpos, targets["com"], strict=True):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        assert np.linalg.norm(data.subtree_com[0] - c) <= TOL


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_batch_shapes_and_the_same_bits_alone(shape: tuple[int, ...]) -> None:
    tree = poekin.load_tree(load_quiet("aloha"))
    n = int(np.prod(shape))
    q_true = poekin.sample_qpos(tree, n, seed=8, within_limits=True).reshape(*shape, tree.nq)
    targets = _targets(tree, q_true, ("left/gripper", "right/gripper"))
    found = tree.ik(targets, tree.qpos0)
    assert found.qpos.shape == (*shape, tree.nq)
    assert found.success.shape == shape
    assert found.frame_errors["left/gripper"][0].shape == shape
    flat = {k: v.reshape(-1, 4, 4) for k, v in targets.items()}
    for i in range(n):
        alone = tree.ik({k: v[i] for k, v in flat.items()}, tree.qpos0)
        np.testing.assert_array_equal(alone.qpos, found.qpos.reshape(-1, tree.nq)[i])


def test_single_frame_form_is_unchanged() -> None:
    tree = poekin.load_tree(load_quiet("aloha"))
    q = poekin.sample_qpos(tree, 1, seed=1, within_limits=True)[0]
    found = tree.ik(tree.pose(q, "left/gripper"), "left/gripper")
    assert bool(found.success) and found.q.shape == (16,)


# --- bad input: one clear error each ---------------------------------------------------


def _g1_targets(tree: poekin.Tree) -> dict[str, np.ndarray]:
    return _targets(tree, tree.qpos0, ("left_foot", "right_foot", "pelvis"))


def test_unknown_frame_suggests_the_nearest(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, _ = g1
    with pytest.raises(UnknownFrameError, match="did you mean 'left_foot'"):
        tree.ik({"left_fot": np.eye(4)}, tree.qpos0)


def test_a_frame_both_held_and_weighted(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, _ = g1
    with pytest.raises(InputError, match=r"'left_foot' is held .* and also given a weight"):
        tree.ik(_g1_targets(tree), tree.qpos0, hold={"left_foot"}, weights={"left_foot": 2.0})


def test_hold_names_a_frame_without_a_target(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, _ = g1
    with pytest.raises(InputError, match="hold names 'left_hand', which has no target"):
        tree.ik(_g1_targets(tree), tree.qpos0, hold={"left_hand"})


def test_held_frames_that_conflict_are_named(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, _ = g1
    targets = _g1_targets(tree)
    apart = np.array(targets["right_foot"])
    apart[:3, 3] += [0.0, -5.0, 0.0]  # 5 m between the feet
    targets["right_foot"] = apart
    with pytest.raises(HeldFramesError, match="'left_foot', 'right_foot' cannot all be met"):
        tree.ik(targets, tree.qpos0, hold=FEET, max_attempts=2)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (np.eye(3), r"'pelvis' \(pose\) must have shape \(\.\.\., 4, 4\), got \(3, 3\)"),
        (np.full((4, 4), np.nan), "'pelvis' contains NaN or inf"),
        ("a", "must be an array of numbers"),
        (  # checked with the others in one call, then alone, naming it
            np.diag([2.0, 1.0, 1.0, 1.0]),
            "the target of 'pelvis' is not a rigid transform: its rotation block is not",
        ),
    ],
)
def test_bad_targets(g1: tuple[poekin.Tree, mujoco.MjModel], value: object, message: str) -> None:
    tree, _ = g1
    targets: dict[str, object] = dict(_g1_targets(tree))
    targets["pelvis"] = value
    with pytest.raises(InputError, match=message):
        tree.ik(targets, tree.qpos0)  # type: ignore[arg-type]


def test_bad_options(g1: tuple[poekin.Tree, mujoco.MjModel]) -> None:
    tree, _ = g1
    targets = _g1_targets(tree)
    with pytest.raises(InputError, match="freeze names 'left_knee', which is no joint"):
        tree.ik(targets, tree.qpos0, freeze={"left_knee"})
    with pytest.raises(InputError, match="posture must be a weight >= 0"):
        tree.ik(targets, tree.qpos0, posture=-1.0)
    with pytest.raises(InputError, match="non-empty dict"):
        tree.ik({}, tree.qpos0)
    with pytest.raises(InputError, match="hold= is for a dict of targets"):
        tree.ik(np.eye(4), "pelvis", hold={"pelvis"})
    with pytest.raises(InputError, match="both position_only and orientation_only"):
        tree.ik(targets, tree.qpos0, position_only={"pelvis"}, orientation_only={"pelvis"})
    with pytest.raises(InputError, match="qpos values"):
        tree.ik(targets, np.zeros(3))


def test_a_mimic_joint_follows_its_leader() -> None:
    """A planar two-link arm whose elbow mimics its shoulder (-2 q1 + 0.25): one variable, so
    the tip's position is one curve; a point on it is reached, checked against the hand
    formula l1 (cos q1, sin q1) + l2 (cos(q1 + q2), sin(q1 + q2))."""
    from test_tree import _two_link

    from poekin.tree import Mimic

    tree = _two_link((None, Mimic("j1", multiplier=-2.0, offset=0.25)))
    q1 = 0.7
    q2 = -2.0 * q1 + 0.25
    tip = [0.3 * np.cos(q1) + 0.2 * np.cos(q1 + q2), 0.3 * np.sin(q1) + 0.2 * np.sin(q1 + q2), 0.1]
    found = tree.ik({"tip": np.array(tip)}, [0.5], position_only={"tip"})
    assert bool(found.success) and found.qpos.shape == (1,)
    np.testing.assert_allclose(found.qpos, [q1], atol=1e-9)


def test_rotation_error_is_the_quaternion_vector_of_lie() -> None:
    """The residual's orientation rows: 2 (x, y, z) of the quaternion with w >= 0, as
    poekin.lie.rotation_to_quat gives it, at every angle up to pi about every axis; and its
    w, which their derivative takes."""
    from poekin.wholebody.solve import _angle, rotation_quaternion

    rng = np.random.default_rng(0)
    w = rng.normal(size=(3000, 3))
    w[:1000] *= (np.pi / np.linalg.norm(w[:1000], axis=1) * rng.uniform(0.99, 1.0, 1000))[:, None]
    w[1000:1003] = np.pi * np.eye(3)  # half turns about each axis
    w[1003] = 0.0
    R = poekin.lie.exp_so3(w)
    quat = poekin.lie.rotation_to_quat(R)
    expected = 2.0 * np.where(quat[:, :1] < 0, -quat[:, 1:], quat[:, 1:])
    found = rotation_quaternion(R)
    np.testing.assert_allclose(2.0 * found[:, 1:], expected, atol=2e-15, rtol=0)
    np.testing.assert_allclose(found[:, 0], np.abs(quat[:, 0]), atol=2e-15, rtol=0)
    np.testing.assert_allclose(_angle(R), poekin.lie.rotation_angle(R), atol=1e-15, rtol=0)


def test_a_weak_posture_is_the_same_level_as_a_strong_one(
    g1: tuple[poekin.Tree, mujoco.MjModel],
) -> None:
    """posture=0.01 (the size mink's examples use) and posture=1 pull the G1 to the same
    configuration: the posture is the last level, its weights' ratios only matter; both meet
    every target, checked by MuJoCo."""
    tree, model = g1
    q_true = _near(tree, 8, 0.2, seed=9)
    targets = _targets(tree, q_true, ("left_elbow_roll_link", "right_elbow_roll_link", *FEET))
    weak = tree.ik(targets, tree.qpos0, hold=FEET, posture=0.01)
    strong = tree.ik(targets, tree.qpos0, hold=FEET, posture=1.0)
    assert weak.success.all() and strong.success.all()
    np.testing.assert_array_equal(weak.qpos, strong.qpos)
    for frame, err in _mj_errors(model, weak.qpos, targets, {}).items():
        assert err.max() <= TOL, frame
    plain = tree.ik(targets, tree.qpos0, hold=FEET)
    arms = slice(7, tree.nq)
    pulled = np.linalg.norm(weak.qpos[:, arms] - tree.qpos0[arms], axis=1)
    assert np.all(pulled <= np.linalg.norm(plain.qpos[:, arms] - tree.qpos0[arms], axis=1) + 1e-9)
