"""poekin.motion.retime: time-optimal timing within velocity and acceleration limits, and
jerk-limited motion through waypoints. The references are not ours: toppra's durations on the
same path and limits, scipy's CubicSpline for the path, the closed-form bang-bang time of a
straight line, finite differences of the returned ``q`` for every limit, Ruckig's jerk limits
checked by third differences."""

from __future__ import annotations

import functools
import logging
import math
import pathlib
import sys

import numpy as np
import pytest
import toppra
import toppra.algorithm
import toppra.constraint
from helpers import load_quiet
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

import poekin
from poekin.errors import InputError, MissingExtraError
from poekin.motion import retime
from poekin.motion._spline import not_a_knot
from poekin.motion.retime import Retimed

logging.getLogger("toppra").setLevel(logging.ERROR)

# UR5e: pi rad/s on every joint (UR's data sheet); FR3: Franka's data sheet. Accelerations are
# in no model file: values of that order.
UR5E_VEL = np.full(6, math.pi)
UR5E_ACC = np.array([8.0, 8.0, 8.0, 12.0, 12.0, 12.0])
FR3_VEL = np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
FR3_ACC = np.full(7, 10.0)
RATE = 500.0
ROUND = 1e-9  # rad/s and rad/s^2: what rounding in q leaves in its finite differences


@functools.cache
def _tree(robot: str) -> poekin.Tree:
    return poekin.load_tree(load_quiet(robot))


def _waypoints(robot: str, count: int, seed: int) -> np.ndarray:
    """``(count, n)`` random joint values within the model's limits (a joint without: within
    one turn)."""
    lo, hi = np.clip(_tree(robot).joint_limits, -math.pi, math.pi).T
    return np.random.default_rng(seed).uniform(lo, hi, (count, len(lo)))


def _toppra_duration(
    q: np.ndarray, vel: np.ndarray, acc: np.ndarray, stages: int | None = None
) -> float:
    """toppra 0.6 on its SplineInterpolator at ``linspace(0, 1, N)``: on its own grid (its
    default), or on ``stages`` equal stages."""
    path = toppra.SplineInterpolator(np.linspace(0.0, 1.0, len(q)), q)
    constraints = [
        toppra.constraint.JointVelocityConstraint(vel),
        toppra.constraint.JointAccelerationConstraint(acc),
    ]
    grid = None if stages is None else np.linspace(0.0, 1.0, stages + 1)
    algo = toppra.algorithm.TOPPRA(
        constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel"
    )
    return float(algo.compute_trajectory().duration)


def _assert_within(r: Retimed, vel: np.ndarray, acc: np.ndarray) -> None:
    """Every sample within the limits: the returned qd and qdd, and the finite differences of
    q (mean velocity over a tick, the second difference), which hold only if the motion between
    the samples is within them too."""
    assert np.all(np.abs(r.qd) <= vel), np.max(np.abs(r.qd) / vel)
    assert np.all(np.abs(r.qdd) <= acc), np.max(np.abs(r.qdd) / acc)
    dt = 1.0 / r.rate
    fd_v = np.diff(r.q, axis=0) / dt
    fd_a = np.diff(r.q, 2, axis=0) / dt**2
    assert np.all(np.abs(fd_v) <= vel + ROUND)
    assert np.all(np.abs(fd_a) <= acc * (1.0 + 1e-9) + 4.0 * np.abs(r.q).max() * 1e-16 / dt**2)


def _assert_ends(r: Retimed, q: np.ndarray) -> None:
    assert np.array_equal(r.q[0], q[0]) and np.array_equal(r.q[-1], q[-1])
    assert not np.any(r.qd[0]) and not np.any(r.qd[-1])
    np.testing.assert_allclose(r.t, np.arange(len(r.t)) / r.rate, rtol=0, atol=1e-15 * r.t[-1])
    assert r.duration == r.t[-1]
    assert r.q.shape == r.qd.shape == r.qdd.shape == (len(r.t), q.shape[1])


# --- the path: scipy's CubicSpline, as toppra's SplineInterpolator uses it --------------------


