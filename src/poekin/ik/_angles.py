"""Revolute angles brought into the joint limits by whole turns (``2 pi``), shared by every IK
solver: an answer is a configuration inside the limits, and a revolute joint reaches the same
pose at ``q`` and ``q + 2 pi k``."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["TWO_PI", "within_limits", "wrap_into_limits"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

TWO_PI = 2.0 * np.pi


def wrap_into_limits(q: FloatArray, limits: FloatArray, revolute: BoolArray) -> FloatArray:
    """``q`` with each revolute angle moved by whole turns into its limits where it can be.

    Args:
        q: ``(..., n)`` joint values (rad, m).
        limits: ``(n, 2)`` lower and upper limits; ``-inf``/``inf`` where unlimited.
        revolute: ``(n,)`` True for the revolute joints (prismatic values never move).

    Returns:
        ``(..., n)`` float64: an angle already within its limits stays as it is (bit for bit);
        one outside moves by the fewest turns that bring it inside; one that no whole turn
        brings inside stays as it is (the caller reports it). A joint without limits on either
        side comes back in ``(-pi, pi]`` (one there already stays as it is).
    """
    q = np.array(q, dtype=np.float64)  # a copy: the caller's array is never changed
    lo, hi = limits[:, 0], limits[:, 1]
    unlimited = revolute & np.isneginf(lo) & np.isposinf(hi)
    limited = revolute & ~unlimited
    # (-pi, pi]: pi - ((pi - q) mod 2 pi) lies in (-pi, pi] for every finite q; an angle there
    # already stays as it is, bit for bit
    free = np.pi - np.mod(np.pi - q, TWO_PI)
    q = np.where(unlimited & ~((q > -np.pi) & (q <= np.pi)), free, q)
    inside = (q >= lo) & (q <= hi)
    with np.errstate(invalid="ignore"):  # inf limits: the turn counts are not used there
        up = np.ceil((lo - q) / TWO_PI)  # fewest whole turns up to reach lo
        down = np.floor((hi - q) / TWO_PI)  # fewest whole turns down to reach hi
        raised = q + up * TWO_PI
        lowered = q + down * TWO_PI
    below, above = q < lo, q > hi
    moved = np.where(below & (raised <= hi), raised, q)
    moved = np.where(above & (lowered >= lo), lowered, moved)
    return np.where(limited & ~inside, moved, q)


def within_limits(q: FloatArray, limits: FloatArray, tol: float = 0.0) -> BoolArray:
    """``(...,)`` True where every joint value of ``(..., n)`` ``q`` lies within ``(n, 2)``
    ``limits``, widened by ``tol`` on each side."""
    inside: BoolArray = np.all((q >= limits[:, 0] - tol) & (q <= limits[:, 1] + tol), axis=-1)
    return inside
