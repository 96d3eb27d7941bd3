"""poekin.motion.track: a whole clip solved as one problem. The clips are smooth motions of the
G1 (hinges a sum of low-frequency sines within their limits, the floating base moving
slowly); every answer is checked by MuJoCo (mj_kinematics on the whole qpos, mj_differentiatePos
for the differences between frames), and the smoothing against tree.ik frame by frame."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_frame_pose
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
import poekin.motion
from poekin.errors import HeldFramesError, InputError, UnknownFrameError
from poekin.motion._banded import solve_pentadiagonal
from poekin.wholebody.space import space

DT = 1.0 / 30.0
TOL = 1e-9
HOLD_TOL = 1e-10
POSES = ("left_elbow_roll_link", "right_elbow_roll_link", "left_foot", "right_foot", "pelvis")
FEET = ("left_foot", "right_foot")
NOISE = 0.005  # m on every target position; NOISE rad of rotation on every pose


@pytest.fixture(scope="module")
def g1() -> tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]]:
    loaded = load_quiet("unitree_g1")
    tree = poekin.load_tree(loaded)
    fingers = tuple(n for n in tree.joint_names if n.split("_")[1] in _FINGER_WORDS)
    return tree, loaded.model, fingers


_FINGER_WORDS = {"zero", "one", "two", "three", "four", "five", "six"}


def _clip(tree: poekin.Tree, fingers: tuple[str, ...], T: int, seed: int) -> np.ndarray:
    """``(T, nq)`` a smooth motion: each hinge its mid-range plus three sines of 0.1 to 0.6 Hz
    (at most a quarter of its range together), inside its limits; the base sways and turns."""
    rng = np.random.default_rng(seed)
    sp = space(tree, fingers)
    t = np.arange(T) * DT
    lo, hi = sp.lower, sp.upper
    centre = np.clip(tree.qpos0[sp.scalar_q], lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))
    amplitude = 0.25 * np.minimum(hi - lo, 1.0) / 3
    wave = np.zeros((T, len(centre)))
    for _ in range(3):
        f = rng.uniform(0.1, 0.6, len(centre))
        phase = rng.uniform(0, 2 * np.pi, len(centre))
        wave += (
            rng.uniform(0, 1, len(centre)) * amplitude * np.sin(2 * np.pi * f * t[:, None] + phase)
        )
    q = np.repeat(tree.qpos0[None], T, axis=0)
    q[:, sp.scalar_q] = np.clip(centre + wave, lo, hi)
    q[:, 0] += 0.1 * np.sin(2 * np.pi * 0.2 * t)
    q[:, 1] += 0.05 * np.sin(2 * np.pi * 0.3 * t)
    yaw = 0.2 * np.sin(2 * np.pi * 0.15 * t)
    q[:, 3:7] = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=1)
    return q


def _targets(model: mujoco.MjModel, q: np.ndarray) -> dict[str, np.ndarray]:
    """MuJoCo's poses of the hands, feet and pelvis, and the head's position, per frame."""
    out: dict[str, list[np.ndarray]] = {f: [] for f in (*POSES, "head")}
    ids = {}
    for f in out:  # the feet and the head are sites, the rest bodies
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f)
        ids[f] = ("site", site) if site >= 0 else ("body", model.body(f).id)
    data = mujoco.MjData(model)
    for row in q:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        for f, (kind, i) in ids.items():
            T = mj_frame_pose(model, data, kind, i)
            out[f].append(T[:3, 3] if f == "head" else T)
    return {f: np.array(v) for f, v in out.items()}


def _noisy(targets: dict[str, np.ndarray], seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    out = {}
    for f, v in targets.items():
        v = np.array(v)
        if v.ndim == 2:
            out[f] = v + rng.normal(0, NOISE, v.shape)
            continue
        v[:, :3, 3] += rng.normal(0, NOISE, (len(v), 3))
        v[:, :3, :3] = poekin.exp_so3(rng.normal(0, NOISE, (len(v), 3))) @ v[:, :3, :3]
        out[f] = v
    return out


def _mj_errors(
    model: mujoco.MjModel, qpos: np.ndarray, targets: dict[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Per frame name, ``(T,)`` the larger of MuJoCo's position and angle errors."""
    found = _targets(model, qpos)
    out = {}
    for f, target in targets.items():
        if target.ndim == 2:
            out[f] = np.linalg.norm(found[f] - target, axis=1)
            continue
        pos, ori = poekin.pose_errors(target, found[f])
        out[f] = np.maximum(pos, ori)
    return out


