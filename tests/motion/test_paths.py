"""poekin.motion.paths: the screw path and the straight line against the Modern Robotics code
(ScrewTrajectory, CartesianTrajectory) pose by pose at the same s(t), and their twists against
central differences of the poses (SciPy's matrix logarithm), over batch shapes."""

from __future__ import annotations

from collections.abc import Callable

import modern_robotics as mr
import numpy as np
import pytest
import scipy.linalg
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

from poekin import lie
from poekin.errors import InputError
from poekin.motion.paths import line_path, line_path_twist, screw_path, screw_path_twist
from poekin.motion.scaling import scaling

BATCH_SHAPES = [(), (1,), (3, 1, 2)]
FAST = settings(max_examples=20, deadline=None)
seeds = st.integers(0, 2**32 - 1)
PATHS = {"screw": (screw_path, screw_path_twist), "line": (line_path, line_path_twist)}


def _poses(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Random poses: rotation angles in [0.1, 3] rad (both codes' logarithms are well
    conditioned there), positions within a metre."""
    axis = rng.normal(size=(*shape, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = rng.uniform(0.1, 3.0, (*shape, 1))
    return np.asarray(lie.homogeneous(lie.exp_so3(axis * angle), rng.uniform(-1, 1, (*shape, 3))))


def _pair(seed: int, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``T0`` and ``T1 = T0 D`` with ``D``'s rotation under 3 rad: the relative rotation stays
    away from pi, where the two ways round are a tie."""
    rng = np.random.default_rng(seed)
    T0 = _poses(rng, shape)
    return T0, T0 @ _poses(rng, shape)


def _log(T: np.ndarray) -> np.ndarray:
    """``[w; v]`` of each pose by SciPy's matrix logarithm (not poekin's)."""
    flat = T.reshape(-1, 4, 4)
    out = np.empty((len(flat), 6))
    for k, M in enumerate(flat):
        X = np.real(scipy.linalg.logm(M))
        out[k] = [X[2, 1], X[0, 2], X[1, 0], *X[:3, 3]]
    return out.reshape(*T.shape[:-2], 6)


@pytest.mark.parametrize("method", [3, 5])
def test_paths_match_modern_robotics(method: int) -> None:
    Tf, N = 2.5, 9
    kind = {3: "cubic", 5: "quintic"}[method]
    s = scaling(kind, np.linspace(0.0, Tf, N), Tf)[0]
    for seed in range(10):
        T0, T1 = _pair(seed, ())
        for name, ours, reference in (
            ("screw_path", screw_path(T0, T1, s), mr.ScrewTrajectory(T0, T1, Tf, N, method)),
            ("line_path", line_path(T0, T1, s), mr.CartesianTrajectory(T0, T1, Tf, N, method)),
        ):
            assert ours.shape == (N, 4, 4)
            assert_close(f"{name} (seed {seed})", ours, np.array(reference), 1e-12)


@FAST
@given(seed=seeds, shape=st.sampled_from(BATCH_SHAPES), path=st.sampled_from(sorted(PATHS)))
def test_batched_paths_are_entry_by_entry(seed: int, shape: tuple[int, ...], path: str) -> None:
    T0, T1 = _pair(seed, shape)
    s = np.random.default_rng(seed).uniform(0.0, 1.0, shape)
    pose, twist = PATHS[path]
    T = pose(T0, T1, s)
    assert T.shape == (*shape, 4, 4)
    for frame in ("body", "space"):
        V, dV = twist(T0, T1, s, frame=frame)
        assert V.shape == dV.shape == (*shape, 6)
        for idx in np.ndindex(*shape):
            one = twist(T0[idx], T1[idx], s[idx], frame=frame)
            np.testing.assert_array_equal(V[idx], one[0])
            np.testing.assert_array_equal(dV[idx], one[1])
    # the ends; s broadcast against one pair of poses
    ends = pose(T0[(0,) * len(shape)], T1[(0,) * len(shape)], np.array([0.0, 1.0]))
    assert_close("T(0)", ends[0], T0[(0,) * len(shape)], 1e-14)
    assert_close("T(1)", ends[1], T1[(0,) * len(shape)], 1e-12)


@FAST
@given(seed=seeds, shape=st.sampled_from(BATCH_SHAPES), path=st.sampled_from(sorted(PATHS)))
def test_twists_match_central_differences(seed: int, shape: tuple[int, ...], path: str) -> None:
    T0, T1 = _pair(seed, shape)
    s = np.random.default_rng(seed + 1).uniform(-0.2, 1.2, shape)  # the formulas hold beyond
    pose, twist = PATHS[path]
    h = 1e-4
    T, T_plus, T_minus = (pose(T0, T1, s + d) for d in (0.0, h, -h))
    inv = np.linalg.inv
    # body: T(s)^-1 T(s + d) = exp(d V + d^2 / 2 V_s + O(d^3)); space likewise on the left
    steps = {
        "body": (_log(inv(T) @ T_plus), _log(inv(T) @ T_minus), _log(inv(T_minus) @ T_plus)),
        "space": (_log(T_plus @ inv(T)), _log(T_minus @ inv(T)), _log(T_plus @ inv(T_minus))),
    }
    for frame, (ahead, behind, across) in steps.items():
        V, dV = twist(T0, T1, s, frame=frame)
        assert_close(f"{path} {frame} twist", V, across / (2 * h), 1e-6)
        assert_close(f"{path} {frame} twist derivative", dV, (ahead + behind) / h**2, 1e-5)


@pytest.mark.parametrize("path", sorted(PATHS))
def test_twists_under_a_time_scaling(path: str) -> None:
    # V = V_s sd and Vdot = V_s sdd + V_ss sd^2: the body twist of T(s(t)) and its rate of change,
    # from poses alone (nested central differences in time), at a quintic's times
    T0, T1 = _pair(7, ())
    pose, twist = PATHS[path]
    Tf = 2.0
    t = np.array([0.3, 0.8, 1.1, 1.7])

    def body_twist(at: np.ndarray, h: float = 1e-5) -> np.ndarray:
        T_plus, T_minus = (pose(T0, T1, scaling("quintic", at + d, Tf)[0]) for d in (h, -h))
        return _log(np.linalg.inv(T_minus) @ T_plus) / (2 * h)

    s, sd, sdd = scaling("quintic", t, Tf)
    V_s, V_ss = twist(T0, T1, s)
    V = V_s * sd[:, None]
    assert_close("V", V, body_twist(t), 1e-8)
    h = 1e-3
    Vdot = (body_twist(t + h) - body_twist(t - h)) / (2 * h)
    assert_close("Vdot", V_s * sdd[:, None] + V_ss * sd[:, None] ** 2, Vdot, 1e-5)


def test_the_line_is_straight_and_the_screw_is_not() -> None:
    T0, T1 = _pair(3, ())
    s = np.linspace(0.0, 1.0, 11)
    p0, p1 = T0[:3, 3], T1[:3, 3]
    line = line_path(T0, T1, s)[:, :3, 3]
    assert_close("line origin", line, p0 + s[:, None] * (p1 - p0), 1e-15)
    V, _ = line_path_twist(T0, T1, s)
    R = line_path(T0, T1, s)[:, :3, :3]
    assert_close(
        "dp/ds = R v_body", (R @ V[:, 3:, None])[..., 0], np.broadcast_to(p1 - p0, (11, 3)), 1e-14
    )
    screw = screw_path(T0, T1, s)[:, :3, 3]
    chord = p0 + s[:, None] * (p1 - p0)
    assert np.max(np.linalg.norm(screw - chord, axis=1)) > 1e-2  # a helix about the screw axis


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: screw_path_twist(np.eye(4), np.eye(4), 0.5, frame="spase"),
            "screw_path_twist: unknown frame 'spase' for the twists; did you mean 'space'?",
        ),
        (
            lambda: line_path_twist(np.eye(4), np.eye(4), 0.5, frame="world"),
            "line_path_twist: unknown frame 'world' for the twists; Valid names: 'body', 'space'",
        ),
        (
            lambda: line_path_twist(np.eye(3), np.eye(4), 0.5),
            "line_path_twist: T0 must be poses (..., 4, 4), got shape (3, 3)",
        ),
        (
            lambda: screw_path(np.eye(4), np.full((4, 4), np.nan), 0.5),
            "screw_path: T1 has NaN or inf entries; give finite poses",
        ),
        (
            lambda: line_path(np.eye(4), np.eye(4), [0.5, np.nan]),
            "line_path: s has NaN or inf entries; give finite path parameters",
        ),
        (
            lambda: screw_path_twist(np.eye(4)[None].repeat(2, 0), np.eye(4), np.zeros(3)),
            "screw_path_twist: T0 (2, 4, 4), T1 (4, 4) and s (3,) do not broadcast together",
        ),
    ],
)
def test_bad_input(call: Callable[[], object], message: str) -> None:
    with pytest.raises(InputError) as info:
        call()
    assert str(info.value).startswith(message), str(info.value)
    assert "\n" not in str(info.value)
