"""chain.follow (poekin.motion.follow): IK along a pose path, the branch kept. Every sample, every
stop and the deviation between samples are checked with MuJoCo's mj_kinematics on the model's
qpos (its Jacobian from mj_jacSite); the UR5e's configuration signs are read from MuJoCo's joint
axes, not from the code under test."""

from __future__ import annotations

import dataclasses
import doctest
from collections.abc import Callable

import mujoco
import numpy as np
import pytest
from helpers import load_quiet, mj_frame_pose
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin.errors import InputError
from poekin.motion import line_path, screw_path
from poekin.motion.follow import S_RESOLUTION, FollowResult

SOLVED = 1e-9  # every sample on the path at its s, by MuJoCo (the solvers reach 1e-10, 1e-12)
# Between samples the tool's deviation is bisected until the midpoint's is under tol; at a
# quarter or three quarters of an interval it is about 3/4 of the midpoint's, plus terms of the
# third order in the interval's length, which are far below 1% of tol at these sample counts
BETWEEN_SLACK = 1.01
# A configuration sign's quantity (m, or a sine) this near 0 has no sign: the stop at a
# singularity is within S_RESOLUTION of it, where it is some 1e-5 (its square root)
EDGE = 1e-4
# A joint at a limit where it stops: within S_RESOLUTION of s, which near a fold of the arm (the
# UR's elbow at +-pi, its limit) is within the square root of it in the joint (3e-5 rad)
AT_LIMIT = 1e-4


@dataclasses.dataclass(frozen=True)
class Robot:
    chain: poekin.Chain
    model: mujoco.MjModel

    def poses(self, q: np.ndarray) -> np.ndarray:
        """``(m, 4, 4)`` poses of the chain's frame from mj_kinematics for ``(m, n)`` ``q``."""
        d = mujoco.MjData(self.model)
        idx = list(self.chain.qpos_indices or ())
        site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, self.chain.frame)
        out = np.empty((len(q), 4, 4))
        for k, row in enumerate(q):
            d.qpos[idx] = row
            mujoco.mj_kinematics(self.model, d)
            out[k] = mj_frame_pose(self.model, d, "site", site)
        return out

    def sigma_min(self, q: np.ndarray) -> float:
        """The smallest singular value of MuJoCo's site Jacobian ``[jacr; jacp]`` at ``q``."""
        d = mujoco.MjData(self.model)
        d.qpos[list(self.chain.qpos_indices or ())] = q
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, self.chain.frame)
        jacp, jacr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        mujoco.mj_jacSite(self.model, d, jacp, jacr, site)
        dofs = [self.model.jnt_dofadr[self.model.joint(n).id] for n in self.chain.joint_names]
        J = np.vstack([jacr, jacp])[:, dofs]
        return float(np.linalg.svd(J, compute_uv=False)[-1])

    def ur_signs(self, q: np.ndarray) -> np.ndarray:
        """``(m, 3)`` a UR's configuration signs from MuJoCo's joint axes: shoulder (which side
        of the plane of axes 1 and 2 the point where axes 5 and 6 meet is), wrist ``sin q5``,
        elbow ``sin q3``; 0 where the quantity is within :data:`EDGE` of 0 (the branch's two
        roots meet there: a singularity, where a path ends)."""
        d = mujoco.MjData(self.model)
        jid = [self.model.joint(n).id for n in self.chain.joint_names]
        out = np.empty((len(q), 3))
        for k, row in enumerate(q):
            d.qpos[list(self.chain.qpos_indices or ())] = row
            mujoco.mj_kinematics(self.model, d)
            z1, h, a1 = d.xaxis[jid[0]], d.xaxis[jid[1]], d.xanchor[jid[0]]
            p5, u5, p6, u6 = d.xanchor[jid[4]], d.xaxis[jid[4]], d.xanchor[jid[5]], d.xaxis[jid[5]]
            A = np.array([[u5 @ u5, -(u5 @ u6)], [u5 @ u6, -(u6 @ u6)]])
            t = np.linalg.solve(A, [u5 @ (p6 - p5), u6 @ (p6 - p5)])
            c56 = p5 + t[0] * u5
            out[k] = (np.dot(c56 - a1, np.cross(z1, h)), np.sin(row[4]), np.sin(row[2]))
        return np.where(np.abs(out) < EDGE, 0.0, np.sign(out))


