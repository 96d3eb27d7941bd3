"""Tests of poekin.lie: hat/vee, exp/log, adjoint and inverse on SO(3) and SE(3)."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
import scipy.linalg
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from poekin import lie
from poekin.errors import InputError

# Absolute tolerance for float64 results of O(1) size. Every map here is a handful of
# well-conditioned float64 operations (errors of a few eps ~ 1e-15), so 1e-12 leaves three
# orders of magnitude of headroom while still catching any wrong Taylor coefficient, branch
# or sign (those show up as errors >= 1e-9 at the sampled angles). Checks that should be
# exact to rounding (orthonormality, agreement with scipy's expm) use a tighter fraction.
ATOL = 1e-12

PI = np.pi
# Angles that exercise every branch: exactly 0, deep and shallow Taylor regions, both sides
# of each series switch (1e-3 and 0.3), the cos t < 0 switch of log_so3 (pi/2), near pi and pi.
SPECIAL_ANGLES = [
    0.0,
    1e-12,
    1e-7,
    1e-6,
    1e-3 * (1 - 1e-9),
    1e-3,
    0.3 * (1 - 1e-9),
    0.3,
    1.0,
    PI / 2 - 1e-9,
    PI / 2 + 1e-9,
    PI - 1e-6,
    PI - 1e-9,
    PI,
]

BATCH_SHAPES = [(), (1,), (3, 1, 2), (3, 1, 2, 1)]

seeds = st.integers(min_value=0, max_value=2**32 - 1)
angles_to_pi = st.one_of(st.sampled_from(SPECIAL_ANGLES), st.floats(0.0, PI))
angles_below_pi = st.one_of(
    st.sampled_from([a for a in SPECIAL_ANGLES if a <= PI - 1e-6]), st.floats(0.0, PI - 1e-6)
)
FAST = settings(max_examples=25, deadline=None)


# --------------------------------------------------------------------------------------------
# sampling helpers


def unit_axes(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """``(*shape, 3)`` random unit vectors."""
    a = rng.normal(size=(*shape, 3))
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def mixed_angles(rng: np.random.Generator, shape: tuple[int, ...], angle: float) -> np.ndarray:
    """``shape`` angles: the first is ``angle``, the others special or uniform in [0, ``angle``]."""
    n = int(np.prod(shape))
    pool = np.array([a for a in SPECIAL_ANGLES if a <= angle] + [angle])
    out = np.where(rng.random(n) < 0.5, rng.choice(pool, n), rng.uniform(0.0, angle, n))
    out[0] = angle
    return out.reshape(shape)


def rotation_vectors(rng: np.random.Generator, shape: tuple[int, ...], angle: float) -> np.ndarray:
    """``(*shape, 3)`` rotation vectors, random axes, angles from :func:`mixed_angles`."""
    return unit_axes(rng, shape) * mixed_angles(rng, shape, angle)[..., None]


def twists(rng: np.random.Generator, shape: tuple[int, ...], angle: float) -> np.ndarray:
    """``(*shape, 6)`` exponential coordinates ``[w; v]`` with ``|w|`` from mixed angles."""
    v = rng.uniform(-1.0, 1.0, size=(*shape, 3))
    return np.concatenate([rotation_vectors(rng, shape, angle), v], axis=-1)


def poses(rng: np.random.Generator, shape: tuple[int, ...], angle: float = PI) -> np.ndarray:
    """``(*shape, 4, 4)`` poses with rotation angle up to ``angle`` and translation in [-1, 1]."""
    return lie.exp_se3(twists(rng, shape, angle))


def transpose(M: np.ndarray) -> np.ndarray:
    return np.swapaxes(M, -1, -2)


# --------------------------------------------------------------------------------------------
# hat / vee


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_hat_vee_so3_round_trip(shape: tuple[int, ...], seed: int) -> None:
    rng = np.random.default_rng(seed)
    omega = rng.normal(size=(*shape, 3))
    W = lie.hat_so3(omega)
    assert W.shape == (*shape, 3, 3)
    assert_close("W + W^T", W + transpose(W), np.zeros_like(W), 0.0)
    assert_close("vee(hat(omega))", lie.vee_so3(W), omega, 0.0)
    x = rng.normal(size=(*shape, 3))
    assert_close("hat(omega) x", (W @ x[..., None])[..., 0], np.cross(omega, x), ATOL)
    # vee reads the antisymmetric part only
    S = rng.normal(size=(*shape, 3, 3))
    assert_close("vee(W + sym)", lie.vee_so3(W + S + transpose(S)), omega, ATOL)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_hat_vee_se3_round_trip(shape: tuple[int, ...], seed: int) -> None:
    rng = np.random.default_rng(seed)
    xi = rng.normal(size=(*shape, 6))
    Xi = lie.hat_se3(xi)
    assert Xi.shape == (*shape, 4, 4)
    assert_close("hat_se3 rotation block", Xi[..., :3, :3], lie.hat_so3(xi[..., :3]), 0.0)
    assert_close("hat_se3 translation column", Xi[..., :3, 3], xi[..., 3:], 0.0)
    assert_close("hat_se3 bottom row", Xi[..., 3, :], np.zeros((*shape, 4)), 0.0)
    assert_close("vee_se3(hat_se3(xi))", lie.vee_se3(Xi), xi, 0.0)


# --------------------------------------------------------------------------------------------
# exponentials against scipy.linalg.expm


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_to_pi)
def test_exp_so3_matches_expm(shape: tuple[int, ...], seed: int, angle: float) -> None:
    omega = rotation_vectors(np.random.default_rng(seed), shape, angle)
    expected = scipy.linalg.expm(lie.hat_so3(omega))
    assert_close("exp_so3", lie.exp_so3(omega), expected, ATOL / 10)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_to_pi)
def test_exp_se3_matches_expm(shape: tuple[int, ...], seed: int, angle: float) -> None:
    xi = twists(np.random.default_rng(seed), shape, angle)
    expected = scipy.linalg.expm(lie.hat_se3(xi))
    assert_close("exp_se3", lie.exp_se3(xi), expected, ATOL / 10)


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, -1, 0], [0, 0, 1], [0.6, 0, -0.8]])
@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_axis_rotation_matches_expm(axis: list[float], shape: tuple[int, ...], seed: int) -> None:
    """About a coordinate axis (exact cos/sin entries) and about any other (Rodrigues)."""
    w = np.array(axis, dtype=np.float64)
    angle = np.random.default_rng(seed).uniform(-2 * PI, 2 * PI, shape)
    expected = np.empty((*shape, 3, 3))
    for idx in np.ndindex(shape):
        expected[idx] = scipy.linalg.expm(lie.hat_so3(w * angle[idx]))
    assert_close("axis_rotation", lie.axis_rotation(w, angle), expected, ATOL)


def test_coordinate_axis_needs_two_exact_zeros() -> None:
    assert lie.coordinate_axis(np.array([0.0, -0.9999999999999998, 0.0])) == (1, -1.0)
    assert lie.coordinate_axis(np.array([2.0, 0.0, 0.0])) == (0, 1.0)
    assert lie.coordinate_axis(np.array([0.0, 1e-300, 1.0])) is None
    assert lie.coordinate_axis(np.zeros(3)) is None


def test_exp_se3_pure_translation() -> None:
    v = np.array([0.3, -2.0, 5.0])
    T = lie.exp_se3(np.concatenate([np.zeros(3), v]))
    assert_close("rotation", T[:3, :3], np.eye(3), 0.0)
    assert_close("translation", T[:3, 3], v, 0.0)
    assert_close("bottom row", T[3], [0.0, 0.0, 0.0, 1.0], 0.0)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, scale=st.floats(0.0, 20.0))
def test_exp_so3_is_a_rotation(shape: tuple[int, ...], seed: int, scale: float) -> None:
    rng = np.random.default_rng(seed)
    omega = unit_axes(rng, shape) * (scale * rng.random(shape))[..., None]
    R = lie.exp_so3(omega)
    identity = np.broadcast_to(np.eye(3), R.shape)
    assert_close("R R^T", R @ transpose(R), identity, ATOL / 100)
    assert_close("det R", np.linalg.det(R), np.ones(shape), ATOL / 100)


def exact_sin_cos(t: float) -> tuple[Fraction, Fraction]:
    """sin and cos of the float ``t`` in exact rational arithmetic (40-term series, t <= pi)."""
    x = Fraction(t)
    sin, cos, term = Fraction(0), Fraction(0), Fraction(1)  # term = x^k / k!
    for k in range(40):
        if k % 2 == 0:
            cos += term if k % 4 == 0 else -term
        else:
            sin += term if k % 4 == 1 else -term
        term = term * x / (k + 1)
    return sin, cos


@pytest.mark.parametrize("t", [a for a in SPECIAL_ANGLES if a > 0] + [0.05, 0.2999, 0.3001, 2.0])
def test_series_coefficients_against_exact_arithmetic(t: float) -> None:
    # The Taylor branches sit below thresholds where their effect on a matrix is < 1e-13, so
    # check the coefficients themselves: relative error <= ATOL / 10 on both sides of a switch.
    x = Fraction(t)
    sin, cos = exact_sin_cos(t)
    half_sin, half_cos = exact_sin_cos(t / 2)
    exact = {
        "sin t / t": (lie._sin_over_t, sin / x),
        "(1 - cos t) / t^2": (lie._one_minus_cos_over_t2, (1 - cos) / x**2),
        "(t - sin t) / t^3": (lie._t_minus_sin_over_t3, (x - sin) / x**3),
        "(1 - t/2 cot(t/2)) / t^2": (
            lie._inverse_v_coefficient,
            (1 - x / 2 * half_cos / half_sin) / x**2,
        ),
        "t / sin t": (lambda a: lie._t_over_sin_t(a, np.sin(a)), x / sin),
    }
    for name, (func, value) in exact.items():
        expected = float(value)
        actual = float(func(np.array(t)))
        assert_close(f"{name} at t={t!r} (relative)", actual / expected, 1.0, ATOL / 10)


# --------------------------------------------------------------------------------------------
# logarithms


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-6, PI - 1e-9, PI])
@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_exp_log_so3_round_trip(shape: tuple[int, ...], angle: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    R = lie.exp_so3(unit_axes(rng, shape) * angle)
    omega = lie.log_so3(R)
    assert omega.shape == (*shape, 3)
    assert_close("|log R|", np.linalg.norm(omega, axis=-1), np.full(shape, angle), ATOL)
    assert_close("exp(log R)", lie.exp_so3(omega), R, ATOL)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-6, PI - 1e-9, PI])
@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_exp_log_se3_round_trip(shape: tuple[int, ...], angle: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    xi = np.concatenate(
        [unit_axes(rng, shape) * angle, rng.uniform(-1.0, 1.0, (*shape, 3))], axis=-1
    )
    T = lie.exp_se3(xi)
    assert_close("exp(log T)", lie.exp_se3(lie.log_se3(T)), T, ATOL)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_below_pi)
def test_log_exp_so3_round_trip(shape: tuple[int, ...], seed: int, angle: float) -> None:
    omega = rotation_vectors(np.random.default_rng(seed), shape, angle)
    assert_close("log(exp omega)", lie.log_so3(lie.exp_so3(omega)), omega, ATOL)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_below_pi)
def test_log_exp_se3_round_trip(shape: tuple[int, ...], seed: int, angle: float) -> None:
    xi = twists(np.random.default_rng(seed), shape, angle)
    assert_close("log(exp xi)", lie.log_se3(lie.exp_se3(xi)), xi, ATOL)


@FAST
@given(seed=seeds)
def test_log_so3_at_pi_gives_the_axis_up_to_sign(seed: int) -> None:
    axis = unit_axes(np.random.default_rng(seed), ())
    omega = lie.log_so3(lie.exp_so3(PI * axis))
    sign = np.sign(omega @ axis)
    assert_close("log(exp(pi a))", omega, sign * PI * axis, ATOL)


@pytest.mark.parametrize("diag", [(-1, -1, 1), (-1, 1, -1), (1, -1, -1)])
def test_log_so3_of_an_exact_half_turn_emits_no_warning(diag: tuple[int, int, int]) -> None:
    # sin t is exactly 0 here (a diagonal matrix has no antisymmetric part), unlike exp(pi a)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        omega = lie.log_so3(np.diag(np.array(diag, dtype=float)))
    assert_close("|log| of a half turn", np.abs(omega), PI * (np.array(diag) > 0), 0.0)


def test_log_se3_coefficient_at_pi() -> None:
    # V^{-1} = I - W/2 + W^2/pi^2 at t = pi, so V^{-1} V = I there
    axis = np.array([0.0, 0.0, 1.0])
    p = np.array([1.0, 2.0, 3.0])
    T = lie.exp_se3(np.concatenate([PI * axis, p]))
    xi = lie.log_se3(T)
    assert np.all(np.isfinite(xi))
    assert_close("|w| at pi", np.linalg.norm(xi[:3]), PI, ATOL)
    assert_close("exp(log T) at pi", lie.exp_se3(xi), T, ATOL)


def test_mixed_batch_is_handled_elementwise_without_warnings() -> None:
    rng = np.random.default_rng(0)
    angles = np.array(SPECIAL_ANGLES)
    omega = unit_axes(rng, angles.shape) * angles[..., None]
    xi = np.concatenate([omega, rng.uniform(-1.0, 1.0, omega.shape)], axis=-1)
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        R = lie.exp_so3(omega)
        T = lie.exp_se3(xi)
        batched = {
            "exp_so3": R,
            "log_so3": lie.log_so3(R),
            "rotation_angle": lie.rotation_angle(R),
            "exp_se3": T,
            "log_se3": lie.log_se3(T),
        }
        for i in range(len(angles)):
            single = {
                "exp_so3": lie.exp_so3(omega[i]),
                "log_so3": lie.log_so3(R[i]),
                "rotation_angle": lie.rotation_angle(R[i]),
                "exp_se3": lie.exp_se3(xi[i]),
                "log_se3": lie.log_se3(T[i]),
            }
            for name, value in single.items():
                assert_close(f"{name}[{i}]", batched[name][i], value, 0.0)


# --------------------------------------------------------------------------------------------
# rotation_angle


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_to_pi)
def test_rotation_angle_is_norm_of_omega(shape: tuple[int, ...], seed: int, angle: float) -> None:
    omega = rotation_vectors(np.random.default_rng(seed), shape, angle)
    expected = np.linalg.norm(omega, axis=-1)
    assert_close("rotation_angle", lie.rotation_angle(lie.exp_so3(omega)), expected, ATOL)


@pytest.mark.parametrize("angle", [1e-12, 1e-9, 1e-7])
@FAST
@given(seed=seeds)
def test_rotation_angle_relative_accuracy_near_zero(angle: float, seed: int) -> None:
    R = lie.exp_so3(unit_axes(np.random.default_rng(seed), (5,)) * angle)
    relative = np.abs(lie.rotation_angle(R) - angle) / angle
    assert np.all(relative < 1e-6), f"rotation_angle relative error {relative.max():.2e}"


def test_rotation_angle_of_identity_is_zero() -> None:
    assert lie.rotation_angle(np.eye(3)) == 0.0
    identities = np.tile(np.eye(3), (2, 3, 1, 1))
    assert_close("batched identity", lie.rotation_angle(identities), np.zeros((2, 3)), 0.0)


@FAST
@given(seed=seeds, delta=st.sampled_from([0.0, 1e-12, 1e-9, 1e-6]))
def test_rotation_angle_as_orientation_error(seed: int, delta: float) -> None:
    rng = np.random.default_rng(seed)
    R_a = lie.exp_so3(rotation_vectors(rng, (4,), PI))
    R_b = R_a @ lie.exp_so3(unit_axes(rng, (4,)) * delta)
    error = lie.rotation_angle(R_b @ transpose(R_a))
    assert_close("orientation error", error, np.full(4, delta), ATOL / 100)


# --------------------------------------------------------------------------------------------
# adjoint and inverse


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_adjoint_is_a_homomorphism(shape: tuple[int, ...], seed: int) -> None:
    rng = np.random.default_rng(seed)
    A, B = poses(rng, shape), poses(rng, shape)
    Ad = lie.adjoint
    assert Ad(A).shape == (*shape, 6, 6)
    assert_close("Ad(A B)", Ad(A @ B), Ad(A) @ Ad(B), ATOL)
    assert_close("Ad(T^-1)", Ad(lie.inverse(A)), np.linalg.inv(Ad(A)), ATOL)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_to_pi)
def test_adjoint_conjugates_exponentials(shape: tuple[int, ...], seed: int, angle: float) -> None:
    rng = np.random.default_rng(seed)
    T = poses(rng, shape)
    xi = twists(rng, shape, angle)
    moved = (lie.adjoint(T) @ xi[..., None])[..., 0]
    assert_close("T exp(xi) T^-1", T @ lie.exp_se3(xi) @ lie.inverse(T), lie.exp_se3(moved), ATOL)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds)
def test_inverse(shape: tuple[int, ...], seed: int) -> None:
    T = poses(np.random.default_rng(seed), shape)
    identity = np.broadcast_to(np.eye(4), T.shape)
    assert_close("inverse(T) T", lie.inverse(T) @ T, identity, ATOL)
    assert_close("T inverse(T)", T @ lie.inverse(T), identity, ATOL)


# --------------------------------------------------------------------------------------------
# lab-named wrappers


@FAST
@given(seed=seeds)
def test_aliases(seed: int) -> None:
    rng = np.random.default_rng(seed)
    omega, xi = rng.normal(size=(2, 3)), rng.normal(size=(2, 6))
    assert_close("vec_to_so3", lie.vec_to_so3(omega), lie.hat_so3(omega), 0.0)
    assert_close("vec_to_se3", lie.vec_to_se3(xi), lie.hat_se3(xi), 0.0)
    assert_close("matrix_exp_so3", lie.matrix_exp_so3(omega), lie.exp_so3(omega), 0.0)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, theta=st.floats(-10.0, 10.0))
def test_matrix_exp_se3_prismatic(shape: tuple[int, ...], seed: int, theta: float) -> None:
    v = unit_axes(np.random.default_rng(seed), shape)
    screw = np.concatenate([np.zeros_like(v), v], axis=-1)
    T = lie.matrix_exp_se3(screw, theta)
    assert_close(
        "prismatic rotation", T[..., :3, :3], np.broadcast_to(np.eye(3), T[..., :3, :3].shape), 0.0
    )
    assert_close("prismatic translation", T[..., :3, 3], v * theta, ATOL)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, theta=st.floats(-10.0, 10.0))
def test_matrix_exp_se3_revolute(shape: tuple[int, ...], seed: int, theta: float) -> None:
    rng = np.random.default_rng(seed)
    w = unit_axes(rng, shape)
    q = rng.normal(size=(*shape, 3))  # a point on the axis
    screw = np.concatenate([w, -np.cross(w, q)], axis=-1)
    thetas = np.full(shape, theta)
    expected = lie.exp_se3(screw * thetas[..., None])
    assert_close("matrix_exp_se3", lie.matrix_exp_se3(screw, thetas), expected, 0.0)
    # the point q on the axis does not move
    moved = (
        lie.matrix_exp_se3(screw, thetas) @ np.concatenate([q, np.ones((*shape, 1))], -1)[..., None]
    )
    assert_close("point on the axis", moved[..., :3, 0], q, ATOL)


def test_matrix_exp_se3_broadcasts_theta() -> None:
    screw = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    T = lie.matrix_exp_se3(screw, np.array([0.0, PI / 2, PI]))
    assert T.shape == (3, 4, 4)
    assert_close("Rz(pi/2)", T[1, :2, :2], [[0.0, -1.0], [1.0, 0.0]], ATOL)


# --------------------------------------------------------------------------------------------
# dtypes and input errors

ROTATION = lie.exp_so3(np.array([0.3, -0.2, 0.1]))
POSE = lie.exp_se3(np.array([0.3, -0.2, 0.1, 1.0, 2.0, 3.0]))
FUNCTIONS: list[tuple[str, Callable[[Any], np.ndarray], np.ndarray, np.ndarray]] = [
    # name, function, float input, integer input
    ("hat_so3", lie.hat_so3, np.array([0.1, 0.2, 0.3]), np.array([1, 2, 3])),
    ("vee_so3", lie.vee_so3, lie.hat_so3([0.1, 0.2, 0.3]), np.eye(3, dtype=int)),
    ("hat_se3", lie.hat_se3, np.arange(6.0), np.arange(6)),
    ("vee_se3", lie.vee_se3, POSE, np.eye(4, dtype=int)),
    ("exp_so3", lie.exp_so3, np.array([0.1, 0.2, 0.3]), np.array([1, 0, 0])),
    ("log_so3", lie.log_so3, ROTATION, np.eye(3, dtype=int)),
    ("rotation_angle", lie.rotation_angle, ROTATION, np.eye(3, dtype=int)),
    ("exp_se3", lie.exp_se3, np.arange(6.0), np.arange(6)),
    ("log_se3", lie.log_se3, POSE, np.eye(4, dtype=int)),
    ("adjoint", lie.adjoint, POSE, np.eye(4, dtype=int)),
    ("inverse", lie.inverse, POSE, np.eye(4, dtype=int)),
    ("vec_to_so3", lie.vec_to_so3, np.array([0.1, 0.2, 0.3]), np.array([1, 2, 3])),
    ("vec_to_se3", lie.vec_to_se3, np.arange(6.0), np.arange(6)),
    ("matrix_exp_so3", lie.matrix_exp_so3, np.array([0.1, 0.2, 0.3]), np.array([1, 0, 0])),
    ("rotation_to_rpy", lie.rotation_to_rpy, ROTATION, np.eye(3, dtype=int)),
]


@pytest.mark.parametrize(("name", "func", "x", "x_int"), FUNCTIONS, ids=[f[0] for f in FUNCTIONS])
def test_dtypes(name: str, func: Callable[[Any], np.ndarray], x: Any, x_int: Any) -> None:
    out64 = func(x)
    out32 = func(x.astype(np.float32))
    assert out32.dtype == np.float32, f"{name}: float32 in gave {out32.dtype} out"
    assert_close(f"{name} float32 vs float64", out32, out64, 1e-5)
    assert func(x_int).dtype == np.float64, f"{name}: int in gave {func(x_int).dtype} out"


def test_matrix_exp_se3_dtypes() -> None:
    screw32 = np.array([0, 0, 1, 0, 0, 0], dtype=np.float32)
    assert lie.matrix_exp_se3(screw32, 0.5).dtype == np.float32
    assert lie.matrix_exp_se3(screw32, np.float32(0.5)).dtype == np.float32
    assert lie.matrix_exp_se3(np.array([0, 0, 1, 0, 0, 0]), 1).dtype == np.float64


def test_float32_near_pi_and_zero() -> None:
    omega = np.array([[0, 0, 0], [1e-7, 0, 0], [0, 0, PI]], dtype=np.float32)
    R = lie.exp_so3(omega)
    assert R.dtype == np.float32
    assert_close("float32 log(exp)", np.abs(lie.log_so3(R)), np.abs(omega), 1e-6)


@pytest.mark.parametrize(
    ("func", "bad", "expected"),
    [
        (lie.hat_so3, np.zeros(4), "(..., 3)"),
        (lie.vee_so3, np.zeros((4, 4)), "(..., 3, 3)"),
        (lie.hat_se3, np.zeros((2, 3)), "(..., 6)"),
        (lie.vee_se3, np.zeros((3, 3)), "(..., 4, 4)"),
        (lie.exp_so3, np.zeros(()), "(..., 3)"),
        (lie.log_so3, np.zeros((3,)), "(..., 3, 3)"),
        (lie.rotation_angle, np.zeros((2, 3, 4)), "(..., 3, 3)"),
        (lie.exp_se3, np.zeros((5, 3)), "(..., 6)"),
        (lie.log_se3, np.zeros((3, 4)), "(..., 4, 4)"),
        (lie.adjoint, np.zeros((6, 6)), "(..., 4, 4)"),
        (lie.inverse, np.zeros((4,)), "(..., 4, 4)"),
        (lie.vec_to_so3, np.zeros(6), "(..., 3)"),
        (lie.vec_to_se3, np.zeros(3), "(..., 6)"),
        (lie.matrix_exp_so3, np.zeros((3, 2)), "(..., 3)"),
    ],
)
def test_wrong_shape_raises(func: Callable[[Any], Any], bad: np.ndarray, expected: str) -> None:
    with pytest.raises(InputError, match=re.escape(expected)) as info:
        func(bad)
    message = str(info.value)
    assert str(bad.shape) in message, message
    assert "\n" not in message
    assert isinstance(info.value, ValueError)


_FINITE_CHECKED = [
    (lie.hat_so3, (3,)),
    (lie.vee_so3, (3, 3)),
    (lie.hat_se3, (6,)),
    (lie.vee_se3, (4, 4)),
    (lie.exp_so3, (3,)),
    (lie.log_so3, (3, 3)),
    (lie.rotation_angle, (3, 3)),
    (lie.exp_se3, (6,)),
    (lie.log_se3, (4, 4)),
    (lie.adjoint, (4, 4)),
    (lie.inverse, (4, 4)),
    (lie.quat_normalize, (4,)),
    (lie.quat_to_rotation, (4,)),
    (lie.rotation_to_quat, (3, 3)),
    (lie.rotation_to_rpy, (3, 3)),
]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize(("func", "shape"), _FINITE_CHECKED)
def test_non_finite_input_is_rejected(
    func: Callable[[Any], Any], shape: tuple[int, ...], bad: float
) -> None:
    x = np.zeros((2, *shape))
    x[1].flat[0] = bad
    with pytest.raises(InputError, match="contains NaN or inf; every value must be finite"):
        func(x)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("angle", [0.0, 1e-7, 1e-3, PI - 1e-3, PI])
@FAST
@given(seed=seeds)
def test_exp_log_round_trips_in_both_precisions(dtype: type, angle: float, seed: int) -> None:
    """Near 0, near pi and at pi, in float32 as in float64: each precision keeps its dtype
    and its own rounding (float32's eps is 1.2e-7; log near pi loses about sqrt(eps))."""
    tol = 1e-3 if dtype is np.float32 else 1e-7
    axis = unit_axes(np.random.default_rng(seed), ())
    omega = (axis * angle).astype(dtype)
    R = lie.exp_so3(omega)
    assert R.dtype == dtype
    assert_close("exp(log(R))", lie.exp_so3(lie.log_so3(R)), R, 10 * tol)
    back = lie.log_so3(R)
    if angle < PI:
        assert_close("log(exp(w))", back, omega, tol)
    else:  # at pi the axis is only defined up to sign
        assert_close("|log(exp(w))|", np.abs(back), np.abs(omega), tol)
    xi = np.concatenate([omega, np.ones(3, dtype=dtype)])
    T = lie.exp_se3(xi)
    assert T.dtype == dtype
    assert_close("exp(log(T))", lie.exp_se3(lie.log_se3(T)), T, 10 * tol)


@pytest.mark.parametrize("turns", [1e3, 1.6e5])
@FAST
@given(seed=seeds)
def test_huge_angles_equal_the_reduced_angle(turns: float, seed: int) -> None:
    """1e6 rad is 1.6e5 turns: exp of it equals exp of the angle mod 2 pi, to the resolution
    of the angle itself (ulp(1e6) = 1.2e-10 rad; reducing by the float 2 pi adds ~4e-11)."""
    rng = np.random.default_rng(seed)
    axis = unit_axes(rng, ())
    angle = rng.uniform(0, 2 * PI) + 2 * PI * np.floor(turns)
    reduced = np.fmod(angle, 2 * PI)
    assert_close("exp_so3", lie.exp_so3(axis * angle), lie.exp_so3(axis * reduced), 1e-9)
    xi, xi_reduced = np.r_[axis * angle, 0, 0, 0], np.r_[axis * reduced, 0, 0, 0]
    assert_close("exp_se3", lie.exp_se3(xi), lie.exp_se3(xi_reduced), 1e-9)


def test_matrix_exp_se3_wrong_shapes_raise() -> None:
    with pytest.raises(InputError, match=re.escape("(..., 6)")):
        lie.matrix_exp_se3(np.zeros(3), 1.0)
    with pytest.raises(InputError, match=re.escape("(4,)")):
        lie.matrix_exp_se3(np.zeros((3, 6)), np.zeros(4))


@pytest.mark.parametrize("batch", [(), (1,), (3, 1, 2, 1)])
def test_homogeneous_puts_r_and_p_in_a_pose(batch: tuple[int, ...]) -> None:
    rng = np.random.default_rng(0)
    R, p = lie.exp_so3(rng.normal(size=(*batch, 3))), rng.normal(size=(*batch, 3))
    T = lie.homogeneous(R, p)
    assert_close("R", T[..., :3, :3], R, 0.0)
    assert_close("p", T[..., :3, 3], p, 0.0)
    assert_close("last row", T[..., 3, :], np.broadcast_to([0.0, 0.0, 0.0, 1.0], (*batch, 4)), 0.0)
    with pytest.raises(InputError, match=re.escape("(..., 3)")):
        lie.homogeneous(R, np.zeros(4))


def test_public_api() -> None:
    for name in lie.__all__:
        assert callable(getattr(lie, name)), name


# --- quaternions ---------------------------------------------------------------------------


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, scale=st.sampled_from([0.0, 1e-16, 1e-3, 1.0, 1.0 + 1e-16, 7.0, 1e8]))
def test_quaternions_match_mujoco(shape: tuple[int, ...], seed: int, scale: float) -> None:
    """quat_normalize and quat_to_rotation are mju_normalize4 and mju_quat2Mat, batched."""
    import mujoco

    rng = np.random.default_rng(seed)
    q = rng.normal(size=(*shape, 4))
    q = q / np.linalg.norm(q, axis=-1, keepdims=True) * scale
    unit = lie.quat_normalize(q)
    R = lie.quat_to_rotation(unit)
    assert unit.shape == q.shape and R.shape == (*shape, 3, 3)
    expected_q, expected_R = np.empty_like(q), np.empty((*shape, 9))
    for idx in np.ndindex(*shape):
        expected_q[idx] = q[idx]
        mujoco.mju_normalize4(expected_q[idx])
        mujoco.mju_quat2Mat(expected_R[idx], expected_q[idx])
    assert_close("quat_normalize", unit, expected_q, 1e-15)
    assert_close("quat_to_rotation", R, expected_R.reshape(*shape, 3, 3), 1e-15)


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@FAST
@given(seed=seeds, angle=angles_to_pi)
def test_rotation_to_quat_round_trip(shape: tuple[int, ...], seed: int, angle: float) -> None:
    rng = np.random.default_rng(seed)
    R = lie.exp_so3(rotation_vectors(rng, shape, angle))
    quat = lie.rotation_to_quat(R)
    assert quat.shape == (*shape, 4)
    assert np.all(quat[..., 0] >= 0)
    assert_close("|quat|", np.linalg.norm(quat, axis=-1), np.ones(shape), 1e-15)
    assert_close("R(quat(R))", lie.quat_to_rotation(quat), R, 1e-15)


