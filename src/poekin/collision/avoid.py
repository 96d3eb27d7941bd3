"""Collision pairs as constraint rows: each near pair's signed distance and its Jacobian.

For a checked pair (:mod:`poekin.collision.query`) with witness points ``p1`` (on the first
geom) and ``p2`` (on the second) and signed distance ``d``, the unit normal ``n = (p2 - p1) /
d`` points from the first geom to the second, whether they are apart (``d > 0``) or overlap
(``d < 0``: the points are the depth apart, the other way round). Moving the configuration by
``dq`` changes the distance, to first order, by

    ``J_d dq``,  ``J_d = n^T (J_p2(q) - J_p1(q))``,

``J_p`` the Jacobian of the point ``p`` carried by its geom's body: ``J_v - [p - o]_x J_w``
from the body's world Jacobian (rows ``[w; v_o]``, :meth:`poekin.Tree.jacobian`), ``o`` the
body's origin. An obstacle fixed in the world, and a geom of a body fixed to it, has
``J_p = 0``; one attached to a frame moves with that frame. This is the gradient of the signed
distance wherever the pair's closest points are unique (two convex shapes apart), and the
derivative of the depth along the contact normal where they overlap.

Two uses, both rows ``G dq >= h``:

* the position constraint of :meth:`poekin.Chain.ik` with ``avoid=True``: ``d + J_d dq >=
  margin`` for each pair closer than an activation distance, linearised at each iterate;
* the velocity damper of :meth:`poekin.Chain.ik_step` (mink's ``CollisionAvoidanceLimit``, with
  its bound on the step ``dq = qvel dt``): ``J_d dq >= -gain (d - margin)``, so that a pair
  closes at most ``gain`` of its gap above ``margin`` in one tick, and one closer than
  ``margin`` is pushed apart (:func:`damper_rows`).

Maths only: no file or terminal output here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.collision.query import _margin, _measure
from poekin.errors import InputError

__all__ = ["ACTIVATION", "PairRows", "check_margin", "damper_rows", "pair_rows"]

FloatArray = NDArray[np.float64]

#: How far beyond ``margin`` a pair gets a row (m): pairs farther apart are not measured
#: exactly (MuJoCo stops early) and constrain nothing.
ACTIVATION = 0.05
_NORMAL_TOL = 1e-12  # m: witness points closer than this give no normal (a zero row)


@dataclasses.dataclass(frozen=True, eq=False)
class PairRows:
    """Every checked pair's signed distance and its Jacobian, per configuration.

    Attributes:
        distance: ``(..., P)`` signed distances (m); ``inf`` for a pair farther apart than
            the activation distance it was measured with.
        jacobian: ``(..., P, nv)`` the rate of each distance per ``qvel`` entry (MuJoCo's
            velocity layout, as :meth:`poekin.Tree.jacobian`; m/rad, m/m), zero where the
            distance is ``inf``.
        pairs: the ``P`` pairs' names, as :attr:`poekin.collision.Distances.pairs`.
    """

    distance: FloatArray
    jacobian: FloatArray
    pairs: tuple[tuple[str, str], ...]


def check_margin(margin: Any, what: str) -> float:
    """``margin`` as a finite float ``>= 0`` (m), or :class:`InputError` naming ``what``."""
    value = _margin(margin, what)
    if not (math.isfinite(value) and value >= 0):
        raise InputError(f"{what}: margin must be a finite distance >= 0 (m), got {value}")
    return value


def pair_rows(
    tree: Any,
    qpos: ArrayLike,
    obstacles: Any = (),
    *,
    activation: float = math.inf,
    ignore: Iterable[Any] = (),
) -> PairRows:
    """The signed distance of every checked pair and its Jacobian ``n^T (J_p2 - J_p1)``.

    Args:
        tree: a tree loaded from a model file (:func:`poekin.load_tree`).
        qpos: ``(..., nq)`` configurations.
        obstacles: obstacles, as for :meth:`poekin.Tree.distances`.
        activation: pairs farther apart than this (m) get distance ``inf`` and a zero row.
        ignore: pairs of names not to check, as for :meth:`poekin.Tree.distances`.

    Returns:
        :class:`PairRows`: ``distance (..., P)``, ``jacobian (..., P, nv)``.

    Raises:
        InputError, UnknownFrameError, ModelError: as :meth:`poekin.Tree.distances`.
    """
    distance, points, scene = _measure(
        tree, qpos, obstacles, _margin(activation, "pair_rows"), ignore
    )
    batch, n_pairs, nv = distance.shape[:-1], distance.shape[-1], tree.nv
    d = distance.reshape(-1, n_pairs)
    pts = points.reshape(-1, n_pairs, 2, 3)
    q = np.broadcast_to(tree._as_qpos(qpos), (*batch, tree.nq)).reshape(-1, tree.nq)
    rows = np.zeros((d.shape[0], n_pairs, nv))
    near = np.isfinite(d)
    if n_pairs and near.any():
        gap = pts[:, :, 1] - pts[:, :, 0]  # (B, P, 3)
        safe = np.where(near & (np.abs(d) > _NORMAL_TOL), d, np.inf)
        normal = np.where(np.isfinite(safe)[..., None], gap / safe[..., None], 0.0)
        frame_of = scene.frame[scene.pairs]  # (P, 2): tree frames, or the base and the world
        moving = sorted({int(f) for f in frame_of.ravel() if f < tree.n_frames})
        # each frame's world Jacobian and origin; the base's and the world's stay zero
        J = np.zeros((d.shape[0], tree.n_frames + 2, 6, nv))
        origin = np.zeros((d.shape[0], tree.n_frames + 2, 3))
        origin[:, : tree.n_frames] = np.asarray(tree.fk(q), dtype=np.float64)[:, :, :3, 3]
        for f in moving:
            J[:, f] = tree.jacobian(q, tree.frame_names[f])
        J = J[:, frame_of]  # (B, P, 2, 6, nv)
        lever = pts - origin[:, frame_of]  # (B, P, 2, 3)
        n = normal[:, :, None, :]
        # n^T (J_v - [lever]_x J_w) = n^T J_v + (lever x n)^T J_w, on each side
        arm = np.stack(
            [
                lever[..., 1] * n[..., 2] - lever[..., 2] * n[..., 1],
                lever[..., 2] * n[..., 0] - lever[..., 0] * n[..., 2],
                lever[..., 0] * n[..., 1] - lever[..., 1] * n[..., 0],
            ],
            axis=-1,
        )
        side = np.einsum("bpsi,bpsin->bpsn", n * np.ones_like(arm), J[..., 3:, :])
        side += np.einsum("bpsi,bpsin->bpsn", arm, J[..., :3, :])
        rows = np.where(near[..., None], side[:, :, 1] - side[:, :, 0], 0.0)
    return PairRows(
        distance=distance,
        jacobian=rows.reshape(*batch, n_pairs, nv),
        pairs=scene.names,
    )


def damper_rows(rows: PairRows, margin: float, gain: float) -> tuple[FloatArray, FloatArray]:
    """The velocity damper's rows ``G dq >= h`` of the measured pairs, ``dq = qvel dt``.

    ``G = J_d`` and ``h = -gain (d - margin)``: a pair may close at most ``gain`` of its gap
    above ``margin`` in one step, and one closer than ``margin`` must open by ``gain`` of its
    shortfall (mink's ``CollisionAvoidanceLimit``, whose bound on ``-J_d dq`` is ``gain' (d -
    margin) / dt``: the same rows for ``gain' = gain dt``). Pairs not measured (``inf``) get
    the row ``0 >= -inf``.

    Args:
        rows: :func:`pair_rows`' answer.
        margin: the distance to keep (m).
        gain: in ``(0, 1]``.

    Returns:
        ``G (..., P, nv)`` and ``h (..., P)``.
    """
    h = np.where(np.isfinite(rows.distance), -gain * (rows.distance - margin), -np.inf)
    return rows.jacobian, h
