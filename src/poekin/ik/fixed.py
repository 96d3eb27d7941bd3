"""Inverse kinematics of JAX arrays and PyTorch tensors: a solve that traces (``jax.jit``,
``jax.vmap``, ``shard_map``; ``torch.compile`` runs it eagerly), and the solution's derivative
by the implicit function theorem.

**The solve** is :mod:`poekin.ik.numerical`'s algorithm and loop: its lanes
(:func:`~poekin.ik.numerical.advance`, one iteration of every lane's attempt, from the
per-iteration functions :func:`~poekin.ik.numerical.evaluate`,
:func:`~poekin.ik.numerical.residual`, :func:`~poekin.ik.numerical.jacobian_rows` and
:func:`~poekin.ik.numerical.step`) and its random starts (:mod:`poekin.ik._rng`, the same
counter-based numbers as NumPy's). A lane runs one target's attempts one after another, attempt
0 from ``q0`` if given, attempt ``a`` otherwise from the NumPy solve's ``a``-th random start,
by the NumPy solve's rules (an attempt ends when it converges, stalls or reaches
``max_iterations``), and the target is finished when an attempt converged, ``max_attempts``
are spent, or its attempts together have run ``max_total_iterations`` (the budget). Its answer
is the converged iterate, else the least-cost iterate of all its attempts.

* PyTorch runs :func:`~poekin.ik.numerical.run_lanes`, the NumPy solve's own loop: finished
  targets leave the lanes;
* JAX runs :func:`_refill`: a fixed number of lanes (:func:`slots`) in one
  ``jax.lax.while_loop``, a lane whose target is finished writing its answer and taking the
  next target (masks, never a branch on values). Under ``jax.vmap`` the whole batch is one call
  (``jax.custom_batching.custom_vmap``), so its targets share the lanes.

So where the NumPy solve needs no more than the budget, this solve gives its answer (the same
attempts, iterations and success; ``q`` to rounding: XLA contracts multiply-adds on the CPU and
PyTorch's vectorised ``sqrt`` is not correctly rounded, so the bits may differ, and under XLA
they may differ with the batch size). Where it needs more, this solve fails at the budget
(``success`` False, the best fit so far). ``success`` means what it means for NumPy: the pose
within the tolerances by the final errors and ``q`` within the limits.

**The derivative** of ``q`` with respect to the targets and the model's parameters comes from
the implicit function theorem at the answer ``q*``, never from the iterations (they run on
values cut from the graph: ``jax.lax.stop_gradient``, ``detach``). The residual
``r(q, T, params)`` (the solver's: ``[k e_o; e_p]``) is zero at a solution, so
``dq = J^+ (dr/dT dT + dr/dparams dparams)`` with ``J = -dr/dq`` the solver's Jacobian
(:func:`~poekin.ik.numerical.jacobian_rows`) and ``J^+ = (J^T J + lam I)^-1 J^T`` (in its dual
form ``J^T (J J^T + lam I)^-1`` for a redundant arm: the minimum-norm ``dq``), ``lam`` the
solver's damping floor ``1e-18 L^2``. A joint held at a limit (``q*`` equal to it) is out of
``J``: its derivative is zero and the others move without it. JAX gets it as a ``custom_jvp``
(forward and reverse mode, ``jit``, ``vmap``), PyTorch as an ``autograd.Function`` (backward).
Where ``success`` is False it is the same formula at the best fit (Gauss-Newton's
linearisation, not the derivative of a minimiser). ``q0`` has no derivative.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sys
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from typing import TYPE_CHECKING, Any

import numpy as np

from poekin import _pose, arrays
from poekin._poe import ChainParams, ChainTerms, _Model, chain_terms, check_shape, poe, pose_of
from poekin.errors import InputError
from poekin.ik import _rng
from poekin.ik.numerical import (
    Entries,
    IKResult,
    Lanes,
    Settings,
    advance,
    aimed,
    check_seed,
    damped_step,
    damping_floor,
    errors,
    evaluate,
    first_start_entries,
    jacobian_rows,
    residual,
    run_lanes,
    settings,
    start_entries,
)

if TYPE_CHECKING:
    from poekin.chain import Chain

__all__ = ["DEFAULT_BUDGET", "array_kind", "solve_arrays"]

# Iterations per target when the caller names no budget: the NumPy solve needs at most this many
# for 99.94% (Sawyer, Lite6) to 99.99% (UR5e, UR10e, FR3) of random targets within the limits
# of every shared arm (20,000 targets each, random starts of seed 0; 200 would leave
# the Lite6 at 99.905%, the protocol's floor being 99.9%)
DEFAULT_BUDGET = 256


def array_kind(T: Any, q0: Any, params: Any) -> arrays.Kind | None:
    """``"jax"`` or ``"torch"`` if the targets, ``q0`` or ``params``' leaves hold a JAX array
    or a PyTorch tensor (this module's solve), None for NumPy; :class:`InputError` if they
    mix the two."""
    leaves = tuple(params) if isinstance(params, ChainParams) else ()
    _, kind = arrays.namespace_of([T, q0, *leaves], "targets, q0 and params")
    return kind


def solve_arrays(
    chain: Chain,
    T: Any,
    q0: Any,
    kind: arrays.Kind,
    *,
    seed: int,
    params: ChainParams | None,
    **options: Any,
) -> IKResult:
    """:meth:`poekin.Chain.ik` for JAX arrays and PyTorch tensors (``kind``): the
    fixed-shape solve, its result in the caller's library, float dtype and device, ``q``
    differentiable with respect to ``T`` and ``params`` (see the module); ``options`` as
    :func:`poekin.ik.numerical.settings` takes them.

    Under torch.compile the solve runs eagerly (``torch.compiler.disable``: a graph break):
    Inductor takes minutes over its unrolled iterations and compiles the random starts'
    wrapping 64-bit products as C++'s undefined signed overflow."""
    solve: Any = _solve_arrays
    if kind == "torch":
        import torch

        disable: Any = torch.compiler.disable
        solve = disable(_solve_arrays)
    found: IKResult = solve(chain, T, q0, kind, seed, params, options)
    return found


def _solve_arrays(
    chain: Chain,
    T: Any,
    q0: Any,
    kind: arrays.Kind,
    seed: int,
    params: ChainParams | None,
    options: dict[str, Any],
) -> IKResult:
    s = settings(**options)
    seed = check_seed(seed)
    if chain.n_joints == 0:
        raise InputError("the chain has no joints: there is nothing to solve for")
    if params is not None and not isinstance(params, ChainParams):
        got = type(params).__name__
        raise InputError(f"params must be a ChainParams (see chain.parameters()), got {got}")
    leaves = () if params is None else tuple(params)
    xp = arrays.namespace(kind)
    dtype, T, q0 = _converted(xp, T, q0, leaves, "q0")
    check_shape(T, (4, 4), "targets")
    n = chain.n_joints
    shapes = [tuple(T.shape[:-2])]
    if q0 is not None:
        check_shape(q0, (n,), "q0")
        shapes.append(tuple(q0.shape[:-1]))
    if params is not None:
        shapes += [tuple(np.shape(params.screws)[:-2]), tuple(np.shape(params.home)[:-2])]
    try:
        batch = np.broadcast_shapes(*shapes)
    except ValueError:
        raise InputError(
            f"the batch axes of targets {tuple(T.shape)}"
            + (f", q0 {tuple(q0.shape)}" if q0 is not None else "")
            + (" and params" if params is not None else "")
            + " do not broadcast together"
        ) from None
    backend = _Backend(kind)
    T = xp.broadcast_to(T, (*batch, 4, 4))
    if q0 is not None:
        q0 = xp.broadcast_to(q0, (*batch, n))
    fixed = backend.stop(T), backend.stop(q0), backend.stop(params)
    model = None if params is None else chain._model(xp, fixed[0], fixed[2], body=False)
    problem = _Problem(chain, chain_terms(chain, dtype == xp.float32), s, xp, model)
    out = _solve(problem, backend, fixed[0], fixed[1], fixed[2], seed)
    q_star = out[0]
    if backend.differentiable(T, leaves):
        q_star = backend.implicit(problem, q_star, T, params)
    if kind == "jax":
        _register_result_pytree()
    return IKResult(q_star, *out[1:])


def _converted(xp: Any, T: Any, q: Any, leaves: Sequence[Any], name: str) -> tuple[Any, Any, Any]:
    """The float dtype of targets ``T``, joint values ``q`` (``name``; or None) and other
    arrays ``leaves``, and ``T`` and ``q`` converted to it, in ``xp``'s arrays on the device of
    the first of them that is one."""
    given = [x for x in (T, q, *leaves) if x is not None]
    anchor = next(x for x in given if arrays.kind_of(x) is not None)
    try:
        dtype = arrays.float_dtype(xp, given)
        T = arrays.convert(T, xp, dtype, anchor)
        q = None if q is None else arrays.convert(q, xp, dtype, anchor)
    except (TypeError, ValueError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(f"targets and {name} must be arrays of numbers: {e}") from e
    if dtype not in (xp.float32, xp.float64):
        raise InputError(f"IK computes in float32 or float64, got {dtype}; cast the inputs")
    return dtype, T, q


def as_arrays(T: Any, q: Any, n: int, kind: arrays.Kind) -> tuple[Any, Any, bool]:
    """Targets ``(..., 4, 4)`` and joint values ``(..., n)`` of a JAX or PyTorch call
    (:meth:`poekin.Chain.ik_step`) in one float dtype, broadcast to one batch shape, and
    whether that dtype is float32 (values are not checked: they may be traced)."""
    xp = arrays.namespace(kind)
    dtype, T, q = _converted(xp, T, q, (), "q")
    check_shape(T, (4, 4), "targets")
    check_shape(q, (n,), "q")
    try:
        batch = np.broadcast_shapes(tuple(T.shape[:-2]), tuple(q.shape[:-1]))
    except ValueError:
        raise InputError(
            f"the batch axes of targets {tuple(T.shape)} and q {tuple(q.shape)} do not "
            "broadcast together"
        ) from None
    return xp.broadcast_to(T, (*batch, 4, 4)), xp.broadcast_to(q, (*batch, n)), dtype == xp.float32


# --- what the solve needs ---------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _Problem:
    """A chain's solve in one library and dtype: its constants, the options, the namespace and
    the model (None: the chain's own constants)."""

    chain: Chain
    terms: ChainTerms
    s: Settings
    xp: Any
    model: _Model | None

    def evaluate(self, q: Entries, model: _Model | None = None) -> tuple[_pose.Pose, Any]:
        """``T(q)`` and the world Jacobian's columns, with the library's own sine and cosine
        (a twelfth of the operations of the kernel's, :mod:`poekin.kernel._sincos`, under XLA)."""
        model = self.model if model is None else model
        return evaluate(self.chain, q, self.xp, model, _pose.sincos)


# --- the libraries' few differences -----------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class _Backend:
    """What JAX and PyTorch do differently: cutting values from the graph, 64-bit integers for
    the random starts, and the implicit derivative's hook (the loops: :func:`_core`)."""

    kind: str

    @property
    def jax(self) -> Any:
        return sys.modules["jax"]

    def stop(self, x: Any) -> Any:
        """``x`` (an array, a :class:`ChainParams` or None) cut from differentiation."""
        if x is None:
            return None
        if isinstance(x, ChainParams):
            return ChainParams(*(self.stop(a) for a in x))
        if arrays.kind_of(x) is None:
            return x
        return self.jax.lax.stop_gradient(x) if self.kind == "jax" else x.detach()

    def wide(self) -> AbstractContextManager[Any]:
        """A context with 64-bit integers (JAX without ``jax_enable_x64``: switched on while
        the random starts are drawn)."""
        if self.kind != "jax":
            return nullcontext()
        switch = getattr(self.jax, "enable_x64", None)  # jax.experimental's before JAX 0.7
        if switch is None:
            switch = self.jax.experimental.enable_x64
            return switch()  # type: ignore[no-any-return]
        return switch(True)  # type: ignore[no-any-return]

    def differentiable(self, T: Any, leaves: Sequence[Any]) -> bool:
        """Whether a derivative may be asked for: always under JAX (tracing decides), for
        PyTorch if a tensor requires its gradient."""
        if self.kind == "jax":
            return True
        return any(getattr(x, "requires_grad", False) for x in (T, *leaves))

    def implicit(self, problem: _Problem, q_star: Any, T: Any, params: ChainParams | None) -> Any:
        """``q_star``, with the implicit function theorem's derivative with respect to ``T``
        and ``params``."""
        if self.kind == "jax":
            return _jax_implicit(problem, q_star, T, params)
        return _torch_implicit()(q_star, problem, T, *(() if params is None else params))


# --- the solve ---------------------------------------------------------------------------------


def _solve(
    problem: _Problem, backend: _Backend, T: Any, q0: Any, params: ChainParams | None, seed: int
) -> tuple[Any, ...]:
    """``q, success, pos_err, ori_err, iterations, attempts`` of ``(..., 4, 4)`` targets from
    ``(..., n)`` ``q0`` (or None) and ``params`` (or None), broadcast to one batch shape."""
    xp, s, terms = problem.xp, problem.s, problem.terms
    n = problem.chain.n_joints
    leaves = () if params is None else tuple(arrays.convert(x, xp, T.dtype, T) for x in params)
    integers = _integers(xp)  # the caller's default integers (int32 under JAX without x64)
    args = [T, *(() if q0 is None else (q0,)), *leaves]
    core = functools.partial(_core, problem, backend, q0 is not None, len(leaves), seed, integers)
    if backend.kind == "jax":
        q_out, conv, total, attempts = _batched(core)(*args)
    else:
        q_out, conv, total, attempts = core(*args)
    target = pose_of(T)
    model = problem.chain._constants if problem.model is None else problem.model
    pose = poe(model.screws, [q_out[..., j] for j in range(n)], xp, right=model.home)
    pos_err, ori_err = errors(pose, target, xp)
    success = conv & (pos_err <= s.pos_tol)
    for j, (lo, hi) in enumerate(terms.bounds):
        success = success & (q_out[..., j] >= lo) & (q_out[..., j] <= hi)
    if not s.position_only:
        success = success & (ori_err <= s.ori_tol)
    return q_out, success, pos_err, ori_err, total, attempts


def _integers(xp: Any) -> Any:
    return xp.__array_namespace_info__().default_dtypes()["integral"]


def _batched(core: Callable[..., Any]) -> Callable[..., Any]:
    """``core`` as a ``jax.custom_batching.custom_vmap`` function: under ``jax.vmap`` it is
    called once on the whole batch (its targets share the lanes of one loop), never traced
    per target."""
    jax = sys.modules["jax"]
    batched: Any = jax.custom_batching.custom_vmap(core)

    def rule(axis_size: int, in_batched: Sequence[bool], *args: Any) -> Any:
        del axis_size, in_batched  # core broadcasts its arguments' batch axes together
        return batched(*args), (True, True, True, True)

    batched.def_vmap(rule)
    return batched  # type: ignore[no-any-return]


def _core(
    problem: _Problem,
    backend: _Backend,
    given_q0: bool,
    n_leaves: int,
    seed: int,
    integers: Any,
    T: Any,
    *rest: Any,
) -> tuple[Any, Any, Any, Any]:
    """The solve's loop for targets ``T`` (``(..., 4, 4)``), ``q0`` if ``given_q0`` and the
    parameters' leaves (``rest``), broadcast together: ``q`` (the answer, ``(..., n)``),
    converged, iterations and attempts (``(...,)``)."""
    xp, s, terms, chain = problem.xp, problem.s, problem.terms, problem.chain
    n = chain.n_joints
    q0 = rest[0] if given_q0 else None
    leaves = rest[1:] if given_q0 else rest
    assert len(leaves) == n_leaves
    shapes = [tuple(T.shape[:-2])]
    if q0 is not None:
        shapes.append(tuple(q0.shape[:-1]))
    shapes += [tuple(leaf.shape[:-2]) for leaf in leaves]
    batch = np.broadcast_shapes(*shapes)
    N = math.prod(batch)
    flat_T = xp.reshape(xp.broadcast_to(T, (*batch, 4, 4)), (N, 4, 4))
    flat_q0 = None if q0 is None else xp.reshape(xp.broadcast_to(q0, (*batch, n)), (N, n))
    per_target = bool(leaves) and any(leaf.ndim > 2 for leaf in leaves)  # batched parameters
    rows = [
        xp.reshape(xp.broadcast_to(leaf, (*batch, *leaf.shape[-2:])), (N, *leaf.shape[-2:]))
        for leaf in (leaves if per_target else ())
    ]
    constant = None
    if leaves and not per_target:
        constant = chain._model(xp, flat_T, ChainParams(*leaves), body=False)
    dtype = T.dtype
    with backend.wide():
        keys = _rng.target_keys(seed, flat_T, flat_q0, xp)
        if flat_q0 is None:
            zero = xp.zeros_like(keys, dtype=_integers(xp))
            first = xp.astype(xp.stack(start_entries(terms, keys, zero, xp), axis=-1), dtype)
        else:
            entries = [flat_q0[:, j] for j in range(n)]
            first = xp.stack(first_start_entries(entries, terms, xp), axis=-1)

        def prepare(rows: list[Any]) -> tuple[_pose.Pose, Any, Any]:
            T_rows, key_rows, *param_rows = rows
            model = constant
            if param_rows:
                model = chain._model(xp, T_rows, ChainParams(*param_rows), body=False)

            def draw(attempt: Any) -> Any:
                drawn = xp.stack(start_entries(terms, key_rows, attempt, xp), axis=-1)
                return xp.astype(drawn, dtype)

            return aimed(pose_of(T_rows), xp), lambda q: problem.evaluate(q, model), draw

        inputs = [flat_T, keys, *rows]
        budget = s.max_total_iterations
        if backend.kind == "jax":
            out = _refill(first, inputs, prepare, terms, s, budget)
        else:
            out = run_lanes(first, inputs, prepare, terms, s, xp, budget)
        q_out, conv, total, attempts = out
        total, attempts = xp.astype(total, integers), xp.astype(attempts, integers)
    return (
        xp.reshape(q_out, (*batch, n)),
        xp.reshape(conv, batch),
        xp.reshape(total, batch),
        xp.reshape(attempts, batch),
    )


def slots(N: int) -> int:
    """Lanes of the JAX loop for ``N`` targets: about ``2 sqrt(N)``, a multiple of 8 (at most
    ``N``). The loop runs about ``N m / K + t`` iterations of ``K`` lanes (``m``: a target's
    mean iterations, ~15; ``t``: the longest target's, up to the budget), each costing a fixed
    ~15 us plus ~1.5 us a lane (measured on a busy 2-core Xeon): ``K`` near
    ``sqrt(N m c / (t c_lane))`` ~ ``sqrt(N)`` is cheapest, and ``2 sqrt(N)`` measured best
    for 100 to 10,000 UR5e and Panda targets."""
    return min(N, 8 * math.ceil(math.sqrt(N) / 4))


def _refill(
    first: Any,
    inputs: Sequence[Any],
    prepare: Callable[[list[Any]], Any],
    terms: Any,
    s: Settings,
    budget: int | None,
) -> tuple[Any, Any, Any, Any]:
    """:func:`~poekin.ik.numerical.run_lanes` with a fixed number of lanes (:func:`slots`), one
    ``jax.lax.while_loop``: a lane whose target is finished writes its answer and takes the
    next target of the batch, until every target is finished."""
    jax = sys.modules["jax"]
    jnp = jax.numpy
    N = first.shape[0]
    K = slots(N)
    # every value made from the inputs (zeros_like), so that under shard_map it varies over
    # the devices as the loop's results do
    zeros = jnp.zeros_like(first[:, 0], dtype=_integers(jnp))
    out = (jnp.zeros_like(first), zeros.astype(bool), zeros, zeros)
    if N == 0:
        return out
    lanes = Lanes.start(first[:K], jnp)
    state = (lanes, zeros[:K] + jnp.arange(K), zeros[0] + K, [x[:K] for x in inputs], out)

    def busy(state: Any) -> Any:
        return jnp.any(state[1] < N)

    def body(state: Any) -> Any:
        lanes, target, following, rows, out = state
        goal, evaluate, draw = prepare(rows)
        lanes, finished, conv, answer = advance(lanes, goal, evaluate, draw, terms, s, jnp, budget)
        finished = finished & (target < N)
        at = jnp.where(finished, target, N)  # N: dropped
        written = (answer, conv, lanes.total, lanes.attempt + 1)
        out = tuple(o.at[at].set(w, mode="drop") for o, w in zip(out, written, strict=True))
        ahead = following + jnp.cumsum(finished) - 1  # the next targets, in lane order
        take = finished & (ahead < N)
        target = jnp.where(finished, jnp.where(take, ahead, N), target)
        following = following + jnp.sum(finished)
        row = jnp.minimum(ahead, N - 1)
        fresh = Lanes.start(first[row], jnp)
        lanes = Lanes(*(_where_rows(take, a, b) for a, b in zip(fresh, lanes, strict=True)))
        rows = [_where_rows(take, x[row], y) for x, y in zip(inputs, rows, strict=True)]
        return lanes, target, following, rows, out

    return jax.lax.while_loop(busy, body, state)[-1]  # type: ignore[no-any-return]


def _where_rows(pick: Any, a: Any, b: Any) -> Any:
    """``a`` in the rows where ``(L,)`` ``pick``, else ``b``."""
    jnp = sys.modules["jax"].numpy
    return jnp.where(jnp.reshape(pick, (-1, *(1,) * (a.ndim - 1))), a, b)


# --- the implicit derivative ------------------------------------------------------------------


def _projector(problem: _Problem, q_star: Any, T: Any) -> list[Entries]:
    """The solver's Jacobian ``J`` (rows) at ``q_star`` for targets ``T`` (values only), its
    columns of joints held at a limit zeroed."""
    xp, terms = problem.xp, problem.terms
    q = [q_star[..., j] for j in range(problem.chain.n_joints)]
    pose, columns = problem.evaluate(q)
    _, _, _, _, quat = residual(pose, pose_of(T), problem.s, xp)
    lo, hi = [b[0] for b in terms.bounds], [b[1] for b in terms.bounds]
    held = [(x <= lo[j]) | (x >= hi[j]) for j, x in enumerate(q)]
    rows = jacobian_rows(columns, quat, problem.s)
    return [[xp.where(h, 0.0, x) for h, x in zip(held, row, strict=True)] for row in rows]


def _linearised(
    problem: _Problem, J: list[Entries], q_star: Any, T: Any, params: ChainParams | None
) -> Any:
    """``J^+ r(q_star, T, params)``: linear in the residual, whose derivative with respect to
    ``T`` and ``params`` (``q_star`` and ``J`` held) is the solution's, ``(..., n)``."""
    xp, chain = problem.xp, problem.chain
    model = None if params is None else chain._model(xp, T, params, body=False)
    q = [q_star[..., j] for j in range(chain.n_joints)]
    pose, _ = problem.evaluate(q, model)
    r = residual(pose, pose_of(T), problem.s, xp)[0]
    lam = damping_floor(problem.terms, problem.s)
    dq = damped_step(J, r, lam, lam, xp)
    return _pose.stack(dq, (chain.n_joints,), xp, xp.zeros_like(q_star[..., 0]))


def _jax_implicit(problem: _Problem, q_star: Any, T: Any, params: ChainParams | None) -> Any:
    jax = sys.modules["jax"]

    def identity(q_star: Any, T: Any, params: Any) -> Any:
        return q_star

    def tangent(primals: Any, tangents: Any) -> Any:
        q_star, T, params = primals
        J = _projector(problem, q_star, T)
        _, dq = jax.jvp(
            lambda T, p: _linearised(problem, J, q_star, T, p), (T, params), tangents[1:]
        )
        return q_star, dq

    implicit = jax.custom_jvp(identity)
    implicit.defjvp(tangent)
    return implicit(q_star, T, params)


@functools.cache
def _torch_implicit() -> Any:
    """An ``autograd.Function``: ``q_star`` forward; backward, the vector-Jacobian product of
    :func:`_linearised` with respect to the targets and the parameters."""
    import torch

    class Implicit(torch.autograd.Function):
        @staticmethod
        def forward(q_star: Any, problem: _Problem, T: Any, *leaves: Any) -> Any:
            return q_star.clone()

        @staticmethod
        def setup_context(ctx: Any, inputs: Any, output: Any) -> None:
            q_star, problem, T, *leaves = inputs
            ctx.problem = problem
            ctx.save_for_backward(q_star, T, *leaves)

        @staticmethod
        def backward(ctx: Any, q_bar: Any) -> Any:
            q_star, T, *leaves = ctx.saved_tensors
            problem: _Problem = ctx.problem
            J = _projector(problem, q_star, T.detach())

            def linearised(T: Any, *leaves: Any) -> Any:
                params = ChainParams(*leaves) if leaves else None
                return _linearised(problem, J, q_star, T, params)

            vjp = torch.func.vjp(linearised, T, *leaves)[1]
            return (None, None, *vjp(q_bar))

    return Implicit.apply


@functools.cache
def _register_result_pytree() -> None:
    """:class:`IKResult` as a JAX pytree of six arrays, so that it leaves ``jit`` and ``vmap``
    (registered at the first JAX solve: JAX is never imported by poekin itself)."""
    jax = sys.modules["jax"]
    fields = [f.name for f in dataclasses.fields(IKResult)]
    jax.tree_util.register_dataclass(IKResult, data_fields=fields, meta_fields=[])
