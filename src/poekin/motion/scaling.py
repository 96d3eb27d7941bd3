"""Time scalings ``s(t)``: the path parameter from 0 at rest to 1 at rest (Modern Robotics 9.2).

With ``tau = t / T``:

* ``"cubic"``: ``s = 3 tau^2 - 2 tau^3``; peak ``sd = 1.5 / T``, peak ``|sdd| = 6 / T^2``
  (at both ends);
* ``"quintic"``: ``s = 10 tau^3 - 15 tau^4 + 6 tau^5``, whose ``sdd`` is also 0 at both
  ends; peak ``sd = 1.875 / T``, peak ``|sdd| = (10 / sqrt(3)) / T^2``;
* ``"trapezoid"``: the trapezoidal velocity profile (MR 9.2.2.1): ``sdd = a`` for the ramp
  time ``v / a``, a cruise at ``sd = v``, ``sdd = -a`` to rest; a triangle (no cruise) where
  the peak velocity ``sqrt(a)`` falls short of the limit, ``v^2 / a > 1``.

The limits bound ``s`` itself (``vel_limit`` in 1/s, ``acc_limit`` in 1/s^2; a path of length
``L`` moves at ``L sd``). A duration of None asks for the shortest within the limits
(:func:`min_duration`). Outside ``[0, T]`` every scaling holds still: ``s = 0`` before, ``1``
after, ``sd = sdd = 0``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import InputError, did_you_mean

__all__ = ["KINDS", "TrapezoidProfile", "min_duration", "scaling", "trapezoid"]

FloatArray = NDArray[np.float64]
Scaled = tuple[FloatArray, FloatArray, FloatArray]  # s, sd, sdd

KINDS = ("cubic", "quintic", "trapezoid")

# peak sd * T and peak |sdd| * T^2 of the polynomial scalings
_PEAK_VEL = {"cubic": 1.5, "quintic": 1.875}
_PEAK_ACC = {"cubic": 6.0, "quintic": 10.0 / math.sqrt(3.0)}
# the trapezoid for a duration alone: cruise for its middle third (Robotics Toolbox's default)
_DEFAULT_CRUISE_VEL = 1.5


@dataclasses.dataclass(frozen=True)
class TrapezoidProfile:
    """A trapezoidal velocity profile of ``s`` from 0 to 1.

    Attributes:
        duration: ``T`` (s).
        velocity: the cruise (peak) velocity ``v`` of ``s`` (1/s).
        acceleration: ``a`` of ``s`` while speeding up and slowing down (1/s^2).
    """

    duration: float
    velocity: float
    acceleration: float

    @property
    def ramp_time(self) -> float:
        """The time spent speeding up (and slowing down), ``v / a`` (s)."""
        return self.velocity / self.acceleration

    @property
    def triangle(self) -> bool:
        """True where there is no cruise: the ramps meet at ``T / 2`` (``v^2 / a = 1``)."""
        return bool(2.0 * self.ramp_time >= self.duration * (1.0 - 1e-12))


def _kind(kind: object, func: str) -> str:
    if not isinstance(kind, str) or kind not in KINDS:
        raise InputError(f"{func}: unknown scaling kind {kind!r}; {did_you_mean(str(kind), KINDS)}")
    return kind


def _limit(value: float | None, name: str, unit: str, func: str) -> float | None:
    """A limit as a float, or None for none (None or inf)."""
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(
            f"{func}: {name} must be a number ({unit}) or None, got {value!r}"
        ) from None
    if math.isnan(x) or x <= 0.0:
        raise InputError(f"{func}: {name} must be > 0 ({unit}), or None for no limit, got {x:g}")
    return None if math.isinf(x) else x


def _duration(value: float | None, func: str) -> float | None:
    """A duration in seconds, or None for none."""
    return None if value is None else _seconds(value, "duration", func)


def _seconds(value: float, name: str, func: str) -> float:
    """A finite time > 0 (s)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{func}: {name} must be a number of seconds, got {value!r}") from None
    if not math.isfinite(x) or x <= 0.0:
        raise InputError(f"{func}: {name} must be finite and > 0 (s), got {x:g}")
    return x


