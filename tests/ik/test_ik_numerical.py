"""Numerical IK (poekin.ik.numerical, Chain.ik): every shared arm's answers checked by MuJoCo's
mj_forward and the joint limits, never by the solver's own residual; the compiled kernel against
the NumPy reference, bit for bit; determinism; branches; unreachable targets; bad input."""

from __future__ import annotations

import functools
import math
import pickle
import warnings
from typing import Any

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_frame_pose
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin.chain import Chain
from poekin.ik import numerical
from poekin.ik._angles import within_limits, wrap_into_limits
from poekin.kernel import _fast

# every arm of the shared Menagerie, with its end frame
ARMS = {
    "ur5e": ("universal_robots_ur5e", None),
    "ur10e": ("universal_robots_ur10e", None),
    "fr3": ("franka_fr3", None),
    "panda": ("franka_emika_panda", "hand"),
    "sawyer": ("rethink_robotics_sawyer", None),
    "lite6": ("ufactory_lite6", None),
}
# joint values that make the Jacobian singular (found from its smallest singular value, < 1e-16
# at random values of the other joints): the wrist (axes 4 and 6 aligned) and the stretched elbow
SINGULAR = {"ur5e": {4: 0.0, 2: 0.0}, "ur10e": {4: 0.0, 2: 0.0}, "lite6": {4: 0.0}}
TOL = 1e-10  # the default tolerances


@functools.cache
def arm(name: str) -> tuple[Any, Chain]:
    robot, frame = ARMS[name]
    loaded = load_quiet(robot)
    return loaded, poekin.load(loaded, frame)


def mj_poses(loaded: Any, chain: Chain, q: np.ndarray) -> np.ndarray:
    """``(N, 4, 4)`` poses of the chain's frame from mj_forward, with ``q`` written into qpos
    (the other joints at the model's qpos0)."""
    model = loaded.model
    data = mujoco.MjData(model)
    fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, chain.frame)
    kind = "site" if fid >= 0 else "body"
    if fid < 0:
        fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, chain.frame)
    assert chain.qpos_indices is not None
    out = np.empty((len(q), 4, 4))
    for k, row in enumerate(np.asarray(q).reshape(-1, chain.n_joints)):
        data.qpos[:] = model.qpos0
        data.qpos[list(chain.qpos_indices)] = row
        mujoco.mj_forward(model, data)
        out[k] = mj_frame_pose(model, data, kind, fid)
    return out


def uniform_q(chain: Chain, n: int, seed: int) -> np.ndarray:
    """``(n, joints)`` configurations uniform within the limits."""
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    return np.random.default_rng(seed).uniform(lo, hi, (n, chain.n_joints))


def check_by_mujoco(
    loaded: Any,
    chain: Chain,
    T: np.ndarray,
    found: numerical.IKResult,
    *,
    position_only: bool = False,
) -> None:
    """Every answer within the limits; every success within the tolerances by MuJoCo's FK; the
    reported errors equal to MuJoCo's (to its rounding)."""
    q = found.q.reshape(-1, chain.n_joints)
    assert within_limits(q, chain.limits).all(), "an answer outside the joint limits"
    T_mj = mj_poses(loaded, chain, q)
    pos, ori = poekin.pose_errors(T.reshape(-1, 4, 4), T_mj)
    ok = found.success.reshape(-1)
    assert np.all(pos[ok] <= TOL + MJ_TOL), f"position error {pos[ok].max():.2e} by MuJoCo"
    if not position_only:
        assert np.all(ori[ok] <= TOL + MJ_TOL), f"orientation error {ori[ok].max():.2e}"
    np.testing.assert_allclose(found.pos_err.reshape(-1), pos, rtol=1e-6, atol=MJ_TOL)
    np.testing.assert_allclose(found.ori_err.reshape(-1), ori, rtol=1e-6, atol=MJ_TOL)


# --- every arm ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ARMS)
def test_random_targets_are_solved_within_the_limits(name: str) -> None:
    loaded, chain = arm(name)
    q_true = uniform_q(chain, 100, seed=1)
    T = mj_poses(loaded, chain, q_true)  # the targets from MuJoCo, not from poekin
    found = chain.ik(T)
    assert found.success.all(), f"{(~found.success).sum()} of 100 not solved"
    check_by_mujoco(loaded, chain, T, found)


