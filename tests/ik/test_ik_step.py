"""Chain.ik_step (poekin.ik.step): one control tick, checked against an independent bounded
least-squares solver (scipy's lsq_linear on the same rows), against mink.solve_ik on the
MuJoCo model, and by MuJoCo's FK: the limits hold at q + qvel dt; the same on JAX and PyTorch."""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import pytest
from array_libs import load as load_lib
from helpers import load_quiet, mj_frame_pose

import poekin
from poekin._poe import pose_of
from poekin.chain import Chain
from poekin.errors import InputError
from poekin.ik import numerical

optimize = pytest.importorskip("scipy.optimize")

DT = 0.002
VMAX = np.pi  # rad/s


@pytest.fixture(scope="module")
def fr3() -> Chain:
    return poekin.load(load_quiet("franka_fr3"))


def _rows(chain: Chain, T: np.ndarray, q: np.ndarray, **options: Any) -> tuple[np.ndarray, ...]:
    """The residual ``r`` and its Jacobian ``J`` (of ``-r``) that the step linearises: the
    numerical solver's rows (poekin.ik.numerical, steps 1 and 2)."""
    s = numerical.settings(**options)
    pose, columns = numerical.evaluate(chain, [np.array(v) for v in q], np)
    r, _, _, _, quat = numerical.residual(pose, pose_of(T), s, np)
    J = numerical.jacobian_rows(columns, quat, s)
    return np.array([[float(x) for x in row] for row in J]), np.array([float(x) for x in r])


def _reference(
    chain: Chain, T: np.ndarray, q: np.ndarray, vmax: float, damping: float = 1e-12
) -> np.ndarray:
    """The step by scipy's bounded least squares (a trust-region reflective method, not an
    active set): min |J x - r|^2 + damping |x|^2 inside the box."""
    J, r = _rows(chain, T, q)
    lo = np.clip(chain.limits[:, 0] - q, -vmax * DT, vmax * DT)
    hi = np.clip(chain.limits[:, 1] - q, -vmax * DT, vmax * DT)
    A = np.vstack([J, np.sqrt(damping) * np.eye(len(q))])
    b = np.concatenate([r, np.zeros(len(q))])
    found = optimize.lsq_linear(A, b, bounds=(lo, hi), method="bvls", tol=1e-15)
    return np.asarray(found.x) / DT


def _cost(chain: Chain, T: np.ndarray, q: np.ndarray, qvel: np.ndarray) -> float:
    J, r = _rows(chain, T, q)
    e = J @ (qvel * DT) - r
    return float(e @ e)


def _configs(chain: Chain, n: int, seed: int, margin: float = 0.2) -> np.ndarray:
    lo, hi = chain.limits[:, 0] + margin, chain.limits[:, 1] - margin
    return np.random.default_rng(seed).uniform(np.maximum(lo, -3), np.minimum(hi, 3), (n, len(lo)))


@pytest.mark.parametrize("robot", ["ur5e", "fr3"])
@pytest.mark.parametrize("reach", [0.002, 0.05, 0.5])
def test_the_step_is_the_bounded_least_squares_optimum(
    robot: str, reach: float, ur5e: Chain, fr3: Chain
) -> None:
    """Small errors (no limit active), medium ones (velocity limits active) and far targets:
    the step equals scipy's bounded least squares where that is unique, and its cost is never
    higher (the FR3's seven joints leave a direction the rows do not see, which the damping
    picks)."""
    chain = ur5e if robot == "ur5e" else fr3
    q = _configs(chain, 20, 1)
    rng = np.random.default_rng(2)
    T = chain.fk(q + rng.normal(0.0, reach, q.shape))
    qvel = chain.ik_step(T, q, DT, velocity_limits=VMAX)
    for k in range(len(q)):
        ref = _reference(chain, T[k], q[k], VMAX)
        assert _cost(chain, T[k], q[k], qvel[k]) <= _cost(chain, T[k], q[k], ref) + 1e-15
        if robot == "ur5e":
            np.testing.assert_allclose(qvel[k], ref, atol=1e-7)
        assert np.all(np.abs(qvel[k]) <= VMAX * (1 + 1e-12))