@pytest.mark.parametrize("count", [2, 3, 4, 5, 9, 40])
def test_spline_is_scipys_cubic_spline(count: int) -> None:
    rng = np.random.default_rng(count)
    y = rng.uniform(-3.0, 3.0, (count, 6))
    ref = CubicSpline(np.linspace(0.0, 1.0, count), y)
    ours = not_a_knot(y)
    s = np.concatenate([rng.uniform(0.0, 1.0, 500), np.linspace(0.0, 1.0, count)])
    for order in range(4):
        expected = ref(s, order)
        scale = max(1.0, float(np.abs(expected).max()))
        np.testing.assert_allclose(ours(s, order), expected, rtol=0, atol=1e-13 * scale)


def test_samples_lie_on_the_spline() -> None:
    q = _waypoints("universal_robots_ur5e", 7, seed=3)
    r = retime(q, UR5E_VEL, UR5E_ACC)
    assert r.s is not None
    assert r.s[0] == 0.0 and r.s[-1] == 1.0 and np.all(np.diff(r.s) >= 0.0)
    ref = CubicSpline(np.linspace(0.0, 1.0, len(q)), q)
    np.testing.assert_allclose(r.q, ref(r.s), rtol=0, atol=1e-13)
    # qd = q'(s) sd and qdd = q'(s) sdd + q''(s) sd^2: against central differences of q
    dt = 1.0 / r.rate
    fd_v = (r.q[2:] - r.q[:-2]) / (2.0 * dt)
    assert np.max(np.abs(fd_v - r.qd[1:-1])) < 1e-3 * UR5E_VEL.max()


# --- durations against toppra and against the closed form -------------------------------------


@pytest.mark.parametrize(
    ("robot", "vel", "acc", "count", "seed"),
    [
        ("universal_robots_ur5e", UR5E_VEL, UR5E_ACC, 5, 1),
        ("universal_robots_ur5e", UR5E_VEL, UR5E_ACC, 7, 2),
        ("universal_robots_ur5e", UR5E_VEL, UR5E_ACC, 10, 3),
        ("universal_robots_ur5e", UR5E_VEL / 4, UR5E_ACC * 2, 6, 4),
        ("franka_fr3", FR3_VEL, FR3_ACC, 6, 5),
        ("franka_fr3", FR3_VEL, FR3_ACC, 9, 6),
    ],
)
def test_duration_agrees_with_toppra(
    robot: str, vel: np.ndarray, acc: np.ndarray, count: int, seed: int
) -> None:
    q = _waypoints(robot, count, seed)
    reference = _toppra_duration(q, vel, acc)
    r = retime(q, vel, acc, rate=RATE)
    assert abs(r.optimal_duration / reference - 1.0) < 0.01
    assert abs(r.duration / reference - 1.0) < 0.01
    assert r.duration >= r.optimal_duration
    _assert_within(r, vel, acc)
    _assert_ends(r, q)


@pytest.mark.parametrize(
    ("robot", "vel", "acc", "count", "seed"),
    [
        ("universal_robots_ur5e", UR5E_VEL, UR5E_ACC, 4, 12),
        ("franka_fr3", FR3_VEL, FR3_ACC, 7, 13),
    ],
)
def test_same_grid_same_optimum_as_toppra(
    robot: str, vel: np.ndarray, acc: np.ndarray, count: int, seed: int
) -> None:
    """On the same grid (equal stages, each spline interval cut into as many) the two TOPP-RAs
    solve the same problems: their optima agree to rounding in toppra's LP solver, far closer
    than toppra's default grid is to either."""
    q = _waypoints(robot, count, seed)
    stages = (count - 1) * 100
    r = retime(q, vel, acc, stages=stages)
    assert abs(r.optimal_duration / _toppra_duration(q, vel, acc, stages) - 1.0) < 1e-5


