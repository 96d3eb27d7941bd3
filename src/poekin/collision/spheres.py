"""Spheres that cover a shape, as cuRobo approximates a robot's links: every point of the shape
lies inside some sphere, and the spheres reach at most ``error`` metres outside it.

* A **sphere** is itself (error 0).
* A **capsule** ``[r, h]`` gets ``k`` spheres on its segment, from end to end at spacing
  ``s = 2h / (k - 1)``, of radius ``R = sqrt(r^2 + (s/2)^2)``: a point of the capsule is within
  ``r`` of a point of the segment, which is within ``s/2`` along the axis of a centre, so within
  ``R`` of it (the ends are centres). They reach ``R - r`` outside it, no more.
* A **cylinder**, a **box** and a convex **mesh** (its vertices ``(V, 3)``) get a grid: their
  bounding box in their frame is cut into cells (as near cubes as the extents allow, ``n_i``
  along axis ``i``), and each cell whose circumscribed sphere reaches the shape keeps that
  sphere. Every point of the shape is in some cell, which is kept. The error stated is the
  bound ``max(R + sd(c))`` over the kept spheres, ``sd(c)`` the signed distance of a centre to
  the shape (a point of a sphere is within ``R`` of ``c``; a centre inside at depth ``d`` has a
  ball of radius ``d`` in the shape, so no point of its sphere is farther than ``R - d`` from
  it). The distances are the exact closed forms for boxes and cylinders and GJK (to ``1e-10``)
  for meshes, whose inside centres count as ``sd = 0`` (a bound again). A box cut along its own
  faces keeps only inside centres, and its error is ``R`` less the half cell, about ``0.37``
  of a cell's side.

Give ``count`` (at most that many spheres, the finest grid within it) or ``tolerance`` (the
fewest spheres whose error is within it, in metres).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from poekin.collision import gjk, primitives
from poekin.errors import InputError

__all__ = ["KINDS", "RobotSpheres", "Spheres", "fit_spheres", "spheres"]

KINDS = ("sphere", "capsule", "cylinder", "box", "mesh")
_MAX_SPHERES = 100_000  # a tolerance finer than this many spheres allow is refused


class Spheres(NamedTuple):
    """Spheres in the shape's frame: ``centers (k, 3)``, ``radii (k,)``, and ``error``, how far
    (m) they reach outside the shape at most."""

    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    error: float


def fit_spheres(
    kind: str, size: Any, *, count: int | None = None, tolerance: float | None = None
) -> Spheres:
    """Spheres covering a shape, in its frame.

    Args:
        kind: ``"sphere"``, ``"capsule"``, ``"cylinder"``, ``"box"`` or ``"mesh"``.
        size: MuJoCo's sizes of the shape (``geom_size``), or a mesh's vertices ``(V, 3)``.
        count: the most spheres to use.
        tolerance: the most they may reach outside the shape (m).

    Returns:
        The spheres and their covering error.

    Raises:
        InputError: an unknown kind, neither or both of ``count`` and ``tolerance``, a count
            below 1, a tolerance not above 0 or finer than 100,000 spheres allow, bad sizes.
    """
    if kind not in KINDS:
        raise InputError(f"fit_spheres: unknown shape kind {kind!r}; use one of {KINDS}")
    if (count is None) == (tolerance is None):
        raise InputError("fit_spheres: give exactly one of count= and tolerance=")
    if count is not None and (not isinstance(count, int | np.integer) or count < 1):
        raise InputError(f"fit_spheres: count must be an integer >= 1, got {count!r}")
    if tolerance is not None and not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"fit_spheres: tolerance must be > 0 (m), got {tolerance}")
    s = _sizes(kind, size)
    if kind == "sphere":
        return Spheres(np.zeros((1, 3)), s[:1].copy(), 0.0)
    if kind == "capsule":
        return _capsule(float(s[0]), float(s[1]), count, tolerance)
    lo, hi = (-s[:3], s[:3]) if kind == "box" else _bounds(kind, s)
    if count is not None:
        return _grid_within(kind, s, lo, hi, count)
    assert tolerance is not None
    return _grid_to(kind, s, lo, hi, tolerance)


def _sizes(kind: str, size: Any) -> NDArray[np.float64]:
    s = np.asarray(size, dtype=np.float64)
    if kind == "mesh":
        if s.ndim != 2 or s.shape[1] != 3 or len(s) < 4 or not np.all(np.isfinite(s)):
            raise InputError(
                f"fit_spheres: a mesh's vertices must be finite, of shape (V, 3) with V >= 4, "
                f"got shape {s.shape}"
            )
        return s
    need = primitives.SIZES[kind]
    if s.ndim != 1 or len(s) < need:
        raise InputError(
            f"fit_spheres: a {kind}'s sizes need {need} entries (MuJoCo's geom_size), got "
            f"shape {s.shape}"
        )
    used = s[:need]
    if not np.all(np.isfinite(used) & (used > 0)):
        bad = used[~(np.isfinite(used) & (used > 0))][0]
        raise InputError(f"fit_spheres: a {kind}'s sizes must be finite and > 0 (m), got {bad}")
    return s


def _capsule(r: float, h: float, count: int | None, tolerance: float | None) -> Spheres:
    if count is None:
        assert tolerance is not None
        half_gap = math.sqrt((r + tolerance) ** 2 - r * r)  # the widest s/2 within tolerance
        count = math.ceil(h / half_gap) + 1
        if count > _MAX_SPHERES:
            raise InputError(
                f"fit_spheres: tolerance {tolerance} m needs {count} spheres on this capsule; "
                f"give a coarser one"
            )
    if count == 1:
        return Spheres(np.zeros((1, 3)), np.array([r + h]), h)
    z = np.linspace(-h, h, count)
    radius = math.sqrt(r * r + (h / (count - 1)) ** 2)
    centers = np.stack([np.zeros(count), np.zeros(count), z], -1)
    return Spheres(centers, np.full(count, radius), radius - r)


def _bounds(kind: str, s: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
    if kind == "cylinder":
        e = np.array([s[0], s[0], s[1]])
        return -e, e
    return s.min(axis=0), s.max(axis=0)


def _signed(kind: str, s: NDArray[np.float64], points: NDArray[np.float64]) -> Any:
    """The signed distances of local ``points (M, 3)`` to the shape (inside mesh points: 0)."""
    T = np.tile(np.eye(4), (len(points), 1, 1))
    T[:, :3, 3] = points
    zero = np.zeros(1)
    if kind == "box":
        return primitives.sphere_box(T, zero, np.eye(4), s).distance
    if kind == "cylinder":
        return primitives.sphere_cylinder(T, zero, np.eye(4), s).distance
    return gjk.gjk("sphere", T, zero, "mesh", np.eye(4), s, depth=False).distance


def _grid(
    kind: str, s: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], a: float
) -> Spheres:
    """The grid of cells of side about ``a``."""
    n = np.maximum(1, np.ceil((hi - lo) / a - 1e-9)).astype(int)
    step = (hi - lo) / n
    axes = [lo[i] + step[i] * (np.arange(n[i]) + 0.5) for i in range(3)]
    centers = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    radius = float(np.linalg.norm(step)) / 2
    sd = _signed(kind, s, centers)
    keep = sd <= radius
    error = float(np.max(radius + sd[keep]))
    return Spheres(centers[keep], np.full(int(keep.sum()), radius), max(error, 0.0))


def _grid_within(
    kind: str, s: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], count: int
) -> Spheres:
    """The finest grid of at most ``count`` spheres: cell sides by bisection."""
    big = float(np.max(hi - lo)) * (1 + 1e-9)
    best = _grid(kind, s, lo, hi, big)  # one cell: one sphere
    if len(best.radii) > count:
        raise InputError(f"fit_spheres: count must be >= {len(best.radii)} here, got {count}")
    small = big / max(count, 1) ** (1 / 3) / 4
    for _ in range(40):
        if big - small <= 1e-6 * big:
            break
        mid = math.sqrt(big * small)
        trial = _grid(kind, s, lo, hi, mid)
        if len(trial.radii) <= count:
            best, big = trial, mid
        else:
            small = mid
    return best


def _grid_to(
    kind: str, s: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], tol: float
) -> Spheres:
    """The coarsest grid whose error is within ``tol``: cell sides halved from the whole box,
    then the largest within it by bisection."""
    big = float(np.max(hi - lo)) * (1 + 1e-9)
    a = big
    fits = _grid(kind, s, lo, hi, a)
    while fits.error > tol:
        a /= 2
        if np.prod(np.ceil((hi - lo) / a)) > _MAX_SPHERES:
            raise InputError(
                f"fit_spheres: tolerance {tol} m needs more than {_MAX_SPHERES} spheres on "
                f"this {kind}; give a coarser one"
            )
        fits = _grid(kind, s, lo, hi, a)
    if a == big:
        return fits
    coarse = 2 * a
    for _ in range(20):
        mid = (a + coarse) / 2
        trial = _grid(kind, s, lo, hi, mid)
        if trial.error <= tol:
            a, fits = mid, trial
        else:
            coarse = mid
    return fits


class RobotSpheres(NamedTuple):
    """Spheres covering every collision geom of a robot, each fixed to a body.

    Attributes:
        bodies: ``(S,)`` each sphere's body, an index of ``tree.body_names`` (-1: the world).
        centers: ``(S, 3)`` each sphere's centre in its body's frame (m).
        radii: ``(S,)`` their radii (m).
        geoms: ``(S,)`` the collision geom each sphere covers, an index of the collision
            model's ``geom_names``.
        error: how far (m) any sphere reaches outside the geom it covers, at most.
    """

    bodies: NDArray[np.intp]
    centers: NDArray[np.float64]
    radii: NDArray[np.float64]
    geoms: NDArray[np.intp]
    error: float

    def world(self, tree: Any, qpos: Any) -> NDArray[np.float64]:
        """``(..., S, 3)`` the centres in the world at ``qpos (..., nq)`` (``tree.fk``)."""
        frames = np.asarray(tree.fk(qpos), dtype=np.float64)
        world = np.broadcast_to(np.eye(4), (*frames.shape[:-3], 1, 4, 4))
        frames = np.concatenate([frames, world], axis=-3)  # index -1: the world
        T = frames[..., self.bodies, :, :]
        out: NDArray[np.float64] = (T[..., :3, :3] @ self.centers[..., None])[..., 0] + T[
            ..., :3, 3
        ]
        return out


def spheres(tree: Any, *, count: int | None = None, tolerance: float | None = None) -> RobotSpheres:
    """Spheres covering a robot's collision geometry (:func:`poekin.collision.model_of`), as
    cuRobo approximates its links: :func:`fit_spheres` on each geom (a plane is skipped: it is
    no link), the centres moved into the geom's body frame.

    Args:
        tree: a tree loaded from a model file.
        count: the most spheres per geom (a sphere takes one).
        tolerance: the most any sphere may reach outside its geom (m).

    Returns:
        A :class:`RobotSpheres`, ``error`` the largest of the geoms' errors.

    Raises:
        InputError: neither or both of ``count`` and ``tolerance``, or as :func:`fit_spheres`.
        ModelError: the tree knows no model file, or its collision meshes are missing.
    """
    from poekin.collision.model import GEOM_TYPES, model_of

    collision = model_of(tree)
    model = collision.mj_model
    bodies, centers, radii, geoms = [], [], [], []
    error = 0.0
    for g, kind in enumerate(collision.geom_types):
        if kind not in KINDS:
            if kind == "plane":
                continue
            raise InputError(
                f"spheres: geom {collision.geom_names[g]!r} is a {kind}, which no fit covers"
            )
        size: Any = collision.geom_sizes[g]
        if kind == "mesh":
            assert GEOM_TYPES[int(model.geom_type[g])] == "mesh"
            m = int(model.geom_dataid[g])
            start, n = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
            size = np.array(model.mesh_vert[start : start + n], dtype=np.float64)
        fit = fit_spheres(kind, size, count=count, tolerance=tolerance)
        bodies.append(np.full(len(fit.radii), int(collision.geom_bodies[g]), dtype=np.intp))
        centers.append(fit.centers @ collision.geom_rot[g].T + collision.geom_pos[g])
        radii.append(fit.radii)
        geoms.append(np.full(len(fit.radii), g, dtype=np.intp))
        error = max(error, float(fit.error))
    if not radii:
        raise InputError("spheres: the model has no collision geom to cover")
    return RobotSpheres(
        np.concatenate(bodies),
        np.concatenate(centers),
        np.concatenate(radii),
        np.concatenate(geoms),
        error,
    )