def test_a_step_the_box_cuts_takes_few_rounds(ur5e: Chain) -> None:
    """Ticks near the UR5e's home toward targets 0.02 rad (per joint) away at pi rad/s, where
    the velocity limits cut most steps: the first round's clamped answer and its working set
    leave a median of 3 further rounds per step (the active set from ``x = 0``, fixing one
    joint a round and testing the multipliers in a round of their own, took 7), and the
    answer is the bounded least-squares optimum."""
    from poekin.ik import step

    rng = np.random.default_rng(21)
    home = np.array([-1.5708, -1.5708, 1.5708, -1.5708, -1.5708, 0.0])  # the model's key
    q = home + rng.normal(0.0, 0.1, (500, 6))
    T = ur5e.fk(q + rng.normal(0.0, 0.02, q.shape))
    reach = VMAX * DT
    lo = list(np.clip(ur5e.limits[:, 0] - q, -reach, reach).T)
    hi = list(np.clip(ur5e.limits[:, 1] - q, -reach, reach).T)
    taken = np.zeros(len(q))

    def loop(rounds: int, body: Any, state: Any, data: Any) -> Any:
        for _ in range(rounds):
            if np.all(state.done):
                break
            taken[:] += ~state.done
            state = body(state, data)
        return state

    x = step.step_entries(
        ur5e, list(q.T), pose_of(T), (lo, hi), 1.0, 1e-12, numerical.settings(), np, loop=loop
    )
    assert np.median(taken) <= 3 and taken.max() <= 8, (np.median(taken), taken.max())
    for k in range(0, 500, 50):
        qvel = np.array([float(v[k]) for v in x]) / DT
        np.testing.assert_allclose(qvel, _reference(ur5e, T[k], q[k], VMAX), atol=1e-6)


def test_limits_hold_at_the_next_configuration(ur5e: Chain) -> None:
    """A target beyond a joint's limit: the step stops that joint exactly at its limit (MuJoCo's
    limits, read from the model), and the others still move toward the target."""
    loaded = load_quiet("universal_robots_ur5e")
    model = loaded.model
    limits = np.array([model.jnt_range[model.joint(name).id] for name in ur5e.joint_names])
    q = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    q[2] = limits[2, 1] - 1e-4  # the elbow a hair below its upper limit
    beyond = q.copy()
    beyond[2] = limits[2, 1] + 0.1
    beyond[0] += 0.01
    T = ur5e.fk(beyond)
    qvel = ur5e.ik_step(T, q, DT, velocity_limits=VMAX)
    nxt = q + qvel * DT
    assert nxt[2] == pytest.approx(limits[2, 1], abs=1e-15)
    np.testing.assert_allclose(qvel, _reference(ur5e, T, q, VMAX), atol=1e-7)
    assert np.all(nxt >= limits[:, 0]) and np.all(nxt <= limits[:, 1])
    data = mujoco.MjData(model)
    site = model.site("attachment_site").id
    before, after = [], []
    for config, out in ((q, before), (nxt, after)):
        data.qpos[:] = config
        mujoco.mj_kinematics(model, data)
        out.append(mj_frame_pose(model, data, "site", site))
    assert np.linalg.norm(after[0][:3, 3] - T[:3, 3]) < np.linalg.norm(before[0][:3, 3] - T[:3, 3])


def test_a_reachable_target_is_met_in_one_tick_by_mujocos_fk(ur5e: Chain) -> None:
    """gain 1 and no velocity limit: one step is one Gauss-Newton iteration, so a target 1e-4
    rad away is met to second order (about 1e-8 m by MuJoCo's FK of q + qvel dt)."""
    loaded = load_quiet("universal_robots_ur5e")
    model, data = loaded.model, mujoco.MjData(loaded.model)
    q = _configs(ur5e, 10, 3)
    goal = q + np.random.default_rng(4).normal(0.0, 1e-4, q.shape)
    qvel = ur5e.ik_step(ur5e.fk(goal), q, DT)
    site = model.site("attachment_site").id
    for k in range(len(q)):
        data.qpos[:] = q[k] + qvel[k] * DT
        mujoco.mj_kinematics(model, data)
        got = mj_frame_pose(model, data, "site", site)
        data.qpos[:] = goal[k]
        mujoco.mj_kinematics(model, data)
        want = mj_frame_pose(model, data, "site", site)
        assert np.linalg.norm(got[:3, 3] - want[:3, 3]) < 1e-7


