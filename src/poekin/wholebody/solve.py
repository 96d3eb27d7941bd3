"""Whole-body inverse kinematics: many frames at once, a floating base, contacts that hold.

:meth:`poekin.Tree.ik` with a dict of targets. Each iteration, from ``qpos``:

1. every frame's pose (:meth:`~poekin.Tree.fk`, one pass) and each target frame's world
   Jacobian (:meth:`~poekin.Tree.jacobian`, MuJoCo's velocity layout), the residual rows of
   each task as :mod:`poekin.wholebody.tasks` defines them;
2. the step of :func:`poekin.wholebody.qp.step`: the held frames' rows as level 1 (a
   Gauss-Newton step that meets them), the soft targets' weighted rows as level 2 in their
   null space, the posture as level 3, every hinge and slide joint kept inside its limits;
   each level is damped by ``0.03 |r|^2`` of its own residual (Levenberg-Marquardt with
   Yamashita and Fukushima's choice: quadratic convergence as ``|r| -> 0``) and the step is
   scaled so that no variable moves more than 1.5 (rad or m);
3. ``qpos`` moves on the configuration space (:class:`poekin.wholebody.space.Space`):
   quaternions stay unit, every iterate is inside the limits.

An attempt stops when every task is met (``pos_tol``, ``ori_tol``), when its cost has not
halved in 8 iterations, or after ``max_iterations``. The first attempt starts at the given
``qpos``; each further one at a configuration whose hinge and slide joints are drawn uniform
within their limits (counter-based, from the seed and the targets' bits, as
:mod:`poekin.ik._rng`: a batch entry gets the same answer alone or in any batch), the base,
ball and frozen joints as given. The answer is the best iterate over all attempts: the held
frames met first, then the least soft cost.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose, lie
from poekin._blas import one_thread
from poekin.errors import HeldFramesError, InputError
from poekin.ik import _rng
from poekin.ik.numerical import Settings, check_seed
from poekin.wholebody import qp
from poekin.wholebody.space import Space, space
from poekin.wholebody.tasks import Task, Tasks, parse

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.tree import Tree

__all__ = ["WholeBodyResult", "solve"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.int64]

DAMPING = 0.03  # lam = DAMPING |r|^2 + FLOOR, per level
FLOOR = 1e-18  # m^2
STEP_MAX = 1.5  # rad or m: the largest move of one variable in one iteration
STALL_FACTOR = 0.5
STALL_ITERATIONS = 8
DRAWS = 16  # random starts a further attempt draws, of which it keeps the best
CHAIN_ATTEMPTS = 30  # attempts of each frame's chain solve in a further attempt's start
POSTURE_TOL = 1e-9  # rad (m): a solve with a posture goes on until its pull moves less
POLISH_ITERATIONS = 20  # level 1 alone, after an attempt that misses a held frame


@dataclasses.dataclass(frozen=True)
class WholeBodyResult:
    """What a whole-body solve found, per batch entry. Immutable NumPy arrays.

    Attributes:
        qpos: ``(..., nq)`` the whole configuration (MuJoCo's layout), every hinge and slide
            joint within its limits, quaternions unit: the solution where ``success``, else
            the best found (held frames met, least soft cost).
        success: ``(...,)`` True where every frame, held and soft, is within ``pos_tol`` and
            ``ori_tol`` of its target.
        frame_errors: frame name to ``(pos_err, ori_err)``, each ``(...,)``: the distance (m)
            and geodesic angle (rad) to its target, 0 for what its mode does not place.
        iterations: ``(...,)`` iterations over all attempts.
        attempts: ``(...,)`` attempts run.
    """

    qpos: FloatArray
    success: BoolArray
    frame_errors: dict[str, tuple[FloatArray, FloatArray]]
    iterations: IntArray
    attempts: IntArray


@dataclasses.dataclass(frozen=True)
class ChainStart:
    """One frame of a further attempt's start, solved alone by :meth:`poekin.Chain.ik`: the
    task, its chain (the joints on its path that earlier frames left unset, from ``base``, a
    body, or the world) and where those joints are in ``qpos``."""

    task: int
    chain: Chain
    base: int | None
    indices: tuple[int, ...]


@dataclasses.dataclass(frozen=True)
class Problem:
    """A validated solve: the tree, its variables, the tasks flattened to ``B`` entries."""

    tree: Tree
    space: Space
    tasks: tuple[Task, ...]
    R: tuple[FloatArray, ...]  # (B, 3, 3) per task
    p: tuple[FloatArray, ...]  # (B, 3) per task
    orientation_weight: float
    posture: FloatArray  # (n,) per-variable gains, zeros for none
    # (tasks, h): True where hinge or slide variable j moves task i's frame
    paths: NDArray[np.int64]
    tolerances: tuple[float, float]  # pos_tol, ori_tol
    # (task, qpos address, body) of the task a random start's floating base is placed by
    anchor: tuple[int, int, int] | None
    seed: int

    @functools.cached_property
    def chains(self) -> tuple[ChainStart, ...]:
        """How a further attempt's start solves each frame alone (built at its first use:
        most solves from a start near the answer need no further attempt)."""
        return _chain_starts(self.tree, self.tasks, self.space, self.anchor)

    def residual(
        self, qpos: FloatArray, rows: IntArray | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[tuple[FloatArray, ...]]]:
        """At ``qpos (B, nq)`` (for the entries ``rows`` of the problem): the held and soft
        rows ``A, b, C, d`` and each task's ``(pos_err, ori_err)``. Every task's numbers are
        computed at once where they can be (one call of each NumPy function for all of them,
        element by element as one task's: the same bits)."""
        tree, k = self.tree, self.orientation_weight
        poses = tree.fk(qpos)
        variables = self.space.variables
        B, count = len(qpos), len(self.tasks)
        R_now = np.empty((B, count, 3, 3))  # each task's frame now: rotation, point
        point = np.empty((B, count, 3))
        frames = [i for i, t in enumerate(self.tasks) if t.index >= 0]
        at = [self.tasks[i].index for i in frames]
        chosen = poses[:, at]  # (B, frames, 4, 4)
        R_now[:, frames] = chosen[..., :3, :3]
        point[:, frames] = chosen[..., :3, 3]
        J = np.empty((B, count, 6, len(variables)))  # [Jw; Jv] each
        for i, t in enumerate(self.tasks):
            if t.index < 0:
                Jv = tree.com_jacobian(qpos)[:, :, variables]
                R_now[:, i], point[:, i] = np.eye(3), tree.com(qpos)
                J[:, i, :3], J[:, i, 3:] = 0 * Jv, Jv
            else:
                J[:, i] = tree.jacobian(qpos, t.name)[:, :, variables]
        R_t, p_t = self._targets(rows)
        M = (R_t @ np.swapaxes(R_now, -1, -2)).reshape(-1, 3, 3)  # every task's at once
        quat = rotation_quaternion(M).reshape(B, count, 4)
        e_o = 2.0 * quat[..., 1:]
        angle = _angle(M).reshape(B, count)
        e_p = p_t - point
        pos_all = np.sqrt(np.sum(e_p * e_p, axis=-1))
        # e_o's exact derivative, as poekin.ik.numerical.jacobian_rows: turning the frame by
        # a dt changes e_o by -(w I + [u]) a dt, (w, u) the quaternion (k a near a solution)
        Jw = J[:, :, :3]
        u = [quat[..., i, None] for i in (1, 2, 3)]  # each (B, tasks, 1) against Jw's columns
        turned = np.stack(_pose.cross(u, [Jw[..., i, :] for i in range(3)]), axis=-2)
        k_e_o, k_Jw = k * e_o, k * (quat[..., :1, None] * Jw + turned)
        zero = np.zeros(B)
        errs: list[tuple[FloatArray, ...]] = []
        held: list[tuple[FloatArray, FloatArray]] = []  # each task's rows: J, r
        soft: list[tuple[FloatArray, FloatArray]] = []
        for i, t in enumerate(self.tasks):
            parts = ([(k_Jw[:, i], k_e_o[:, i])] if t.mode != "position" else []) + (
                [(J[:, i, 3:], e_p[:, i])] if t.mode != "orientation" else []
            )
            one = len(parts) == 1
            rows_J = parts[0][0] if one else np.concatenate([j for j, _ in parts], axis=1)
            rows_r = parts[0][1] if one else np.concatenate([r for _, r in parts], axis=1)
            errs.append(
                (
                    pos_all[:, i] if t.mode != "orientation" else zero,
                    angle[:, i] if t.mode != "position" else zero,
                )
            )
            if t.held:
                held.append((rows_J, rows_r))
            else:
                w = math.sqrt(t.weight)
                soft.append((w * rows_J, w * rows_r))
        n = self.space.n
        A = np.concatenate([h[0] for h in held], axis=1) if held else np.zeros((B, 0, n))
        b = np.concatenate([h[1] for h in held], axis=1) if held else np.zeros((B, 0))
        C = np.concatenate([f[0] for f in soft], axis=1) if soft else np.zeros((B, 0, n))
        d = np.concatenate([f[1] for f in soft], axis=1) if soft else np.zeros((B, 0))
        return A, b, C, d, errs

    def _targets(self, rows: IntArray | None) -> tuple[FloatArray, FloatArray]:
        """Every task's target rotation ``(B, tasks, 3, 3)`` and point ``(B, tasks, 3)`` (of
        the entries ``rows``): stacked once for the whole problem."""
        if rows is None:
            return self._stacked_targets
        R_t, p_t = self._stacked_targets
        return R_t[rows], p_t[rows]

    @functools.cached_property
    def _stacked_targets(self) -> tuple[FloatArray, FloatArray]:
        return np.stack(self.R, axis=1), np.stack(self.p, axis=1)


def rotation_quaternion(M: FloatArray) -> FloatArray:
    """``(B, 4)``: the unit quaternion ``(w, x, y, z)``, ``w >= 0``, of rotations ``M (B, 3,
    3)``, by Shepperd's method (the largest of ``w, x, y, z`` from the diagonal, the others
    from the off-diagonal sums and differences). ``2 (x, y, z)`` is ``2 sin(theta / 2)`` times
    the axis, a frame's orientation error as :mod:`poekin.ik.numerical` defines it, never zero
    at pi."""
    m00, m11, m22 = M[:, 0, 0], M[:, 1, 1], M[:, 2, 2]
    tr = m00 + m11 + m22
    sx, sy, sz = M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]
    ax, ay, az = M[:, 2, 1] + M[:, 1, 2], M[:, 0, 2] + M[:, 2, 0], M[:, 1, 0] + M[:, 0, 1]
    four = np.stack([1 + tr, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], axis=1)
    k = np.argmax(four, axis=1)
    if not np.any(k):  # w the largest everywhere (within 120 degrees): case 0 alone, its bits
        r0 = 0.5 * np.sqrt(np.maximum(four[:, 0], 0.0))
        s0 = 0.25 / r0
        only: FloatArray = np.stack([r0, sx * s0, sy * s0, sz * s0], axis=1)
        return only
    rows = np.arange(len(M))
    r = 0.5 * np.sqrt(np.maximum(four[rows, k], 0.0))
    s = 0.25 / r
    xs, ys, zs, axs, ays, azs = sx * s, sy * s, sz * s, ax * s, ay * s, az * s
    cases = np.stack(  # row k: the quaternion when the k-th of w, x, y, z is the largest
        [r, xs, ys, zs, xs, r, azs, ays, ys, azs, r, axs, zs, ays, axs, r], axis=1
    ).reshape(-1, 4, 4)
    quat = cases[rows, k]
    signed: FloatArray = np.where(quat[:, :1] < 0, -quat, quat)
    return signed