@pytest.fixture(scope="module")
def ur5e() -> Robot:
    loaded = load_quiet("universal_robots_ur5e")
    return Robot(poekin.load(loaded), loaded.model)


@pytest.fixture(scope="module")
def fr3() -> Robot:
    loaded = load_quiet("franka_fr3")
    return Robot(poekin.load(loaded), loaded.model)


def _in_limits(chain: poekin.Chain, rng: np.random.Generator) -> np.ndarray:
    lo = np.maximum(chain.limits[:, 0], -np.pi)
    hi = np.minimum(chain.limits[:, 1], np.pi)
    return rng.uniform(lo, hi)


def _line(robot: Robot, seed: int, reach: float) -> tuple[np.ndarray, Callable[..., np.ndarray]]:
    """A random start and a straight line from its pose: toward the pose of another random
    in-limit configuration (``reach`` 1), or ``reach`` of the way there."""
    rng = np.random.default_rng(seed)
    qa, qb = _in_limits(robot.chain, rng), _in_limits(robot.chain, rng)
    T0 = robot.chain.fk(qa)
    T1 = line_path(T0, robot.chain.fk(qb), reach)
    return qa, lambda s: line_path(T0, T1, s)


def check(robot: Robot, result: FollowResult, path: Callable[..., np.ndarray]) -> None:
    """Everything a result promises, checked by MuJoCo and the path itself."""
    chain, q, s = robot.chain, result.q, result.s
    tol, ori_tol, max_step = 1e-4, 1e-3, 0.1
    assert q.shape == (len(s), chain.n_joints) and result.T.shape == (len(s), 4, 4)
    assert s[0] == 0.0 and np.all(np.diff(s) > 0) and result.fraction == s[-1]
    # every sample, the last (where it stops) too, is on the path at its s
    pos, ori = poekin.pose_errors(path(s), robot.poses(q))
    assert pos.max() <= SOLVED and ori.max() <= SOLVED
    assert np.all(q >= chain.limits[:, 0]) and np.all(q <= chain.limits[:, 1])
    # no silent flip: every step bounded, and a UR's configuration signs never change
    if len(s) > 1:
        assert np.max(np.abs(np.diff(q, axis=0))) <= max_step
    if chain.robot.endswith("ur5e") and result.branch is not None:
        signs = robot.ur_signs(q)
        assert np.all(signs[0] != 0) and np.all((signs == signs[0]) | (signs == 0)), "a flip"
    # the deviation between samples, at a quarter, the middle and three quarters of each
    if len(s) > 1:
        for t in (0.25, 0.5, 0.75):
            between = robot.poses((1 - t) * q[:-1] + t * q[1:])
            pos, ori = poekin.pose_errors(path((1 - t) * s[:-1] + t * s[1:]), between)
            assert pos.max() <= tol * BETWEEN_SLACK and ori.max() <= ori_tol * BETWEEN_SLACK
    check_stop(robot, result, path)


def check_stop(robot: Robot, result: FollowResult, path: Callable[..., np.ndarray]) -> None:
    """The reason a result gives for stopping, checked where it stopped."""
    chain, q_end = robot.chain, result.q[-1]
    if result.reason == "done":
        assert result.fraction == 1.0 and result.detail == ""
        return
    assert result.fraction < 1.0 and result.detail
    after = path(np.array([result.fraction + 10 * S_RESOLUTION]))[0]
    if result.reason == "joint_limit":
        k = chain.joint_names.index(result.joint)
        assert np.min(np.abs(chain.limits[k] - q_end[k])) < AT_LIMIT, result.detail
    elif result.reason == "unreachable":
        # no configuration reaches the pose a little further on: no closed-form branch, no
        # numerical solve from random starts; and the arm is at its workspace's edge
        assert not chain.ik(after, max_attempts=200).success, result.detail
        assert robot.sigma_min(q_end) < 1e-3
    elif result.reason == "singular":
        assert robot.sigma_min(q_end) < 1e-4
        assert result.sigma_min == pytest.approx(robot.sigma_min(q_end), abs=1e-9)
    else:
        assert result.reason == "jump", result.reason
        # reachable, but not within max_step of the last sample
        assert chain.ik(after, max_attempts=200).success
        near = chain.ik(after, q_end, max_attempts=1)
        assert not (near.success and np.max(np.abs(near.q - q_end)) <= 0.1)


