"""poekin.motion.scaling: the cubic and quintic against the Modern Robotics code, the minimum-time
trapezoid against Ruckig (infinite jerk: its rest-to-rest profile within velocity and
acceleration limits), every derivative against finite differences of ``s``."""

from __future__ import annotations

import math

import modern_robotics as mr
import numpy as np
import pytest
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st
from ruckig import InputParameter, Result, Ruckig, Trajectory

from poekin.errors import InputError
from poekin.motion.scaling import KINDS, min_duration, scaling, trapezoid

BATCH_SHAPES = [(), (1,), (3, 1, 2)]
FAST = settings(max_examples=25, deadline=None)
durations = st.floats(0.05, 20.0)
seeds = st.integers(0, 2**32 - 1)
limits = st.floats(0.05, 20.0)


def _fd(kind: str, t: np.ndarray, T: float | None, h: float, **kw: float) -> tuple[np.ndarray, ...]:
    """Central differences of ``s`` (first and second) at ``t``, step ``h``."""
    s_minus, s0, s_plus = (scaling(kind, t + d, T, **kw)[0] for d in (-h, 0.0, h))
    return (s_plus - s_minus) / (2 * h), (s_plus - 2 * s0 + s_minus) / (h * h)


def _ruckig(v: float, a: float) -> Trajectory:
    """Ruckig's time-optimal 0-to-1 rest-to-rest profile within v and a (no jerk limit)."""
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [1.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [math.inf]
    traj = Trajectory(1)
    assert Ruckig(1).calculate(inp, traj) == Result.Working
    return traj


@FAST
@given(T=durations, seed=seeds, shape=st.sampled_from(BATCH_SHAPES))
def test_cubic_and_quintic_match_modern_robotics(
    T: float, seed: int, shape: tuple[int, ...]
) -> None:
    t = np.random.default_rng(seed).uniform(0.0, T, shape)
    for kind, reference in (("cubic", mr.CubicTimeScaling), ("quintic", mr.QuinticTimeScaling)):
        s, sd, sdd = scaling(kind, t, T)
        assert s.shape == sd.shape == sdd.shape == shape
        expected = np.vectorize(lambda x, f=reference: f(T, x))(t)
        assert_close(f"{kind} s", s, expected, 1e-14)


@FAST
@given(T=durations, seed=seeds, shape=st.sampled_from(BATCH_SHAPES))
def test_polynomial_derivatives_match_finite_differences(
    T: float, seed: int, shape: tuple[int, ...]
) -> None:
    h = 1e-4 * T
    t = np.random.default_rng(seed).uniform(2 * h, T - 2 * h, shape)
    for kind in ("cubic", "quintic"):
        _, sd, sdd = scaling(kind, t, T)
        fd, fdd = _fd(kind, t, T, h)
        # truncation ~h^2 s''' (s''' ~ 60 / T^3), rounding ~1e-16 / h^2
        assert_close(f"{kind} sd * T", sd * T, fd * T, 1e-7)
        assert_close(f"{kind} sdd * T^2", sdd * T**2, fdd * T**2, 1e-5)


@pytest.mark.parametrize("kind", KINDS)
def test_boundary_values_and_clamping(kind: str) -> None:
    T = 1.7
    s, sd, sdd = scaling(kind, np.array([-1.0, 0.0, T, T + 1.0]), T)
    np.testing.assert_array_equal(s, [0.0, 0.0, 1.0, 1.0])
    np.testing.assert_array_equal(sd, [0.0, 0.0, 0.0, 0.0])
    assert sdd[0] == sdd[3] == 0.0
    if kind == "quintic":  # rest to rest in acceleration too
        np.testing.assert_array_equal(sdd, 0.0)
    if kind == "cubic":  # the cubic's acceleration jumps at both ends: the phase that starts there
        assert_close("cubic sdd(0), sdd(T)", sdd[1:3], [6 / T**2, -6 / T**2], 1e-14)
    s_mid = scaling(kind, T / 2, T)[0]
    assert s_mid.shape == ()
    assert abs(float(s_mid) - 0.5) < 1e-15  # every profile is symmetric


@pytest.mark.parametrize("kind", ["cubic", "quintic"])
def test_polynomial_peaks_and_min_duration(kind: str) -> None:
    T = 2.0
    t = np.linspace(0.0, T, 200_001)
    _, sd, sdd = scaling(kind, t, T)
    peak_v, peak_a = sd.max(), np.abs(sdd).max()
    # the shortest duration within limits equal to those peaks is T itself (dense: to 1e-9)
    assert abs(min_duration(kind, peak_v, None) - T) < 1e-9
    assert abs(min_duration(kind, None, peak_a) - T) < 1e-9
    # limits below the peaks: duration=None stretches it until the peaks meet them
    v, a = 0.3, 0.2
    T_min = min_duration(kind, v, a)
    _, sd, sdd = scaling(kind, np.linspace(0.0, T_min, 200_001), None, vel_limit=v, acc_limit=a)
    assert sd.max() <= v * (1 + 1e-12) and np.abs(sdd).max() <= a * (1 + 1e-12)
    assert max(sd.max() / v, np.abs(sdd).max() / a) > 1 - 1e-9  # one of them is met


@FAST
@given(v=limits, a=limits)
def test_min_time_trapezoid_matches_ruckig(v: float, a: float) -> None:
    reference = _ruckig(v, a)
    profile = trapezoid(vel_limit=v, acc_limit=a)
    assert abs(profile.duration - reference.duration) <= 1e-9 * reference.duration
    if abs(v * v / a - 1) > 1e-9:  # MR 9.2.2.1: no cruise where v^2 / a > 1
        assert profile.triangle == (v * v > a)
    t = np.linspace(0.0, profile.duration, 41)
    s, sd, sdd = scaling("trapezoid", t, vel_limit=v, acc_limit=a)
    expected = np.array([reference.at_time(x) for x in t])[:, :, 0]  # (41, 3): p, v, a
    assert_close("s", s, expected[:, 0], 1e-9)
    assert_close("sd / v", sd / v, expected[:, 1] / v, 1e-9)
    # where the acceleration jumps (the ends too), Ruckig's and ours may sit on either side
    corners = np.array(
        [0.0, profile.ramp_time, profile.duration - profile.ramp_time, profile.duration]
    )
    away = np.min(np.abs(t[:, None] - corners), axis=1) > 1e-9
    assert_close("sdd / a", (sdd / a)[away], (expected[away, 2] / a), 1e-9)


@FAST
@given(v=limits, a=limits, seed=seeds, shape=st.sampled_from(BATCH_SHAPES))
def test_trapezoid_derivatives_and_peaks(
    v: float, a: float, seed: int, shape: tuple[int, ...]
) -> None:
    profile = trapezoid(vel_limit=v, acc_limit=a)
    T, ramp = profile.duration, profile.ramp_time
    h = 1e-5 * T
    t = np.random.default_rng(seed).uniform(0.0, T, shape)
    corners = np.array([0.0, ramp, T - ramp, T])
    t = np.where(np.min(np.abs(t[..., None] - corners), axis=-1) < 3 * h, T / 2 + 0.1 * ramp, t)
    s, sd, sdd = scaling("trapezoid", t, None, vel_limit=v, acc_limit=a)
    assert s.shape == shape
    fd, fdd = _fd("trapezoid", t, None, h, vel_limit=v, acc_limit=a)
    # s is piecewise quadratic: central differences are exact up to rounding
    assert_close("sd / v", sd / v, fd / v, 1e-6)
    assert_close("sdd / a", sdd / a, fdd / a, 1e-3)
    dense = np.linspace(0.0, T, 100_001)
    _, sd, sdd = scaling("trapezoid", dense, None, vel_limit=v, acc_limit=a)
    peak_v = min(v, math.sqrt(a))  # a triangle peaks at sqrt(a), below the velocity limit
    assert abs(sd.max() - peak_v) <= 1e-4 * peak_v
    assert np.abs(sdd).max() == pytest.approx(a, rel=1e-15)


def test_trapezoid_from_a_duration() -> None:
    # MR 9.2.2.1's three ways to choose two of v, a, T
    T = 3.0
    by_acc = trapezoid(T, acc_limit=1.0)  # a T^2 >= 4: v = (a T - sqrt(a^2 T^2 - 4 a)) / 2
    assert by_acc.acceleration == 1.0
    assert by_acc.velocity == pytest.approx((3.0 - math.sqrt(5.0)) / 2, rel=1e-14)
    by_vel = trapezoid(T, vel_limit=0.5)  # 1 < v T <= 2: a = v^2 / (v T - 1)
    assert by_vel.velocity == 0.5 and by_vel.acceleration == pytest.approx(0.5, rel=1e-14)
    triangle = trapezoid(T, vel_limit=1.0)  # v T > 2: the limit is out of reach, a triangle
    assert triangle.triangle and triangle.velocity == pytest.approx(2 / T, rel=1e-14)
    plain = trapezoid(T)  # Robotics Toolbox's default: cruise at 1.5 / T
    assert plain.velocity == pytest.approx(0.5) and plain.ramp_time == pytest.approx(T / 3)
    for profile in (by_acc, by_vel, triangle, plain):
        # the area under sd, v (T - v / a), is 1 exactly when T = 1 / v + v / a
        assert 1 / profile.velocity + profile.ramp_time == pytest.approx(T, rel=1e-14)
    # a duration and both limits, at least the minimum time: the acceleration is the limit, the
    # velocity within its limit
    shortest = trapezoid(vel_limit=0.5, acc_limit=1.0).duration
    profile = trapezoid(shortest * 1.2, vel_limit=0.5, acc_limit=1.0)
    assert profile.acceleration == 1.0 and profile.velocity < 0.5
    _, sd, _ = scaling(
        "trapezoid", np.linspace(0, 4, 40_001), shortest * 1.2, vel_limit=0.5, acc_limit=1.0
    )
    assert sd.max() <= 0.5
    # at exactly the minimum time: the minimum-time profile
    again = trapezoid(shortest, vel_limit=0.5, acc_limit=1.0)
    assert again.velocity == pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: scaling("quntic", 0.5, 1.0),
            "unknown scaling kind 'quntic'; did you mean 'quintic'?",
        ),
        (lambda: scaling(3, 0.5, 1.0), "unknown scaling kind 3"),
        (lambda: scaling("cubic", 0.5, 0.0), "duration must be finite and > 0 (s), got 0"),
        (lambda: scaling("cubic", 0.5, -2.0), "duration must be finite and > 0 (s), got -2"),
        (lambda: scaling("cubic", 0.5, math.nan), "duration must be finite and > 0"),
        (lambda: scaling("cubic", 0.5, "long"), "duration must be a number of seconds"),
        (lambda: scaling("cubic", [0.1, math.nan], 1.0), "t has NaN or inf entries"),
        (lambda: scaling("cubic", 0.5), "cubic needs a duration, or vel_limit or acc_limit"),
        (lambda: scaling("cubic", 0.5, vel_limit=-1.0), "vel_limit must be > 0 (1/s)"),
        (lambda: scaling("quintic", 0.5, acc_limit=0.0), "acc_limit must be > 0 (1/s^2)"),
        (lambda: scaling("cubic", 0.5, vel_limit=math.nan), "vel_limit must be > 0"),
        (
            lambda: scaling("cubic", 0.5, acc_limit="fast"),
            "acc_limit must be a number (1/s^2) or None",
        ),
        (lambda: scaling("quintic", 0.5, 1.0, vel_limit=1.0), "quintic needs at least 1.875 s"),
        (lambda: scaling("trapezoid", 0.5), "trapezoid needs acc_limit (and vel_limit, if any)"),
        (lambda: scaling("trapezoid", 0.5, vel_limit=1.0), "needs acc_limit"),
        (lambda: scaling("trapezoid", 0.5, 1.0, acc_limit=1.0), "it needs at least 2 s"),
        (lambda: scaling("trapezoid", 0.5, 1.0, vel_limit=0.5), "more than 2 s (1 / vel_limit)"),
        (
            lambda: scaling("trapezoid", 0.5, 2.2, vel_limit=0.5, acc_limit=1.0),
            "too short for vel_limit 0.5 1/s and acc_limit 1 1/s^2: it needs at least 2.5 s",
        ),
        (lambda: min_duration("trapezoid", 1.0), "trapezoid needs acc_limit"),
        (lambda: min_duration("cubic"), "cubic needs vel_limit or acc_limit"),
        (lambda: min_duration("cubc", 1.0), "did you mean 'cubic'?"),
    ],
)
def test_bad_input(call: object, message: str) -> None:
    with pytest.raises(InputError) as info:
        call()  # type: ignore[operator]
    text = str(info.value)
    assert message in text, text
    assert "\n" not in text
    assert text.split(":")[0] in ("scaling", "min_duration")


def test_an_infinite_limit_is_none() -> None:
    t = np.linspace(0.0, 3.0, 7)
    for got, expected in zip(
        scaling("trapezoid", t, None, vel_limit=math.inf, acc_limit=1.0),
        scaling("trapezoid", t, 2.0, vel_limit=None, acc_limit=1.0),  # the triangle's time
        strict=True,
    ):
        np.testing.assert_array_equal(got, expected)