def _angle(M: FloatArray) -> FloatArray:
    """The geodesic angle of rotations ``M`` (rad, ``[0, pi]``): ``atan2(|vee(M)|, (tr M - 1)
    / 2)``, as :func:`poekin.pose_errors`."""
    vee = np.stack(
        [M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], axis=1
    )
    angle: FloatArray = np.arctan2(
        0.5 * np.sqrt(np.sum(vee * vee, axis=1)), 0.5 * (M[:, 0, 0] + M[:, 1, 1] + M[:, 2, 2] - 1)
    )
    return angle


def _met(errs: list[tuple[FloatArray, ...]], s: Settings, which: list[bool]) -> BoolArray:
    ok = np.ones(errs[0][0].shape, dtype=bool) if errs else np.ones(0, dtype=bool)
    for (pos, ori), use in zip(errs, which, strict=True):
        if use:
            ok &= (pos <= s.pos_tol) & (ori <= s.ori_tol)
    return ok


def _keys(seed: int, problem: Problem, q0: FloatArray) -> Any:
    key = _rng.mix(np.full(q0.shape[0], seed, dtype=np.uint64))
    values = [
        a.reshape(q0.shape[0], -1) for pair in zip(problem.R, problem.p, strict=True) for a in pair
    ]
    for block in [*values, q0]:
        for j in range(block.shape[1]):
            key = _rng.mix(key ^ _rng.bits(block[:, j]))
    return key


