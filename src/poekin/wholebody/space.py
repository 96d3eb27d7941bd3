"""The configuration space a whole-body solve moves in: ``qpos`` and its tangent, ``qvel``.

``qpos`` is MuJoCo's layout and the tangent MuJoCo's velocity layout (:meth:`poekin.Tree.
jacobian`'s columns): a hinge or slide joint moves by its own number; a free joint's position
by the world-frame step ``v`` and its quaternion ``Q`` to ``Q exp(w / 2)`` (``w`` the angular
step about the body's own axes); a ball joint's quaternion likewise. Quaternions are
normalised after each move, as MuJoCo's ``mj_integratePos`` does.

The solved variables are every tangent entry except those of frozen joints. Hinge and slide
entries have the joints' limits as bounds; ball and free entries have none.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from poekin.errors import InputError, did_you_mean

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = ["Space", "space"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]


@dataclasses.dataclass(frozen=True)
class Space:
    """A tree's variables for a solve.

    Attributes:
        nq, nv: the tree's ``qpos`` and tangent sizes.
        variables: ``(n,)`` the tangent (``qvel``) index of each solved variable.
        scalar_q: ``(h,)`` the ``qpos`` index of each solved hinge or slide joint ...
        scalar_v: ``(h,)`` ... its index among the variables ...
        lower, upper: ``(h,)`` ... and its limits (``-inf``/``inf`` if none).
        revolute: ``(h,)`` True for a hinge.
        quats: ``(qpos index of w, variable index of the first angular entry)`` of each solved
            ball or free joint's quaternion.
        free_p: ``(qpos index of x, variable index of v_x)`` of each solved free joint.
        frozen: the frozen joints' names.
    """

    nq: int
    nv: int
    variables: IntArray
    scalar_q: IntArray
    scalar_v: IntArray
    lower: FloatArray
    upper: FloatArray
    revolute: BoolArray
    quats: tuple[tuple[int, int], ...]
    free_p: tuple[tuple[int, int], ...]
    frozen: frozenset[str]

    @property
    def n(self) -> int:
        return len(self.variables)

    def integrate(self, qpos: FloatArray, x: FloatArray) -> FloatArray:
        """``qpos (B, nq)`` moved by the variables' step ``x (B, n)``."""
        out = np.array(qpos, dtype=np.float64)
        out[:, self.scalar_q] += x[:, self.scalar_v]
        for a, v in self.free_p:
            out[:, a : a + 3] += x[:, v : v + 3]
        for a, v in self.quats:
            out[:, a : a + 4] = quat_times_exp(out[:, a : a + 4], x[:, v : v + 3])
        return out

    def bounds(self, qpos: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(B, n)`` bounds on a step from ``qpos``: the limits less the position, each
        holding zero (a joint outside its limits may stay where it is: an iteration of
        :meth:`poekin.Tree.ik` starts inside); none for quaternion and free-position entries."""
        lo, hi = self._room(qpos)
        return np.minimum(lo, 0.0), np.maximum(hi, 0.0)

    def step_bounds(self, qpos: FloatArray, reach: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(B, n)`` bounds on one control tick's step from ``qpos``, each entry within
        ``reach`` ``(n,)`` of zero (``v_max dt``): hinge and slide ``clamp(lower - q, -reach,
        reach)`` to ``clamp(upper - q, -reach, reach)``, so that a joint outside its limits
        moves back toward them, at most at its velocity limit (:meth:`bounds` lets it stay)."""
        lo, hi = self._room(qpos)
        return np.minimum(np.maximum(lo, -reach), reach), np.minimum(np.maximum(hi, -reach), reach)

    def _room(self, qpos: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(B, n)`` hinge and slide ``lower - q`` and ``upper - q``; -inf and inf for the
        quaternion and free-position entries."""
        B = qpos.shape[0]
        lo = np.full((B, self.n), -np.inf)
        hi = np.full((B, self.n), np.inf)
        q = qpos[:, self.scalar_q]
        lo[:, self.scalar_v] = self.lower - q
        hi[:, self.scalar_v] = self.upper - q
        return lo, hi

    def difference(self, qpos: FloatArray, reference: FloatArray) -> FloatArray:
        """``(B, n)`` the step from ``qpos`` toward ``reference`` for a posture: hinge and
        slide ``reference - qpos``, ball joints the rotation vector between the quaternions,
        free joints none (a posture does not move the base)."""
        out = np.zeros((qpos.shape[0], self.n))
        out[:, self.scalar_v] = reference[:, self.scalar_q] - qpos[:, self.scalar_q]
        free = {v for _, v in self.free_p}
        for a, v in self.quats:
            if v - 3 in free:
                continue
            out[:, v : v + 3] = quat_log_between(qpos[:, a : a + 4], reference[:, a : a + 4])
        return out

    def clip(self, qpos: FloatArray) -> FloatArray:
        """``qpos`` with each solved hinge and slide joint clamped into its limits."""
        out = np.array(qpos, dtype=np.float64)
        out[..., self.scalar_q] = np.clip(out[..., self.scalar_q], self.lower, self.upper)
        return out


def quat_times_exp(Q: FloatArray, w: FloatArray) -> FloatArray:
    """``(B, 4)`` unit quaternions ``Q exp(w / 2)`` for rotation vectors ``w (B, 3)`` in the
    body frame, normalised (``wxyz``)."""
    angle = np.sqrt(np.sum(w * w, axis=1))
    half = 0.5 * angle
    small = angle < 1e-8
    s = np.where(small, 0.5 - angle * angle / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    e = np.concatenate([np.cos(half)[:, None], s[:, None] * w], axis=1)
    out = _quat_mul(Q, e)
    unit: FloatArray = out / np.sqrt(np.sum(out * out, axis=1))[:, None]
    return unit


def _quat_mul(a: FloatArray, b: FloatArray) -> FloatArray:
    aw, ax, ay, az = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    bw, bx, by, bz = b[:, 0], b[:, 1], b[:, 2], b[:, 3]
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=1,
    )


def quat_log_between(Q: FloatArray, P: FloatArray) -> FloatArray:
    """``(B, 3)`` the body-frame rotation vector ``w`` with ``P = Q exp(w / 2)`` (the shorter
    way round)."""
    conj = Q * np.array([1.0, -1.0, -1.0, -1.0])
    n = np.sqrt(np.sum(Q * Q, axis=1) * np.sum(P * P, axis=1))
    r = _quat_mul(conj, P) / n[:, None]
    r = np.where(r[:, :1] < 0, -r, r)
    v = r[:, 1:]
    sin_half = np.sqrt(np.sum(v * v, axis=1))
    angle = 2.0 * np.arctan2(sin_half, r[:, 0])
    scale = np.where(sin_half > 1e-12, angle / np.where(sin_half > 1e-12, sin_half, 1.0), 2.0)
    w: FloatArray = v * scale[:, None]
    return w


def space(tree: Tree, freeze: Collection[str]) -> Space:
    """The :class:`Space` of ``tree`` with the joints ``freeze`` held (kept with the tree).

    Raises:
        InputError: ``freeze`` names no joint of the tree (the message suggests one), or
            leaves nothing to solve for.
    """
    key = "wholebody-space:" + ",".join(sorted(freeze))
    cache = tree._ik_cache
    if key not in cache:
        cache[key] = _space(tree, frozenset(freeze))
    found: Space = cache[key]
    return found


def _space(tree: Tree, frozen: frozenset[str]) -> Space:
    for name in sorted(frozen):
        if name not in tree.joint_names:
            raise InputError(
                f"freeze names {name!r}, which is no joint: "
                f"{did_you_mean(name, list(tree.joint_names))}"
            )
    variables: list[int] = []
    scalar_q: list[int] = []
    scalar_v: list[int] = []
    lower: list[float] = []
    upper: list[float] = []
    revolute: list[bool] = []
    quats: list[tuple[int, int]] = []
    free_p: list[tuple[int, int]] = []
    dof_adr = tree._dof_adr
    for k, (name, kind, mimic) in enumerate(
        zip(tree.joint_names, tree.joint_types, tree.mimics, strict=True)
    ):
        if mimic is not None or name in frozen:
            continue
        a, v, at = int(tree.qpos_adr[k]), int(dof_adr[k]), len(variables)
        if kind in ("revolute", "prismatic"):
            variables.append(v)
            scalar_q.append(a)
            scalar_v.append(at)
            lower.append(float(tree.joint_limits[k, 0]))
            upper.append(float(tree.joint_limits[k, 1]))
            revolute.append(kind == "revolute")
        elif kind == "ball":
            variables.extend(range(v, v + 3))
            quats.append((a, at))
        else:
            variables.extend(range(v, v + 6))
            free_p.append((a, at))
            quats.append((a + 3, at + 3))
    if not variables:
        raise InputError("every joint is frozen: nothing to solve for; freeze fewer joints")
    return Space(
        nq=tree.nq,
        nv=tree.nv,
        variables=np.array(variables, dtype=np.intp),
        scalar_q=np.array(scalar_q, dtype=np.intp),
        scalar_v=np.array(scalar_v, dtype=np.intp),
        lower=np.array(lower),
        upper=np.array(upper),
        revolute=np.array(revolute, dtype=bool),
        quats=tuple(quats),
        free_p=tuple(free_p),
        frozen=frozen,
    )
