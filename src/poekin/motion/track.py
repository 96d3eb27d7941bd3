"""A whole clip of targets solved as one problem: every frame's configuration at once.

:func:`track` takes frame names to ``T`` targets each (a clip of end-effector or keypoint
poses at a fixed rate) and finds the ``T`` configurations ``q_0 ... q_{T-1}`` together, as one
nonlinear least squares:

    minimise  sum_t sum_i w_i |r_i(q_t)|^2                        (targets)
            + a_v sum_t |(q_{t+1} - q_t) / dt|^2                  (velocity)
            + a_a sum_t |(q_{t+1} - 2 q_t + q_{t-1}) / dt^2|^2    (acceleration)

with ``r_i`` a frame's residual as :mod:`poekin.wholebody.tasks` defines it (``k e_o`` and
``e_p``, world frame), differences taken on the configuration space
(:mod:`poekin.wholebody.space`: a hinge's own number, the floating base's position in the world
frame and its rotation ``log(R_t^T R_{t+1})`` in the body frame), and subject to

* held frames (``hold``) met exactly in the frames where their contact mask is on (a foot in
  contact); where it is off they are ordinary targets;
* every hinge and slide joint within its limits, at every iterate;
* optionally, ``|q_{t+1} - q_t| <= v_max dt`` for every hinge and slide joint, at every iterate.

Each Levenberg-Marquardt iteration linearises every frame (one batched
:meth:`~poekin.Tree.fk` and :meth:`~poekin.Tree.jacobian` per frame name over the whole clip),
and eliminates each frame's held rows as the whole-body solver does (the least-norm step that
meets them, and an orthonormal basis of their null space, :mod:`poekin.wholebody.qp`). The
remaining normal equations are block-pentadiagonal, the velocity terms coupling neighbouring
frames and the acceleration terms frames two apart, and are solved in ``O(T)``
(:mod:`poekin.motion._banded`), never as a dense ``(T nv)^2`` matrix. A joint that would leave
its limits is held at the bound and the step solved again (an active set, per iteration). An
active velocity limit is a stiff quadratic term on that difference, and after each step a
forward sweep clamps each difference back within its limit, so that every iterate is
feasible. A step is kept when it lowers the total cost (held residuals included), else the
damping grows tenfold. The smoothness costs tie each frame to its neighbours, so the answer
cannot switch branch (a wrist flip) between two frames without paying for it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin._blas import one_thread
from poekin.errors import HeldFramesError, InputError
from poekin.ik.numerical import settings
from poekin.motion._banded import solve_pentadiagonal
from poekin.wholebody import qp
from poekin.wholebody.solve import Problem, _problem
from poekin.wholebody.space import Space, quat_log_between
from poekin.wholebody.step import model_velocity_limits
from poekin.wholebody.tasks import parse

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = ["TrackResult", "track"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

SMOOTH_VELOCITY = 1e-6  # m^2 per (rad/s)^2: the default velocity cost's weight
SMOOTH_ACCELERATION = 1e-8  # m^2 per (rad/s^2)^2: the default acceleration cost's weight
DAMPING = 0.03  # Levenberg-Marquardt: lam = mu (cost per frame), mu starting here
FLOOR = 1e-18
STEP_MAX = 1.5  # rad or m: the largest move of one variable in one iteration
STIFF = 1e6  # the weight (per (rad/s)^2 dt^2) of an active velocity limit's term
REJECTIONS = 12  # damping increases in a row before an iteration gives up
RELATIVE_TOL = 1e-7  # converged: an iteration lowered the cost by less than this fraction
COST_FLOOR = 1e-24  # m^2 per frame: converged (errors of a picometre)
STUCK_RATIO = 1e4  # a frame whose target cost is this many times the clip's median is stuck
REPAIRS = 2  # rounds of re-solving stuck frames, each followed by the whole solve
POLISH_ITERATIONS = 20  # held rows alone, after the iterations, until they are met
RELEASES = 3  # joints released from their bounds per step at most (one per frame each time)
_BOUND_TOL = 1e-12
_RELEASE_TOL = 1e-12


@dataclasses.dataclass(frozen=True)
class TrackResult:
    """What :func:`track` found for a clip of ``T`` frames. NumPy arrays.

    Attributes:
        qpos: ``(T, nq)`` the configuration at each frame (MuJoCo's layout), every hinge and
            slide joint within its limits (and velocity limits), quaternions unit.
        success: True when the iterations converged (the cost stopped falling) and every held
            frame is met (``pos_tol``, ``ori_tol``) wherever its contact mask is on.
        frame_errors: frame name to ``(pos_err, ori_err)``, each ``(T,)``: the distance (m)
            and geodesic angle (rad) to its target per frame, 0 for what its mode does not
            place.
        pos_err: ``(T,)`` the largest position error over the frames, per frame (m).
        ori_err: ``(T,)`` the largest orientation error over the frames, per frame (rad).
        target_cost: ``sum_t sum_i w_i |r_i|^2`` over the soft targets (m^2).
        velocity_cost: ``sum_t |(q_{t+1} - q_t) / dt|^2`` (unweighted, (rad/s)^2).
        acceleration_cost: ``sum_t |(q_{t+1} - 2 q_t + q_{t-1}) / dt^2|^2`` (unweighted).
        iterations: Levenberg-Marquardt iterations run.
    """

    qpos: FloatArray
    success: bool
    frame_errors: dict[str, tuple[FloatArray, FloatArray]]
    pos_err: FloatArray
    ori_err: FloatArray
    target_cost: float
    velocity_cost: float
    acceleration_cost: float
    iterations: int


@dataclasses.dataclass(frozen=True)
class _Clip:
    """A validated clip: the problem over its ``T`` frames and what couples them."""

    problem: Problem
    T: int
    held_rows: BoolArray  # (T, m): the residual rows met exactly, per frame
    held_frames: BoolArray  # (T, tasks): the tasks held, per frame
    w_v: float  # sqrt(a_v) / dt: a velocity residual's factor
    w_a: float  # sqrt(a_a) / dt^2
    v_dt: FloatArray  # (h,) each hinge or slide variable's largest change per frame
    stiff: float  # an active velocity limit's weight
    tolerances: tuple[float, float]
    dt: float


def track(
    tree: Tree,
    targets_over_time: Mapping[str, ArrayLike],
    qpos0: ArrayLike | None = None,
    *,
    hold: object = None,
    contact: ArrayLike | Mapping[str, ArrayLike] | None = None,
    weights: Mapping[str, float] | None = None,
    position_only: object = None,
    smooth_velocity: float = SMOOTH_VELOCITY,
    smooth_acceleration: float = SMOOTH_ACCELERATION,
    velocity_limits: ArrayLike | None = None,
    dt: float = 1.0 / 30.0,
    orientation_weight: float = 0.3,
    pos_tol: float = 1e-10,
    ori_tol: float = 1e-10,
    max_iterations: int = 100,
    freeze: Collection[str] = (),
) -> TrackResult:
    """The configurations of a whole clip, solved together (the module's docstring).

    Args:
        tree: the robot.
        targets_over_time: frame name (a body, a site, or ``"com"``) to its targets over the
            clip: ``(T, 4, 4)`` poses ``T_world_frame``, or ``(T, 3)`` points (placed by
            position only); every frame the same ``T``.
        qpos0: ``(nq,)`` a configuration near the clip's first frame (default
            :attr:`~poekin.Tree.qpos0`): the first frame is solved from it by
            :meth:`~poekin.Tree.ik` and that answer starts every frame; or ``(T, nq)``, a start
            per frame (frame-by-frame answers, a previous clip). Frozen joints keep its values.
        hold: names of frames met exactly where their contact mask is on (the feet).
        contact: where the held frames are held: None (every frame), ``(T,)`` bools for every
            held frame, ``(T, len(hold))`` with ``hold`` a sequence (its order), or a dict of
            held frame name to ``(T,)`` bools. Where a held frame's mask is off it is a soft
            target (its weight in ``weights``, default 1).
        weights: frame name to the weight (default 1) of its target cost.
        position_only: names of frames placed by their position only (``(T, 3)`` targets are).
        smooth_velocity: ``a_v >= 0``, the velocity cost's weight (m^2 per (rad/s)^2).
        smooth_acceleration: ``a_a >= 0``, the acceleration cost's weight (m^2 per
            (rad/s^2)^2).
        velocity_limits: each ``qvel`` entry's largest speed (rad/s, m/s), one number or
            ``(nv,)`` (``inf`` for none), kept on hinge and slide joints: ``|q_{t+1} - q_t| <=
            v_max dt``; default the model's (:attr:`~poekin.Tree.joint_velocity_limits`).
        dt: the time between frames (s).
        orientation_weight: metres per radian in the residual.
        pos_tol: a held frame is met within this (m) ...
        ori_tol: ... and this (rad).
        max_iterations: Levenberg-Marquardt iterations at most.
        freeze: names of joints kept at ``qpos0`` (a humanoid's fingers).

    Returns:
        :class:`TrackResult`.

    Raises:
        UnknownFrameError: a target for a frame the tree lacks (the message suggests one).
        InputError: targets of the wrong shape, of different lengths, or with NaN or inf; a
            contact mask of the wrong shape; bad weights, ``dt``, smoothness weights, velocity
            limits or options.
        HeldFramesError: held frames that cannot be met where their mask is on (an
            InputError).

    Example:
        >>> robot = poekin.load_tree("unitree_g1")
        >>> T = robot.fk(np.repeat(robot.qpos0[None], 5, axis=0))  # (5, n_frames, 4, 4)
        >>> found = poekin.motion.track(robot, {"pelvis": T[:, 0]})
        >>> found.qpos.shape
        (5, 44)
    """
    targets, T = _clip_targets(targets_over_time)
    frames_by_position = _with_points(targets, position_only)
    held = _held_names(hold, targets)
    mask = _contact(contact, hold, held, T)
    options = settings(
        pos_tol=pos_tol,
        ori_tol=ori_tol,
        orientation_weight=orientation_weight,
        max_iterations=max_iterations,
    )
    a_v = _non_negative(smooth_velocity, "smooth_velocity", "m^2 s^2/rad^2")
    a_a = _non_negative(smooth_acceleration, "smooth_acceleration", "m^2 s^4/rad^2")
    dt = _positive(dt, "dt", "s")
    with one_thread():
        tasks = parse(tree, targets, hold=None, position_only=frames_by_position, weights=weights)
        start = _start(tree, targets, qpos0, T, held, mask, frames_by_position, weights, freeze)
        problem, q, _ = _problem(
            tree, tasks, start, 0.0, freeze, options, 0, clip=True, starts=False
        )
        sp = problem.space
        held_frames = np.stack(
            [mask.get(t.name, np.zeros(T, dtype=bool)) for t in problem.tasks], axis=1
        )
        held_rows = np.repeat(held_frames, [t.rows for t in problem.tasks], axis=1)
        limits = model_velocity_limits(velocity_limits, tree)[sp.variables][sp.scalar_v] * dt
        clip = _Clip(
            problem,
            T,
            held_rows,
            held_frames,
            math.sqrt(a_v) / dt,
            math.sqrt(a_a) / dt**2,
            limits,
            STIFF / dt**2,
            (options.pos_tol, options.ori_tol),
            dt,
        )
        q = _feasible(sp, q, limits)
        q, iterations, converged = _solve(clip, q, options.max_iterations)
        for _ in range(REPAIRS):  # frames stuck far from their targets: re-solved, then again

            def solve_frame(t: int, start: FloatArray) -> FloatArray:
                return _frame_ik(
                    tree, targets, t, start, held, mask, frames_by_position, weights, freeze
                )

            repaired = _repair(clip, q, solve_frame)
            if repaired is None:
                break
            q, more, converged = _solve(
                clip, _feasible(sp, repaired, limits), options.max_iterations
            )
            iterations += more
        q = _polish(clip, q)
        return _result(clip, q, iterations, converged)


# --- the inputs -----------------------------------------------------------------------------


def _positive(value: object, name: str, unit: str) -> float:
    x = _number(value, name, unit)
    if not x > 0:
        raise InputError(f"track: {name} must be a finite number > 0 ({unit}), got {x!r}")
    return x


def _non_negative(value: object, name: str, unit: str) -> float:
    x = _number(value, name, unit)
    if not x >= 0:
        raise InputError(f"track: {name} must be a finite number >= 0 ({unit}), got {x!r}")
    return x


def _number(value: object, name: str, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InputError(f"track: {name} must be a number ({unit}), got {value!r:.40}")
    x = float(value)
    if not math.isfinite(x):
        raise InputError(f"track: {name} must be a finite number ({unit}), got {x!r}")
    return x


def _clip_targets(targets: Mapping[str, ArrayLike]) -> tuple[dict[str, FloatArray], int]:
    """The targets as arrays, each ``(T, 4, 4)`` or ``(T, 3)``, finite, and the common ``T``."""
    if not isinstance(targets, Mapping) or not targets:
        raise InputError(
            "track: targets_over_time must be a non-empty dict of frame name to (T, 4, 4) "
            "poses or (T, 3) points, e.g. {'left_foot': T_left_foot}"
        )
    out: dict[str, FloatArray] = {}
    for name, value in targets.items():
        if not isinstance(name, str):
            raise InputError(f"track: target names must be frame names (str), got {name!r:.40}")
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(
                f"track: the targets of {name!r} must be an array of numbers, "
                f"got {type(value).__name__}"
            ) from None
        if not (arr.ndim == 3 and arr.shape[1:] == (4, 4)) and not (
            arr.ndim == 2 and arr.shape[1] == 3
        ):
            raise InputError(
                f"track: the targets of {name!r} must be (T, 4, 4) poses or (T, 3) points, "
                f"got shape {arr.shape}"
            )
        bad = ~np.isfinite(arr.reshape(len(arr), -1)).all(axis=1)
        if np.any(bad):
            raise InputError(
                f"track: the target of {name!r} at frame {int(np.flatnonzero(bad)[0])} has NaN "
                "or inf; every entry must be finite (drop or fill the missing frames)"
            )
        out[name] = arr
    lengths = {name: len(arr) for name, arr in out.items()}
    if len(set(lengths.values())) > 1:
        listed = ", ".join(f"{name!r}: {n}" for name, n in lengths.items())
        raise InputError(
            f"track: every frame's clip must have the same number of frames T, got {listed}"
        )
    T = next(iter(lengths.values()))
    if T == 0:
        raise InputError("track: the clip has no frames; give at least one target per frame")
    return out, T


def _with_points(targets: Mapping[str, FloatArray], position_only: object) -> frozenset[str]:
    """``position_only``'s names with every frame given points."""
    if position_only is None:
        names: frozenset[str] = frozenset()
    elif isinstance(position_only, str):
        names = frozenset({position_only})
    elif isinstance(position_only, Collection) and all(isinstance(v, str) for v in position_only):
        names = frozenset(position_only)
    else:
        raise InputError(
            f"track: position_only must be a frame name or a collection of names, "
            f"got {position_only!r:.60}"
        )
    return names | {name for name, arr in targets.items() if arr.ndim == 2}


def _held_names(hold: object, targets: Mapping[str, FloatArray]) -> tuple[str, ...]:
    if hold is None:
        return ()
    if isinstance(hold, str):
        names: tuple[str, ...] = (hold,)
    elif isinstance(hold, Collection) and all(isinstance(v, str) for v in hold):
        names = tuple(hold) if isinstance(hold, Sequence) else tuple(sorted(hold))
    else:
        raise InputError(
            f"track: hold must be a frame name or a collection of names, got {hold!r:.60}"
        )
    for name in names:
        if name not in targets:
            raise InputError(
                f"track: hold names {name!r}, which has no target; give it targets too, or "
                f"hold one of {sorted(targets)}"
            )
    return names


def _contact(
    contact: ArrayLike | Mapping[str, ArrayLike] | None,
    hold: object,
    held: tuple[str, ...],
    T: int,
) -> dict[str, BoolArray]:
    """Held frame name to its ``(T,)`` mask."""
    if contact is None:
        return {name: np.ones(T, dtype=bool) for name in held}
    if not held:
        raise InputError("track: contact is given but hold names no frame; name the held frames")
    if isinstance(contact, Mapping):
        for name in contact:
            if name not in held:
                raise InputError(
                    f"track: contact names {name!r:.40}, which is not held; hold it, or give "
                    f"masks for {list(held)}"
                )
        return {
            name: _mask(contact[name], name, T) if name in contact else np.ones(T, dtype=bool)
            for name in held
        }
    arr = np.asarray(contact)
    if arr.ndim == 2 and len(held) > 1 and not isinstance(hold, Sequence):
        raise InputError(
            "track: a (T, n_held) contact mask needs hold in a fixed order (a list or tuple), "
            "or give contact as a dict of frame name to (T,) mask"
        )
    if arr.ndim == 1:
        return {name: _mask(arr, name, T) for name in held}
    if arr.ndim == 2 and arr.shape[1] == len(held):
        return {name: _mask(arr[:, k], name, T) for k, name in enumerate(held)}
    raise InputError(
        f"track: contact must be (T,) or (T, {len(held)}) bools (one column per held frame), "
        f"got shape {arr.shape}"
    )


def _mask(value: ArrayLike, name: str, T: int) -> BoolArray:
    arr = np.asarray(value)
    if arr.dtype != np.bool_ and not (arr.dtype.kind in "iu" and np.all((arr == 0) | (arr == 1))):
        raise InputError(f"track: the contact mask of {name!r} must be bools, got {arr.dtype}")
    if arr.shape != (T,):
        raise InputError(
            f"track: the contact mask of {name!r} has shape {arr.shape}, the clip {T} frames; "
            f"give one bool per frame, ({T},)"
        )
    return arr.astype(bool)


def _start(
    tree: Tree,
    targets: Mapping[str, FloatArray],
    qpos0: ArrayLike | None,
    T: int,
    held: tuple[str, ...],
    mask: Mapping[str, BoolArray],
    position_only: frozenset[str],
    weights: Mapping[str, float] | None,
    freeze: Collection[str],
) -> FloatArray:
    """``(T, nq)``: ``qpos0`` per frame as given, or the first frame solved from it and that
    answer in every frame."""
    q = tree.qpos0 if qpos0 is None else tree._as_qpos(qpos0)
    if q.shape == (T, tree.nq):
        return q
    if q.shape != (tree.nq,):
        raise InputError(
            f"track: qpos0 must be ({tree.nq},), one configuration, or ({T}, {tree.nq}), one "
            f"per frame, got shape {q.shape}"
        )
    first = _frame_ik(tree, targets, 0, q, held, mask, position_only, weights, freeze)
    return np.repeat(first[None], T, axis=0)


def _frame_ik(
    tree: Tree,
    targets: Mapping[str, FloatArray],
    t: int,
    start: FloatArray,
    held: tuple[str, ...],
    mask: Mapping[str, BoolArray],
    position_only: frozenset[str],
    weights: Mapping[str, float] | None,
    freeze: Collection[str],
) -> FloatArray:
    """Frame ``t`` alone, by :meth:`Tree.ik` from ``start`` (one attempt): its ``qpos``."""
    one = {name: arr[t] for name, arr in targets.items()}
    held_t = {name for name in held if mask[name][t]}
    soft_weights = {k: v for k, v in (weights or {}).items() if k not in held_t}
    found = tree.ik(
        one,
        start,
        hold=held_t or None,
        position_only=position_only or None,
        weights=soft_weights or None,
        freeze=freeze,
        max_attempts=1,
    )
    return np.asarray(found.qpos, dtype=np.float64)


def _repair(
    clip: _Clip, q: FloatArray, solve_frame: Callable[[int, FloatArray], FloatArray]
) -> FloatArray | None:
    """``q`` with its stuck frames re-solved, or None if none is stuck or none improves.

    A frame is stuck when its target cost is above :data:`STUCK_RATIO` times the clip's median
    (a local minimum the joint start led it to, far from frames on either side: exact targets
    met everywhere but there, or noise whose cost is alike in every frame). Each run of stuck
    frames is solved frame by frame from the frame before it (:meth:`Tree.ik`, one attempt, so
    that the motion stays on its branch), and a frame keeps its new configuration where that
    lowers its target cost."""
    s = _state(clip, q)
    per_frame = np.sum(s.d * s.d, axis=1)
    floor = max(float(np.median(per_frame)), COST_FLOOR)
    stuck = per_frame > STUCK_RATIO * floor
    if not stuck.any() or stuck.all():
        return None
    out = q.copy()
    changed = False
    good = np.flatnonzero(~stuck)
    for t in np.flatnonzero(stuck):  # in order: a run's frames from the one before
        start = out[t - 1] if t > 0 else out[good[0]]
        candidate = solve_frame(int(t), start)
        if _frame_cost(clip, out, candidate, int(t)) < per_frame[t]:
            out[t] = candidate
            changed = True
    return out if changed else None


def _frame_cost(clip: _Clip, q: FloatArray, qpos: FloatArray, t: int) -> float:
    """The target cost at frame ``t`` of the clip ``q`` with ``qpos`` ``(nq,)`` there (its
    soft rows, as :func:`_state` weighs them; the problem's targets are the whole clip's)."""
    trial = q.copy()
    trial[t] = qpos
    _, _, _, d, _ = clip.problem.residual(trial)
    soft = d[t] * ~clip.held_rows[t]
    return float(np.sum(soft * soft))


# --- the configuration space over time ------------------------------------------------------


def _differences(sp: Space, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Between consecutive frames of ``q (T, nq)``: ``delta (T - 1, n)``, the tangent step
    from ``q_t`` to ``q_{t+1}``, and its derivatives ``P = d delta / d x_{t+1}`` and
    ``M = d delta / d x_t`` ``(T - 1, n, n)`` (``I`` and ``-I`` but for rotations: ``Jr^-1``
    and ``-Jl^-1`` of the rotation vector)."""
    a, b = q[:-1], q[1:]
    K, n = len(a), sp.n
    delta = np.zeros((K, n))
    delta[:, sp.scalar_v] = b[:, sp.scalar_q] - a[:, sp.scalar_q]
    for at, v in sp.free_p:
        delta[:, v : v + 3] = b[:, at : at + 3] - a[:, at : at + 3]
    P = np.broadcast_to(np.eye(n), (K, n, n)).copy()
    M = -P
    for at, v in sp.quats:
        phi = quat_log_between(a[:, at : at + 4], b[:, at : at + 4])
        delta[:, v : v + 3] = phi
        inv_r = _jr_inverse(phi)
        P[:, v : v + 3, v : v + 3] = inv_r
        M[:, v : v + 3, v : v + 3] = -np.swapaxes(inv_r, 1, 2)  # Jl^-1(phi) = Jr^-1(phi)^T
    return delta, P, M


def _jr_inverse(phi: FloatArray) -> FloatArray:
    """``(K, 3, 3)`` the inverse right Jacobian of SO(3) at rotation vectors ``phi (K, 3)``:
    ``Log(Exp(phi) Exp(d)) = phi + Jr^-1(phi) d + O(d^2)``."""
    theta = np.sqrt(np.sum(phi * phi, axis=1))
    small = theta < 1e-4
    t = np.where(small, 1.0, theta)
    coef = np.where(
        small,
        1.0 / 12.0 + theta**2 / 720.0,
        1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)),
    )
    W = np.zeros((len(phi), 3, 3))
    W[:, 0, 1], W[:, 0, 2], W[:, 1, 2] = -phi[:, 2], phi[:, 1], -phi[:, 0]
    W = W - np.swapaxes(W, 1, 2)
    out: FloatArray = np.eye(3) + 0.5 * W + coef[:, None, None] * (W @ W)
    return out


def _feasible(sp: Space, q: FloatArray, v_dt: FloatArray) -> FloatArray:
    """``q (T, nq)`` with each hinge and slide joint's change from the frame before clamped
    within ``v_dt`` (a forward sweep; the joints stay within their limits)."""
    if not np.any(np.isfinite(v_dt)):
        return q
    q = np.array(q)
    cols = sp.scalar_q
    for t in range(1, len(q)):
        prev = q[t - 1, cols]
        lo = np.maximum(prev - v_dt, sp.lower)
        hi = np.minimum(prev + v_dt, sp.upper)
        q[t, cols] = np.clip(q[t, cols], lo, hi)
    return q


# --- one linearisation ----------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _State:
    """A clip's configuration and everything its step needs."""

    q: FloatArray  # (T, nq)
    A: FloatArray  # (T, m, n) held rows (zero where not held)
    b: FloatArray  # (T, m)
    C: FloatArray  # (T, m, n) soft rows, weighted (zero where held)
    d: FloatArray  # (T, m)
    errs: list[tuple[FloatArray, ...]]
    delta: FloatArray  # (T - 1, n)
    P: FloatArray
    M: FloatArray
    held_cost: float
    target_cost: float
    velocity_cost: float  # sum |delta|^2 (rad^2)
    acceleration_cost: float  # sum |delta_t - delta_{t-1}|^2 (rad^2)

    def cost(self, clip: _Clip) -> float:
        """The merit a step must lower: targets, held residuals and smoothness."""
        return (
            self.target_cost
            + self.held_cost
            + clip.w_v**2 * self.velocity_cost
            + clip.w_a**2 * self.acceleration_cost
        )


def _exact_orientation_rows(problem: Problem, C: FloatArray, d: FloatArray) -> FloatArray:
    """``C`` with each orientation row block the derivative of its residual away from zero.

    A frame's orientation residual is ``c e_o`` (``c = k sqrt(weight)``), ``e_o = 2 v`` of the
    unit quaternion ``(w, v)`` (``w >= 0``) of ``M = R_target R^T``; turning the frame by
    ``omega`` (world) makes ``M`` ``M exp(-omega)``, so that ``d e_o = -(w I + [v]x) omega``.
    The rows of :meth:`Problem.residual` are its value at ``e_o = 0`` (``-omega``), which is
    enough where targets are met; a clip's noisy targets are not, and Gauss-Newton needs the
    derivative at its answer to converge to the least-squares solution of its cost."""
    C = np.array(C)
    at = 0
    for t in problem.tasks:
        if t.mode != "position":
            c = problem.orientation_weight * math.sqrt(t.weight)
            v = d[:, at : at + 3] / (2.0 * c)
            w = np.sqrt(np.maximum(1.0 - np.sum(v * v, axis=1), 0.0))
            S = w[:, None, None] * np.eye(3)
            S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
            S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
            C[:, at : at + 3] = S @ C[:, at : at + 3]
        at += t.rows
    return C


def _state(clip: _Clip, q: FloatArray) -> _State:
    _, _, C, d, errs = clip.problem.residual(q)
    C = _exact_orientation_rows(clip.problem, C, d)
    held = clip.held_rows
    A, b = C * held[:, :, None], d * held
    C, d = C * ~held[:, :, None], d * ~held
    delta, P, M = _differences(clip.problem.space, q)
    accel = delta[1:] - delta[:-1]
    return _State(
        q,
        A,
        b,
        C,
        d,
        errs,
        delta,
        P,
        M,
        float(np.sum(b * b)),
        float(np.sum(d * d)),
        float(np.sum(delta * delta)),
        float(np.sum(accel * accel)),
    )


def _normal_equations(
    clip: _Clip, s: _State, active: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The Gauss-Newton model's ``H`` (diagonal, first and second off-diagonal blocks) and
    gradient ``g`` over the clip's steps ``x (T, n)``: cost ``|r0 + J x|^2`` with ``H = J^T
    J``, ``g = J^T r0``. ``active (T - 1, h)``: the sign of each active velocity limit, 0 for
    none."""
    T, n = s.q.shape[0], clip.problem.space.n
    Ct = np.swapaxes(s.C, 1, 2)
    D = Ct @ s.C
    g = -(Ct @ s.d[:, :, None])[:, :, 0]
    U1 = np.zeros((max(T - 1, 0), n, n))
    U2 = np.zeros((max(T - 2, 0), n, n))
    if clip.w_v > 0 and T > 1:
        _add_terms(D, U1, U2, g, [clip.w_v * s.M, clip.w_v * s.P], clip.w_v * s.delta, 0)
    if clip.w_a > 0 and T > 2:
        blocks = [-s.M[:-1], s.M[1:] - s.P[:-1], s.P[1:]]
        r0 = s.delta[1:] - s.delta[:-1]
        _add_terms(D, U1, U2, g, [clip.w_a * B for B in blocks], clip.w_a * r0, 0)
    if np.any(active):
        sp = clip.problem.space
        W = clip.stiff * (active != 0)
        r0 = s.delta[:, sp.scalar_v] - active * clip.v_dt
        j = sp.scalar_v
        D[:-1, j, j] += W
        D[1:, j, j] += W
        U1[:, j, j] -= W
        g[:-1, j] -= W * r0
        g[1:, j] += W * r0
    return D, U1, U2, g


def _add_terms(
    D: FloatArray,
    U1: FloatArray,
    U2: FloatArray,
    g: FloatArray,
    blocks: list[FloatArray],
    r0: FloatArray,
    first: int,
) -> None:
    """Add residuals ``r0_k + sum_i B_i[k] x_{first + k + i}`` (``k`` over ``len(r0)``) to the
    normal equations, in place."""
    K = len(r0)
    for i, Bi in enumerate(blocks):
        at = slice(first + i, first + i + K)
        Bt = np.swapaxes(Bi, 1, 2)
        D[at] += Bt @ Bi
        g[at] += (Bt @ r0[:, :, None])[:, :, 0]
        for j in range(i + 1, len(blocks)):
            U = U1 if j - i == 1 else U2
            U[at] += Bt @ blocks[j]


def _step(
    clip: _Clip,
    s: _State,
    lam: float,
    active: FloatArray,
    fixed: BoolArray,
    *,
    soft: bool = True,
) -> tuple[FloatArray, BoolArray, float]:
    """The clip's step ``x (T, n)``, the joints at a bound after it, and the decrease of the
    cost that the linear model predicts.

    Each frame's held rows are met (least norm), and the rest of the Gauss-Newton model is
    minimised over their null spaces, damped by ``lam`` (without ``soft``: the held rows
    alone). ``fixed (T, n)``: the joints held at the bound they are at (an active set carried
    from the last step); one whose multiplier says the model falls as it moves inside is
    released and the step solved again. A joint the step would carry past a bound stops
    there and joins the set."""
    sp = clip.problem.space
    lo, hi = sp.bounds(s.q)
    at_lo, at_hi = lo >= 0.0, hi <= 0.0
    fixed = fixed & (at_lo | at_hi)
    terms = _normal_equations(clip, s, active) if soft else None
    lam_hold = DAMPING * np.sum(s.b * s.b, axis=1) + FLOOR
    for _ in range(RELEASES + 1):
        x = _constrained(clip, s, terms, fixed, lam_hold, lam)
        if terms is None:
            break
        release = _pulled_inside(s, terms, x, fixed, at_lo)
        if not np.any(release):
            break
        fixed = fixed & ~release
    past = ~fixed & ((x < lo - _BOUND_TOL) | (x > hi + _BOUND_TOL))
    x = np.clip(x, lo, hi)
    held = s.b - np.einsum("tmi,ti->tm", s.A, x)
    predicted = s.held_cost - float(np.sum(held * held))
    if terms is not None:
        predicted -= float(np.sum(x * (2.0 * terms[3] + _times_h(*terms[:3], x))))
    return x, fixed | past, predicted


def _constrained(
    clip: _Clip,
    s: _State,
    terms: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None,
    fixed: BoolArray,
    lam_hold: FloatArray,
    lam: float,
) -> FloatArray:
    """The step with the ``fixed`` joints at 0: per frame, the held rows and the fixed
    joints as level 1 (:func:`poekin.wholebody.qp._damped_solve`: the least-norm step that
    meets them, and their null space), the model over the clip in those null spaces."""
    T, n = fixed.shape
    null = ~fixed  # a frame without held rows: level 1 is its fixed joints alone
    Z = null[:, None, :] * np.eye(n)
    x_hold = np.zeros((T, n))
    rows = np.flatnonzero(clip.held_rows.any(axis=1))
    if rows.size:
        f = fixed[rows]
        Mh = np.concatenate([s.A[rows] * ~f[:, None, :], f[:, :, None] * np.eye(n)], axis=1)
        rh = np.concatenate([s.b[rows], np.zeros((rows.size, n))], axis=1)
        x_hold[rows], Z[rows], null[rows] = qp._damped_solve(Mh, rh, lam_hold[rows])
    if terms is None:
        return x_hold
    z = _reduced(*terms, Z, null, x_hold, lam)
    x: FloatArray = x_hold + np.einsum("tij,tj->ti", Z, z)
    return x


def _pulled_inside(
    s: _State,
    terms: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    x: FloatArray,
    fixed: BoolArray,
    at_lo: BoolArray,
) -> BoolArray:
    """Per frame, the fixed joint whose multiplier has the wrong sign the most: the model's
    gradient ``G = H x + g`` less its part the held rows take (``G + A^T nu``, ``nu`` from
    the free joints, as :mod:`poekin.wholebody.qp` releases), negative at a lower bound or
    positive at an upper one."""
    G = _times_h(*terms[:3], x) + terms[3]
    free = ~fixed
    residual = np.array(G)
    rows = np.flatnonzero(np.any(s.A != 0.0, axis=(1, 2)))
    if rows.size:
        At = np.swapaxes(s.A[rows], 1, 2) * free[rows, :, None]
        pinv = np.linalg.pinv(At, rcond=qp.RANK_TOL)
        nu = np.einsum("tmi,ti->tm", pinv, -G[rows] * free[rows])
        residual[rows] += np.einsum("tmi,tm->ti", s.A[rows], nu)
    wrong = np.where(at_lo, -residual, residual)
    wrong = np.where(fixed & (wrong > _RELEASE_TOL * (1.0 + np.abs(G))), wrong, -np.inf)
    worst = np.argmax(wrong, axis=1)
    has = np.isfinite(np.max(wrong, axis=1))
    out: BoolArray = has[:, None] & (np.arange(x.shape[1])[None, :] == worst[:, None])
    return out


def _times_h(D: FloatArray, U1: FloatArray, U2: FloatArray, x: FloatArray) -> FloatArray:
    """``H x`` for the block-pentadiagonal ``H`` and ``x (T, n)``."""
    Hx: FloatArray = np.einsum("tij,tj->ti", D, x)
    Hx[:-1] += np.einsum("tij,tj->ti", U1, x[1:])
    Hx[1:] += np.einsum("tji,tj->ti", U1, x[:-1])
    Hx[:-2] += np.einsum("tij,tj->ti", U2, x[2:])
    Hx[2:] += np.einsum("tji,tj->ti", U2, x[:-2])
    return Hx


def _reduced(
    D: FloatArray,
    U1: FloatArray,
    U2: FloatArray,
    g: FloatArray,
    Z: FloatArray,
    null: BoolArray,
    x0: FloatArray,
    lam: float,
) -> FloatArray:
    """``z (T, n)`` minimising the model at ``x0 + Z z`` plus ``lam |z|^2`` (``Z``'s zero
    columns, where not null, get ``z = 0``)."""
    Zt = np.swapaxes(Z, 1, 2)
    rhs = -np.einsum("tij,tj->ti", Zt, g + _times_h(D, U1, U2, x0))
    Dz = Zt @ D @ Z
    idx = np.arange(Z.shape[1])
    Dz[:, idx, idx] += lam + ~null
    U1z = Zt[:-1] @ U1 @ Z[1:]
    U2z = Zt[:-2] @ U2 @ Z[2:]
    return solve_pentadiagonal(Dz, U1z, U2z, rhs)


# --- the iterations -------------------------------------------------------------------------


def _move(clip: _Clip, q: FloatArray, x: FloatArray) -> FloatArray:
    sp = clip.problem.space
    biggest = float(np.max(np.abs(x), initial=0.0))
    if biggest > STEP_MAX:
        x = x * (STEP_MAX / biggest)
    return _feasible(sp, sp.clip(sp.integrate(q, x)), clip.v_dt)


def _solve(clip: _Clip, q: FloatArray, max_iterations: int) -> tuple[FloatArray, int, bool]:
    """Levenberg-Marquardt over the clip from ``q``: the last accepted iterate, the
    iterations run and whether the cost converged. The damping is ``mu`` times the cost per
    frame, ``mu`` updated by Nielsen's rule from how the cost fell against the model's
    prediction (a rejected step doubles its growth)."""
    sp = clip.problem.space
    s = _state(clip, q)
    mu, grow = DAMPING, 2.0
    active = np.zeros((max(clip.T - 1, 0), len(sp.scalar_v)))
    fixed = np.zeros((clip.T, sp.n), dtype=bool)
    iterations = 0
    while iterations < max_iterations:
        iterations += 1
        cost = s.cost(clip)
        for _ in range(REJECTIONS):
            x, at_bound, predicted = _step(clip, s, mu * cost / clip.T + FLOOR, active, fixed)
            new = _state(clip, _move(clip, s.q, x))
            now = new.cost(clip)
            if now <= cost:
                break
            mu, grow = mu * grow, grow * 2.0
        else:
            return s.q, iterations, True  # no step lowers the cost: a stationary point
        rho = (cost - now) / predicted if predicted > 0 else 0.0
        mu, grow = mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 2.0
        active = _active(clip, s, new, x, active)
        s, fixed = new, at_bound
        if (cost - now <= RELATIVE_TOL * cost or now <= COST_FLOOR * clip.T) and not np.any(active):
            return s.q, iterations, True
    return s.q, iterations, False


def _active(clip: _Clip, s: _State, new: _State, x: FloatArray, active: FloatArray) -> FloatArray:
    """The velocity limits active after a step: those the step reached or crossed (before
    the clamp), less those whose stiff term pulled the difference back inside."""
    if not np.any(np.isfinite(clip.v_dt)) or clip.T < 2:
        return active
    j = clip.problem.space.scalar_v
    wanted = s.delta[:, j] + x[1:, j] - x[:-1, j]  # the step's difference, unclamped
    at = np.abs(new.delta[:, j]) >= clip.v_dt * (1.0 - 1e-9)
    keep = (active != 0) & (wanted * active > clip.v_dt)  # still pushing outward
    out: FloatArray = np.where(at | keep, np.sign(new.delta[:, j]), 0.0)
    return out


def _polish(clip: _Clip, q: FloatArray) -> FloatArray:
    """``q`` after up to :data:`POLISH_ITERATIONS` steps of the held rows alone, until every
    held frame is met where it is held."""
    s = _state(clip, q)
    no_limits = np.zeros((max(clip.T - 1, 0), len(clip.problem.space.scalar_v)))
    fixed = np.zeros((clip.T, clip.problem.space.n), dtype=bool)
    for _ in range(POLISH_ITERATIONS):
        if _held_met(clip, s):
            break
        x, fixed, _ = _step(clip, s, 0.0, no_limits, fixed, soft=False)
        s = _state(clip, _move(clip, s.q, x))
    return s.q


def _held_met(clip: _Clip, s: _State) -> bool:
    pos_tol, ori_tol = clip.tolerances
    for k, (pos, ori) in enumerate(s.errs):
        held = clip.held_frames[:, k]
        if np.any(held & ((pos > pos_tol) | (ori > ori_tol))):
            return False
    return True


def _result(clip: _Clip, q: FloatArray, iterations: int, converged: bool) -> TrackResult:
    s = _state(clip, q)
    tasks = clip.problem.tasks
    if not _held_met(clip, s):
        pos_tol, ori_tol = clip.tolerances
        for k, (pos, ori) in enumerate(s.errs):
            missed = clip.held_frames[:, k] & ((pos > pos_tol) | (ori > ori_tol))
            if np.any(missed):
                t = int(np.flatnonzero(missed)[0])
                raise HeldFramesError(
                    f"track: the held frame {tasks[k].name!r} cannot be met at frame {t}: the "
                    f"best clip within the limits leaves it {float(pos[t]):.3g} m and "
                    f"{float(ori[t]):.3g} rad from its target; release it there (contact), "
                    "loosen the velocity limits, or move its target"
                )
    frame_errors = {t.name: (pos, ori) for t, (pos, ori) in zip(tasks, s.errs, strict=True)}
    return TrackResult(
        qpos=q,
        success=converged,
        frame_errors=frame_errors,
        pos_err=np.max(np.stack([e[0] for e in s.errs]), axis=0),
        ori_err=np.max(np.stack([e[1] for e in s.errs]), axis=0),
        target_cost=s.target_cost,
        velocity_cost=s.velocity_cost / clip.dt**2,
        acceleration_cost=s.acceleration_cost / clip.dt**4,
        iterations=iterations,
    )