def _restart(
    problem: Problem,
    keys: Any,
    attempt: int,
    best: FloatArray,
    q0: FloatArray,
    rows: IntArray,
    errs: list[tuple[FloatArray, ...]],
) -> FloatArray:
    """The start of a further attempt. Even attempts: from the best iterate, the hinge and
    slide joints that move a frame still missed drawn anew (uniform within their limits),
    the rest kept (a humanoid whose feet are placed retries its arms and torso). Odd
    attempts, and entries that miss nothing the draw could move: :func:`_best_drawn`."""
    t_pos, t_ori = problem.tolerances
    missed = np.stack([(pos > t_pos) | (ori > t_ori) for pos, ori in errs], axis=1)
    redraw = (missed.astype(np.int64) @ problem.paths) > 0  # joints that move a missed frame
    partial = np.any(redraw, axis=1) & (attempt % 2 == 0)  # odd attempts redraw all
    q = np.array(best)
    some = np.flatnonzero(partial)
    if some.size:
        counter = np.full(some.size, attempt, dtype=np.int64)
        q[some] = _drawn(problem.space, q[some], redraw[some], keys[some], counter)
    full = np.flatnonzero(~partial)
    if full.size:
        q[full] = _best_drawn(problem, keys[full], attempt, q0[full], rows[full])
    return q


