"""Collision-free inverse kinematics: ``chain.ik(T, avoid=True)`` and ``tree.ik(T, frame, qpos,
avoid=True)``.

Every checked pair of the robot's collision geometry, with itself and with the obstacles
(:mod:`poekin.collision`), is kept at least ``margin`` apart, as a constraint inside the
solve. Each iteration of :mod:`poekin.ik.numerical`'s damped least squares becomes the small
quadratic programme

    minimize ``|J dq - r|^2 + lam |dq|^2``  subject to
    ``lo <= dq <= hi`` and ``d_k + J_k dq >= margin`` for each pair ``k`` closer than
    ``margin + ACTIVATION``,

the first the joint limits and the step's cap (no joint moves more than 1.5 rad or m), the
second the pairs' distances linearised at the iterate with the witness points' Jacobians
(:func:`poekin.collision.avoid.pair_rows`). A pair already closer than ``margin`` gets an
elastic slack, weighed :data:`ELASTIC` times the task, so that the step that pushes it out
most is taken where the limits do not let it out at once. The programme is solved exactly by
a primal active set (Nocedal and Wright's algorithm 16.3) from ``dq = 0``, which the limits
and the rows with slack allow.

An attempt converges when the pose is within ``pos_tol`` and ``ori_tol`` **and** every pair,
measured at the iterate (:func:`poekin.collision.query.hits`), is at least ``margin`` apart;
it stalls, restarts and counts as :mod:`poekin.ik.numerical`'s do, from the same starts
(``q0``, then the seeded random ones). ``success`` is True only where such an iterate was
found: an answer that collides is never a success.

The targets are first solved without the pairs (the compiled kernel); an answer that reaches
its target and keeps every pair ``margin`` apart is one of the constrained problem's
(no row is active at it), and stands. For a target whose answer collides, a chain with a
closed form (:meth:`poekin.Chain.ik_all`: six joints) and a whole pose has only its branches
for answers: the valid one that keeps the margin, nearest ``q0`` (without ``q0``, the first
in the closed form's own order), stands, found in one batched call and one collision check;
where none keeps it and every branch is a regular point of the arm (its answers isolated, not
the continuum of a straight wrist), the target has no clear answer and fails at once. Without
``q0`` (the starts are random anyway) the targets left are solved plainly again from
:data:`RESTARTS` other seeds' starts, in batches, and the first clear answer stands. Only the
targets left then are solved again with the rows; a target the plain solve cannot reach is not
(the rows only shrink the set of answers), and fails as it did. Without success ``q`` is the
best iterate that kept the margin, or the plain solve's answer if none did.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin._poe import chain_terms
from poekin.collision.avoid import ACTIVATION, damper_rows, pair_rows
from poekin.collision.query import Checked, first_clear, frames_of, hits, prepare
from poekin.errors import ModelError
from poekin.ik import _rng
from poekin.ik.numerical import (
    DAMPING,
    STALL_FACTOR,
    STALL_ITERATIONS,
    STEP_MAX,
    IKResult,
    Settings,
    chain_pose_entries,
    damping_ceiling,
    damping_floor,
    errors,
    evaluate,
    first_start,
    jacobian_rows,
    residual,
    starts,
    wrapped,
)
from poekin.ik.numerical import solve as plain_solve

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.tree import Tree

__all__ = ["BACKTRACKS", "ELASTIC", "Scene", "chain_scene", "inequality_qp", "solve", "step"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

ELASTIC = 1e8  # the weight of a slack (of a pair closer than margin) against the task's cost
BACKTRACKS = 8  # halvings of a step that would leave a clear iterate colliding
RESTARTS = 16  # without q0: plain solves from other seeds' starts, before the rows
FEASIBLE_TOL = 1e-9  # relative: a pair at margin (1 - this) or more keeps the margin
_QP_TOL = 1e-14


@dataclasses.dataclass(frozen=True)
class Scene:
    """What the pairs are measured on: the tree in the solve's world, where the solved joints
    sit in its ``qpos`` (``indices``) and ``qvel`` (``dofs``), the obstacles, the margin and
    the pairs left out."""

    tree: Tree
    indices: tuple[int, ...]
    dofs: tuple[int, ...]
    obstacles: tuple[Any, ...]
    margin: float
    ignore: tuple[Any, ...]

    def qpos(self, q: FloatArray, base: FloatArray) -> FloatArray:
        """``(N, nq)`` ``base`` (``(nq,)``, or one row a configuration) with the solved
        joints at ``q (N, n)``."""
        if self._whole:  # the solved joints are the whole of qpos, in order
            return np.ascontiguousarray(q, dtype=np.float64)
        out = np.empty((len(q), base.shape[-1]))
        out[:] = base
        out[:, self._columns] = q
        return out

    @functools.cached_property
    def _columns(self) -> NDArray[np.intp]:
        return np.array(self.indices, dtype=np.intp)

    @functools.cached_property
    def _whole(self) -> bool:
        return self.indices == tuple(range(self.tree.nq))

    def rows(self, q: FloatArray, base: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(N, P)`` distances (``inf`` beyond activation) and ``(N, P, n)`` their Jacobians
        with respect to the solved joints."""
        found = pair_rows(
            self.tree,
            self.qpos(q, base),
            self.obstacles,
            activation=self.margin + ACTIVATION,
            ignore=self.ignore,
        )
        return found.distance, found.jacobian[..., list(self.dofs)]

    @functools.cached_property
    def checked(self) -> Checked:
        """The pairs, ready to check (built once)."""
        return prepare(self.tree, self.obstacles, self.ignore)

    def clear(self, q: FloatArray, base: FloatArray) -> BoolArray:
        """``(N,)`` whether every pair is at least ``margin`` apart (to :data:`FEASIBLE_TOL`)."""
        return np.asarray(~hits(self.checked, self._frames(q, base), self._cutoff))

    def first_clear(self, q: FloatArray, base: FloatArray, groups: Any) -> NDArray[np.int64]:
        """``(N,)`` for each group of configurations ``q[groups[i]:groups[i + 1]]`` (and
        ``base``), the index of its first that :meth:`clear` passes, -1 where none does
        (:func:`poekin.collision.query.first_clear`: the configurations after it are not
        checked)."""
        return first_clear(self.checked, self._frames(q, base), self._cutoff, groups)

    def _frames(self, q: FloatArray, base: FloatArray) -> Any:
        return frames_of(self.tree, self.qpos(q, base))

    @property
    def _cutoff(self) -> float:
        """A pair nearer than this misses the margin (:data:`FEASIBLE_TOL`)."""
        return self.margin * (1 - FEASIBLE_TOL)


