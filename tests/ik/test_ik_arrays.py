"""Chain.ik on JAX arrays and PyTorch tensors (poekin.ik.fixed): every answer checked by MuJoCo's
mj_forward and the joint limits; the NumPy solve's answer wherever it ends within the budget of
iterations, a failure at the budget elsewhere; more targets than the JAX loop has lanes (each
lane takes the next target); the caller's library, dtype and batch shape; jit, vmap (nested,
model parameters per target), torch.compile; the derivative by the implicit function theorem
against central finite differences of the NumPy solve (the UR5e and the 7-joint Panda, targets
and model parameters), nothing through the iterations; a batch sharded over 8 host devices; bad
input.

A JAX solve compiles its iterations (seconds on the CPU): the JAX tests compile few programs,
with XLA's quick options (``FAST_COMPILE``), and are marked slow."""

from __future__ import annotations

import contextlib
import functools
import json
import os
import subprocess
import sys
import textwrap
from dataclasses import astuple
from typing import Any

import numpy as np
import pytest
from array_libs import LIBRARIES, Lib, load
from helpers import load_quiet
from test_ik_numerical import arm, check_by_mujoco, mj_poses, uniform_q

import poekin
from poekin import InputError, arrays, lie
from poekin.chain import Chain, ChainParams
from poekin.ik import IKResult, _rng, fixed
from poekin.ik._angles import within_limits, wrap_into_limits

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# XLA's quick compile on the CPU: 2-4x less compile time, slower programs (docs/ik.md)
FAST_COMPILE = {"xla_cpu_use_fusion_emitters": False, "xla_backend_optimization_level": 0}
TIGHT = {"pos_tol": 1e-13, "ori_tol": 1e-13, "max_attempts": 1}  # derivative tests: from q0
H = 1e-6  # central differences' step


@functools.cache
def lib(name: str) -> Lib:
    return load(name)


def numpy_result(found: IKResult, L: Lib) -> IKResult:
    return IKResult(
        *(
            L.numpy(x)
            for x in (
                found.q,
                found.success,
                found.pos_err,
                found.ori_err,
                found.iterations,
                found.attempts,
            )
        )
    )


def jit(L: Lib, f: Any) -> Any:
    """``f`` compiled: ``jax.jit`` with :data:`FAST_COMPILE`; PyTorch runs it eagerly."""
    return L.module.jit(f, compiler_options=FAST_COMPILE) if L.name == "jax" else f


def slow_for_jax(name: str) -> Any:
    return pytest.param(name, marks=pytest.mark.slow) if name == "jax" else name


LIBS = [slow_for_jax(name) for name in LIBRARIES]


# --- the answers: MuJoCo, the limits, the NumPy solve ----------------------------------------


def targets(chain: Chain, loaded: Any, n: int, seed: int) -> np.ndarray:
    """MuJoCo's poses of configurations within the limits, and two out of reach."""
    T = mj_poses(loaded, chain, uniform_q(chain, n, seed))
    T[-2:, :3, 3] *= 2.5 / np.linalg.norm(T[-2:, :3, 3], axis=-1, keepdims=True)
    return T


def assert_numpy_answer(found: IKResult, expected: IKResult, budget: int) -> None:
    """Where the NumPy solve ends within ``budget`` iterations, its answer: the same attempts,
    iterations, success and solution (to rounding); elsewhere a failure at the budget."""
    within = expected.iterations <= budget
    assert within.sum() >= 0.8 * len(within) - 2, "too few targets to compare"
    assert np.array_equal(found.success[within], expected.success[within]), "success differs"
    assert np.array_equal(found.attempts[within], expected.attempts[within])
    assert np.array_equal(found.iterations[within], expected.iterations[within])
    solved = within & expected.success
    assert np.abs(found.q[solved] - expected.q[solved]).max() < 1e-9
    assert not found.success[~within].any()
    assert np.all(found.iterations[~within] == budget)