# --- the UR5e: the closed form, one branch -------------------------------------------------------


def test_ur5e_movel_keeps_the_branch_and_the_line(ur5e: Robot) -> None:
    chain = ur5e.chain
    q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T0 = chain.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.2, -0.1, -0.15]

    def path(s: np.ndarray) -> np.ndarray:
        return line_path(T0, T1, s)

    result = chain.follow(path, q0)
    assert result.done and result.fraction == 1.0 and result.branch is not None
    assert np.array_equal(result.q[0], q0)
    assert result.max_deviation <= 1e-4 and result.max_ori_deviation <= 1e-3
    check(ur5e, result, path)
    # the branch kept: every sample's signs are those of q0, as MuJoCo's axes read them
    assert np.all(ur5e.ur_signs(result.q) == ur5e.ur_signs(q0[None]))
    # signs: the wrist's +1 is q5 > 0, the elbow's +1 is q3 < 0 (q0: q5 > 0, q3 > 0)
    assert result.signs is not None and result.signs[1:] == (1, -1)


def test_samples_are_joined_by_screw_motions(ur5e: Robot) -> None:
    """An array path: the given poses are samples (s uniform), the screw motion between
    them; a tighter tol re-samples more densely."""
    chain = ur5e.chain
    q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T = chain.fk(np.array([q0, q0 + np.array([0.3, 0.2, -0.3, 0.2, 0.3, 0.4]), q0 + 0.5]))

    def path(s: np.ndarray) -> np.ndarray:
        first = s <= 0.5
        u = np.where(first, 2 * s, 2 * s - 1)
        return np.where(first[:, None, None], screw_path(T[0], T[1], u), screw_path(T[1], T[2], u))

    coarse = chain.follow(T, q0)
    fine = chain.follow(T, q0, tol=1e-5, ori_tol=1e-4)
    assert coarse.reason == fine.reason == "done"
    assert {0.0, 0.5, 1.0} <= set(coarse.s.tolist())
    assert len(fine.s) > len(coarse.s)
    check(ur5e, coarse, path)
    assert fine.max_deviation <= 1e-5 and fine.max_ori_deviation <= 1e-4


def test_a_1000_sample_line(ur5e: Robot) -> None:
    """The benchmark's case: a line given as 1,000 samples needs no re-sampling."""
    chain = ur5e.chain
    q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T0 = chain.fk(q0)
    T1 = chain.fk(np.array([0.8, -0.9, 1.0, -0.2, 1.3, -0.3]))
    s = np.linspace(0.0, 1.0, 1000)
    result = chain.follow(line_path(T0, T1, s), q0)
    assert result.reason == "done" and np.array_equal(result.s, s)
    check(ur5e, result, lambda x: line_path(T0, T1, x))


def test_ur5e_stops_at_the_wrist_singularity_instead_of_flipping(ur5e: Robot) -> None:
    """Wrist_2 turned through 0: the pose path crosses the wrist singularity, where the branch
    (q5 > 0) ends and only a flip of q4 and q6 by pi would go on."""
    chain = ur5e.chain
    qa = np.array([0.0, -1.2, 1.4, -0.5, 0.05, 0.2])
    qb = qa.copy()
    qb[4] = -0.05
    T = chain.fk(np.array([qa, qb]))
    result = chain.follow(T, qa)
    assert result.reason == "singular" and result.sigma_min is not None
    assert result.fraction == pytest.approx(0.5, abs=1e-8)  # q5 = 0 halfway
    check(ur5e, result, lambda s: screw_path(T[0], T[1], s))