def chain_scene(
    chain: Chain, obstacles: tuple[Any, ...], margin: float, ignore: Iterable[Any]
) -> Scene:
    """The :class:`Scene` of a chain cut from a tree loaded from a model file, the tree
    placed in the chain's world (:attr:`poekin.Chain.base`).

    Raises:
        ModelError: the chain knows no model file (typed by hand, from other parameters, or
            from a base body of a floating robot: solve the tree, ``tree.ik(T, frame, qpos,
            avoid=True)``).
    """
    tree = chain._tree
    if tree is None:
        raise ModelError(
            "avoid=True needs the robot's collision geometry, and this chain knows no model "
            "file (typed by hand, or with other parameters): load it with poekin.load(...)"
        )
    if not np.array_equal(chain.base, tree.base):
        key = ("placed", chain.base.tobytes())
        if key not in chain._ik_cache:
            chain._ik_cache[key] = tree.with_base(chain.base @ lie.inverse(tree.base))
        tree = chain._ik_cache[key]
    joints = [tree.joint_names.index(name) for name in chain.joint_names]
    return Scene(
        tree=tree,
        indices=tuple(int(tree.qpos_adr[k]) for k in joints),
        dofs=tuple(int(tree._dof_adr[k]) for k in joints),
        obstacles=tuple(obstacles),
        margin=margin,
        ignore=tuple(ignore),
    )