def _drawn(sp: Space, q: FloatArray, redraw: BoolArray, keys: Any, counter: IntArray) -> FloatArray:
    """``q (B, nq)`` with each solved hinge or slide joint ``j`` where ``redraw[:, j]`` drawn
    uniform within its limits (an unlimited hinge in ``[-pi, pi)``, an unlimited slide kept),
    from the keys at their counters (:func:`poekin.ik._rng.uniform`)."""
    q = np.array(q)
    for j, a in enumerate(sp.scalar_q):
        lo, hi = sp.lower[j], sp.upper[j]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            if not sp.revolute[j]:
                continue
            lo, hi = -math.pi, math.pi
        u = _rng.uniform(keys, counter, j)
        q[:, a] = np.where(redraw[:, j], lo + u * (hi - lo), q[:, a])
    return q


def _best_drawn(
    problem: Problem, keys: Any, attempt: int, q0: FloatArray, rows: IntArray
) -> FloatArray:
    """Of :data:`DRAWS` starts, each with every joint that moves a target drawn anew, the base
    placed (:func:`_placed`) and each frame then solved alone (:func:`_by_chains`), the one
    of least cost (held frames first): where frames share joints (a torso under both arms),
    the draws are the search over those joints."""
    B = len(rows)
    many_rows = np.repeat(rows, DRAWS)
    counter = (attempt * DRAWS + np.tile(np.arange(DRAWS), B)).astype(np.int64)
    movers = np.broadcast_to(np.any(problem.paths, axis=0), (B * DRAWS, problem.paths.shape[1]))
    many = _drawn(
        problem.space, np.repeat(q0, DRAWS, axis=0), movers, np.repeat(keys, DRAWS), counter
    )
    many = _by_chains(problem, _placed(problem, many, many_rows), many_rows, attempt)
    _, b, _, d, _ = problem.residual(many, many_rows)
    hold = np.sum(b * b, axis=1).reshape(B, DRAWS)
    soft = np.sum(d * d, axis=1).reshape(B, DRAWS)
    pick = _least(hold, soft)
    return many.reshape(B, DRAWS, -1)[np.arange(B), pick]


def _least(hold: FloatArray, soft: FloatArray) -> IntArray:
    """Per row, the column of least ``hold``, ties broken by the least ``soft``."""
    lowest = hold == np.min(hold, axis=1, keepdims=True)
    best: IntArray = np.argmin(np.where(lowest, soft, np.inf), axis=1)
    return best


def _by_chains(problem: Problem, q: FloatArray, rows: IntArray, attempt: int) -> FloatArray:
    """``q`` with each frame of :attr:`Problem.chains` solved alone, in turn, by its chain's
    exact solver (:meth:`poekin.Chain.ik`, seeded by the attempt), the joints before it as
    set: a start that meets every target that can be met frame by frame."""
    from poekin.ik.numerical import settings, solve

    options = settings(max_attempts=CHAIN_ATTEMPTS, position_only=False)
    position = settings(max_attempts=CHAIN_ATTEMPTS, position_only=True)
    q = np.array(q)
    for c in problem.chains:
        t = problem.tasks[c.task]
        T = lie.homogeneous(problem.R[c.task][rows], problem.p[c.task][rows])
        if c.base is not None:
            T = lie.inverse(problem.tree.fk(q)[:, c.base]) @ T
        found = solve(
            c.chain,
            np.ascontiguousarray(T),
            q[:, list(c.indices)],
            seed=(problem.seed * 1_000_003 + attempt) % 2**64,
            options=position if t.mode == "position" else options,
        )
        q[:, list(c.indices)] = found.q
    return q


