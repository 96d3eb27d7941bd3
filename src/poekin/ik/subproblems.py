"""Paden-Kahan subproblems: the rotations about known axes that move known vectors into known
places, solved in closed form and batched. Analytic IK (:mod:`poekin.ik.analytic`) splits a
6-joint arm into a sequence of them.

References: R. M. Murray, Z. Li and S. S. Sastry, *A Mathematical Introduction to Robotic
Manipulation* (1994), section 3.2; K. M. Lynch and F. C. Park, *Modern Robotics* (2017),
chapter 6; A. J. Elias and J. T. Wen, "IK-Geo: Unified robot inverse kinematics using
subproblem decomposition" (arXiv:2211.05737; code: github.com/rpiRobotics/ik-geo), whose
numbering and notation these follow (``rot(k, theta)`` is the rotation about the unit axis ``k`` by
``theta``; every axis passes through the origin, so the vectors are directions or points
relative to a point on the axes).

Each public function takes NumPy arrays whose last axis has length 3 (vectors) or none (scalars),
broadcast together over their leading axes, and returns the angles in ``(-pi, pi]`` and a flag
``exists``: True where an exact solution exists, to the relative tolerance ``tol`` (the
equation's residual at the returned angle is at most about ``tol`` times the size of its
vectors). Where none exists the least-squares angle comes back (still finite). Problems with
two solutions return both on a new last axis of length 2, the ``+`` root first; a tangent
(double) root comes back twice.

Where a circle the solution runs on shrinks to a point (``p`` on the axis ``k``: every angle
solves the equation, or none does), the angle is a convention, documented on each function.

The ``*_cs`` functions are the same solvers on *entries* (:mod:`poekin._pose`: a vector is
three arrays, or three Python floats for a constant) returning cosines and sines instead of
angles; the IK chains them without an ``atan2`` and a ``sin``/``cos`` between steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose
from poekin.errors import InputError

__all__ = [
    "TOL",
    "CosSin",
    "Quadratic",
    "rotate",
    "sp1",
    "sp1_cs",
    "sp2",
    "sp2_cs",
    "sp3",
    "sp3_cs",
    "sp4",
    "sp4_cs",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Entry = Any
Vec = tuple[Entry, Entry, Entry]

#: Default relative tolerance of the ``exists`` flags: an equation counts as solved exactly when
#: its residual is below this times the size of its vectors (rounding is ~1e-16).
TOL = 1e-12

# A circle whose radius is below this times the size of its vectors counts as a point, and its
# angle is the documented convention (the residual that convention leaves is below it).
_DEGENERATE = 1e-13

_SIGNS = np.array([1.0, -1.0])  # the + root, then the - root


class CosSin(NamedTuple):
    """An angle as its cosine and sine (entries)."""

    c: Entry
    s: Entry


class Quadratic(NamedTuple):
    """Two roots of a subproblem (each :class:`CosSin` entry has a last axis of 2: ``+``, ``-``),
    whether they are exact, and whether the circle was a point (the convention applied)."""

    root: CosSin
    exists: Entry
    degenerate: Entry


# --- entries -----------------------------------------------------------------------------------


def dot(a: Sequence[Entry], b: Sequence[Entry]) -> Entry:
    return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2]


def sub(a: Sequence[Entry], b: Sequence[Entry]) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def add(a: Sequence[Entry], b: Sequence[Entry]) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def lift(v: Sequence[Entry]) -> Vec:
    """Each array entry of ``v`` with a new last axis (of 1), for a solver that adds one."""
    return tuple(x[..., None] if isinstance(x, np.ndarray) else x for x in v)  # type: ignore[return-value]


def unit(x: Entry, y: Entry) -> CosSin:
    """``(x, y) / |(x, y)|``; ``(1, 0)`` where both are zero (angle 0). The norm is
    ``sqrt(x^2 + y^2)`` (no overflow at these sizes), which the compiled kernel vectorises
    to the same bits."""
    r = np.sqrt(x * x + y * y)
    zero = r == 0.0
    safe = np.where(zero, 1.0, r)
    return CosSin(np.where(zero, 1.0, x / safe), y / safe)


def rotate(k: Sequence[Entry], a: CosSin, p: Sequence[Entry]) -> Vec:
    """``rot(k, theta) p`` for a unit ``k`` and ``theta``'s cosine and sine:
    ``(k.p) k + c (p - (k.p) k) + s (k x p)``."""
    kp = dot(k, p)
    kxp = _pose.cross(k, p)
    return tuple(  # type: ignore[return-value]
        (kp * k[i] + a.c * (p[i] - kp * k[i])) + a.s * kxp[i] for i in range(3)
    )


def sp1_cs(p1: Sequence[Entry], p2: Sequence[Entry], k: Sequence[Entry]) -> CosSin:
    """Subproblem 1 on entries: ``theta`` minimising ``|rot(k, theta) p1 - p2|``, as
    ``atan2((k x p1) . p2, (k x p1) . (k x p2))`` normalised; angle 0 where ``p1`` or ``p2``
    lies on the axis."""
    kxp1 = _pose.cross(k, p1)
    kxp2 = _pose.cross(k, p2)
    return unit(dot(kxp1, kxp2), dot(kxp1, p2))


def sp4_cs(
    h: Sequence[Entry], p: Sequence[Entry], k: Sequence[Entry], d: Entry, tol: Entry, tiny: Entry
) -> Quadratic:
    """Subproblem 4 on entries: ``h . rot(k, theta) p = d``, i.e. ``a cos + b sin = c`` with
    ``a = h . (p - (k.p) k)``, ``b = h . (k x p)``, ``c = d - (h.k)(k.p)``.

    The roots ``theta = atan2(b, a) +- atan2(e, c)``, ``e = sqrt(a^2 + b^2 - c^2)``, come as
    ``(a c -+ b e, b c +- a e)`` normalised: no ``acos``, and a root near the tangent (``e``
    small) keeps its residual at rounding level. ``e`` is clamped at 0 where the plane misses
    the circle (least squares: the circle's point nearest the plane). ``exists``:
    ``|c| - sqrt(a^2 + b^2) <= tol``. Where the circle's radius term ``sqrt(a^2 + b^2)`` is at
    most ``tiny`` (``p`` on the axis ``k``, or ``h`` along it) the roots are 0 and pi.
    """
    kp = dot(k, p)
    hk = dot(h, k)
    a = dot(h, p) - hk * kp
    b = dot(h, _pose.cross(k, p))
    c = d - hk * kp
    r2 = a * a + b * b
    r = np.sqrt(r2)
    e = np.sqrt(np.maximum(r2 - c * c, 0.0))
    exists = np.abs(c) - r <= tol
    degenerate = r <= tiny
    a, b, c, e = (np.asarray(x)[..., None] for x in (a, b, c, e))
    x = a * c - _SIGNS * (b * e)
    y = b * c + _SIGNS * (a * e)
    point = np.asarray(degenerate)[..., None]
    root = unit(np.where(point, _SIGNS, x), np.where(point, 0.0, y))
    return Quadratic(root, exists, degenerate)


def sp3_cs(
    p1: Sequence[Entry], p2: Sequence[Entry], k: Sequence[Entry], dist2: Entry, tol: Entry,
    tiny: Entry,
) -> Quadratic:  # fmt: skip
    """Subproblem 3 on entries, given the squared distance: ``|rot(k, theta) p1 - p2|^2 =
    dist2``, as subproblem 4 ``p2 . rot(k, theta) p1 = (|p1|^2 + |p2|^2 - dist2) / 2``
    (``tol`` and ``tiny`` in its units, lengths squared)."""
    d = (dot(p1, p1) + dot(p2, p2) - dist2) * 0.5
    return sp4_cs(p2, p1, k, d, tol, tiny)


def sp2_cs(
    p1: Sequence[Entry], p2: Sequence[Entry], k1: Sequence[Entry], k2: Sequence[Entry],
    tol: Entry, tiny: Entry,
) -> tuple[Quadratic, CosSin]:  # fmt: skip
    """Subproblem 2 on entries: ``rot(k1, theta1) p1 = rot(k2, theta2) p2``.

    ``theta1`` first, by subproblem 4 on the circle of ``p1`` about ``k1``: the point must lie
    in the plane ``k2 . x = k2 . p2`` of the circle of ``p2``; then ``theta2`` by subproblem 1,
    turning ``p2`` onto the point ``rot(k1, theta1) p1`` actually reached. The circle of ``p1``
    is parametrised by ``p1`` itself, never by its height along ``k1``, so it may shrink to a
    point (``p1`` on ``k1``: any ``theta1``; 0 and pi by the convention) without losing
    accuracy. Returns theta1's roots (on a new last axis) and theta2 for each.
    """
    first = sp4_cs(k2, p1, k1, dot(k2, p2), tol, tiny)
    reached = rotate(lift(k1), first.root, lift(p1))
    return first, sp1_cs(lift(p2), reached, lift(k2))


# --- arrays ------------------------------------------------------------------------------------


def _vectors(*arrays: ArrayLike) -> list[Vec]:
    out = []
    for x in arrays:
        a = np.asarray(x, dtype=np.float64)
        if a.ndim == 0 or a.shape[-1] != 3:
            raise InputError(f"expected vectors of shape (..., 3), got shape {a.shape}")
        out.append((a[..., 0], a[..., 1], a[..., 2]))
    return out


def _size(*vs: Vec) -> Entry:
    """The largest norm among ``vs`` (1 where all are zero): the scale of the tolerances."""
    big = np.sqrt(dot(vs[0], vs[0]))
    for v in vs[1:]:
        big = np.maximum(big, np.sqrt(dot(v, v)))
    return np.where(big > 0.0, big, 1.0)


def _angle(a: CosSin) -> FloatArray:
    return np.asarray(np.arctan2(a.s, a.c), dtype=np.float64)


def _flag(x: Entry) -> BoolArray:
    return np.asarray(x, dtype=np.bool_)


class Solution(NamedTuple):
    """One-angle subproblem: ``theta`` ``(...,)`` rad and ``exists`` ``(...,)``."""

    theta: FloatArray
    exists: BoolArray


class Pair(NamedTuple):
    """Two-root subproblem: ``theta`` ``(..., 2)`` rad (the ``+`` root first) and ``exists``
    ``(...,)``."""

    theta: FloatArray
    exists: BoolArray


class TwoAngles(NamedTuple):
    """Subproblem 2: ``theta1``, ``theta2`` ``(..., 2)`` rad (pairs) and ``exists``
    ``(...,)``."""

    theta1: FloatArray
    theta2: FloatArray
    exists: BoolArray


def sp1(p1: ArrayLike, p2: ArrayLike, k: ArrayLike, *, tol: float = TOL) -> Solution:
    """Subproblem 1: the angle ``theta`` with ``rot(k, theta) p1 = p2``.

    Args:
        p1, p2: ``(..., 3)`` vectors.
        k: ``(..., 3)`` unit axis.
        tol: relative tolerance of ``exists``.

    Returns:
        ``theta`` ``(...,)`` in ``(-pi, pi]``: the unique solution, or the least-squares one
        (``p1`` turned as close to ``p2`` as it gets); 0 where ``p1`` or ``p2`` lies on the axis.
        ``exists``: ``|p1| = |p2|`` and ``k . p1 = k . p2``, to ``tol`` times the larger norm.
    """
    v1, v2, kk = _vectors(p1, p2, k)
    theta = _angle(sp1_cs(v1, v2, kk))
    size = _size(v1, v2)
    exists = (np.abs(np.sqrt(dot(v1, v1)) - np.sqrt(dot(v2, v2))) <= tol * size) & (
        np.abs(dot(kk, v1) - dot(kk, v2)) <= tol * size
    )
    return Solution(theta, _flag(exists))


def sp4(h: ArrayLike, p: ArrayLike, k: ArrayLike, d: ArrayLike, *, tol: float = TOL) -> Pair:
    """Subproblem 4: the angles ``theta`` with ``h . rot(k, theta) p = d`` (the circle of ``p``
    about ``k`` meets a plane with normal ``h``).

    Args:
        h: ``(..., 3)`` plane normal (any length).
        p: ``(..., 3)`` vector turned about ``k``.
        k: ``(..., 3)`` unit axis.
        d: ``(...)`` the plane's offset.
        tol: relative tolerance of ``exists``, in units of ``|h| |p|``.

    Returns:
        ``theta`` ``(..., 2)``: up to two solutions (a tangent plane gives one twice); where the
        plane misses the circle, the angle of the circle's point nearest to it, twice. Where
        ``p`` lies on the axis (or ``h`` along it) every angle or none solves the equation:
        0 and pi. ``exists``: the plane meets the circle, to ``tol``.
    """
    hh, pp, kk = _vectors(h, p, k)
    scale = np.sqrt(dot(hh, hh)) * _size(pp)
    out = sp4_cs(hh, pp, kk, np.asarray(d, dtype=np.float64), tol * scale, _DEGENERATE * scale)
    return Pair(_angle(out.root), _flag(out.exists))


def sp3(p1: ArrayLike, p2: ArrayLike, k: ArrayLike, dist: ArrayLike, *, tol: float = TOL) -> Pair:
    """Subproblem 3: the angles ``theta`` with ``|rot(k, theta) p1 - p2| = dist`` (the circle of
    ``p1`` about ``k`` meets the sphere of radius ``dist`` about ``p2``).

    Args:
        p1: ``(..., 3)`` vector turned about ``k``.
        p2: ``(..., 3)`` centre of the sphere.
        k: ``(..., 3)`` unit axis.
        dist: ``(...)`` the distance, >= 0.
        tol: relative tolerance of ``exists``, in units of ``|p1| |p2|``.

    Returns:
        ``theta`` ``(..., 2)``: up to two solutions; the least-squares angle twice where the
        sphere misses the circle; 0 and pi where ``p1`` lies on the axis or ``p2`` projects
        onto it. ``exists``: the sphere meets the circle, to ``tol``.
    """
    v1, v2, kk = _vectors(p1, p2, k)
    scale = _size(v1) * _size(v2)
    dd = np.asarray(dist, dtype=np.float64)
    out = sp3_cs(v1, v2, kk, dd * dd, tol * scale, _DEGENERATE * scale)
    return Pair(_angle(out.root), _flag(out.exists))


def sp2(
    p1: ArrayLike, p2: ArrayLike, k1: ArrayLike, k2: ArrayLike, *, tol: float = TOL
) -> TwoAngles:
    """Subproblem 2: the angle pairs with ``rot(k1, theta1) p1 = rot(k2, theta2) p2`` (two
    circles, of ``p1`` about ``k1`` and of ``p2`` about ``k2``, meet).

    Args:
        p1, p2: ``(..., 3)`` vectors, of equal length for an exact solution.
        k1, k2: ``(..., 3)`` unit axes, not parallel.
        tol: relative tolerance of ``exists``.

    Returns:
        ``theta1``, ``theta2`` ``(..., 2)``: up to two pairs (touching circles give one twice);
        where the circles do not meet, ``theta1`` puts ``rot(k1, theta1) p1`` nearest the plane
        of the other circle and ``theta2`` is the least-squares turn of ``p2`` onto that point.
        Where ``p1`` lies on ``k1``, ``theta1`` is 0 and pi. ``exists``: the circles meet, to
        ``tol`` times the larger norm.
    """
    v1, v2, a1, a2 = _vectors(p1, p2, k1, k2)
    size = _size(v1, v2)
    first, second = sp2_cs(v1, v2, a1, a2, tol * size, _DEGENERATE * size)
    same_norm = np.abs(np.sqrt(dot(v1, v1)) - np.sqrt(dot(v2, v2))) <= tol * size
    t1 = _angle(first.root)
    t2 = np.broadcast_to(_angle(second), t1.shape)
    return TwoAngles(t1, np.array(t2), _flag(first.exists & same_norm))
