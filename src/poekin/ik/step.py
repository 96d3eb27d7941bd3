"""A chain's differential IK step for control loops: :meth:`poekin.Chain.ik_step`.

One control tick: the joint velocity ``qvel = x / dt`` whose step ``x`` solves the box-constrained
damped least squares

    minimize ``|J x - gain r|^2 + lam |x|^2``  subject to  ``lo <= x <= hi``,

with ``r`` and ``J`` the residual and its Jacobian of :mod:`poekin.ik.numerical` (steps 1 and 2:
the same rows, ``[k e_o; e_p]``, the same orientation weight ``k``), ``lam`` the damping, and the
box ``lo_j = clamp(lower_j - q_j, -v_j dt, v_j dt)``, ``hi_j = clamp(upper_j - q_j, -v_j dt, v_j
dt)``: every joint within its limits at ``q + x`` and within its velocity limit ``v_j``. (A
joint that starts outside its limits moves back toward them, at most at its velocity limit: the
box is then on one side of zero.) It is the problem mink's ``solve_ik`` poses as a general QP
for one frame task, a ``ConfigurationLimit`` of gain 1 and a ``VelocityLimit``
(``tests/ik/test_ik_step.py`` checks the two against each other), and :meth:`poekin.Tree.ik_step`
poses for a tree (by a null-space method with SVDs, which also takes held frames and posture).

**The active set** (the primal method for bounds, Nocedal and Wright's algorithm 16.3). The
first round solves the problem with every joint free but those whose bounds meet (the damped
normal equations, :func:`~poekin.ik.numerical.damped_step`'s systems) and clamps the answer
into the box; each joint the box cut is fixed at its bound (a feasible start with its working
set; none cut: the step is done). Each further round

* solves the problem for the free joints with the fixed ones at their bounds (the ``n x n``
  system: ``J^T J`` and ``J^T b`` are formed once per step, each round takes their free rows
  and columns; or, for a chain whose free joints outnumber the residual's rows, the dual
  ``m x m`` form, each well conditioned where it is used) and moves toward that answer as far
  as the box allows, fixing the joint that stops it;
* where the move reached that answer, releases the fixed joint whose multiplier has the wrong
  sign there (the cost falls if it leaves its bound), or stops when there is none (the KKT
  conditions hold: the step is optimal).

Every round keeps ``x`` inside the box, so a step cut short by :func:`max_rounds` is still
within every limit. The rounds run in lock-step over the batch with masks, with the array
library's namespace ``xp`` (entries, as :mod:`poekin.ik.numerical`), until every step is done
(NumPy, PyTorch, and JAX's ``jax.lax.while_loop``) or :func:`max_rounds`; a finished step
keeps its bits, so each step's answer depends on its own numbers only. Under JAX and PyTorch
the step is differentiable with respect to the target and ``q`` for the active set it ends
with.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose, arrays
from poekin._poe import as_joint_values, chain_terms, pose_of
from poekin.errors import InputError
from poekin.ik import fixed
from poekin.ik.numerical import (
    Settings,
    _cholesky_solve,
    _ik_kernel,
    _kernel_options,
    broadcast_together,
    check_targets,
    damped_step_dual,
    evaluate,
    jacobian_rows,
    residual,
    settings,
)
from poekin.kernel import _sincos

if TYPE_CHECKING:
    from poekin.chain import Chain

__all__ = ["max_rounds", "positive_number", "step", "step_entries", "step_quick"]

FloatArray = NDArray[np.float64]
Entry = Any
Entries = list[Any]

FLOOR = 1e-18  # m^2: the damping's floor, which keeps the systems positive definite
COMPACT = 8  # JAX: the rounds run on the steps not done where at most 1 in this many is
RELEASE = 1e-12  # a multiplier below -RELEASE |J_j| |gain r| releases its joint (rounding)


def max_rounds(n: int) -> int:
    """The active set's rounds at most, for ``n`` joints: room for each joint to be fixed,
    released and fixed again, and two more to stop."""
    return 3 * n + 2


class _Round(NamedTuple):
    """The active set's state: the step ``x``, the fixed joints (each at its bound), and
    whether the step is done."""

    x: Entries
    fixed: Entries
    done: Entry


def step_entries(
    chain: Chain,
    q: Entries,
    target: _pose.Pose,
    bounds: tuple[Entries, Entries],
    gain: float,
    lam: float,
    s: Settings,
    xp: Any,
    trig: Any = _sincos.sincos,
    loop: Any = None,
    stop: Any = None,
) -> Entries:
    """The step ``x`` (entries, ``(...)`` each) from ``q`` toward ``target`` within ``bounds``
    (``lo``, ``hi`` entries, ``lo <= 0 <= hi`` where ``q`` is inside its limits).

    ``loop(rounds, body, state)`` runs the rounds (default: until every step is done, or
    :func:`max_rounds`, NumPy's). With ``stop`` (JAX's ``stop_gradient``, PyTorch's
    ``detach``) the rounds run on values cut from differentiation, and a step that is done is
    solved once more, differentiably, for the active set they ended with: its derivative is
    the one at that active set (a step cut short by the rounds keeps the rounds' value, with
    none)."""
    pose, columns = evaluate(chain, q, xp, None, trig)
    r, _, _, _, quat = residual(pose, target, s, xp)
    J = jacobian_rows(columns, quat, s)
    b = [gain * rk for rk in r]
    H, g = _gram(J, b, xp)
    lo, hi = bounds
    if stop is None:
        return _rounds(J, b, H, g, lo, hi, lam, xp, loop).x
    cut = [[stop(v) for v in row] for row in J], [stop(v) for v in b]
    gram_cut = [[stop(v) for v in row] for row in H], [stop(v) for v in g]
    lo_cut, hi_cut = [stop(v) for v in lo], [stop(v) for v in hi]
    state = _rounds(*cut, *gram_cut, lo_cut, hi_cut, lam, xp, loop)
    at = [
        xp.where(f, xp.where(x <= lc, lj, hj), 0.0 * lj)
        for f, x, lc, lj, hj in zip(state.fixed, state.x, lo_cut, lo, hi, strict=True)
    ]
    live = _solve_free(*_dual_rows(J, b), H, g, lam, at, state.fixed, xp)
    return [xp.where(state.done, u, stop(x)) for u, x in zip(live, state.x, strict=True)]


def _gram(J: list[Entries], b: Entries, xp: Any) -> tuple[list[Entries], Entries]:
    """``J^T J`` (``n x n`` entries, both triangles, each entry once: ``H[i][j]`` is
    ``H[j][i]``) and ``J^T b`` (``n``), which every round's system and multipliers read."""
    n, m = len(J[0]), len(J)
    cols = [[J[k][i] for k in range(m)] for i in range(n)]
    pairs = [(i, j) for i in range(n) for j in range(i + 1)]
    # under JAX each entry computed once (_pose.settle), not again in every round's
    once = _pose.settle([_dot(cols[i], cols[j]) for i, j in pairs] + [_dot(c, b) for c in cols], xp)
    H: list[Entries] = [[None] * n for _ in range(n)]
    for (i, j), v in zip(pairs, once, strict=False):
        H[i][j] = H[j][i] = v
    return H, once[len(pairs) :]