@pytest.mark.parametrize("name", ARMS)
def test_targets_near_the_limits_are_solved(name: str) -> None:
    """Half the joints at a limit or 1e-6 inside it."""
    loaded, chain = arm(name)
    rng = np.random.default_rng(2)
    q = uniform_q(chain, 60, seed=2)
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    at = rng.random(q.shape) < 0.5
    edge = np.where(rng.random(q.shape) < 0.5, lo, hi) + np.where(
        rng.random(q.shape) < 0.5, 0.0, 1e-6
    ) * np.where(rng.random(q.shape) < 0.5, 1, -1)
    q = np.where(at, np.clip(edge, lo, hi), q)
    T = mj_poses(loaded, chain, q)
    found = chain.ik(T)
    assert found.success.mean() >= 0.98, f"{found.success.mean():.3f} solved near the limits"
    check_by_mujoco(loaded, chain, T, found)


@pytest.mark.parametrize("name", sorted(SINGULAR))
@pytest.mark.parametrize("offset", [0.0, 1e-7, 1e-4])
def test_near_singular_targets_are_solved(name: str, offset: float) -> None:
    loaded, chain = arm(name)
    q = uniform_q(chain, 40, seed=3)
    for joint, value in SINGULAR[name].items():
        q[:20, joint] = value + offset  # one of them, then both
    q[20:, 4] = SINGULAR[name][4] + offset
    T = mj_poses(loaded, chain, q)
    found = chain.ik(T)
    assert np.all(np.isfinite(found.q))
    assert found.success.all(), f"{(~found.success).sum()} near-singular targets not solved"
    check_by_mujoco(loaded, chain, T, found)


@pytest.mark.parametrize("name", ["ur5e", "panda"])
def test_unreachable_targets_fail_with_the_best_fit_inside_the_limits(name: str) -> None:
    loaded, chain = arm(name)
    q = uniform_q(chain, 12, seed=4)
    T = mj_poses(loaded, chain, q)
    T[:, :3, 3] *= 2.5 / np.linalg.norm(T[:, :3, 3], axis=-1, keepdims=True)  # beyond reach
    found = chain.ik(T)
    assert not found.success.any(), "a false success"
    assert np.all(found.attempts == 100)
    check_by_mujoco(loaded, chain, T, found)
    # the least-squares best over 100 attempts: no worse than the best of 100 random
    # configurations (the cost the solver minimises: |e_p|^2 + (k 2 sin(theta/2))^2)
    k = numerical.DEFAULT_ORIENTATION_WEIGHT
    cost = found.pos_err**2 + (k * 2 * np.sin(found.ori_err / 2)) ** 2
    sample = chain.fk(uniform_q(chain, 100, seed=5))
    for i in range(len(T)):
        pos, ori = poekin.pose_errors(np.broadcast_to(T[i], sample.shape), sample)
        assert cost[i] <= np.min(pos**2 + (k * 2 * np.sin(ori / 2)) ** 2)


def test_a_pose_no_orientation_reaches_fails_without_a_false_success(ur5e: Chain) -> None:
    """Reachable position, but a rotation the UR5e cannot have there (a shoulder-height target
    facing the base from inside the base column)."""
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.163]  # on the base axis, inside the first link
    found = ur5e.ik(T, max_attempts=5)
    assert not found.success
    assert within_limits(found.q, ur5e.limits)


def test_position_only_reaches_the_point_whatever_the_orientation() -> None:
    loaded, chain = arm("ur5e")
    q = uniform_q(chain, 50, seed=6)
    T = mj_poses(loaded, chain, q)
    T[:, :3, :3] = np.eye(3)  # an orientation the solve must ignore
    found = chain.ik(T, position_only=True)
    assert found.success.all()
    check_by_mujoco(loaded, chain, T, found, position_only=True)
    assert found.ori_err.max() > 1e-3  # the orientation was not met, and that is fine


def test_position_only_for_a_five_joint_arm() -> None:
    loaded = load_quiet("trs_so_arm100")
    chain = poekin.load(loaded, "Fixed_Jaw")
    assert chain.n_joints == 5
    q = uniform_q(chain, 40, seed=7)
    T = mj_poses(loaded, chain, q)
    found = chain.ik(T, position_only=True)
    assert found.success.all()
    check_by_mujoco(loaded, chain, T, found, position_only=True)


# --- branches and starts -----------------------------------------------------------------------


