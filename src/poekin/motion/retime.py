"""The fastest timing of a joint path within per-joint velocity and acceleration limits, and,
with jerk limits, a jerk-limited motion through the same waypoints.

:func:`retime` takes waypoints ``q_path (N, n)``. The path through them is the not-a-knot
cubic spline at uniform parameter ``s = linspace(0, 1, N)``: toppra's ``SplineInterpolator``
(scipy's ``CubicSpline``) on ``np.linspace(0, 1, N)``, computed here in NumPy. Its time-optimal
parameterisation ``s(t)`` is TOPP-RA (:mod:`poekin.motion._topp`, written here, no dependency;
its durations agree with toppra's to well under 1%: ``tests/motion/test_retime.py``,
``benchmarks/bench_motion.py``), at rest at both ends.

The guarantee: the limits hold on the whole continuous motion, not only at the grid points of
the parameterisation. The peaks of ``|qd|`` and ``|qdd|`` between the grid points are found in
closed form (:func:`poekin.motion._topp.peaks`), and the motion is slowed uniformly in time by
the factor that brings them within the limits (``qd`` scales as ``1/c``, ``qdd`` as ``1/c^2``),
then to a whole number of control ticks. So every sample, and every finite difference of the
samples' ``q``, is within every limit (up to rounding, 1e-9 relative margin).

With ``jerk_limits`` the motion is Ruckig's (the ``motion`` extra): one time-synchronised,
jerk-limited Ruckig trajectory per pair of consecutive waypoints, from each waypoint's velocity
on the velocity- and acceleration-limited timing (and zero acceleration there) to the next's.
It passes every waypoint, at a control tick, with continuous velocity and acceleration, within
all three limits everywhere (Ruckig's guarantee; checked by the tests at every sample), but
between the waypoints it follows Ruckig's profiles, not the spline.
"""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin._extras import require
from poekin._poe import real_array
from poekin.errors import InputError
from poekin.motion import _topp
from poekin.motion._spline import Spline, not_a_knot

__all__ = ["Retimed", "retime"]

FloatArray = NDArray[np.float64]

MARGIN = 1e-9  # relative: what the slow-down adds for rounding in the peaks


@dataclasses.dataclass(frozen=True)
class Retimed:
    """A joint motion sampled at a control rate (:func:`retime`'s result).

    Attributes:
        t: ``(K,)`` sample times (s), ``k / rate``, from 0 to :attr:`duration`.
        q: ``(K, n)`` joint values; ``q[0]`` and ``q[-1]`` are the path's first and last
            waypoints, exactly.
        qd: ``(K, n)`` joint velocities (0 at both ends).
        qdd: ``(K, n)`` joint accelerations.
        s: ``(K,)`` the path parameter at each sample (the spline's, in ``[0, 1]``); ``None``
            with jerk limits (the motion leaves the spline between waypoints).
        waypoint_times: ``(N,)`` when the motion passes each waypoint (s).
        duration: ``t[-1]`` (s).
        optimal_duration: the time-optimal duration on the parameterisation's grid, before the
            slow-down that keeps the motion between grid points and the ticks within the
            limits (s); with jerk limits, that of the velocity- and acceleration-limited motion.
        rate: the control rate (Hz).
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    s: FloatArray | None
    waypoint_times: FloatArray
    duration: float
    optimal_duration: float
    rate: float


def _limits(value: ArrayLike, n: int, name: str, unit: str, *, infinite: bool) -> FloatArray:
    """``(n,)`` limits from a scalar or ``(n,)``, each > 0 (``inf`` allowed if ``infinite``)."""
    arr = real_array(value, f"retime: {name}")
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != n):
        raise InputError(
            f"retime: {name} must be one number or one per joint (shape ({n},)), "
            f"got shape {arr.shape}"
        )
    arr = np.broadcast_to(arr, (n,))
    for j, v in enumerate(arr):
        if math.isnan(v) or v <= 0.0 or (math.isinf(v) and not infinite):
            allowed = " or inf for none" if infinite else ", finite"
            raise InputError(
                f"retime: {name} must be > 0 ({unit}){allowed}, got {v:g} for joint {j}"
            )
    return np.array(arr)


def _grid(spline: Spline, per_interval: int) -> FloatArray:
    """``(M + 1,)`` the knots, each interval cut into ``per_interval`` equal stages."""
    k = spline.knots
    frac = np.arange(per_interval) / per_interval
    inner = (k[:-1, None] + np.diff(k)[:, None] * frac).ravel()
    return np.append(inner, 1.0)


def _topp_timing(
    spline: Spline, vel: FloatArray, acc: FloatArray, stages: int
) -> tuple[FloatArray, FloatArray, FloatArray, float, float]:
    """The grid, ``sd`` at its points and ``sdd`` on its stages, slowed within the limits
    everywhere; the grid's optimal duration and the slow-down factor."""
    intervals = len(spline.knots) - 1
    s = _grid(spline, max(1, math.ceil(stages / intervals)))
    dq, ddq = spline(s, 1), spline(s, 2)
    x, u = _topp.solve(s, dq, ddq, vel, acc)
    D = np.diff(s)
    sd = np.sqrt(x)
    optimal = float(np.sum(2.0 * D / (sd[:-1] + sd[1:])))
    dddq = spline(0.5 * (s[:-1] + s[1:]), 3)  # constant on each stage
    vel_peak, acc_peak = _topp.peaks(D, x, u, dq, ddq, dddq)
    slow = max(1.0, float(np.max(vel_peak / vel)), math.sqrt(float(np.max(acc_peak / acc))))
    return s, sd, u, optimal, slow * (1.0 + MARGIN)


