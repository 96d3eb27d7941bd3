"""Revolute angles brought into the joint limits by whole turns (``2 pi``), shared by every IK
solver: an answer is a configuration inside the limits, and a revolute joint reaches the same
pose at ``q`` and ``q + 2 pi k``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from poekin import arrays

__all__ = ["TWO_PI", "outside_limits", "within_limits", "wrap_into_limits"]

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


def outside_limits(
    q: FloatArray, limits: FloatArray, names: Sequence[str], angles: Sequence[bool]
) -> str:
    """The values of ``(..., n)`` ``q`` outside ``(n, 2)`` ``limits``, in words, or ``""``:
    ``outside the joint limits: 'elbow' = 4 rad, not in [-3.14, 3.14]``, and for a batch
    ``3 of 20 configurations are outside the joint limits: 'elbow' in 3 rows (first row 2:
    4 rad), not in [...]``. ``names`` and ``angles`` (rad, else m) say what each entry is. The
    command line's notes and :class:`~poekin.errors.JointLimitsWarning` say it."""
    lo, hi = limits[:, 0], limits[:, 1]
    rows = q.reshape(-1, q.shape[-1])
    outside = (rows < lo) | (rows > hi)
    if not np.any(outside):
        return ""
    one = rows.shape[0] == 1
    joints = []
    for j in map(int, np.flatnonzero(outside.any(axis=0))):
        bad = np.flatnonzero(outside[:, j])
        r = int(bad[0])
        value = f"{rows[r, j]:.6g} {'rad' if angles[j] else 'm'}"
        rows_word = f"{len(bad)} row{'s' if len(bad) > 1 else ''}"
        where = f"= {value}" if one else f"in {rows_word} (first row {r}: {value})"
        joints.append(f"{names[j]!r} {where}, not in [{lo[j]:.6g}, {hi[j]:.6g}]")
    named = "; ".join(joints)
    if one:
        return f"outside the joint limits: {named}"
    n_bad = int(np.count_nonzero(outside.any(axis=-1)))
    return f"{n_bad} of {rows.shape[0]} configurations are outside the joint limits: {named}"