@pytest.mark.parametrize("name", LIBS)
@pytest.mark.parametrize("robot", ["ur5e", "panda"])
def test_the_numpy_solves_answer_within_the_budget(name: str, robot: str) -> None:
    """jit(vmap(ik)) for JAX (24 targets, more than the loop's lanes), a batch for PyTorch:
    targets within reach and out of it, every answer checked by MuJoCo and the limits."""
    L = lib(name)
    loaded, chain = arm(robot)
    T = targets(chain, loaded, 24, seed=30)
    budget = 24  # small, so that some targets need more than the budget
    assert fixed.slots(len(T)) < len(T)
    solve = jit(
        L,
        L.module.vmap(lambda t: chain.ik(t, max_total_iterations=budget))
        if name == "jax"
        else lambda t: chain.ik(t, max_total_iterations=budget),
    )
    found = numpy_result(solve(L.asarray(T)), L)
    check_by_mujoco(loaded, chain, T, found)
    assert not found.success[-2:].any()
    expected = chain.ik(T)
    assert (expected.success & (expected.iterations > budget)).any()  # the budget binds
    assert_numpy_answer(found, expected, budget)


@pytest.mark.parametrize("name", LIBS)
def test_q0_starts_the_first_attempt_and_keeps_the_branch(name: str) -> None:
    """From q0 near the generating configuration: its branch, in one attempt."""
    L = lib(name)
    loaded, chain = arm("ur5e")
    q = uniform_q(chain, 6, seed=31)
    T = mj_poses(loaded, chain, q)
    solve = jit(L, lambda t, q0: chain.ik(t, q0, max_attempts=2))
    found = numpy_result(solve(L.asarray(T), L.asarray(q + 0.05)), L)
    check_by_mujoco(loaded, chain, T, found)
    assert found.success.all() and np.all(found.attempts == 1)
    assert np.abs(found.q - q).max() < 1e-9
    assert_numpy_answer(found, chain.ik(T, q + 0.05, max_attempts=2), fixed.DEFAULT_BUDGET)


def test_the_callers_library_dtype_and_batch_shape() -> None:
    """PyTorch: float64 and float32 in and out, batch shapes (), (1,), (3, 1, 2) broadcast
    against q0, integer counts; float32 answers within float32 tolerances by MuJoCo."""
    L = lib("torch")
    torch = L.module
    loaded, chain = arm("ur5e")
    q = uniform_q(chain, 6, seed=32)
    T = mj_poses(loaded, chain, q)
    for batch in [(), (1,), (3, 1, 2)]:
        n = int(np.prod(batch))
        t = torch.tensor(T[:n].reshape(*batch, 4, 4))
        q0 = torch.tensor(q[0])  # one start for every target
        found = chain.ik(t, q0, max_attempts=3)
        assert isinstance(found.q, torch.Tensor) and found.q.dtype == torch.float64
        assert tuple(found.q.shape) == (*batch, 6)
        for x in (found.success, found.pos_err, found.ori_err, found.iterations):
            assert tuple(x.shape) == batch
        assert found.success.dtype == torch.bool and found.iterations.dtype == torch.int64
        expected = chain.ik(T[:n].reshape(*batch, 4, 4), q[0], max_attempts=3)
        np.testing.assert_array_equal(L.numpy(found.attempts), expected.attempts)
        flat = [x.reshape(n, *x.shape[len(batch) :]) for x in astuple(numpy_result(found, L))]
        check_by_mujoco(loaded, chain, T[:n], IKResult(*flat))
    single = chain.ik(torch.tensor(T, dtype=torch.float32), pos_tol=3e-5, ori_tol=3e-5)
    assert single.q.dtype == torch.float32 and bool(single.success.all())
    q32 = L.numpy(single.q).astype(np.float64)
    assert within_limits(q32, chain.limits).all()
    pos, ori = poekin.pose_errors(T, mj_poses(loaded, chain, q32))
    assert pos.max() < 3e-5 + 1e-6 and ori.max() < 3e-5 + 1e-6


def test_position_only_and_q0_outside_the_limits() -> None:
    """PyTorch: a point target for the 5-joint SO-100; q0 turned and clamped into the limits."""
    L = lib("torch")
    loaded = load_quiet("trs_so_arm100")
    so100 = poekin.load(loaded, "Fixed_Jaw")
    points = mj_poses(loaded, so100, uniform_q(so100, 5, seed=33))
    reach = so100.ik(L.asarray(points), position_only=True, max_attempts=8)
    assert bool(reach.success.all())
    check_by_mujoco(loaded, so100, points, numpy_result(reach, L), position_only=True)
    loaded, chain = arm("ur5e")
    far = np.full(6, 9.0)  # beyond every limit (the UR5e's are +-2 pi, the elbow's +-pi)
    T = mj_poses(loaded, chain, far[None] - 2 * np.pi)
    found = chain.ik(L.asarray(T), L.asarray(far), max_attempts=1)
    check_by_mujoco(loaded, chain, T, numpy_result(found, L))
    assert bool(found.success.all()) and int(found.iterations) == 1  # turned: the same pose
    np.testing.assert_allclose(L.numpy(found.q), far[None] - 2 * np.pi, atol=1e-15)