def test_ur5e_stops_at_a_joint_limit_naming_the_joint(ur5e: Robot) -> None:
    limits = np.array(ur5e.chain.limits)
    limits[0] = [-0.5, 0.5]
    narrow = Robot(dataclasses.replace(ur5e.chain, limits=limits), ur5e.model)
    qa = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    qb = qa.copy()
    qb[0] = 0.8  # the base turned past its (narrowed) limit
    T = ur5e.chain.fk(np.array([qa, qb]))
    result = narrow.chain.follow(T, qa)
    assert result.reason == "joint_limit" and result.joint == "shoulder_pan_joint"
    assert result.fraction == pytest.approx(0.2 / 0.5, abs=1e-6)  # the base at 0.5 rad
    check(narrow, result, lambda s: screw_path(T[0], T[1], s))
    # the arm's own limits let it go on
    assert ur5e.chain.follow(T, qa).reason == "done"


def test_ur5e_line_out_of_the_workspace_is_unreachable(ur5e: Robot) -> None:
    chain = ur5e.chain
    q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T0 = chain.fk(q0)
    T1 = T0.copy()
    T1[0, 3] += 2.0  # 2 m along x: the UR5e reaches 0.85 m

    def path(s: np.ndarray) -> np.ndarray:
        return line_path(T0, T1, s)

    result = chain.follow(path, q0)
    assert result.reason == "unreachable" and 0.1 < result.fraction < 0.9
    check(ur5e, result, path)
    # the edge: the elbow stretched (q3 near 0) where the line leaves the workspace
    assert abs(np.sin(result.q[-1, 2])) < 1e-3


def test_a_singular_start_is_solved_numerically(ur5e: Robot) -> None:
    """q0 at the wrist singularity (q5 = 0): the closed form's convention fixes q4 and q6 its own
    way, so q0 is on no branch, and each sample is chain.ik from the one before."""
    chain = ur5e.chain
    q0 = np.array([0.3, -1.2, 1.4, -0.5, 0.0, 0.2])
    T0 = chain.fk(q0)
    T1 = T0.copy()
    T1[2, 3] -= 0.05

    def path(s: np.ndarray) -> np.ndarray:
        return line_path(T0, T1, s)

    result = chain.follow(path, q0)
    assert result.branch is None and result.signs is None
    check(ur5e, result, path)


def test_ur5e_branch_ends_where_another_goes_on(ur5e: Robot) -> None:
    """A line (random seed 47) that leaves the reach of q0's branch while another branch (the
    other shoulder) still reaches it: a singular stop, not a switch."""
    q0, path = _line(ur5e, 47, reach=1.0)
    result = ur5e.chain.follow(path, q0)
    assert result.reason == "singular" and "ends here" in result.detail
    after = path(np.array([result.fraction + 10 * S_RESOLUTION]))
    assert ur5e.chain.ik_all(after).valid.any()
    check(ur5e, result, path)


def _broken(T0: np.ndarray, T1: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """A path that jumps from ``T0`` to ``T1`` at s = 0.5."""
    return lambda s: np.where((np.asarray(s) < 0.5)[..., None, None], T0, T1)


@pytest.mark.parametrize("robot_name", ["ur5e", "fr3"])
def test_a_path_that_jumps(robot_name: str, request: pytest.FixtureRequest) -> None:
    robot: Robot = request.getfixturevalue(robot_name)
    q0 = Q0 if robot_name == "ur5e" else np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
    path = _broken(robot.chain.fk(q0), robot.chain.fk(q0 + 0.3))
    result = robot.chain.follow(path, q0)
    assert result.reason == "jump" and result.done is False
    assert result.fraction == pytest.approx(0.5, abs=1e-8)
    check(robot, result, path)


def test_fr3_path_that_jumps_out_of_the_solve_s_reach(fr3: Robot) -> None:
    """A jump to a pose that one attempt from the last sample does not solve (random restarts
    do): a jump, not unreachable."""
    q0 = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
    far = np.array([0.752, -0.821, -2.663, -2.994, 1.758, 4.17, 0.643])
    assert not fr3.chain.ik(fr3.chain.fk(far), q0, max_attempts=1).success
    path = _broken(fr3.chain.fk(q0), fr3.chain.fk(far))
    result = fr3.chain.follow(path, q0)
    assert result.reason == "jump" and "no solution nearby" in result.detail
    check(fr3, result, path)


@pytest.mark.parametrize("seed", range(12))
def test_ur5e_random_lines(ur5e: Robot, seed: int) -> None:
    q0, path = _line(ur5e, seed, reach=1.0 if seed % 2 else 0.2)
    check(ur5e, ur5e.chain.follow(path, q0), path)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), reach=st.floats(0.01, 1.0))
