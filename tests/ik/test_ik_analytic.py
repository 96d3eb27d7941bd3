"""poekin.ik.analytic (``Chain.ik_all``): every closed-form solution, checked by MuJoCo.

Targets are MuJoCo's poses of joint values drawn within the limits. Every solution marked valid
must put MuJoCo's end frame on the target to 1e-12 (m and rad) within the joint limits, every
solution marked invalid must be outside the limits or miss the target, and the drawn joint
values must be among the solutions (to 1e-6 rad: near a singularity an angle moves much more
than the pose it produces, so the exactness is judged on the pose).
"""

from __future__ import annotations

import pathlib

import ik_arms
import mujoco
import numpy as np
import pytest
from ik_arms import Arm
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

import poekin
from poekin.errors import AnalyticIKError, InputError, ModelError
from poekin.ik import analytic
from poekin.ik._angles import within_limits

EXACT = 1e-12  # m and rad: the residual every valid solution must meet, checked by MuJoCo
SAME_Q = 1e-6  # rad: the drawn joint values are among the solutions


@pytest.fixture(scope="session")
def folder(tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    return tmp_path_factory.mktemp("ik_arms")


ARMS = {
    "ur5e": lambda folder: ik_arms.menagerie("ur5e", "universal_robots_ur5e"),
    "ur10e": lambda folder: ik_arms.menagerie("ur10e", "universal_robots_ur10e"),
    "ur5_cb3_dh": lambda folder: ik_arms.from_chain(
        "ur5_cb3_dh", poekin.named_params("ur5-dh").to_chain(), folder
    ),
    "puma560": lambda folder: ik_arms.from_mjcf("puma560", ik_arms.PUMA560_XML, folder),
    "irb120": lambda folder: ik_arms.from_mjcf("irb120", ik_arms.IRB120_XML, folder),
    "lite6": lambda folder: ik_arms.menagerie("lite6", "ufactory_lite6"),
    "roll_shoulder": lambda folder: ik_arms.from_mjcf(
        "roll_shoulder", ik_arms.ROLL_SHOULDER_XML, folder
    ),
}
GEOMETRIES = {
    "ur5e": "three parallel axes (2, 3, 4), axes 5 and 6 meet",
    "ur10e": "three parallel axes (2, 3, 4), axes 5 and 6 meet",
    "ur5_cb3_dh": "three parallel axes (2, 3, 4), axes 5 and 6 meet",
    "puma560": "spherical wrist (axes 4, 5, 6 meet), axes 2 and 3 parallel",
    "irb120": "spherical wrist (axes 4, 5, 6 meet), axes 2 and 3 parallel",
    "lite6": "spherical wrist (axes 4, 5, 6 meet), axes 1 and 2 meet",
    "roll_shoulder": "spherical wrist (axes 4, 5, 6 meet), axes 2 and 3 meet",
}
_built: dict[str, Arm] = {}


def arm_named(name: str, folder: pathlib.Path) -> Arm:
    if name not in _built:
        _built[name] = ARMS[name](folder)
    return _built[name]


@pytest.fixture(params=list(ARMS))
def arm(request: pytest.FixtureRequest, folder: pathlib.Path) -> Arm:
    return arm_named(request.param, folder)


def residuals(arm: Arm, q: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's position and orientation errors of ``(m, 6)`` q against ``(m, 4, 4)`` T."""
    return poekin.pose_errors(T, arm.mujoco_poses(q))


def angle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest joint difference modulo 2 pi."""
    return np.max(np.abs(np.angle(np.exp(1j * (a - b)))), axis=-1)


def check(arm: Arm, T: np.ndarray, q_drawn: np.ndarray | None = None) -> analytic.IKSolutions:
    """Solve ``(m, 4, 4)`` targets and check every claim of the result against MuJoCo."""
    sol = arm.chain.ik_all(T)
    m = len(T)
    assert sol.q.shape == (m, 8, 6) and sol.valid.shape == (m, 8)
    assert np.all(np.isfinite(sol.q))
    flat_q = sol.q.reshape(-1, 6)
    pos, ori = residuals(arm, flat_q, np.repeat(T, 8, axis=0))
    pos, ori = pos.reshape(m, 8), ori.reshape(m, 8)
    inside = within_limits(sol.q, arm.chain.limits)
    valid = sol.valid
    worst = max(pos[valid].max(initial=0.0), ori[valid].max(initial=0.0))
    assert worst <= EXACT, f"{arm.name}: a valid solution misses by {worst:.2e}"
    assert np.all(inside[valid]), "a valid solution is outside the joint limits"
    missed = np.maximum(pos, ori) > 1e-9
    assert np.all(missed[~valid] | ~inside[~valid]), (
        "an exact solution inside the limits is invalid"
    )
    assert np.allclose(sol.pos_err, pos, atol=1e-13) and np.allclose(sol.ori_err, ori, atol=1e-13)
    if q_drawn is not None:
        gap = np.where(valid, angle_gap(sol.q, q_drawn[:, None, :]), np.inf).min(axis=1)
        assert gap.max() <= SAME_Q, f"{arm.name}: drawn q not found, off by {gap.max():.2e}"
    return sol


def test_geometry_is_found_from_the_screws(arm: Arm) -> None:
    geo = analytic.geometry(arm.chain)
    assert geo.description == GEOMETRIES[arm.name]
    assert geo.n_solutions == 8
    assert analytic.geometry(arm.chain) is geo  # found once per chain


def test_random_targets(arm: Arm) -> None:
    q = arm.sample(150, seed=1)
    sol = check(arm, arm.mujoco_poses(q), q)
    assert sol.valid.any(axis=1).all()


def test_branches_are_distinct(folder: pathlib.Path) -> None:
    """No branch repeats another (away from singularities), and an unlimited UR5 reaches all
    eight branches of most targets."""
    arm = arm_named("ur5_cb3_dh", folder)
    q = arm.sample(100, seed=2)
    sol = check(arm, arm.mujoco_poses(q), q)
    for s, v in zip(sol.q, sol.valid, strict=True):
        assert len(np.unique(np.round(s[v], 6), axis=0)) == v.sum()
    assert np.mean(sol.valid.sum(axis=1) == 8) > 0.5


def test_batch_shapes(folder: pathlib.Path) -> None:
    arm = arm_named("ur5e", folder)
    T = arm.mujoco_poses(arm.sample(6, seed=3))
    flat = arm.chain.ik_all(T)
    for shape in [(), (1,), (3, 1, 2)]:
        n = int(np.prod(shape))
        sol = arm.chain.ik_all(T[:n].reshape(*shape, 4, 4))
        assert sol.q.shape == (*shape, 8, 6) and sol.valid.shape == (*shape, 8)
        assert sol.pos_err.shape == (*shape, 8)
        np.testing.assert_array_equal(sol.q.reshape(n, 8, 6), flat.q[:n])
        np.testing.assert_array_equal(sol.valid.reshape(n, 8), flat.valid[:n])


def test_result_is_immutable(folder: pathlib.Path) -> None:
    arm = arm_named("ur5e", folder)
    sol = arm.chain.ik_all(arm.chain.fk(np.zeros(6)))
    with pytest.raises(AttributeError):
        sol.q = sol.q  # type: ignore[misc]


# --- singular and unreachable targets -----------------------------------------------------------


@pytest.mark.parametrize("q5", [0.0, np.pi, 1e-9, -1e-6, np.pi - 1e-8])
@pytest.mark.parametrize("name", ["ur5e", "ur5_cb3_dh"])
def test_ur_wrist_singularity(name: str, q5: float, folder: pathlib.Path) -> None:
    """q5 = 0 or pi puts axis 6 parallel to axes 2 to 4: q2 + q3 + q4 and q6 are coupled, and
    a solution exists for every target (the drawn q is one)."""
    arm = arm_named(name, folder)
    q = arm.sample(40, seed=4)
    q[:, 4] = q5
    sol = check(arm, arm.mujoco_poses(q))
    assert sol.valid.any(axis=1).all()


@pytest.mark.parametrize("q3", [0.0, 1e-9, -1e-7])
@pytest.mark.parametrize("name", ["ur5e", "puma560"])
def test_stretched_elbow(name: str, q3: float, folder: pathlib.Path) -> None:
    arm = arm_named(name, folder)
    q = arm.sample(40, seed=5)
    if name == "puma560":  # stretched: forearm along the upper arm
        q3 = q3 - np.arctan2(0.0203, 0.4318) + np.pi / 2
    q[:, 2] = q3
    sol = check(arm, arm.mujoco_poses(q))
    assert sol.valid.any(axis=1).all()


@pytest.mark.parametrize("name", ["puma560", "irb120", "lite6", "roll_shoulder"])
@pytest.mark.parametrize("q5", [0.0, 1e-10, 1e-7])
def test_spherical_wrist_singularity(name: str, q5: float, folder: pathlib.Path) -> None:
    """q5 = 0 aligns axes 4 and 6 in all four arms: only q4 + q6 (or q4 - q6) is fixed, and
    the singular branches share it evenly, or put it all on q6."""
    arm = arm_named(name, folder)
    q = arm.sample(40, seed=6)
    q[:, 4] = q5
    sol = check(arm, arm.mujoco_poses(q))
    assert sol.valid.any(axis=1).all()
    if q5 == 0.0:  # the branches where the wrist is singular (others may not be)
        # (where the arm's first three joints sit at a double root of their own, q5 comes out
        # ~1e-10 and the wrist is solved as a regular one: exact, without the convention)
        singular = sol.valid & (np.abs(np.sin(sol.q[..., 4])) < 1e-9)
        assert singular.any(axis=1).all()
        q4, q6 = sol.q[..., 3], sol.q[..., 5]
        on6 = singular & (q4 == 0.0)
        even = singular & (np.abs(np.abs(q4) - np.abs(np.angle(np.exp(1j * q6)))) < 1e-12)
        assert np.mean(on6.any(axis=1)) > 0.8 and np.mean((even & ~on6).any(axis=1)) > 0.8


def _axis_point(chain: poekin.Chain, i: int) -> tuple[np.ndarray, np.ndarray]:
    s = chain.screws[i]
    return np.cross(s[:3], s[3:]), s[:3]


def _meet(chain: poekin.Chain, i: int, j: int) -> np.ndarray:
    """Where axes i and j (0-based) meet at q = 0 (least squares)."""
    (a, u), (b, v) = _axis_point(chain, i), _axis_point(chain, j)
    t = np.linalg.lstsq(np.stack([u, -v], axis=1), b - a, rcond=None)[0]
    return a + t[0] * u


def _moved(chain: poekin.Chain, q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Where ``point`` (at q = 0, moving with the end frame) is at ``q``."""
    T = chain.fk(q) @ np.linalg.inv(chain.home)
    return T[:3, :3] @ point + T[:3, 3]


@pytest.mark.parametrize("name", ["ur5e", "irb120", "puma560", "lite6"])
def test_shoulder_singularity(name: str, folder: pathlib.Path) -> None:
    """The wrist point (UR: where axes 5 and 6 meet) as close to axis 1 as the arm lets it:
    on axis 1 (IRB 120: q1 is free, and the solutions have q1 = 0 and pi; the Lite6's, 2e-6 m
    off as its axes 2 and 3 are not quite parallel) or on the cylinder of the shoulder offset
    (UR5e, PUMA: the two q1 roots coincide)."""
    arm = arm_named(name, folder)
    chain = arm.chain
    wrist = _meet(chain, 4, 5) if name == "ur5e" else _meet(chain, 3, 4)
    r1, h1 = _axis_point(chain, 0)
    h2 = chain.screws[1, :3]
    across = np.cross(h1, h2)  # the arm's plane direction at q1 = 0
    rng = np.random.default_rng(7)
    targets, drawn = [], []
    while len(targets) < 6:
        q = arm.sample(1, seed=int(rng.integers(1 << 30)))[0]
        q[0] = 0.0

        def reach(q2: float, q: np.ndarray = q) -> float:
            return float((_moved(chain, np.r_[q[0], q2, q[2:]], wrist) - r1) @ across)

        grid = np.linspace(*np.clip(chain.limits[1], -np.pi, np.pi), 40)
        values = [reach(g) for g in grid]
        change = [k for k in range(39) if values[k] * values[k + 1] < 0]
        if not change:
            continue
        q[1] = brentq(reach, grid[change[0]], grid[change[0] + 1], xtol=1e-15, rtol=1e-15)
        q[0] = rng.uniform(-2.5, 2.5)
        drawn.append(q)
        targets.append(arm.mujoco_poses(q[None])[0])
    sol = check(arm, np.array(targets))
    assert sol.valid.any(axis=1).all()
    if name == "irb120":
        q1 = sol.q[..., 0][sol.valid]
        assert np.all(np.isin(np.round(np.abs(q1), 12), [0.0, round(np.pi, 12)]))


@pytest.mark.parametrize("name", list(ARMS))
def test_unreachable_targets_are_all_invalid(name: str, folder: pathlib.Path) -> None:
    arm = arm_named(name, folder)
    q = arm.sample(20, seed=8)
    T = arm.mujoco_poses(q)
    far = T.copy()
    far[:, :3, 3] *= 10.0  # ten times as far from the base as a reachable pose
    sol = arm.chain.ik_all(far)
    assert not sol.valid.any() and np.all(np.isfinite(sol.q))
    assert np.all(np.maximum(sol.pos_err, sol.ori_err) > 1e-3)


def test_just_out_of_reach(folder: pathlib.Path) -> None:
    """Stretched arm, target pushed 1e-9 m (above the existence tolerance) and 1e-14 m (below
    it, rounding) further out along the arm."""
    arm = arm_named("ur5e", folder)
    q = arm.sample(10, seed=9)
    q[:, 2] = 0.0
    T = arm.mujoco_poses(q)
    wrist = np.array([_moved(arm.chain, row, _meet(arm.chain, 4, 5)) for row in q])
    shoulder = _meet(arm.chain, 0, 1)  # on axis 1: it does not move
    out = (wrist - shoulder) / np.linalg.norm(wrist - shoulder, axis=1, keepdims=True)
    for push, reachable in [(1e-9, False), (1e-14, True)]:
        moved = T.copy()
        moved[:, :3, 3] += push * out
        sol = arm.chain.ik_all(moved)
        assert sol.valid.any(axis=1).all() == reachable


# --- the geometry test --------------------------------------------------------------------------


def _tilted(chain: poekin.Chain, joint: int, degrees: float) -> poekin.Chain:
    """``chain`` with axis ``joint`` (0-based) turned by ``degrees`` about a normal of it
    through its point."""
    point, w = _axis_point(chain, joint)
    normal = np.cross(w, [0.0, 0.0, 1.0] if abs(w[2]) < 0.9 else [1.0, 0.0, 0.0])
    R = Rotation.from_rotvec(np.radians(degrees) * normal / np.linalg.norm(normal)).as_matrix()
    screws = chain.screws.copy()
    w2 = R @ w
    screws[joint] = np.r_[w2, -np.cross(w2, point)]
    return poekin.Chain(chain.joint_names, chain.joint_types, screws, chain.home, chain.limits)


def _shifted(chain: poekin.Chain, joint: int, offset: np.ndarray) -> poekin.Chain:
    point, w = _axis_point(chain, joint)
    screws = chain.screws.copy()
    screws[joint] = np.r_[w, -np.cross(w, point + offset)]
    return poekin.Chain(chain.joint_names, chain.joint_types, screws, chain.home, chain.limits)


def test_seven_joints_are_refused() -> None:
    fr3 = poekin.load(ik_arms.load_quiet("franka_fr3"))
    with pytest.raises(AnalyticIKError, match=r"needs 6 revolute joints; .*fr3.* has 7"):
        fr3.ik_all(fr3.fk(np.zeros(7)))


def test_a_tilted_ur_axis_is_named(folder: pathlib.Path) -> None:
    ur = arm_named("ur5e", folder).chain
    with pytest.raises(AnalyticIKError, match=r"axes 2 and 3 are not parallel: 0\.3 deg") as e:
        _tilted(ur, 2, 0.3).ik_all(np.eye(4), refine=False)
    assert isinstance(e.value, ModelError)
    assert "spherical wrist" in str(e.value) and "chain.ik" in str(e.value)
    with pytest.raises(AnalyticIKError, match=r"axes 2 and 4 are not parallel: 0\.3 deg"):
        _tilted(ur, 3, 0.3).ik_all(np.eye(4), refine=False)
    with pytest.raises(AnalyticIKError, match=r"not parallel: 1 deg.*nor within 0\.01 of one"):
        _tilted(ur, 3, 1.0).ik_all(np.eye(4))  # too far for the refined nearest geometry


def test_a_fourth_parallel_axis_is_named(folder: pathlib.Path) -> None:
    """Axis 5 turned parallel to axes 2 to 4 (and axis 6 to where axis 5 was, so that they
    still meet): four parallel axes, no closed form."""
    ur = arm_named("ur5e", folder).chain
    screws = ur.screws.copy()
    point = _meet(ur, 4, 5)
    for joint, w in ((4, ur.screws[1, :3]), (5, ur.screws[4, :3])):
        screws[joint] = np.r_[w, -np.cross(w, point)]
    flat = poekin.Chain(ur.joint_names, ur.joint_types, screws, ur.home, ur.limits)
    with pytest.raises(AnalyticIKError, match="axes 2 and 5 are parallel"):
        analytic.geometry(flat)


def test_a_wrist_that_does_not_meet_is_named(folder: pathlib.Path) -> None:
    irb = arm_named("irb120", folder).chain
    off = _shifted(irb, 4, np.array([0.0, 0.0, 0.0032]))  # axis 5 (along y) 3.2 mm up
    with pytest.raises(AnalyticIKError, match=r"axes 4 and 5 do not meet: 3\.2 mm apart"):
        analytic.geometry(off)
    ur = arm_named("ur5e", folder).chain
    five = _shifted(ur, 5, 0.0032 * np.cross(ur.screws[4, :3], ur.screws[5, :3]))
    with pytest.raises(AnalyticIKError, match=r"axes 5 and 6 do not meet: 3\.2 mm apart"):
        analytic.geometry(five)


def test_a_spherical_wrist_with_an_unsupported_shoulder_is_named(folder: pathlib.Path) -> None:
    """The IRB 120 with axis 2 moved 5 mm off axis 1 and axis 3 tilted by 1 deg: its wrist
    still meets in a point, but no split of the first three axes applies."""
    irb = arm_named("irb120", folder).chain
    bent = _tilted(_shifted(irb, 1, np.array([0.005, 0.0, 0.0])), 2, 1.0)
    with pytest.raises(AnalyticIKError) as e:
        analytic.geometry(bent)
    assert (
        "its first three axes fails: axes 2 and 3 are not parallel: 1 deg, axes 1 and 2 do not "
        "meet: 5 mm apart, axes 2 and 3 do not meet: 5 mm apart" in str(e.value)
    )


def test_within_tolerance_is_accepted(folder: pathlib.Path) -> None:
    ur = arm_named("ur5e", folder).chain
    analytic.geometry(_tilted(ur, 2, np.degrees(analytic.GEOMETRY_TOL) / 2))
    with pytest.raises(AnalyticIKError):
        analytic.geometry(_tilted(ur, 2, np.degrees(analytic.GEOMETRY_TOL) * 2))


def test_lite6_geometry(folder: pathlib.Path) -> None:
    """The Menagerie Lite6: a spherical wrist, axes 1 and 2 meet; its axes 2 and 3, parallel
    by design, are 7.3e-6 rad apart in the model, so the split used is axes 1 and 2 meeting."""
    lite6 = arm_named("lite6", folder).chain
    w2, w3 = lite6.screws[1, :3], lite6.screws[2, :3]
    assert 7e-6 < np.linalg.norm(np.cross(w2, w3)) < 8e-6
    assert "axes 1 and 2 meet" in analytic.geometry(lite6).description


def test_prismatic_joints_are_refused() -> None:
    chain = poekin.Chain(
        ("a", "b", "c", "d", "e", "f"),
        ("revolute",) * 5 + ("prismatic",),
        np.vstack([np.tile([0, 0, 1, 0, 0, 0], (5, 1)), [0, 0, 0, 0, 0, 1]]),
        np.eye(4),
    )
    with pytest.raises(AnalyticIKError, match=r"6 revolute joints; this chain has 6 \(RRRRRP\)"):
        chain.ik_all(np.eye(4))


@pytest.mark.parametrize(
    ("T", "match"),
    [
        (np.eye(3), r"shape \(\.\.\., 4, 4\)"),
        (np.full((4, 4), np.nan), "NaN or inf"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "not a rigid transform"),
        (np.diag([2.0, 1.0, 1.0, 1.0]), "not a rigid transform"),
        ("pose", "must be numbers"),
    ],
)
def test_bad_targets(T: object, match: str, folder: pathlib.Path) -> None:
    with pytest.raises(InputError, match=match):
        arm_named("ur5e", folder).chain.ik_all(T)  # type: ignore[arg-type]


# --- the compiled twin -------------------------------------------------------------------------

needs_kernel = pytest.mark.skipif(not poekin.compiled_kernel(), reason="no compiled kernel")


@needs_kernel
def test_kernel_equals_the_numpy_reference(arm: Arm) -> None:
    """Same operations in the same order: the same validity and the same angles but for the
    last bit or two of atan2 (the kernel's own)."""
    q = arm.sample(400, seed=10)
    q[:100, 4] = 0.0  # wrist singularities
    q[100:150, 2] = 0.0  # stretched elbows (UR)
    T = arm.chain.fk(q)
    T[150:160, :3, 3] *= 10  # out of reach
    ref_q, ref_valid = analytic.solve_numpy(arm.chain, T)
    got = analytic.solve_kernel(arm.chain, T)
    assert got is not None
    np.testing.assert_array_equal(got[1], ref_valid)
    assert np.max(np.abs(got[0] - ref_q)) <= 4 * np.finfo(float).eps * np.pi


@needs_kernel
def test_kernel_orders_the_branches_as_the_numpy_reference() -> None:
    """ik_all(T, near=q)'s ordering (analytic.order_numpy) and the kernel's twin: the same
    bits, on branches with ties (repeated rows), invalid ones, angles an odd number of half
    turns from the reference (round half to even), unlimited and prismatic joints, and
    limits that no turn reaches."""
    from poekin.kernel import _fast

    rng = np.random.default_rng(3)
    N, K, J = 500, 8, 6
    q = rng.uniform(-9.0, 9.0, (N, K, J))
    q[:, 5] = q[:, 2]  # ties: the stable order keeps them as they came
    ref = rng.uniform(-7.0, 7.0, (N, J))
    q[:50, 0] = ref[:50] + np.pi * rng.choice([-3.0, -1.0, 1.0, 3.0], (50, J))
    ref[50:70] = 0.0
    q[50:70, 1] = np.pi * rng.choice([-1.0, 1.0], (20, J))  # exactly half a turn from 0
    q[70:80, 3, 4] = np.nan  # sorted last among the valid or the invalid, as NumPy sorts
    valid = rng.random((N, K)) < 0.6
    limits = np.array([[-2 * np.pi, 2 * np.pi], [-np.inf, np.inf], [-3.0, 3.0], [0.1, 0.2],
                       [-np.inf, 1.0], [-6.0, 6.5]])  # fmt: skip
    revolute = np.array([True, True, True, True, True, False])
    args = (q, valid, ref, limits, revolute)
    want_q, want_valid = analytic.order_numpy(*args)
    got_q, got_valid = _fast._kernel.ordered(*args)
    np.testing.assert_array_equal(got_valid, want_valid)
    np.testing.assert_array_equal(got_q, want_q)  # NaN where NaN
    assert got_q[~np.isnan(got_q)].tobytes() == want_q[~np.isnan(want_q)].tobytes()
    assert not np.array_equal(want_q, q) and want_valid[:, 0].sum() > want_valid[:, -1].sum()


def test_without_the_kernel(folder: pathlib.Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An install without a C compiler runs the NumPy reference, with the same checks."""
    monkeypatch.setattr(analytic, "_kernel", None)
    arm = arm_named("irb120", folder)
    q = arm.sample(30, seed=12)
    check(arm, arm.mujoco_poses(q), q)
    assert analytic.solve_kernel(arm.chain, np.eye(4)) is None
    with pytest.raises(InputError, match="not a rigid transform"):
        arm.chain.ik_all(np.diag([1.0, 1.0, 1.0, 2.0]))


@needs_kernel
def test_kernel_widths_threads_and_batches_give_the_same_bits(folder: pathlib.Path) -> None:
    from poekin.kernel import _fast

    arm = arm_named("puma560", folder)
    T = arm.chain.fk(arm.sample(3000, seed=11))
    best = _fast._kernel.set_width(0)
    threads = poekin.get_threads()
    results = []
    try:
        for w in (2, 4, 8):
            if w <= best:
                _fast._kernel.set_width(w)
                for t in (1, 2):
                    poekin.set_threads(t)
                    results.append(arm.chain.ik_all(T).q)
    finally:
        _fast._kernel.set_width(_fast.DEFAULT_WIDTH)
        poekin.set_threads(threads)
    singles = np.stack([arm.chain.ik_all(t).q for t in T[:20]])
    for r in results[1:]:
        np.testing.assert_array_equal(r, results[0])
    np.testing.assert_array_equal(singles, results[0][:20])


def test_unaligned_targets_give_the_same_solutions(folder: pathlib.Path) -> None:
    """An array at an odd offset in its buffer (from Dask, ``np.frombuffer``) is copied for the
    kernel, not refused."""
    from test_ik_numerical import unaligned

    arm = arm_named("ur5e", folder)
    T = arm.chain.fk(arm.sample(50, seed=12))
    expected = arm.chain.ik_all(T)
    got = arm.chain.ik_all(unaligned(T))
    np.testing.assert_array_equal(got.q, expected.q)
    np.testing.assert_array_equal(got.valid, expected.valid)


@needs_kernel
def test_kernel_rejects_what_the_reference_rejects(folder: pathlib.Path) -> None:
    chain = arm_named("ur5e", folder).chain
    T = np.tile(np.eye(4), (100, 1, 1))
    T[37, 0, 0] = 1.001
    with pytest.raises(InputError, match=r"target pose \(37,\) is not a rigid transform"):
        chain.ik_all(T)


# --- the page -----------------------------------------------------------------------------------


# --- a calibrated arm: the nearest ideal geometry, refined (issue 26) ---------------------------

CALIBRATED = pathlib.Path(__file__).resolve().parents[1] / "data" / "ur" / "ur5e_calibration.yaml"


def _calibrated() -> tuple[poekin.Chain, mujoco.MjModel]:
    """The synthetic calibrated UR5e (tests/data/ur: axes 0.07 and 0.12 deg from parallel, 5
    and 6 0.022 mm apart), and MuJoCo's compile of it, written as a URDF."""
    import tempfile

    chain = poekin.load_params(CALIBRATED)
    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / "calibrated.urdf"
        poekin.export(chain, "urdf", path)
        model = mujoco.MjModel.from_xml_path(str(path))
    return chain, model


def _mj_fk(model: mujoco.MjModel, frame: str, q: np.ndarray) -> np.ndarray:
    data = mujoco.MjData(model)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
    out = np.tile(np.eye(4), (len(q), 1, 1))
    for n, x in enumerate(q):
        data.qpos[:] = x
        mujoco.mj_forward(model, data)
        out[n, :3, :3], out[n, :3, 3] = data.xmat[body].reshape(3, 3), data.xpos[body]
    return out


def test_a_calibrated_ur_gets_every_branch_refined_on_itself() -> None:
    """A real UR's axes are never exactly parallel, so the exact closed form refuses it; the
    nearest ideal geometry's branches, refined on the arm, are exact by MuJoCo's FK of the
    arm (1e-10), distinct, within the limits, and hold the configuration each target came
    from for >= 99.8% of targets (measured: 99.9%; the rest sit at a straight wrist, where the
    arm can have more solutions than 8 branches hold)."""
    chain, model = _calibrated()
    with pytest.raises(AnalyticIKError, match=r"axes 2 and 3 are not parallel: 0\.07 deg"):
        chain.ik_all(np.eye(4), refine=False)
    q = poekin.sample_joint_values(chain, 1000, seed=3, within_limits=True)
    T = _mj_fk(model, chain.frame, q)
    found = chain.ik_all(T)
    assert found.geometry.nearest == (
        "axes 2 and 3 are not parallel: 0.07 deg; axes 2 and 4 are not parallel: 0.12 deg; "
        "axes 5 and 6 do not meet: 0.022 mm apart"
    )
    ok = found.valid
    assert ok.sum(axis=-1).mean() > 6.9  # the nominal UR5e: 7.07 per target on such q
    reached = _mj_fk(model, chain.frame, found.q[ok])
    pos, ori = poekin.pose_errors(np.broadcast_to(T[:, None], (*ok.shape, 4, 4))[ok], reached)
    assert pos.max() <= 1e-10 + 1e-13 and ori.max() <= 1e-10 + 1e-13
    assert within_limits(found.q[ok], chain.limits).all()
    for t in range(len(q)):
        sols = found.q[t][ok[t]]
        gaps = np.abs(sols[:, None] - sols[None]).max(axis=-1) + np.eye(len(sols))
        assert (gaps > 1e-8).all(), t  # no branch twice
    own = (np.abs(poekin.wrap(found.q, chain, q[:, None]) - q[:, None]).max(axis=-1) < 1e-7) & ok
    assert own.any(axis=-1).mean() >= 0.998


# Configurations of bench_ik.py's calibrated UR5e whose solutions the refinement once missed:
# a straight wrist where the ideal geometry reaches no solution (q5 = -0.018), a straight wrist
# where the arm has a second solution near the ideal geometry's one (q5 = 3.113), and a
# stretched and a folded elbow (q3 = 0.001, -3.141), where a solve to 1e-10 left the answer
# 2e-6 rad from the exact one
HARD = [
    [-0.384223, -1.738537, 0.365231, -4.833179, -0.017645, -4.938934],
    [5.448227, 6.275011, 3.103937, 3.115015, 3.113082, 3.284158],
    [-1.330814, 0.690557, 0.001222, 3.696246, 1.223878, 4.597576],
    [1.045095, 4.247786, -3.140899, 3.295736, -2.251878, -5.500646],
]


def test_a_straight_wrist_and_a_stretched_elbow_keep_the_configuration_they_came_from() -> None:
    """Each of :data:`HARD`, with the nominal UR5e's limits (as bench_ik.py has them), is among
    its target's valid branches to 1e-7 rad; every valid branch is exact by MuJoCo's FK and
    within the limits."""
    import dataclasses

    chain, model = _calibrated()
    chain = dataclasses.replace(chain, limits=poekin.load("universal_robots_ur5e").limits)
    q = np.array(HARD)
    T = _mj_fk(model, chain.frame, q)
    found = chain.ik_all(T)
    gap = np.abs(poekin.wrap(found.q, chain, q[:, None]) - q[:, None]).max(axis=-1)
    assert ((gap < 1e-7) & found.valid).any(axis=-1).all(), gap.min(axis=-1)
    ok = found.valid
    reached = _mj_fk(model, chain.frame, found.q[ok])
    pos, ori = poekin.pose_errors(np.broadcast_to(T[:, None], (*ok.shape, 4, 4))[ok], reached)
    assert pos.max() <= 1e-10 and ori.max() <= 1e-10
    assert within_limits(found.q[ok], chain.limits).all()


def test_a_calibrated_ur_at_absurd_targets_finds_nothing_inside_the_limits() -> None:
    """Targets from 1e-300 m to 1e300 m away, signed zeros among them (the ideal geometry
    gives no finite start beyond 1e154): no valid branch, every q finite and within the
    limits, the same bits alone and in a batch."""
    import dataclasses

    chain, _ = _calibrated()
    chain = dataclasses.replace(chain, limits=poekin.load("universal_robots_ur5e").limits)
    far = [[1e300, 0.0, 0.0], [1e155, 1e155, 0.0], [-1e200, 1e-300, -0.0], [1e20, 0.0, 0.0]]
    T = np.tile(np.eye(4), (len(far), 1, 1))
    T[:, :3, 3] = far
    found = chain.ik_all(T)
    assert not found.valid.any()
    assert np.isfinite(found.q).all() and within_limits(found.q, chain.limits).all()
    for k in range(len(far)):
        assert chain.ik_all(T[k]).q.tobytes() == found.q[k].tobytes()


def test_refined_branches_are_the_solutions_a_search_finds() -> None:
    """On 40 targets, 2,000 random starts each of the numerical solver find at most 1% of
    solutions that the refined closed form does not list (where a straight wrist moves the
    calibrated arm's solutions far from the ideal geometry's). Solutions count as one within
    1e-4 rad: near a fold two converged answers of one solution differ by that much."""
    chain, _ = _calibrated()
    q = poekin.sample_joint_values(chain, 40, seed=4, within_limits=True)
    found = chain.ik_all(chain.fk(q))
    rng = np.random.default_rng(5)
    distinct, missing = 0, 0
    for t in range(len(q)):
        starts = rng.uniform(-np.pi, np.pi, (2000, 6))
        search = chain.ik(np.broadcast_to(chain.fk(q[t]), (2000, 4, 4)), starts, max_attempts=1)
        seen: list[np.ndarray] = []
        for s in poekin.wrap(search.q[search.success], chain):
            if not any(np.abs(s - u).max() < 1e-4 for u in seen):
                seen.append(s)
        listed = found.q[t][found.valid[t]]
        distinct += len(seen)
        missing += sum(
            not (np.abs(poekin.wrap(listed, chain, s) - s).max(axis=-1) < 1e-4).any() for s in seen
        )
    assert distinct > 250 and missing <= 0.01 * distinct, (missing, distinct)


def test_near_orders_the_branches_and_gives_the_nearest_equivalents(folder: pathlib.Path) -> None:
    """ik_all(T, near=q): the branch of q first, its angles those of q (a +-2 pi joint at
    q6 = 6.0 comes back at 6.0, not -0.28), the valid branches by distance; the same poses."""
    ur = arm_named("ur5e", folder).chain
    q = np.array([[0.3, -1.2, 1.4, -0.5, 1.1, 6.0], [-2.0, -2.2, -1.0, 4.0, -0.4, -5.5]])
    T = ur.fk(q)
    plain, near = ur.ik_all(T), ur.ik_all(T, near=q)
    assert np.allclose(near.q[:, 0], q, atol=1e-9)
    for t in range(len(q)):
        d = np.linalg.norm(near.q[t] - q[t], axis=-1)[near.valid[t]]
        assert (np.diff(d) >= 0).all() and near.valid[t][: len(d)].all()
        assert near.valid[t].sum() == plain.valid[t].sum()
    assert np.allclose(ur.fk(near.q[near.valid]), np.repeat(T, near.valid.sum(-1), axis=0))
    with pytest.raises(InputError, match="near must be"):
        ur.ik_all(T, near=np.zeros((3, 6)))
    with pytest.raises(InputError, match="near contains NaN or inf"):
        ur.ik_all(T, near=np.full(6, np.nan))


def test_ik_nearest_branch_is_the_closed_forms_nearest_q0(folder: pathlib.Path) -> None:
    ur = arm_named("ur5e", folder).chain
    q = poekin.sample_joint_values(ur, 50, seed=6, within_limits=True)
    T = ur.fk(q)
    found = ur.ik(T, q + 0.05, nearest_branch=True)
    assert found.success.all() and (found.iterations == 0).all()
    assert np.allclose(found.q, q, atol=1e-9)  # the generating branch is the nearest
    far = T.copy()
    far[0, :3, 3] = [3.0, 0.0, 0.0]  # no branch: the numerical best fit from q0
    missed = ur.ik(far, q, nearest_branch=True)
    assert not missed.success[0] and missed.iterations[0] > 0 and missed.success[1:].all()
    with pytest.raises(InputError, match="nearest_branch chooses among"):
        ur.ik(T, nearest_branch=True)