def _placed(problem: Problem, q: FloatArray, rows: IntArray) -> FloatArray:
    """``q`` with its floating base moved so that the anchor task's frame is on its target
    (its position only for a position task): a random start whose joints are drawn in their
    limits, near the targets."""
    if problem.anchor is None:
        return q
    i, a, body = problem.anchor
    t = problem.tasks[i]
    T = problem.tree.fk(q)
    T_frame, T_base = T[:, t.index], T[:, body]
    if t.mode == "pose":
        T_target = lie.homogeneous(problem.R[i][rows], problem.p[i][rows])
        T_new = T_target @ lie.inverse(T_frame) @ T_base
    else:
        T_new = np.array(T_base)
        T_new[:, :3, 3] += problem.p[i][rows] - T_frame[:, :3, 3]
    q = np.array(q)
    q[:, a : a + 3] = T_new[:, :3, 3]
    q[:, a + 3 : a + 7] = lie.rotation_to_quat(T_new[:, :3, :3])
    return q


def _paths(tree: Tree, tasks: tuple[Task, ...], sp: Space) -> NDArray[np.int64]:
    """``(tasks, h)``: 1 where solved hinge or slide variable ``j`` moves task ``i``'s frame
    (every one for the centre of mass)."""
    column = {int(a): j for j, a in enumerate(sp.scalar_q)}
    out = np.zeros((len(tasks), len(sp.scalar_q)), dtype=np.int64)
    for i, t in enumerate(tasks):
        if t.index < 0:
            out[i] = 1
            continue
        for k in tree.path_joints(tree.frame_names[t.index]):
            j = column.get(int(tree.qpos_adr[k]))
            if j is not None and tree.mimics[k] is None:
                out[i, j] = 1
    return out


def _chain_starts(
    tree: Tree, tasks: tuple[Task, ...], sp: Space, anchor: tuple[int, int, int] | None
) -> tuple[ChainStart, ...]:
    """The frames a further attempt's start solves alone, the longest paths first (poses
    before points): each with the hinge and slide joints on its path that no earlier frame
    (nor the anchor's, whose frame the base placement meets) has set, where those form the
    end of the path and include no mimic joint; frames placed by orientation alone, and the
    CoM, are left out. So the first arm under a torso solves the torso with it (one of its
    branches), and the second arm the rest for that torso."""
    solved = {int(a) for a in sp.scalar_q}
    done: set[int] = set()
    if anchor is not None:
        t = tasks[anchor[0]]
        done.update(tree.path_joints(tree.frame_names[t.index]))
    order = sorted(
        (i for i, t in enumerate(tasks) if t.index >= 0 and t.mode != "orientation"),
        key=lambda i: (
            -len(tree.path_joints(tree.frame_names[tasks[i].index])),
            tasks[i].rows != 6,
        ),
    )
    out: list[ChainStart] = []
    for i in order:
        if anchor is not None and i == anchor[0]:
            continue
        frame = tree.frame_names[tasks[i].index]
        path = tree.path_joints(frame)
        rest = [k for k in path if k not in done]
        cut = len(path) - len(rest)
        if not rest or path[cut:] != tuple(rest):
            continue
        if any(
            tree.joint_types[k] not in ("revolute", "prismatic")
            or tree.mimics[k] is not None
            or int(tree.qpos_adr[k]) not in solved
            for k in rest
        ):
            continue
        base = None if cut == 0 else int(tree.joint_bodies[path[cut - 1]])
        key = f"wholebody-chain:{frame}:{base}"
        if key not in tree._ik_cache:
            tree._ik_cache[key] = tree.chain(
                frame, base=None if base is None else tree.body_names[base]
            )
        chain = tree._ik_cache[key]
        if chain.n_joints != len(rest):
            continue
        done.update(rest)
        indices = tuple(int(tree.qpos_adr[k]) for k in rest)
        out.append(ChainStart(i, chain, base, indices))
    return tuple(out)


