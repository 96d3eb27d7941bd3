"""Revolute angles brought into the joint limits by whole turns (``2 pi``), shared by every IK
solver: an answer is a configuration inside the limits, and a revolute joint reaches the same
pose at ``q`` and ``q + 2 pi k``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import arrays
from poekin.errors import InputError

__all__ = ["TWO_PI", "nearest_turns", "outside_limits", "within_limits", "wrap", "wrap_into_limits"]

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


def nearest_turns(q: Any, reference: Any, limits: FloatArray, revolute: Any) -> Any:
    """``(..., n)`` ``q`` with each revolute angle moved by whole turns to the equivalent
    nearest ``reference`` (broadcast against ``q``) among those within ``limits``; an angle
    that no turn brings within them stays as it is. Prismatic values never move. NumPy."""
    q = np.array(q, dtype=np.float64)
    ref = np.broadcast_to(np.asarray(reference, dtype=np.float64), q.shape)
    lo, hi = limits[:, 0], limits[:, 1]
    turning = np.asarray(revolute, dtype=np.bool_)
    with np.errstate(invalid="ignore"):  # infinite limits: no bound on the turns
        fewest = np.ceil((lo - q) / TWO_PI)  # the turns that keep q + 2 pi k within the limits
        most = np.floor((hi - q) / TWO_PI)
    # |q + 2 pi k - ref| is convex in k: the nearest allowed k is the nearest k, clipped
    k = np.clip(np.round((ref - q) / TWO_PI), fewest, most)
    moved = q + k * TWO_PI
    return np.where(turning & (fewest <= most) & (k != 0), moved, q)


def wrap(q: ArrayLike, chain: Any, reference: ArrayLike | None = None) -> FloatArray:
    """Each revolute joint's value of ``q`` as its equivalent (the same angle, whole turns
    apart) nearest ``reference`` within the joint's limits, or, without a reference, the one
    nearest 0 (in ``[-pi, pi]`` where the limits allow it). What a controller wants of an IK
    answer: 6.09 rad on a +-2 pi joint is valid, but it is -0.19 rad.

    Args:
        q: ``(..., n)`` joint values (rad, m) of ``chain``'s joints.
        chain: a :class:`~poekin.Chain` (its limits and joint types).
        reference: ``(..., n)`` joint values to be nearest (the robot's current ones),
            broadcast against ``q``; None for 0.

    Returns:
        ``(..., n)`` float64: the same poses (``chain.fk`` agrees to rounding); prismatic
        values, and angles that no whole turn brings within the limits, unchanged.

    Raises:
        InputError: ``q`` or ``reference`` not real finite values of the chain's joints.
    """
    from poekin._poe import as_joint_values

    values = as_joint_values(q, chain.n_joints, what="joint values")
    if not np.all(np.isfinite(values)):
        raise InputError("joint values contain NaN or inf; every value must be finite")
    if reference is None:
        ref = np.zeros(chain.n_joints)
    else:
        ref = as_joint_values(reference, chain.n_joints, what="reference values")
        if not np.all(np.isfinite(ref)):
            raise InputError("reference values contain NaN or inf; every value must be finite")
        try:
            np.broadcast_shapes(values.shape, ref.shape)
        except ValueError:
            raise InputError(
                f"reference of shape {ref.shape} does not broadcast against q of shape "
                f"{values.shape}"
            ) from None
    revolute = [t == "revolute" for t in chain.joint_types]
    out: FloatArray = nearest_turns(values, ref, chain.limits, revolute)
    return out


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
