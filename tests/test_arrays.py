"""JAX arrays and PyTorch tensors (poekin.arrays): the same results as the NumPy path on every
model, the caller's kind of array, dtype and batch shape back, derivatives equal to the
analytic Jacobians and finite at the special points, model parameters as leaves, and the
errors a user sees. Each check runs on both libraries; test_arrays_jax.py and
test_arrays_torch.py test each library's own transformations."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np
import pytest
from array_libs import LIBRARIES, Lib, load
from helpers import assert_close, load_quiet
from test_chain import random_chain
from test_tree import FEATURES_XML, MENAGERIE

import poekin
from poekin import InputError, lie
from poekin._extras import install_command
from poekin.chain import Chain, ChainParams
from poekin.io.import_mujoco import tree_from_model
from poekin.tree import Tree, TreeParams
from poekin.verification.verify import sample_qpos

# Float64 JAX and PyTorch vs the NumPy path (the compiled kernel): the same formulas in the
# same order, differing only in sin and cos (each library's own, < 1 ulp) and, under XLA, in
# fused multiply-adds; issue #16 asks for <= 1e-15 m and rad.
LIB_TOL = 1e-15
# Derivatives by automatic differentiation vs the analytic Jacobians: products of a few float64
# poses, ~1e-15; issue #16 asks for 1e-12.
GRAD_TOL = 1e-12
# Derivatives with respect to model parameters vs central differences with h = 1e-6:
# truncation ~h^2 and rounding ~1e-16/h, both ~1e-10; a wrong term is off by ~1e-1.
FD_TOL, FD_STEP = 1e-6, 1e-6
# The parameter path's general formulas (Rodrigues for every hinge, B = Ad(M^-1) S computed
# from the parameters) against the model's own (cos/sin entries): a few roundings apart.
PARAM_TOL = 2e-14
# Float32 vs float64 on the same q, every Menagerie model, 1000 samples in [-2 pi, 2 pi]:
# measured at most 4.3e-7 m and 6.8e-7 rad (docs/jax-pytorch.md); float32's eps is 1.2e-7 and
# an angle near 2 pi is itself rounded by 2.4e-7.
F32_POS_TOL, F32_ORI_TOL = 1e-6, 1.5e-6
N = 64
BATCH_SHAPES = [(), (1,), (3, 1, 2)]
SPECIAL_ANGLES = [0.0, np.pi, -np.pi, 2 * np.pi, -2 * np.pi]
SPECIAL_QUATS = [
    [1.0, 0.0, 0.0, 0.0],  # identity
    [-1.0, 0.0, 0.0, 0.0],  # the identity's antipode
    [0.0, 1.0, 0.0, 0.0],  # a half turn
    [0.0, -0.6, 0.0, 0.8],  # a half turn about another axis
    [0.0, 0.0, 0.0, 0.0],  # zero: MuJoCo reads the identity
    [2.0, 0.0, 0.0, 0.0],  # unnormalised
]


@pytest.fixture(scope="module", params=LIBRARIES)
def lib(request: pytest.FixtureRequest) -> Lib:
    return load(request.param)


@pytest.fixture(scope="module")
def features() -> Tree:
    return tree_from_model(mujoco.MjModel.from_xml_string(FEATURES_XML))


CHAIN_METHODS = ["fk", "fk_body", "jacobian_space", "jacobian_body", "jacobian_world"]


# --- the same results as NumPy ----------------------------------------------------------------


# PyTorch checks every Menagerie model. JAX compiles each operation once per shape (seconds a
# model on a shared machine), and the models' arrays go through the one generic path whatever
# the library: JAX checks a chain (the UR5e, the SO-100), a floating base (the go2) and a
# spherical wrist (the Lite6), and every joint type on the features tree (below). The G1 (38
# bodies) goes through no code the go2 does not: PyTorch alone checks it (below).
JAX_MODELS = ["universal_robots_ur5e", "trs_so_arm100", "unitree_go2", "ufactory_lite6"]
ARRAY_CASES = [
    *(("jax", robot) for robot in JAX_MODELS),
    *(("torch", robot) for robot in MENAGERIE if robot != "unitree_g1"),
]


@pytest.mark.parametrize(("library", "robot"), ARRAY_CASES)
def test_every_menagerie_model_equals_the_numpy_path(library: str, robot: str) -> None:
    _equals_the_numpy_path(load(library), robot)


def test_the_g1_equals_the_numpy_path_in_pytorch() -> None:
    _equals_the_numpy_path(load("torch"), "unitree_g1")


def _equals_the_numpy_path(lib: Lib, robot: str) -> None:
    """tree.fk in every form, tree.jacobian of every frame (a big tree's every third and its
    sites) in every convention, and the
    model's default chain's fk, fk_body and Jacobians, float64, on random configurations."""
    loaded = load_quiet(robot)
    tree = poekin.load_tree(loaded)
    qpos = sample_qpos(tree, N, seed=11)
    x = lib.asarray(qpos)
    for form in ("4x4", "3x4", "pos_quat"):
        got = tree.fk(x, form=form)
        assert type(got) is type(x) and lib.dtype(got) == "float64"
        assert_close(f"{robot} tree.fk {form}", lib.numpy(got), tree.fk(qpos, form=form), LIB_TOL)
    # every frame's Jacobian, or for a big tree (the G1's 42 frames: 30 s of JAX's tracing)
    # every third, its sites among them
    frames = tree.frame_names
    if len(frames) > 16:
        frames = tuple(dict.fromkeys([*frames[::3], *tree.site_names]))
    for name in frames:
        for convention in ("space", "body", "world"):
            got = lib.numpy(tree.jacobian(x, name, convention))
            expected = tree.jacobian(qpos, name, convention)
            assert_close(f"{robot} {name} {convention}", got, expected, LIB_TOL)
    for name in reversed(tree.frame_names):  # the chain of the last frame that has one
        try:
            chain = tree.chain(name)
        except poekin.ModelError:  # a ball or free joint on the path: no PoE chain
            continue
        q = qpos[:, list(chain.qpos_indices or ())]
        for method in CHAIN_METHODS:
            got = lib.numpy(getattr(chain, method)(lib.asarray(q)))
            assert_close(f"{robot} {name} chain.{method}", got, getattr(chain, method)(q), LIB_TOL)
        break


def test_every_joint_type_and_special_values_equal_the_numpy_path(lib: Lib, features: Tree) -> None:
    """Hinges, slides, ball and free joints, refs and anchors, sites on the world; quaternions
    zero, antipodal, unnormalised; hinge angles at 0, pi and 2 pi."""
    qpos = sample_qpos(features, len(SPECIAL_QUATS) * len(SPECIAL_ANGLES), seed=12)
    for k, kind in enumerate(features.joint_types):
        a = int(features.qpos_adr[k])
        if kind in ("ball", "free"):
            a += 3 if kind == "free" else 0
            qpos[:, a : a + 4] = np.repeat(SPECIAL_QUATS, len(SPECIAL_ANGLES), axis=0)
        elif kind == "revolute":
            qpos[:, a] = np.tile(SPECIAL_ANGLES, len(SPECIAL_QUATS))
    x = lib.asarray(qpos)
    assert_close("features", lib.numpy(features.fk(x)), features.fk(qpos), LIB_TOL)
    for name in features.frame_names:
        got = lib.numpy(features.jacobian(x, name, "body"))
        assert_close(name, got, features.jacobian(qpos, name, "body"), LIB_TOL)


@pytest.mark.parametrize("seed", range(3))
def test_random_chains_equal_the_numpy_path(lib: Lib, seed: int) -> None:
    """General and coordinate axes, pitched screws, prismatic joints; the tolerance scales
    with the chain's reach, as rounding does."""
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, 7, aligned=seed == 1)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (N, 7))
    tol = LIB_TOL * max(1.0, float(np.abs(chain.fk(q)[..., :3, 3]).max()))
    for method in CHAIN_METHODS:
        got = lib.numpy(getattr(chain, method)(lib.asarray(q)))
        assert_close(method, got, getattr(chain, method)(q), 2 * tol)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_batch_shapes(lib: Lib, ur5e: Chain, features: Tree, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(13)
    q = rng.uniform(-6, 6, (*shape, 6))
    for method in CHAIN_METHODS:
        got = getattr(ur5e, method)(lib.asarray(q))
        assert tuple(got.shape) == getattr(ur5e, method)(q).shape
    qpos = sample_qpos(features, int(np.prod(shape)), seed=13).reshape(*shape, features.nq)
    got = features.fk(lib.asarray(qpos), form="pos_quat")
    assert tuple(got.shape) == (*shape, features.n_frames, 7)
    assert_close("tree", lib.numpy(got), features.fk(qpos, form="pos_quat"), LIB_TOL)
    J = features.jacobian(lib.asarray(qpos), "finger")
    assert tuple(J.shape) == (*shape, 6, features.nv)


def test_a_chain_without_joints_and_an_empty_batch(lib: Lib) -> None:
    home = lie.exp_se3(np.array([0.1, 0.2, 0.3, 1.0, 2.0, 3.0]))
    fixed = Chain((), (), np.zeros((0, 6)), home)
    got = fixed.fk(lib.asarray(np.zeros((2, 0))))
    assert_close("fixed", lib.numpy(got), np.broadcast_to(home, (2, 4, 4)), 0.0)
    assert tuple(fixed.jacobian_world(lib.asarray(np.zeros((2, 0)))).shape) == (2, 6, 0)
    chain = random_chain(np.random.default_rng(1), 3)
    assert tuple(chain.fk(lib.asarray(np.zeros((0, 3)))).shape) == (0, 4, 4)


# --- dtypes ---------------------------------------------------------------------------------------


def test_float32_stays_float32_within_the_stated_error(lib: Lib) -> None:
    """The float32 figures of docs/jax-pytorch.md: every Menagerie tree, float32 vs float64 on
    the same q."""
    worst_pos = worst_ori = 0.0
    for robot in MENAGERIE:
        tree = poekin.load_tree(load_quiet(robot))
        qpos = sample_qpos(tree, 250, seed=1)
        got = tree.fk(lib.asarray(qpos, "float32"))
        assert lib.dtype(got) == "float32"
        pos, ori = poekin.pose_errors(tree.fk(qpos), lib.numpy(got).astype(np.float64))
        worst_pos, worst_ori = max(worst_pos, float(pos.max())), max(worst_ori, float(ori.max()))
    assert worst_pos <= F32_POS_TOL and worst_ori <= F32_ORI_TOL, (worst_pos, worst_ori)


def test_dtype_rules(lib: Lib, ur5e: Chain) -> None:
    """Floats keep their dtype, integers take the library's default float, and parameters of
    another float dtype promote as the library's arrays do."""
    q = np.zeros((2, 6))
    assert lib.dtype(ur5e.jacobian_body(lib.asarray(q, "float32"))) == "float32"
    ints = ur5e.fk(lib.asarray(q, "int32"))
    default = "float64"  # JAX with jax_enable_x64 (the tests'); torch.get_default_dtype() here
    if lib.name == "torch":
        default = str(lib.module.get_default_dtype()).removeprefix("torch.")
    assert lib.dtype(ints) == default
    params = ur5e.parameters(like=lib.asarray(q, "float32"))
    assert lib.dtype(params.screws) == "float32"
    assert lib.dtype(ur5e.fk(lib.asarray(q), params=params)) == "float64"


# --- derivatives ----------------------------------------------------------------------------------


def _twist_derivatives(J: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``dT/dq_i = [J_s[:, i]] T`` for a space Jacobian: ``(4, 4, n)``."""
    return np.stack([lie.hat_se3(J[:, i]) @ T for i in range(J.shape[-1])], axis=-1)


def test_derivative_of_fk_is_the_space_jacobian(lib: Lib, ur5e: Chain) -> None:
    """Forward and reverse mode, space and body form, at q = 0, +-pi, +-2 pi (all joints, and
    the first joint with the others random): finite and equal to dT/dq_i = [J_s[:, i]] T."""
    rng = np.random.default_rng(14)
    rows = [np.full(6, a) for a in SPECIAL_ANGLES] + [
        np.r_[a, rng.uniform(-3, 3, 5)] for a in SPECIAL_ANGLES
    ]
    q = np.array(rows)
    expected = np.stack([_twist_derivatives(ur5e.jacobian_space(x), ur5e.fk(x)) for x in q])
    for method in ("fk", "fk_body"):
        for mode in (lib.jacobian, lib.jacobian_rev):
            got = lib.numpy(mode(getattr(ur5e, method), lib.asarray(q)))
            assert np.all(np.isfinite(got))
            assert_close(f"d {method} / dq", got, expected, GRAD_TOL)


def _qvel_to_qpos(tree: Tree, qpos: np.ndarray) -> np.ndarray:
    """``(nq, nv)``: qpos rates of unit qvel, ``q_dot = q (0, w) / 2`` for a quaternion ``q``
    and body angular velocity ``w``."""
    E = np.zeros((tree.nq, tree.nv))
    for k, kind in enumerate(tree.joint_types):
        if tree.mimics[k] is not None:
            continue
        a, d = int(tree.qpos_adr[k]), int(tree._dof_adr[k])
        if kind in ("revolute", "prismatic"):
            E[a, d] = 1.0
            continue
        if kind == "free":
            E[a : a + 3, d : d + 3] = np.eye(3)
            a, d = a + 3, d + 3
        w, x, y, z = qpos[a : a + 4] / np.linalg.norm(qpos[a : a + 4])
        E[a : a + 4, d : d + 3] = 0.5 * np.array([[-x, -y, -z], [w, -z, y], [z, w, -x], [-y, x, w]])
    return E


def test_derivative_of_tree_fk_is_the_jacobian_at_special_points(lib: Lib, features: Tree) -> None:
    """Every frame of a tree with ball and free joints, at identity, antipodal and half-turn
    quaternions and hinges at 0, pi and 2 pi: the derivative along qvel (quaternion rates
    ``q (0, w) / 2``) is ``[w] T`` and ``p_dot = v``, the world Jacobian's rows."""
    base = sample_qpos(features, 1, seed=15)[0]
    for quat, angle in zip(SPECIAL_QUATS[:4], SPECIAL_ANGLES, strict=False):
        qpos = base.copy()
        for k, kind in enumerate(features.joint_types):
            a = int(features.qpos_adr[k])
            if kind in ("ball", "free"):
                qpos[a + (3 if kind == "free" else 0) :][:4] = quat
            elif kind == "revolute":
                qpos[a] = angle
        dT = lib.numpy(lib.jacobian(features.fk, lib.asarray(qpos[None])))[0]  # (F, 4, 4, nq)
        assert np.all(np.isfinite(dT))
        along_qvel = dT @ _qvel_to_qpos(features, qpos)
        T = features.fk(qpos)
        for f, name in enumerate(features.frame_names):
            J = features.jacobian(qpos, name)
            for i in range(features.nv):
                dR = lie.hat_so3(J[:3, i]) @ T[f, :3, :3]
                assert_close(f"{name} R col {i}", along_qvel[f, :3, :3, i], dR, GRAD_TOL)
                assert_close(f"{name} p col {i}", along_qvel[f, :3, 3, i], J[3:, i], GRAD_TOL)


def test_gradients_through_quaternions_are_finite(lib: Lib) -> None:
    """Zero, tiny, unit, antipodal and half-turn quaternions: MuJoCo's normalisation has a
    finite derivative everywhere (the identity where it leaves the quaternion as it is)."""
    quats = np.array([*SPECIAL_QUATS, [1e-20, 0.0, 0.0, 0.0]])
    J = lib.numpy(
        lib.jacobian(lambda x: lie.quat_to_rotation(lie.quat_normalize(x)), lib.asarray(quats))
    )
    assert np.all(np.isfinite(J))


LOG_ANGLES = [0.0, 1e-12, 1e-7, 1e-3, 0.3, 2.0, np.pi - 1e-3, np.pi - 1e-6, np.pi - 1e-9, np.pi]


@pytest.mark.slow
def test_gradients_through_log_near_zero_and_pi(lib: Lib) -> None:
    """d log(exp(w)) / dw is the identity for |w| < pi, near 0 (Taylor branch) and near pi
    (the symmetric-part branch) alike; exactly at pi, where log jumps, it is finite. So is the
    derivative of rotation_angle."""
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    w = axis * np.array(LOG_ANGLES)[:, None]
    J = lib.numpy(lib.jacobian(lambda x: lie.log_so3(lie.exp_so3(x)), lib.asarray(w)))
    xi = np.concatenate([w, np.tile([0.1, -0.2, 0.3], (len(w), 1))], axis=-1)
    J6 = lib.numpy(lib.jacobian_rev(lambda x: lie.log_se3(lie.exp_se3(x)), lib.asarray(xi)))
    assert np.all(np.isfinite(J)) and np.all(np.isfinite(J6))
    below = np.array(LOG_ANGLES) < np.pi
    assert_close("d log(exp(w))/dw", J[below], np.broadcast_to(np.eye(3), J[below].shape), 1e-9)
    assert_close("d log(exp(xi))/dxi", J6[below], np.broadcast_to(np.eye(6), J6[below].shape), 1e-9)
    R = lie.exp_so3(w)
    dangle = lib.numpy(lib.grad(lambda M: lie.rotation_angle(M).sum(), lib.asarray(R)))
    assert np.all(np.isfinite(dangle))


# --- model parameters -----------------------------------------------------------------------------


def _central_differences(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    """``(*f's shape, *x's shape)``."""
    out = []
    for idx in np.ndindex(x.shape):
        step = np.zeros_like(x)
        step[idx] = FD_STEP
        out.append((f(x + step) - f(x - step)) / (2 * FD_STEP))
    return np.moveaxis(np.array(out), 0, -1).reshape(*np.shape(f(x)), *x.shape)


def test_parameters_round_trip(lib: Lib, ur5e: Chain, features: Tree) -> None:
    q = np.random.default_rng(16).uniform(-3, 3, (5, 6))
    params = ur5e.parameters(like=lib.asarray(q))
    assert isinstance(params, ChainParams) and type(params.screws) is type(lib.asarray(q))
    for method in CHAIN_METHODS:  # the general formulas: no coordinate-axis shortcut
        got = lib.numpy(getattr(ur5e, method)(lib.asarray(q), params=params))
        assert_close(method, got, getattr(ur5e, method)(q), PARAM_TOL)
    assert_close("NumPy params", ur5e.fk(q, params=ur5e.parameters()), ur5e.fk(q), PARAM_TOL)
    # a batch of models: leading axes of the parameters broadcast against q's
    S = np.stack([ur5e.screws, ur5e.screws[[1, 0, 2, 3, 4, 5]]])
    stacked = ChainParams(lib.asarray(S), lib.asarray(np.stack([ur5e.home] * 2)))
    got = lib.numpy(ur5e.fk(lib.asarray(q[:2]), params=stacked))
    for k in range(2):
        expected = ur5e.fk(q[k], params=ChainParams(S[k], ur5e.home))
        assert_close(f"model {k} of a batch", got[k], expected, PARAM_TOL)
    rebuilt = ur5e.with_parameters(params)
    assert np.array_equal(rebuilt.screws, ur5e.screws) and rebuilt.joint_names == ur5e.joint_names
    qpos = sample_qpos(features, 5, seed=16)
    tparams = features.parameters(like=lib.asarray(qpos))
    assert isinstance(tparams, TreeParams)
    got = lib.numpy(features.fk(lib.asarray(qpos), params=tparams))
    assert_close("tree params", got, features.fk(qpos), PARAM_TOL)
    got = lib.numpy(features.jacobian(lib.asarray(qpos), "bob", params=tparams))
    assert_close("tree params jacobian", got, features.jacobian(qpos, "bob"), PARAM_TOL)
    assert np.array_equal(features.with_parameters(tparams).body_rot, features.body_rot)


@pytest.mark.slow
def test_chain_parameter_gradients_equal_central_differences(lib: Lib, ur5e: Chain) -> None:
    """d fk / d screws and d fk / d home, space and body form, with the general formulas (the
    UR5e's axes are coordinate axes: a shortcut there would get the axis derivative wrong)."""
    q = np.random.default_rng(17).uniform(-3, 3, 6)
    S, M = ur5e.screws.copy(), ur5e.home.copy()
    x = lib.asarray(q)
    for method in ("fk", "fk_body"):
        fk = getattr(ur5e, method)

        def by_screws(s: Any, m: Any = M, fk: Callable[..., Any] = fk) -> Any:
            return fk(x, params=ChainParams(s, m))

        def by_home(m: Any, fk: Callable[..., Any] = fk) -> Any:
            return fk(x, params=ChainParams(S, m))

        # the differences on the NumPy path: the same formulas, without a library's overhead
        got = lib.numpy(lib.jacobian(by_screws, lib.asarray(S[None])))[0]
        fd = _central_differences(lambda s, fk=fk: fk(q, params=ChainParams(s, M)), S)
        assert_close(f"{method} d/dscrews", got, fd, FD_TOL)
        got = lib.numpy(lib.jacobian_rev(by_home, lib.asarray(M[None])))[0]
        fd = _central_differences(lambda m, fk=fk: fk(q, params=ChainParams(S, m)), M)
        assert_close(f"{method} d/dhome", got, fd, FD_TOL)


@pytest.mark.slow
def test_tree_parameter_gradients_equal_central_differences(lib: Lib, features: Tree) -> None:
    """Every field of TreeParams at once (a pytree): body offsets, joint axes (hinge and slide),
    anchors (hinge and ball), site offsets; a scalar loss of all frames, reverse mode."""
    qpos = sample_qpos(features, 3, seed=18)
    weights = np.random.default_rng(18).normal(size=(3, features.n_frames, 4, 4))
    x, w = lib.asarray(qpos), lib.asarray(weights)
    base = features.parameters()

    def loss(params: TreeParams) -> Any:
        return (features.fk(x, params=params) * w).sum()

    grads = lib.grad(loss, TreeParams(*(lib.asarray(v) for v in base)))
    assert isinstance(grads, TreeParams)
    for field in TreeParams._fields:

        def numpy_loss(v: np.ndarray, field: str = field) -> np.ndarray:
            params = base._replace(**{field: v})
            return np.asarray(np.sum(features.fk(qpos, params=params) * weights))

        fd = _central_differences(numpy_loss, np.array(getattr(base, field)))
        got = lib.numpy(getattr(grads, field))
        assert_close(f"d loss / d {field}", got, fd, FD_TOL * max(1.0, float(np.abs(fd).max())))


# --- what a user sees -----------------------------------------------------------------------------


def test_errors_are_one_line(lib: Lib, ur5e: Chain, features: Tree) -> None:
    with pytest.raises(InputError, match=r"expected 6 joint values \(shape \(\.\.\., 6\)\)"):
        ur5e.fk(lib.asarray(np.zeros((2, 5))))
    with pytest.raises(InputError, match=r"expected 17 qpos values.*qpos = \["):
        features.fk(lib.asarray(np.zeros(3)))
    with pytest.raises(InputError, match="out= takes NumPy arrays only"):
        ur5e.fk(lib.asarray(np.zeros(6)), out=np.empty((4, 4)))
    with pytest.raises(InputError, match="unknown form 'posquat'"):
        ur5e.fk(lib.asarray(np.zeros(6)), form="posquat")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="params must be a ChainParams"):
        ur5e.fk(lib.asarray(np.zeros(6)), params=(ur5e.screws, ur5e.home))  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"params.screws must have shape \(\.\.\., 6, 6\)"):
        ur5e.fk(lib.asarray(np.zeros(6)), params=ChainParams(np.zeros((5, 6)), ur5e.home))
    with pytest.raises(InputError, match="did you mean 'world'"):
        features.jacobian(lib.asarray(features.qpos0), "finger", "wrld")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="expected real numbers"):
        ur5e.fk(lib.asarray(np.zeros(6), "complex128"))


