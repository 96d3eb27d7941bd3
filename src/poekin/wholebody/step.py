"""A differential step for control loops: :meth:`poekin.Tree.ik_step`.

One tick: the joint velocity ``qvel (..., nv)`` (MuJoCo's layout) that, applied for ``dt``,
moves each soft target's frame toward its target, from the residuals and Jacobians at
``qpos`` (:mod:`poekin.wholebody.tasks`), by :func:`poekin.wholebody.qp.step` with ``x =
qvel dt``:

1. the held frames' velocity is zero: ``J_held x = 0`` exactly (whatever the targets ask);
2. the soft rows ``min sum w |J x - gain e|^2 + damping |x|^2`` in that null space;
3. the posture (toward the reference configuration, weighted) in what null space is left;
4. every hinge and slide joint within its limits at ``qpos + qvel dt`` and within its
   velocity limit: ``clamp(lower - q, -v_max dt, v_max dt) <= x <= clamp(upper - q, -v_max dt,
   v_max dt)`` (a joint outside its limits moves back toward them, at most at its velocity
   limit, as :meth:`poekin.Chain.ik_step`'s does).

It is the problem mink's ``solve_ik`` poses as a general QP (a frame task's cost the same
rows, its equality constraints the held frames, its ``ConfigurationLimit`` with gain 1 and its
``VelocityLimit`` the box), solved here by an active set on the box.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin._blas import one_thread
from poekin.errors import InputError
from poekin.ik.numerical import settings
from poekin.ik.step import positive_number
from poekin.wholebody import qp
from poekin.wholebody.solve import FLOOR, _problem
from poekin.wholebody.tasks import parse

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = ["StepProblem", "model_velocity_limits", "solve_step", "step_problem"]

FloatArray = NDArray[np.float64]


def model_velocity_limits(value: ArrayLike | None, tree: Tree) -> FloatArray:
    """``(nv,)`` each qvel entry's largest speed: ``value``, or the model's
    (:attr:`poekin.Tree.joint_velocity_limits` on hinge and slide entries, none on ball and
    free ones)."""
    nv = tree.nv
    if value is None:  # the model's, kept with the tree (read-only: callers take new arrays)
        out = tree._ik_cache.get("velocity_limits")
        if out is None:
            out = np.full(nv, np.inf)
            for k, (kind, mimic) in enumerate(zip(tree.joint_types, tree.mimics, strict=True)):
                if mimic is None and kind in ("revolute", "prismatic"):
                    out[tree._dof_adr[k]] = tree.joint_velocity_limits[k]
            out.flags.writeable = False
            tree._ik_cache["velocity_limits"] = out
        model: FloatArray = out
        return model
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape not in ((), (nv,)) or np.any(np.isnan(arr)) or np.any(arr <= 0):
        raise InputError(
            f"velocity_limits must be one number > 0 or {nv} of them (rad/s or m/s, one per "
            f"qvel entry; inf for none), got shape {arr.shape}"
        )
    limits: FloatArray = np.broadcast_to(arr, (nv,)).copy()
    return limits


class StepProblem(NamedTuple):
    """One tick's problem, as :meth:`poekin.Tree.ik_step` poses it, for ``B`` environments
    and the ``n`` variables of ``variables``: ``min |C x - d|^2 + damping |x|^2`` with ``A x =
    0`` and ``lo <= x <= hi`` (``x = qvel dt``; ``d`` already times the gain), then the
    posture's move ``posture`` ``(B, n)`` (None: no posture) with ``posture_weights`` in what
    redundancy is left. ``A (B, mh, n)``, ``C (B, ms, n)``, ``d (B, ms)``, ``lo, hi (B, n)``."""

    A: FloatArray
    C: FloatArray
    d: FloatArray
    lo: FloatArray
    hi: FloatArray
    damping: float
    posture: FloatArray | None
    posture_weights: FloatArray
    variables: NDArray[np.intp]  # each variable's qvel entry
    batch: tuple[int, ...]
    nv: int
    dt: float


def step_problem(
    tree: Tree,
    targets: Mapping[str, ArrayLike],
    qpos: ArrayLike,
    dt: float,
    *,
    hold: object = None,
    position_only: object = None,
    orientation_only: object = None,
    weights: Mapping[str, float] | None = None,
    posture: float | ArrayLike = 0.0,
    velocity_limits: ArrayLike | None = None,
    gain: float = 1.0,
    damping: float = 1e-12,
    orientation_weight: float = 0.3,
    freeze: Collection[str] = (),
) -> StepProblem:
    """:meth:`poekin.Tree.ik_step`'s validated problem (its arguments), before it is solved
    (:func:`solve_step`): what a general QP solver takes to solve the same tick
    (``benchmarks/bench_wholebody.py`` gives it to daqp)."""
    dt = positive_number(dt, "dt", "s", zero=False)
    gain = positive_number(gain, "gain", "1/step", zero=True)
    damping = positive_number(damping, "damping", "m^2", zero=True)
    tasks = parse(
        tree,
        targets,
        hold=hold,
        position_only=position_only,
        orientation_only=orientation_only,
        weights=weights,
    )
    options = settings(orientation_weight=orientation_weight)
    problem, q, batch = _problem(
        tree, tasks, qpos, posture, freeze, options, 0, clip=False, starts=False
    )
    sp = problem.space
    limits = model_velocity_limits(velocity_limits, tree)[sp.variables] * dt
    A, _, C, d, _ = problem.residual(q)
    lo, hi = sp.step_bounds(q, limits)
    posture_step = None
    if np.any(problem.posture):
        reference = np.broadcast_to(tree.qpos0, q.shape)
        posture_step = sp.difference(q, reference)
    return StepProblem(
        A,
        C,
        gain * d,
        lo,
        hi,
        damping,
        posture_step,
        problem.posture,
        np.asarray(sp.variables, dtype=np.intp),
        tuple(batch),
        tree.nv,
        dt,
    )


def solve_step(p: StepProblem) -> FloatArray:
    """:meth:`poekin.Tree.ik_step`'s answer, ``qvel (*batch, nv)``: the :func:`step_problem`
    ``p`` solved by :func:`poekin.wholebody.qp.step`."""
    B = p.A.shape[0]
    with one_thread():  # small SVDs: a thread pool only waits (poekin._blas)
        x = qp.step(
            p.A,
            np.zeros(p.A.shape[:2]),
            p.C,
            p.d,
            p.lo,
            p.hi,
            np.full(B, FLOOR),
            np.full(B, p.damping + FLOOR),
            p.posture,
            p.posture_weights,
        ).x
    qvel = np.zeros((B, p.nv))  # zero where no variable is (frozen joints, mimic followers)
    qvel[:, p.variables] = x / p.dt
    return qvel.reshape(*p.batch, p.nv)
