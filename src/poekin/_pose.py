"""Pose arithmetic entry by entry: the reference path's formulas, for every array library.

The reference FK and Jacobian paths (:func:`poekin._poe.poe`, :mod:`poekin._levels`) and the
quaternion and matrix helpers of :mod:`poekin.lie` are written here once, and NumPy, JAX and
PyTorch run the very same functions. A rotation is three rows of three *entries*, a point three
entries; an entry is an array of the batch shape (one value per configuration) or a Python float
(a model constant, the same for every configuration, which also keeps the caller's dtype and
device). Results are new values, never written in place, so JAX can trace them.

Sums run left to right in the compiled kernel's order (``_kernel_core.h``), so the kernel and the
NumPy reference agree to the last bit except for the sign of zero, where one of them leaves out a
product with a structural zero (a coordinate-axis joint, an identity offset), and for sin and cos
(the kernel's own, below 1 ulp). Only ``+ - * /`` and comparisons are used on entries; the few
operations that need the library (``sin``, ``cos``, ``sqrt``, ``where``, ``stack``) take its
namespace ``xp``. Every ``where`` has finite values on both sides and every ``sqrt`` a positive
argument, so gradients are finite everywhere (JAX and PyTorch differentiate both sides).

The ``*_stacked`` functions are the same formulas on stacked arrays: rotations
``(m, 3, 3, ...)`` and points ``(m, 3, ...)``, ``m`` poses (the bodies of a tree's group,
:mod:`poekin._levels`) first and the batch axes last, so that every operation runs over
contiguous memory. Each entry is computed by the operations its entry-by-entry twin applies to
it, in the same order (tested equal bit for bit), in a few operations on whole arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

__all__ = [
    "IDENTITY",
    "ORIGIN",
    "Entry",
    "Mat",
    "Pose",
    "Vec",
    "about_point",
    "about_point_stacked",
    "axis_turn",
    "axis_turn_stacked",
    "compose",
    "compose_const",
    "compose_stacked",
    "cross",
    "hat",
    "is_identity",
    "mat_mat",
    "mat_mat_stacked",
    "mat_vec",
    "mat_vec_stacked",
    "norm",
    "quat_matrix",
    "quat_normalize",
    "rodrigues",
    "rodrigues_stacked",
    "rotation_quat",
    "settle",
    "settle_pose",
    "sincos",
    "stack",
    "stack_mat",
    "to_array",
    "transpose",
    "unstack",
]

Entry = Any  # an array of the batch shape, or a Python float
Vec = tuple[Entry, Entry, Entry]
Mat = tuple[Vec, Vec, Vec]  # rows
Pose = tuple[Mat, Vec]
Form = Literal["4x4", "3x4", "pos_quat"]

IDENTITY: Mat = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
ORIGIN: Vec = (0.0, 0.0, 0.0)

# MuJoCo's mjMINVAL: a quaternion shorter than this normalises to the identity.
QUAT_MIN_NORM = 1e-15


def settle_pose(pose: Pose, xp: Any) -> Pose:
    """``pose``, each entry computed once (:func:`settle`)."""
    (r0, r1, r2), p = pose
    e = settle([*r0, *r1, *r2, *p], xp)
    return ((e[0], e[1], e[2]), (e[3], e[4], e[5]), (e[6], e[7], e[8])), (e[9], e[10], e[11])


def settle(values: Sequence[Entry], xp: Any) -> list[Entry]:
    """``values`` as they are, computed once.

    XLA fuses an elementwise value into each of its consumers and, on the CPU, computes it
    again in every one: the sines and cosines of the joint angles, on which all twelve entries
    of a pose depend, would be evaluated twelve times per configuration (1.0 us per UR5e
    configuration, measured, against 0.3 us). Under JAX the values therefore pass through an
    operation XLA does not fuse across: a ``lax.cond`` whose branches both give them back
    (the one taken, bit for bit; the other times one, so that the two are not one function),
    on a predicate XLA cannot fold away (``True`` through an optimization barrier) and that
    depends on no value, so that ``jax.vmap`` keeps it a ``cond`` and a sharded batch needs no
    communication. (A dot with the identity on the values stacked did the same at a cost: the
    stacking and the dot took a fifth of a UR5e ``ik_step`` of 4,096 configurations under
    ``jax.jit`` on the CPU, in XLA's profile.) Other libraries compute each operation once
    anyway and get ``values`` back. Python floats among ``values`` (constants) stay as they
    are; arrays are broadcast together.
    """
    if getattr(xp, "__name__", "") != "jax.numpy" or not values:
        return list(values)
    import jax

    out = list(values)
    live = [i for i, v in enumerate(values) if not isinstance(v, float)]  # constants stay
    if not live:
        return out
    shape = np.broadcast_shapes(*(tuple(values[i].shape) for i in live))
    parts = [xp.broadcast_to(values[i], shape) for i in live]
    taken = jax.lax.optimization_barrier(xp.asarray(True))  # type: ignore[no-untyped-call]
    once = jax.lax.cond(taken, _same, _times_one, parts)
    for k, i in enumerate(live):
        out[i] = once[k]
    return out


def _same(values: list[Entry]) -> list[Entry]:
    return values


def _times_one(values: list[Entry]) -> list[Entry]:
    return [v * 1.0 for v in values]


def sincos(angles: Sequence[Entry], xp: Any) -> tuple[list[Entry], list[Entry]]:
    """The sines and cosines of ``angles``, each computed once (:func:`settle`)."""
    both = settle([*(xp.sin(a) for a in angles), *(xp.cos(a) for a in angles)], xp)
    return both[: len(angles)], both[len(angles) :]


def mat_vec(R: Mat, v: Sequence[Entry]) -> Vec:
    """``R v``, each row summed left to right."""
    return (
        (R[0][0] * v[0] + R[0][1] * v[1]) + R[0][2] * v[2],
        (R[1][0] * v[0] + R[1][1] * v[1]) + R[1][2] * v[2],
        (R[2][0] * v[0] + R[2][1] * v[1]) + R[2][2] * v[2],
    )


def mat_mat(A: Mat, B: Mat) -> Mat:
    """``A B``, each entry summed left to right."""
    return (
        (
            (A[0][0] * B[0][0] + A[0][1] * B[1][0]) + A[0][2] * B[2][0],
            (A[0][0] * B[0][1] + A[0][1] * B[1][1]) + A[0][2] * B[2][1],
            (A[0][0] * B[0][2] + A[0][1] * B[1][2]) + A[0][2] * B[2][2],
        ),
        (
            (A[1][0] * B[0][0] + A[1][1] * B[1][0]) + A[1][2] * B[2][0],
            (A[1][0] * B[0][1] + A[1][1] * B[1][1]) + A[1][2] * B[2][1],
            (A[1][0] * B[0][2] + A[1][1] * B[1][2]) + A[1][2] * B[2][2],
        ),
        (
            (A[2][0] * B[0][0] + A[2][1] * B[1][0]) + A[2][2] * B[2][0],
            (A[2][0] * B[0][1] + A[2][1] * B[1][1]) + A[2][2] * B[2][1],
            (A[2][0] * B[0][2] + A[2][1] * B[1][2]) + A[2][2] * B[2][2],
        ),
    )


def transpose(R: Mat) -> Mat:
    return ((R[0][0], R[1][0], R[2][0]), (R[0][1], R[1][1], R[2][1]), (R[0][2], R[1][2], R[2][2]))


def cross(a: Sequence[Entry], b: Sequence[Entry]) -> Vec:
    """``a x b`` (NumPy's ``np.cross`` arithmetic)."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def hat(w: Sequence[Entry]) -> Mat:
    """``[w]``, with ``[w] x = w x x``."""
    return ((0.0, -w[2], w[1]), (w[2], 0.0, -w[0]), (-w[1], w[0], 0.0))


def is_identity(R: Mat) -> bool:
    """Whether constant ``R`` is exactly the identity (entries that are arrays never are)."""
    return all(
        isinstance(R[i][j], float) and R[i][j] == (1.0 if i == j else 0.0)
        for i in range(3)
        for j in range(3)
    )


def compose(pose: Pose, R: Mat, t: Sequence[Entry]) -> Pose:
    """``pose (R, t)``: the point first, ``p + R_pose t``, then ``R_pose R``."""
    R_cur, p = pose
    moved = mat_vec(R_cur, t)
    return mat_mat(R_cur, R), (p[0] + moved[0], p[1] + moved[1], p[2] + moved[2])


def compose_const(pose: Pose, R: Mat, t: Sequence[Entry]) -> Pose:
    """:func:`compose` with a model constant: as the kernel's CONST and TRANSLATE operations,
    only the point moves when ``R`` is exactly the identity (``R_pose I = R_pose`` in every bit
    but signs of zero), and nothing changes when ``t`` is zero too."""
    if not is_identity(R):
        return compose(pose, R, t)
    if all(isinstance(x, float) and x == 0.0 for x in t):
        return pose
    R_cur, p = pose
    moved = mat_vec(R_cur, t)
    return R_cur, (p[0] + moved[0], p[1] + moved[1], p[2] + moved[2])


def rodrigues(W: Mat, W2: Mat, s: Entry, c1: Entry) -> Mat:
    """``(I + s W) + c1 W^2``: a rotation about a unit axis ``w`` (``W = [w]``, ``W2 = W W``)
    by the angle whose sine is ``s`` and ``1 - cos`` is ``c1``."""
    return tuple(  # type: ignore[return-value]
        tuple((IDENTITY[i][j] + s * W[i][j]) + c1 * W2[i][j] for j in range(3)) for i in range(3)
    )


def about_point(R: Mat, point: Sequence[Entry]) -> Vec:
    """``point - R point``: the translation of the rotation ``R`` about ``point``."""
    turned = mat_vec(R, point)
    return (point[0] - turned[0], point[1] - turned[1], point[2] - turned[2])


def axis_turn(
    pose: Pose, k: int, s: Entry, c: Entry, point: Sequence[Entry], along: Entry | None
) -> Pose:
    """``pose (R_k, (point - R_k point) + along e_k)`` for the rotation ``R_k`` about coordinate
    axis ``k`` whose sine is ``s`` (signed by the axis's direction) and cosine ``c``; ``along``
    is a screw's advance along the axis, or None for none.

    Only columns ``a = k + 1`` and ``b = k + 2`` (mod 3) of the rotation change: this is the
    arithmetic of :func:`compose` with the zeros and ones of ``R_k`` left out (the kernel's
    AXIS operations), equal to it but for signs of zero.
    """
    a, b = (k + 1) % 3, (k + 2) % 3
    R, p = pose
    ra, rb = point[a], point[b]
    t = [0.0, 0.0, 0.0]
    t[a] = ra - (c * ra - s * rb)
    t[b] = rb - (s * ra + c * rb)
    if along is not None:
        t[k] = along
        moved = mat_vec(R, t)
        p = (p[0] + moved[0], p[1] + moved[1], p[2] + moved[2])
    else:
        p = tuple(p[i] + (R[i][a] * t[a] + R[i][b] * t[b]) for i in range(3))  # type: ignore[assignment]
    rows = []
    for i in range(3):
        row = list(R[i])
        row[a] = c * R[i][a] + s * R[i][b]
        row[b] = c * R[i][b] - s * R[i][a]
        rows.append(tuple(row))
    return tuple(rows), p  # type: ignore[return-value]


def norm(v: Sequence[Entry], xp: Any) -> Entry:
    """``|v|``, summed left to right, with a finite gradient at ``v = 0`` (where ``sqrt``'s is
    infinite): the square root of a positive stand-in there, then 0."""
    sq = v[0] * v[0] + v[1] * v[1]
    for x in v[2:]:
        sq = sq + x * x
    positive = sq > 0
    return xp.where(positive, xp.sqrt(xp.where(positive, sq, 1.0)), 0.0)


def quat_normalize(quat: Sequence[Entry], xp: Any) -> tuple[Entry, Entry, Entry, Entry]:
    """A quaternion ``(w, x, y, z)`` scaled to unit length as MuJoCo's ``mju_normalize4`` does:
    the identity below norm ``1e-15``, unchanged within ``1e-15`` of unit norm, else times
    ``1 / norm``. The norm's gradient is finite at zero (:func:`norm`)."""
    w, x, y, z = quat
    n = norm((w, x, y, z), xp)
    tiny = n < QUAT_MIN_NORM
    unchanged = xp.abs(n - 1.0) <= QUAT_MIN_NORM
    inv = 1.0 / xp.where(tiny | unchanged, 1.0, n)
    return (
        xp.where(tiny, 1.0, w * inv),
        xp.where(tiny, 0.0, x * inv),
        xp.where(tiny, 0.0, y * inv),
        xp.where(tiny, 0.0, z * inv),
    )


def quat_matrix(quat: Sequence[Entry]) -> Mat:
    """The rotation matrix of a unit quaternion ``(w, x, y, z)`` (MuJoCo's ``mju_quat2Mat``)."""
    w, x, y, z = quat
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    wx, wy, wz, xy, xz, yz = w * x, w * y, w * z, x * y, x * z, y * z
    return (
        (ww + xx - yy - zz, 2 * (xy - wz), 2 * (xz + wy)),
        (2 * (xy + wz), ww - xx + yy - zz, 2 * (yz - wx)),
        (2 * (xz - wy), 2 * (yz + wx), ww - xx - yy + zz),
    )


def rotation_quat(R: Mat, xp: Any) -> tuple[Entry, Entry, Entry, Entry]:
    """The unit quaternion ``(w, x, y, z)`` with ``w >= 0`` of a rotation, by Shepperd's method:
    the largest of ``|w|, |x|, |y|, |z|`` (the first of equals) from the diagonal, the others
    divided by it. The divisor is at least 1, so every branch is finite."""
    a = R[2][1] - R[1][2]  # 4 w x
    b = R[0][2] - R[2][0]  # 4 w y
    c = R[1][0] - R[0][1]  # 4 w z
    xy = R[0][1] + R[1][0]  # 4 x y
    xz = R[0][2] + R[2][0]  # 4 x z
    yz = R[1][2] + R[2][1]  # 4 y z
    d0, d1, d2 = R[0][0], R[1][1], R[2][2]
    diag = (1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2)
    # the first largest, as argmax picks it
    first = [
        (diag[0] >= diag[1]) & (diag[0] >= diag[2]) & (diag[0] >= diag[3]),
        (diag[1] > diag[0]) & (diag[1] >= diag[2]) & (diag[1] >= diag[3]),
        (diag[2] > diag[0]) & (diag[2] > diag[1]) & (diag[2] >= diag[3]),
        (diag[3] > diag[0]) & (diag[3] > diag[1]) & (diag[3] > diag[2]),
    ]
    best = xp.where(
        first[0], diag[0], xp.where(first[1], diag[1], xp.where(first[2], diag[2], diag[3]))
    )
    big = xp.sqrt(xp.where(best > 0.25, best, 0.25)) * 2  # 4 * the chosen component, >= 1
    # numerator of component i when component j is the largest
    num = ((None, a, b, c), (a, None, xy, xz), (b, xy, None, yz), (c, xz, yz, None))
    quat = []
    for i in range(4):
        top = big / 4
        for j in range(4):
            if j != i:
                top = xp.where(first[j], num[i][j], top)
        quat.append(xp.where(first[i], top, top / big))
    negative = quat[0] < 0
    return tuple(xp.where(negative, -e, e) for e in quat)  # type: ignore[return-value]


def stack(entries: Sequence[Entry], shape: tuple[int, ...], xp: Any, like: Any) -> Any:
    """The entries as one array of trailing shape ``shape`` (row-major), after the batch axes of
    ``like`` (an array of the batch shape in the result's dtype, on its device). Python floats
    become full arrays; arrays are broadcast to the batch shape."""
    if not entries:  # e.g. the (6, 0) Jacobian of a chain without joints
        one = xp.reshape(xp.zeros_like(like), (*like.shape, *(1,) * len(shape)))
        return xp.zeros_like(xp.broadcast_to(one, (*like.shape, *shape)))
    if xp is np and not like.shape and all(isinstance(e, float) or not e.shape for e in entries):
        # one NumPy configuration, whose entries are NumPy's scalars (floats) and 0-d arrays:
        # one conversion, not an array per entry
        return np.asarray(entries, dtype=like.dtype).reshape(shape)
    full = [xp.full_like(like, e) if isinstance(e, float) else e for e in entries]
    if any(tuple(e.shape) != tuple(like.shape) for e in full):
        full = list(xp.broadcast_arrays(like, *full)[1:])
    flat = xp.stack(full, -1)
    return xp.reshape(flat, (*flat.shape[:-1], *shape))


def pose_entries(pose: Pose, form: Form, xp: Any) -> tuple[list[Entry], tuple[int, ...]]:
    """A pose's entries in ``form``, and that form's trailing shape."""
    R, p = pose
    if form == "pos_quat":
        if all(isinstance(e, float) for row in R for e in row):  # a constant frame
            return [*p, *(float(e) for e in rotation_quat(R, np))], (7,)
        return [*p, *rotation_quat(R, xp)], (7,)
    rows = [e for i in range(3) for e in (*R[i], p[i])]
    if form == "3x4":
        return rows, (3, 4)
    return [*rows, 0.0, 0.0, 0.0, 1.0], (4, 4)


def to_array(pose: Pose, form: Form, xp: Any, like: Any) -> Any:
    """One pose per configuration, ``(..., 4, 4)``, ``(..., 3, 4)`` or ``(..., 7)``."""
    entries, shape = pose_entries(pose, form, xp)
    return stack(entries, shape, xp, like)


def poses_to_array(poses: Sequence[Pose], form: Form, xp: Any, like: Any) -> Any:
    """Several poses per configuration, ``(..., len(poses), *form's shape)``, in one stack."""
    entries: list[Entry] = []
    shape: tuple[int, ...] = (4, 4)
    for pose in poses:
        some, shape = pose_entries(pose, form, xp)
        entries.extend(some)
    return stack(entries, (len(poses), *shape), xp, like)


# --- stacked arrays ---------------------------------------------------------------------------


def unstack(a: Any, axis: int, xp: Any) -> tuple[Any, ...]:
    """``a``'s slices along ``axis``: PyTorch's ``unbind`` (whose derivative is one stack,
    where a slice's allocates and zeroes all of ``a`` for each), else indexing (views)."""
    if hasattr(a, "unbind"):
        return tuple(a.unbind(axis))
    keys = [(*(slice(None),) * axis, i) for i in range(a.shape[axis])]
    return tuple(a[key] for key in keys)


def mat_vec_stacked(R: Any, v: Any, xp: Any) -> Any:
    """:func:`mat_vec` of ``R (m, 3, 3, ...)`` and ``v (m, 3, ...)``: ``(m, 3, ...)``."""
    c0, c1, c2 = unstack(R, 2, xp)  # columns, (m, 3, ...)
    v0, v1, v2 = (e[:, None] for e in unstack(v, 1, xp))
    return (c0 * v0 + c1 * v1) + c2 * v2


def mat_mat_stacked(A: Any, B: Any, xp: Any) -> Any:
    """:func:`mat_mat` of ``A (m, 3, 3, ...)`` and ``B (m, 3, 3, ...)``."""
    a0, a1, a2 = (c[:, :, None] for c in unstack(A, 2, xp))  # columns (m, 3, 1, ...)
    b0, b1, b2 = (r[:, None] for r in unstack(B, 1, xp))  # rows (m, 1, 3, ...)
    return (a0 * b0 + a1 * b1) + a2 * b2


def compose_stacked(R_cur: Any, p: Any, R: Any, t: Any, xp: Any) -> tuple[Any, Any]:
    """:func:`compose` of the poses ``(R_cur, p)`` and ``(R, t)``: ``(R_cur R, p + R_cur t)``."""
    return mat_mat_stacked(R_cur, R, xp), p + mat_vec_stacked(R_cur, t, xp)


def about_point_stacked(R: Any, point: Any, xp: Any) -> Any:
    """:func:`about_point`: ``point - R point``."""
    return point - mat_vec_stacked(R, point, xp)


def rodrigues_stacked(W: Any, W2: Any, s: Any, c1: Any, eye: Any) -> Any:
    """:func:`rodrigues` of ``W``, ``W2 (m, 3, 3, ...)`` and ``s``, ``c1 (m, ...)``; ``eye``:
    the identity, ``(1, 3, 3, 1, ...)`` in the result's library, dtype and device."""
    return (eye + s[:, None, None] * W) + c1[:, None, None] * W2


def axis_turn_stacked(
    R: Any, p: Any, k: int, s: Any, c: Any, point: Any | None, xp: Any
) -> tuple[Any, Any]:
    """:func:`axis_turn` without a screw's advance, of the poses ``(R (m, 3, 3, ...),
    p (m, 3, ...))`` by angles of sines ``s (m, ...)`` and cosines ``c (m, ...)`` about
    coordinate axis ``k`` through ``point (m, 3, ...)``; ``point`` None: the origin, where the
    translation is zero (and left out: the result differs from :func:`axis_turn`'s only in
    signs of zero)."""
    a, b = (k + 1) % 3, (k + 2) % 3
    s, c = s[:, None], c[:, None]
    cols = list(unstack(R, 2, xp))
    Ra, Rb = cols[a], cols[b]
    if point is not None:
        r = unstack(point, 1, xp)
        ra, rb = r[a][:, None], r[b][:, None]
        ta = ra - (c * ra - s * rb)
        tb = rb - (s * ra + c * rb)
        p = p + (Ra * ta + Rb * tb)
    cols[a] = c * Ra + s * Rb
    cols[b] = c * Rb - s * Ra
    if tuple(cols[k].shape) != tuple(cols[a].shape):
        cols[k] = xp.broadcast_to(cols[k], tuple(cols[a].shape))
    return xp.stack(cols, axis=2), p


def stack_mat(M: Mat, xp: Any) -> Any:
    """A matrix of entries (arrays of one shape ``(m, ...)``, or Python floats among them) as
    one ``(m, 3, 3, ...)`` array."""
    like = next(e for row in M for e in row if not isinstance(e, float))
    rows = [
        xp.stack([xp.full_like(like, e) if isinstance(e, float) else e for e in row], axis=1)
        for row in M
    ]
    return xp.stack(rows, axis=1)