# --------------------------------------------------------------------------------------------
# what is not a rotation or a pose (issue 20), roll-pitch-yaw


@pytest.mark.parametrize(
    ("T", "message"),
    [
        (
            np.diag([2.0, 2.0, 2.0, 1.0]),
            r"T is not a rigid transform .*: its rotation block is not",
        ),
        (np.diag([1.0, 1.0, -1.0, 1.0]), r"not orthonormal with det \+1 .*det R = -1"),
        (np.vstack([POSE[:3], [1.0, 0.0, 0.0, 1.0]]), r"its last row is \[1.0, 0.0, 0.0, 1.0\]"),
        (np.stack([POSE, POSE * 0.5]), r"T\[1\] is not a rigid transform"),
    ],
)
def test_log_se3_refuses_what_is_not_a_rigid_transform(T: np.ndarray, message: str) -> None:
    with pytest.raises(InputError, match=message) as info:
        lie.log_se3(T)
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="R is not a rotation: it is not orthonormal"):
        lie.log_so3(np.diag([1.0, 2.0, 1.0]))


def test_log_takes_rotations_as_rounded_as_a_typed_pose() -> None:
    """1e-7 off orthonormal (a pose typed to 7 digits) is a rotation; float32 gets its own
    rounding's worth."""
    R = np.round(lie.exp_so3(np.array([0.3, -0.2, 0.1])), 7)
    assert_close("log", lie.log_so3(R), [0.3, -0.2, 0.1], 1e-6)
    T32 = lie.exp_se3(np.array([0.3, -0.2, 0.1, 1.0, 2.0, 3.0]).astype(np.float32))
    assert lie.log_se3(T32 @ T32 @ T32).dtype == np.float32