def _anchor(tree: Tree, tasks: tuple[Task, ...], sp: Space) -> tuple[int, int, int] | None:
    """The task that places a random start's base: one that places a frame's position below
    a solved free joint (preferred in the order below), with that joint's qpos address and
    body."""
    free = {a for a, _ in sp.free_p}
    found: list[tuple[int, int, int, int]] = []
    for i, t in enumerate(tasks):
        if t.index < 0 or t.mode == "orientation":
            continue
        path = tree.path_joints(tree.frame_names[t.index])
        if path and tree.joint_types[path[0]] == "free" and int(tree.qpos_adr[path[0]]) in free:
            # a frame on the base body itself first (the base then lands on its target),
            # then held frames before soft ones, poses before positions
            rank = (len(path) > 1) * 4 + (not t.held) * 2 + (t.mode != "pose")
            found.append((rank, i, int(tree.qpos_adr[path[0]]), int(tree.joint_bodies[path[0]])))
    if not found:
        return None
    _, i, a, body = min(found)
    return i, a, body


def _attempt(
    problem: Problem, q: FloatArray, rows: IntArray, s: Settings, reference: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray, IntArray]:
    """One attempt for the entries ``rows`` from ``q``: the best iterate per entry, its held
    and soft costs (the held one 0 where the held frames are met), whether it met every task,
    and the iterations run. An entry whose best iterate misses a held frame is then polished:
    up to :data:`POLISH_ITERATIONS` more, of level 1 alone (Gauss-Newton on the held frames,
    quadratic near a solution), from that iterate."""
    found = _iterate(problem, q, rows, s, reference, s.max_iterations, soft=True)
    best_q, best_hold, best_soft, success, iterations = found
    polish = np.flatnonzero(best_hold > 0)
    if polish.size:
        more = _iterate(
            problem, best_q[polish], rows[polish], s, reference, POLISH_ITERATIONS, soft=False
        )
        better = _better(more[1] == 0, more[1], more[2], best_hold[polish], best_soft[polish])
        for arr, new in zip((best_q, best_hold, best_soft), more[:3], strict=True):
            arr[polish[better]] = new[better]
        success[polish] |= more[3]
        iterations[polish] += more[4]
    return best_q, best_hold, best_soft, success, iterations


def _iterate(
    problem: Problem,
    q: FloatArray,
    rows: IntArray,
    s: Settings,
    reference: FloatArray,
    max_iterations: int,
    *,
    soft: bool,
) -> tuple[FloatArray, FloatArray, FloatArray, BoolArray, IntArray]:
    """Iterations for the entries ``rows`` from ``q`` (:func:`_attempt`'s results); without
    ``soft``, level 1 alone."""
    B = len(rows)
    q = np.array(q)
    held_flags = [t.held for t in problem.tasks]
    all_flags = [True] * len(problem.tasks)
    best_q = np.array(q)
    best_hold = np.full(B, np.inf)
    best_soft = np.full(B, np.inf)
    done = np.zeros(B, dtype=bool)
    success = np.zeros(B, dtype=bool)
    iterations = np.zeros(B, dtype=np.int64)
    mark = np.full(B, np.inf)
    mark_hold = np.full(B, np.inf)
    since = np.zeros(B, dtype=np.int64)
    pulling = soft and bool(np.any(problem.posture))
    posture_move = np.full(B, np.inf if pulling else 0.0)  # level 3's last move
    for _ in range(max_iterations + 1):
        live = np.flatnonzero(~done)
        if live.size == 0:
            break
        ql = q[live]
        A, b, C, d, errs = problem.residual(ql, rows[live])
        hold_cost = np.sum(b * b, axis=1)
        soft_cost = np.sum(d * d, axis=1)
        held_ok = _met(errs, s, held_flags)
        met = _met(errs, s, all_flags)
        # an iterate that meets every task beats any that does not, and the latest such wins
        # (the posture moves it on along the solutions)
        better = met | (
            ~success[live]
            & _better(held_ok, hold_cost, soft_cost, best_hold[live], best_soft[live])
        )
        best_q[live[better]] = ql[better]
        best_hold[live[better]] = np.where(held_ok, 0.0, hold_cost)[better]
        best_soft[live[better]] = soft_cost[better]
        success[live] |= met
        # progress: either level's cost halves (the held one while it is not met)
        hold_drop = ~held_ok & (hold_cost < STALL_FACTOR * mark_hold[live])
        soft_drop = soft & (soft_cost < STALL_FACTOR * mark[live])
        mark_hold[live] = np.where(hold_drop, hold_cost, mark_hold[live])
        mark[live] = np.where(soft_drop, soft_cost, mark[live])
        since[live] = np.where(hold_drop | soft_drop | met, 0, since[live] + 1)
        finished = (met & (posture_move[live] <= POSTURE_TOL)) if soft else held_ok
        stop = finished | (since[live] >= STALL_ITERATIONS) | (iterations[live] >= max_iterations)
        done[live] = stop
        go = ~stop
        if not np.any(go):
            break
        g = live[go]
        lo, hi = problem.space.bounds(ql[go])
        posture = None
        if soft and np.any(problem.posture):
            posture = problem.space.difference(ql[go], reference[rows[g]])
        if not soft:
            C, d = C[:, :0], d[:, :0]
        taken = qp.step(
            A[go],
            b[go],
            C[go],
            d[go],
            lo,
            hi,
            DAMPING * hold_cost[go] + FLOOR,
            DAMPING * soft_cost[go] + FLOOR,
            posture,
            problem.posture,
        )
        x = taken.x
        posture_move[g] = taken.posture_move
        biggest = np.max(np.abs(x), axis=1, initial=0.0)
        x *= np.where(biggest > STEP_MAX, STEP_MAX / np.maximum(biggest, 1e-300), 1.0)[:, None]
        q[g] = problem.space.clip(problem.space.integrate(ql[go], x))
        iterations[g] += 1
    return best_q, best_hold, best_soft, success, iterations


