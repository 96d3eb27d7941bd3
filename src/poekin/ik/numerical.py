"""Numerical inverse kinematics of a chain: damped least squares inside the joint limits.

One algorithm, written here once as the NumPy reference (batched over targets, entry by entry
like :func:`poekin._poe.poe`), and repeated operation for operation by the compiled kernel
(``_ik_core.h``): both give the same bits (``tests/ik/test_ik_numerical.py`` checks it).

**One attempt**, for a target ``(R_t, p_t)`` from a start ``q`` inside the limits, repeats:

1. ``T(q) = (R, p)`` and the world Jacobian ``J`` (rows ``[w; v_frame]``: the end frame's
   angular velocity and its origin's velocity, both in the world frame, the frame the target
   is given in), with the kernel's own sine and cosine (:mod:`poekin.kernel._sincos`);
2. the residual ``r = [k e_o; e_p]``: ``e_p = p_t - p`` (m) and ``e_o = 2 (x, y, z)``, the
   vector part of the quaternion ``(w >= 0)`` of ``R_t R^T`` by Shepperd's method (square
   roots only, so NumPy and C agree to the bit): ``2 sin(theta/2)`` times the axis, the
   rotation vector to first order, and never zero at ``theta = pi``. ``k`` is
   ``orientation_weight`` (m/rad). With ``position_only``, ``r = e_p``;
3. stop if ``|e_p| <= pos_tol`` and ``theta <= ori_tol`` (from ``|e_o|``, without arcsin:
   ``theta <= |e_o| / sqrt(1 - |e_o|^2/4)``), or if the cost ``|r|^2`` has not halved in the
   last 8 iterations (a stall), or after ``max_iterations``;
4. the Levenberg-Marquardt step ``d`` of ``(J^T J + lam I) d = J^T r`` (``J J^T`` in its dual
   form when the chain has more joints than ``r`` has rows), damped by
   ``lam = min(0.03 |r|^2 + 1e-18 L^2, L^2)`` (``L``: the chain's size; Yamashita and
   Fukushima's choice, which keeps quadratic convergence as ``|r| -> 0``, also at singular
   solutions, with a ceiling for far targets; the floor only keeps the system positive
   definite: near a singular solution, where ``J`` has a singular value ``sigma`` of 1e-7, a
   floor above ``sigma^2`` would damp the very direction the solve must move along), scaled so
   that no joint moves more than 1.5 (rad or m);
5. the joint limits as constraints: a revolute joint that the step takes out of its limits
   is first moved by whole turns (:func:`~poekin.ik._angles.wrap_into_limits`: the same
   pose); a joint that still leaves them is held at its limit (an active set) and the step
   is solved again for the other joints; an unlimited revolute joint is kept in
   ``(-pi, pi]``. Every iterate is inside the limits.

**Far targets.** A target farther than :data:`FAR` (a million metres, along any axis) from
the world's origin is aimed at, in steps 2 to 5, as the point at that distance on the line
from the origin to it (:func:`aimed`): its cost would otherwise overflow (positions of 1e155 m
square to inf) and leave no least-cost iterate. No arm reaches that far, so such a target
fails; its answer is the least-cost iterate for the point aimed at, deterministic and inside
the limits, and its errors are those to the target itself (:func:`errors`, which does not
overflow short of distances beyond the largest float).

**Attempts.** The first starts at ``q0`` (brought into the limits) if given, else each starts
at a configuration uniform within the limits, drawn from a counter-based generator keyed by
the seed and the bits of the target and ``q0`` (:mod:`poekin.ik._rng`); attempts run in turn
until one succeeds or ``max_attempts`` have run. A target's answer therefore depends on its
own numbers only: alone, in any batch, at any position, on any thread or vector width.
Without success the answer is the iterate of least cost over all attempts.

The reference runs every target of a batch in lock-step, with masks: the per-iteration maths
(:func:`evaluate`, :func:`residual`, :func:`jacobian_rows`, :func:`damped_step`, :func:`step`,
with :func:`~poekin.ik._angles.wrap_into_limits`) uses ``+ - * / sqrt floor`` and ``where``
on entries, with the array library's namespace ``xp``, and reads the chain's constants as
Python values (:class:`ChainTerms`); the random starts (:mod:`poekin.ik._rng`) take an
``xp`` too. Only :func:`solve_reference`'s bookkeeping (dropping finished targets, writing
results) is NumPy's: :mod:`poekin.ik.fixed` solves JAX arrays and PyTorch tensors with the
same functions and a fixed shape of work instead.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import sys
import types
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose, arrays, lie
from poekin._poe import (
    ChainTerms,
    Column,
    Trig,
    _Model,
    as_joint_values,
    chain_terms,
    real_array,
    space_jacobian,
    world_columns,
)
from poekin.errors import InputError, JointLimitsWarning
from poekin.ik import _rng
from poekin.ik._angles import outside_limits, within_limits, wrap_into_limits
from poekin.kernel import _fast, _sincos

if TYPE_CHECKING:
    from poekin.chain import Chain

__all__ = [
    "DEFAULT_MAX_ATTEMPTS",
    "DEFAULT_MAX_ITERATIONS",
    "DEFAULT_ORIENTATION_WEIGHT",
    "IKResult",
    "Settings",
    "settings",
    "solve",
    "solve_reference",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]
Entry = Any
Entries = list[Any]

DEFAULT_ORIENTATION_WEIGHT = 0.3  # m/rad
DEFAULT_MAX_ITERATIONS = 50
DEFAULT_MAX_ATTEMPTS = 100

DAMPING = 0.03  # lam = DAMPING |r|^2 + FLOOR L^2, at most L^2
FLOOR = 1e-18
STEP_MAX = 1.5  # rad (or m): the largest move of one joint in one iteration
STALL_FACTOR = 0.5  # an attempt stalls when its cost has not fallen below this times ...
STALL_ITERATIONS = 8  # ... its last such value for this many iterations
# A target position beyond this along any axis (m) is aimed at from this distance (see "Far
# targets" above)
FAR = 1e6
# Above this (m), squares of a distance's entries could overflow: it is computed scaled
HUGE = 1e150
# The stopping test is this much stricter than success (relative, in squared errors), so that
# an attempt that stops has met the tolerances whatever the last bit of the final errors.
TOL_MARGIN = 1.0 - 1e-6


@dataclasses.dataclass(frozen=True)
class IKResult:
    """What an inverse kinematics solve found, per target. Immutable. NumPy arrays, or, for
    JAX and PyTorch input, arrays of that library (a JAX pytree: it leaves ``jit`` and
    ``vmap``).

    Attributes:
        q: ``(..., n)`` joint values (rad, m), always within the joint limits: the solution
            where ``success``, else the least-squares best configuration found. For
            :meth:`poekin.Tree.ik`, ``(..., nq)``: the whole ``qpos``.
        success: ``(...,)`` True where the pose is reached within ``pos_tol`` and ``ori_tol``
            (position only with ``position_only``) and ``q`` is within the limits.
        pos_err: ``(...,)`` distance between the target's origin and the frame's at ``q`` (m).
        ori_err: ``(...,)`` geodesic angle between the target's rotation and the frame's at
            ``q`` (rad, in ``[0, pi]``; as :func:`poekin.pose_errors`).
        iterations: ``(...,)`` iterations run over all attempts (one FK and Jacobian each).
        attempts: ``(...,)`` attempts run, the last one the answer's (1 if the first start
            succeeded).
    """

    q: FloatArray
    success: BoolArray
    pos_err: FloatArray
    ori_err: FloatArray
    iterations: IntArray
    attempts: IntArray


# --- settings -----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Settings:
    """The options of a solve, validated (see :meth:`poekin.Chain.ik` for their meaning)."""

    pos_tol: float
    ori_tol: float
    position_only: bool
    orientation_weight: float
    max_iterations: int
    max_attempts: int
    max_total_iterations: int | None = None  # JAX and PyTorch's budget (None: NumPy's, none)

    @property
    def pos_tol2(self) -> float:
        """The stopping test's bound on ``|e_p|^2``."""
        return self.pos_tol * self.pos_tol * TOL_MARGIN

    @property
    def ori_tol2(self) -> float:
        """The stopping test's bound on ``|e_o|^2``: ``theta <= |e_o| / sqrt(1 - |e_o|^2/4)``
        (``|e_o| = 2 sin(theta/2)``), so ``|e_o|^2 (1 + tol^2/4) <= tol^2`` implies
        ``theta <= tol``."""
        tol2 = self.ori_tol * self.ori_tol
        return tol2 / (1.0 + tol2 / 4.0) * TOL_MARGIN


