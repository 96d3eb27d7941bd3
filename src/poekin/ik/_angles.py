"""Revolute angles brought into the joint limits by whole turns (``2 pi``), shared by every IK
solver: an answer is a configuration inside the limits, and a revolute joint reaches the same
pose at ``q`` and ``q + 2 pi k``."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from poekin import arrays

__all__ = ["TWO_PI", "within_limits", "wrap_into_limits"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

TWO_PI = 2.0 * np.pi


def wrap_into_limits(q: Any, limits: Any, revolute: Any, xp: Any = np) -> Any:
    """``q`` with each revolute angle moved by whole turns into its limits where it can be.

    One implementation for NumPy (the compiled kernel's reference: ``_ik_common.h`` does the
    same arithmetic), JAX and PyTorch: ``+ - * /``, ``remainder``, ``ceil``, ``floor`` and
    ``where`` of the namespace ``xp``, the model's limits as constants of ``q``'s dtype.

    Args:
        q: ``(..., n)`` joint values (rad, m), an array of ``xp``.
        limits: ``(n, 2)`` lower and upper limits, ``-inf``/``inf`` where unlimited: an array,
            or ``n`` pairs of Python floats (what code traced by torch.compile passes).
        revolute: ``n`` flags, True for the revolute joints (prismatic values never move).
        xp: ``q``'s array namespace (NumPy's by default).

    Returns:
        ``(..., n)`` (float64 for NumPy, else ``q``'s dtype): an angle already within its
        limits stays as it is (bit for bit); one outside moves by the fewest turns that bring
        it inside; one that no whole turn brings inside stays as it is (the caller reports
        it). A joint without limits on either side comes back in ``(-pi, pi]`` (one there
        already stays as it is).
    """
    if xp is np:
        q = np.array(q, dtype=np.float64)  # a copy: the caller's array is never changed
    pairs = [(float(a), float(b)) for a, b in limits]
    turning = [bool(r) for r in revolute]
    free_flags = [
        r and a == -math.inf and b == math.inf for r, (a, b) in zip(turning, pairs, strict=True)
    ]
    lo = _constant([a for a, _ in pairs], q, xp)
    hi = _constant([b for _, b in pairs], q, xp)
    unlimited = _constant(free_flags, q, xp)
    limited = _constant([r and not f for r, f in zip(turning, free_flags, strict=True)], q, xp)
    # (-pi, pi]: pi - ((pi - q) mod 2 pi) lies in (-pi, pi] for every finite q; an angle there
    # already stays as it is, bit for bit
    free = np.pi - xp.remainder(np.pi - q, TWO_PI)
    q = xp.where(unlimited & ~((q > -np.pi) & (q <= np.pi)), free, q)
    inside = (q >= lo) & (q <= hi)
    # infinite limits give infinite turn counts, never used
    up = xp.ceil((lo - q) / TWO_PI)  # fewest whole turns up to reach lo
    down = xp.floor((hi - q) / TWO_PI)  # fewest whole turns down to reach hi
    raised = q + up * TWO_PI
    lowered = q + down * TWO_PI
    below, above = q < lo, q > hi
    moved = xp.where(below & (raised <= hi), raised, q)
    moved = xp.where(above & (lowered >= lo), lowered, moved)
    return xp.where(limited & ~inside, moved, q)


def _constant(values: list[Any], like: Any, xp: Any) -> Any:
    """Per-joint Python values as an array that enters ``like``'s computation: float64 or bool
    for NumPy, else ``like``'s dtype (or bool) on its device."""
    boolean = bool(values) and isinstance(values[0], bool)
    if xp is np:
        return np.array(values, dtype=np.bool_ if boolean else np.float64)
    dtype = xp.bool if boolean else like.dtype
    if arrays.kind_of(like) == "torch":
        return xp.asarray(values, dtype=dtype, device=like.device)
    return xp.asarray(values, dtype=dtype)


def within_limits(q: FloatArray, limits: FloatArray, tol: float = 0.0) -> BoolArray:
    """``(...,)`` True where every joint value of ``(..., n)`` ``q`` lies within ``(n, 2)``
    ``limits``, widened by ``tol`` on each side."""
    inside: BoolArray = np.all((q >= limits[:, 0] - tol) & (q <= limits[:, 1] + tol), axis=-1)
    return inside