@pytest.mark.parametrize(("distance", "vel", "acc"), [(2.0, 1.0, 3.0), (0.2, 1.0, 3.0)])
def test_a_straight_line_is_bang_bang(distance: float, vel: float, acc: float) -> None:
    """Two waypoints: the spline is the segment, and the fastest motion along it accelerates
    at the limit, cruises at the speed limit if it reaches it, and brakes at the limit."""
    q = np.array([[0.5], [0.5 + distance]])
    if distance >= vel**2 / acc:
        exact = distance / vel + vel / acc
    else:
        exact = 2.0 * math.sqrt(distance / acc)
    r = retime(q, vel, acc, rate=2000.0)
    assert abs(r.optimal_duration / exact - 1.0) < 1e-3
    assert r.duration - exact < 1e-3 * exact + 1.0 / r.rate
    assert np.max(np.abs(r.qd)) > 0.99 * min(vel, math.sqrt(distance * acc))
    _assert_within(r, np.array([vel]), np.array([acc]))


def test_model_velocity_limits_with_none_for_a_joint() -> None:
    """A URDF's <limit velocity> (Tree.joint_velocity_limits), inf for a joint that gives none:
    that joint is bounded by its acceleration alone."""
    robot = str(pathlib.Path(__file__).parents[1] / "data" / "urdf" / "serial_arm.urdf")
    vel = _tree(robot).joint_velocity_limits
    assert np.isinf(vel).any() and np.isfinite(vel).any()
    q = _waypoints(robot, 6, seed=7)
    acc = np.full(len(vel), 5.0)
    r = retime(q, vel, acc)
    reference = _toppra_duration(q, np.where(np.isinf(vel), 1e6, vel), acc)
    assert abs(r.duration / reference - 1.0) < 0.01
    _assert_within(r, vel, acc)


# --- every sample within every limit ----------------------------------------------------------


def test_between_the_grid_points_too() -> None:
    """A coarse grid (20 stages) and a fast rate (20 kHz): the peaks between grid points are
    caught and the motion slowed, so the dense samples are within the limits as well."""
    q = _waypoints("franka_fr3", 5, seed=8)
    r = retime(q, FR3_VEL, FR3_ACC, stages=20, rate=20000.0)
    _assert_within(r, FR3_VEL, FR3_ACC)
    _assert_ends(r, q)
    assert r.duration > r.optimal_duration  # the peaks between the grid points slowed it
    fine = retime(q, FR3_VEL, FR3_ACC)
    assert r.duration >= fine.optimal_duration  # never faster than the optimum


@settings(max_examples=25, deadline=None)
@given(
    count=st.integers(2, 8),
    n=st.integers(1, 4),
    seed=st.integers(0, 2**32 - 1),
    rate=st.sampled_from([50.0, 500.0, 1000.0]),
)
def test_random_paths_within_limits(count: int, n: int, seed: int, rate: float) -> None:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.0, 2.0, (count, n))
    vel = rng.uniform(0.5, 4.0, n)
    acc = rng.uniform(1.0, 20.0, n)
    r = retime(q, vel, acc, rate=rate, stages=200)
    _assert_within(r, vel, acc)
    _assert_ends(r, q)
    assert r.waypoint_times[0] == 0.0 and np.all(np.diff(r.waypoint_times) > 0.0)
    assert abs(r.waypoint_times[-1] - r.duration) <= 1e-12 * r.duration


def test_scalar_limits_and_a_path_that_does_not_move() -> None:
    q = _waypoints("universal_robots_ur5e", 4, seed=9)
    assert np.array_equal(retime(q, math.pi, 8.0).q, retime(q, UR5E_VEL, np.full(6, 8.0)).q)
    still = retime(np.repeat(q[:1], 3, axis=0), 1.0, 1.0)
    assert still.duration == 0.0 and np.array_equal(still.q, q[:1])


# --- jerk limits, by Ruckig -------------------------------------------------------------------


def test_jerk_limited_through_the_waypoints() -> None:
    q = _waypoints("franka_fr3", 6, seed=10)
    jerk = np.full(7, 200.0)
    r = retime(q, FR3_VEL, FR3_ACC, jerk_limits=jerk)
    assert r.s is None
    _assert_within(r, FR3_VEL, FR3_ACC)
    _assert_ends(r, q)
    dt = 1.0 / r.rate
    assert np.all(np.abs(np.diff(r.qdd, axis=0)) / dt <= jerk * (1.0 + 1e-9))
    third = np.diff(r.q, 3, axis=0) / dt**3
    assert np.all(np.abs(third) <= jerk * (1.0 + 1e-6))
    # each waypoint on a tick, and the motion continuous through it
    ticks = np.rint(r.waypoint_times * r.rate).astype(int)
    np.testing.assert_allclose(ticks / r.rate, r.waypoint_times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.q[ticks], q, rtol=0, atol=1e-9)


