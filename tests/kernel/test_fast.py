"""The compiled FK kernel against the pure-NumPy reference path, for every joint type and form,
its batch, thread and ``out=`` behaviour, and the errors a user sees."""

from __future__ import annotations

import copy
import dataclasses
import inspect
import os
import pathlib
import pickle
import re
import warnings

import mujoco
import numpy as np
import pytest
from helpers import assert_close, load_quiet
from test_chain import random_chain
from test_tree import FEATURES_XML, MENAGERIE, _two_link

import poekin
from poekin import InputError, lie
from poekin.chain import Chain
from poekin.io.import_mujoco import tree_from_model
from poekin.kernel import _fast
from poekin.tree import Mimic, Tree
from poekin.verification.verify import sample_qpos

# Kernel vs reference. Both do the same arithmetic in the same order; they differ only in sin
# and cos (the kernel's own, below 1 ulp, against the C library's), which moves a pose by a
# few 1e-16 on metre-sized robots. Issue #5 asks for <= 1e-15.
REF_TOL = 1e-15
URDF = pathlib.Path(__file__).parents[1] / "data" / "urdf"
N_SAMPLES = 10_000
BATCH_SHAPES = [(), (1,), (3, 1, 2, 1)]
FORMS = ["4x4", "3x4", "pos_quat"]


@pytest.fixture(scope="module")
def features() -> Tree:
    return tree_from_model(mujoco.MjModel.from_xml_string(FEATURES_XML))


def test_the_compiled_kernel_is_installed() -> None:
    """CI sets POEKIN_REQUIRE_COMPILED=1, so a silently failed build cannot pass as NumPy."""
    if os.environ.get("POEKIN_REQUIRE_COMPILED") != "1" and not poekin.compiled_kernel():
        pytest.skip("built without a C compiler: the NumPy path serves")
    assert poekin.compiled_kernel()


# --- the same results as the reference path ------------------------------------------------


@pytest.mark.parametrize("form", ["fk", "fk_body"])
def test_chain_equals_the_reference(ur5e: Chain, form: str) -> None:
    q = np.random.default_rng(0).uniform(-2 * np.pi, 2 * np.pi, (N_SAMPLES, 6))
    reference = ur5e._fk_numpy if form == "fk" else ur5e._fk_body_numpy
    assert_close(f"UR5e {form}", getattr(ur5e, form)(q), reference(q), REF_TOL)


@pytest.mark.parametrize("seed", range(5))
def test_random_revolute_and_prismatic_chains_equal_the_reference(seed: int) -> None:
    """Random chains reach ~10 m (prismatic joints at 2 pi m, random homes): the tolerance
    scales with the largest coordinate, as rounding does."""
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, 7)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (2_000, 7))
    for form in ("fk", "fk_body"):
        expected = getattr(chain, f"_{form}_numpy")(q)
        tol = REF_TOL * max(1.0, float(np.abs(expected).max()))
        assert_close(form, getattr(chain, form)(q), expected, tol)


def test_coordinate_axis_chains_equal_the_reference() -> None:
    """Axes along +-x, +-y, +-z, with and without pitch: the kernel's AXIS operations, each of
    the six (three axes, pitched or not) met at least once."""
    codes: set[int] = set()
    for seed in range(20):
        rng = np.random.default_rng(seed)
        chain = random_chain(rng, 7, aligned=True)
        q = rng.uniform(-2 * np.pi, 2 * np.pi, (1_000, 7))
        for form in ("fk", "fk_body"):
            expected = getattr(chain, f"_{form}_numpy")(q)
            tol = REF_TOL * max(1.0, float(np.abs(expected).max()))
            assert_close(f"seed {seed} {form}", getattr(chain, form)(q), expected, tol)
        for kernel in (chain._space_kernel, chain._body_kernel):
            if kernel is not None:
                codes |= set(kernel.__reduce__()[1][0][:, 0].tolist())
    if not poekin.compiled_kernel():
        return  # the NumPy path served both sides: nothing more to check
    axis_codes = set(range(_fast._AXIS, _fast._AXIS_PITCH + 3))
    assert axis_codes <= codes, f"AXIS operations never built: {sorted(axis_codes - codes)}"