def _velocities(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """``(T - 1, nv)`` MuJoCo's ``(q_{t+1} - q_t) / dt`` on the configuration space."""
    out = np.zeros((len(qpos) - 1, model.nv))
    for t in range(len(qpos) - 1):
        mujoco.mj_differentiatePos(model, out[t], DT, qpos[t], qpos[t + 1])
    return out


def _mean_acceleration(model: mujoco.MjModel, qpos: np.ndarray) -> float:
    """The mean of ``|qdd|`` over the hinge entries and the frames (rad/s^2)."""
    qdd = np.diff(_velocities(model, qpos), axis=0) / DT
    return float(np.mean(np.abs(qdd[:, 6:])))


def _rms(errors: dict[str, np.ndarray]) -> float:
    return float(np.sqrt(np.mean(np.square(np.stack(list(errors.values()))))))


def _within_limits(tree: poekin.Tree, qpos: np.ndarray) -> None:
    sp = space(tree, ())
    q = qpos[:, sp.scalar_q]
    assert np.all((q >= sp.lower) & (q <= sp.upper))
    np.testing.assert_allclose(np.linalg.norm(qpos[:, 3:7], axis=1), 1.0, atol=1e-15)


# --- the banded solver ------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 9), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_pentadiagonal_solve_against_dense(T: int, n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(T * n, T * n))
    H = H + H.T
    frame = np.arange(T * n) // n
    H[np.abs(frame[:, None] - frame[None, :]) > 2] = 0.0  # blocks two frames apart at most
    H += 2 * T * n * np.eye(T * n)  # diagonally dominant: positive definite
    block = [[H[a * n : (a + 1) * n, b * n : (b + 1) * n] for b in range(T)] for a in range(T)]
    D = np.array([block[t][t] for t in range(T)])
    U1 = np.array([block[t][t + 1] for t in range(T - 1)]).reshape(-1, n, n)
    U2 = np.array([block[t][t + 2] for t in range(T - 2)]).reshape(-1, n, n)
    r = rng.normal(size=(T, n))
    x = solve_pentadiagonal(D, U1, U2, r)
    np.testing.assert_allclose(x.ravel(), np.linalg.solve(H, r.ravel()), rtol=0, atol=1e-12)


# --- exact targets ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "frames", [40, pytest.param(300, marks=pytest.mark.slow)]
)  # 300: the issue's
def test_exact_clip_recovered_checked_by_mujoco(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]], frames: int
) -> None:
    tree, model, fingers = g1
    q_true = _clip(tree, fingers, frames, seed=1)
    targets = _targets(model, q_true)
    # smoothing this small leaves exact targets exact; its terms still couple the frames
    found = poekin.motion.track(
        tree, targets, tree.qpos0, freeze=fingers, smooth_velocity=0.0, smooth_acceleration=1e-15
    )
    assert found.success and found.qpos.shape == (frames, tree.nq)
    for frame, err in _mj_errors(model, found.qpos, targets).items():
        assert err.max() <= TOL, (frame, err.max())
    assert np.max(found.pos_err) <= TOL and np.max(found.ori_err) <= TOL
    _within_limits(tree, found.qpos)


def test_held_feet_met_where_in_contact(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]],
) -> None:
    tree, model, fingers = g1
    q_true = _clip(tree, fingers, 24, seed=2)
    targets = _noisy(_targets(model, q_true), seed=3)
    exact = _targets(model, q_true)
    for foot in FEET:  # a held foot's target is where it is
        targets[foot] = exact[foot]
    contact = np.ones((24, 2), dtype=bool)
    contact[8:16, 0] = False  # the left foot swings in the middle
    found = poekin.motion.track(
        tree, targets, tree.qpos0, hold=FEET, contact=contact, freeze=fingers
    )
    errors = _mj_errors(model, found.qpos, targets)
    for k, foot in enumerate(FEET):
        assert errors[foot][contact[:, k]].max() <= HOLD_TOL + MJ_TOL, foot
    assert found.success
    _within_limits(tree, found.qpos)


# --- noisy targets: smoother than frame by frame -----------------------------------------------