def _positive(value: object, name: str, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InputError(f"{name} must be a number ({unit}), got {value!r:.40}")
    x = float(value)
    if not (math.isfinite(x) and x > 0):
        raise InputError(f"{name} must be a finite number > 0 ({unit}), got {x!r}")
    return x


def _count(value: object, name: str, most: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InputError(f"{name} must be an integer from 1 to {most}, got {value!r:.40}")
    if not 1 <= int(value) <= most:
        raise InputError(f"{name} must be an integer from 1 to {most}, got {int(value)}")
    return int(value)


def settings(
    *,
    pos_tol: float = 1e-10,
    ori_tol: float = 1e-10,
    position_only: bool = False,
    orientation_weight: float = DEFAULT_ORIENTATION_WEIGHT,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    max_attempts: int = DEFAULT_MAX_ATTEMPTS,
    max_total_iterations: int | None = None,
) -> Settings:
    """Validated :class:`Settings`; :class:`InputError` names a bad one. Arguments seen before
    (of the same types) are not validated again: a controller's calls stay cheap."""
    args = (
        pos_tol,
        ori_tol,
        position_only,
        orientation_weight,
        max_iterations,
        max_attempts,
        max_total_iterations,
    )
    try:
        return _settings_seen(*args)
    except TypeError:  # an unhashable argument: validation says what is wrong with it
        return _settings(*args)


@functools.lru_cache(maxsize=64, typed=True)
def _settings_seen(*args: Any) -> Settings:
    return _settings(*args)


def _settings(
    pos_tol: float,
    ori_tol: float,
    position_only: bool,
    orientation_weight: float,
    max_iterations: int,
    max_attempts: int,
    max_total_iterations: int | None,
) -> Settings:
    if not isinstance(position_only, bool | np.bool_):
        raise InputError(f"position_only must be True or False, got {position_only!r:.40}")
    budget = max_total_iterations
    return Settings(
        _positive(pos_tol, "pos_tol", "m"),
        _positive(ori_tol, "ori_tol", "rad"),
        bool(position_only),
        _positive(orientation_weight, "orientation_weight", "m/rad"),
        _count(max_iterations, "max_iterations", 1_000_000),
        _count(max_attempts, "max_attempts", 1_000_000),
        None if budget is None else _count(budget, "max_total_iterations", 1_000_000_000),
    )


def check_seed(seed: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2**64:
        raise InputError(f"seed must be an integer from 0 to 2**64 - 1, got {seed!r:.40}")
    return int(seed)


# --- the damping's bounds for a chain ------------------------------------------------------


def damping_floor(terms: ChainTerms, s: Settings) -> float:
    """The damping's floor, ``1e-18 L^2`` with ``L`` at least the orientation weight."""
    return FLOOR * _damping_length2(terms.scale, s)


def damping_ceiling(terms: ChainTerms, s: Settings) -> float:
    return _damping_length2(terms.scale, s)


def _damping_length2(scale: float, s: Settings) -> float:
    """``L^2`` of the damping (:func:`step`): the chain's size, at least the orientation
    weight."""
    length = max(scale, 0.0 if s.position_only else s.orientation_weight)
    return length * length


# --- one iteration's maths (entries; every array library) ---------------------------------


def evaluate(
    chain: Chain,
    q: Sequence[Entry],
    xp: Any,
    model: _Model | None = None,
    trig: Trig = _sincos.sincos,
) -> tuple[_pose.Pose, list[Column]]:
    """The end pose ``T(q)`` and the world Jacobian's columns ``[w; v_frame]``, with the
    compiled kernel's sine and cosine (``trig``; the array library's own below float64), of
    the chain's constants or of ``model`` (:meth:`poekin.Chain._model`, from parameters)."""
    model = chain._constants if model is None else model
    columns, pose = space_jacobian(model.screws, model.rows, q, xp, model.home, trig)
    # under JAX each entry of the end pose computed once, not again in each of the residual's
    # and the Jacobian's entries (_pose.settle: a fifth less compile time, measured)
    pose = _pose.settle_pose(pose, xp)
    return pose, world_columns(columns, pose[1])


def residual(
    pose: _pose.Pose, target: _pose.Pose, s: Settings, xp: Any
) -> tuple[Entries, Entry, Entry, Entry, Entries]:
    """``r`` (rows), ``|r|^2``, ``|e_p|^2``, ``|e_o|^2`` (see the module's step 2) and the
    quaternion ``(w, x, y, z)`` of ``R_t R^T`` that ``e_o`` comes from."""
    (R, p), (R_t, p_t) = pose, target
    e_p = [p_t[0] - p[0], p_t[1] - p[1], p_t[2] - p[2]]
    # (settled: every entry of the Jacobian's angular rows reads it)
    quat = _pose.settle(list(_pose.rotation_quat(_pose.mat_mat(R_t, _pose.transpose(R)), xp)), xp)
    e_o = [2.0 * quat[1], 2.0 * quat[2], 2.0 * quat[3]]
    k = s.orientation_weight
    r = e_p if s.position_only else [k * e_o[0], k * e_o[1], k * e_o[2], *e_p]
    return r, _sum_squares(r), _sum_squares(e_p), _sum_squares(e_o), quat


def _sum_squares(v: Sequence[Entry]) -> Entry:
    total = v[0] * v[0]
    for x in v[1:]:
        total = total + x * x
    return total


def jacobian_rows(columns: Sequence[Column], quat: Sequence[Entry], s: Settings) -> list[Entries]:
    """The Jacobian of ``-r`` as rows of entries (``m x n``): the world Jacobian's linear rows
    ``v``, and for ``e_o`` the exact derivative ``k (w a + v x a)`` of each angular column
    ``a``, where ``(w, v)`` is the quaternion of ``R_t R^T`` (turning the frame by ``a dt``
    turns it by ``-a dt``: ``d e_o = -(w I + [v]) a dt``). Near a solution (``w = 1``,
    ``v = 0``) it is ``k a``; far from one it keeps the steps on the cost's true slope, so that
    the best fit of an unreachable target is a minimum of ``|r|^2``."""
    linear = [[c[3 + i] for c in columns] for i in range(3)]
    if s.position_only:
        return linear
    k, w, v = s.orientation_weight, quat[0], quat[1:]
    turned = [_pose.cross(v, c[:3]) for c in columns]
    angular = [
        [k * (w * c[i] + vc[i]) for c, vc in zip(columns, turned, strict=True)] for i in range(3)
    ]
    return angular + linear


def _cholesky_solve(A: list[Entries], b: Entries, tiny: float, xp: Any) -> Entries:
    """``A x = b`` for symmetric positive definite ``A`` (its lower triangle is read), by its
    ``L D L^T`` factorisation (Cholesky's without square roots, ``L`` unit lower triangular);
    a pivot ``D_j`` below ``tiny`` (rounding, in a damped system) is taken as ``tiny``.

    The one division of each row is off the chain of dependent operations that an iteration
    waits for: ``E_ij = L_ij D_j`` is kept beside ``L``, and the solves divide by ``D`` once,
    between the forward and the backward pass (the kernel's single calls, issue 26)."""
    n = len(b)
    L: list[Entries] = [[None] * n for _ in range(n)]
    E: list[Entries] = [[None] * n for _ in range(n)]
    D: Entries = [None] * n
    for j in range(n):
        acc = A[j][j]
        for k in range(j):
            acc = acc - E[j][k] * L[j][k]
        D[j] = xp.where(acc > tiny, acc, tiny)
        for i in range(j + 1, n):
            acc = A[i][j]
            for k in range(j):
                acc = acc - E[i][k] * L[j][k]
            E[i][j] = acc
            L[i][j] = acc / D[j]
    y: Entries = []
    for i in range(n):
        acc = b[i]
        for k in range(i):
            acc = acc - L[i][k] * y[k]
        y.append(acc)
    # under JAX each pass's entries computed once (_pose.settle), not again in each later one
    y = _pose.settle(y, xp)
    x: Entries = [None] * n
    for i in reversed(range(n)):
        acc = y[i] / D[i]
        for k in range(i + 1, n):
            acc = acc - L[k][i] * x[k]
        x[i] = acc
    return _pose.settle(x, xp)


def damped_step(J: list[Entries], r: Entries, lam: Entry, tiny: float, xp: Any) -> Entries:
    """``d = (J^T J + lam I)^-1 J^T r`` for ``J`` (``m x n`` entries): in this form when
    ``n <= m`` (:func:`damped_step_primal`), else as ``J^T (J J^T + lam I)^-1 r``
    (:func:`damped_step_dual`: the same ``d``; a system of size ``m``, well conditioned for a
    redundant chain as ``lam -> 0``). Sums run over the shared index in ascending order,
    starting with its first product."""
    if len(J[0]) <= len(J):
        return damped_step_primal(J, r, lam, tiny, xp)
    return damped_step_dual(J, r, lam, tiny, xp)


def damped_step_primal(J: list[Entries], r: Entries, lam: Entry, tiny: float, xp: Any) -> Entries:
    """:func:`damped_step` by the ``n x n`` system ``(J^T J + lam I) d = J^T r``."""
    m, n = len(J), len(J[0])
    A = [
        [_dot([J[k][i] for k in range(m)], [J[k][j] for k in range(m)]) for j in range(i + 1)]
        for i in range(n)
    ]
    for i in range(n):
        A[i][i] = A[i][i] + lam
    g = [_dot([J[k][i] for k in range(m)], r) for i in range(n)]
    return _cholesky_solve(A, g, tiny, xp)


def damped_step_dual(J: list[Entries], r: Entries, lam: Entry, tiny: float, xp: Any) -> Entries:
    """:func:`damped_step` by the ``m x m`` system: ``d = J^T z``, ``(J J^T + lam I) z = r``."""
    m, n = len(J), len(J[0])
    B = [[_dot(J[a], J[b]) for b in range(a + 1)] for a in range(m)]
    for a in range(m):
        B[a][a] = B[a][a] + lam
    z = _cholesky_solve(B, r, tiny, xp)
    return [_dot([J[a][i] for a in range(m)], z) for i in range(n)]


def _dot(a: Sequence[Entry], b: Sequence[Entry]) -> Entry:
    total = a[0] * b[0]
    for x, y in zip(a[1:], b[1:], strict=True):
        total = total + x * y
    return total


def _capped(d: Entries, xp: Any) -> Entries:
    """``d`` scaled so that its largest entry is at most :data:`STEP_MAX` in size."""
    largest = xp.abs(d[0])
    for x in d[1:]:
        largest = xp.maximum(largest, xp.abs(x))
    factor = xp.where(largest > STEP_MAX, STEP_MAX / xp.where(largest > 0, largest, 1.0), 1.0)
    return [x * factor for x in d]


def wrapped(v: Entries, terms: ChainTerms, xp: Any) -> Entries:
    """Each value moved by whole turns into its limits where that helps
    (:func:`wrap_into_limits`), a cyclic joint's into ``(-pi, pi]``; a value already there
    keeps its bits."""
    moved = wrap_into_limits(xp.stack(v, axis=-1), terms.bounds, terms.turns, xp)
    return [moved[..., j] for j in range(len(v))]


def step(
    q: Entries,
    J: list[Entries],
    r: Entries,
    cost: Entry,
    terms: ChainTerms,
    s: Settings,
    xp: Any,
) -> Entries:
    """The next iterate from ``q`` (module step 4 and 5): inside the limits."""
    floor, ceiling = damping_floor(terms, s), damping_ceiling(terms, s)
    lam = xp.minimum(DAMPING * cost + floor, arrays.scalar(ceiling, xp, cost))
    d = _capped(damped_step(J, r, lam, floor, xp), xp)
    v = [qi + di for qi, di in zip(q, d, strict=True)]
    w = wrapped(v, terms, xp)
    lo, hi = [b[0] for b in terms.bounds], [b[1] for b in terms.bounds]
    blocked = [(wj < lo[j]) | (wj > hi[j]) for j, wj in enumerate(w)]
    anything = blocked[0]
    for b in blocked[1:]:
        anything = anything | b
    # the active set: blocked joints go to their limit; the others are solved for again
    to_limit = [_clamp(vj, lo[j], hi[j], xp) - q[j] for j, vj in enumerate(v)]
    fixed = [xp.where(b, t, 0.0) for b, t in zip(blocked, to_limit, strict=True)]
    r_free = [rk - _dot(Jk, fixed) for rk, Jk in zip(r, J, strict=True)]
    J_free = [[xp.where(b, 0.0, x) for b, x in zip(blocked, row, strict=True)] for row in J]
    d_free = damped_step(J_free, r_free, lam, floor, xp)
    d2 = _capped([xp.where(b, f, x) for b, f, x in zip(blocked, fixed, d_free, strict=True)], xp)
    v2 = [qi + di for qi, di in zip(q, d2, strict=True)]
    w = [xp.where(anything, a, b) for a, b in zip(wrapped(v2, terms, xp), w, strict=True)]
    return [_clamp(wj, lo[j], hi[j], xp) for j, wj in enumerate(w)]


def _clamp(x: Entry, lo: float, hi: float, xp: Any) -> Entry:
    """``x`` within ``[lo, hi]`` (``-inf``/``inf`` where unbounded)."""
    return xp.minimum(xp.maximum(x, arrays.scalar(lo, xp, x)), arrays.scalar(hi, xp, x))


def aimed(target: _pose.Pose, xp: Any) -> _pose.Pose:
    """The target the solve aims at: ``target`` itself, or, if its position ``p_t`` is beyond
    :data:`FAR` along any axis, the point at distance ``FAR`` on the line from the origin to
    it, ``(p_t / m) (FAR / |p_t / m|)`` for ``m = max |p_t_i|`` (no square of ``p_t``, so
    nothing overflows); the rotation is kept."""
    R_t, p_t = target
    m = xp.maximum(xp.maximum(xp.abs(p_t[0]), xp.abs(p_t[1])), xp.abs(p_t[2]))
    far = m > FAR
    unit = [x / xp.where(far, m, 1.0) for x in p_t]
    length = xp.sqrt((unit[0] * unit[0] + unit[1] * unit[1]) + unit[2] * unit[2])  # in [1, 2]
    factor = FAR / xp.where(far, length, 1.0)
    p = tuple(xp.where(far, u * factor, x) for u, x in zip(unit, p_t, strict=True))
    return R_t, p  # type: ignore[return-value]


def distance(v: Sequence[Entry], xp: Any) -> Entry:
    """``|v|`` of three entries as :func:`poekin._pose.norm`, or, where an entry exceeds
    :data:`HUGE` (its square could overflow), ``m |v / m|`` for ``m = max |v_i|``."""
    m = xp.maximum(xp.maximum(xp.abs(v[0]), xp.abs(v[1])), xp.abs(v[2]))
    scale = xp.where(m > HUGE, m, 1.0)  # 1: the same bits as _pose.norm
    return scale * _pose.norm([x / scale for x in v], xp)


def errors(pose: _pose.Pose, target: _pose.Pose, xp: Any) -> tuple[Entry, Entry]:
    """Position (m) and geodesic orientation (rad) errors, as :func:`poekin.pose_errors`:
    ``|p_t - p|`` (:func:`distance`, finite for any finite target) and
    ``atan2(|vee(M)|, (tr M - 1) / 2)`` for ``M = R_t R^T``.

    With NumPy, ``atan2`` is the C library's (:func:`math.atan2`), as in the kernel: NumPy's
    own ``arctan2`` (SIMD code on some CPUs) may differ from it in the last bit."""
    (R, p), (R_t, p_t) = pose, target
    pos = distance((p_t[0] - p[0], p_t[1] - p[1], p_t[2] - p[2]), xp)
    M = _pose.mat_mat(R_t, _pose.transpose(R))
    atan2 = _c_atan2 if xp is np else lie._atan2(xp)
    ori = atan2(_pose.norm(lie._vee(M), xp), (lie._trace(M) - 1) / 2)
    return pos, ori


def _c_atan2(y: FloatArray, x: FloatArray) -> FloatArray:
    return np.asarray(np.frompyfunc(math.atan2, 2, 1)(y, x), dtype=np.float64)


def start_entries(terms: ChainTerms, keys: Any, attempt: Any, xp: Any) -> Entries:
    """Random starts (float64, one entry per joint) for keys at their attempt numbers
    (arrays that broadcast together)."""
    return [
        base + _rng.uniform(keys, attempt, j, xp) * span
        for j, (base, span) in enumerate(zip(terms.base, terms.span, strict=True))
    ]


def starts(terms: ChainTerms, keys: Any, attempt: Any) -> FloatArray:
    """``(N, n)`` random starts for ``(N,)`` keys at their attempt numbers."""
    columns = start_entries(terms, keys, attempt, np)
    return np.stack(columns, axis=-1) if columns else np.zeros((len(keys), 0))


def first_start_entries(q0: Entries, terms: ChainTerms, xp: Any) -> Entries:
    """``q0`` (entries) brought into the limits: turned where whole turns help, else clamped
    (a cyclic joint into ``(-pi, pi]``)."""
    lo, hi = [b[0] for b in terms.bounds], [b[1] for b in terms.bounds]
    w = wrapped(q0, terms, xp)
    return [_clamp(wj, lo[j], hi[j], xp) for j, wj in enumerate(w)]


def first_start(q0: FloatArray, terms: ChainTerms) -> FloatArray:
    """``(N, n)`` ``q0`` brought into the limits (:func:`first_start_entries`)."""
    return np.stack(first_start_entries(list(np.moveaxis(q0, -1, 0)), terms, np), axis=-1)


# --- attempts in flight: one iteration, and the loop that drops finished targets -----------


class Lanes(NamedTuple):
    """Attempts in flight, one per lane (arrays of ``xp``): ``q`` and ``best_q`` ``(L, n)``,
    the rest ``(L,)``. ``best_q`` is the least-cost iterate of the lane's target over all its
    attempts so far (cost ``best_cost``); ``stall`` counts the iterations since the cost last
    fell below ``STALL_FACTOR`` times ``stall_ref``; ``it`` counts the attempt's iterations,
    ``total`` the target's, ``attempt`` is the attempt's number (0 first)."""

    q: Any
    best_q: Any
    best_cost: Any
    stall: Any
    stall_ref: Any
    it: Any
    total: Any
    attempt: Any

    @classmethod
    def start(cls, q: Any, xp: Any) -> Lanes:
        """Each lane's first attempt from ``(L, n)`` starts ``q``."""
        cost = xp.zeros_like(q[:, 0]) + math.inf
        count = xp.zeros_like(q[:, 0], dtype=_integers(xp))
        return cls(q, q, cost, count, cost, count, count, count)

    def take(self, rows: Any, xp: Any) -> Lanes:
        """The lanes of integer indices ``rows`` (NumPy and PyTorch)."""
        return Lanes(*(take_rows(x, rows, xp) for x in self))


def take_rows(x: Any, rows: Any, xp: Any) -> Any:
    """``x[rows]`` for integer indices ``rows`` (PyTorch: ``index_select``; its advanced
    indexing of a 2-d tensor takes milliseconds with two threads)."""
    return x[rows] if xp is np else x.index_select(0, rows)


def _put_rows(out: Any, rows: Any, values: Any, xp: Any) -> None:
    """``out[rows] = values``, in place (PyTorch: ``index_copy_``)."""
    if xp is np:
        out[rows] = values
    else:
        out.index_copy_(0, rows, values)


def _where_true(mask: Any, xp: Any) -> Any:
    """The indices of the True entries of ``(L,)`` ``mask``."""
    return np.flatnonzero(mask) if xp is np else xp.nonzero(mask)[0]


def _integers(xp: Any) -> Any:
    integers = xp.__array_namespace_info__().default_dtypes()["integral"]
    return integers


def advance(
    lanes: Lanes,
    goal: _pose.Pose,
    evaluate: Any,
    draw: Any,
    terms: ChainTerms,
    s: Settings,
    xp: Any,
    budget: int | None = None,
) -> tuple[Lanes, Any, Any, Any]:
    """One iteration of every lane's attempt (the module's steps 1 to 5 and the attempts'
    rules), for targets ``goal`` (entries ``(L,)``).

    ``evaluate(q)``: the pose and the world Jacobian's columns of ``q`` (entries);
    ``draw(attempt)``: ``(L, n)`` random starts of the lanes' targets at attempt numbers
    ``(L,)``. A lane's attempt ends when it converges, stalls or reaches ``max_iterations``;
    its target is finished when the attempt converged, was the last of ``max_attempts``, or
    (``budget``) the target has run that many iterations; an attempt that ends otherwise
    restarts the lane at the target's next random start.

    Returns:
        The next lanes, and ``(L,)``: finished, converged (the evaluated iterate met the
        tolerances), and ``(L, n)`` the answer (that iterate if converged, else
        ``best_q``), meaningful where finished.
    """
    q = lanes.q
    q_entries = [q[:, j] for j in range(q.shape[-1])]
    pose, columns = evaluate(q_entries)
    r, cost, ep2, eo2, quat = residual(pose, goal, s, xp)
    conv = ep2 <= s.pos_tol2
    if not s.position_only:
        conv = conv & (eo2 <= s.ori_tol2)
    better = cost < lanes.best_cost
    best_cost = xp.where(better, cost, lanes.best_cost)
    best_q = xp.where(better[:, None], q, lanes.best_q)
    improved = cost < lanes.stall_ref * STALL_FACTOR
    stall_ref = xp.where(improved, cost, lanes.stall_ref)
    stall = xp.where(improved, 0, lanes.stall + 1)
    it, total = lanes.it + 1, lanes.total + 1
    end = conv | (stall >= STALL_ITERATIONS) | (it >= s.max_iterations)
    finished = end & (conv | (lanes.attempt + 1 >= s.max_attempts))
    if budget is not None:
        finished = finished | (total >= budget)
    restart = end & ~finished
    J = jacobian_rows(columns, quat, s)
    m, n = len(J), len(q_entries)
    # under JAX each computed once, not again in every consumer (_pose.settle)
    flat = _pose.settle([*r, cost, *(x for row in J for x in row)], xp)
    r, cost, J = flat[:m], flat[m], [flat[m + 1 + i * n : m + 1 + (i + 1) * n] for i in range(m)]
    q_next = xp.stack(_pose.settle(step(q_entries, J, r, cost, terms, s, xp), xp), axis=-1)
    q_next = xp.where(restart[:, None], draw(lanes.attempt + 1), q_next)
    answer = xp.where(conv[:, None], q, best_q)
    lanes = Lanes(
        q_next,
        best_q,
        best_cost,
        xp.where(restart, 0, stall),
        xp.where(restart, math.inf, stall_ref),
        xp.where(restart, 0, it),
        total,
        lanes.attempt + xp.astype(restart, lanes.attempt.dtype),
    )
    return lanes, finished, conv, answer


def run_lanes(
    first: Any,
    inputs: Sequence[Any],
    prepare: Any,
    terms: ChainTerms,
    s: Settings,
    xp: Any,
    budget: int | None = None,
) -> tuple[Any, Any, Any, Any]:
    """Every target's attempts, one lane per target, in lock-step: a target leaves the lanes
    when it is finished (NumPy and PyTorch: boolean indexing).

    Args:
        first: ``(N, n)`` each target's first start.
        inputs: arrays of ``N`` rows, the targets' data.
        prepare: ``prepare(rows)``, ``rows`` those of ``inputs`` of the lanes: the goals
            (pose entries), ``evaluate`` and ``draw`` for :func:`advance`.
        budget: iterations per target at most (None: no bound but the attempts').

    Returns:
        ``(N, n)`` the answers, ``(N,)`` converged, iterations and attempts.
    """
    N = first.shape[0]
    lanes = Lanes.start(first, xp)
    lane = xp.arange(N, **({} if xp is np else {"device": first.device}))
    out_q = xp.zeros_like(first)
    out_conv = xp.zeros_like(lanes.it, dtype=xp.bool)
    out_total = xp.zeros_like(lanes.it)
    out_attempts = xp.zeros_like(lanes.it)
    rows = list(inputs)
    while lane.shape[0]:
        goal, evaluate, draw = prepare(rows)
        lanes, finished, conv, answer = advance(lanes, goal, evaluate, draw, terms, s, xp, budget)
        # bookkeeping: the finished targets' results, then only the others go on
        done = _where_true(finished, xp)
        if done.shape[0]:
            to = take_rows(lane, done, xp)
            _put_rows(out_q, to, take_rows(answer, done, xp), xp)
            _put_rows(out_conv, to, take_rows(conv, done, xp), xp)
            _put_rows(out_total, to, take_rows(lanes.total, done, xp), xp)
            _put_rows(out_attempts, to, take_rows(lanes.attempt, done, xp) + 1, xp)
            keep = _where_true(~finished, xp)
            lane, lanes = take_rows(lane, keep, xp), lanes.take(keep, xp)
            rows = [take_rows(x, keep, xp) for x in rows]
    return out_q, out_conv, out_total, out_attempts


# --- the NumPy reference --------------------------------------------------------------------


def solve_reference(
    chain: Chain, T: FloatArray, q0: FloatArray | None, seed: int, s: Settings
) -> tuple[FloatArray, BoolArray, FloatArray, FloatArray, IntArray, IntArray]:
    """The reference solve of ``(N, 4, 4)`` targets (validated), from ``(N, n)`` ``q0`` or
    random starts: ``q, success, pos_err, ori_err, iterations, attempts``, each ``(N, ...)``.

    Every target runs in lock-step with the others (:func:`run_lanes`); a target leaves the
    batch when it is done.
    """
    terms = chain_terms(chain)
    keys = _rng.target_keys(seed, T, q0)
    attempt = np.zeros(len(T), dtype=np.int64)
    first = first_start(q0, terms) if q0 is not None else starts(terms, keys, attempt)

    def prepare(rows: list[Any]) -> tuple[_pose.Pose, Any, Any]:
        T_rows, keys_rows = rows
        return (
            aimed(chain_pose_entries(T_rows), np),
            lambda q: evaluate(chain, q, np),
            lambda attempt: starts(terms, keys_rows, attempt),
        )

    out_q, out_conv, out_total, out_attempts = run_lanes(first, [T, keys], prepare, terms, s, np)
    target = chain_pose_entries(T)
    pose, _ = evaluate(chain, list(out_q.T), np)
    pos_err, ori_err = errors(pose, target, np)
    pos_err = np.asarray(pos_err, dtype=np.float64)
    ori_err = np.asarray(ori_err, dtype=np.float64)
    success = out_conv & (pos_err <= s.pos_tol) & within_limits(out_q, terms.limits)
    if not s.position_only:
        success &= ori_err <= s.ori_tol
    return out_q, success, pos_err, ori_err, out_total, out_attempts


def chain_pose_entries(T: Any) -> _pose.Pose:
    """The pose entries of ``(N, 4, 4)`` targets."""
    R = tuple(tuple(T[:, i, j] for j in range(3)) for i in range(3))
    return R, (T[:, 0, 3], T[:, 1, 3], T[:, 2, 3])  # type: ignore[return-value]


# --- the entry point ------------------------------------------------------------------------


def check_targets(T: ArrayLike) -> FloatArray:
    """``T`` as float64 ``(..., 4, 4)`` rigid transforms, or :class:`InputError`."""
    if _fast.rigid_targets(T):  # the kernel's one pass: T as it is (a few poses a tick)
        plain: FloatArray = T  # type: ignore[assignment]
        return plain
    arr = real_array(T, "targets")
    if arr.ndim < 2 or arr.shape[-2:] != (4, 4):
        raise InputError(f"targets must have shape (..., 4, 4), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError("targets contain NaN or inf; every entry must be finite")
    R = arr[..., :3, :3]
    gram = np.einsum("...ki,...kj->...ij", R, R)
    bad_rotation = np.any(np.abs(gram - np.eye(3)) > 1e-6, axis=(-2, -1))
    bad_rotation |= np.linalg.det(R) <= 0
    bad_row = np.any(np.abs(arr[..., 3, :] - [0.0, 0.0, 0.0, 1.0]) > 1e-12, axis=-1)
    for bad, what in (
        (bad_rotation, "its rotation block is not orthonormal with det +1 (to 1e-6)"),
        (bad_row, "its last row is not [0, 0, 0, 1]"),
    ):
        if np.any(bad):
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            at = f" at index {where}" if where else ""
            raise InputError(f"target{at} is not a rigid transform: {what}")
    return _plain(arr)


def _plain(arr: FloatArray) -> FloatArray:
    """``arr`` C-contiguous and aligned, as the kernel reads it (a copy only if it is not:
    an array in a buffer at an odd offset, as Dask and ``np.frombuffer`` hand out, is not
    aligned)."""
    return np.require(arr, requirements=("C", "A"))


def solve(
    chain: Chain,
    T: ArrayLike,
    q0: ArrayLike | None = None,
    *,
    seed: int = 0,
    options: Settings,
) -> IKResult:
    """:meth:`poekin.Chain.ik`: validate, then run the compiled kernel (the NumPy reference
    without one) on the targets flattened to one batch."""
    seed = check_seed(seed)
    kernel = _ik_kernel(chain)
    if kernel is not None:
        done = kernel.solve(T, q0, seed, _kernel_options(chain, options), False)
        if done is not None:
            return IKResult(*done)
    arr, start = _inputs(chain, T, q0)
    if kernel is not None:
        done = kernel.solve(arr, start, seed, _kernel_options(chain, options), True)
        assert done is not None, "validated arguments were refused by the kernel"
        return IKResult(*done)
    batch = arr.shape[:-2]
    _fast._note_slow_path(batch)  # once a process, for a big batch without the kernel
    flat_q0 = None if start is None else start.reshape(-1, chain.n_joints)
    out = solve_reference(chain, arr.reshape(-1, 4, 4), flat_q0, seed, options)
    q, success, pos_err, ori_err, iterations, attempts = out
    return IKResult(
        q.reshape(*batch, chain.n_joints),
        success.reshape(batch),
        pos_err.reshape(batch),
        ori_err.reshape(batch),
        iterations.reshape(batch),
        attempts.reshape(batch),
    )


def _inputs(chain: Chain, T: ArrayLike, q0: ArrayLike | None) -> tuple[FloatArray, Any]:
    """Targets and ``q0`` validated, broadcast to one batch shape, C-contiguous and aligned."""
    if chain.n_joints == 0:
        raise InputError("the chain has no joints: there is nothing to solve for")
    arr = check_targets(T)
    if q0 is None:
        return arr, None
    start = as_joint_values(q0, chain.n_joints, what="q0 values")
    angles = [kind == "revolute" for kind in chain.joint_types]
    said = outside_limits(start, chain_terms(chain).limits, chain.joint_names, angles)
    if said:
        warnings.warn(
            f"q0 is {said}: the first attempt starts from it brought into the limits (whole "
            "turns, else clamped); q0 is in radians (and metres)",
            JointLimitsWarning,
            stacklevel=_caller_level(),
        )
    return broadcast_together(arr, start, "q0")


def _caller_level() -> int:
    """The ``stacklevel`` of a warning issued where this is called that points at the first
    line outside poekin: the user's call of ``chain.ik`` or ``tree.ik``."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame: types.FrameType | None = sys._getframe(1)
    level = 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def broadcast_together(
    targets: FloatArray, values: FloatArray, name: str
) -> tuple[FloatArray, FloatArray]:
    """``(..., 4, 4)`` targets and ``(..., n)`` values (``name`` in the message) broadcast to
    one batch shape, C-contiguous and aligned; :class:`InputError` if their batch axes do not
    broadcast."""
    try:
        batch = np.broadcast_shapes(targets.shape[:-2], values.shape[:-1])
    except ValueError:
        raise InputError(
            f"{name} of shape {values.shape} does not broadcast against targets of shape "
            f"{targets.shape}: their batch axes must broadcast"
        ) from None
    return (
        _plain(np.broadcast_to(targets, (*batch, 4, 4))),
        _plain(np.broadcast_to(values, (*batch, values.shape[-1]))),
    )


def _ik_kernel(chain: Chain) -> Any:
    """The chain's compiled solver (built at first use), or None without the kernel."""
    cache = chain._ik_cache
    if "kernel" not in cache:
        terms = chain_terms(chain)
        cache["kernel"] = _fast.ik_kernel(
            chain._jacobian_world_kernel,
            terms.limits,
            terms.revolute,
            terms.cyclic,
            terms.start_base,
            terms.start_span,
        )
    return cache["kernel"]


def _kernel_options(chain: Chain, s: Settings) -> tuple[float, ...]:
    """The settings and the algorithm's constants as the kernel reads them, every derived
    number computed here once (kept with the chain, per settings)."""
    cache = chain._ik_cache
    key = ("options", s)
    if key not in cache:
        cache[key] = _options_of(chain_terms(chain).scale, s)
    options: tuple[float, ...] = cache[key]
    return options


def _options_of(scale: float, s: Settings) -> tuple[float, ...]:
    """The kernel's options for a chain of size ``scale`` (:class:`ChainTerms`) and ``s``."""
    return (
        s.pos_tol,
        s.ori_tol,
        s.pos_tol2,
        s.ori_tol2,
        s.orientation_weight,
        DAMPING,
        FLOOR * _damping_length2(scale, s),
        _damping_length2(scale, s),
        STEP_MAX,
        STALL_FACTOR,
        float(STALL_ITERATIONS),
        float(s.position_only),
        float(s.max_iterations),
        float(s.max_attempts),
    )


def solve_quick(
    chain: Chain,
    T: FloatArray,
    q0: FloatArray | None,
    seed: int,
    pos_tol: float,
    ori_tol: float,
    position_only: bool,
    orientation_weight: float,
    max_iterations: int,
    max_attempts: int,
) -> IKResult | None:
    """:meth:`poekin.Chain.ik` for NumPy arrays ``T`` and ``q0`` without ``params`` or a
    budget, as :func:`solve` runs it, with less around the kernel: the options validated and
    turned into the kernel's once per chain size and values (:func:`_quick_options`), the
    kernel taking the arrays as they are. None where that does not serve (no kernel, an
    unhashable option, a seed that is not a plain int in range, arguments the kernel leaves
    to the validation): the caller then runs the usual path, which says what is wrong."""
    quick = chain._ik_cache.get("quick")
    if quick is None:
        kernel = _ik_kernel(chain)
        if kernel is None:
            return None
        memo: list[tuple[Any, ...] | None] = [None]
        quick = chain._ik_cache["quick"] = (kernel, chain_terms(chain).scale, memo)
        # Chain.ik(T[, q0])'s own call in C from now on (fast_method), the defaults' options
        options = _quick_options(quick[1], *chain._IK_DEFAULTS)
        object.__setattr__(chain, "_ik_quick", (kernel.quick, options, IKResult))
    kernel, scale, memo = quick
    seen = memo[0]  # the options of the chain's last call: the very same objects, validated
    if (
        seen is not None
        and seen[0] is pos_tol
        and seen[1] is ori_tol
        and seen[2] is position_only
        and seen[3] is orientation_weight
        and seen[4] is max_iterations
        and seen[5] is max_attempts
    ):
        options = seen[6]
    else:
        try:
            options = _quick_options(
                scale,
                pos_tol,
                ori_tol,
                position_only,
                orientation_weight,
                max_iterations,
                max_attempts,
            )
        except TypeError:  # an unhashable option: the usual path says what is wrong with it
            return None
        args = (pos_tol, ori_tol, position_only, orientation_weight, max_iterations, max_attempts)
        memo[0] = (*args, options)
    if type(seed) is not int or not 0 <= seed < 2**64:
        return None
    found: IKResult | None = kernel.solve(T, q0, seed, options, False, IKResult)  # or None
    return found


def solve_valid(chain: Chain, T: FloatArray, q0: FloatArray, options: Settings) -> IKResult:
    """:func:`solve` of targets and starts the caller knows valid: ``T`` ``(..., 4, 4)``
    finite rigid transforms and ``q0`` finite and within the limits, both C-contiguous
    float64 (:func:`poekin.ik.analytic.ik_all`'s refinement), which the kernel then does not
    check again (seed 0)."""
    kernel = _ik_kernel(chain)
    if kernel is not None:
        found: IKResult | None = kernel.solve(
            T, q0, 0, _kernel_options(chain, options), True, IKResult
        )
        if found is not None:
            return found
    return solve(chain, T, q0, options=options)


@functools.lru_cache(maxsize=64, typed=True)
def _quick_options(
    scale: float,
    pos_tol: float,
    ori_tol: float,
    position_only: bool,
    orientation_weight: float,
    max_iterations: int,
    max_attempts: int,
) -> tuple[float, ...]:
    """The kernel's options (:func:`_kernel_options`) of a chain of size ``scale`` for these
    options of :func:`settings` (``max_total_iterations`` None), validated."""
    s = _settings(
        pos_tol, ori_tol, position_only, orientation_weight, max_iterations, max_attempts, None
    )
    return _options_of(scale, s)