def inequality_qp(
    H: FloatArray, g: FloatArray, lo: FloatArray, hi: FloatArray, G: FloatArray, h: FloatArray
) -> FloatArray:
    """``x`` minimising ``x^T H x / 2 - g^T x`` subject to ``lo <= x <= hi`` and ``G x >= h``.

    ``H (n, n)`` symmetric positive definite, ``lo <= 0 <= hi`` (``-inf``/``inf`` where
    none), ``G (m, n)``. A row that ``x = 0`` breaks (``h_k > 0``) gets a slack ``s_k``
    (``G_k x + s_k >= h_k``) weighed ``ELASTIC max(1, max H_ii) s_k^2 / 2``: the row is met
    where the box allows it, else broken as little as that weight says. Solved by a primal
    active set from ``x = 0`` (every iterate feasible; Nocedal and Wright, algorithm 16.3).
    """
    n = len(g)
    broken = np.flatnonzero(h > 0)
    k = len(broken)
    size = n + k
    Hz = np.zeros((size, size))
    Hz[:n, :n] = H
    # the slacks scaled so that their block of the Hessian is H's size, not ELASTIC times it:
    # s_k = c t_k with c^2 = 1 / ELASTIC (a Hessian block of H's scale keeps the KKT systems
    # well conditioned)
    weight = max(1.0, float(np.max(np.diag(H))))
    c_slack = 1.0 / np.sqrt(ELASTIC)
    Hz[n:, n:] = np.eye(k) * weight
    c = np.concatenate([-g, np.zeros(k)])
    lower = np.flatnonzero(np.isfinite(lo))
    upper = np.flatnonzero(np.isfinite(hi))
    A = np.zeros((len(lower) + len(upper) + len(h), size))
    A[np.arange(len(lower)), lower] = 1.0
    A[len(lower) + np.arange(len(upper)), upper] = -1.0
    A[len(lower) + len(upper) :, :n] = G
    A[len(lower) + len(upper) + broken, n + np.arange(k)] = c_slack
    b = np.concatenate([lo[lower], -hi[upper], h])
    z = np.concatenate([np.zeros(n), np.maximum(h[broken], 0.0) / c_slack])
    working: list[int] = []
    # after a full step the iterate is the working set's minimiser, and the next step is zero
    # but for rounding (some 1e-14 of it on a vertex of an ill-conditioned H): taken as zero,
    # not tested against a tolerance that rounding can miss (which stepped in place for ever)
    minimised = False
    for _ in range(4 * len(b) + 8):
        grad = Hz @ z + c
        Aw = A[working]
        m = len(working)
        K = np.zeros((size + m, size + m))
        K[:size, :size], K[:size, size:], K[size:, :size] = Hz, -Aw.T, Aw
        rhs = np.concatenate([-grad, np.zeros(m)])
        try:
            sol = np.linalg.solve(K, rhs)
        except np.linalg.LinAlgError:  # working rows that depend on each other
            sol = np.linalg.lstsq(K, rhs, rcond=None)[0]
        p, lam = sol[:size], sol[size:]
        if minimised or np.max(np.abs(p), initial=0.0) <= _QP_TOL * (1.0 + np.max(np.abs(z))):
            if m == 0 or lam.min() >= -_QP_TOL * (1.0 + np.max(np.abs(grad))):
                break
            working.pop(int(np.argmin(lam)))
            minimised = False
            continue
        Ap = A @ p
        room = A @ z - b
        closing = Ap < -_QP_TOL * (1.0 + np.abs(room))
        closing[working] = False
        alpha, stop = 1.0, -1
        for i in np.flatnonzero(closing):
            a = max(room[i], 0.0) / -Ap[i]
            if a < alpha:
                alpha, stop = a, int(i)
        z = z + alpha * p
        minimised = stop < 0
        if stop >= 0:
            working.append(stop)
    return z[:n]


def _step(
    q: FloatArray,
    J: FloatArray,
    r: FloatArray,
    cost: float,
    d: FloatArray,
    Gd: FloatArray,
    chain: Chain,
    s: Settings,
    margin: float,
) -> FloatArray:
    """The step ``dq`` from ``q (n,)``: the programme of the module's docstring."""
    terms = chain_terms(chain)
    floor = damping_floor(terms, s)
    lam = min(DAMPING * cost + floor, damping_ceiling(terms, s))
    H = J.T @ J + lam * np.eye(len(q))
    lo = np.minimum(np.maximum(terms.limits[:, 0] - q, -STEP_MAX), 0.0)
    hi = np.maximum(np.minimum(terms.limits[:, 1] - q, STEP_MAX), 0.0)
    near = np.isfinite(d)
    return inequality_qp(H, J.T @ r, lo, hi, Gd[near], margin - d[near])


def _moved(q: FloatArray, dq: FloatArray, chain: Chain) -> FloatArray:
    """``q + dq`` turned by whole turns into the limits where that helps, and clamped."""
    terms = chain_terms(chain)
    w = np.array(wrapped([np.atleast_1d(x) for x in q + dq], terms, np), dtype=np.float64)[:, 0]
    return np.clip(w, terms.limits[:, 0], terms.limits[:, 1])