@pytest.mark.parametrize("robot", MENAGERIE)
def test_menagerie_trees_equal_the_reference(robot: str) -> None:
    tree = poekin.load_tree(load_quiet(robot))
    qpos = sample_qpos(tree, N_SAMPLES, seed=3)
    assert_close(f"{robot} frames", tree.fk(qpos), tree._fk_numpy(qpos), REF_TOL)


def test_every_joint_type_equals_the_reference(features: Tree) -> None:
    """Hinge, slide, ball and free joints, refs and anchors, unnormalised and zero quaternions."""
    rng = np.random.default_rng(4)
    qpos = sample_qpos(features, N_SAMPLES, seed=4)
    for name in ("wrist_ball", "float"):
        k = features.joint_names.index(name)
        a = features.qpos_adr[k] + (3 if name == "float" else 0)
        qpos[: N_SAMPLES // 2, a : a + 4] *= rng.uniform(1e-3, 1e3, (N_SAMPLES // 2, 1))
        qpos[:10, a : a + 4] = 0.0  # the identity, as in MuJoCo
    assert_close("features", features.fk(qpos), features._fk_numpy(qpos), REF_TOL)


@pytest.mark.parametrize("leader_first", [True, False])
def test_mimic_joints_equal_the_reference(leader_first: bool) -> None:
    mimic = Mimic("j1" if leader_first else "j2", multiplier=-2.0, offset=0.25)
    tree = _two_link((None, mimic) if leader_first else (mimic, None))
    q = np.random.default_rng(5).uniform(-10, 10, (1_000, 1))
    assert_close("mimic", tree.fk(q), tree._fk_numpy(q), REF_TOL)


def test_urdf_followers_before_their_leader_equal_the_reference() -> None:
    tree = poekin.load_tree(URDF / "gripper_mimic_later.urdf")
    qpos = sample_qpos(tree, N_SAMPLES, seed=5)
    assert_close("gripper", tree.fk(qpos), tree._fk_numpy(qpos), REF_TOL)


@pytest.mark.parametrize("scale", [1e3, 1e5, 6e5, 1e6, 1e9])
def test_huge_angles_equal_the_reference(ur5e: Chain, scale: float) -> None:
    """Beyond 2^19 rad sin and cos come from the C library; below, from the kernel's own."""
    q = np.random.default_rng(6).uniform(-scale, scale, (1_000, 6))
    q[::7] = 0.5  # blocks that mix small and huge angles
    assert_close(f"|q| <= {scale:g}", ur5e.fk(q), ur5e._fk_numpy(q), REF_TOL)


# --- forms, batch axes, out= ---------------------------------------------------------------


@pytest.mark.parametrize("form", FORMS)
def test_forms_are_views_of_the_4x4_pose(ur5e: Chain, features: Tree, form: str) -> None:
    q = np.random.default_rng(7).uniform(-6, 6, (500, 6))
    qpos = sample_qpos(features, 500, seed=7)
    for what, fk, x in (("chain", ur5e.fk, q), ("tree", features.fk, qpos)):
        T = fk(x)
        expected = _fast.reformat(T, form)
        assert_close(f"{what} {form}", fk(x, form=form), expected, 1e-15)
    quat = ur5e.fk(q, form="pos_quat")[..., 3:]
    assert np.all(quat[..., 0] >= 0), "quaternions are wxyz with w >= 0"
    # Shepperd's method does not renormalise: R's own rounding (~1e-15) shows in |quat|
    assert_close("unit quaternions", np.linalg.norm(quat, axis=-1), np.ones(500), 1e-14)


def test_pos_quat_is_rotation_to_quat_bit_for_bit_in_every_case(ur5e: Chain) -> None:
    rng = np.random.default_rng(17)
    q = rng.uniform(-6, 6, (2000, 6))
    q[:1000] = rng.integers(-4, 5, (1000, 6)) * (np.pi / 2)  # ties between the candidates
    T = ur5e.fk(q)
    R = T[..., :3, :3]
    d0, d1, d2 = np.moveaxis(np.diagonal(R, 0, -2, -1), -1, 0)
    diag = np.stack([1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2], -1)
    assert set(np.argmax(diag, -1)) == {0, 1, 2, 3}, "w, x, y and z each the largest somewhere"
    pq = ur5e.fk(q, form="pos_quat")  # every width's the same bits: see the test below
    assert np.array_equal(pq[..., 3:], lie.rotation_to_quat(R))
    assert np.array_equal(pq[..., :3], T[..., :3, 3])


@pytest.mark.parametrize("batch", BATCH_SHAPES)
@pytest.mark.parametrize("form", FORMS)
def test_batch_axes_and_shapes(ur5e: Chain, features: Tree, batch: tuple, form: str) -> None:
    rng = np.random.default_rng(8)
    q = rng.uniform(-6, 6, (*batch, 6))
    tail = {"4x4": (4, 4), "3x4": (3, 4), "pos_quat": (7,)}[form]
    assert ur5e.fk(q, form=form).shape == (*batch, *tail)
    assert ur5e.fk_body(q, form=form).shape == (*batch, *tail)
    qpos = sample_qpos(features, int(np.prod(batch)), seed=8).reshape(*batch, features.nq)
    assert features.fk(qpos, form=form).shape == (*batch, features.n_frames, *tail)


def test_one_configuration_gives_the_same_bits_alone_or_in_a_batch(ur5e: Chain) -> None:
    q = np.random.default_rng(9).uniform(-6, 6, (37, 6))
    batch = ur5e.fk(q)
    for i in range(len(q)):
        assert np.array_equal(ur5e.fk(q[i]), batch[i]), f"configuration {i}"


def test_thread_count_does_not_change_the_bits(ur5e: Chain, features: Tree) -> None:
    q = np.random.default_rng(10).uniform(-6, 6, (50_003, 6))  # several threads' worth
    qpos = sample_qpos(features, 40_001, seed=10)
    before = poekin.get_threads()
    try:
        poekin.set_threads(1)
        one = ur5e.fk(q), features.fk(qpos)
        poekin.set_threads(4)
        four = ur5e.fk(q), features.fk(qpos)
    finally:
        poekin.set_threads(before)
    assert np.array_equal(one[0], four[0]) and np.array_equal(one[1], four[1])


def _widths() -> list[int]:
    """The kernel widths this CPU runs (8: AVX-512, 4: AVX2, 2: any)."""
    if not poekin.compiled_kernel():
        return []
    best = _fast._kernel.set_width(0)  # the widest
    _fast._kernel.set_width(_fast.DEFAULT_WIDTH)
    return [w for w in (2, 4, 8) if w <= best]


@pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")
def test_the_environment_chooses_the_kernel_width() -> None:
    """POEKIN_KERNEL_WIDTH picks a narrower kernel at import (CI runs the kernel's tests so);
    a width this CPU does not run is a warning that names the ones it does, not an error."""
    import subprocess
    import sys

    code = "import poekin.kernel._fast as f; print(f._kernel.get_width(), f.DEFAULT_WIDTH)"
    for width in (w for w in (2, 4, 8) if w <= max(_widths())):
        env = {**os.environ, "POEKIN_KERNEL_WIDTH": str(width)}
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert out.stdout.split() == [str(width)] * 2, out.stderr
    env = {**os.environ, "POEKIN_KERNEL_WIDTH": "16"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert "KernelWidthWarning: POEKIN_KERNEL_WIDTH='16' is not a width this CPU runs" in out.stderr
    assert out.stdout.split() == [str(max(_widths()))] * 2


@pytest.mark.parametrize("form", FORMS)
def test_every_instruction_set_gives_the_same_bits(ur5e: Chain, features: Tree, form: str) -> None:
    """The AVX-512, AVX2 and SSE2/NEON kernels do the same operations in the same order."""
    widths = _widths()
    if len(widths) < 2:
        pytest.skip("this CPU runs one kernel width")
    q = np.random.default_rng(15).uniform(-7, 7, (1_001, 6))
    q[5] = 1e6  # a huge angle: the C library's sin and cos in that block
    qpos = sample_qpos(features, 1_001, seed=15)
    results = {}
    try:
        for w in widths:
            _fast._kernel.set_width(w)
            results[w] = (
                ur5e.fk(q, form=form),
                ur5e.fk_body(q, form=form),
                features.fk(qpos, form=form),
            )
    finally:
        _fast._kernel.set_width(_fast.DEFAULT_WIDTH)
    for w in widths[1:]:
        for a, b in zip(results[widths[0]], results[w], strict=True):
            assert np.array_equal(a, b), f"width {w} differs from width {widths[0]}"


@pytest.mark.parametrize("form", FORMS)
def test_out_is_filled_and_returned(ur5e: Chain, features: Tree, form: str) -> None:
    q = np.random.default_rng(11).uniform(-6, 6, (3, 4, 6))
    out = np.full(ur5e.fk(q, form=form).shape, np.nan)
    assert ur5e.fk(q, out=out, form=form) is out
    assert np.array_equal(out, ur5e.fk(q, form=form))
    qpos = sample_qpos(features, 5, seed=11)
    out_t = np.empty(features.fk(qpos, form=form).shape)
    assert features.fk(qpos, out=out_t, form=form) is out_t
    assert np.array_equal(out_t, features.fk(qpos, form=form))
    by_position = np.empty_like(out)
    assert ur5e.fk_body(q, by_position, form) is by_position  # out and form by position too
    assert np.array_equal(by_position, ur5e.fk_body(q, out=out, form=form))


@pytest.mark.parametrize(
    ("out", "message"),
    [
        (np.empty((5, 4, 4), dtype=np.float32), "float64"),
        (np.empty((4, 5, 4)), "shape (5, 4, 4)"),
        (np.empty((5, 4, 8))[..., ::2], "C-contiguous"),
        ([[0.0] * 4] * 4, "got list"),
    ],
)
def test_bad_out_is_an_input_error(ur5e: Chain, out: object, message: str) -> None:
    with pytest.raises(InputError, match="out must be") as info:
        ur5e.fk(np.zeros((5, 6)), out=out)  # type: ignore[arg-type]
    assert message in str(info.value)


def test_read_only_out_is_refused(ur5e: Chain) -> None:
    out = np.empty((4, 4))
    out.flags.writeable = False
    with pytest.raises(InputError, match="writeable"):
        ur5e.fk(np.zeros(6), out=out)


def test_unknown_form_suggests_the_near_miss(ur5e: Chain) -> None:
    with pytest.raises(InputError, match="'pos_quat'"):
        ur5e.fk(np.zeros(6), form="posquat")  # type: ignore[arg-type]


# --- inputs the fast path hands back to validation ------------------------------------------


def test_inputs_that_need_converting_give_the_same_poses(ur5e: Chain) -> None:
    q = np.random.default_rng(12).uniform(-3, 3, (10, 6))
    expected = ur5e.fk(q)
    for what, x in [
        ("list", q.tolist()),
        ("Fortran order", np.asfortranarray(q)),
        ("strided", np.repeat(q, 2, axis=0)[::2]),
        ("big-endian", q.astype(">f8")),
    ]:
        assert_close(what, ur5e.fk(x), expected, 0.0)
    assert_close("int", ur5e.fk(np.ones(6, dtype=int)), ur5e.fk(np.ones(6)), 0.0)
    q32 = q.astype(np.float32)
    assert_close("float32", ur5e.fk(q32), ur5e.fk(q32.astype(np.float64)), 0.0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_values_are_refused_on_the_fast_path(ur5e: Chain, bad: float) -> None:
    q = np.zeros((100, 6))
    q[57, 3] = bad
    with pytest.raises(InputError, match="NaN or inf"):
        ur5e.fk(q)
    with pytest.raises(InputError, match="NaN or inf"):
        ur5e.fk(q[57])


def test_wrong_length_is_refused_with_the_layout(features: Tree) -> None:
    with pytest.raises(InputError, match=f"expected {features.nq} qpos values"):
        features.fk(np.zeros(features.nq + 1))


# --- settings, pickling, the NumPy fallback -------------------------------------------------


@pytest.mark.parametrize("bad", [0, -1, 257, 2.0, True, "2"])
def test_set_threads_refuses_nonsense(bad: object) -> None:
    with pytest.raises(InputError, match="threads must be an integer from 1 to 256"):
        poekin.set_threads(bad)  # type: ignore[arg-type]


def test_set_threads_none_restores_the_default(monkeypatch: pytest.MonkeyPatch) -> None:
    before = poekin.get_threads()
    monkeypatch.setenv("POEKIN_NUM_THREADS", "3")
    try:
        poekin.set_threads(1)
        assert poekin.get_threads() == 1
        poekin.set_threads(None)
        assert poekin.get_threads() == 3
    finally:
        poekin.set_threads(before)


def test_chains_and_trees_pickle_and_copy(ur5e: Chain, features: Tree) -> None:
    q = np.random.default_rng(13).uniform(-3, 3, (20, 6))
    qpos = sample_qpos(features, 20, seed=13)
    for clone in (pickle.loads(pickle.dumps(ur5e)), copy.deepcopy(ur5e)):
        assert np.array_equal(clone.fk(q), ur5e.fk(q))
    assert np.array_equal(pickle.loads(pickle.dumps(features)).fk(qpos), features.fk(qpos))


def test_bound_methods_pickle_by_value_as_dask_sends_them(ur5e: Chain, features: Tree) -> None:
    """cloudpickle (Dask's, Ray's) pickles ``chain.fk`` as its function and its chain; the
    function is the compiled descriptor, which pickles as the class attribute it is."""
    cloudpickle = pytest.importorskip("cloudpickle")
    q = np.random.default_rng(15).uniform(-3, 3, (20, 6))
    qpos = sample_qpos(features, 20, seed=15)
    for method, x in ((ur5e.fk, q), (ur5e.jacobian_world, q), (features.fk, qpos)):
        for dumps in (pickle.dumps, cloudpickle.dumps):
            clone = pickle.loads(dumps(method))
            assert np.array_equal(clone(x), method(x))
    assert pickle.loads(cloudpickle.dumps(Chain.fk)) is Chain.fk


def test_without_the_kernel_the_numpy_path_gives_the_same_poses(
    ur5e: Chain, features: Tree, monkeypatch: pytest.MonkeyPatch
) -> None:
    q = np.random.default_rng(14).uniform(-6, 6, (200, 6))
    qpos = sample_qpos(features, 200, seed=14)
    expected = {f: (ur5e.fk(q, form=f), features.fk(qpos, form=f)) for f in FORMS}
    monkeypatch.setattr(_fast, "_kernel", None)
    chain = Chain(ur5e.joint_names, ur5e.joint_types, ur5e.screws, ur5e.home)
    tree = dataclasses.replace(features)  # built again: now without a kernel
    assert chain._space_kernel is None and tree._kernel is None
    for f in FORMS:
        assert_close(f"chain {f}", chain.fk(q, form=f), expected[f][0], REF_TOL)
        assert_close(f"tree {f}", tree.fk(qpos, form=f), expected[f][1], REF_TOL)
    out = np.empty((200, 4, 4))
    assert chain.fk(q, out=out) is out
    assert all(getattr(chain, f"_jacobian_{c}_kernel") is None for c in JACOBIANS)
    for c in ("space", "body", "world"):
        J = getattr(chain, f"jacobian_{c}")(q)
        assert_close(f"chain jacobian_{c}", J, getattr(ur5e, f"jacobian_{c}")(q), REF_TOL)
        J = tree.jacobian(qpos, "finger", c)
        assert_close(f"tree jacobian {c}", J, features.jacobian(qpos, "finger", c), REF_TOL)
    assert tree._jacobian_kernels and all(k is None for k in tree._jacobian_kernels.values())


def test_without_the_kernel_a_big_batch_says_so_once(
    ur5e: Chain, monkeypatch: pytest.MonkeyPatch
) -> None:
    """issue #15: the NumPy path is 40-130x slower in batches; say it when it matters, once."""
    monkeypatch.setattr(_fast, "_kernel", None)
    monkeypatch.setattr(_fast, "_slow_noted", False)
    chain = Chain(ur5e.joint_names, ur5e.joint_types, ur5e.screws, ur5e.home)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        chain.fk(np.zeros((100, 6)))  # small: no note
        assert caught == []
        chain.fk(np.zeros((10_000, 6)))
        chain.jacobian_space(np.zeros((20_000, 6)))
    (note,) = caught
    assert note.category is _fast.SlowPathWarning
    assert str(note.message) == _fast.kernel_description()
    assert "the NumPy path, 40 to 130 times slower in batches" in str(note.message)
    assert "reinstall poekin with a C compiler" in str(note.message)


# --- the methods that run the kernel before any Python (_fast.fast_method) -----------------

FAST_METHODS = [
    (Chain, "fk"),
    (Chain, "fk_body"),
    (Tree, "fk"),
    *((Chain, f"jacobian_{c}") for c in ("space", "body", "world")),
]


@pytest.mark.parametrize(("cls", "name"), FAST_METHODS)
def test_fast_methods_keep_the_signature_name_and_docs(cls: type, name: str) -> None:
    method = getattr(cls, name)
    python = method.__wrapped__
    assert isinstance(method, poekin.kernel._kernel.FastMethod) and callable(python)
    assert inspect.signature(method) == inspect.signature(python)
    assert (method.__name__, method.__qualname__) == (name, f"{cls.__name__}.{name}")
    assert method.__doc__ and method.__doc__ == python.__doc__


CALLS = [  # (args, kwargs) after q; all ask for the same 3x4 poses written into out
    ((), {"out": "out", "form": "3x4"}),
    (("out",), {"form": "3x4"}),
    (("out", "3x4"), {}),
    ((), {"form": "3x4", "out": "out"}),
]


@pytest.mark.parametrize(("args", "kwargs"), CALLS)
@pytest.mark.parametrize("q_by_name", [False, True])
def test_fast_methods_take_arguments_by_position_or_name(
    ur5e: Chain, args: tuple, kwargs: dict, q_by_name: bool
) -> None:
    q = np.random.default_rng(15).uniform(-6, 6, (5, 6))
    expected = ur5e.fk(q)[..., :3, :]
    out = np.empty((5, 3, 4))
    args = tuple(out if a == "out" else a for a in args)
    kwargs = {k: out if v == "out" else v for k, v in kwargs.items()}
    got = ur5e.fk(q=q, **kwargs) if q_by_name and not args else ur5e.fk(q, *args, **kwargs)
    assert got is out
    assert np.array_equal(out, expected)


@pytest.mark.parametrize(
    ("args", "kwargs"),
    [
        ((), {}),
        ((np.zeros(6),), {"bogus": 1}),
        ((np.zeros(6),), {"q": np.zeros(6)}),
        ((np.zeros(6), None, "4x4", 1), {}),
        ((np.zeros(6), None), {"out": None}),
    ],
)
def test_fast_methods_refuse_bad_calls_as_python_does(
    ur5e: Chain, args: tuple, kwargs: dict
) -> None:
    with pytest.raises(TypeError) as python:
        Chain.fk.__wrapped__(ur5e, *args, **kwargs)
    with pytest.raises(TypeError, match="^" + re.escape(str(python.value)) + "$"):
        ur5e.fk(*args, **kwargs)


def test_fast_methods_work_unbound_and_bound(ur5e: Chain, features: Tree) -> None:
    q = np.random.default_rng(16).uniform(-6, 6, (3, 6))
    qpos = sample_qpos(features, 3, seed=16)
    assert np.array_equal(Chain.fk(ur5e, q), ur5e.fk(q))
    bound = ur5e.fk_body  # a bound method object, called later
    assert bound.__self__ is ur5e
    assert np.array_equal(bound(q), ur5e.fk_body(q))
    assert np.array_equal(
        Tree.fk(features, qpos, None, "pos_quat"), features.fk(qpos, form="pos_quat")
    )


def test_without_the_kernel_fast_method_is_the_function(monkeypatch: pytest.MonkeyPatch) -> None:
    def fk(self: object, q: object, out: object = None, form: str = "4x4") -> object:
        return q

    assert isinstance(_fast.fast_method("_kernel")(fk), poekin.kernel._kernel.FastMethod)
    monkeypatch.setattr(_fast, "_kernel", None)
    assert _fast.fast_method("_kernel")(fk) is fk


# --- Jacobians ------------------------------------------------------------------------------

JACOBIANS = ["space", "body", "world"]


@pytest.mark.parametrize("convention", JACOBIANS)
def test_ur5e_jacobians_equal_the_reference(ur5e: Chain, convention: str) -> None:
    q = np.random.default_rng(15).uniform(-2 * np.pi, 2 * np.pi, (N_SAMPLES, 6))
    got = getattr(ur5e, f"jacobian_{convention}")(q)
    assert_close(f"UR5e {convention}", got, ur5e._jacobian_numpy(convention, q), REF_TOL)


@pytest.mark.parametrize("seed", range(6))
def test_random_chain_jacobians_equal_the_reference(seed: int) -> None:
    """Random and coordinate-axis chains, pitched screws and prismatic joints; the tolerance
    scales with the chain's reach and the Jacobian's size, as rounding does."""
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, 7, aligned=seed % 2 == 0)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (2_000, 7))
    reach = float(np.abs(chain.fk(q)[..., :3, 3]).max())  # the world form rounds at w x p
    for convention in JACOBIANS:
        expected = chain._jacobian_numpy(convention, q)
        tol = REF_TOL * max(1.0, reach, float(np.abs(expected).max()))
        assert_close(convention, getattr(chain, f"jacobian_{convention}")(q), expected, tol)


@pytest.mark.parametrize("robot", [*MENAGERIE, "features", "mimic", "gripper_mimic_later.urdf"])
def test_tree_jacobians_equal_the_reference(robot: str, features: Tree) -> None:
    """Every frame in every convention: hinge, slide, ball, free and mimic joints (followers
    after and before their leaders)."""
    if robot == "features":
        tree = features
    elif robot == "mimic":
        tree = _two_link((None, Mimic("j1", multiplier=-2.0, offset=0.25)))
    elif robot.endswith(".urdf"):
        tree = poekin.load_tree(URDF / robot)
    else:
        tree = poekin.load_tree(load_quiet(robot))
    qpos = sample_qpos(tree, 500, seed=17)
    tol = REF_TOL * max(1.0, float(np.abs(tree.fk(qpos)[..., :3, 3]).max()))
    for f, name in enumerate(tree.frame_names):
        for convention in JACOBIANS:
            expected = tree._jacobian_numpy(qpos, f, convention)
            assert_close(
                f"{name} {convention}", tree.jacobian(qpos, name, convention), expected, tol
            )


@pytest.mark.parametrize("batch", BATCH_SHAPES)
def test_jacobian_batches_give_the_same_bits_as_single_calls(ur5e: Chain, batch: tuple) -> None:
    q = np.random.default_rng(16).uniform(-6, 6, (*batch, 6))
    J = ur5e.jacobian_body(q)
    assert J.shape == (*batch, 6, 6)
    for idx in np.ndindex(batch):
        assert np.array_equal(J[idx], ur5e.jacobian_body(q[idx]))
    lists = ur5e.jacobian_world(q.tolist())  # converted, validated, then the kernel
    assert np.array_equal(lists, ur5e.jacobian_world(q))
    with pytest.raises(InputError, match="NaN or inf"):
        ur5e.jacobian_space(np.full((*batch, 6), np.inf))


def test_a_kernel_refuses_operations_out_of_range() -> None:
    if not poekin.compiled_kernel():
        pytest.skip("no compiled kernel")
    ops = np.array([[_fast._LOAD, 0, 0, 5]], dtype=np.int32)  # slot 5 of 1
    with pytest.raises(ValueError, match="operation 0 is out of range"):
        _fast._kernel.Kernel(ops, np.zeros(1), 0, 1, 1, False)


def test_python_sees_a_get_and_call_of_the_python_method(ur5e: Chain) -> None:
    """Tools that trace Python (torch.compile) read FastMethod.__get__ and __call__ from the
    type: they bind and call the Python method, which gives the kernel's results; the
    interpreter keeps the C slots."""
    if not poekin.compiled_kernel():
        pytest.skip("no compiled kernel")
    q = np.random.default_rng(18).uniform(-6, 6, (3, 6))
    for name in ("fk", "fk_body", "jacobian_world"):
        method = getattr(Chain, name)
        python = type(method).__get__(method, ur5e, Chain)
        assert python.__func__ is method.__wrapped__ and python.__self__ is ur5e
        assert type(method).__get__(method, None, Chain) is method
        assert np.array_equal(python(q), getattr(ur5e, name)(q))
        assert np.array_equal(type(method).__call__(method, ur5e, q), python(q))
        assert isinstance(getattr(ur5e, name).__func__, poekin.kernel._kernel.FastMethod)
