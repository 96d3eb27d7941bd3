"""Joint-space trajectories, sampled at a rate: between two configurations under a time scaling,
and through via points with parabolic blends.

* :func:`joint_trajectory`: ``q(t) = q0 + s(t) (q1 - q0)`` (Modern Robotics'
  ``JointTrajectory``, 9.2) for a scaling of :func:`poekin.motion.scaling`, its duration
  given or the shortest within per-joint velocity and acceleration limits;
* :func:`via_trajectory`: straight segments between via points, each at the speed of its
  slowest joint at ``qdmax`` (Robotics Toolbox's ``mstraj``), joined by parabolic blends of time
  ``tacc``: constant acceleration from one segment's velocity to the next, centred on the via
  point's time. It starts at the first via point and ends at the last, at rest; it passes by the
  others at ``(qd_out - qd_in) tacc / 8``, never faster than ``qdmax``.

Both return a :class:`JointTrajectory` sampled at ``t = k / rate``, from 0 to the first sample
at or after the end, where the robot holds still. Maths only, no I/O.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import InputError
from poekin.motion.scaling import _kind, _seconds, min_duration, scaling

__all__ = ["JointTrajectory", "joint_trajectory", "via_trajectory"]

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class JointTrajectory:
    """Joint values over time, sampled at a rate.

    Attributes:
        t: sample times ``(N,)`` (s), ``k / rate``.
        q: joint values ``(N, ..., n)``.
        qd: joint velocities ``(N, ..., n)``.
        qdd: joint accelerations ``(N, ..., n)``.
        duration: the motion's time (s); the last sample is the first at or after it, at rest.
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    duration: float


def _rate(rate: float, func: str) -> float:
    try:
        r = float(rate)
    except (TypeError, ValueError):
        raise InputError(
            f"{func}: rate must be a number of samples per second (Hz), got {rate!r}"
        ) from None
    if not math.isfinite(r) or r <= 0.0:
        raise InputError(f"{func}: rate must be finite and > 0 (Hz), got {r:g}")
    return r


def _times(duration: float, rate: float) -> FloatArray:
    """``k / rate`` for ``k = 0 ...`` up to the first at or after ``duration``."""
    n = math.ceil(duration * rate * (1.0 - 1e-12)) + 1
    return np.arange(n, dtype=np.float64) / rate


def _joints(value: ArrayLike, name: str, func: str) -> FloatArray:
    q = np.asarray(value, dtype=np.float64)
    if q.ndim == 0:
        raise InputError(f"{func}: {name} must be joint values (..., n), got a scalar")
    if not np.all(np.isfinite(q)):
        raise InputError(f"{func}: {name} has NaN or inf entries; give finite joint values")
    return q


def _per_joint(
    value: ArrayLike | None, n: int, name: str, unit: str, func: str
) -> FloatArray | None:
    """A limit per joint ``(n,)`` (a scalar for all); inf for none. None stays None."""
    if value is None:
        return None
    x = np.asarray(value, dtype=np.float64)
    if x.ndim > 1 or (x.ndim == 1 and x.shape[0] != n):
        raise InputError(
            f"{func}: {name} must be one value or one per joint ({n},), got shape {x.shape}"
        )
    x = np.broadcast_to(x, (n,))
    bad = np.flatnonzero(~(x > 0.0))  # NaN too
    if bad.size:
        j = int(bad[0])
        raise InputError(f"{func}: {name} must be > 0 ({unit}), got {x[j]:g} for joint {j}")
    return x


def _s_limit(limit: FloatArray | None, span: FloatArray) -> float | None:
    """The limit on ``s`` that keeps every joint moving by ``span (..., n)`` within ``limit``."""
    if limit is None:
        return None
    with np.errstate(divide="ignore"):
        ratio = limit / np.abs(span)
    value = float(np.min(ratio)) if ratio.size else math.inf
    return None if math.isinf(value) else value