def _dual_rows(J: list[Entries], b: Entries) -> tuple[list[Entries], Entries]:
    """The rows ``J``, ``b`` where the joints outnumber them (the dual form can then be
    needed), else none."""
    return (J, b) if len(J[0]) > len(J) else ([], [])


class _Data(NamedTuple):
    """What the rounds read, entries of the batch's shape: the rows where the dual form can be
    needed (:func:`_dual_rows`), their :func:`_gram`, the box, the joints whose bounds meet,
    and each joint's multiplier scale ``|J_j| |b|`` (1 where it is 0)."""

    J: list[Entries]
    b: Entries
    H: list[Entries]
    g: Entries
    lo: Entries
    hi: Entries
    pinned: Entries
    scale: Entries


def _solve_free(
    J: list[Entries],
    b: Entries,
    H: list[Entries],
    g: Entries,
    lam: float,
    x: Entries,
    fx: Entries,
    xp: Any,
) -> Entries:
    """The free joints' optimum with the fixed ones (``fx``) at ``x`` (entries, ``n``), from
    the :func:`_gram` ``H``, ``g`` of the rows: the primal system is ``H``'s free rows and
    columns with ``lam`` added, and ``g_i - sum_j H_ij x_j`` over the fixed ``j`` (the free
    part of ``J^T (b - J x_fixed)``). The rows ``J``, ``b`` themselves where the joints
    outnumber them (:func:`_dual_rows`; else empty): the dual form where the free ones do."""
    n, m = len(x), len(J)
    A = [
        [xp.where(fx[i] | fx[j], 0.0, H[i][j]) for j in range(i)] + [xp.where(fx[i], 0.0, H[i][i])]
        for i in range(n)
    ]
    for i in range(n):
        A[i][i] = A[i][i] + lam
    at = [xp.where(f, xj, 0.0) for f, xj in zip(fx, x, strict=True)]
    rhs = [xp.where(fx[i], 0.0, g[i] - _dot(H[i], at)) for i in range(n)]
    d = _cholesky_solve(A, rhs, FLOOR, xp)
    if m:  # more free joints than rows: the dual form where they are
        J_free = [[xp.where(f, 0.0, v) for f, v in zip(fx, row, strict=True)] for row in J]
        b_free = [bk - _dot(row, at) for bk, row in zip(b, J, strict=True)]
        free = _count([~f for f in fx], xp)
        dual = damped_step_dual(J_free, b_free, lam, FLOOR, xp)
        d = [xp.where(free > m, u, v) for u, v in zip(dual, d, strict=True)]
    return [xp.where(f, xj, dj) for f, xj, dj in zip(fx, x, d, strict=True)]


