"""Exact signed distances between primitive shapes, in closed form, batched, on every array
library.

Shapes are plain arrays, as MuJoCo describes its geoms:

* a **pose** ``(..., 4, 4)``: the shape's frame in the world (its centre; a capsule's and a
  cylinder's axis is the frame's z axis);
* **sizes** ``(..., k)`` as MuJoCo's ``geom_size``, of which each kind reads its first entries
  (a row of ``model.geom_size``, three entries, is taken as it is): sphere ``[r]``, capsule
  ``[r, half_length]`` (the segment from ``-half_length`` to ``+half_length`` on z, inflated
  by ``r``), cylinder ``[r, half_length]``, box half sizes ``[x, y, z]``;
* a **plane** is the half-space ``z <= 0`` of its frame (normal ``+z``), infinite, as MuJoCo
  collides it; it has no sizes here.

Every function returns a :class:`Distance`: the signed distance ``(...)`` (negative: the
shapes overlap, by that penetration depth, the smallest translation that separates them), and
the witness points ``(..., 2, 3)`` in the world, the first on the first shape, the second on
the second, with ``points[..., 1, :] - points[..., 0, :] = distance * n`` for the unit
direction ``n`` from the first shape to the second. Apart, they are the closest points;
overlapping, each is the point of its shape deepest inside the other. This is MuJoCo's
convention (``mj_geomDistance``'s ``fromto``), and the distances are MuJoCo's exactly, to
rounding, separated and overlapping (tested on random poses and sizes).

The batch axes of the poses and sizes broadcast together. NumPy input is computed in float64
and checked (shapes, finite values, sizes ``>= 0``: :class:`~poekin.errors.InputError`); JAX
arrays and PyTorch tensors keep their float dtype (:mod:`poekin.arrays`' rules) and are only
checked for shape (no check on traced values), and run the same
formulas through their array-API namespace, with gradients: every ``where`` has finite values
on both sides and every square root a positive argument, so ``jax.grad`` and PyTorch's
autograd give finite derivatives everywhere (at coincident centres and parallel axes
included, where the witness direction is a choice; the distance is differentiable wherever
the closest points are unique).

Every dot product and matrix-vector product is summed entry by entry in one fixed order, so that
the compiled twin (``poekin/kernel/_distance.h``, which :func:`poekin.collision.gjk.distance`
runs for NumPy input) gives the same bits.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from poekin import arrays
from poekin.errors import InputError

__all__ = [
    "SIZES",
    "Distance",
    "box_corner_signs",
    "capsule_capsule",
    "plane_box",
    "plane_capsule",
    "plane_cylinder",
    "plane_ellipsoid",
    "plane_sphere",
    "sphere_box",
    "sphere_capsule",
    "sphere_cylinder",
    "sphere_sphere",
]

# How many leading entries of MuJoCo's geom_size each kind reads.
SIZES = {"sphere": 1, "capsule": 2, "cylinder": 2, "box": 3, "ellipsoid": 3}

# Squared lengths below this count as zero: a direction is then a fixed choice, and 1 - b^2 of
# two capsule axes below it counts as parallel (any point of the overlap is a closest point).
_TINY = 1e-30
_PARALLEL = 1e-14


class Distance(NamedTuple):
    """Signed distances ``(...)`` and witness points ``(..., 2, 3)`` (first shape, second)."""

    distance: Any
    points: Any


# --------------------------------------------------------------------------------------------
# input


def _prepare(
    func: str, poses: tuple[Any, ...], sizes: tuple[tuple[Any, str], ...]
) -> tuple[Any, list[Any], list[Any]]:
    """The namespace, the poses and the sizes of ``func``'s arguments in one float dtype.

    ``sizes`` pairs each size array with its kind (which says how many entries it needs)."""
    values = [*poses, *(s for s, _ in sizes)]
    xp, kind = arrays.namespace_of(values, f"{func}: poses and sizes")
    if kind is None:
        out = [np.asarray(v) for v in values]
        for a in out:
            if a.dtype.kind not in "biuf":
                raise InputError(f"{func}: expected real numbers, got an array of dtype {a.dtype}")
        out = [a.astype(np.float64, copy=False) for a in out]
    else:
        dtype = arrays.float_dtype(xp, values)
        anchor = next(v for v in values if arrays.kind_of(v) is not None)
        out = [arrays.convert(v, xp, dtype, anchor) for v in values]
    P, S = out[: len(poses)], out[len(poses) :]
    for k, T in enumerate(P):
        if tuple(T.shape[-2:]) != (4, 4):
            raise InputError(
                f"{func}: expected pose{k + 1} of shape (..., 4, 4), got shape {tuple(T.shape)}"
            )
        if kind is None and not np.all(np.isfinite(T)):
            raise InputError(f"{func}: pose{k + 1} contains NaN or inf; every value must be finite")
    for s, (_, shape_kind) in zip(S, sizes, strict=True):
        need = SIZES[shape_kind]
        if s.ndim == 0 or s.shape[-1] < need:
            raise InputError(
                f"{func}: a {shape_kind}'s sizes need {need} entries (MuJoCo's geom_size), "
                f"got shape {tuple(s.shape)}"
            )
        if kind is None:
            used = s[..., :need]
            if not np.all(np.isfinite(used)) or np.any(used < 0):
                bad = used[~(np.isfinite(used) & (used >= 0))].flat[0]
                raise InputError(
                    f"{func}: a {shape_kind}'s sizes must be finite and >= 0 (m), got {bad}"
                )
    return xp, P, S


def _dot(a: Any, b: Any, xp: Any) -> Any:
    """``a . b`` over the last axis of 3, summed in this order (the compiled twin's)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _clip(x: Any, lo: Any, hi: Any, xp: Any) -> Any:
    return xp.minimum(xp.maximum(x, lo), hi)


def _unit(v: Any, fallback: Any, xp: Any) -> tuple[Any, Any]:
    """``v / |v|`` and ``|v|``, ``fallback`` (a unit vector) where ``v`` is (nearly) zero; the
    length's gradient is finite there too."""
    s = _dot(v, v, xp)
    ok = s > _TINY
    n = xp.sqrt(xp.where(ok, s, 1.0))
    u = xp.where(ok[..., None], v / n[..., None], fallback)
    return u, xp.where(ok, n, 0.0)


def _result(dist: Any, p1: Any, p2: Any, xp: Any) -> Distance:
    """The distances and points, broadcast to one batch shape."""
    shape = np.broadcast_shapes(tuple(dist.shape), tuple(p1.shape[:-1]), tuple(p2.shape[:-1]))
    points = xp.stack([xp.broadcast_to(p1, (*shape, 3)), xp.broadcast_to(p2, (*shape, 3))], -2)
    return Distance(xp.broadcast_to(dist, shape), points)


def _inflated(a: Any, b: Any, r1: Any, r2: Any, fallback: Any, xp: Any) -> Distance:
    """Two shapes that are the points ``a`` and ``b`` of their cores (the closest pair)
    inflated by ``r1`` and ``r2``: distance ``|b - a| - r1 - r2`` along ``n = (b - a)/|b - a|``
    (``fallback`` where the cores touch), witnesses ``a + r1 n`` and ``b - r2 n``."""
    n, length = _unit(b - a, fallback, xp)
    return _result(length - r1 - r2, a + r1[..., None] * n, b - r2[..., None] * n, xp)


def _frame(T: Any) -> tuple[Any, Any]:
    """A pose's origin ``(..., 3)`` and rotation ``(..., 3, 3)``."""
    return T[..., :3, 3], T[..., :3, :3]


def _to_local(R: Any, v: Any, xp: Any) -> Any:
    """``R^T v`` for world vectors ``v (..., 3)``, each entry summed in the order of
    :func:`_dot`."""
    return xp.stack([_dot(R[..., :, i], v, xp) for i in range(3)], -1)


def _to_world(R: Any, v: Any, xp: Any) -> Any:
    """``R v`` for local vectors ``v (..., 3)``, each entry summed in the order of
    :func:`_dot`."""
    return xp.stack([_dot(R[..., i, :], v, xp) for i in range(3)], -1)


def _z_axis(like: Any, xp: Any) -> Any:
    """The unit vector ``+z``, in ``like``'s dtype and device: the fixed witness direction."""
    z = xp.zeros_like(like[..., :3, 3])
    return xp.stack([z[..., 0], z[..., 1], z[..., 2] + 1.0], -1)


# --------------------------------------------------------------------------------------------
# spheres and capsules


def sphere_sphere(pose1: Any, size1: Any, pose2: Any, size2: Any) -> Distance:
    """Sphere to sphere: ``|c2 - c1| - r1 - r2``.

    Args:
        pose1: the first sphere's pose ``(..., 4, 4)`` (its centre; the rotation is unused).
        size1: its sizes ``(..., k)``, ``[r, ...]``.
        pose2: the second sphere's pose ``(..., 4, 4)``.
        size2: its sizes ``(..., k)``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)``.

    Raises:
        InputError: a pose not ``(..., 4, 4)``, a negative radius, NaN (NumPy input).
    """
    xp, (T1, T2), (s1, s2) = _prepare(
        "sphere_sphere", (pose1, pose2), ((size1, "sphere"), (size2, "sphere"))
    )
    return _inflated(T1[..., :3, 3], T2[..., :3, 3], s1[..., 0], s2[..., 0], _z_axis(T1, xp), xp)


def sphere_capsule(pose1: Any, size1: Any, pose2: Any, size2: Any) -> Distance:
    """Sphere to capsule: the centre's distance to the capsule's segment, less both radii.

    Args:
        pose1: the sphere's pose ``(..., 4, 4)``.
        size1: its sizes ``(..., k)``, ``[r, ...]``.
        pose2: the capsule's pose ``(..., 4, 4)``, its segment on the frame's z axis.
        size2: its sizes ``(..., k)``, ``[r, half_length, ...]``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)``.

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, (T1, T2), (s1, s2) = _prepare(
        "sphere_capsule", (pose1, pose2), ((size1, "sphere"), (size2, "capsule"))
    )
    c, (p, R) = T1[..., :3, 3], _frame(T2)
    u, h = R[..., :, 2], s2[..., 1]
    t = _clip(_dot(c - p, u, xp), -h, h, xp)
    b = p + t[..., None] * u
    return _inflated(c, b, s1[..., 0], s2[..., 0], _z_axis(T1, xp), xp)


def _segments(c1: Any, u: Any, h1: Any, c2: Any, v: Any, h2: Any, xp: Any) -> tuple[Any, Any]:
    """The closest points of the segments ``c1 + s u``, ``|s| <= h1`` and ``c2 + t v``,
    ``|t| <= h2`` (unit ``u``, ``v``): Ericson's clamped solution (*Real-Time Collision
    Detection*, 5.1.9). Parallel segments (``1 - (u.v)^2 < 1e-14``) take ``s = 0`` clamped and
    its nearest ``t``, one of their closest pairs."""
    w = c1 - c2
    b, c, f = _dot(u, v, xp), _dot(u, w, xp), _dot(v, w, xp)
    denom = 1.0 - b * b
    parallel = denom < _PARALLEL
    s = xp.where(parallel, 0.0, (b * f - c) / xp.where(parallel, 1.0, denom))
    s = _clip(s, -h1, h1, xp)
    t = b * s + f
    t_clamped = _clip(t, -h2, h2, xp)
    s = xp.where(t == t_clamped, s, _clip(b * t_clamped - c, -h1, h1, xp))
    return c1 + s[..., None] * u, c2 + t_clamped[..., None] * v


def capsule_capsule(pose1: Any, size1: Any, pose2: Any, size2: Any) -> Distance:
    """Capsule to capsule: the distance of their segments (robust for parallel ones), less
    both radii.

    Args:
        pose1: the first capsule's pose ``(..., 4, 4)``, its segment on the frame's z axis.
        size1: its sizes ``(..., k)``, ``[r, half_length, ...]``.
        pose2: the second capsule's pose ``(..., 4, 4)``.
        size2: its sizes ``(..., k)``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)``; for parallel
        capsules whose segments overlap along the axis, one of the closest pairs.

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, (T1, T2), (s1, s2) = _prepare(
        "capsule_capsule", (pose1, pose2), ((size1, "capsule"), (size2, "capsule"))
    )
    (p1, R1), (p2, R2) = _frame(T1), _frame(T2)
    a, b = _segments(p1, R1[..., :, 2], s1[..., 1], p2, R2[..., :, 2], s2[..., 1], xp)
    return _inflated(a, b, s1[..., 0], s2[..., 0], _z_axis(T1, xp), xp)


