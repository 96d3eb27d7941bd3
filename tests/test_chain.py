"""Chain: PoE forward kinematics on random chains, against a product of general exponentials."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from poekin import Chain, InputError, adjoint, exp_se3, inverse, named_params

# Products of <= 8 exponentials of unit screws with |q| <= 2 pi and offsets <= 1 m: each factor
# rounds at ~1e-16 relative, so 1e-13 leaves a wide margin while catching any real mistake.
TOL = 1e-13
BATCH_SHAPES = [(), (1,), (3, 1, 2)]


def random_chain(rng: np.random.Generator, n: int, *, aligned: bool = False) -> Chain:
    """A chain of ``n`` joints with random axes, axis points and joint types.

    ``aligned``: every axis along +-x, +-y or +-z, some revolute screws with a pitch, and a home
    whose rotation permutes the axes, so space and body screws both take the coordinate-axis
    path (``lie.coordinate_axis``) that most real robots take.
    """
    screws, types = np.zeros((n, 6)), []
    for i in range(n):
        if aligned:
            axis = np.zeros(3)
            axis[rng.integers(3)] = rng.choice([-1.0, 1.0])
        else:
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
        if rng.random() < 0.3:
            screws[i, 3:] = axis
            types.append("prismatic")
        else:
            point = rng.uniform(-1, 1, size=3)
            pitch = rng.uniform(-0.1, 0.1) if aligned and rng.random() < 0.3 else 0.0
            screws[i] = np.r_[axis, -np.cross(axis, point) + pitch * axis]
            types.append("revolute")
    home = exp_se3(rng.normal(size=6))
    if aligned:
        home[:3, :3] = np.eye(3)[rng.permutation(3)] * rng.choice([-1.0, 1.0], size=3)
        home[:3, :3] *= np.sign(np.linalg.det(home[:3, :3]))  # a rotation, det +1
    return Chain(tuple(f"j{i}" for i in range(n)), tuple(types), screws, home)


def reference_fk(chain: Chain, q: np.ndarray) -> np.ndarray:
    """Textbook PoE with the general SE(3) exponential, one configuration at a time."""
    out = np.empty((*q.shape[:-1], 4, 4))
    for idx in np.ndindex(q.shape[:-1]):
        T = np.eye(4)
        for S, qi in zip(chain.screws, q[idx], strict=True):
            T = T @ exp_se3(S * qi)
        out[idx] = T @ chain.home
    return out


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 8), shape=st.sampled_from(BATCH_SHAPES))
def test_space_and_body_fk_match_reference(seed: int, n: int, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, n)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, size=(*shape, n))
    expected = reference_fk(chain, q)
    assert_close("fk", chain.fk(q), expected, TOL)
    assert_close("fk_body", chain.fk_body(q), expected, TOL)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 8), shape=st.sampled_from(BATCH_SHAPES))
def test_coordinate_axis_chains_match_reference(seed: int, n: int, shape: tuple[int, ...]) -> None:
    """Screws along +-x, +-y, +-z, with and without pitch, in space and body form."""
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, n, aligned=True)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, size=(*shape, n))
    expected = reference_fk(chain, q)
    assert_close("fk", chain.fk(q), expected, TOL)
    assert_close("fk_body", chain.fk_body(q), expected, TOL)
    assert_close("fk(0)", chain.fk(np.zeros(n)), chain.home, 0.0)
    assert_close("fk_body(0)", chain.fk_body(np.zeros(n)), chain.home, 0.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), aligned=st.booleans())
def test_whole_turns_do_not_move_the_end(seed: int, aligned: bool) -> None:
    """Revolute joints without pitch at ~1e6 rad (past the kernel's own reduction, 2^19) pose
    the end as the same angles mod 2 pi do, to the resolution of the angle (ulp(1e6) =
    1.2e-10 rad) times the chain's reach of a few metres."""
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, 6, aligned=aligned)
    q = rng.uniform(-np.pi, np.pi, (50, 6))
    pitch = np.sum(chain.screws[:, :3] * chain.screws[:, 3:], axis=-1)  # helical screws advance
    turning = np.array([t == "revolute" for t in chain.joint_types]) & (np.abs(pitch) < 1e-12)
    turns = 2 * np.pi * rng.integers(-160_000, 160_000, (50, 6))
    assert_close("fk", chain.fk(q + turning * turns), chain.fk(q), 1e-8)
    assert_close("fk_body", chain.fk_body(q + turning * turns), chain.fk_body(q), 1e-8)


@pytest.mark.parametrize("scale", [0.0, 1e-12, 1e-7])
def test_fk_near_home(scale: float) -> None:
    rng = np.random.default_rng(1)
    chain = random_chain(rng, 6)
    q = scale * rng.normal(size=6)
    assert_close("fk", chain.fk(q), reference_fk(chain, q), TOL)
    if scale == 0.0:
        assert_close("fk(0)", chain.fk(q), chain.home, 0.0)


def test_body_screws_are_adjoint_of_space_screws() -> None:
    chain = random_chain(np.random.default_rng(2), 5)
    expected = (adjoint(inverse(chain.home)) @ chain.screws.T).T
    assert_close("body_screws", chain.body_screws, expected, 1e-15)


def test_batched_result_equals_one_at_a_time() -> None:
    chain = random_chain(np.random.default_rng(3), 6)
    q = np.random.default_rng(4).uniform(-6, 6, size=(3, 1, 2, 6))
    batched = chain.fk(q)
    for idx in np.ndindex(q.shape[:-1]):
        assert_close(f"fk{idx}", batched[idx], chain.fk(q[idx]), 0.0)


