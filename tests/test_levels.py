"""Trees group by group (poekin._levels), the reference path that NumPy, JAX and PyTorch run:
the stacked formulas are the entry formulas bit for bit; isomorphic subtrees go side by side
whatever their offsets, anchors and axis directions; the results equal the compiled kernel's
for bodies in any order, mimic joints, deep chains and batches of models; and a program grows
with the groups, not with the entries (which keeps JAX's and Inductor's compiles short)."""

from __future__ import annotations

import importlib.util
from typing import Any

import numpy as np
import pytest
from array_libs import LIBRARIES, Lib, load
from helpers import assert_close, load_quiet
from hypothesis import given, settings
from hypothesis import strategies as st
from test_tree import _random_chain_tree

import poekin
from poekin import _pose, lie
from poekin.tree import Mimic, Tree, TreeParams
from poekin.verification.verify import sample_qpos

BATCH_SHAPES = [(), (1,), (3, 1, 2)]
# The NumPy reference path vs the compiled kernel, as tests/kernel/test_fast.py; JAX and PyTorch vs
# the kernel, as tests/test_arrays.py: per metre the frames reach.
REF_TOL = 1e-15
LIB_TOL = 1e-15
PARAM_TOL = 2e-14  # the parameter path's general formulas, as tests/test_arrays.py
# jit(vmap(tree.fk)): the entry-by-entry path was ~1,400 equations for the go2 and ~1,900 for
# aloha (their bodies' 12 entries, one expression each); by groups a few dozen per group.
EQUATIONS_PER_GROUP, EQUATIONS_BASE = 60, 100
INSTALLED = [name for name in LIBRARIES if importlib.util.find_spec(name) is not None]


def _entries(a: np.ndarray, ndim: int) -> Any:
    """The entries ``(m, ...)`` of stacked ``(m, 3, ...)`` or ``(m, 3, 3, ...)`` arrays."""
    if ndim == 1:
        return tuple(a[:, i] for i in range(3))
    return tuple(tuple(a[:, i, j] for j in range(3)) for i in range(3))


def _stacked(entries: Any, ndim: int) -> np.ndarray:
    if ndim == 1:
        return np.stack(np.broadcast_arrays(*entries), axis=1)
    return np.stack([np.stack(np.broadcast_arrays(*row), axis=1) for row in entries], axis=1)


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), shape=st.sampled_from(BATCH_SHAPES), k=st.integers(0, 2))
def test_stacked_formulas_are_the_entry_formulas_bit_for_bit(
    seed: int, shape: tuple[int, ...], k: int
) -> None:
    """Every ``*_stacked`` formula of poekin._pose against its entry-by-entry twin (the kernel's
    arithmetic) on random stacks of four, over the batch shapes: the same bits, but where the
    stacked turn about the origin leaves out a zero translation (the same values)."""
    rng = np.random.default_rng(seed)
    A, B = rng.normal(size=(2, 4, 3, 3, *shape))
    p, t, point = rng.normal(size=(3, 4, 3, *shape))
    s, c = rng.normal(size=(2, 4, *shape))
    mat = _pose.mat_mat(_entries(A, 2), _entries(B, 2))
    assert np.array_equal(_bits(_pose.mat_mat_stacked(A, B, np)), _bits(_stacked(mat, 2)))
    vec = _pose.mat_vec(_entries(A, 2), _entries(t, 1))
    assert np.array_equal(_bits(_pose.mat_vec_stacked(A, t, np)), _bits(_stacked(vec, 1)))
    R, q = _pose.compose((_entries(A, 2), _entries(p, 1)), _entries(B, 2), _entries(t, 1))
    R_s, q_s = _pose.compose_stacked(A, p, B, t, np)
    assert np.array_equal(_bits(R_s), _bits(_stacked(R, 2)))
    assert np.array_equal(_bits(q_s), _bits(_stacked(q, 1)))
    turned = _pose.about_point(_entries(A, 2), _entries(point, 1))
    assert np.array_equal(
        _bits(_pose.about_point_stacked(A, point, np)), _bits(_stacked(turned, 1))
    )
    W = _pose.hat(_entries(t, 1))
    W2 = _pose.mat_mat(W, W)
    W_s, W2_s = _stacked(W, 2), _stacked(W2, 2)
    eye = np.eye(3).reshape(1, 3, 3, *(1,) * len(shape))
    rod = _pose.rodrigues(W, W2, s, 1.0 - c)
    got = _pose.rodrigues_stacked(W_s, W2_s, s, 1.0 - c, eye)
    assert np.array_equal(_bits(got), _bits(_stacked(rod, 2)))
    for about in (point, None):
        at = _entries(point if about is not None else np.zeros_like(point), 1)
        R, q = _pose.axis_turn((_entries(A, 2), _entries(p, 1)), k, s, c, at, None)
        R_s, q_s = _pose.axis_turn_stacked(A, p, k, s, c, about, np)
        same = np.array_equal if about is None else lambda x, y: np.array_equal(_bits(x), _bits(y))
        assert same(R_s, _stacked(R, 2)) and same(q_s, _stacked(q, 1))