def per_target_parameters(n: int, seed: int) -> tuple[Chain, np.ndarray, ChainParams]:
    """The UR5e with each target's own model (its screws' moments and home position moved by
    1 cm at most), targets from configurations within the limits by that model's FK."""
    _, chain = arm("ur5e")
    rng = np.random.default_rng(seed)
    S = np.broadcast_to(chain.screws, (n, 6, 6)).copy()
    S[:, :, 3:] += rng.uniform(-0.01, 0.01, (n, 6, 3))
    H = np.broadcast_to(chain.home, (n, 4, 4)).copy()
    H[:, :3, 3] += rng.uniform(-0.01, 0.01, (n, 3))
    q = uniform_q(chain, n, seed)
    T = np.stack([chain.with_parameters(ChainParams(S[i], H[i])).fk(q[i]) for i in range(n)])
    return chain, T, ChainParams(S, H)


def assert_reached_by_own_model(chain: Chain, T: np.ndarray, P: ChainParams, q: np.ndarray) -> None:
    """Each answer within the limits and at its target by its own model's FK (the NumPy path,
    itself checked against MuJoCo)."""
    assert within_limits(q, chain.limits).all()
    for i in range(len(T)):
        reached = chain.with_parameters(ChainParams(P.screws[i], P.home[i])).fk(q[i])
        pos, ori = poekin.pose_errors(T[i], reached)
        assert pos < 1e-10 + 1e-12 and ori < 1e-10 + 1e-12


def test_model_parameters_per_target() -> None:
    """PyTorch: a batch of targets, each with its own screws and home pose; each answer the
    one the target gets alone, bit for bit."""
    torch = lib("torch").module
    chain, T, P = per_target_parameters(12, seed=37)
    tensors = ChainParams(torch.tensor(P.screws), torch.tensor(P.home))
    found = chain.ik(torch.tensor(T), params=tensors, max_attempts=16)
    assert bool(found.success.all())
    assert_reached_by_own_model(chain, T, P, found.q.numpy())
    for i in (0, 5, 11):
        alone = chain.ik(
            torch.tensor(T[i]), params=ChainParams(*(x[i] for x in tensors)), max_attempts=16
        )
        assert torch.equal(alone.q, found.q[i]) and int(alone.iterations) == found.iterations[i]


@pytest.mark.slow
def test_jax_nested_vmap_with_model_parameters_per_target() -> None:
    """vmap of vmap over a (4, 10) batch of targets, each with its own model: one loop for the
    40 targets (custom_vmap), the PyTorch solve's answers (to rounding), each reached."""
    jax = lib("jax").module
    torch = lib("torch").module
    chain, T, P = per_target_parameters(40, seed=38)

    def solve(t: Any, screws: Any, home: Any) -> Any:
        return chain.ik(t, params=ChainParams(screws, home), max_attempts=16)

    nested = jax.jit(jax.vmap(jax.vmap(solve)), compiler_options=FAST_COMPILE)
    args = [x.reshape(4, 10, *x.shape[1:]) for x in (T, P.screws, P.home)]
    found = numpy_result(nested(*(jax.numpy.asarray(x) for x in args)), lib("jax"))
    assert found.q.shape == (4, 10, 6) and found.success.all()
    q = found.q.reshape(40, 6)
    assert_reached_by_own_model(chain, T, P, q)
    by_torch = chain.ik(
        torch.tensor(T), params=ChainParams(*(torch.tensor(x) for x in P)), max_attempts=16
    )
    assert np.abs(q - by_torch.q.numpy()).max() < 1e-9
    assert np.array_equal(found.iterations.reshape(40), by_torch.iterations.numpy())