# --------------------------------------------------------------------------------------------
# a sphere and a solid


def _point_box(q: Any, h: Any, xp: Any) -> tuple[Any, Any, Any]:
    """A local point ``q`` against the box of half sizes ``h``: its signed distance, the box's
    witness (the nearest surface point: clamped outside, on the nearest face inside) and the
    outward unit normal there, all local."""
    clamped = _clip(q, -h, h, xp)
    gap = q - clamped
    outside = _dot(gap, gap, xp) > 0.0
    margin = h - xp.abs(q)  # > 0 inside, per axis
    face = xp.argmin(margin, axis=-1)
    on_face = xp.stack([face == 0, face == 1, face == 2], -1)
    sign = xp.where(q >= 0, 1.0, -1.0)
    inside_normal = xp.where(on_face, sign, 0.0)
    inside_point = xp.where(on_face, sign * h, q)
    depth = xp.min(margin, axis=-1)
    n_out, length = _unit(gap, inside_normal, xp)
    dist = xp.where(outside, length, -depth)
    point = xp.where(outside[..., None], clamped, inside_point)
    normal = xp.where(outside[..., None], n_out, inside_normal)
    return dist, point, normal


def sphere_box(pose1: Any, size1: Any, pose2: Any, size2: Any) -> Distance:
    """Sphere to box: the centre's signed distance to the box, less the radius (a centre
    inside the box is at minus its distance to the nearest face).

    Args:
        pose1: the sphere's pose ``(..., 4, 4)``.
        size1: its sizes ``(..., k)``, ``[r, ...]``.
        pose2: the box's pose ``(..., 4, 4)``.
        size2: its half sizes ``(..., 3)``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)``.

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, (T1, T2), (s1, s2) = _prepare(
        "sphere_box", (pose1, pose2), ((size1, "sphere"), (size2, "box"))
    )
    c, (p, R) = T1[..., :3, 3], _frame(T2)
    sd, point, normal = _point_box(_to_local(R, c - p, xp), s2[..., :3], xp)
    r = s1[..., 0]
    n = _to_world(R, normal, xp)  # from the box out, towards the centre
    return _result(sd - r, c - r[..., None] * n, p + _to_world(R, point, xp), xp)


def sphere_cylinder(pose1: Any, size1: Any, pose2: Any, size2: Any) -> Distance:
    """Sphere to cylinder: the centre's signed distance to the solid cylinder, less the radius.

    Args:
        pose1: the sphere's pose ``(..., 4, 4)``.
        size1: its sizes ``(..., k)``, ``[r, ...]``.
        pose2: the cylinder's pose ``(..., 4, 4)``, its axis the frame's z axis.
        size2: its sizes ``(..., k)``, ``[r, half_length, ...]``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)``.

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, (T1, T2), (s1, s2) = _prepare(
        "sphere_cylinder", (pose1, pose2), ((size1, "sphere"), (size2, "cylinder"))
    )
    c, (p, R) = T1[..., :3, 3], _frame(T2)
    q = _to_local(R, c - p, xp)
    rc, h = s2[..., 0], s2[..., 1]
    zero = xp.zeros_like(q[..., 0])
    radial, rho = _unit(xp.stack([q[..., 0], q[..., 1], zero], -1), _x_axis(q, xp), xp)
    z = q[..., 2]
    sz = xp.where(z >= 0, 1.0, -1.0)
    d_rho, d_z = rho - rc, xp.abs(z) - h
    # outside: the nearest point of the cylinder, the radius and the height clamped
    rho_c, z_c = xp.minimum(rho, rc), _clip(z, -h, h, xp)
    near = radial * rho_c[..., None] + xp.stack([zero, zero, z_c], -1)
    gap = q - near
    outside = (d_rho > 0) | (d_z > 0)
    cap = d_z >= d_rho  # inside: the nearer of the cap and the side
    axis_z = xp.stack([zero, zero, sz], -1)
    inside_point = xp.where(
        cap[..., None],
        xp.stack([q[..., 0], q[..., 1], sz * h], -1),
        radial * rc[..., None] + xp.stack([zero, zero, z], -1),
    )
    inside_normal = xp.where(cap[..., None], axis_z, radial)
    n_out, length = _unit(gap, inside_normal, xp)
    sd = xp.where(outside, length, xp.maximum(d_rho, d_z))
    point = xp.where(outside[..., None], near, inside_point)
    normal = xp.where(outside[..., None], n_out, inside_normal)
    r = s1[..., 0]
    n = _to_world(R, normal, xp)
    return _result(sd - r, c - r[..., None] * n, p + _to_world(R, point, xp), xp)


