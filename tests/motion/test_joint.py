"""poekin.motion.joint: joint_trajectory against Modern Robotics' JointTrajectory on the same
inputs and within its limits; via_trajectory by its properties (the ends at rest, near each via
point, within qdmax, continuous, derivatives equal to finite differences), and one segment of it
against the trapezoid scaling (itself checked against Ruckig)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import modern_robotics as mr
import numpy as np
import pytest
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from poekin.errors import InputError
from poekin.motion.joint import JointTrajectory, joint_trajectory, via_trajectory
from poekin.motion.scaling import KINDS, scaling

BATCH_SHAPES = [(), (1,), (3, 1, 2)]
FAST = settings(max_examples=15, deadline=None)
seeds = st.integers(0, 2**32 - 1)


@pytest.mark.parametrize("method", [3, 5])
def test_joint_trajectory_matches_modern_robotics(method: int) -> None:
    rng = np.random.default_rng(method)
    q0, q1 = rng.uniform(-3, 3, (2, 6))
    Tf, rate = 2.0, 50.0  # samples k / 50: MR's N = 101 points, Tf / (N - 1) apart
    kind = {3: "cubic", 5: "quintic"}[method]
    traj = joint_trajectory(q0, q1, Tf, kind=kind, rate=rate)
    assert isinstance(traj, JointTrajectory) and traj.duration == Tf
    assert_close("t", traj.t, np.linspace(0.0, Tf, 101), 1e-15)
    assert_close("q", traj.q, mr.JointTrajectory(q0, q1, Tf, 101, method), 1e-13)
    with pytest.raises(dataclasses.FrozenInstanceError):
        traj.q = traj.qd  # type: ignore[misc]


def test_quintic_joint_trajectory_matches_robotics_toolboxs_jtraj() -> None:
    """Robotics Toolbox's ``jtraj`` (a quintic from rest to rest, the bench extra's anchor) on
    the same times: the same q, qd and qdd."""
    rtb = pytest.importorskip("roboticstoolbox")
    q0, q1 = np.array([0.0, -1.2, 0.4]), np.array([1.0, 0.3, -0.8])
    ours = joint_trajectory(q0, q1, 2.0, kind="quintic", rate=50.0)
    theirs = rtb.jtraj(q0, q1, ours.t)
    assert_close("q", ours.q, theirs.q, 1e-13)
    assert_close("qd", ours.qd, theirs.qd, 1e-12)
    assert_close("qdd", ours.qdd, theirs.qdd, 1e-11)


@pytest.mark.parametrize("kind", KINDS)
def test_joint_derivatives_match_finite_differences(kind: str) -> None:
    rng = np.random.default_rng(1)
    q0, q1 = rng.uniform(-2, 2, (2, 7))
    rate = 2000.0
    traj = joint_trajectory(q0, q1, 1.5, kind=kind, rate=rate)
    fd = (traj.q[2:] - traj.q[:-2]) * rate / 2
    # q is C1: central differences err by at most h |qdd| where the acceleration jumps
    assert_close("qd", traj.qd[1:-1], fd, np.max(np.abs(traj.qdd)) / rate)
    fdd = (traj.qd[2:] - traj.qd[:-2]) * rate / 2
    err = np.max(np.abs(traj.qdd[1:-1] - fdd), axis=1)
    # the cubic's and the trapezoid's acceleration jumps: a few samples at the corners
    assert np.mean(err < 1e-4) > 0.99 and np.sum(err >= 1e-4) <= 6


@FAST
@given(seed=seeds, shape=st.sampled_from(BATCH_SHAPES), kind=st.sampled_from(KINDS))
def test_joint_trajectory_batched(seed: int, shape: tuple[int, ...], kind: str) -> None:
    rng = np.random.default_rng(seed)
    q0, q1 = rng.uniform(-2, 2, (2, *shape, 3))
    traj = joint_trajectory(q0, q1, 0.7, kind=kind, rate=100.0)
    assert traj.q.shape == traj.qd.shape == traj.qdd.shape == (71, *shape, 3)
    for idx in np.ndindex(*shape):
        one = joint_trajectory(q0[idx], q1[idx], 0.7, kind=kind, rate=100.0)
        np.testing.assert_array_equal(traj.q[(slice(None), *idx)], one.q)
        np.testing.assert_array_equal(traj.qdd[(slice(None), *idx)], one.qdd)


@pytest.mark.parametrize("kind", KINDS)
def test_joint_trajectory_within_limits(kind: str) -> None:
    q0 = np.array([0.0, 1.0, -0.5, 2.0])
    q1 = np.array([1.5, -1.0, -0.5, 2.3])  # joint 2 does not move
    vmax = np.array([1.0, 0.8, 0.01, 3.0])
    amax = np.array([2.0, 0.9, 0.01, 5.0])
    traj = joint_trajectory(q0, q1, kind=kind, vel_limits=vmax, acc_limits=amax, rate=20_000.0)
    peak_v = np.abs(traj.qd).max(axis=0) / vmax
    peak_a = np.abs(traj.qdd).max(axis=0) / amax
    assert peak_v.max() <= 1 + 1e-12 and peak_a.max() <= 1 + 1e-12
    assert max(peak_v.max(), peak_a.max()) > 1 - 1e-6  # the binding joint is at its limit
    assert_close("q at the end", traj.q[-1], q1, 1e-15)
    assert_close("at rest at the end", traj.qd[-1], np.zeros(4), 0.0)
    # a longer duration within the same limits stays within them; a shorter one is refused
    longer = joint_trajectory(
        q0, q1, traj.duration * 1.3, kind=kind, vel_limits=vmax, acc_limits=amax
    )
    assert np.all(np.abs(longer.qd) <= vmax * (1 + 1e-12))
    assert np.all(np.abs(longer.qdd) <= amax * (1 + 1e-12))
    with pytest.raises(InputError, match=r"too short for the joint limits: .* needs at least"):
        joint_trajectory(q0, q1, traj.duration * 0.9, kind=kind, vel_limits=vmax, acc_limits=amax)


def test_joint_trajectory_that_does_not_move() -> None:
    q = np.array([0.3, -0.2])
    still = joint_trajectory(q, q, vel_limits=1.0, acc_limits=1.0)
    assert still.duration == 0.0 and still.t.tolist() == [0.0]
    np.testing.assert_array_equal(still.q, q[None])
    held = joint_trajectory(q, q, 0.01, rate=1000.0)
    np.testing.assert_array_equal(held.q, np.broadcast_to(q, (11, 2)))


VIA = np.array(
    [[0.0, 0.0, 0.0], [1.0, 0.5, -0.4], [1.0, 2.0, 0.2], [0.2, 1.5, 0.2], [0.0, 0.0, 0.0]]
)
QDMAX = np.array([1.0, 2.0, 0.5])


@pytest.mark.parametrize("tacc", [0.05, 0.3, 1.0])
def test_via_trajectory_properties(tacc: float) -> None:
    rate = 5000.0
    traj = via_trajectory(VIA, qdmax=QDMAX, tacc=tacc, rate=rate)
    # starts at the first via point and ends at the last, at rest
    assert_close("start", traj.q[0], VIA[0], 0.0)
    assert_close("end", traj.q[-1], VIA[-1], 1e-15)
    assert_close("qd at the ends", traj.qd[[0, -1]], np.zeros((2, 3)), 0.0)
    assert traj.t[-1] >= traj.duration > traj.t[-2]
    # never faster than qdmax; the slowest joint of a segment longer than tacc reaches it
    speed = np.abs(traj.qd) / QDMAX
    assert speed.max() <= 1 + 1e-12
    assert speed.max() > 1 - 1e-12
    # passes by each interior via point, within qdmax * tacc (the blend's reach), and at most
    # |qd_out - qd_in| tacc / 8 (the parabola's offset at its middle) plus a sample's travel
    seg_time = np.maximum(np.max(np.abs(np.diff(VIA, axis=0)) / QDMAX, axis=1), tacc)
    seg_vel = np.diff(VIA, axis=0) / seg_time[:, None]
    for k in range(1, len(VIA) - 1):
        gap = np.min(np.max(np.abs(traj.q - VIA[k]), axis=1))
        assert gap <= np.max(QDMAX * tacc)
        offset = np.max(np.abs(seg_vel[k] - seg_vel[k - 1])) * tacc / 8
        assert gap <= offset + np.max(QDMAX) / rate + 1e-12
    # continuous q and qd; derivatives equal central differences (q is C1, piecewise quadratic)
    assert np.max(np.abs(np.diff(traj.q, axis=0))) <= np.max(QDMAX) / rate * (1 + 1e-9)
    amax = np.max(np.abs(traj.qdd))
    assert np.max(np.abs(np.diff(traj.qd, axis=0))) <= amax / rate * (1 + 1e-9)
    inner = traj.t[1:-1] < traj.duration
    fd = (traj.q[2:] - traj.q[:-2]) * rate / 2
    assert_close("qd", traj.qd[1:-1][inner], fd[inner], amax / rate)
    fdd = (traj.qd[2:] - traj.qd[:-2]) * rate / 2
    err = np.max(np.abs(traj.qdd[1:-1] - fdd), axis=1)
    assert np.sum(err > 1e-9) <= 2 * 2 * len(VIA)  # a sample either side of each blend's ends


def test_one_via_segment_is_the_trapezoid() -> None:
    q0, q1 = VIA[1], VIA[2]
    tacc = 0.4
    traj = via_trajectory([q0, q1], qdmax=QDMAX, tacc=tacc, rate=200.0)
    T_seg = np.max(np.abs(q1 - q0) / QDMAX)
    assert traj.duration == pytest.approx(T_seg + tacc, rel=1e-15)
    # cruise at 1 / T_seg in s, reached in tacc: the trapezoid of that duration and velocity
    s, sd, sdd = scaling("trapezoid", traj.t, traj.duration, vel_limit=1 / T_seg)
    assert_close("q", traj.q, q0 + s[:, None] * (q1 - q0), 1e-14)
    assert_close("qd", traj.qd, sd[:, None] * (q1 - q0), 1e-13)
    corners = np.array([0.0, tacc, traj.duration - tacc, traj.duration])
    away = np.min(np.abs(traj.t[:, None] - corners), axis=1) > 1e-9  # either side of a jump
    assert_close("qdd", traj.qdd[away], (sdd[:, None] * (q1 - q0))[away], 1e-12)


def test_via_trajectory_with_durations() -> None:
    durations = [1.0, 0.5, 2.0, 0.6]
    traj = via_trajectory(VIA, durations=durations, tacc=0.5, rate=1000.0)
    assert traj.duration == pytest.approx(sum(durations) + 0.5, rel=1e-15)
    # the middle of a segment's straight part: on the line between its via points
    mid = round((0.25 + 1.0 + 1.0) * 1000)  # via 2 at 0.25 + 1.5 s; segment 2 is 2 s long
    seg_vel = (VIA[3] - VIA[2]) / 2.0
    assert_close("qd on segment 2", traj.qd[mid], seg_vel, 1e-12)
    assert_close("q on segment 2", traj.q[mid], VIA[2] + seg_vel * 0.5, 1e-12)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: joint_trajectory([0.0], [1.0], 1.0, rate=0.0),
            "joint_trajectory: rate must be finite and > 0 (Hz), got 0",
        ),
        (
            lambda: joint_trajectory([0.0], [1.0], 1.0, rate="fast"),
            "rate must be a number of samples per second",
        ),
        (
            lambda: joint_trajectory([0.0], [np.nan], 1.0),
            "joint_trajectory: q1 has NaN or inf entries",
        ),
        (
            lambda: joint_trajectory(0.0, 1.0, 1.0),
            "joint_trajectory: q0 must be joint values (..., n), got a scalar",
        ),
        (
            lambda: joint_trajectory([0.0, 0.0], [1.0, 1.0, 1.0], 1.0),
            "q0 (2,) and q1 (3,) do not broadcast",
        ),
        (
            lambda: joint_trajectory([0.0], [1.0]),
            "give a duration, or vel_limits and/or acc_limits",
        ),
        (
            lambda: joint_trajectory([0.0], [1.0], -1.0),
            "duration must be finite and > 0 (s), got -1",
        ),
        (
            lambda: joint_trajectory([0.0], [1.0], kind="cubik", vel_limits=1.0),
            "did you mean 'cubic'?",
        ),
        (
            lambda: joint_trajectory([0, 0, 0], [1, 1, 1], vel_limits=[1.0, 1.0, -1.0]),
            "joint_trajectory: vel_limits must be > 0 (rad/s), got -1 for joint 2",
        ),
        (
            lambda: joint_trajectory([0, 0], [1, 1], acc_limits=[1.0, 0.0]),
            "acc_limits must be > 0 (rad/s^2), got 0 for joint 1",
        ),
        (
            lambda: joint_trajectory([0, 0], [1, 1], vel_limits=[1.0, 2.0, 3.0]),
            "one value or one per joint (2,), got shape (3,)",
        ),
        (
            lambda: joint_trajectory([0.0], [1.0], kind="trapezoid", vel_limits=1.0),
            "the minimum-time trapezoid needs acc_limits",
        ),
        (
            lambda: joint_trajectory([0, 0], [1, 0], vel_limits=[np.inf, 1.0]),
            "the joints that move have no finite limit",
        ),
        (
            lambda: via_trajectory([[0.0, 1.0]], qdmax=1.0, tacc=0.1),
            "via_trajectory: via must be at least two via points (M, n), got shape (1, 2)",
        ),
        (
            lambda: via_trajectory(VIA, qdmax=1.0, tacc=0.0),
            "via_trajectory: tacc must be finite and > 0 (s), got 0",
        ),
        (
            lambda: via_trajectory(VIA, qdmax=[1.0, 0.0, 1.0], tacc=0.1),
            "qdmax must be > 0 (rad/s), got 0 for joint 1",
        ),
        (
            lambda: via_trajectory(VIA, tacc=0.1),
            "give one of qdmax (rad/s) and durations (s), not neither",
        ),
        (lambda: via_trajectory(VIA, qdmax=1.0, durations=[1.0] * 4, tacc=0.1), "not both"),
        (
            lambda: via_trajectory(VIA, durations=[1.0] * 3, tacc=0.1),
            "durations must be one per segment (4,), got shape (3,)",
        ),
        (
            lambda: via_trajectory(VIA, durations=[1.0, 0.05, 1.0, 1.0], tacc=0.1),
            "at least tacc (0.1 s), got 0.05 s for segment 1",
        ),
        (
            lambda: via_trajectory(VIA, qdmax=1.0, tacc=0.1, rate=-5.0),
            "via_trajectory: rate must be finite and > 0 (Hz), got -5",
        ),
        (
            lambda: via_trajectory(VIA * np.nan, qdmax=1.0, tacc=0.1),
            "via_trajectory: via has NaN or inf entries",
        ),
    ],
)
def test_bad_input(call: Callable[[], object], message: str) -> None:
    with pytest.raises(InputError) as info:
        call()
    text = str(info.value)
    assert message in text, text
    assert "\n" not in text and text.split(":")[0] in ("joint_trajectory", "via_trajectory")