@pytest.mark.slow
def test_jax_jit_traces_once_and_float32_without_x64() -> None:
    """A jitted solve traces poekin once per shape; with jax_enable_x64 off (float32, 32-bit
    integers) the random starts still come from 64-bit words (jax.enable_x64 inside)."""
    jax = lib("jax").module
    loaded, chain = arm("ur5e")
    T = mj_poses(loaded, chain, uniform_q(chain, 4, seed=34))
    traces = []

    def solve(t: Any) -> Any:
        traces.append(1)
        return chain.ik(t, pos_tol=3e-5, ori_tol=3e-5, max_attempts=8)

    with jax.enable_x64(False):
        compiled = jax.jit(solve, compiler_options=FAST_COMPILE)
        found = compiled(jax.numpy.asarray(T, dtype=jax.numpy.float32))
        compiled(jax.numpy.asarray(T[::-1], dtype=jax.numpy.float32))
        assert found.q.dtype == jax.numpy.float32 and found.iterations.dtype == np.int32
    assert len(traces) == 1
    q = np.asarray(found.q, dtype=np.float64)
    assert bool(found.success.all()) and within_limits(q, chain.limits).all()
    pos, ori = poekin.pose_errors(T, mj_poses(loaded, chain, q))
    assert pos.max() < 3e-5 + 1e-6 and ori.max() < 3e-5 + 1e-6


def test_torch_compile_runs_the_solve_eagerly() -> None:
    """Inside a torch.compile'd function the solve is a graph break: the eager answer."""
    torch = lib("torch").module
    _, chain = arm("ur5e")
    T = torch.tensor(chain.fk(uniform_q(chain, 5, seed=35)))
    compiled = torch.compile(lambda t: chain.ik(t, max_attempts=2).q * 2.0)
    assert torch.equal(compiled(T), chain.ik(T, max_attempts=2).q * 2.0)


@pytest.mark.parametrize("name", LIBRARIES)
def test_the_random_starts_and_whole_turns_are_numpys_bits(name: str) -> None:
    """The shared helpers on the library's arrays: the keys and uniform numbers of the random
    starts (64-bit words), and wrap_into_limits, equal NumPy's bit for bit."""
    L = lib(name)
    rng = np.random.default_rng(36)
    T = rng.normal(size=(40, 4, 4))
    q0 = rng.normal(size=(40, 7))
    attempt = np.arange(5)[:, None]
    expected = _rng.uniform(_rng.target_keys(9, T, q0), attempt, 3)
    xp = arrays.namespace(name)
    wide = L.module.enable_x64(True) if name == "jax" else contextlib.nullcontext()
    with wide:
        keys = _rng.target_keys(9, L.asarray(T), L.asarray(q0), xp)
        got = L.numpy(_rng.uniform(keys, L.asarray(attempt, "int64"), 3, xp))
    assert np.array_equal(got.view(np.uint64), expected.view(np.uint64))
    limits = np.array([[-np.inf, np.inf], [-1.0, 2.0], [-0.5, np.inf], [-3.0, 3.0]])
    revolute = np.array([True, True, True, False])
    q = rng.uniform(-40.0, 40.0, (200, 4))
    turned = wrap_into_limits(L.asarray(q), limits, revolute, xp)
    want = wrap_into_limits(q, limits, revolute)
    assert np.array_equal(L.numpy(turned).view(np.uint64), want.view(np.uint64))


# --- derivatives ------------------------------------------------------------------------------


def rigid_direction(rng: np.random.Generator, T: np.ndarray) -> np.ndarray:
    """A tangent ``dT`` of SE(3) at ``T`` (a twist in the target's frame)."""
    return T @ lie.hat_se3(rng.normal(size=6))


def param_direction(rng: np.random.Generator, chain: Chain) -> ChainParams:
    """A tangent of the model's parameters that keeps unit axes and a rigid home pose: each
    axis turned (``dw`` normal to ``w``), each moment moved, the home pose turned and moved."""
    w = chain.screws[:, :3]
    dw = np.cross(w, rng.normal(size=w.shape))
    dS = np.hstack([dw, rng.normal(size=w.shape)]) * 0.1
    dS[[t == "prismatic" for t in chain.joint_types], :3] = 0.0
    return ChainParams(dS, chain.home @ lie.hat_se3(rng.normal(size=6)) * 0.1)


def numpy_solve(chain: Chain, T: np.ndarray, q0: np.ndarray, params: ChainParams) -> np.ndarray:
    found = chain.with_parameters(params).ik(T, q0, **TIGHT)
    assert found.success.all()
    return found.q