def min_duration(
    kind: str, vel_limit: float | None = None, acc_limit: float | None = None
) -> float:
    """The shortest duration of scaling ``kind`` whose ``sd`` and ``sdd`` stay within the limits.

    Cubic and quintic: ``max(c_v / vel_limit, sqrt(c_a / acc_limit))`` with their peaks ``c_v``,
    ``c_a`` (module docstring). Trapezoid: ``1 / v + v / a``, or the triangle's ``2 / sqrt(a)``
    where ``v^2 / a > 1`` (MR 9.2.2.1).

    Args:
        kind: ``"cubic"``, ``"quintic"`` or ``"trapezoid"``.
        vel_limit: the largest ``sd`` (1/s); None or inf for none.
        acc_limit: the largest ``|sdd|`` (1/s^2); None or inf for none.

    Returns:
        The duration in seconds.

    Raises:
        InputError: an unknown kind, a limit that is not > 0, no limit at all, or a trapezoid
            without acc_limit.
    """
    func = "min_duration"
    kind = _kind(kind, func)
    v = _limit(vel_limit, "vel_limit", "1/s", func)
    a = _limit(acc_limit, "acc_limit", "1/s^2", func)
    if kind == "trapezoid":
        return _trapezoid(None, v, a, func).duration
    if v is None and a is None:
        raise InputError(f"{func}: {kind} needs vel_limit or acc_limit (or both) to set a duration")
    by_vel = _PEAK_VEL[kind] / v if v is not None else 0.0
    by_acc = math.sqrt(_PEAK_ACC[kind] / a) if a is not None else 0.0
    return max(by_vel, by_acc)


def trapezoid(
    duration: float | None = None,
    *,
    vel_limit: float | None = None,
    acc_limit: float | None = None,
) -> TrapezoidProfile:
    """The trapezoidal profile of ``s`` that two of duration, velocity and acceleration define.

    * the limits, no duration: the minimum-time profile, ``T = 1 / v + v / a``; where
      ``v^2 / a > 1``, or without ``vel_limit``, the velocity limit is never reached and the
      profile is the triangle ``v = sqrt(a)``, ``T = 2 / sqrt(a)``
      (:attr:`TrapezoidProfile.triangle`);
    * a duration and ``acc_limit``: that acceleration, ``v = (a T - sqrt(a^2 T^2 - 4 a)) / 2``
      (MR 9.2.2.1, it needs ``a T^2 >= 4``), which stays within ``vel_limit`` if one is given
      exactly when ``T`` is at least the minimum time;
    * a duration and ``vel_limit`` only: that cruise velocity, ``a = v^2 / (v T - 1)`` (it needs
      ``v T > 1``); where ``v T > 2`` the limit cannot be reached in ``T`` and the profile is the
      triangle ``v = 2 / T``;
    * a duration alone: a cruise at ``1.5 / T`` for the middle third (Robotics Toolbox's
      ``trapezoidal``).

    Args:
        duration: ``T`` (s), or None for the minimum time within the limits.
        vel_limit: the largest ``sd`` (1/s); None or inf for none.
        acc_limit: the largest ``|sdd|`` (1/s^2); None or inf for none.

    Returns:
        The profile.

    Raises:
        InputError: a duration or limit that is not finite and > 0, neither a duration nor
            ``acc_limit``, or a duration too short for the limits (the message gives the minimum).
    """
    func = "trapezoid"
    T = _duration(duration, func)
    v = _limit(vel_limit, "vel_limit", "1/s", func)
    a = _limit(acc_limit, "acc_limit", "1/s^2", func)
    return _trapezoid(T, v, a, func)


def _trapezoid(T: float | None, v: float | None, a: float | None, func: str) -> TrapezoidProfile:
    """:func:`trapezoid` on checked inputs (None: no duration, no limit); errors name ``func``."""
    if T is None:
        if a is None:
            raise InputError(
                f"{func}: the minimum-time trapezoid needs acc_limit (and vel_limit, if any), "
                "or give it a duration"
            )
        if v is None or v * v > a:  # the ramps meet before reaching v: a triangle
            peak = math.sqrt(a)
            return TrapezoidProfile(2.0 / peak, peak, a)
        return TrapezoidProfile(1.0 / v + v / a, v, a)
    if a is not None:
        if a * T * T < 4.0:
            raise InputError(
                f"{func}: duration {T:g} s is too short for acc_limit {a:g} 1/s^2: "
                f"it needs at least {2.0 / math.sqrt(a):g} s (2 / sqrt(acc_limit))"
            )
        # (a T - root) / 2 without the cancellation
        cruise = 2.0 * a / (a * T + math.sqrt(max(a * a * T * T - 4.0 * a, 0.0)))
        if v is not None and cruise > v * (1.0 + 1e-12):
            shortest = _trapezoid(None, v, a, func).duration
            raise InputError(
                f"{func}: duration {T:g} s is too short for vel_limit {v:g} 1/s and acc_limit "
                f"{a:g} 1/s^2: it needs at least {shortest:g} s"
            )
        return TrapezoidProfile(T, cruise, a)
    if v is not None:
        if v * T <= 1.0:
            raise InputError(
                f"{func}: duration {T:g} s is too short for vel_limit {v:g} 1/s: it needs more "
                f"than {1.0 / v:g} s (1 / vel_limit)"
            )
        if v * T >= 2.0:
            return TrapezoidProfile(T, 2.0 / T, 4.0 / (T * T))
        return TrapezoidProfile(T, v, v * v / (v * T - 1.0))
    cruise = _DEFAULT_CRUISE_VEL / T
    return TrapezoidProfile(T, cruise, cruise * cruise / (cruise * T - 1.0))