def test_small_errors_give_minks_step(ur5e: Chain) -> None:
    """mink.solve_ik on the MuJoCo model, the same frame task (position cost 1, orientation
    0.3), ConfigurationLimit and VelocityLimit: the same step where the error is small (the
    two residuals, mink's log and poekin's quaternion, agree to first order)."""
    mink = pytest.importorskip("mink")
    loaded = load_quiet("universal_robots_ur5e")
    model = loaded.model
    q = _configs(ur5e, 5, 5)
    goal = q + np.random.default_rng(6).normal(0.0, 1e-4, q.shape)
    T = ur5e.fk(goal)
    qvel = ur5e.ik_step(T, q, DT, velocity_limits=VMAX)
    for k in range(len(q)):
        config = mink.Configuration(model)
        config.update(q[k])
        task = mink.FrameTask(
            "attachment_site", "site", position_cost=1.0, orientation_cost=0.3, lm_damping=0.0
        )
        task.set_target(mink.SE3.from_matrix(T[k]))
        limits = [
            mink.ConfigurationLimit(model, gain=1.0),
            mink.VelocityLimit(model, dict.fromkeys(ur5e.joint_names, VMAX)),
        ]
        theirs = mink.solve_ik(config, [task], DT, "daqp", damping=1e-12, limits=limits)
        # the step itself (qvel dt, rad) to 1e-6, as tests/wholebody/test_step.py: the error
        # definitions differ at second order (mink's body twist, poekin's world-axes rows)
        np.testing.assert_allclose(qvel[k] * DT, theirs * DT, atol=1e-6, rtol=0)


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_batches_give_the_bits_of_single_calls(ur5e: Chain, shape: tuple[int, ...]) -> None:
    count = int(np.prod(shape, dtype=int))
    q = _configs(ur5e, count, 7)
    T = ur5e.fk(q + np.random.default_rng(8).normal(0.0, 0.05, q.shape))
    qvel = ur5e.ik_step(T.reshape(*shape, 4, 4), q.reshape(*shape, 6), DT, velocity_limits=VMAX)
    assert qvel.shape == (*shape, 6)
    flat = qvel.reshape(count, 6)
    for k in range(count):
        one = ur5e.ik_step(T[k], q[k], DT, velocity_limits=VMAX)
        assert np.array_equal(one, flat[k])


def test_one_target_for_many_configurations_broadcasts(ur5e: Chain) -> None:
    q = _configs(ur5e, 4, 9)
    T = ur5e.fk(q[0] + 0.01)
    qvel = ur5e.ik_step(T, q, DT)
    assert qvel.shape == (4, 6)
    assert np.array_equal(qvel[2], ur5e.ik_step(T, q[2], DT))


def test_position_only_moves_the_origin(ur5e: Chain) -> None:
    q = _configs(ur5e, 1, 10)[0]
    T = ur5e.fk(q + 1e-4)
    T_turned = T.copy()
    T_turned[:3, :3] = poekin.exp_so3([0.0, 0.0, 1.0]) @ T[:3, :3]  # the orientation ignored
    a = ur5e.ik_step(T, q, DT, position_only=True)
    b = ur5e.ik_step(T_turned, q, DT, position_only=True)
    assert np.array_equal(a, b)
    p = ur5e.fk(q + a * DT)[:3, 3]
    assert np.linalg.norm(p - T[:3, 3]) < 1e-7


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"dt": 0.0}, "dt must be a finite number > 0"),
        ({"dt": "fast"}, "dt must be a number"),
        ({"gain": -1.0}, "gain must be a finite number >= 0"),
        ({"damping": float("nan")}, "damping must be a finite number >= 0"),
        ({"velocity_limits": [1.0, 2.0]}, "velocity_limits must be one number > 0 or 6"),
        ({"velocity_limits": 0.0}, "velocity_limits must be one number > 0 or 6"),
    ],
)
def test_bad_options(ur5e: Chain, options: dict[str, Any], message: str) -> None:
    q = np.zeros(6)
    dt = options.pop("dt", DT)
    with pytest.raises(InputError, match=message):
        ur5e.ik_step(ur5e.fk(q), q, dt, **options)


def test_bad_targets_and_values(ur5e: Chain) -> None:
    q = np.zeros(6)
    T = ur5e.fk(q)
    with pytest.raises(InputError, match="targets must have shape"):
        ur5e.ik_step(T[:3], q, DT)
    with pytest.raises(InputError, match="expected 6 q values"):
        ur5e.ik_step(T, q[:5], DT)
    with pytest.raises(InputError, match="NaN"):
        ur5e.ik_step(T, np.full(6, np.nan), DT)
    bad = T.copy()
    bad[0, 3] = np.nan
    with pytest.raises(InputError, match="NaN"):
        ur5e.ik_step(bad, q, DT)
    with pytest.raises(InputError, match="does not broadcast"):
        ur5e.ik_step(np.broadcast_to(T, (3, 4, 4)), np.zeros((2, 6)), DT)