def finite_differences(
    chain: Chain, T: np.ndarray, q: np.ndarray, dT: np.ndarray, dP: ChainParams
) -> np.ndarray:
    """Central differences of the NumPy solve from the solution ``q`` (its branch)."""
    P = chain.parameters()
    moved = [
        numpy_solve(
            chain,
            T + s * H * dT,
            q,
            ChainParams(*(p + s * H * d for p, d in zip(P, dP, strict=True))),
        )
        for s in (1.0, -1.0)
    ]
    return (moved[0] - moved[1]) / (2 * H)


def solution(robot: str, seed: int) -> tuple[Chain, np.ndarray, np.ndarray]:
    """A chain, a configuration inside its limits (away from them) and its pose."""
    _, chain = arm(robot)
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    q = (lo + hi) / 2 + (hi - lo) / 2 * np.random.default_rng(seed).uniform(-0.7, 0.7, len(lo))
    return chain, q, chain.fk(q)


@pytest.mark.parametrize("name", LIBS)
@pytest.mark.parametrize("robot", ["ur5e", "panda"])
def test_the_derivative_matches_finite_differences(name: str, robot: str) -> None:
    """d q / d (T, params) along tangent directions, against central differences of the NumPy
    solve: reverse mode (jax.grad of a loss; torch.autograd.grad of each joint) and, for JAX,
    forward mode (jax.jvp). The Panda has 7 joints: the minimum-norm solution, which is the
    step the solver takes from q0. (JAX with the Panda: the targets only, as a program with
    parameters takes twice as long to compile.)"""
    L = lib(name)
    chain, q, T = solution(robot, seed=40)
    rng = np.random.default_rng(41)
    dT, dP = rigid_direction(rng, T), param_direction(rng, chain)
    with_params = not (name == "jax" and robot == "panda")
    if not with_params:
        dP = ChainParams(*(np.zeros_like(x) for x in dP))
    fd = finite_differences(chain, T, q, dT, dP)
    assert np.abs(fd).max() > 0.1  # a direction that moves the solution

    def solve(t: Any, *params: Any) -> Any:
        model = ChainParams(*params) if params else None
        return chain.ik(t, L.asarray(q), params=model, **TIGHT).q

    args = [L.asarray(x) for x in (T, *(chain.parameters() if with_params else ()))]
    tangents = [dT, *(dP if with_params else ())]
    if name == "jax":
        jax = L.module
        weights = np.random.default_rng(46).normal(size=len(q))  # a loss's d loss / d q
        argnums = tuple(range(len(args)))

        def both(*args: Any) -> Any:
            loss = jax.grad(lambda *a: solve(*a) @ weights, argnums=argnums)(*args)
            fwd = jax.jvp(solve, args, tuple(jax.numpy.asarray(t) for t in tangents))[1]
            return loss, fwd

        grads, fwd = jit(L, both)(*args)
        np.testing.assert_allclose(np.asarray(fwd), fd, atol=1e-6 * np.abs(fd).max())
        reverse = sum(
            float((np.asarray(g) * t).sum()) for g, t in zip(grads, tangents, strict=True)
        )
        assert abs(reverse - weights @ fd) < 1e-6 * np.abs(fd).max() * np.abs(weights).sum()
        return
    for a in args:
        a.requires_grad_(True)
    out = solve(*args)
    rows = [L.module.autograd.grad(out[k], args, retain_graph=True) for k in range(len(q))]
    directional = [
        sum(float((g.numpy() * t).sum()) for g, t in zip(row, tangents, strict=True))
        for row in rows
    ]
    np.testing.assert_allclose(directional, fd, atol=1e-6 * np.abs(fd).max())


def test_torch_gradcheck() -> None:
    """torch.autograd.gradcheck: the backward pass against its own central differences of the
    tensor solve, every entry of the target (not only rigid motions) and of the home pose."""
    torch = lib("torch").module
    chain, q, T = solution("ur5e", seed=42)
    q0 = torch.tensor(q)
    screws = torch.tensor(chain.screws)

    def solve(t: Any, home: Any) -> Any:
        return chain.ik(t, q0, params=ChainParams(screws, home), max_iterations=6, **TIGHT).q

    inputs = (torch.tensor(T, requires_grad=True), torch.tensor(chain.home, requires_grad=True))
    assert torch.autograd.gradcheck(solve, inputs, eps=1e-6, atol=1e-6, rtol=1e-5)