def joint_trajectory(
    q0: ArrayLike,
    q1: ArrayLike,
    duration: float | None = None,
    *,
    kind: str = "quintic",
    vel_limits: ArrayLike | None = None,
    acc_limits: ArrayLike | None = None,
    rate: float = 500.0,
) -> JointTrajectory:
    """The straight joint-space motion ``q0 + s(t) (q1 - q0)`` from rest to rest.

    Every joint starts and ends together; with limits, the binding joint sets the time (the
    limit on ``s`` is ``min_j limit_j / |q1_j - q0_j|``), and the trapezoid reaches it.

    Args:
        q0: start ``(..., n)``.
        q1: end ``(..., n)``, broadcast with ``q0``; a batch moves on one clock.
        duration: the motion's time (s); None for the shortest within the limits.
        kind: the time scaling, ``"cubic"``, ``"quintic"`` or ``"trapezoid"``
            (:func:`poekin.motion.scaling`).
        vel_limits: the largest ``|qd|`` per joint ``(n,)``, or one for all (rad/s; inf for
            none).
        acc_limits: the largest ``|qdd|`` per joint, likewise (rad/s^2).
        rate: samples per second (Hz).

    Returns:
        The samples, ``q (N, ..., n)``. Where nothing moves and no duration is given, one
        sample at ``t = 0``.

    Raises:
        InputError: NaN, shapes that do not broadcast, a limit that is not > 0 (naming the
            joint), neither a duration nor a limit, a duration shorter than the limits allow
            (the message gives the shortest), an unknown kind, or a rate that is not > 0.
    """
    func = "joint_trajectory"
    kind = _kind(kind, func)
    r = _rate(rate, func)
    a, b = _joints(q0, "q0", func), _joints(q1, "q1", func)
    try:
        shape = np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        raise InputError(
            f"{func}: q0 {a.shape} and q1 {b.shape} do not broadcast together"
        ) from None
    a = np.broadcast_to(a, shape)
    span = np.broadcast_to(b, shape) - a
    n = shape[-1]
    v = _s_limit(_per_joint(vel_limits, n, "vel_limits", "rad/s", func), span)
    acc = _s_limit(_per_joint(acc_limits, n, "acc_limits", "rad/s^2", func), span)
    if duration is None:
        if vel_limits is None and acc_limits is None:
            raise InputError(
                f"{func}: give a duration, or vel_limits and/or acc_limits to find one"
            )
        if v is None and acc is None:  # nothing moves (or no joint that moves has a limit)
            if np.any(span != 0.0):
                raise InputError(
                    f"{func}: the joints that move have no finite limit; give a duration"
                )
            zero = np.zeros((1, *shape))
            return JointTrajectory(np.zeros(1), a[None].copy(), zero, zero.copy(), 0.0)
        if kind == "trapezoid" and acc is None:
            raise InputError(
                f"{func}: the minimum-time trapezoid needs acc_limits (rad/s^2), or give a duration"
            )
        T = min_duration(kind, v, acc)
    else:
        T = _seconds(duration, "duration", func)
        shortest = min_duration(kind, v, acc) if (v is not None or acc is not None) else 0.0
        if shortest > T * (1.0 + 1e-12):
            raise InputError(
                f"{func}: duration {T:g} s is too short for the joint limits: {kind} needs at "
                f"least {shortest:.6g} s (or give duration=None for the shortest)"
            )
    t = _times(T, r)
    s, sd, sdd = scaling(kind, t, T, vel_limit=v, acc_limit=acc)
    grow = (slice(None),) + (None,) * len(shape)
    return JointTrajectory(t, a + s[grow] * span, sd[grow] * span, sdd[grow] * span, T)