def _rounds(
    J: list[Entries],
    b: Entries,
    H: list[Entries],
    g: Entries,
    lo: Entries,
    hi: Entries,
    lam: float,
    xp: Any,
    loop: Any,
) -> _Round:
    """The active set's rounds (the module's docstring) on the rows ``J``, ``b`` (their
    :func:`_gram` ``H``, ``g``) in the box ``lo``, ``hi``: the last state."""
    n = len(lo)
    zero = xp.zeros_like(lo[0])
    size_b = xp.sqrt(_sum_squares(b))
    scale = [xp.sqrt(H[j][j]) * size_b for j in range(n)]
    # a joint whose bounds meet cannot move: fixed from the start, and never released
    pinned = [lo[j] >= hi[j] for j in range(n)]
    data = _Data(*_dual_rows(J, b), H, g, lo, hi, pinned, [xp.where(s > 0, s, 1.0) for s in scale])
    # the first round: the free joints' optimum, clamped into the box, each joint the box
    # cut fixed at its bound (done where none was)
    inside = [xp.minimum(xp.maximum(zero, lo[j]), hi[j]) for j in range(n)]
    first = _solve_free(data.J, data.b, H, g, lam, inside, pinned, xp)
    x0 = [xp.minimum(xp.maximum(t, lo[j]), hi[j]) for j, t in enumerate(first)]
    cut = [~pin & (v != t) for pin, v, t in zip(pinned, x0, first, strict=True)]
    start = _Round(
        x=x0, fixed=[pin | c for pin, c in zip(pinned, cut, strict=True)], done=~_any(cut)
    )

    def body(state: _Round, data: _Data) -> _Round:
        x, fx = state.x, state.fixed
        lo, hi, H, g = data.lo, data.hi, data.H, data.g
        never = state.done & ~state.done  # False, of the batch's shape
        # (1) toward the free joints' optimum, as far as the box allows
        target_x = _solve_free(data.J, data.b, H, g, lam, x, fx, xp)
        p = [t - xj for t, xj in zip(target_x, x, strict=True)]
        alpha = xp.ones_like(x[0])
        block = [never] * n
        for j in range(n):
            room = xp.where(p[j] < 0.0, lo[j] - x[j], hi[j] - x[j])
            moving = (~fx[j]) & (p[j] != 0.0)
            ratio = xp.where(moving, room / xp.where(moving, p[j], 1.0), 2.0)
            first = ratio < alpha  # the first joint that stops the move
            block = [first if k == j else bk & ~first for k, bk in enumerate(block)]
            alpha = xp.where(first, ratio, alpha)
        full = alpha >= 1.0
        moved = [
            xp.where(
                full,
                t,
                xp.where(block[j], xp.where(p[j] < 0.0, lo[j], hi[j]), x[j] + alpha * p[j]),
            )
            for j, t in enumerate(target_x)
        ]
        moved = [xp.minimum(xp.maximum(v, lo[j]), hi[j]) for j, v in enumerate(moved)]
        fixed_moved = [f | (bk & ~full) for f, bk in zip(fx, block, strict=True)]
        # (2) where the move reached the optimum: the multipliers of the fixed joints there,
        # the most negative released
        worst = -RELEASE * xp.ones_like(x[0])
        release = [never] * n
        for j in range(n):
            grad = (_dot(H[j], moved) - g[j]) + lam * moved[j]  # J^T (J x - b) + lam x
            mu = xp.where(moved[j] <= lo[j], grad, -grad) / data.scale[j]
            candidate = fixed_moved[j] & ~data.pinned[j] & (mu < worst)
            release = [candidate if k == j else rk & ~candidate for k, rk in enumerate(release)]
            worst = xp.where(candidate, mu, worst)
        new_fixed = [fm & ~(full & rl) for fm, rl in zip(fixed_moved, release, strict=True)]
        new_done = full & ~_any(release)
        keep = state.done
        return _Round(
            x=[xp.where(keep, a, c) for a, c in zip(x, moved, strict=True)],
            fixed=[xp.where(keep, a, c) for a, c in zip(fx, new_fixed, strict=True)],
            done=keep | new_done,
        )

    rounds = max_rounds(n)
    if loop is None:
        state = start
        for _ in range(rounds):
            if bool(np.all(state.done)):
                break
            state = body(state, data)
    else:
        state = loop(rounds, body, start, data)
    return state