@pytest.mark.parametrize(
    "name",
    [pytest.param("jax", marks=pytest.mark.slow), "torch"],  # JAX: 13 s of tracing
)
def test_arrays_give_numpys_step(name: str, ur5e: Chain, fr3: Chain) -> None:
    """JAX arrays (under jit and vmap too) and PyTorch tensors: NumPy's step to rounding (the
    libraries' own sine and cosine), with the same limits active. Under JAX, vmapped over two
    batches of 64 ticks whose velocity limits cut most steps: the rounds run on the whole batch
    until at most 8 steps are left, then on those alone (poekin.ik.step.COMPACT)."""
    lib = load_lib(name)
    # JAX traces each chain for seconds: the FR3's dual systems on PyTorch, the UR5e's on both
    for chain in (ur5e,) if name == "jax" else (ur5e, fr3):
        q = _configs(chain, 128 if name == "jax" else 8, 11)
        T = chain.fk(q + np.random.default_rng(12).normal(0.0, 0.05, q.shape))
        want = chain.ik_step(T, q, DT, velocity_limits=VMAX)

        def step(T_: Any, q_: Any, c: Chain = chain) -> Any:
            return c.ik_step(T_, q_, DT, velocity_limits=VMAX)

        if name == "jax":  # traced once (eager JAX takes seconds)
            jax, n = lib.module, chain.n_joints
            halves = lib.asarray(T.reshape(2, 64, 4, 4)), lib.asarray(q.reshape(2, 64, n))
            got = lib.numpy(jax.jit(jax.vmap(step))(*halves)).reshape(128, n)
        else:
            got = lib.numpy(step(lib.asarray(T), lib.asarray(q)))
        np.testing.assert_allclose(got, want, atol=1e-10)


@pytest.mark.parametrize(
    "name",
    [pytest.param("jax", marks=pytest.mark.slow), "torch"],  # JAX: 12 s of tracing
)
def test_arrays_differentiate_the_step(name: str, ur5e: Chain) -> None:
    """No limit active: d qvel / d q by the library's reverse mode equals central differences
    of NumPy's step."""
    lib = load_lib(name)
    q = _configs(ur5e, 1, 13)[0]
    T = ur5e.fk(q + 1e-3)

    def f(q_: Any) -> Any:
        return ur5e.ik_step(lib.asarray(T), q_, DT)[0]

    if name == "jax":  # traced once, not run op by op
        jax = lib.module
        grad = lib.numpy(jax.jit(jax.grad(f))(lib.asarray(q)))
    else:
        grad = lib.numpy(lib.grad(f, lib.asarray(q)))
    h = 1e-6
    fd = np.array(
        [
            (ur5e.ik_step(T, q + h * e, DT)[0] - ur5e.ik_step(T, q - h * e, DT)[0]) / (2 * h)
            for e in np.eye(6)
        ]
    )
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-5)


@pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")
@pytest.mark.parametrize("robot", ["ur5e", "fr3"])
@pytest.mark.parametrize("position_only", [False, True])
def test_the_kernel_gives_the_references_bits(
    robot: str, position_only: bool, ur5e: Chain, fr3: Chain, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The compiled twin (_ik_step.h) against the NumPy reference (step_entries), bit for bit:
    small and far targets, limits and velocity limits active, the FR3's dual systems, at this
    machine's width (CI runs this file at the narrower ones too)."""
    from poekin.ik import step

    chain = ur5e if robot == "ur5e" else fr3
    rng = np.random.default_rng(14)
    q = np.concatenate([_configs(chain, 40, 15), _configs(chain, 20, 16, margin=0.0)])
    q[-10:, 1] = chain.limits[1, 1]  # on a limit
    T = chain.fk(q + rng.normal(0.0, 1.0, q.shape) * rng.choice([1e-4, 1e-2, 1.0], (len(q), 1)))
    options = {
        "velocity_limits": rng.uniform(0.5, 3.0, chain.n_joints),
        "position_only": position_only,
    }
    quick = chain.ik_step(T, q, DT, **options)
    usual = step.step(
        chain,
        T,
        q,
        DT,
        velocity_limits=options["velocity_limits"],
        gain=0.9,
        damping=1e-6,
        s=numerical.settings(position_only=position_only),
    )
    monkeypatch.setattr(step, "_ik_kernel", lambda chain: None)
    reference = chain.ik_step(T, q, DT, **options)
    assert np.array_equal(quick, reference)
    reference_usual = step.step(
        chain,
        T,
        q,
        DT,
        velocity_limits=options["velocity_limits"],
        gain=0.9,
        damping=1e-6,
        s=numerical.settings(position_only=position_only),
    )
    assert np.array_equal(usual, reference_usual)


def test_the_quick_path_leaves_bad_input_to_the_usual_one(ur5e: Chain) -> None:
    """Arrays the kernel takes as they are give the usual path's bits; a NaN, a target that is
    not rigid or a wrong shape goes to the validation and its message."""
    from poekin.ik import step

    q = _configs(ur5e, 3, 17)
    T = ur5e.fk(q + 0.01)
    usual = step.step(
        ur5e, T, q, DT, velocity_limits=None, gain=1.0, damping=1e-12, s=numerical.settings()
    )
    assert np.array_equal(ur5e.ik_step(T, q, DT), usual)
    sheared = T.copy()
    sheared[0, 0, 1] += 0.01
    with pytest.raises(InputError, match="not a rigid transform"):
        ur5e.ik_step(sheared, q, DT)
    with pytest.raises(InputError, match="expected 6 q values"):
        ur5e.ik_step(T, q[:, :4].copy(), DT)