def _evaluate(
    chain: Chain, q: FloatArray, goal: Any, s: Settings
) -> tuple[FloatArray, FloatArray, float, bool]:
    """``J (m, n)``, ``r (m,)``, the cost and whether the pose meets the tolerances, at ``q``."""
    pose, columns = evaluate(chain, [np.atleast_1d(x) for x in q], np)
    r, cost, ep2, eo2, quat = residual(pose, goal, s, np)
    J = np.array([[float(x[0]) for x in row] for row in jacobian_rows(columns, quat, s)])
    met = bool(ep2[0] <= s.pos_tol2) and (s.position_only or bool(eo2[0] <= s.ori_tol2))
    return J, np.array([float(x[0]) for x in r]), float(cost[0]), met


def _solve_one(
    chain: Chain,
    T: FloatArray,
    q0: FloatArray | None,
    key: Any,
    base: FloatArray,
    s: Settings,
    scene: Scene,
) -> tuple[FloatArray | None, bool, int, int]:
    """One target's constrained attempts: the answer (None if no iterate kept the margin),
    whether it converged, the iterations and the attempts run."""
    terms = chain_terms(chain)
    R = tuple(tuple(np.atleast_1d(T[i, j]) for j in range(3)) for i in range(3))
    goal = (R, tuple(np.atleast_1d(T[i, 3]) for i in range(3)))
    best: FloatArray | None = None
    best_cost = np.inf
    total = 0
    margin = scene.margin * (1 - FEASIBLE_TOL)
    for attempt in range(s.max_attempts):
        if attempt == 0 and q0 is not None:
            q = first_start(q0[None], terms)[0]
        else:
            q = starts(terms, np.atleast_1d(key), np.atleast_1d(attempt))[0]
            if not scene.clear(q[None], base[None])[0]:
                continue  # a random start that collides: the next one
        stall, stall_ref = 0, np.inf
        d, Gd = scene.rows(q[None], base[None])
        for _ in range(s.max_iterations):
            total += 1
            J, r, cost, met = _evaluate(chain, q, goal, s)
            clear = bool(np.all(d[0] >= margin))
            if met and clear:
                return q, True, total, attempt + 1
            if clear and cost < best_cost:
                best, best_cost = q, cost
            if cost < stall_ref * STALL_FACTOR:
                stall, stall_ref = 0, cost
            else:
                stall += 1
                if stall >= STALL_ITERATIONS:
                    break
            dq = _step(q, J, r, cost, d[0], Gd[0], chain, s, scene.margin)
            for _ in range(BACKTRACKS):  # a clear iterate's step that collides is halved
                q_next = _moved(q, dq, chain)
                d_next, G_next = scene.rows(q_next[None], base[None])
                if not clear or np.all(d_next[0] >= margin):
                    break
                dq = dq / 2
            else:
                break  # no step from here keeps the margin: a stall
            q, d, Gd = q_next, d_next, G_next
    return best, False, total, s.max_attempts


def _rows(base: FloatArray, index: Any) -> FloatArray:
    """The rows ``index`` of ``base (N, nq)``, or ``base (nq,)`` itself: shared by all."""
    return base if base.ndim == 1 else base[index]


def _restart_seed(seed: int, r: int) -> int:
    """The seed of restart ``r`` (0, 1, ...) of a solve seeded ``seed``: its own stream."""
    return int(_rng.mix(np.uint64((seed + r + 1) % 2**64)))


def _clear_branch(
    chain: Chain,
    T: FloatArray,
    near: FloatArray | None,
    colliding: FloatArray,
    base: FloatArray,
    s: Settings,
    scene: Scene,
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray]:
    """``(N, n)`` for each target ``T (N, 4, 4)``, the closed form's branch (:meth:`Chain.ik_all`)
    nearest ``near (N, n)`` (None: the first in the closed form's order) that is valid and
    keeps the margin, if it meets the tolerances; NaN where it does not, where none does, or
    where the chain has no closed form. Then ``(N,)`` its position and orientation errors, and
    ``(N,)`` where no answer keeps the margin (:func:`_no_clear_answer`). The branch of
    ``colliding (N, n)`` (the plain answer, within 1e-6 rad) is known to collide and not
    checked again. For six joints and a whole pose the branches are every answer there is, so a
    clear one is the constrained problem's answer, and the nearest is the one a solve from
    ``near`` would look for."""
    from poekin.errors import AnalyticIKError

    out = np.full(colliding.shape, np.nan)
    pos, ori = np.full(len(colliding), np.nan), np.full(len(colliding), np.nan)
    none = np.zeros(len(colliding), dtype=bool)
    try:
        branches = chain.ik_all(T, near=near)
    except AnalyticIKError:
        return out, pos, ori, none
    limits = chain_terms(chain).limits
    # each target's valid branches within the limits, in order, but the plain answer's
    rows, cols = np.nonzero(branches.valid)
    candidates = branches.q[rows, cols]
    turns = np.remainder(candidates - colliding[rows] + np.pi, 2 * np.pi) - np.pi
    keep = np.all((candidates >= limits[:, 0]) & (candidates <= limits[:, 1]), axis=-1)
    keep &= np.any(np.abs(turns) > 1e-6, axis=-1)
    rows, candidates = rows[keep], candidates[keep]
    groups = np.searchsorted(rows, np.arange(len(colliding) + 1))
    # up to the first of each target's that keeps the margin
    first = scene.first_clear(candidates, _rows(base, rows), groups)
    has = np.flatnonzero(first >= 0)
    chosen = candidates[first[has]]
    # measured as the numerical solve measures them, by that solve from the branch itself: it
    # meets the tolerances where the solve stops there (a branch it moves is left out)
    measured = plain_solve(chain, T[has], chosen, seed=0, options=s)
    met = measured.success & np.all(measured.q == chosen, axis=-1)
    out[has[met]], pos[has[met]], ori[has[met]] = (
        chosen[met],
        measured.pos_err[met],
        measured.ori_err[met],
    )
    if not branches.geometry.nearest:
        none = _no_clear_answer(chain, branches.q, branches.valid, first < 0)
    return out, pos, ori, none