def _sum_squares(v: Sequence[Entry]) -> Entry:
    total = v[0] * v[0]
    for x in v[1:]:
        total = total + x * x
    return total


def _dot(a: Sequence[Entry], b: Sequence[Entry]) -> Entry:
    total = a[0] * b[0]
    for x, y in zip(a[1:], b[1:], strict=True):
        total = total + x * y
    return total


def _any(v: Sequence[Entry]) -> Entry:
    out = v[0]
    for x in v[1:]:
        out = out | x
    return out


def _count(v: Sequence[Entry], xp: Any) -> Entry:
    total = xp.where(v[0], 1, 0)
    for x in v[1:]:
        total = total + xp.where(x, 1, 0)
    return total


def positive_number(value: object, name: str, unit: str, *, zero: bool) -> float:
    """``value`` as a float, a finite number ``> 0`` (``>= 0`` with ``zero``), else an
    :class:`InputError` that names it and its ``unit``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InputError(f"{name} must be a number ({unit}), got {value!r:.40}")
    x = float(value)
    if not (math.isfinite(x) and (x >= 0 if zero else x > 0)):
        raise InputError(
            f"{name} must be a finite number {'>= 0' if zero else '> 0'} ({unit}), got {x!r}"
        )
    return x


def _velocity_limits(value: ArrayLike | None, n: int) -> tuple[float, ...]:
    if value is None:
        return (math.inf,) * n
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape not in ((), (n,)) or np.any(np.isnan(arr)) or np.any(arr <= 0):
        raise InputError(
            f"velocity_limits must be one number > 0 or {n} of them (rad/s or m/s, one per "
            f"joint; inf for none), got {np.array2string(arr, threshold=8)}"
        )
    return tuple(float(v) for v in np.broadcast_to(arr, (n,)))


def step(
    chain: Chain,
    T: Any,
    q: Any,
    dt: float,
    *,
    velocity_limits: ArrayLike | None,
    gain: float,
    damping: float,
    s: Settings,
) -> Any:
    """:meth:`poekin.Chain.ik_step` (its docstring holds the arguments): ``(..., n)`` joint
    velocities, NumPy arrays, or the JAX arrays or PyTorch tensors given."""
    dt = positive_number(dt, "dt", "s", zero=False)
    gain = positive_number(gain, "gain", "1/step", zero=True)
    lam = positive_number(damping, "damping", "m^2", zero=True) + FLOOR
    n = chain.n_joints
    if n == 0:
        raise InputError("the chain has no joints: there is nothing to move")
    vmax = _velocity_limits(velocity_limits, n)
    xp, kind = arrays.namespace_of([T, q], "targets and q")
    if kind is None:
        T_arr, q_arr = broadcast_together(
            check_targets(T), as_joint_values(q, n, what="q values"), "q"
        )
        terms, trig, loop, stop = chain_terms(chain), _sincos.sincos, None, None
    else:
        T_arr, q_arr, single = fixed.as_arrays(T, q, n, kind)
        terms, trig = chain_terms(chain, single), _pose.sincos
        loop, stop = _loop(kind)
    reach = [v * dt for v in vmax]
    if kind is None and (kernel := _ik_kernel(chain)) is not None:
        options = _kernel_options(chain, s)
        x = kernel.step(
            T_arr, q_arr, np.array(reach), options, gain, lam, -RELEASE, max_rounds(n), True
        )
        if x is not None:  # the compiled twin (a chain of at most 16 joints)
            return x / dt
    q_e = [q_arr[..., j] for j in range(n)]
    lo, hi = [], []
    for j, (lower, upper) in enumerate(terms.bounds):
        lo.append(xp.minimum(xp.maximum(lower - q_e[j], -reach[j]), reach[j]))
        hi.append(xp.minimum(xp.maximum(upper - q_e[j], -reach[j]), reach[j]))
    x_e = step_entries(chain, q_e, pose_of(T_arr), (lo, hi), gain, lam, s, xp, trig, loop, stop)
    return xp.stack(x_e, axis=-1) / dt


def step_quick(
    chain: Chain,
    T: FloatArray,
    q: FloatArray,
    dt: float,
    velocity_limits: Any,
    gain: float,
    damping: float,
    position_only: bool,
    orientation_weight: float,
) -> FloatArray | None:
    """:func:`step` for NumPy arrays, as it runs them, with less around the kernel: the
    options validated and turned into the kernel's once per chain and values
    (:func:`_quick_options`), the kernel taking the arrays as they are. None where that does
    not serve (no kernel, an unhashable option, arguments the kernel leaves to the
    validation): the caller then runs :func:`step`, which says what is wrong."""
    kernel = _ik_kernel(chain)
    if kernel is None:
        return None
    try:
        options = _quick_options(
            chain, dt, velocity_limits, gain, damping, position_only, orientation_weight
        )
    except (TypeError, InputError):  # unhashable or bad: step says what is wrong
        return None
    reach, kernel_options, lam, rounds = options
    x = kernel.step(T, q, reach, kernel_options, gain, lam, -RELEASE, rounds, False)
    if x is None:
        return None
    out: FloatArray = x / dt
    return out


@functools.lru_cache(maxsize=64, typed=True)
def _quick_options(
    chain: Chain,
    dt: float,
    velocity_limits: Any,
    gain: float,
    damping: float,
    position_only: bool,
    orientation_weight: float,
) -> tuple[FloatArray, tuple[float, ...], float, int]:
    """The kernel's arguments of :func:`step_quick` for these options, validated: each
    joint's reach ``v dt`` (read-only), the kernel's options, the damping and the rounds."""
    dt = positive_number(dt, "dt", "s", zero=False)
    positive_number(gain, "gain", "1/step", zero=True)
    lam = positive_number(damping, "damping", "m^2", zero=True) + FLOOR
    s = settings(position_only=position_only, orientation_weight=orientation_weight)
    reach = np.array([v * dt for v in _velocity_limits(velocity_limits, chain.n_joints)])
    reach.flags.writeable = False
    return reach, _kernel_options(chain, s), lam, max_rounds(chain.n_joints)


def _loop(kind: str) -> tuple[Any, Any]:
    """The rounds and the cut from differentiation under JAX (:func:`_jax_rounds`;
    ``stop_gradient``) and PyTorch (until every step of the batch is done or
    :func:`max_rounds`, in Python; ``detach``)."""
    if kind == "jax":
        import jax

        return _jax_rounds, jax.lax.stop_gradient

    def run_torch(rounds: int, body: Any, state: Any, data: Any) -> Any:
        import torch

        for _ in range(rounds):
            if bool(torch.all(state.done)):
                break
            state = body(state, data)
        return state

    return run_torch, lambda x: x.detach()


def _jax_rounds(rounds: int, body: Any, state: _Round, data: _Data) -> _Round:
    """The rounds under JAX: ``jax.lax.while_loop``, until every step is done or
    :func:`max_rounds`. In a batch of ``B >= 2 COMPACT`` steps, once at most ``B / COMPACT``
    (rounded up) are not done, the rounds go on with those steps alone, gathered and scattered
    back: the lock-step rounds of a tick's few hard steps then cost that fraction of the
    batch's (each step's numbers are its own: the same answer)."""
    import jax
    import jax.numpy as jnp

    def run(carry: tuple[Any, _Round], dt: _Data, until: Any) -> tuple[Any, _Round]:
        def more(c: tuple[Any, _Round]) -> Any:
            return (c[0] < rounds) & ~until(c[1].done)

        def once(c: tuple[Any, _Round]) -> tuple[Any, _Round]:
            return c[0] + 1, body(c[1], dt)

        return jax.lax.while_loop(more, once, carry)  # type: ignore[no-any-return]

    shape = jnp.shape(state.done)
    size = math.prod(shape)
    room = -(-size // COMPACT)
    if 2 * room > size:
        return run((0, state), data, jnp.all)[1]
    k, state = run((0, state), data, lambda done: jnp.sum(~done) <= room)

    def flat(v: Any) -> Any:
        return jnp.broadcast_to(v, shape).reshape(size)

    at = jnp.nonzero(~flat(state.done), size=room, fill_value=size)[0]  # filled past the end

    def take(v: Any) -> Any:  # a filled slot: done, every joint fixed, zeros
        return flat(v).at[at].get(mode="fill", fill_value=v.dtype == jnp.bool_)

    _, few = run((k, jax.tree.map(take, state)), jax.tree.map(take, data), jnp.all)
    return jax.tree.map(  # type: ignore[no-any-return]
        lambda v, u: flat(v).at[at].set(u, mode="drop").reshape(shape), state, few
    )