def test_q0_keeps_a_trajectory_on_its_branch(ur5e: Chain) -> None:
    """Small steps along a path of targets, each solved from the last answer, give small steps
    in q, on the generating branch (an elbow-up UR5e path through many solutions)."""
    t = np.linspace(0.0, 1.0, 60)[:, None]
    q_path = np.array([0.2, -1.3, 1.5, -1.0, 1.2, 0.3]) + t * np.array(
        [1.5, 0.4, -0.6, 0.8, -0.5, 2.0]
    )
    T = ur5e.fk(q_path)
    q = q_path[0]
    answers = []
    for k in range(len(T)):
        found = ur5e.ik(T[k], q)
        assert found.success
        answers.append(found.q)
        q = found.q
    answers = np.array(answers)
    assert np.abs(np.diff(answers, axis=0)).max() < 0.1
    np.testing.assert_allclose(answers, q_path, atol=1e-7)


def test_q0_outside_the_limits_is_brought_inside(ur5e: Chain) -> None:
    q = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    start = q + np.array([4 * np.pi, -4 * np.pi, 0.0, 2 * np.pi, 0.0, 0.0])  # whole turns out
    with pytest.warns(poekin.JointLimitsWarning, match="q0 is outside the joint limits"):
        found = ur5e.ik(ur5e.fk(q), start)
    assert found.success and found.attempts == 1
    assert within_limits(found.q, ur5e.limits)