def test_mixing_jax_and_torch_is_refused(ur5e: Chain) -> None:
    jax, torch = load("jax"), load("torch")
    params = ur5e.parameters(like=jax.asarray(np.zeros(1)))
    with pytest.raises(InputError, match="mix JAX arrays and PyTorch tensors"):
        ur5e.fk(torch.asarray(np.zeros(6)), params=params)


def test_a_missing_array_api_compat_names_the_extra(
    lib: Lib, ur5e: Chain, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(poekin.arrays, "_namespaces", {})
    monkeypatch.setitem(sys.modules, "array_api_compat", None)  # import fails
    with pytest.raises(poekin.MissingExtraError) as info:
        ur5e.fk(lib.asarray(np.zeros(6)))
    what = "JAX arrays" if lib.name == "jax" else "PyTorch tensors"
    assert str(info.value) == (
        f"{what} needs array-api-compat, which is not installed: {install_command(lib.name)}"
    )


def test_importing_poekin_imports_no_array_library() -> None:
    """``import poekin`` and NumPy FK leave JAX, PyTorch and array-api-compat unimported."""
    code = (
        "import sys, numpy as np, poekin\n"
        "c = poekin.Chain(('j',), ('revolute',), [[0, 0, 1, 0, 0, 0]], np.eye(4))\n"
        "c.fk([0.5]); c.fk(np.zeros((3, 1))); c.jacobian_world([0.5])\n"
        "print(sorted(m for m in ('jax', 'torch', 'array_api_compat') if m in sys.modules))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_with_parameters_refuses_traced_values_and_bad_models(ur5e: Chain) -> None:
    jax = load("jax")

    def build(screws: Any) -> Any:
        ur5e.with_parameters(ChainParams(screws, ur5e.home))
        return screws.sum()

    with pytest.raises(InputError, match="traced JAX value; build the model outside jit"):
        jax.module.jit(build)(jax.asarray(ur5e.screws))
    bent = ur5e.screws.copy()
    bent[0, :3] *= 1.1
    with pytest.raises(InputError, match="unit axis"):
        ur5e.with_parameters(ChainParams(jax.asarray(bent), ur5e.home))