def _x_axis(like: Any, xp: Any) -> Any:
    """The unit vector ``+x`` of ``like``'s batch shape (``like (..., 3)``)."""
    z = xp.zeros_like(like)
    return xp.stack([z[..., 0] + 1.0, z[..., 1], z[..., 2]], -1)


# --------------------------------------------------------------------------------------------
# the plane (the half-space z <= 0 of its frame) and a convex shape


def _plane(func: str, plane: Any, pose: Any, size: Any, kind: str) -> tuple[Any, Any, Any, Any]:
    """The namespace, the plane's origin and normal (world), the shape's pose and sizes."""
    xp, (P, T), (s,) = _prepare(func, (plane, pose), ((size, kind),))
    return xp, P, T, s


def _on_plane(xp: Any, P: Any, lowest: Any, radius: Any | None = None) -> Distance:
    """The plane against the shape whose lowest point (deepest along ``-n``) is ``lowest``,
    inflated by ``radius``: distance ``n.(lowest - o) - radius``, witnesses the projection on
    the plane and the point itself (less ``radius`` along ``n``)."""
    o, n = P[..., :3, 3], P[..., :3, 2]
    height = _dot(lowest - o, n, xp)
    on_plane = lowest - height[..., None] * n
    if radius is None:
        return _result(height, on_plane, lowest, xp)
    return _result(height - radius, on_plane, lowest - radius[..., None] * n, xp)