# A branch is a regular point of the arm where its space Jacobian's smallest singular value is
# above this (rad or m per rad): there the arm's answers are isolated, and the closed form's
# branches are all of them
REGULAR = 1e-6


def _no_clear_answer(
    chain: Chain, q: FloatArray, valid: BoolArray, none_clear: BoolArray
) -> BoolArray:
    """``(N,)`` where a target of the exact closed form, whose valid branches ``q (N, k, n)``
    are none of them clear (``none_clear``), has no answer that keeps the margin: each branch
    is a regular point (:data:`REGULAR`), so the branches and their whole turns (the same
    poses of every link) are every answer. At a singular one (a straight wrist, the wrist's
    centre on the first axis) the answers are a continuum, and another member of it may be
    clear: the constrained solve looks."""
    rows, cols = np.nonzero(valid & none_clear[:, None])
    if not len(rows):
        return np.zeros(len(q), dtype=bool)
    smallest = np.linalg.svd(chain.jacobian_space(q[rows, cols]), compute_uv=False)[:, -1]
    singular = np.zeros(len(q), dtype=bool)
    singular[rows[smallest <= REGULAR]] = True
    return none_clear & ~singular


def _pose_errors(chain: Chain, q: FloatArray, T: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(N,)`` position (m) and orientation (rad) errors of ``q (N, n)`` for ``T (N, 4, 4)``,
    as the numerical solve measures them (on the chain's compiled FK)."""
    pose = chain_pose_entries(np.asarray(chain.fk(q), dtype=np.float64))
    pos_err, ori_err = errors(pose, chain_pose_entries(T), np)
    return np.asarray(pos_err, dtype=np.float64), np.asarray(ori_err, dtype=np.float64)


def solve(
    chain: Chain,
    T: Any,
    q0: Any,
    base: FloatArray,
    *,
    seed: int,
    options: Settings,
    scene: Scene,
) -> IKResult:
    """Collision-free IK of ``(..., 4, 4)`` targets, broadcast with ``q0 (..., n)`` (or None)
    and ``base (..., nq)``, the configuration the solved joints are set in, as the module's
    docstring says. The plain solve validates ``T`` and ``q0`` (its errors and warnings).

    Returns:
        An :class:`~poekin.ik.IKResult` over the chain's joints.
    """
    plain = plain_solve(chain, T, q0, seed=seed, options=options)
    T = np.asarray(T, dtype=np.float64)
    q0 = None if q0 is None else np.asarray(q0, dtype=np.float64)
    batch = plain.success.shape
    n = chain.n_joints
    q = np.array(plain.q, dtype=np.float64).reshape(-1, n)
    flat_T = np.broadcast_to(T, (*batch, 4, 4)).reshape(-1, 4, 4)
    nq = base.shape[-1]  # base (nq,): one configuration for every target (a chain's solve)
    flat_base = base if base.ndim == 1 else np.broadcast_to(base, (*batch, nq)).reshape(-1, nq)
    flat_q0 = None if q0 is None else np.broadcast_to(q0, (*batch, n)).reshape(-1, n)
    success = np.array(plain.success).reshape(-1)
    iterations = np.array(plain.iterations).reshape(-1)
    attempts = np.array(plain.attempts).reshape(-1)
    clear = scene.clear(q, flat_base) if len(q) else np.zeros(0, dtype=bool)
    redo = np.flatnonzero(success & ~clear)
    pos_err = np.array(plain.pos_err, dtype=np.float64).reshape(-1)
    ori_err = np.array(plain.ori_err, dtype=np.float64).reshape(-1)
    if len(redo) and not options.position_only:
        near = None if flat_q0 is None else flat_q0[redo]
        settled, pos, ori, none = _clear_branch(
            chain, flat_T[redo], near, q[redo], _rows(flat_base, redo), options, scene
        )
        found = ~np.isnan(settled[:, 0])
        q[redo[found]] = settled[found]
        pos_err[redo[found]], ori_err[redo[found]] = pos[found], ori[found]
        success[redo[none]] = False  # no answer keeps the margin: it fails at once
        redo = redo[~found & ~none]
    if flat_q0 is None:  # random starts anyway: the plain solve's other seeds first
        for r in range(RESTARTS):
            if not len(redo):
                break
            again = plain_solve(
                chain, flat_T[redo], None, seed=_restart_seed(seed, r), options=options
            )
            ok = np.array(again.success) & scene.clear(again.q, _rows(flat_base, redo))
            q[redo[ok]] = again.q[ok]
            pos_err[redo[ok]], ori_err[redo[ok]] = again.pos_err[ok], again.ori_err[ok]
            iterations[redo] += again.iterations
            attempts[redo] += again.attempts
            redo = redo[~ok]
    if len(redo):
        keys = _rng.target_keys(seed, flat_T[redo], None if flat_q0 is None else flat_q0[redo])
    for k, i in enumerate(redo):
        start = None if flat_q0 is None else flat_q0[i]
        found_q, conv, its, tries = _solve_one(
            chain, flat_T[i], start, keys[k], _rows(flat_base, i), options, scene
        )
        if found_q is not None:
            q[i] = found_q
        success[i] = conv
        iterations[i] += its
        attempts[i] += tries
    if len(redo):  # the answers the constrained solve changed, measured again
        pos_err[redo], ori_err[redo] = _pose_errors(chain, q[redo], flat_T[redo])
    return IKResult(
        q.reshape(*batch, n),
        success.reshape(batch),
        pos_err.reshape(batch),
        ori_err.reshape(batch),
        iterations.reshape(batch),
        attempts.reshape(batch),
    )


def step(
    chain: Chain,
    T: FloatArray,
    q: FloatArray,
    dt: float,
    reach: FloatArray,
    gain: float,
    damping: float,
    s: Settings,
    scene: Scene,
    damper_gain: float,
) -> FloatArray:
    """:meth:`poekin.Chain.ik_step` with ``avoid``: ``(N, n)`` velocities for ``(N, 4, 4)``
    targets and ``(N, n)`` ``q`` (validated), the step ``x = qvel dt`` minimising ``|J x -
    gain r|^2 + damping |x|^2`` within the limits and ``reach = v_max dt`` and the velocity
    damper's rows (:func:`poekin.collision.avoid.damper_rows`: no pair closes more than
    ``damper_gain`` of its gap above ``margin`` in one tick), by :func:`inequality_qp`."""
    terms = chain_terms(chain)
    measured = pair_rows(
        scene.tree,
        scene.qpos(q, scene.tree.qpos0),
        scene.obstacles,
        activation=scene.margin + ACTIVATION,
        ignore=scene.ignore,
    )
    G, h = damper_rows(measured, scene.margin, damper_gain)
    G = G[..., list(scene.dofs)]
    out = np.zeros_like(q)
    for i in range(len(q)):
        R = tuple(tuple(np.atleast_1d(T[i, a, b]) for b in range(3)) for a in range(3))
        goal = (R, tuple(np.atleast_1d(T[i, a, 3]) for a in range(3)))
        J, r, _, _ = _evaluate(chain, q[i], goal, s)
        lo = np.clip(terms.limits[:, 0] - q[i], -reach, reach)
        hi = np.clip(terms.limits[:, 1] - q[i], -reach, reach)
        near = np.isfinite(h[i])
        H = J.T @ J + damping * np.eye(len(q[i]))
        x = inequality_qp(
            H, J.T @ (gain * r), np.minimum(lo, 0.0), np.maximum(hi, 0.0), G[i][near], h[i][near]
        )
        out[i] = np.clip(x, lo, hi) / dt
    return out