def test_ur5e_lines_property(ur5e: Robot, seed: int, reach: float) -> None:
    q0, path = _line(ur5e, seed, reach)
    check(ur5e, ur5e.chain.follow(path, q0), path)


# --- the FR3: seven joints, chain.ik from the sample before --------------------------------------


def test_fr3_line(fr3: Robot) -> None:
    chain = fr3.chain
    q0 = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
    T0 = chain.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.1, 0.2, -0.1]

    def path(s: np.ndarray) -> np.ndarray:
        return line_path(T0, T1, s)

    result = chain.follow(path, q0)
    assert result.reason == "done" and result.branch is None
    check(fr3, result, path)


def test_fr3_out_of_reach(fr3: Robot) -> None:
    chain = fr3.chain
    q0 = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
    T0 = chain.fk(q0)
    T1 = T0.copy()
    T1[1, 3] += 2.0

    def path(s: np.ndarray) -> np.ndarray:
        return line_path(T0, T1, s)

    result = chain.follow(path, q0)
    assert result.reason == "unreachable"
    check(fr3, result, path)


def test_fr3_joint_limit(fr3: Robot) -> None:
    """Joints 1, 3, 5 and 7 held near their starts: joint 1 alone turns the arm about the base,
    until its (narrowed) limit."""
    limits = np.array(fr3.chain.limits)
    for k in (0, 2, 4, 6):
        limits[k] = [-0.2, 0.2] if k != 6 else [0.5, 0.9]
    narrow = Robot(dataclasses.replace(fr3.chain, limits=limits), fr3.model)
    qa = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
    qb = qa.copy()
    qb[0] = 0.6
    T = fr3.chain.fk(np.array([qa, qb]))
    result = narrow.chain.follow(T, qa)
    assert result.reason == "joint_limit", result.detail
    check(narrow, result, lambda s: screw_path(T[0], T[1], s))


@pytest.mark.parametrize("seed", range(6))
def test_fr3_random_lines(fr3: Robot, seed: int) -> None:
    q0, path = _line(fr3, seed, reach=1.0 if seed % 2 else 0.2)
    check(fr3, fr3.chain.follow(path, q0), path)


@pytest.mark.slow
@pytest.mark.parametrize(("robot_name", "lines"), [("ur5e", 500), ("fr3", 250)])
def test_1000_random_lines(robot_name: str, lines: int, request: pytest.FixtureRequest) -> None:
    """The issue's goal: 1,000 random straight lines per arm, half between the poses of two
    random configurations, half a fifth of the way: the deviation bound always met, no flip,
    every stop confirmed. The 1,000 of each (the FR3's numerical solve a line at a time: 77 s)
    ran by hand on 2026-12-02, every one met; CI runs the first 500 and 250, within its time."""
    robot: Robot = request.getfixturevalue(robot_name)
    reasons: dict[str, int] = {}
    for seed in range(lines):
        q0, path = _line(robot, 10_000 + seed, reach=1.0 if seed % 2 else 0.2)
        result = robot.chain.follow(path, q0)
        check(robot, result, path)
        reasons[result.reason] = reasons.get(result.reason, 0) + 1
    assert reasons.get("done", 0) > lines // 10, reasons


# --- the result, and bad input -------------------------------------------------------------------


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
def test_the_docstring_example_runs() -> None:
    runner = doctest.DocTestRunner()
    for test in doctest.DocTestFinder().find(
        poekin.Chain.follow, globs={"poekin": poekin, "np": np}
    ):
        runner.run(test)
    assert runner.failures == 0 and runner.tries >= 6