def _better(
    held_ok: BoolArray,
    hold_cost: FloatArray,
    soft_cost: FloatArray,
    best_hold: FloatArray,
    best_soft: FloatArray,
) -> BoolArray:
    """Whether an iterate beats the best so far: held frames met beats not; among iterates
    that meet them the lesser soft cost wins, among those that do not the lesser held cost."""
    hold = np.where(held_ok, 0.0, hold_cost)
    out: BoolArray = (hold < best_hold) | ((hold == best_hold) & (soft_cost < best_soft))
    return out


def solve(
    tree: Tree,
    targets: Mapping[str, ArrayLike],
    qpos: ArrayLike | None,
    *,
    hold: object,
    position_only: object,
    orientation_only: object,
    weights: Mapping[str, float] | None,
    posture: float | ArrayLike,
    freeze: Collection[str],
    seed: int,
    options: Settings,
) -> WholeBodyResult:
    """:meth:`poekin.Tree.ik` with a dict of targets (its docstring holds the arguments), on
    one BLAS thread (:mod:`poekin._blas`: its SVDs are of a few dozen columns, which a busy
    machine's thread pool slows tenfold)."""
    with one_thread():
        tasks = parse(
            tree,
            targets,
            hold=hold,
            position_only=position_only,
            orientation_only=orientation_only,
            weights=weights,
        )
        seed = check_seed(seed)
        problem, q0, batch = _problem(tree, tasks, qpos, posture, freeze, options, seed)
        B = q0.shape[0]
        keys: Any = None  # drawn at the first further attempt
        best_q = np.array(q0)
        best_hold = np.full(B, np.inf)
        best_soft = np.full(B, np.inf)
        success = np.zeros(B, dtype=bool)
        iterations = np.zeros(B, dtype=np.int64)
        attempts = np.zeros(B, dtype=np.int64)
        for attempt in range(options.max_attempts):
            rows = np.flatnonzero(~success)
            if rows.size == 0:
                break
            if attempt == 0:
                start = q0[rows]
            else:
                *_, errs = problem.residual(best_q[rows], rows)
                if keys is None:
                    keys = _keys(seed, problem, q0)
                start = _restart(problem, keys[rows], attempt, best_q[rows], q0[rows], rows, errs)
            q, hold_c, soft_c, ok, its = _attempt(problem, start, rows, options, q0)
            better = ok | _better(hold_c == 0, hold_c, soft_c, best_hold[rows], best_soft[rows])
            best_q[rows[better]] = q[better]
            best_hold[rows[better]] = hold_c[better]
            best_soft[rows[better]] = soft_c[better]
            success[rows] = ok
            iterations[rows] += its
            attempts[rows] += 1
        *_, errs = problem.residual(best_q)
        success = _met(errs, options, [True] * len(problem.tasks))
        held = [t for t in problem.tasks if t.held]
        if held:
            missed = ~_met(errs, options, [t.held for t in problem.tasks])
            if np.any(missed):
                _raise_held(problem, errs, missed, batch, options.max_attempts)
        shape = batch
        return WholeBodyResult(
            qpos=best_q.reshape(*shape, tree.nq),
            success=success.reshape(shape),
            frame_errors={
                t.name: (pos.reshape(shape), ori.reshape(shape))
                for t, (pos, ori) in zip(problem.tasks, errs, strict=True)
            },
            iterations=iterations.reshape(shape),
            attempts=attempts.reshape(shape),
        )