def test_a_joint_held_at_its_limit_has_no_derivative() -> None:
    """The Panda's first joint at its limit: its derivative is zero, the other six move as the
    solver moves them when the target moves the way that pushes that joint out (one-sided
    differences: the other way, the joint leaves the limit). (Not the elbow: without it the
    other six cannot change the wrist's distance from the shoulder, and the target cannot be
    followed.)"""
    joint = 0
    torch = lib("torch").module
    chain, q, _ = solution("panda", seed=43)
    q[joint] = chain.limits[joint, 1]
    T = chain.fk(q)
    dT = rigid_direction(np.random.default_rng(44), T)
    t = torch.tensor(T, requires_grad=True)
    out = chain.ik(t, torch.tensor(q), **TIGHT).q
    assert torch.equal(out.detach(), torch.tensor(q))
    rows = [torch.autograd.grad(out[k], t, retain_graph=True)[0].numpy() for k in range(7)]
    dq = np.array([(g * dT).sum() for g in rows])
    assert dq[joint] == 0.0
    moved = {s: chain.ik(T + s * H * dT, q, **TIGHT).q for s in (1.0, -1.0)}
    # one side stays at the limit (to the solver's last, second-order, steps); the other
    # leaves it by about H times the derivative with every joint free
    held = [s for s, x in moved.items() if abs(x[joint] - q[joint]) < 1e-4 * H]
    assert len(held) == 1, {s: x[joint] - q[joint] for s, x in moved.items()}
    one_sided = (moved[held[0]] - q) / (held[0] * H)
    np.testing.assert_allclose(dq, one_sided, atol=1e-4 * np.abs(one_sided).max())


@pytest.mark.parametrize("name", LIBRARIES)
def test_no_derivative_flows_through_the_iterations(name: str) -> None:
    """JAX: a gradient's program has one loop, the solve's own, not its transpose too.
    PyTorch: the autograd graph of q is the same small graph whether the solve ran 3
    iterations or 30."""
    L = lib(name)
    chain, q, T = solution("ur5e", seed=45)
    if name == "jax":
        jax = L.module

        def solve(t: Any) -> Any:
            return chain.ik(t, jax.numpy.asarray(q), **TIGHT).q

        def loops(f: Any) -> int:
            text = str(jax.make_jaxpr(f)(jax.numpy.asarray(T)))  # traced, not run
            return text.count("scan[") + text.count("while[")

        # differentiating the iterations would add their transpose: a loop run backwards
        assert loops(solve) == loops(jax.grad(lambda t: solve(t).sum())) == 1
        return

    def graph_size(iterations: int) -> int:
        t = L.module.tensor(T, requires_grad=True)
        out = chain.ik(t, L.module.tensor(q), max_iterations=iterations, **TIGHT).q
        seen, todo = set(), [out.grad_fn]
        while todo:
            node = todo.pop()
            if node is not None and node not in seen:
                seen.add(node)
                todo += [n for n, _ in node.next_functions]
        return len(seen)

    assert graph_size(3) == graph_size(30) <= 3


# --- scale-out ----------------------------------------------------------------------------------

SHARDED = textwrap.dedent(
    """
    import json, os, re, sys, warnings
    os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=8"
    warnings.simplefilter("ignore")
    import jax, numpy as np, poekin
    from jax import shard_map
    from jax.sharding import NamedSharding, PartitionSpec as P
    jax.config.update("jax_enable_x64", True)
    chain = poekin.load("universal_robots_ur5e")
    mesh = jax.make_mesh((8,), ("batch",))
    q = np.random.default_rng(0).uniform(chain.limits[:, 0], chain.limits[:, 1], (64, 6))
    T = chain.fk(q)
    solve = lambda t: chain.ik(t, max_attempts=4)
    fast = {"xla_cpu_use_fusion_emitters": False, "xla_backend_optimization_level": 0}
    alone = jax.jit(solve, compiler_options=fast)  # each device's slice of 8, on one device
    parts = [alone(jax.device_put(T[i : i + 8], jax.devices()[0])) for i in range(0, 64, 8)]
    one = jax.tree.map(lambda *x: np.concatenate(x), *parts)
    sharded = jax.jit(shard_map(solve, mesh=mesh, in_specs=P("batch"), out_specs=P("batch")),
                      compiler_options=fast)
    spread = jax.device_put(T, NamedSharding(mesh, P("batch")))
    by_map = sharded(spread)
    hlo = sharded.lower(spread).compile().as_text()
    print(json.dumps({
        "devices": jax.device_count(),
        "equal": all(np.array_equal(np.asarray(a), np.asarray(b)) for a, b in zip(
            jax.tree.leaves(one), jax.tree.leaves(by_map))),
        "spread_over": len(by_map.q.sharding.device_set),
        "solved": float(np.asarray(by_map.success).mean()),
        "answers": [np.asarray(x).tolist() for x in jax.tree.leaves(by_map)[:4]],
        "collectives": sorted(set(re.findall(
            r"all-reduce|all-gather|collective-permute|all-to-all|reduce-scatter", hlo))),
    }))
    """
)