def plane_sphere(plane: Any, pose: Any, size: Any) -> Distance:
    """Plane to sphere: the centre's height above the plane, less the radius.

    Args:
        plane: the plane's pose ``(..., 4, 4)`` (the half-space ``z <= 0`` of this frame).
        pose: the sphere's pose ``(..., 4, 4)``.
        size: its sizes ``(..., k)``, ``[r, ...]``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)`` (plane, sphere).

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, P, T, s = _plane("plane_sphere", plane, pose, size, "sphere")
    return _on_plane(xp, P, T[..., :3, 3], s[..., 0])


def plane_capsule(plane: Any, pose: Any, size: Any) -> Distance:
    """Plane to capsule: the lower end of the segment's height, less the radius.

    Args:
        plane: the plane's pose ``(..., 4, 4)``.
        pose: the capsule's pose ``(..., 4, 4)``.
        size: its sizes ``(..., k)``, ``[r, half_length, ...]``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)`` (plane, capsule); a
        capsule parallel to the plane takes its ``-z`` end.

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, P, T, s = _plane("plane_capsule", plane, pose, size, "capsule")
    (p, R), n = _frame(T), P[..., :3, 2]
    u = R[..., :, 2]
    down = xp.where(_dot(u, n, xp) > 0, -1.0, 1.0)  # towards the plane
    return _on_plane(xp, P, p + (down * s[..., 1])[..., None] * u, s[..., 0])