def _smoothing(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]], T: int
) -> tuple[float, float, float, float]:
    """Mean joint acceleration and RMS target error (against the noisy targets) of track and
    of tree.ik frame by frame, each frame from the last answer."""
    tree, model, fingers = g1
    targets = _noisy(_targets(model, _clip(tree, fingers, T, seed=4)), seed=5)
    found = poekin.motion.track(tree, targets, tree.qpos0, freeze=fingers)
    frames, q = [], tree.qpos0
    for t in range(T):
        one = {f: v[t] for f, v in targets.items()}
        q = tree.ik(one, q, position_only={"head"}, freeze=fingers, max_attempts=1).qpos
        frames.append(q)
    by_frame = np.array(frames)
    return (
        _mean_acceleration(model, found.qpos),
        _rms(_mj_errors(model, found.qpos, targets)),
        _mean_acceleration(model, by_frame),
        _rms(_mj_errors(model, by_frame, targets)),
    )


def test_noisy_clip_smoother_than_frame_by_frame(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]],
) -> None:
    acc, err, acc_frames, err_frames = _smoothing(g1, 45)
    assert acc < acc_frames / 4, (acc, acc_frames)
    assert err < 1.2 * err_frames, (err, err_frames)


@pytest.mark.slow
def test_noisy_300_frames_smoother_than_frame_by_frame(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]],
) -> None:
    acc, err, acc_frames, err_frames = _smoothing(g1, 300)
    assert acc < acc_frames / 4, (acc, acc_frames)
    assert err < 1.2 * err_frames, (err, err_frames)


# --- the answer is the least-squares solution of the stated cost --------------------------------


def _cost(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    targets: dict[str, np.ndarray],
    a_v: float,
    a_a: float,
) -> float:
    """The module's cost from MuJoCo alone: positions, ``0.3^2 (3 - tr(R_target^T R))`` per
    pose (``|e_o|^2 = 4 sin^2(theta / 2)``), and the velocity and acceleration costs from
    mj_differentiatePos."""
    found = _targets(model, qpos)
    total = 0.0
    for f, target in targets.items():
        if target.ndim == 2:
            total += np.sum((found[f] - target) ** 2)
            continue
        total += np.sum((found[f][:, :3, 3] - target[:, :3, 3]) ** 2)
        trace = np.einsum("tij,tij->t", target[:, :3, :3], found[f][:, :3, :3])
        total += 0.09 * np.sum(3.0 - trace)
    v = _velocities(model, qpos)
    a = np.diff(v, axis=0) / DT
    return float(total + a_v * np.sum(v * v) + a_a * np.sum(a * a))


def test_answer_is_a_stationary_point_of_the_cost(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]],
) -> None:
    tree, model, fingers = g1
    T, a_v, a_a = 10, 1e-4, 1e-6
    targets = _noisy(_targets(model, _clip(tree, fingers, T, seed=6)), seed=7)
    found = poekin.motion.track(
        tree,
        targets,
        tree.qpos0,
        freeze=fingers,
        smooth_velocity=a_v,
        smooth_acceleration=a_a,
        max_iterations=200,
    )
    sp = space(tree, fingers)
    rng = np.random.default_rng(8)

    def slope(q: np.ndarray, u: np.ndarray, eps: float = 1e-6) -> float:
        ends = []
        for sign in (1.0, -1.0):
            moved = np.array(q)
            for t in range(T):
                mujoco.mj_integratePos(model, moved[t], sign * u[t], eps)
            ends.append(_cost(model, moved, targets, a_v, a_a))
        return (ends[0] - ends[1]) / (2 * eps)

    for _ in range(3):
        u = np.zeros((T, tree.nv))
        u[:, sp.variables] = rng.normal(size=(T, sp.n))
        away = np.array(found.qpos)
        for t in range(T):
            mujoco.mj_integratePos(model, away[t], u[t], 1e-3)
        assert abs(slope(found.qpos, u)) <= 1e-3 * abs(slope(away, u))


# --- velocity limits ----------------------------------------------------------------------------


def test_velocity_limits_hold_at_every_frame(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]],
) -> None:
    tree, model, fingers = g1
    q_true = _clip(tree, fingers, 20, seed=9)
    targets = _targets(model, q_true)
    v_max = 0.3  # rad/s: slower than the clip's fastest joints
    assert np.abs(_velocities(model, q_true)[:, 6:]).max() > 1.5 * v_max
    found = poekin.motion.track(tree, targets, tree.qpos0, freeze=fingers, velocity_limits=v_max)
    v = _velocities(model, found.qpos)[:, 6:]
    assert np.abs(v).max() <= v_max * (1 + 1e-9)
    assert np.abs(v).max() >= v_max * 0.99  # the limit binds
    _within_limits(tree, found.qpos)