def test_isomorphic_subtrees_go_side_by_side(go2: Tree) -> None:
    """The go2's four legs are four lanes (a group per hip, thigh and calf); aloha's two arms,
    whose bases sit at different rotations, two lanes of ten bodies, the fingers four; a serial
    arm, one lane."""
    assert [len(g.bodies) for g in go2._plan.groups] == [1, 4, 4, 4]
    aloha = poekin.load_tree(load_quiet("aloha"))
    assert [len(g.bodies) for g in aloha._plan.groups] == [2] * 8 + [4]
    assert aloha._plan.body_order is None and aloha._plan.site_order is None
    ur5e = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    assert {len(g.bodies) for g in ur5e._plan.groups} == {1}


def _replicated_tree(rng: np.random.Generator, copies: int, floating: bool, bfs: bool) -> Tree:
    """``copies`` subtrees of one random shape (hinges about coordinate axes of either
    direction and about other axes, slides, ball joints; sites on some bodies) with every
    offset, anchor and axis direction drawn anew, under a free base or the world, bodies in
    depth-first or breadth-first order; and a world site listed first."""
    n = int(rng.integers(2, 6))
    parents = [-1] + [int(rng.integers(0, b)) for b in range(1, n)]  # within the template
    kinds = [str(rng.choice(["axis", "revolute", "prismatic", "ball", "none"])) for _ in range(n)]
    kinds[0] = "axis" if kinds[0] == "none" else kinds[0]  # at least one joint
    axes_k = [int(rng.integers(3)) for _ in range(n)]
    sites = [bool(rng.random() < 0.5) for _ in range(n)]
    # bodies: base (if floating), then each copy's template, renumbered
    preorder, todo = [], [0]  # the template depth first
    while todo:
        b = todo.pop()
        preorder.append(b)
        todo.extend(reversed([c for c in range(n) if parents[c] == b and c]))
    order: list[tuple[int, int]] = [(c, b) for c in range(copies) for b in preorder]
    if bfs:
        depth = [0] * n
        for b in range(1, n):
            depth[b] = depth[parents[b]] + 1
        order.sort(key=lambda cb: (depth[cb[1]], cb[0], cb[1]))
    index = {cb: i + int(floating) for i, cb in enumerate(order)}
    names, body_parents, joint_types, joint_bodies, axes = [], [], [], [], []
    site_bodies: list[int] = [-1]
    if floating:
        names.append("base")
        body_parents.append(-1)
        joint_types.append("free")
        joint_bodies.append(0)
        axes.append([0.0, 0.0, 1.0])
    for c, b in order:
        names.append(f"c{c}b{b}")
        body_parents.append(index[(c, parents[b])] if b else (0 if floating else -1))
        kind = kinds[b]
        if kind != "none":
            axis = rng.normal(size=3)
            if kind == "axis":
                axis = np.eye(3)[axes_k[b]] * rng.choice([-1.0, 1.0])
            joint_types.append("revolute" if kind == "axis" else kind)
            joint_bodies.append(index[(c, b)])
            axes.append(axis / np.linalg.norm(axis))
    for c in range(copies):
        site_bodies.extend(index[(c, b)] for b in range(n) if sites[b])
    nb, nj, ns = len(names), len(joint_types), len(site_bodies)
    anchors = rng.uniform(-0.1, 0.1, (nj, 3)) * (rng.random((nj, 1)) < 0.5)
    order_j = np.argsort(joint_bodies, kind="stable")  # joints grouped in body order
    return Tree(
        body_names=tuple(names),
        body_parents=body_parents,
        body_pos=rng.uniform(-0.5, 0.5, (nb, 3)) * (rng.random((nb, 1)) < 0.7),
        body_rot=[
            lie.exp_so3(w) if rng.random() < 0.5 else np.eye(3) for w in rng.normal(size=(nb, 3))
        ],
        joint_names=tuple(f"j{k}" for k in range(nj)),
        joint_types=tuple(joint_types[k] for k in order_j),
        joint_bodies=[joint_bodies[k] for k in order_j],
        joint_axes=np.array(axes)[order_j],
        joint_anchors=anchors[order_j],
        joint_refs=rng.uniform(-0.5, 0.5, nj)
        * np.isin(np.array(joint_types)[order_j], ["revolute", "prismatic"]),
        joint_limits=[[-np.inf, np.inf]] * nj,
        mimics=[None] * nj,
        site_names=tuple(f"s{s}" for s in range(ns)),
        site_bodies=site_bodies,
        site_pos=rng.uniform(-0.2, 0.2, (ns, 3)),
        site_rot=[lie.exp_so3(w) for w in rng.normal(size=(ns, 3))],
    )


def _reach_tol(tol: float, T: np.ndarray) -> float:
    return tol * max(1.0, float(np.abs(T).max()))