def box_corner_signs(R: Any, n: Any, xp: Any) -> Any:
    """For a box of rotation ``R (..., 3, 3)``, the signs ``(..., 3)`` of its corner lowest
    along ``n (..., 3)`` (``-1`` where an axis points up, ``+1`` otherwise)."""
    return xp.where(_to_local(R, n, xp) > 0, -1.0, 1.0)


def plane_box(plane: Any, pose: Any, size: Any) -> Distance:
    """Plane to box: the height of its lowest corner.

    Args:
        plane: the plane's pose ``(..., 4, 4)``.
        pose: the box's pose ``(..., 4, 4)``.
        size: its half sizes ``(..., 3)``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)`` (plane, box).

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, P, T, s = _plane("plane_box", plane, pose, size, "box")
    p, R = _frame(T)
    corner = box_corner_signs(R, P[..., :3, 2], xp) * s[..., :3]
    return _on_plane(xp, P, p + _to_world(R, corner, xp))


def plane_cylinder(plane: Any, pose: Any, size: Any) -> Distance:
    """Plane to cylinder: the height of the lowest point of its lower rim,
    ``z - h |n.a| - r sqrt(1 - (n.a)^2)``.

    Args:
        plane: the plane's pose ``(..., 4, 4)``.
        pose: the cylinder's pose ``(..., 4, 4)``, its axis ``a`` the frame's z axis.
        size: its sizes ``(..., k)``, ``[r, half_length, ...]``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)`` (plane, cylinder); an
        axis along the normal takes the lower cap's centre.

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, P, T, s = _plane("plane_cylinder", plane, pose, size, "cylinder")
    (p, R), n = _frame(T), P[..., :3, 2]
    a = R[..., :, 2]
    na = _dot(n, a, xp)
    down = xp.where(na > 0, -1.0, 1.0)
    across, _ = _unit(na[..., None] * a - n, xp.zeros_like(a), xp)  # lowest way within a cap
    lowest = p + (down * s[..., 1])[..., None] * a + s[..., 0][..., None] * across
    return _on_plane(xp, P, lowest)


def plane_ellipsoid(plane: Any, pose: Any, size: Any) -> Distance:
    """Plane to ellipsoid: the height of its support point along ``-n``,
    ``z - |D R^T n|`` for its radii ``D``.

    Args:
        plane: the plane's pose ``(..., 4, 4)``.
        pose: the ellipsoid's pose ``(..., 4, 4)``.
        size: its radii ``(..., 3)``.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)`` (plane, ellipsoid).

    Raises:
        InputError: as :func:`sphere_sphere`.
    """
    xp, P, T, s = _plane("plane_ellipsoid", plane, pose, size, "ellipsoid")
    p, R = _frame(T)
    radii = s[..., :3]
    m = _to_local(R, P[..., :3, 2], xp) * radii  # D R^T n
    m_unit, _ = _unit(m, _z_axis(T, xp), xp)
    return _on_plane(xp, P, p - _to_world(R, radii * m_unit, xp))