@pytest.mark.parametrize("kernel", [True, False])
def test_q0_far_outside_the_limits_is_named_in_python(
    ur5e: Chain, kernel: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue #26: the shell notes a start outside the limits, Python said nothing. Degrees
    read as radians: a JointLimitsWarning names each joint outside, its value and limits, at
    the caller's line, with the kernel and without; a start inside warns of nothing."""
    if not kernel:
        monkeypatch.setattr(_fast, "_kernel", None)
    chain = Chain(ur5e.joint_names, ur5e.joint_types, ur5e.screws, ur5e.home, ur5e.limits)
    q = np.array([0.3, -1.2, 1.4, -0.5, 0.05, 0.02])
    T = chain.fk(q)
    with pytest.warns(poekin.JointLimitsWarning) as said:
        chain.ik(T, np.degrees(q))
    assert len(said) == 1 and said[0].filename == __file__
    message = str(said[0].message)
    assert message.startswith(
        "q0 is outside the joint limits: 'shoulder_pan_joint' = 17.1887 rad, not in "
        "[-6.28319, 6.28319]; 'shoulder_lift_joint' = -68.7549 rad, not in [-6.28319, 6.28319]; "
        "'elbow_joint' = 80.2141 rad, not in [-3.1415, 3.1415]; 'wrist_1_joint' = -28.6479 rad"
    ), message
    assert "wrist_2_joint" not in message  # 2.86 rad is inside
    with pytest.warns(poekin.JointLimitsWarning, match=r"2 of 3 configurations are outside"):
        chain.ik(np.stack([T] * 3), np.stack([q, np.degrees(q), np.degrees(q)]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert chain.ik(T, q + 0.01).success
        assert chain.ik(np.stack([T] * 3), np.stack([q] * 3)).success.all()


def test_unlimited_joints_come_back_in_minus_pi_pi(ur5e: Chain) -> None:
    chain = Chain(ur5e.joint_names, ur5e.joint_types, ur5e.screws, ur5e.home)  # no limits
    q = np.random.default_rng(8).uniform(-3, 3, (50, 6))
    found = chain.ik(chain.fk(q), q + 20.0)  # starts many turns away
    assert found.success.all()
    assert np.all((found.q > -np.pi) & (found.q <= np.pi))
    wrapped = wrap_into_limits(found.q, chain.limits, np.ones(6, bool))  # a no-op, to rounding
    np.testing.assert_allclose(found.q, wrapped, rtol=0.0, atol=1e-15)


# --- the kernel against the reference; determinism -------------------------------------------


def reference(
    chain: Chain, T: np.ndarray, q0: np.ndarray | None = None, seed: int = 0, **options: Any
) -> tuple:
    s = numerical.settings(**options)
    return numerical.solve_reference(chain, T, q0, seed, s)


def fields(found: numerical.IKResult) -> tuple:
    return (found.q, found.success, found.pos_err, found.ori_err, found.iterations, found.attempts)


def assert_same_bits(a: tuple, b: tuple, what: str) -> None:
    names = ("q", "success", "pos_err", "ori_err", "iterations", "attempts")
    for name, x, y in zip(names, a, b, strict=True):
        x, y = np.atleast_1d(x), np.atleast_1d(y)
        assert x.shape == y.shape and x.dtype == y.dtype, f"{what}: {name} shape or dtype"
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), f"{what}: {name} differs"


@pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")
@pytest.mark.filterwarnings("ignore::poekin.JointLimitsWarning")  # starts far outside, on purpose
@pytest.mark.parametrize("name", ARMS)
def test_the_kernel_gives_the_reference_bits(name: str) -> None:
    _, chain = arm(name)
    rng = np.random.default_rng(9)
    q = uniform_q(chain, 12, seed=9)
    T = chain.fk(q)
    T[-2:, :3, 3] *= 2.5 / np.linalg.norm(T[-2:, :3, 3], axis=-1, keepdims=True)  # unreachable
    options = {"max_attempts": 4}
    cases = [
        ("random starts", T, None, options),
        ("q0", T, q + rng.normal(0.0, 0.5, q.shape), options),
        ("position only", T, None, {**options, "position_only": True}),
    ]
    for what, targets, q0, opts in cases:
        ours = fields(chain.ik(targets, q0, seed=3, **opts))
        assert_same_bits(ours, reference(chain, targets, q0, seed=3, **opts), f"{name} {what}")


@pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")
@pytest.mark.parametrize("n_targets", [1, 2, 3])
def test_a_few_targets_attempts_side_by_side_give_the_reference_bits(
    ur5e: Chain, n_targets: int
) -> None:
    """Fewer targets than lanes run a target's attempts side by side, in rounds; with q0 the
    first round is attempt 0 alone (_ik_core.h). Starts far from the answer and targets out of
    reach make later rounds run, and every attempt fail; each attempt count ends a round at
    another place."""
    rng = np.random.default_rng(21)
    q = uniform_q(ur5e, 3 * n_targets, seed=21)
    T = ur5e.fk(q)
    T[::3, :3, 3] *= 2.0 / np.linalg.norm(T[::3, :3, 3], axis=-1, keepdims=True)  # unreachable
    lo, hi = ur5e.limits[:, 0], ur5e.limits[:, 1]
    far = np.clip(q + rng.normal(0.0, 1.5, q.shape), lo, hi)
    for attempts in (1, 2, 3, 5, 8):
        for rows in (slice(k, k + n_targets) for k in range(0, len(T), n_targets)):
            for q0 in (None, far[rows]):
                what = f"{n_targets} targets, {attempts} attempts, q0: {q0 is not None}"
                ours = fields(ur5e.ik(T[rows], q0, seed=5, max_attempts=attempts))
                theirs = reference(ur5e, T[rows], q0, seed=5, max_attempts=attempts)
                assert_same_bits(ours, theirs, what)


@pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")
@pytest.mark.filterwarnings("ignore::poekin.JointLimitsWarning")  # starts far outside, on purpose
def test_the_kernel_gives_the_reference_bits_for_unlimited_and_prismatic_joints() -> None:
    """Cyclic joints wrapped from far away (numpy.mod's arithmetic in C), a prismatic joint
    with and without limits, a tilted (non coordinate) axis and a pitched screw."""
    rng = np.random.default_rng(10)
    w = np.array(
        [[0, 0, 1], [0, 1, 0], [0.6, 0.0, 0.8], [0, 0, 0], [1, 0, 0], [0, 0, 1], [0, 0, 0]], float
    )
    points = rng.normal(0.0, 0.3, (7, 3))
    v = -np.cross(w, points)
    v[3] = [0.0, 0.0, 1.0]  # prismatic
    v[6] = [1.0, 0.0, 0.0]
    v[5] += 0.05 * w[5]  # pitch
    types = ("revolute", "revolute", "revolute", "prismatic", "revolute", "revolute", "prismatic")
    limits = np.array(
        [
            [-np.inf, np.inf],
            [-2, 2],
            [-np.inf, np.inf],
            [-0.3, 0.4],
            [-1, 5],
            [-np.inf, np.inf],
            [-np.inf, np.inf],
        ]
    )
    home = np.eye(4)
    home[:3, 3] = [0.4, 0.1, 0.5]
    chain = Chain(tuple(f"j{k}" for k in range(7)), types, np.hstack([w, v]), home, limits)
    q = np.clip(rng.uniform(-3, 3, (30, 7)), limits[:, 0], limits[:, 1])
    T = chain.fk(q)
    q0 = q + rng.uniform(-40.0, 40.0, q.shape)
    for q_start in (None, q0):
        ours = fields(chain.ik(T, q_start, max_attempts=3))
        assert_same_bits(
            ours, reference(chain, T, q_start, max_attempts=3), f"q0 given: {q_start is not None}"
        )


def test_without_the_kernel_the_reference_answers(
    ur5e: Chain, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An installation without a C compiler: the same bits from the NumPy reference."""
    T = ur5e.fk(uniform_q(ur5e, 10, seed=11)).reshape(2, 5, 4, 4)
    expected = fields(ur5e.ik(T))
    monkeypatch.setattr(_fast, "_kernel", None)
    chain = Chain(ur5e.joint_names, ur5e.joint_types, ur5e.screws, ur5e.home, ur5e.limits)
    assert_same_bits(fields(chain.ik(T)), expected, "the NumPy path")
    assert chain._ik_cache["kernel"] is None


def test_a_target_gets_the_same_bits_alone_in_any_batch_and_position(ur5e: Chain) -> None:
    T = ur5e.fk(uniform_q(ur5e, 40, seed=12))
    batch = fields(ur5e.ik(T))
    order = np.random.default_rng(12).permutation(40)
    shuffled = fields(ur5e.ik(T[order]))
    for i in (0, 7, 39):
        alone = fields(ur5e.ik(T[i]))
        assert_same_bits(alone, tuple(f[i] for f in batch), f"target {i} alone")
        j = int(np.flatnonzero(order == i)[0])
        assert_same_bits(tuple(f[j] for f in shuffled), alone, f"target {i} shuffled")
    assert_same_bits(fields(ur5e.ik(T)), batch, "a repeated run")


def unaligned(a: np.ndarray) -> np.ndarray:
    """A copy of ``a`` in a buffer at an odd offset, as Dask's workers and ``np.frombuffer``
    hand arrays out: C-contiguous float64, but not aligned."""
    out = np.ndarray(a.shape, np.float64, buffer=np.zeros(a.nbytes + 1, np.uint8), offset=1)
    out[...] = a
    assert out.flags.c_contiguous and not out.flags.aligned
    return out


def test_unaligned_arrays_give_the_same_bits(ur5e: Chain) -> None:
    """The kernel reads aligned arrays only: unaligned targets, q0 and qpos are copied first,
    not refused (a Dask result used to fail an assertion)."""
    q = uniform_q(ur5e, 20, seed=15)
    T = ur5e.fk(q)
    expected = fields(ur5e.ik(T, q[::-1]))
    assert_same_bits(fields(ur5e.ik(unaligned(T), unaligned(q[::-1]))), expected, "unaligned")
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    got = tree.ik(unaligned(T), ur5e.frame, unaligned(q[::-1]), warm_start=True)
    assert_same_bits(fields(got), expected, "unaligned, Tree.ik")


def test_the_seed_changes_the_starts_not_the_success(ur5e: Chain) -> None:
    T = ur5e.fk(uniform_q(ur5e, 30, seed=13))
    a, b = ur5e.ik(T, seed=1), ur5e.ik(T, seed=2)
    assert a.success.all() and b.success.all()
    assert not np.array_equal(a.iterations, b.iterations)


@pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")
def test_thread_counts_and_vector_widths_give_the_same_bits() -> None:
    _, chain = arm("panda")
    T = chain.fk(uniform_q(chain, 300, seed=14))  # enough targets for two threads
    before = poekin.get_threads()
    results = []
    try:
        for threads in (1, 2):
            poekin.set_threads(threads)
            results.append(fields(chain.ik(T, max_attempts=5)))
        best = _fast._kernel.set_width(0)
        for width in (w for w in (2, 4, 8) if w <= best):
            _fast._kernel.set_width(width)
            results.append(fields(chain.ik(T[:50], max_attempts=5)))
    finally:
        poekin.set_threads(before)
        _fast._kernel.set_width(_fast.DEFAULT_WIDTH)
    assert_same_bits(results[1], results[0], "two threads")
    for r in results[2:]:
        assert_same_bits(r, tuple(f[:50] for f in results[0]), "another vector width")


# --- shapes ------------------------------------------------------------------------------------


@pytest.mark.parametrize("batch", [(), (1,), (3, 1, 2)])
def test_batch_shapes(ur5e: Chain, batch: tuple[int, ...]) -> None:
    q = uniform_q(ur5e, int(np.prod(batch)), seed=15).reshape(*batch, 6)
    found = ur5e.ik(ur5e.fk(q))
    assert found.q.shape == (*batch, 6)
    for f in (found.success, found.pos_err, found.ori_err, found.iterations, found.attempts):
        assert f.shape == batch
    assert found.success.dtype == bool and found.iterations.dtype == np.int64
    assert found.success.all()


def test_q0_broadcasts_against_the_targets(ur5e: Chain) -> None:
    q = uniform_q(ur5e, 6, seed=16).reshape(3, 2, 6)
    T = ur5e.fk(q)
    start = np.zeros(6)
    found = ur5e.ik(T, start)
    assert found.q.shape == (3, 2, 6) and found.success.all()
    one = ur5e.ik(T[0, 0], np.zeros((4, 6)))  # one target from four (equal) starts
    assert one.q.shape == (4, 6) and np.array_equal(one.q[0], one.q[3])


def test_results_are_immutable_and_chains_still_pickle(ur5e: Chain) -> None:
    T = ur5e.fk(uniform_q(ur5e, 3, seed=17))
    found = ur5e.ik(T)
    with pytest.raises(AttributeError):
        found.q = found.q  # type: ignore[misc]
    clone = pickle.loads(pickle.dumps(ur5e))  # its IK solver too
    assert_same_bits(fields(clone.ik(T)), fields(found), "the unpickled chain")


# --- bad input ---------------------------------------------------------------------------------


def _not_rigid() -> np.ndarray:
    T = np.eye(4)
    T[0, 0] = 1.1
    return T


def _mirror() -> np.ndarray:
    T = np.eye(4)
    T[2, 2] = -1.0
    return T


def _last_row() -> np.ndarray:
    T = np.eye(4)
    T[3, 0] = 0.5
    return T


@pytest.mark.parametrize(
    ("T", "kwargs", "message"),
    [
        (np.eye(3), {}, r"shape \(\.\.\., 4, 4\)"),
        (np.full((4, 4), np.nan), {}, "NaN or inf"),
        ("pose", {}, "must be numbers"),
        (_not_rigid(), {}, "not a rigid transform: its rotation"),
        (_mirror(), {}, "det \\+1"),
        (_last_row(), {}, r"last row is not \[0, 0, 0, 1\]"),
        (np.eye(4), {"q0": np.zeros(5)}, r"expected 6 q0 values"),
        (np.eye(4), {"q0": [0, 0, 0, 0, 0, np.nan]}, "NaN or inf"),
        (np.stack([np.eye(4)] * 3), {"q0": np.zeros((2, 6))}, "does not broadcast"),
        (np.eye(4), {"pos_tol": 0.0}, r"pos_tol must be a finite number > 0 \(m\)"),
        (np.eye(4), {"ori_tol": -1e-3}, r"ori_tol must be a finite number > 0 \(rad\)"),
        (np.eye(4), {"ori_tol": "1e-6"}, "ori_tol must be a number"),
        (np.eye(4), {"pos_tol": [1e-6]}, "pos_tol must be a number"),
        (np.eye(4), {"orientation_weight": np.inf}, "orientation_weight must be a finite"),
        (np.eye(4), {"max_attempts": 0}, "max_attempts must be an integer from 1"),
        (np.eye(4), {"max_iterations": 2.5}, "max_iterations must be an integer"),
        (np.eye(4), {"position_only": "yes"}, "position_only must be True or False"),
        (np.eye(4), {"seed": -1}, "seed must be an integer from 0 to 2\\*\\*64 - 1"),
        (np.eye(4), {"seed": 1.5}, "seed must be an integer"),
    ],
)
def test_bad_input_is_one_clear_input_error(
    ur5e: Chain, T: Any, kwargs: dict, message: str
) -> None:
    with pytest.raises(poekin.InputError, match=message) as info:
        ur5e.ik(T, **kwargs)
    assert "\n" not in str(info.value)


def test_a_bad_target_in_a_batch_is_named_by_its_index(ur5e: Chain) -> None:
    T = np.stack([np.eye(4)] * 4).reshape(2, 2, 4, 4)
    T[1, 0, 0, 0] = 2.0
    with pytest.raises(poekin.InputError, match=r"target at index \(1, 0\)"):
        ur5e.ik(T)


def test_a_chain_without_joints_is_refused() -> None:
    chain = Chain((), (), np.zeros((0, 6)), np.eye(4))
    with pytest.raises(poekin.InputError, match="no joints"):
        chain.ik(np.eye(4))


@pytest.mark.parametrize(
    "call",
    [
        "chain.ik",
        "chain.ik_all",
        "chain.ik q0",
        "tree.ik",
        "calibrate measured",
        "list of complex",
    ],
)
def test_complex_targets_are_refused_not_cast(ur5e: Chain, go2: poekin.Tree, call: str) -> None:
    """Issue #26: complex targets were cast to their real part with only NumPy's
    ComplexWarning. Every public entry that takes arrays refuses them with a named InputError
    (one conversion, chain.real_array), and warns of nothing first."""
    from poekin.calibration import check_measurements

    T = ur5e.fk(np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])) + 0j
    calls = {
        "chain.ik": lambda: ur5e.ik(T),
        "chain.ik_all": lambda: ur5e.ik_all(T),
        "chain.ik q0": lambda: ur5e.ik(T.real, np.zeros(6) + 1e-9j),
        "tree.ik": lambda: go2.ik(T, "FL_calf"),
        "calibrate measured": lambda: check_measurements(np.stack([T] * 2), 2),
        "list of complex": lambda: ur5e.ik(T.tolist()),
    }
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(poekin.InputError, match="must be real numbers, got complex") as info:
            calls[call]()
    assert "pass their real part (numpy.real)" in str(info.value)


def test_an_empty_batch_gives_empty_answers_without_a_warning(ur5e: Chain) -> None:
    """Issue #26: no targets, no answers: arrays of the batch shape (0,), and no warning (the
    command line refuses an --input without rows instead)."""
    T = np.zeros((0, 4, 4))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = ur5e.ik(T)
        found_q0 = ur5e.ik(T, np.zeros((0, 6)))
        every = ur5e.ik_all(T)
    for got in (found, found_q0):
        assert got.q.shape == (0, 6) and got.q.dtype == np.float64
        for field in (got.success, got.pos_err, got.ori_err, got.iterations, got.attempts):
            assert field.shape == (0,)
    assert every.q.shape == (0, 8, 6) and every.valid.shape == (0, 8)


# --- targets of every magnitude (issue 26) ----------------------------------------------------

# positions from 1e-300 m to 1e308 m, signed zeros and subnormals among them (the distance of a
# target whose entries are near the largest float, 1.8e308, overflows: its error is inf)
MAGNITUDES = [0.0, -0.0, 5e-324, -2.2e-308, 1e-300, 1e-150, 1e-20, 0.3, 1.0, 1e3, 1e6]
MAGNITUDES += [1.0000001e6, 1e20, 1e154, 1e155, 1e200, 1e300, -1e300, 1e308]


def _magnitude_targets(values: list[float], seed: int) -> np.ndarray:
    """One target per value: a random rotation, the position (value, -value / 2, value) with
    one axis zero or signed zero at random."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(len(values), 4))
    T = np.tile(np.eye(4), (len(values), 1, 1))
    T[:, :3, :3] = poekin.quat_to_rotation(quat / np.linalg.norm(quat, axis=-1, keepdims=True))
    for k, v in enumerate(values):
        p = np.array([v, -v / 2, v])
        p[rng.integers(3)] = rng.choice([0.0, -0.0])
        T[k, :3, 3] = p
    return T


def _true_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``|a - b|`` row by row by :func:`math.hypot`, which does not overflow."""
    return np.array([math.hypot(*(x - y)) for x, y in zip(a, b, strict=True)])


@pytest.mark.parametrize("name", ["ur5e", "panda"])
def test_targets_of_every_magnitude_give_limited_deterministic_answers(name: str) -> None:
    """A target of any finite position, 1e-300 m to 1e308 m (a cost that squares to inf), gives
    a finite q inside the limits, the same for identical targets, the same bits in the kernel
    and the reference, success only within the tolerances by MuJoCo, and its true error."""
    loaded, chain = arm(name)
    T = _magnitude_targets(MAGNITUDES, seed=3)
    k = MAGNITUDES.index(1e300)
    T = np.concatenate([T, np.repeat(T[k : k + 1], 4, axis=0)])  # four more of the 1e300 one
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no overflow on the way
        found = chain.ik(T, max_attempts=3)
        ref = reference(chain, T, max_attempts=3)
    if poekin.compiled_kernel():
        assert_same_bits(fields(found), ref, "kernel and reference")
    assert np.isfinite(found.q).all() and within_limits(found.q, chain.limits).all()
    assert np.array_equal(found.q[-4:], np.repeat(found.q[k : k + 1], 4, axis=0))
    far = np.abs(T[:, :3, 3]).max(axis=-1) > 2.0
    assert not found.success[far].any()
    T_mj = mj_poses(loaded, chain, found.q)
    assert np.isfinite(found.pos_err).all()
    np.testing.assert_allclose(
        found.pos_err, _true_distance(T[:, :3, 3], T_mj[:, :3, 3]), rtol=1e-9, atol=MJ_TOL
    )


@pytest.mark.parametrize("name", ["ur5e", "lite6"])
def test_closed_form_of_targets_of_every_magnitude(name: str) -> None:
    """ik_all: every finite target gives finite, limited branches or none, never a warning."""
    _, chain = arm(name)
    T = _magnitude_targets(MAGNITUDES, seed=4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        every = chain.ik_all(T)
    far = np.abs(T[:, :3, 3]).max(axis=-1) > 2.0
    assert not every.valid[far].any()
    assert np.isfinite(every.q[every.valid]).all()
    assert within_limits(every.q[every.valid], chain.limits).all()


@pytest.mark.skipif(not _fast.compiled_kernel(), reason="needs the compiled kernel")
@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_the_kernels_target_check_decides_as_numpys(
    shape: tuple[int, ...], monkeypatch: pytest.MonkeyPatch
) -> None:
    """check_targets' one pass in the kernel (a plain float64 array) accepts exactly what its
    NumPy tests accept: rotations off by 1e-9 to 1e-3 (either side of the 1e-6 bound on R^T R),
    mirrors, last rows off by 1e-14 to 1e-10, NaN, and arrays the kernel does not read."""
    rng = np.random.default_rng(len(shape))
    cases = []
    for scale in (1e-9, 1e-8, 1e-5, 1e-3):
        T = np.array(poekin.exp_se3(rng.normal(size=(*shape, 6))))
        T[..., :3, :3] += scale * rng.normal(size=(*shape, 3, 3))
        cases.append(T)
    mirror = np.array(poekin.exp_se3(rng.normal(size=(*shape, 6))))
    mirror[..., :3, 0] *= -1
    cases.append(mirror)
    for scale in (1e-14, 1e-10):
        T = np.array(poekin.exp_se3(rng.normal(size=(*shape, 6))))
        T[..., 3, 0] += scale
        cases.append(T)
    nan = np.array(poekin.exp_se3(rng.normal(size=(*shape, 6))))
    nan[..., 0, 3] = np.nan
    cases += [nan, np.swapaxes(cases[0], -1, -2), cases[0].astype(np.float32)]

    def decide(T: np.ndarray) -> bool:
        try:
            numerical.check_targets(T)
        except poekin.InputError:
            return False
        return True

    with_kernel = [decide(T) for T in cases]
    monkeypatch.setattr(_fast, "rigid_targets", lambda T: False)
    assert with_kernel == [decide(T) for T in cases]
    assert True in with_kernel and False in with_kernel


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 7),
    shape=st.sampled_from([(), (1,), (3, 1, 2)]),
    damping=st.sampled_from([0.0, 1e-12, 1e-3, 1.0]),
)
def test_the_ldlt_solve_is_numpy_s_solve(
    seed: int, n: int, shape: tuple[int, ...], damping: float
) -> None:
    """The damped normal equations' solve (``L D L^T``) against LAPACK's, over batch shapes:
    the systems ``J^T J + lam I`` of random Jacobians, rank-deficient ones too (two equal
    columns: a pivot at rounding, taken as ``tiny``, where LAPACK's answer is meaningless)."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(*shape, 6, n))
    A = np.swapaxes(J, -1, -2) @ J + (damping + 1e-9) * np.eye(n)
    b = rng.normal(size=(*shape, n))
    rows = [[A[..., i, j] for j in range(n)] for i in range(n)]
    x = np.stack(numerical._cholesky_solve(rows, [b[..., i] for i in range(n)], 1e-300, np), -1)
    expected = np.linalg.solve(A, b[..., None])[..., 0]
    scale = np.linalg.cond(A)[..., None] * np.abs(expected).max(axis=-1, keepdims=True)
    assert np.all(np.abs(x - expected) <= 1e-13 * scale + 1e-300)
    if n >= 2:  # a column repeated: the singular system's pivot is floored, the answer finite
        J[..., 1] = J[..., 0]
        S = np.swapaxes(J, -1, -2) @ J
        rows = [[S[..., i, j] for j in range(n)] for i in range(n)]
        y = numerical._cholesky_solve(rows, [b[..., i] for i in range(n)], 1e-12, np)
        assert all(np.all(np.isfinite(v)) for v in y)