def _sample(
    spline: Spline, s: FloatArray, sd: FloatArray, u: FloatArray, c: float, t: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """``s, q, qd, qdd`` at times ``t`` of the motion slowed ``c`` times, and the times at the
    grid points."""
    sd, u = sd / c, u / (c * c)
    D = np.diff(s)
    T = np.concatenate([[0.0], np.cumsum(2.0 * D / (sd[:-1] + sd[1:]))])
    i = np.clip(np.searchsorted(T, t, side="right") - 1, 0, len(D) - 1)
    tau = t - T[i]
    path = np.clip(s[i] + sd[i] * tau + 0.5 * u[i] * tau * tau, s[i], s[i + 1])
    speed = np.maximum(sd[i] + u[i] * tau, 0.0)[:, None]
    dq = spline(path, 1)
    q = spline(path)
    qd = dq * speed
    qdd = dq * u[i][:, None] + spline(path, 2) * speed * speed
    return path, q, qd, qdd, T


def retime(
    q_path: ArrayLike,
    vel_limits: ArrayLike,
    acc_limits: ArrayLike,
    *,
    jerk_limits: ArrayLike | None = None,
    rate: float = 500.0,
    stages: int = 1000,
) -> Retimed:
    """The fastest motion along the spline through ``q_path`` within the limits, at rest at
    both ends, sampled at ``rate``.

    Args:
        q_path: ``(N, n)`` waypoints, ``N >= 2`` (rad, m); the path is the not-a-knot cubic
            spline through them at ``s = linspace(0, 1, N)`` (toppra's ``SplineInterpolator``).
        vel_limits: ``(n,)`` or one number: each joint's largest speed (rad/s, m/s), > 0;
            ``inf`` for none, as :attr:`poekin.Tree.joint_velocity_limits` gives (a URDF's
            ``<limit velocity>``), so ``tree.joint_velocity_limits`` can be passed as it is.
        acc_limits: ``(n,)`` or one number: each joint's largest acceleration (rad/s^2), > 0
            and finite (MJCF and URDF give none).
        jerk_limits: ``(n,)`` or one number (rad/s^3), > 0: a jerk-limited motion through the
            waypoints by Ruckig (the ``motion`` extra; finite velocity limits needed), see the
            module's text.
        rate: samples per second (Hz), > 0.
        stages: how many stages (at least, >= 2) the parameterisation's grid has; more is
            closer to the continuous optimum and slower (the default is within about 0.2% of
            it on the tests' paths).

    Returns:
        :class:`Retimed`: ``t (K,)``, ``q, qd, qdd (K, n)``, every sample within every limit.

    Raises:
        InputError: fewer than 2 waypoints, NaN or inf in ``q_path``, limits that are not > 0
            or not one per joint (infinite where they must be finite), a rate that is not a
            finite number > 0, ``stages`` below 2.
        MissingExtraError: ``jerk_limits`` without Ruckig installed.
    """
    q = real_array(q_path, "retime: q_path")
    if q.ndim != 2 or q.shape[0] < 2 or q.shape[1] < 1:
        raise InputError(
            f"retime: q_path must be waypoints (N, n) with N >= 2, got shape {q.shape}"
        )
    bad = np.argwhere(~np.isfinite(q))
    if len(bad):
        raise InputError(
            f"retime: q_path has NaN or inf (waypoint {bad[0][0]}, joint {bad[0][1]}); "
            "give finite joint values"
        )
    n = q.shape[1]
    vel = _limits(vel_limits, n, "vel_limits", "rad/s", infinite=jerk_limits is None)
    acc = _limits(acc_limits, n, "acc_limits", "rad/s^2", infinite=False)
    jerk = (
        None
        if jerk_limits is None
        else _limits(jerk_limits, n, "jerk_limits", "rad/s^3", infinite=False)
    )
    if isinstance(rate, bool) or not isinstance(rate, numbers.Real) or not rate > 0.0:
        raise InputError(f"retime: rate must be > 0 (Hz), got {rate!r}")
    if not math.isfinite(rate):
        raise InputError(f"retime: rate must be finite (Hz), got {rate!r}")
    if isinstance(stages, bool) or not isinstance(stages, numbers.Integral) or stages < 2:
        raise InputError(f"retime: stages must be a whole number >= 2, got {stages!r}")
    rate = float(rate)
    spline = not_a_knot(q)
    if not np.any(spline.c[:3]):  # every waypoint the same: nothing to move
        zero = np.zeros((1, n))
        return Retimed(
            t=np.zeros(1),
            q=q[:1].copy(),
            qd=zero,
            qdd=zero.copy(),
            s=np.zeros(1),
            waypoint_times=np.zeros(len(q)),
            duration=0.0,
            optimal_duration=0.0,
            rate=rate,
        )
    s, sd, u, optimal, slow = _topp_timing(spline, vel, acc, int(stages))
    ticks = math.ceil(slow * optimal * rate)
    c = ticks / (optimal * rate)  # >= slow: the end on a tick
    t = np.arange(ticks + 1) / rate
    path, qs, qd, qdd, T = _sample(spline, s, sd, u, c, t)
    path[-1], qs[-1], qd[-1] = 1.0, q[-1], 0.0
    on_knots = np.searchsorted(s, spline.knots)
    if jerk is None:
        return Retimed(
            t=t,
            q=qs,
            qd=qd,
            qdd=qdd,
            s=path,
            waypoint_times=T[on_knots],
            duration=float(t[-1]),
            optimal_duration=optimal,
            rate=rate,
        )
    speed = sd[on_knots] / c
    return _jerk_limited(q, spline(spline.knots, 1) * speed[:, None], vel, acc, jerk, rate, optimal)


def _jerk_limited(
    q: FloatArray,
    qd: FloatArray,
    vel: FloatArray,
    acc: FloatArray,
    jerk: FloatArray,
    rate: float,
    optimal: float,
) -> Retimed:
    """Ruckig from waypoint to waypoint (velocities ``qd (N, n)``, zero acceleration), each
    segment a whole number of ticks."""
    ruckig = require("ruckig", "motion", "retime with jerk_limits")
    n = q.shape[1]
    otg = ruckig.Ruckig(n, 1.0 / rate)
    inp = ruckig.InputParameter(n)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = vel.tolist(), acc.tolist(), jerk.tolist()
    inp.duration_discretization = ruckig.DurationDiscretization.Discrete
    qd = np.clip(qd, -vel, vel)
    qd[0] = qd[-1] = 0.0
    pos, vels, accs, times = [q[:1]], [np.zeros((1, n))], [np.zeros((1, n))], [0.0]
    start = 0
    for k in range(len(q) - 1):
        inp.current_position, inp.current_velocity = q[k].tolist(), qd[k].tolist()
        inp.current_acceleration = [0.0] * n
        inp.target_position, inp.target_velocity = q[k + 1].tolist(), qd[k + 1].tolist()
        inp.target_acceleration = [0.0] * n
        traj = ruckig.Trajectory(n)
        otg.calculate(inp, traj)  # Ruckig's Python module raises RuckigError on any failure
        m = round(traj.duration * rate)
        states = [traj.at_time(j / rate) for j in range(1, m + 1)]
        p = np.array([st[0] for st in states]).reshape(m, n)
        p[-1] = q[k + 1]
        pos.append(p)
        vels.append(np.array([st[1] for st in states]).reshape(m, n))
        accs.append(np.array([st[2] for st in states]).reshape(m, n))
        start += m
        times.append(start / rate)
    qd_all = np.concatenate(vels)
    qd_all[-1] = 0.0
    t = np.arange(start + 1) / rate
    return Retimed(
        t=t,
        q=np.concatenate(pos),
        qd=qd_all,
        qdd=np.concatenate(accs),
        s=None,
        waypoint_times=np.array(times),
        duration=float(t[-1]),
        optimal_duration=optimal,
        rate=rate,
    )
