"""Signed distances between any two convex shapes: a batched GJK on support functions, EPA for
the penetration depth, and the dispatch that prefers a closed form where one exists.

Shapes are described as in :mod:`poekin.collision.primitives` (a pose ``(..., 4, 4)`` and
MuJoCo's sizes), with two more kinds: ``"ellipsoid"`` (radii ``[a, b, c]``) and ``"mesh"``,
whose "sizes" are its vertices ``(V, 3)`` in the shape's frame, taken as their convex hull (as
MuJoCo collides a mesh), the same vertices for every pose of the batch.

:func:`gjk` is the distance of Gilbert, Johnson and Keerthi on the shapes' support functions,
vectorised over the batch in NumPy: every pair takes one step per round until all have
converged. Spheres and capsules enter as their cores (a point, a segment) and their radii are
subtracted at the end, which is exact and converges in a few rounds. The closest point of each
simplex to the origin is found by trying all its faces (vertices, edges, triangles, the
tetrahedron) with barycentric coordinates from signed areas and volumes, and keeping the
nearest with non-negative coordinates. A pair stops when its distance's upper and lower bounds
(``|x|`` and the support plane's ``x.w/|x|``) are within ``tol`` (default ``1e-10`` m) or no
round improves it: the distance is then within ``tol`` of the true one.

A pair whose shapes overlap (GJK's simplex encloses the origin) gets its penetration depth by
the expanding polytope algorithm (EPA), pair by pair in NumPy (the slower path: a fraction of a
millisecond per pair), to ``epa_tol`` (default ``1e-9`` m) on polytopes (boxes, meshes), and as
far as ``epa_faces`` faces take it on curved shapes (cylinders, ellipsoids), whose depth EPA
approaches from below; the measured worst against MuJoCo is in the tests. Shapes that only
touch, within ``tol``, report their GJK distance (``0`` to within ``tol``).

This NumPy code is the reference. :func:`distance`, :func:`gjk` and :func:`pair_distances`
run its compiled twin (``poekin/kernel/_distance.h``, scalar C pair by pair, on
``poekin.set_threads`` threads) for NumPy input wherever the kernel is built: the same
operations in the same order, so the same bits (``tests/kernel/test_distance_kernel.py``),
EPA included (``benchmarks/bench_distance.py``: on cylinders, GJK some 20 times faster, EPA
some 300). Every sum of products is written out here entry by entry for that (no einsum, BLAS
or ``np.linalg``, whose order of summation varies). JAX arrays and PyTorch tensors take the
array-generic closed forms of :mod:`~poekin.collision.primitives`.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from poekin import arrays
from poekin.collision import primitives
from poekin.collision.primitives import Distance
from poekin.errors import InputError
from poekin.kernel import _fast

__all__ = ["GEOM_TYPES", "KINDS", "distance", "gjk", "pair_distances"]

Array = NDArray[Any]  # float64, or the bool and int arrays of masks and indices
Support = Callable[[Array, Array], Array]  # (local directions (N, 3), item indices) -> points

KINDS = ("sphere", "capsule", "cylinder", "box", "ellipsoid", "mesh")
_CLOSED = {
    ("sphere", "sphere"): primitives.sphere_sphere,
    ("sphere", "capsule"): primitives.sphere_capsule,
    ("capsule", "capsule"): primitives.capsule_capsule,
    ("sphere", "box"): primitives.sphere_box,
    ("sphere", "cylinder"): primitives.sphere_cylinder,
}
_PLANE = {
    "sphere": primitives.plane_sphere,
    "capsule": primitives.plane_capsule,
    "cylinder": primitives.plane_cylinder,
    "box": primitives.plane_box,
    "ellipsoid": primitives.plane_ellipsoid,
}
#: MuJoCo's geom type numbers (``mjtGeom``), as the compiled kernel takes the kinds.
GEOM_TYPES = {
    "plane": 0,
    "sphere": 2,
    "capsule": 3,
    "ellipsoid": 4,
    "cylinder": 5,
    "box": 6,
    "mesh": 7,
}
# the compiled twin (poekin/kernel/_distance.h), None without a C compiler; the tests set it to
# None for the reference
_kernel: Any = _fast._kernel  # type: ignore[attr-defined]
# gjk's defaults: tol, max_iter, epa_tol, epa_faces
_DEFAULTS = (1e-10, 200, 1e-9, 1000)
# every face of a simplex of 4 slots: 4 vertices, 6 edges, 4 triangles, the tetrahedron
_FACES = [c for k in (1, 2, 3, 4) for c in itertools.combinations(range(4), k)]


def distance(kind1: str, pose1: Any, size1: Any, kind2: str, pose2: Any, size2: Any) -> Distance:
    """The signed distance and witness points of any two convex shapes: the closed form of
    :mod:`~poekin.collision.primitives` where there is one (in either order; the points come
    back in the order given), else :func:`gjk`.

    Args:
        kind1: ``"plane"``, ``"sphere"``, ``"capsule"``, ``"cylinder"``, ``"box"``,
            ``"ellipsoid"`` or ``"mesh"``.
        pose1: its pose ``(..., 4, 4)``.
        size1: its sizes ``(..., k)`` (MuJoCo's ``geom_size``; ignored for a plane), or a
            mesh's vertices ``(V, 3)``.
        kind2: the second shape's kind (two planes have no distance).
        pose2: its pose ``(..., 4, 4)``.
        size2: its sizes or vertices.

    Returns:
        The signed distance ``(...)`` and witness points ``(..., 2, 3)``.

    Raises:
        InputError: an unknown kind, two planes, or the inputs' errors.
    """
    for k in (kind1, kind2):
        if k != "plane" and k not in KINDS:
            raise InputError(f"distance: unknown shape kind {k!r}; use 'plane' or one of {KINDS}")
    if kind1 == kind2 == "plane":
        raise InputError("distance: two planes have no distance; give at most one plane")
    fast = _compiled(kind1, pose1, size1, kind2, pose2, size2, (*_DEFAULTS, True, True))
    if fast is not None:
        return fast
    flip = kind2 == "plane" or (kind1, kind2) in {(b, a) for a, b in _CLOSED if a != b}
    if flip:
        found = distance(kind2, pose2, size2, kind1, pose1, size1)
        return Distance(found.distance, found.points[..., ::-1, :])
    if kind1 == "plane":
        if kind2 == "mesh":
            return gjk("plane", pose1, None, kind2, pose2, size2)
        return _PLANE[kind2](pose1, pose2, size2)
    if (kind1, kind2) in _CLOSED:
        return _CLOSED[kind1, kind2](pose1, size1, pose2, size2)
    return gjk(kind1, pose1, size1, kind2, pose2, size2)


# --------------------------------------------------------------------------------------------
# the shapes' support functions


class _Shape:
    """One shape of every pair of the batch, flattened to ``N`` items: its frames, the support
    function of its core in the local frame, and the radius around that core."""

    def __init__(self, kind: str, pose: Array, size: Any, shape: tuple[int, ...]) -> None:
        n = int(np.prod(shape))
        self.kind = kind
        T = np.broadcast_to(pose, (*shape, 4, 4)).reshape(n, 4, 4)
        self.p: Array = T[:, :3, 3]
        self.R: Array = T[:, :3, :3]
        self.radius: Array = np.zeros(n)
        if kind == "mesh":
            self.vertices = size
            self.support: Support = self._mesh
            return
        s = np.broadcast_to(size, (*shape, size.shape[-1])).reshape(n, size.shape[-1])
        self.size: Array = s
        if kind in ("sphere", "capsule"):
            self.radius = s[:, 0].copy()
        self.support = getattr(self, "_" + kind)

    def world(self, d: Array, idx: Array) -> Array:
        """The support points (world) of the items ``idx`` in world directions ``d (M, 3)``."""
        R = self.R[idx]
        local = np.stack([_dot(R[:, :, i], d) for i in range(3)], -1)  # R^T d
        s = self.support(local, idx)
        out: Array = self.p[idx] + np.stack([_dot(R[:, i, :], s) for i in range(3)], -1)
        return out

    @staticmethod
    def _sign(x: Array) -> Array:
        return np.where(x >= 0, 1.0, -1.0)

    def _sphere(self, d: Array, idx: Array) -> Array:
        return np.zeros_like(d)

    def _capsule(self, d: Array, idx: Array) -> Array:
        out = np.zeros_like(d)
        out[:, 2] = self._sign(d[:, 2]) * self.size[idx, 1]
        return out

    def _box(self, d: Array, idx: Array) -> Array:
        return self._sign(d) * self.size[idx, :3]

    def _cylinder(self, d: Array, idx: Array) -> Array:
        rho = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
        scale = np.where(rho > 0, self.size[idx, 0] / np.where(rho > 0, rho, 1.0), 0.0)
        return np.stack(
            [d[:, 0] * scale, d[:, 1] * scale, self._sign(d[:, 2]) * self.size[idx, 1]], -1
        )

    def _ellipsoid(self, d: Array, idx: Array) -> Array:
        radii = self.size[idx, :3]
        m = radii * d
        length = np.sqrt(_dot(m, m))[:, None]
        return np.where(length > 0, radii * m / np.where(length > 0, length, 1.0), 0.0)

    def _mesh(self, d: Array, idx: Array) -> Array:
        best = np.argmax(_dot(d[:, None, :], self.vertices[None]), axis=-1)
        return self.vertices[best]  # type: ignore[no-any-return]


def _check(func: str, kind: str, pose: Any, size: Any, name: str) -> tuple[Array, Any]:
    """A NumPy pose and sizes (or vertices) of ``kind``, checked."""
    if kind not in (*KINDS, "plane"):
        raise InputError(f"{func}: unknown shape kind {kind!r}; use one of {KINDS}")
    T = np.asarray(pose, dtype=np.float64)
    if T.shape[-2:] != (4, 4):
        raise InputError(f"{func}: expected {name} of shape (..., 4, 4), got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise InputError(f"{func}: {name} contains NaN or inf; every value must be finite")
    if kind == "plane":
        return T, None
    s = np.asarray(size, dtype=np.float64)
    if kind == "mesh":
        if s.ndim != 2 or s.shape[1] != 3 or len(s) == 0:
            raise InputError(
                f"{func}: a mesh's vertices must be an array of shape (V, 3), got {s.shape}"
            )
        if not np.all(np.isfinite(s)):
            raise InputError(f"{func}: a mesh's vertices contain NaN or inf")
        return T, s
    need = primitives.SIZES[kind]
    if s.ndim == 0 or s.shape[-1] < need:
        raise InputError(
            f"{func}: a {kind}'s sizes need {need} entries (MuJoCo's geom_size), got shape "
            f"{s.shape}"
        )
    used = s[..., :need]
    if not np.all(np.isfinite(used) & (used >= 0)):
        bad = used[~(np.isfinite(used) & (used >= 0))].flat[0]
        raise InputError(f"{func}: a {kind}'s sizes must be finite and >= 0 (m), got {bad}")
    return T, s


# --------------------------------------------------------------------------------------------
# GJK


def _dot(a: Array, b: Array) -> Array:
    """``a . b`` over the last axis of 3, summed in this order (the compiled twin's)."""
    out: Array = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]
    return out


def _cross(a: Array, b: Array) -> Array:
    """``a x b`` over the last axis."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        -1,
    )


def _norm(a: Array) -> Array:
    """``|a|`` over the last axis of 3."""
    out: Array = np.sqrt(_dot(a, a))
    return out


def _combine(w: Array, Y: Array, slots: Sequence[int]) -> Array:
    """``sum_k w[..., k] Y[..., slots[k], :]``, summed in the order of ``slots``."""
    out: Array = w[..., 0, None] * Y[..., slots[0], :]
    for k in range(1, len(slots)):
        out = out + w[..., k, None] * Y[..., slots[k], :]
    return out


def _face_weights(Y: Array, face: tuple[int, ...]) -> tuple[Array, Array]:
    """Barycentric coordinates ``(M, len(face))`` of the point of ``face``'s affine hull
    nearest the origin (the origin itself for a tetrahedron), and whether they are defined
    (the face not degenerate)."""
    P = [Y[:, i] for i in face]
    m = len(Y)
    if len(face) == 1:
        return np.ones((m, 1)), np.ones(m, dtype=bool)
    if len(face) == 2:
        e = P[1] - P[0]
        ee = _dot(e, e)
        ok = ee > 1e-28 * np.maximum(_dot(P[0], P[0]), 1e-300)
        mu = -_dot(P[0], e) / np.where(ok, ee, 1.0)
        return np.stack([1 - mu, mu], -1), ok
    if len(face) == 3:
        n = _cross(P[1] - P[0], P[2] - P[0])
        nn = _dot(n, n)
        scale = _dot(P[1] - P[0], P[1] - P[0]) * _dot(P[2] - P[0], P[2] - P[0])
        ok = nn > 1e-24 * scale
        den = np.where(ok, nn, 1.0)
        lam = [
            _dot(n, _cross(P[1], P[2])),
            _dot(n, _cross(P[2], P[0])),
            _dot(n, _cross(P[0], P[1])),
        ]
        return np.stack(lam, -1) / den[:, None], ok
    a, b, c, d = P
    vol = _dot(b - a, _cross(c - a, d - a))
    edges = _norm(b - a) * _norm(c - a)
    ok = np.abs(vol) > 1e-12 * edges * _norm(d - a)
    den = np.where(ok, vol, 1.0)
    lam = [
        _dot(b, _cross(c, d)),
        -_dot(a, _cross(c, d)),
        _dot(a, _cross(b, d)),
        -_dot(a, _cross(b, c)),
    ]
    return np.stack(lam, -1) / den[:, None], ok


def _closest(Y: Array, used: NDArray[np.bool_]) -> tuple[Array, NDArray[np.bool_]]:
    """The barycentric weights ``(M, 4)`` of the point of the simplices ``Y (M, 4, 3)`` (the
    slots ``used``) nearest the origin, and the slots of the face it lies on."""
    m = len(Y)
    best = np.full(m, np.inf)
    weights = np.zeros((m, 4))
    members = np.zeros((m, 4), dtype=bool)
    for face in _FACES:
        lam, ok = _face_weights(Y, face)
        ok &= used[:, list(face)].all(axis=1) & (lam >= 0).all(axis=1)
        x = _combine(lam, Y, face)
        norm2 = np.where(ok, _dot(x, x), np.inf)
        better = norm2 < best
        if not better.any():
            continue
        best = np.where(better, norm2, best)
        weights[better] = 0.0
        members[better] = False
        for j, slot in enumerate(face):
            weights[better, slot] = lam[better, j]
            members[better, slot] = True
    return weights, members


def _run_gjk(
    a: _Shape, b: _Shape, n: int, tol: float, max_iter: int
) -> tuple[Array, Array, Array, NDArray[np.bool_], Array, Array, Array]:
    """GJK on the cores of ``a`` and ``b`` for all ``n`` items: the core distance, the two
    core witnesses, whether the simplex encloses the origin, and that final simplex (its
    Minkowski points and their points on ``a`` and ``b``, ``(n, 4, 3)``)."""
    Y = np.zeros((n, 4, 3))
    YA, YB = np.zeros((n, 4, 3)), np.zeros((n, 4, 3))
    used = np.zeros((n, 4), dtype=bool)
    lam = np.zeros((n, 4))
    inside = np.zeros(n, dtype=bool)
    everyone = np.arange(n)
    d = a.p - b.p
    d = np.where((_dot(d, d) > 0)[:, None], d, [1.0, 0.0, 0.0])
    sa, sb = a.world(-d, everyone), b.world(d, everyone)
    Y[:, 0], YA[:, 0], YB[:, 0], used[:, 0], lam[:, 0] = sa - sb, sa, sb, True, 1.0
    x = Y[:, 0].copy()
    active = everyone
    for _ in range(max_iter):
        if len(active) == 0:
            break
        xa = x[active]
        sa, sb = a.world(-xa, active), b.world(xa, active)
        w = sa - sb
        xx = _dot(xa, xa)
        norm = np.sqrt(xx)
        gap = (xx - _dot(xa, w)) / np.where(norm > 0, norm, 1.0)
        stop = (gap <= tol) | (norm <= tol)
        go = active[~stop]
        if len(go) == 0:
            break
        w, sa, sb = w[~stop], sa[~stop], sb[~stop]
        slot = np.argmin(used[go], axis=1)  # the first free slot
        Y[go, slot], YA[go, slot], YB[go, slot], used[go, slot] = w, sa, sb, True
        weights, members = _closest(Y[go], used[go])
        x_new = _combine(weights, Y[go], range(4))
        progress = _dot(x_new, x_new) < _dot(x[go], x[go])
        keep = go[progress]
        x[keep], lam[keep], used[keep] = x_new[progress], weights[progress], members[progress]
        # a slot dropped from a stalled item's simplex: restore the simplex it had
        stalled = go[~progress]
        used[stalled, slot[~progress]] = False
        full = members[progress].all(axis=1)
        inside[keep[full]] = True
        active = keep[~full]
    pa = _combine(lam, YA, range(4))
    pb = _combine(lam, YB, range(4))
    dist = _norm(pa - pb)
    return dist, pa, pb, inside, Y, YA, YB


# --------------------------------------------------------------------------------------------
# EPA


def _epa(
    a: _Shape, b: _Shape, i: int, Y: Array, YA: Array, YB: Array, tol: float, max_faces: int
) -> tuple[float, Array, Array]:
    """The penetration depth of item ``i`` (whose GJK tetrahedron ``Y (4, 3)``, with points
    ``YA`` and ``YB``, encloses the origin) and the points of ``a`` and ``b`` deepest in each
    other: the expanding polytope algorithm.

    Each round takes the face nearest the origin, adds the support point along its normal, and
    replaces the faces that point sees, found by walking from that face across its neighbours
    (so they are one patch, whose rim the new faces close). The nearest face's distance is a
    lower bound of the depth that grows round by round; a round that would lower it (rounding,
    on a support point all but on a face) ends the expansion with the round before."""
    idx = np.array([i])
    verts, va, vb = list(Y), list(YA), list(YB)
    faces: list[tuple[int, int, int]] = []
    normals: list[Array] = []
    dists: list[float] = []
    # adj[f][e]: the face across edge e (from vertex e to vertex e + 1) of face f, and its edge
    adj: list[list[tuple[int, int]]] = []

    def add(f: tuple[int, int, int]) -> None:
        p0, p1, p2 = (verts[k] for k in f)
        n = _cross(p1 - p0, p2 - p0)
        length = float(_norm(n))
        faces.append(f)
        adj.append([(-1, -1)] * 3)
        if length <= 1e-300:  # a degenerate face is never the nearest
            normals.append(n)
            dists.append(np.inf)
            return
        normals.append(n / length)
        dists.append(float(_dot(n, p0)) / length)

    for f in ((0, 1, 2), (0, 3, 1), (0, 2, 3), (1, 3, 2)):
        p0, p1, p2 = (Y[k] for k in f)
        other = Y[({0, 1, 2, 3} - set(f)).pop()]
        outward = _dot(_cross(p1 - p0, p2 - p0), other - p0) < 0
        add(f if outward else (f[0], f[2], f[1]))
    _link(faces, adj, range(4))
    alive = [True] * 4
    best = (-np.inf, 0)
    while True:
        k = int(np.argmin(np.where(alive, dists, np.inf)))
        if dists[k] < best[0]:
            break
        best = (dists[k], k)
        n = normals[k]
        sa, sb = a.world(n[None], idx)[0], b.world(-n[None], idx)[0]
        w = sa - sb
        if _dot(n, w) - dists[k] <= tol or len(faces) >= max_faces:
            break
        horizon: list[tuple[int, int]] = []
        alive[k] = False
        for e in range(3):
            _visit(*adj[k][e], w, normals, dists, adj, alive, horizon)
        verts.append(w)
        va.append(sa)
        vb.append(sb)
        first = len(faces)
        for g, e in horizon:
            u, v = faces[g][e], faces[g][(e + 1) % 3]
            add((v, u, len(verts) - 1))
            adj[-1][0], adj[g][e] = (g, e), (len(faces) - 1, 0)
            alive.append(True)
        _link(faces, adj, range(first, len(faces)))
    dist, k = best
    n, f = normals[k], faces[k]
    P = np.array([verts[j] for j in f])
    m = _cross(P[1] - P[0], P[2] - P[0])
    target = dist * n  # the origin's projection on the face
    lam = np.array(
        [
            _dot(m, _cross(P[1] - target, P[2] - target)),
            _dot(m, _cross(P[2] - target, P[0] - target)),
            _dot(m, _cross(P[0] - target, P[1] - target)),
        ]
    ) / _dot(m, m)
    pa = _combine(lam, np.array([va[j] for j in f]), range(3))
    pb = _combine(lam, np.array([vb[j] for j in f]), range(3))
    return dist, pa, pb


def _visit(
    g: int,
    e: int,
    w: Array,
    normals: list[Array],
    dists: list[float],
    adj: list[list[tuple[int, int]]],
    alive: list[bool],
    horizon: list[tuple[int, int]],
) -> None:
    """EPA's walk over the faces that ``w`` sees, entering face ``g`` by its edge ``e``: a
    face it sees is removed and its other two edges walked; a face it does not see puts the
    edge on the horizon (in order around the patch)."""
    if g < 0 or not alive[g]:  # an edge left unjoined (rounding): nothing across it
        return
    if _dot(normals[g], w) - dists[g] <= 0:
        horizon.append((g, e))
        return
    alive[g] = False
    for step in (1, 2):
        _visit(*adj[g][(e + step) % 3], w, normals, dists, adj, alive, horizon)


def _link(faces: list[tuple[int, int, int]], adj: list[list[tuple[int, int]]], new: range) -> None:
    """Join the faces ``new`` to each other across the edges they share (an edge ``(u, v)`` of
    one is ``(v, u)`` of the other); edges already joined stay as they are."""
    edges = {}
    for f in new:
        for e in range(3):
            edges[faces[f][e], faces[f][(e + 1) % 3]] = (f, e)
    for (u, v), (f, e) in edges.items():
        if adj[f][e][0] < 0 and (v, u) in edges:
            adj[f][e] = edges[v, u]


# --------------------------------------------------------------------------------------------


def gjk(
    kind1: str,
    pose1: Any,
    size1: Any,
    kind2: str,
    pose2: Any,
    size2: Any,
    *,
    tol: float = 1e-10,
    max_iter: int = 200,
    epa_tol: float = 1e-9,
    epa_faces: int = 1000,
    depth: bool = True,
) -> Distance:
    """The signed distance and witness points of two convex shapes by GJK (EPA when they
    overlap), batched over the poses and sizes (NumPy).

    Args:
        kind1: ``"sphere"``, ``"capsule"``, ``"cylinder"``, ``"box"``, ``"ellipsoid"`` or
            ``"mesh"`` (and ``"plane"`` against a mesh).
        pose1: its pose ``(..., 4, 4)``.
        size1: its sizes ``(..., k)`` (MuJoCo's ``geom_size``), or a mesh's vertices
            ``(V, 3)`` in its frame.
        kind2: the second shape's kind.
        pose2: its pose ``(..., 4, 4)``.
        size2: its sizes or vertices.
        tol: the distance's accuracy (m) for separated shapes.
        max_iter: the most GJK rounds.
        epa_tol: the penetration depth's accuracy (m) on polytopes.
        epa_faces: the most faces of an EPA polytope (curved shapes stop there).
        depth: False skips EPA: overlapping cores then report ``0`` as their distance (the
            result is ``-(r1 + r2)``, an upper bound of the signed distance, enough to know
            that the shapes overlap), and their witness points are a common point of the
            cores.

    Returns:
        The signed distance ``(...)`` (negative: penetration depth) and witness points
        ``(..., 2, 3)``, as :mod:`~poekin.collision.primitives` defines them.

    Raises:
        InputError: an unknown kind, a pose not ``(..., 4, 4)``, a negative size, a mesh's
            vertices not ``(V, 3)``, NaN.
    """
    fast = _compiled(
        kind1, pose1, size1, kind2, pose2, size2, (tol, max_iter, epa_tol, epa_faces, depth, False)
    )
    if fast is not None:
        return fast
    T1, s1 = _check("gjk", kind1, pose1, size1, "pose1")
    T2, s2 = _check("gjk", kind2, pose2, size2, "pose2")
    if kind2 == "plane" and kind1 == "mesh":
        found = gjk(kind2, pose2, size2, kind1, pose1, size1, tol=tol)
        return Distance(found.distance, found.points[..., ::-1, :])
    if "plane" in (kind1, kind2):
        if kind1 != "plane" or kind2 != "mesh":
            raise InputError("gjk: a plane goes only with a mesh here; use distance()")
        return _plane_mesh(T1, T2, s2)
    shapes = [T1.shape[:-2], T2.shape[:-2]]
    for k, s in ((kind1, s1), (kind2, s2)):
        if k != "mesh":
            shapes.append(s.shape[:-1])
    shape = np.broadcast_shapes(*shapes)
    n = int(np.prod(shape))
    a = _Shape(kind1, T1, s1, shape)
    b = _Shape(kind2, T2, s2, shape)
    dist, pa, pb, inside, Y, YA, YB = _run_gjk(a, b, n, tol, max_iter)
    sign = np.full(n, -1.0)  # the direction from a to b is -(pa - pb) apart
    for i in np.flatnonzero(inside) if depth else ():
        dist[i], pa[i], pb[i] = _epa(a, b, int(i), Y[i], YA[i], YB[i], epa_tol, epa_faces)
        sign[i] = 1.0
    x = pa - pb
    length = _norm(x)[:, None]
    n12 = np.where(length > 0, sign[:, None] * x / np.where(length > 0, length, 1.0), 0.0)
    if not depth:
        dist[inside] = 0.0
        pb[inside] = pa[inside]
    signed = np.where(inside, -dist, dist) - a.radius - b.radius
    p1 = pa + a.radius[:, None] * n12
    p2 = pb - b.radius[:, None] * n12
    return Distance(signed.reshape(shape), np.stack([p1, p2], -2).reshape(*shape, 2, 3))


def _plane_mesh(P: Array, T: Array, vertices: Array) -> Distance:
    """The plane (half-space ``z <= 0`` of ``P``) against a mesh: its lowest vertex."""
    shape = np.broadcast_shapes(P.shape[:-2], T.shape[:-2])
    P, T = np.broadcast_to(P, (*shape, 4, 4)), np.broadcast_to(T, (*shape, 4, 4))
    R = T[..., None, :3, :3]
    world = T[..., None, :3, 3] + np.stack([_dot(R[..., i, :], vertices) for i in range(3)], -1)
    o, n = P[..., :3, 3], P[..., :3, 2]
    heights = _dot(world - o[..., None, :], n[..., None, :])
    k = np.argmin(heights, axis=-1)
    low = np.take_along_axis(world, k[..., None, None], axis=-2)[..., 0, :]
    h = np.take_along_axis(heights, k[..., None], axis=-1)[..., 0]
    return Distance(h, np.stack([low - h[..., None] * n, low], -2))


# --------------------------------------------------------------------------------------------
# the compiled twin


def _compiled(
    kind1: str,
    pose1: Any,
    size1: Any,
    kind2: str,
    pose2: Any,
    size2: Any,
    options: tuple[float, int, float, int, bool, bool],
) -> Distance | None:
    """The compiled kernel's answer (the reference's bits) for NumPy input that the reference
    accepts; None without the kernel, for JAX and PyTorch input, and for input the reference
    refuses (it then says why). ``options``: gjk's four, ``depth``, and whether the closed
    forms serve (:func:`distance`) or GJK (:func:`gjk`)."""
    values = (pose1, size1, pose2, size2)
    if _kernel is None or any(arrays.kind_of(v) is not None for v in values):
        return None
    closed = options[5]
    if not closed and "plane" in (kind1, kind2) and {kind1, kind2} != {"plane", "mesh"}:
        return None
    try:
        T1, s1 = _check("distance", kind1, pose1, size1, "pose1")
        T2, s2 = _check("distance", kind2, pose2, size2, "pose2")
        shapes = [T1.shape[:-2], T2.shape[:-2]]
        shapes += [s.shape[:-1] for k, s in ((kind1, s1), (kind2, s2)) if k not in _NO_ROWS]
        shape = np.broadcast_shapes(*shapes)
    except (InputError, ValueError, TypeError):
        return None
    n = int(np.prod(shape))
    args = []
    for kind, T, s in ((kind1, T1, s1), (kind2, T2, s2)):
        if kind == "mesh":
            rows = np.ascontiguousarray(s)
        else:
            rows = np.zeros((n, 3))
            if kind != "plane":
                k = min(3, s.shape[-1])
                rows[:, :k] = np.broadcast_to(s[..., :k], (*shape, k)).reshape(n, k)
        poses = np.ascontiguousarray(np.broadcast_to(T, (*shape, 4, 4)).reshape(n, 4, 4))
        args += [GEOM_TYPES[kind], poses, rows]
    tol, max_iter, epa_tol, epa_faces, depth, _ = options
    dist, points = _kernel.distance(
        *args, (float(tol), int(max_iter), float(epa_tol), int(epa_faces), int(depth), int(closed))
    )
    return Distance(dist.reshape(shape), points.reshape(*shape, 2, 3))


_NO_ROWS = ("plane", "mesh")  # kinds whose sizes have no batch axes


def pair_distances(
    kinds: Sequence[str],
    sizes: Any,
    pairs: Any,
    poses: Any,
    vertices: Sequence[Any | None] | None = None,
    cutoff: float = np.inf,
) -> Distance:
    """The signed distances and witness points of ``P`` pairs of ``G`` shapes (a model's
    collision geoms) at a batch of their world poses: :func:`distance` of each pair, in one
    compiled call where the kernel is built (the same bits), pair by pair otherwise.

    A pair at ``cutoff`` or farther apart is not reported (distance ``inf``, points NaN, as
    MuJoCo's ``distmax`` leaves it). The kernel does not measure a pair that a bound puts
    beyond ``cutoff`` by 1e-6 m (the bounding spheres of :func:`bounding_radii`, a box's faces,
    a shape against the other's bounding sphere, a cylinder's capsule): it comes out the same,
    and no rounding decides which pairs it skips.

    Args:
        kinds: the ``G`` shapes' kinds (as :func:`distance` names them).
        sizes: their sizes ``(G, k)`` (MuJoCo's ``geom_size``; ignored for planes and meshes).
        pairs: the pairs ``(P, 2)``, indices of the shapes (two planes have no distance).
        poses: the shapes' world poses ``(..., G, 4, 4)``.
        vertices: for each shape, its vertices ``(V, 3)`` if a mesh, else None (or no list
            where there is no mesh).
        cutoff: the distance (m) from which a pair is not reported; default: all are.

    Returns:
        The signed distances ``(..., P)`` and witness points ``(..., P, 2, 3)``, the first of
        each pair on ``pairs[p, 0]``.

    Raises:
        InputError: an unknown kind, pairs out of range or of two planes, a mesh without
            vertices, poses not ``(..., G, 4, 4)``, and the shapes' own errors.
    """
    g = len(kinds)
    for k in kinds:
        if k not in GEOM_TYPES:
            raise InputError(
                f"pair_distances: unknown shape kind {k!r}; use 'plane' or one of {KINDS}"
            )
    S = np.asarray(sizes, dtype=np.float64)
    if S.ndim != 2 or S.shape[0] != g:
        raise InputError(f"pair_distances: expected sizes of shape ({g}, k), got {S.shape}")
    S = np.ascontiguousarray(np.pad(S[:, :3], ((0, 0), (0, max(0, 3 - S.shape[1])))))
    P = np.asarray(pairs)
    if P.ndim != 2 or P.shape[1] != 2 or P.dtype.kind not in "iu":
        raise InputError(
            f"pair_distances: expected pairs of shape (P, 2) of integers, got {P.shape}"
        )
    if P.size and (P.min() < 0 or P.max() >= g):
        raise InputError(f"pair_distances: pairs must be indices of the {g} shapes, 0 to {g - 1}")
    for a, b in P:
        if kinds[a] == kinds[b] == "plane":
            raise InputError(
                f"pair_distances: shapes {a} and {b} are two planes; they have no distance"
            )
    T = np.asarray(poses, dtype=np.float64)
    if T.ndim < 3 or T.shape[-3:] != (g, 4, 4):
        raise InputError(
            f"pair_distances: expected poses of shape (..., {g}, 4, 4), got shape {T.shape}"
        )
    verts = list(vertices) if vertices is not None else [None] * g
    if len(verts) != g or any(
        (v is None) == (k == "mesh") for k, v in zip(kinds, verts, strict=True)
    ):
        raise InputError(
            "pair_distances: give vertices (V, 3) for each mesh and None for each other shape"
        )
    eye = np.eye(4)
    for k, row, v in zip(kinds, S, verts, strict=True):
        _check("pair_distances", k, eye, v if k == "mesh" else row, "pose")
    if not np.all(np.isfinite(T)):
        raise InputError("pair_distances: poses contain NaN or inf; every value must be finite")
    try:
        limit = float(cutoff)
    except (TypeError, ValueError):
        raise InputError(
            f"pair_distances: cutoff must be a number (m), got {type(cutoff).__name__}"
        ) from None
    if np.isnan(limit):
        raise InputError("pair_distances: cutoff must be a number (m) or inf, got nan")
    shape = T.shape[:-3]
    found = posed_pairs(shapes(kinds, S, verts), P, T.reshape(-1, g, 4, 4), None, None, limit)
    assert isinstance(found, Distance)
    return Distance(
        found.distance.reshape(*shape, len(P)), found.points.reshape(*shape, len(P), 2, 3)
    )


@dataclasses.dataclass(frozen=True, eq=False)
class Shapes:
    """``G`` shapes as :func:`posed_pairs` and the kernel read them (:func:`shapes`): their
    kinds, ``sizes (G, 3)``, a mesh's vertices (else None), and the kernel's arrays of them
    (MuJoCo's type numbers, the meshes' vertices packed, the bounding radii)."""

    kinds: tuple[str, ...]
    sizes: Array
    vertices: tuple[Any | None, ...]
    types: Array
    mesh_adr: Array
    mesh_num: Array
    mesh_vert: Array
    radii: Array


def shapes(kinds: Sequence[str], sizes: Array, vertices: Sequence[Any | None]) -> Shapes:
    """:class:`Shapes` of checked kinds, ``sizes (G, 3)`` and vertices. A kind poekin does not
    measure (a height field, which MuJoCo measures) gets type -1 and no bound: no pair given
    to the kernel may name it."""
    meshes = [np.asarray(v, dtype=np.float64).reshape(-1, 3) for v in vertices if v is not None]
    num = np.array([0 if v is None else len(v) for v in vertices], dtype=np.int32)
    return Shapes(
        kinds=tuple(kinds),
        sizes=np.ascontiguousarray(sizes, dtype=np.float64),
        vertices=tuple(vertices),
        types=np.array([GEOM_TYPES.get(k, -1) for k in kinds], dtype=np.int32),
        mesh_adr=np.concatenate([[0], np.cumsum(num)[:-1]]).astype(np.int32),
        mesh_num=num,
        mesh_vert=np.ascontiguousarray(np.concatenate(meshes) if meshes else np.zeros((0, 3))),
        radii=bounding_radii(kinds, sizes, vertices),
    )


def posed_pairs(
    shaped: Shapes,
    pairs: Any,
    frames: Array,
    frame_of: Any,
    local: Array | None,
    cutoff: float,
    hit: bool = False,
) -> Distance | NDArray[np.bool_]:
    """:func:`pair_distances` on checked arguments, with the geoms posed on frames: geom
    ``g`` at ``frames[:, frame_of[g]] @ local[g]`` (:func:`compose`; ``local[g]`` alone where
    ``frame_of[g] < 0``), or at ``frames[:, g]`` where ``local`` is None. ``frames (B, F, 4,
    4)``, ``pairs (P, 2)``. With ``hit``, only ``(B,)`` whether some pair is nearer than
    ``cutoff`` (the kernel stops at the first)."""
    if _kernel is not None:
        found = _kernel.pair_distances(
            *_kernel_args(shaped, pairs, frames, frame_of, local), float(cutoff), hit
        )
        return found if hit else Distance(*found)
    kinds, sizes, vertices = shaped.kinds, shaped.sizes, shaped.vertices
    index = np.arange(len(kinds)) if local is None else np.asarray(frame_of)
    poses = frames if local is None else compose(frames, index, local)
    B = poses.shape[0]
    dist = np.full((B, len(pairs)), np.inf)
    points = np.full((B, len(pairs), 2, 3), np.nan)
    for p, (a, b) in enumerate(np.asarray(pairs).tolist()):
        found = distance(
            kinds[a],
            poses[:, a],
            vertices[a] if kinds[a] == "mesh" else sizes[a],
            kinds[b],
            poses[:, b],
            vertices[b] if kinds[b] == "mesh" else sizes[b],
        )
        near = found.distance < cutoff
        dist[:, p] = np.where(near, found.distance, np.inf)
        points[:, p] = np.where(near[:, None, None], found.points, np.nan)
    return np.asarray((dist < cutoff).any(axis=-1)) if hit else Distance(dist, points)


def first_clear(
    shaped: Shapes,
    pairs: Any,
    frames: Array,
    frame_of: Any,
    local: Array | None,
    cutoff: float,
    groups: Array,
) -> NDArray[np.int64]:
    """``(N,)`` for each group of configurations, ``frames[groups[i]:groups[i + 1]]``
    (``groups (N + 1,)`` nondecreasing offsets), the index of its first configuration with
    no pair nearer than ``cutoff``, or -1 where none is (arguments as :func:`posed_pairs`).
    The kernel looks at each group's configurations in order and stops at that one; the
    reference checks them all and takes the first."""
    offsets = np.ascontiguousarray(groups, dtype=np.int64)
    if _kernel is not None:
        found: NDArray[np.int64] = _kernel.pair_distances(
            *_kernel_args(shaped, pairs, frames, frame_of, local), float(cutoff), True, offsets
        )
        return found
    hit = np.asarray(posed_pairs(shaped, pairs, frames, frame_of, local, cutoff, True))
    return first_false(hit, offsets)


def first_false(flags: NDArray[np.bool_], groups: Array) -> NDArray[np.int64]:
    """``(N,)`` the index of each group's first False among ``flags (B,)``, the groups
    ``flags[groups[i]:groups[i + 1]]``; -1 where a group has none."""
    index = np.arange(len(flags))
    clear = np.where(flags, len(flags), index)
    starts = np.asarray(groups[:-1], dtype=np.int64)
    ends = np.asarray(groups[1:], dtype=np.int64)
    out = np.full(len(starts), -1, dtype=np.int64)
    filled = starts < ends
    if filled.any():
        first = np.minimum.reduceat(np.append(clear, len(flags)), starts[filled])
        inside = first < ends[filled]
        out[np.flatnonzero(filled)[inside]] = first[inside]
    return out


def _kernel_args(
    shaped: Shapes, pairs: Any, frames: Array, frame_of: Any, local: Array | None
) -> tuple[Any, ...]:
    """The kernel's ``pair_distances`` arguments up to the cutoff (``frames`` may be the
    kernel's ``(FK kernel, qpos)``, :func:`poekin.collision.query.frames_of`)."""
    index = np.arange(len(shaped.kinds)) if local is None else np.asarray(frame_of)
    return (
        shaped.types,
        shaped.sizes,
        shaped.mesh_adr,
        shaped.mesh_num,
        shaped.mesh_vert,
        np.ascontiguousarray(pairs, dtype=np.int32),
        frames if isinstance(frames, tuple) else np.ascontiguousarray(frames, dtype=np.float64),
        np.ascontiguousarray(index, dtype=np.int32),
        None if local is None else np.ascontiguousarray(local, dtype=np.float64),
        (*_DEFAULTS, 1, 1),
        shaped.radii,
    )


def compose(frames: Array, frame_of: Any, local: Array) -> Array:
    """``(B, G, 4, 4)`` the poses ``frames[:, frame_of[g]] @ local[g]`` (``local[g]`` where
    ``frame_of[g] < 0``), each entry's four products summed in order, as the kernel sums
    them. ``frames (B, F, 4, 4)``, ``local (G, 4, 4)``."""
    index = np.asarray(frame_of)
    F = frames[:, np.maximum(index, 0)]
    out = F[..., :, 0, None] * local[:, None, 0, :]
    for k in (1, 2, 3):
        out = out + F[..., :, k, None] * local[:, None, k, :]
    out[:, index < 0] = local[index < 0]
    return np.asarray(out)


def bounding_radii(kinds: Sequence[str], sizes: Array, vertices: Sequence[Any | None]) -> Array:
    """``(G,)`` the radius about each shape's origin of a sphere that holds it (``inf`` for
    a plane or a kind poekin does not measure): MuJoCo's ``geom_rbound``. ``sizes (G, 3)``;
    ``vertices`` a mesh's, else None."""
    radii = np.empty(len(kinds))
    for g, (kind, s, v) in enumerate(zip(kinds, sizes, vertices, strict=True)):
        if kind not in GEOM_TYPES or kind == "plane":
            radii[g] = np.inf
        elif kind == "mesh":
            radii[g] = np.sqrt(np.max(np.sum(np.square(np.asarray(v, dtype=np.float64)), axis=-1)))
        else:
            radii[g] = {
                "sphere": s[0],
                "capsule": s[0] + s[1],
                "cylinder": np.sqrt(s[0] * s[0] + s[1] * s[1]),
                "box": np.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]),
                "ellipsoid": max(s[0], s[1], s[2]),
            }[kind]
    return radii