def _raise_held(
    problem: Problem,
    errs: list[tuple[FloatArray, ...]],
    missed: BoolArray,
    batch: tuple[int, ...],
    attempts: int,
) -> None:
    i = int(np.flatnonzero(missed)[0])
    where = f" at index {tuple(int(v) for v in np.unravel_index(i, batch))}" if batch else ""
    held = [(t, e) for t, e in zip(problem.tasks, errs, strict=True) if t.held]
    names = ", ".join(repr(t.name) for t, _ in held)
    worst = max(held, key=lambda te: float(te[1][0][i]) + float(te[1][1][i]))
    t, (pos, ori) = worst
    raise HeldFramesError(
        f"the held frames {names} cannot all be met together{where}: the best configuration "
        f"of {attempts} attempt{'s' if attempts != 1 else ''} within the limits leaves "
        f"{t.name!r} {float(pos[i]):.3g} m and {float(ori[i]):.3g} rad from its target; move "
        "their targets closer together, hold fewer frames, or allow more max_attempts"
    )


def _problem(
    tree: Tree,
    tasks: Tasks,
    qpos: ArrayLike | None,
    posture: float | ArrayLike,
    freeze: Collection[str],
    options: Settings,
    seed: int,
    *,
    clip: bool = True,
    starts: bool = True,
) -> tuple[Problem, FloatArray, tuple[int, ...]]:
    """The :class:`Problem`, ``qpos`` broadcast and flattened to ``(B, nq)`` (clamped into the
    limits with ``clip``) and the batch shape; without ``starts``, none of what further
    attempts' starts need (a single step)."""
    if isinstance(freeze, str):
        freeze = (freeze,)
    sp = space(tree, freeze)
    q = tree.qpos0 if qpos is None else tree._as_qpos(qpos)
    try:
        batch = tuple(np.broadcast_shapes(tasks.batch, q.shape[:-1]))
    except ValueError:
        raise InputError(
            f"qpos's batch shape {q.shape[:-1]} does not broadcast against the targets' "
            f"{tasks.batch}"
        ) from None
    B = math.prod(batch)
    q0 = np.broadcast_to(q, (*batch, tree.nq)).reshape(B, tree.nq)
    q0 = sp.clip(q0) if clip else np.array(q0)
    R = tuple(_flat(t.R, batch, B, (3, 3)) for t in tasks.tasks)
    p = tuple(_flat(t.p, batch, B, (3,)) for t in tasks.tasks)
    anchor = _anchor(tree, tasks.tasks, sp) if starts else None
    problem = Problem(
        tree,
        sp,
        tasks.tasks,
        R,
        p,
        options.orientation_weight,
        _posture(posture, sp),
        _paths(tree, tasks.tasks, sp) if starts else np.zeros((0, 0), dtype=np.int64),
        (options.pos_tol, options.ori_tol),
        anchor,
        seed,
    )
    return problem, q0, batch


def _flat(value: FloatArray, batch: tuple[int, ...], B: int, tail: tuple[int, ...]) -> FloatArray:
    """``value (..., *tail)`` broadcast to ``(*batch, *tail)`` and flattened to ``(B,
    *tail)``: a reshape alone where it has that shape already (a control tick's targets)."""
    if value.shape == (*batch, *tail):
        return value.reshape(B, *tail)
    return np.broadcast_to(value, (*batch, *tail)).reshape(B, *tail)


def _posture(posture: float | ArrayLike, sp: Space) -> FloatArray:
    """Per-variable weights ``>= 0``: one number for every joint, or ``(nv,)``."""
    arr = np.asarray(posture, dtype=np.float64) if not isinstance(posture, bool) else None
    if arr is None or arr.shape not in ((), (sp.nv,)) or not np.all(np.isfinite(arr) & (arr >= 0)):
        raise InputError(
            f"posture must be a weight >= 0, or {sp.nv} of them (one per qvel entry), "
            f"got {posture!r:.60}"
        )
    gains: FloatArray = np.broadcast_to(arr, (sp.nv,))[sp.variables].copy()
    return gains