@pytest.mark.slow
def test_a_batch_sharded_over_8_devices_is_one_devices_bit_for_bit() -> None:
    """shard_map runs the solve on each device's slice of the targets: the slices' results on
    one device bit for bit, and the compiled program holds no cross-device communication.
    XLA_FLAGS must be set before JAX starts: a fresh process."""
    lib("jax")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.path.join(REPO, "src"), *sys.path])}
    done = subprocess.run(
        [sys.executable, "-c", SHARDED], capture_output=True, text=True, env=env, timeout=900
    )
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    loaded, chain = arm("ur5e")
    q = np.random.default_rng(0).uniform(chain.limits[:, 0], chain.limits[:, 1], (64, 6))
    answers = [np.array(x) for x in out.pop("answers")]  # q, success, pos_err, ori_err
    check_by_mujoco(loaded, chain, chain.fk(q), IKResult(*answers, *answers[-2:]))
    assert out == {
        "devices": 8,
        "equal": True,
        "spread_over": 8,
        "solved": out["solved"],
        "collectives": [],
    }
    assert out["solved"] > 0.9


# --- bad input ----------------------------------------------------------------------------------


def test_bad_input_is_one_clear_input_error() -> None:
    jnp = lib("jax").module.numpy
    torch = lib("torch").module
    _, chain = arm("ur5e")
    T = chain.fk(np.zeros(6))
    cases = [
        ((jnp.asarray(T), torch.zeros(6)), {}, "mix JAX arrays and PyTorch tensors"),
        (
            (torch.tensor(T),),
            {"params": ChainParams(jnp.asarray(chain.screws), chain.home)},
            "mix JAX arrays and PyTorch tensors",
        ),
        ((torch.zeros(3, 3, dtype=torch.float64),), {}, "targets must have shape (..., 4, 4)"),
        ((torch.tensor(T), torch.zeros(5, dtype=torch.float64)), {}, "q0 must have shape"),
        ((torch.tensor(np.stack([T, T])), torch.zeros(3, 6)), {}, "do not broadcast"),
        ((torch.tensor(T, dtype=torch.float16),), {}, "float32 or float64"),
        (
            (torch.tensor(T),),
            {"params": ChainParams(torch.zeros(5, 6), chain.home)},
            "params.screws must have shape",
        ),
        ((torch.tensor(T),), {"params": (chain.screws, chain.home)}, "must be a ChainParams"),
        ((torch.tensor(T),), {"pos_tol": -1.0}, "pos_tol must be a finite number > 0"),
        ((torch.tensor(T),), {"seed": -1}, "seed must be an integer"),
        (
            (torch.tensor(T),),
            {"max_total_iterations": 0},
            "max_total_iterations must be an integer from 1",
        ),
        ((T,), {"max_total_iterations": 10}, "max_total_iterations bounds the solve of JAX"),
    ]
    cases += [
        ((torch.tensor(T), [[1.0, 2.0], [3.0]]), {}, "targets and q0 must be arrays of numbers"),
        ((torch.tensor(T), ["a"] * 6), {}, "expected real numbers"),
    ]
    for args, kwargs, message in cases:
        with pytest.raises(InputError, match=None) as caught:
            chain.ik(*args, **kwargs)
        assert message in str(caught.value) and "\n" not in str(caught.value), message
    nothing = Chain((), (), np.zeros((0, 6)), np.eye(4))
    with pytest.raises(InputError, match="no joints"):
        nothing.ik(torch.tensor(T))
    tree = poekin.load_tree("unitree_go2")
    with pytest.raises(InputError, match=r"Tree\.ik takes NumPy arrays"):
        tree.ik(torch.tensor(T), "FL_calf")