@pytest.mark.parametrize("shape", BATCH_SHAPES)
def test_rotation_to_rpy_is_scipys_extrinsic_xyz(shape: tuple[int, ...]) -> None:
    """URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll), which is SciPy's extrinsic 'xyz' (an
    independent construction): the angles, and R rebuilt from them."""
    from scipy.spatial.transform import Rotation

    n = int(np.prod(shape))
    R = Rotation.random(n, random_state=1).as_matrix().reshape(*shape, 3, 3)
    rpy = lie.rotation_to_rpy(R)
    assert rpy.shape == (*shape, 3)
    expected = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_euler("xyz").reshape(*shape, 3)
    assert_close("rpy", rpy, expected, 1e-12)
    rebuilt = Rotation.from_euler("xyz", rpy.reshape(-1, 3)).as_matrix().reshape(R.shape)
    assert_close("Rz Ry Rx", rebuilt, R, 1e-12)
    roll, pitch, yaw = 0.3, -0.4, 2.5
    Rx = lie.exp_so3(np.array([roll, 0.0, 0.0]))
    Ry = lie.exp_so3(np.array([0.0, pitch, 0.0]))
    Rz = lie.exp_so3(np.array([0.0, 0.0, yaw]))
    assert_close("by hand", lie.rotation_to_rpy(Rz @ Ry @ Rx), [roll, pitch, yaw], 1e-14)


@pytest.mark.parametrize("pitch", [PI / 2, -PI / 2])
def test_rotation_to_rpy_at_gimbal_lock_puts_the_turn_in_yaw(pitch: float) -> None:
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("xyz", [0.7, pitch, 0.4]).as_matrix()
    roll, pitch_back, yaw = lie.rotation_to_rpy(R)
    assert roll == 0.0 and abs(pitch_back - pitch) < 1e-7
    assert_close(
        "same R", Rotation.from_euler("xyz", [roll, pitch_back, yaw]).as_matrix(), R, 1e-12
    )