def via_trajectory(
    via: ArrayLike,
    *,
    tacc: float,
    qdmax: ArrayLike | None = None,
    durations: ArrayLike | None = None,
    rate: float = 500.0,
) -> JointTrajectory:
    """Straight joint-space segments through via points, joined by parabolic blends.

    Segment ``i`` (from ``via[i]`` to ``via[i + 1]``) lasts ``durations[i]``, or, with
    ``qdmax``, the time its slowest joint takes at its ``qdmax``, ``max_j |dq_j| / qdmax_j``
    (as Robotics Toolbox's ``mstraj``), and at least ``tacc``. Around each via point's time a
    blend of time ``tacc`` accelerates at ``(qd_out - qd_in) / tacc`` from one segment's
    velocity to the next (from and to rest at the first and last via point). The motion takes
    ``sum(segment times) + tacc``; the segments' velocities bound ``|qd|`` throughout.

    Args:
        via: via points ``(M, n)``, ``M >= 2``; the motion starts at the first, ends at the last.
        tacc: the blend time (s), ``> 0``.
        qdmax: the largest speed per joint ``(n,)``, or one for all (rad/s; inf for none).
        durations: the segments' times ``(M - 1,)`` (s), each at least ``tacc``, instead of
            ``qdmax``.
        rate: samples per second (Hz).

    Returns:
        The samples, ``q (N, n)``.

    Raises:
        InputError: fewer than two via points, NaN, a ``tacc``, rate, speed or duration that is
            not > 0, neither or both of ``qdmax`` and ``durations``, or a duration under
            ``tacc``.
    """
    func = "via_trajectory"
    r = _rate(rate, func)
    points = _joints(via, "via", func)
    if points.ndim != 2 or points.shape[0] < 2:
        raise InputError(
            f"{func}: via must be at least two via points (M, n), got shape {points.shape}"
        )
    blend = _seconds(tacc, "tacc", func)
    steps = np.diff(points, axis=0)  # (M - 1, n)
    if (qdmax is None) == (durations is None):
        raise InputError(
            f"{func}: give one of qdmax (rad/s) and durations (s), not "
            + ("both" if qdmax is not None else "neither")
        )
    if durations is not None:
        times = np.asarray(durations, dtype=np.float64)
        if times.shape != (len(steps),):
            raise InputError(
                f"{func}: durations must be one per segment ({len(steps)},), "
                f"got shape {times.shape}"
            )
        short = np.flatnonzero(~(times >= blend))  # NaN too
        if short.size:
            i = int(short[0])
            raise InputError(
                f"{func}: durations must be at least tacc ({blend:g} s), got {times[i]:g} s "
                f"for segment {i}"
            )
    else:
        speed = _per_joint(qdmax, points.shape[1], "qdmax", "rad/s", func)
        with np.errstate(divide="ignore", invalid="ignore"):
            slowest = np.max(np.where(steps != 0.0, np.abs(steps) / speed, 0.0), axis=1)
        times = np.maximum(slowest, blend)
    velocity = steps / times[:, None]  # (M - 1, n), each segment's
    rest = np.zeros((1, points.shape[1]))
    v_in = np.concatenate([rest, velocity])  # (M, n): into each via point ...
    v_out = np.concatenate([velocity, rest])  # ... and out of it
    at = blend / 2 + np.concatenate([[0.0], np.cumsum(times)])  # (M,): the via points' times
    total = float(at[-1] + blend / 2)
    t = _times(total, r)
    u = np.minimum(t, total)
    k = np.clip(np.searchsorted(at, u), 1, len(at) - 1)  # at[k - 1] < u <= at[k]
    k = np.where(u - at[k - 1] < at[k] - u, k - 1, k)  # the nearest via point
    dt = u - at[k]  # to it
    # a blend from its start to just before its end (a corner takes the phase it starts, as in
    # poekin.motion.scaling); the first and the last reach the ends, from and to rest
    in_blend = ((-blend / 2 <= dt) & (dt < blend / 2)) | (u <= at[0]) | (u >= at[-1])
    seg = np.where(dt > 0, k, k - 1).clip(0, len(times) - 1)  # the segment around u otherwise
    line = points[seg] + velocity[seg] * (u - at[seg])[:, None]
    w = (dt + blend / 2)[:, None]  # time into the blend
    dv = v_out[k] - v_in[k]
    start = points[k] - v_in[k] * (blend / 2)
    q = np.where(in_blend[:, None], start + v_in[k] * w + dv * w * w / (2 * blend), line)
    qd = np.where(in_blend[:, None], v_in[k] + dv * w / blend, velocity[seg])
    qdd = np.where(in_blend[:, None], dv / blend, 0.0)
    zero = np.zeros_like(qd)
    qd = np.where((t >= total)[:, None], zero, qd)  # at rest from the end (exactly)
    qdd = np.where((t > total)[:, None], zero, qdd)
    return JointTrajectory(t, q, qd, qdd, total)