# --- small clips and starts ---------------------------------------------------------------------


def test_one_frame_and_a_start_per_frame(
    g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]],
) -> None:
    tree, model, fingers = g1
    q_true = _clip(tree, fingers, 3, seed=10)
    targets = _targets(model, q_true)
    one = poekin.motion.track(tree, {f: v[:1] for f, v in targets.items()}, freeze=fingers)
    assert one.qpos.shape == (1, tree.nq) and one.success
    assert (
        max(
            e.max()
            for e in _mj_errors(model, one.qpos, {f: v[:1] for f, v in targets.items()}).values()
        )
        <= TOL
    )
    start = poekin.motion.track(
        tree, targets, q_true, freeze=fingers, smooth_velocity=0.0, smooth_acceleration=0.0
    )
    np.testing.assert_allclose(start.qpos, q_true, atol=1e-12)
    assert start.iterations <= 2


# --- bad input ----------------------------------------------------------------------------------


def test_bad_inputs(g1: tuple[poekin.Tree, mujoco.MjModel, tuple[str, ...]]) -> None:
    tree, _, _ = g1
    T = tree.fk(np.repeat(tree.qpos0[None], 4, axis=0))
    pelvis, foot = T[:, tree.frame_index("pelvis")], T[:, tree.frame_index("left_foot")]
    track = poekin.motion.track
    with pytest.raises(InputError, match=r"same number of frames T.*'pelvis': 4.*'left_foot': 3"):
        track(tree, {"pelvis": pelvis, "left_foot": foot[:3]})
    nan = np.array(pelvis)
    nan[2, 0, 3] = np.nan
    with pytest.raises(InputError, match="'pelvis' at frame 2 has NaN"):
        track(tree, {"pelvis": nan})
    with pytest.raises(UnknownFrameError, match="did you mean 'pelvis'"):
        track(tree, {"pelvs": pelvis})
    with pytest.raises(
        InputError, match=r"\(T, 4, 4\) poses or \(T, 3\) points, got shape \(4, 4\)"
    ):
        track(tree, {"pelvis": pelvis[0]})
    with pytest.raises(InputError, match="non-empty dict"):
        track(tree, {})
    with pytest.raises(
        InputError, match="contact mask of 'left_foot' has shape \\(3,\\), the clip 4"
    ):
        track(tree, {"pelvis": pelvis, "left_foot": foot}, hold="left_foot", contact=[1, 1, 0])
    with pytest.raises(InputError, match=r"contact must be \(T,\) or \(T, 1\)"):
        track(tree, {"left_foot": foot}, hold="left_foot", contact=np.ones((4, 3), bool))
    with pytest.raises(InputError, match="must be bools"):
        track(tree, {"left_foot": foot}, hold="left_foot", contact=[0.5] * 4)
    with pytest.raises(InputError, match="hold names 'right_foot', which has no target"):
        track(tree, {"left_foot": foot}, hold="right_foot")
    with pytest.raises(InputError, match="contact is given but hold names no frame"):
        track(tree, {"left_foot": foot}, contact=[True] * 4)
    with pytest.raises(InputError, match="hold in a fixed order"):
        track(
            tree,
            {"left_foot": foot, "pelvis": pelvis},
            hold={"left_foot", "pelvis"},
            contact=np.ones((4, 2), bool),
        )
    with pytest.raises(InputError, match=r"dt must be a finite number > 0 \(s\), got 0.0"):
        track(tree, {"pelvis": pelvis}, dt=0.0)
    with pytest.raises(InputError, match="smooth_acceleration must be a finite number >= 0"):
        track(tree, {"pelvis": pelvis}, smooth_acceleration=-1.0)
    with pytest.raises(InputError, match="smooth_velocity must be a number"):
        track(tree, {"pelvis": pelvis}, smooth_velocity="high")
    with pytest.raises(InputError, match=rf"qpos0 must be \({tree.nq},\).*\(4, {tree.nq}\)"):
        track(tree, {"pelvis": pelvis}, np.zeros((3, tree.nq)))
    with pytest.raises(InputError, match="velocity_limits must be one number > 0"):
        track(tree, {"pelvis": pelvis}, velocity_limits=-1.0)
    far = np.array(foot)
    far[:, 2, 3] += 5.0  # five metres up, with the pelvis held too
    with pytest.raises(HeldFramesError):
        track(tree, {"pelvis": pelvis, "left_foot": far}, hold=("pelvis", "left_foot"))