def test_jerk_limited_through_a_waypoint_given_twice() -> None:
    q = _waypoints("franka_fr3", 3, seed=14)[[0, 1, 1, 2]]
    jerk = np.full(7, 500.0)
    r = retime(q, FR3_VEL, FR3_ACC, jerk_limits=jerk)
    _assert_within(r, FR3_VEL, FR3_ACC)
    _assert_ends(r, q)
    assert np.all(np.abs(np.diff(r.qdd, axis=0)) * r.rate <= jerk * (1.0 + 1e-9))
    assert len(r.waypoint_times) == 4


def test_jerk_limits_without_ruckig(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ruckig", None)
    q = _waypoints("franka_fr3", 3, seed=11)
    with pytest.raises(MissingExtraError, match=r"retime with jerk_limits needs ruckig.*motion"):
        retime(q, FR3_VEL, FR3_ACC, jerk_limits=100.0)


# --- bad input: one line that says what is wrong ----------------------------------------------

Q3 = np.array([[0.0, 0.0], [0.5, 1.0], [1.0, 0.0]])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"q_path": Q3[:1]}, "q_path must be waypoints (N, n) with N >= 2, got shape (1, 2)"),
        ({"q_path": Q3[0]}, "q_path must be waypoints (N, n) with N >= 2, got shape (2,)"),
        ({"q_path": np.where(Q3 == 1.0, np.nan, Q3)}, "NaN or inf (waypoint 1, joint 1)"),
        ({"q_path": Q3 + 0j}, "q_path must be real numbers"),
        (
            {"vel_limits": [1.0, -1.0]},
            "vel_limits must be > 0 (rad/s) or inf for none, got -1 for joint 1",
        ),
        ({"vel_limits": 0.0}, "vel_limits must be > 0 (rad/s) or inf for none, got 0 for joint 0"),
        ({"vel_limits": [1.0, np.nan]}, "got nan for joint 1"),
        (
            {"vel_limits": [1.0, 1.0, 1.0]},
            "vel_limits must be one number or one per joint (shape (2,)), got shape (3,)",
        ),
        ({"acc_limits": [0.0, 1.0]}, "acc_limits must be > 0 (rad/s^2), finite, got 0 for joint 0"),
        ({"acc_limits": np.inf}, "acc_limits must be > 0 (rad/s^2), finite, got inf for joint 0"),
        ({"acc_limits": np.ones((2, 2))}, "acc_limits must be one number or one per joint"),
        ({"jerk_limits": -5.0}, "jerk_limits must be > 0 (rad/s^3), finite, got -5 for joint 0"),
        (
            {"jerk_limits": 5.0, "vel_limits": [1.0, np.inf]},
            "vel_limits must be > 0 (rad/s), finite, got inf for joint 1",
        ),
        ({"rate": 0.0}, "rate must be > 0 (Hz), got 0.0"),
        ({"rate": -500.0}, "rate must be > 0 (Hz), got -500.0"),
        ({"rate": np.nan}, "rate must be > 0 (Hz), got nan"),
        ({"rate": np.inf}, "rate must be finite (Hz), got inf"),
        ({"rate": "500"}, "rate must be > 0 (Hz), got '500'"),
        ({"stages": 1}, "stages must be a whole number >= 2, got 1"),
        ({"stages": 2.5}, "stages must be a whole number >= 2, got 2.5"),
    ],
)
def test_bad_input(kwargs: dict[str, object], message: str) -> None:
    args: dict[str, object] = {"q_path": Q3, "vel_limits": 1.0, "acc_limits": 2.0, **kwargs}
    with pytest.raises(InputError) as info:
        retime(**args)  # type: ignore[arg-type]
    text = str(info.value)
    assert text.startswith("retime: ") and message in text and "\n" not in text, text