def test_the_result_is_read_only(ur5e: Robot) -> None:
    q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    T = ur5e.chain.fk(np.array([q0, q0 + 0.01]))
    result = ur5e.chain.follow(T, q0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.reason = "jump"  # type: ignore[misc]
    for a in (result.q, result.s, result.T):
        assert not a.flags.writeable


Q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
NAN_POSES = np.full((2, 4, 4), np.nan)
REFLECTION = np.diag([1.0, 1.0, -1.0, 1.0])

# (what the call changes: T_path as a function of the two good poses, or other arguments;
# the message's start)
BAD: dict[str, tuple[dict[str, object], str]] = {
    "one pose": ({"T_path": lambda T: T[0]}, "follow: T_path must be at least 2 poses (N, 4, 4)"),
    "one sample": ({"T_path": lambda T: T[:1]}, "follow: T_path must be at least 2 poses"),
    "text": ({"T_path": lambda T: "line"}, "follow: T_path must be poses (N, 4, 4) or a callable"),
    "NaN": ({"T_path": lambda T: np.stack([T[0], NAN_POSES[0]])}, "follow: T_path[1] has NaN"),
    "reflection": (
        {"T_path": lambda T: np.stack([T[0], T[1] @ REFLECTION])},
        "follow: T_path[1] is not a rigid transform",
    ),
    "short q0": ({"q0": Q0[:5]}, "follow: q0 must be 6 joint values (shape (6,))"),
    "text q0": ({"q0": "home"}, "follow: q0 must be 6 joint values"),
    "NaN q0": ({"q0": [np.nan] * 6}, "follow: q0 has NaN or inf entries"),
    "q0 beyond": (
        {"q0": Q0 + np.array([0, 0, 5, 0, 0, 0])},
        "follow: q0 is outside the joint limits: 'elbow_joint' = 6.4",
    ),
    "q0 off the path": ({"q0": Q0 + 0.01}, "follow: q0 puts the end frame"),
    "zero step": ({"max_step": 0}, "follow: max_step must be a number > 0 (rad), got 0"),
    "negative step": ({"max_step": -1.0}, "follow: max_step must be a number > 0 (rad), got -1.0"),
    "NaN tol": ({"tol": float("nan")}, "follow: tol must be a number > 0 (m), got nan"),
    "text ori_tol": ({"ori_tol": "1e-3"}, "follow: ori_tol must be a number > 0 (rad)"),
    "samples of an array": ({"samples": 5}, "follow: samples is for a callable path"),
    "one sample of a function": (
        {"T_path": lambda T: lambda s: T, "samples": 1},
        "follow: samples must be an integer >= 2",
    ),
    "function of the wrong shape": (
        {"T_path": lambda T: lambda s: T[0]},
        "follow: the path function must return poses (..., 4, 4) in the shape of s",
    ),
    "function of a float": (
        {"T_path": lambda T: lambda s: T[0] * float(s)},
        "follow: the path function failed on s of shape (11,)",
    ),
    "function of bad poses": (
        {"T_path": lambda T: lambda s: line_path(T[0], T[1][:3], s)},
        "line_path: T1 must be poses (..., 4, 4)",
    ),
    "function of NaN": (
        {"T_path": lambda T: lambda s: np.full((len(s), 4, 4), np.nan)},
        "follow: the path function's pose at s = 0 has NaN",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_one_clear_line(ur5e: Robot, case: str) -> None:
    changes, message = BAD[case]
    T = ur5e.chain.fk(np.array([Q0, Q0 + 0.1]))
    kwargs: dict[str, object] = {"T_path": T, "q0": Q0, **changes}
    if "T_path" in changes:
        kwargs["T_path"] = changes["T_path"](T)  # type: ignore[operator]
    with pytest.raises(InputError) as info:
        ur5e.chain.follow(**kwargs)  # type: ignore[arg-type]
    text = str(info.value)
    assert text.startswith(message), text
    assert "\n" not in text