@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    copies=st.integers(2, 3),
    floating=st.booleans(),
    bfs=st.booleans(),
)
def test_replicated_subtrees_equal_the_kernel(
    seed: int, copies: int, floating: bool, bfs: bool
) -> None:
    """Copies of a random subtree share groups (lanes) although their offsets, anchors and
    axis directions differ, in depth-first or breadth-first body order (the frames then come
    back in the tree's order): the NumPy reference path equals the compiled kernel, frames and
    Jacobians, and so does PyTorch (JAX, which compiles each random tree's operations for
    seconds, takes the same grouped path on the go2, whose legs are copies:
    test_a_batch_of_models_broadcasts_against_qpos and test_arrays)."""
    rng = np.random.default_rng(seed)
    tree = _replicated_tree(rng, copies, floating, bfs)
    assert max(len(g.bodies) for g in tree._plan.groups) >= copies
    assert (tree._plan.body_order is not None) == bfs  # bodies out of depth-first order
    qpos = sample_qpos(tree, 8, seed=seed % 2**31)
    expected = tree.fk(qpos)
    assert_close("reference", tree._fk_numpy(qpos), expected, _reach_tol(REF_TOL, expected))
    frames = tree.frame_names
    for f in (frames[-1], frames[len(frames) // 2]):
        J = tree.jacobian(qpos, f)
        got = tree._jacobian_numpy(qpos, tree.frame_index(f), "world")
        assert_close(f"jacobian {f}", got, J, _reach_tol(REF_TOL, J) * 10)
    if "torch" in INSTALLED:
        lib = load("torch")
        got = lib.numpy(tree.fk(lib.asarray(qpos)))
        assert_close(f"{lib.name} fk", got, expected, _reach_tol(LIB_TOL, expected) * 4)


def test_a_deep_chain() -> None:
    """A serial tree 200 bodies deep (every group one lane): the reference path equals the
    kernel."""
    tree = _random_chain_tree(np.random.default_rng(3), 200, [None] * 200)
    q = np.random.default_rng(4).uniform(-3, 3, (4, 200))
    expected = tree.fk(q)
    assert_close("deep", tree._fk_numpy(q), expected, _reach_tol(REF_TOL, expected) * 10)


@pytest.fixture(scope="module", params=LIBRARIES)
def lib(request: pytest.FixtureRequest) -> Lib:
    return load(request.param)


def test_mimic_followers_equal_the_kernel(lib: Lib) -> None:
    """A chain whose followers come before and after their leaders (the qpos expansion's
    gather, multiplier and offset), in JAX and PyTorch: fk and a Jacobian as the kernel's."""
    mimics: list[Mimic | None] = [Mimic("j3", -1.5, 0.25), None, None, None, Mimic("j1", 2.0)]
    tree = _random_chain_tree(np.random.default_rng(5), 5, mimics)
    q = np.random.default_rng(6).uniform(-3, 3, (7, tree.nq))
    expected = tree.fk(q)
    assert_close("fk", lib.numpy(tree.fk(lib.asarray(q))), expected, LIB_TOL)
    J = tree.jacobian(q, "b4")
    assert_close("jacobian", lib.numpy(tree.jacobian(lib.asarray(q), "b4")), J, LIB_TOL * 10)


def test_a_batch_of_models_broadcasts_against_qpos(lib: Lib, go2: Tree) -> None:
    """Parameters with a leading axis (two models: the go2's and one with moved hips and
    turned axes) against qpos of shape (3, 1, nq): poses and Jacobians of shape (3, 2, ...),
    each the model's own."""
    own = go2.parameters()
    moved = TreeParams(
        own.body_pos + 0.01,
        own.body_rot,
        np.roll(own.joint_axes, 1, axis=-1),
        own.joint_anchors + 0.02,
        own.site_pos,
        own.site_rot,
    )
    models = [own, moved]
    stacked = TreeParams(*(lib.asarray(np.stack(fields)) for fields in zip(*models, strict=True)))
    qpos = sample_qpos(go2, 3, seed=7)
    x = lib.asarray(qpos[:, None])
    got = lib.numpy(go2.fk(x, params=stacked))
    jac = lib.numpy(go2.jacobian(x, "FL_calf", params=stacked))
    assert got.shape == (3, 2, go2.n_frames, 4, 4) and jac.shape == (3, 2, 6, go2.nv)
    for k, model in enumerate(models):
        assert_close(f"model {k}", got[:, k], go2.fk(qpos, params=model), PARAM_TOL)
        expected = go2.jacobian(qpos, "FL_calf", params=model)
        assert_close(f"model {k} jacobian", jac[:, k], expected, PARAM_TOL)


def test_programs_grow_with_groups_not_entries(go2: Tree) -> None:
    """jit(vmap(tree.fk)) traces to a few dozen equations per group: the go2 (four groups and a
    site) and aloha (nine and two) in a few hundred, where the entry-by-entry path took ~1,400
    and ~1,900 (which XLA compiled for seconds and Inductor for minutes)."""
    jax = load("jax").module
    for tree in (go2, poekin.load_tree(load_quiet("aloha"))):
        qpos = jax.numpy.asarray(sample_qpos(tree, 2, seed=8))
        equations = len(jax.make_jaxpr(jax.vmap(tree.fk))(qpos).jaxpr.eqns)
        groups = len(tree._plan.groups) + len(tree._plan.sites)
        assert equations <= EQUATIONS_PER_GROUP * groups + EQUATIONS_BASE, (tree, equations)