def test_chain_is_immutable() -> None:
    chain = random_chain(np.random.default_rng(5), 3)
    for name in ("screws", "home", "body_screws", "limits"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(chain, name)[0, 0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        chain.home = np.eye(4)  # type: ignore[misc]


def test_chain_copies_its_inputs() -> None:
    screws = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]])
    chain = Chain(("a",), ("revolute",), screws, np.eye(4))
    screws[0, 2] = 5.0
    assert chain.screws[0, 2] == 1.0


def test_dtypes_and_empty_batch() -> None:
    chain = random_chain(np.random.default_rng(6), 4)
    q64 = np.array([1.0, -2.0, 0.5, 3.0])
    assert chain.fk(q64.astype(np.float32)).dtype == np.float64
    assert_close("int q", chain.fk([1, -2, 0, 3]), chain.fk([1.0, -2.0, 0.0, 3.0]), 0.0)
    assert chain.fk(np.zeros((0, 4))).shape == (0, 4, 4)
    assert chain.fk_body(np.zeros((2, 0, 4))).shape == (2, 0, 4, 4)


@pytest.mark.parametrize(
    ("q", "match"),
    [
        ([0.0, 1.0], r"expected 4 joint values .* shape \(2,\)"),
        (np.zeros((3, 5)), r"expected 4 joint values .* shape \(3, 5\)"),
        (1.0, r"expected 4 joint values"),
        ([0.0, np.nan, 0.0, 0.0], "NaN or inf"),
        ([0.0, np.inf, 0.0, 0.0], "NaN or inf"),
        (["a", "b", "c", "d"], "must be numbers, got 'a'"),
        # issue 20: not numbers is not "NaN or inf"; complex is refused, not cast to real
        (np.array([None] * 4), r"must be numbers, got None in array\(\[None"),
        ([0.0, None, 0.0, 0.0], "must be numbers, got None"),
        (np.zeros(4) + 1j, "must be real numbers, got complex numbers"),
        ([0.0, 0.0, 1j, 0.0], "must be real numbers, got complex numbers"),
        (np.array([0, 0, np.complex64(1), 0], dtype=object), "got complex numbers"),
        ([{}, 0.0, 0.0, 0.0], "must be numbers, got"),
    ],
)
def test_bad_joint_values(q: object, match: str) -> None:
    """One validation for the FK of both forms, the three Jacobians and a DH table's FK."""
    chain = random_chain(np.random.default_rng(7), 4)
    for method in (
        chain.fk,
        chain.fk_body,
        chain.jacobian_space,
        chain.jacobian_body,
        chain.jacobian_world,
    ):
        with pytest.raises(InputError, match=match) as info:
            method(q)  # type: ignore[arg-type]
        assert "\n" not in str(info.value)


def test_a_dh_table_refuses_what_is_not_a_real_number() -> None:
    table = named_params("ur5e-dh")
    with pytest.raises(InputError, match="must be numbers, got None"):
        table.fk(np.array([None] * 6))
    with pytest.raises(InputError, match="must be real numbers, got complex numbers"):
        table.fk(np.zeros(6, dtype=complex))


@pytest.mark.parametrize(
    ("screw", "kind", "match"),
    [
        ([0, 0, 2, 0, 0, 0], "revolute", "unit axis"),
        ([0, 0, 0, 0, 0, 0], "revolute", "unit axis"),
        ([0, 0, 1, 0, 0, 1], "prismatic", "prismatic screw"),
        ([0, 0, 0, 0, 0, 2], "prismatic", "prismatic screw"),
        ([0, 0, 1, 0, 0, 0], "spherical", "unknown joint type"),
    ],
)
def test_bad_screws(screw: list[float], kind: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        Chain(("j",), (kind,), [screw], np.eye(4))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("home", "match"),
    [
        (np.diag([2.0, 1.0, 1.0, 1.0]), "orthonormal"),
        (np.diag([-1.0, 1.0, 1.0, 1.0]), "orthonormal"),
        (np.eye(4) + np.eye(4, k=-3), "last row"),
        (np.eye(3), r"shape \(4, 4\)"),
        (np.full((4, 4), np.nan), "NaN"),
    ],
)
def test_bad_home(home: np.ndarray, match: str) -> None:
    with pytest.raises(InputError, match=match):
        Chain(("j",), ("revolute",), [[0, 0, 1, 0, 0, 0]], home)


def test_bad_limits_and_lengths() -> None:
    with pytest.raises(InputError, match="lower <= upper"):
        Chain(("j",), ("revolute",), [[0, 0, 1, 0, 0, 0]], np.eye(4), limits=[[1.0, -1.0]])
    with pytest.raises(InputError, match="joint types"):
        Chain(("j", "k"), ("revolute",), [[0, 0, 1, 0, 0, 0]], np.eye(4))


def test_describe_and_repr() -> None:
    chain = random_chain(np.random.default_rng(8), 2)
    info = chain.describe()
    assert [j["name"] for j in info["joints"]] == ["j0", "j1"]
    assert_close("home", info["home"], chain.home, 0.0)
    assert "j0(" in repr(chain)


def test_chain_without_joints_is_its_home_pose() -> None:
    """A frame fixed to the world: no joints, fk is M for every (empty) q."""
    home = exp_se3(np.array([0.1, 0.2, 0.3, 1.0, 2.0, 3.0]))
    chain = Chain((), (), np.zeros((0, 6)), home)
    assert_close("fk", chain.fk(np.zeros((2, 0))), np.broadcast_to(home, (2, 4, 4)), 0.0)
    assert_close("fk_body", chain.fk_body(np.zeros(0)), home, 0.0)