def scaling(
    kind: str,
    t: ArrayLike,
    duration: float | None = None,
    *,
    vel_limit: float | None = None,
    acc_limit: float | None = None,
) -> Scaled:
    """The time scaling ``s(t)`` and its exact derivatives ``sd = ds/dt``, ``sdd = d2s/dt2``.

    Shapes: ``t (...)`` gives ``s, sd, sdd (...)`` each. Outside ``[0, T]``, ``s`` is 0 before
    and 1 after, ``sd = sdd = 0``. Where ``sdd`` jumps (the ends of the cubic, the trapezoid's
    corners), ``t`` on a corner gets the value of the phase it starts: ``sdd(0) = 6 / T^2`` for
    the cubic, ``a`` for the trapezoid, and ``sdd(T) = -6 / T^2``, ``-a``.

    Args:
        kind: ``"cubic"``, ``"quintic"`` or ``"trapezoid"`` (module docstring).
        t: times (s).
        duration: ``T`` (s). None: the shortest within the limits (:func:`min_duration`).
        vel_limit: the largest ``sd`` (1/s); None or inf for none. With a duration, the
            polynomial scalings check it; the trapezoid is built from it (:func:`trapezoid`).
        acc_limit: the largest ``|sdd|`` (1/s^2); None or inf for none; likewise.

    Returns:
        ``(s, sd, sdd)``, float64 arrays of ``t``'s shape.

    Raises:
        InputError: an unknown kind (with the nearest name), NaN or inf times, a duration or
            limit that is not > 0, no duration and no limit, or a duration too short for the
            limits (the message gives the minimum).
    """
    func = "scaling"
    kind = _kind(kind, func)
    T = _duration(duration, func)
    v = _limit(vel_limit, "vel_limit", "1/s", func)
    a = _limit(acc_limit, "acc_limit", "1/s^2", func)
    tt = np.asarray(t, dtype=np.float64)
    if not np.all(np.isfinite(tt)):
        raise InputError(f"{func}: t has NaN or inf entries; give finite times (s)")
    if kind == "trapezoid":
        return _trapezoid_at(_trapezoid(T, v, a, func), tt)
    if T is None:
        if v is None and a is None:
            raise InputError(f"{func}: {kind} needs a duration, or vel_limit or acc_limit")
        T = min_duration(kind, v, a)
    else:
        shortest = min_duration(kind, v, a) if (v is not None or a is not None) else 0.0
        if shortest > T * (1.0 + 1e-12):
            raise InputError(
                f"{func}: duration {T:g} s is too short for the limits: {kind} needs at least "
                f"{shortest:g} s (or give duration=None for the shortest)"
            )
    return _polynomial_at(kind, tt, T)


def _polynomial_at(kind: str, t: FloatArray, T: float) -> Scaled:
    tau = np.clip(t / T, 0.0, 1.0)
    inside = (t >= 0.0) & (t <= T)
    if kind == "cubic":
        s = tau * tau * (3.0 - 2.0 * tau)
        sd = 6.0 * tau * (1.0 - tau) / T
        sdd = (6.0 - 12.0 * tau) / (T * T)
    else:
        s = tau**3 * (10.0 + tau * (-15.0 + 6.0 * tau))
        sd = 30.0 * tau**2 * (1.0 - tau) ** 2 / T
        sdd = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / (T * T)
    zero = np.zeros_like(tau)
    return s, np.where(inside, sd, zero), np.where(inside, sdd, zero)


def _trapezoid_at(profile: TrapezoidProfile, t: FloatArray) -> Scaled:
    T, v, a = profile.duration, profile.velocity, profile.acceleration
    ramp = min(profile.ramp_time, T / 2.0)
    u = np.clip(t, 0.0, T)
    rest = T - u  # time left
    speeding = u < ramp
    slowing = rest < ramp
    s = np.where(speeding, 0.5 * a * u * u, np.where(slowing, 1.0 - 0.5 * a * rest * rest, 0.0))
    cruise = ~(speeding | slowing)
    s = np.where(cruise, v * u - 0.5 * v * ramp, s)
    sd = np.where(speeding, a * u, np.where(slowing, a * rest, v))
    sdd = np.where(speeding, a, np.where(slowing, -a, 0.0))
    inside = (t >= 0.0) & (t <= T)
    s = np.where(t > T, 1.0, np.where(t < 0.0, 0.0, s))
    zero = np.zeros_like(u)
    return s, np.where(inside, sd, zero), np.where(inside, sdd, zero)
