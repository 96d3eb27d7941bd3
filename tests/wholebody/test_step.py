"""Tree.ik_step (poekin.wholebody.step): one control tick, against mink.solve_ik on the same
tasks, limits and dt, and checked by MuJoCo's Jacobians: held frames do not move, limits hold
at qpos + qvel dt."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from helpers import load_quiet

import poekin
from poekin.errors import InputError
from poekin.wholebody.space import space

mink = pytest.importorskip("mink")

DT = 0.002
VMAX = np.pi  # rad/s, every joint


def _mink_step(
    model: mujoco.MjModel,
    tree: poekin.Tree,
    q: np.ndarray,
    targets: dict[str, np.ndarray],
    held: tuple[str, ...] = (),
) -> np.ndarray:
    """mink's step on the problem ik_step poses: frame tasks with position cost 1 and
    orientation cost 0.3 (poekin's orientation_weight), no Levenberg-Marquardt damping,
    the held frames as equality constraints with gain 0 (zero velocity), ConfigurationLimit
    with gain 1 (the limits themselves), VelocityLimit on every hinge."""
    config = mink.Configuration(model)
    config.update(q)
    tasks, constraints = [], []
    for frame, T in targets.items():
        kind = "site" if frame in tree.site_names else "body"
        task = mink.FrameTask(frame, kind, position_cost=1.0, orientation_cost=0.3, lm_damping=0.0)
        if frame in held:
            task = mink.FrameTask(frame, kind, position_cost=1.0, orientation_cost=1.0, gain=0.0)
        task.set_target(mink.SE3.from_matrix(T))
        (constraints if frame in held else tasks).append(task)
    hinges = [n for n, t in zip(tree.joint_names, tree.joint_types, strict=True) if t == "revolute"]
    limits = [
        mink.ConfigurationLimit(model, gain=1.0),
        mink.VelocityLimit(model, dict.fromkeys(hinges, VMAX)),
    ]
    return np.asarray(
        mink.solve_ik(
            config, tasks, DT, "daqp", damping=1e-12, limits=limits, constraints=constraints or None
        )
    )


def _velocity_limits(tree: poekin.Tree) -> np.ndarray:
    names = tree.dof_names()
    hinge = {n for n, t in zip(tree.joint_names, tree.joint_types, strict=True) if t == "revolute"}
    return np.array([VMAX if n in hinge else np.inf for n in names])


def _cost(
    tree: poekin.Tree, q: np.ndarray, targets: dict[str, np.ndarray], qvel: np.ndarray
) -> float:
    """ik_step's own level-2 cost of a step: sum |J dq - e|^2 over the soft frames."""
    from poekin.ik.numerical import settings
    from poekin.wholebody.solve import _problem
    from poekin.wholebody.tasks import parse

    problem, qq, _ = _problem(
        tree, parse(tree, targets), q, 0.0, (), settings(), 0, clip=False, starts=False
    )
    _, _, C, d, _ = problem.residual(qq)
    x = (qvel * DT)[problem.space.variables]
    r = C[0] @ x - d[0]
    return float(r @ r)


@pytest.mark.parametrize(
    ("robot", "frame"),
    [("universal_robots_ur5e", "attachment_site"), ("franka_fr3", "attachment_site")],
)
def test_small_errors_give_minks_step(robot: str, frame: str) -> None:
    loaded = load_quiet(robot)
    tree, model = poekin.load_tree(loaded), loaded.model
    rng = np.random.default_rng(0)
    for seed in range(10):
        q = poekin.sample_qpos(tree, 1, seed=seed, within_limits=True)[0]
        T = tree.pose(q, frame).copy()
        T[:3, 3] += rng.normal(0.0, 1e-4, 3)  # a teleoperation handle moves 0.1 mm a tick
        T[:3, :3] = poekin.lie.exp_so3(rng.normal(0.0, 1e-4, 3)) @ T[:3, :3]
        targets = {frame: T}
        ours = tree.ik_step(targets, q, DT, velocity_limits=_velocity_limits(tree))
        theirs = _mink_step(model, tree, q, targets)
        # the step itself (qvel dt, rad) to 1e-6; the error definitions differ at second
        # order (mink: the body twist log(T^-1 T_target); poekin: p_t - p and the rotation's
        # quaternion vector, in world axes), about |e|^2 = 1e-8 rad here
        np.testing.assert_allclose(ours * DT, theirs * DT, atol=1e-6, rtol=0)


def test_active_limits_give_a_step_no_worse_than_minks() -> None:
    loaded = load_quiet("universal_robots_ur5e")
    tree, model = poekin.load_tree(loaded), loaded.model
    vel = _velocity_limits(tree)
    lower, upper = tree.joint_limits[:, 0], tree.joint_limits[:, 1]
    for seed in range(10):
        q = poekin.sample_qpos(tree, 1, seed=seed, within_limits=True)[0]
        T = tree.pose(
            poekin.sample_qpos(tree, 1, seed=100 + seed, within_limits=True)[0], "attachment_site"
        )
        targets = {"attachment_site": T}  # far: the velocity limits bind
        ours = tree.ik_step(targets, q, DT, velocity_limits=vel)
        theirs = _mink_step(model, tree, q, targets)
        for step in (ours, theirs):  # both meet every constraint
            assert np.all(np.abs(step) <= VMAX * (1 + 1e-9))
            assert np.all((q + step * DT >= lower - 1e-12) & (q + step * DT <= upper + 1e-12))
        # the two error definitions differ at this distance, so the steps do too; each is
        # optimal for its own cost, so ours is no worse in ours
        assert _cost(tree, q, targets, ours) <= _cost(tree, q, targets, theirs) * (1 + 1e-9) + 1e-18


def test_g1_held_feet_do_not_move_and_match_mink() -> None:
    loaded = load_quiet("unitree_g1")
    tree, model = poekin.load_tree(loaded), loaded.model
    q = np.array(tree.qpos0)
    T = tree.fk(q)
    rng = np.random.default_rng(1)
    targets = {f: T[tree.frame_index(f)] for f in ("left_foot", "right_foot")}
    for f in ("left_elbow_roll_link", "right_elbow_roll_link", "pelvis"):
        moved = T[tree.frame_index(f)].copy()
        moved[:3, 3] += rng.normal(0.0, 1e-4, 3)
        targets[f] = moved
    held = ("left_foot", "right_foot")
    ours = tree.ik_step(targets, q, DT, hold=set(held), velocity_limits=_velocity_limits(tree))
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    for f in held:
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(
            model, data, jacp, jacr, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f)
        )
        assert np.abs(jacp @ ours).max() <= 1e-10 and np.abs(jacr @ ours).max() <= 1e-10, f
    theirs = _mink_step(model, tree, q, targets, held)
    # 43 joints for 30 rows, the arms near straight at qpos0: the cost is flat along many
    # steps, and mink's QP (regularised by damping=1e-12 only, solved to daqp's tolerance)
    # stops at 3x the cost poekin's reaches (1e-11 against 5e-12 here), 1e-3 rad/s away.
    # So: every constraint met (above), and a cost no higher than mink's.
    soft = {f: targets[f] for f in targets if f not in held}
    assert _cost(tree, q, soft, ours) <= _cost(tree, q, soft, theirs) + 1e-18


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_batches_give_the_steps_of_single_calls(shape: tuple[int, ...]) -> None:
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    n = int(np.prod(shape))
    q = poekin.sample_qpos(tree, n, seed=3, within_limits=True)
    T = tree.fk(poekin.sample_qpos(tree, n, seed=4, within_limits=True))[
        :, tree.frame_index("attachment_site")
    ]
    many = tree.ik_step(
        {"attachment_site": T.reshape(*shape, 4, 4)}, q.reshape(*shape, 6), DT, velocity_limits=VMAX
    )
    assert many.shape == (*shape, 6)
    for i in range(n):
        one = tree.ik_step({"attachment_site": T[i]}, q[i], DT, velocity_limits=VMAX)
        np.testing.assert_allclose(many.reshape(-1, 6)[i], one, atol=1e-12, rtol=0)
        within = q[i] + one * DT
        sp = space(tree, ())
        assert np.all((within >= sp.lower - 1e-12) & (within <= sp.upper + 1e-12))


def test_bad_step_options() -> None:
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    targets = {"attachment_site": tree.pose(tree.qpos0, "attachment_site")}
    with pytest.raises(InputError, match="dt must be a finite number > 0"):
        tree.ik_step(targets, tree.qpos0, 0.0)
    with pytest.raises(InputError, match="velocity_limits must be one number > 0 or 6"):
        tree.ik_step(targets, tree.qpos0, DT, velocity_limits=[1.0, 2.0])
    with pytest.raises(InputError, match="gain must be"):
        tree.ik_step(targets, tree.qpos0, DT, gain=-1.0)


def test_a_urdfs_velocity_limits_bound_the_step() -> None:
    """<limit velocity> read as Pinocchio reads it (model.velocityLimit), and the step within
    it when no velocity_limits are given; a continuous joint has none."""
    import pathlib

    pin = pytest.importorskip("pinocchio")
    path = pathlib.Path(__file__).parents[1] / "data" / "urdf" / "serial_arm.urdf"
    tree = poekin.load_tree(path)
    model = pin.buildModelFromUrdf(str(path))
    by_name = {
        name: float(model.velocityLimit[model.joints[model.getJointId(name)].idx_v])
        for name in tree.joint_names
    }
    for name, speed in zip(tree.joint_names, tree.joint_velocity_limits, strict=True):
        assert speed == by_name[name] or (np.isinf(speed) and name == "j4"), name
    frame = tree.frame_names[-1]
    far = tree.pose(np.full(tree.nq, 1.0), frame)
    qvel = tree.ik_step({frame: far}, np.zeros(tree.nq), 0.01)
    assert np.all(np.abs(qvel) <= tree.joint_velocity_limits * (1 + 1e-12))
    assert np.any(np.isclose(np.abs(qvel), tree.joint_velocity_limits, rtol=1e-12))


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "franka_fr3"])
def test_a_joint_outside_its_limits_moves_back_at_its_velocity_limit(robot: str) -> None:
    """A joint beyond its limit by more than one tick's reach (a simulation's overshoot) has
    no step that brings it inside: it moves back at its velocity limit, as chain.ik_step's does
    (the tree's step could leave it where it was before), and the others stay in their box."""
    tree = poekin.load_tree(load_quiet(robot))
    chain = poekin.load(load_quiet(robot))
    lo, hi = tree.joint_limits[:, 0], tree.joint_limits[:, 1]
    q = np.clip(np.asarray(tree.qpos0, dtype=float), lo, hi)
    T = tree.pose(q, "attachment_site")
    dt, speed = 0.01, 1.0
    for j in range(tree.nq):
        for side, beyond in ((1.0, hi[j] + 0.3), (-1.0, lo[j] - 0.3)):
            qo = q.copy()
            qo[j] = beyond
            qvel = tree.ik_step({"attachment_site": T}, qo, dt, velocity_limits=speed)
            assert qvel[j] == -side * speed, (j, side, qvel)
            assert chain.ik_step(T, qo, dt, velocity_limits=speed)[j] == qvel[j]
            x = qvel * dt
            others = np.arange(tree.nq) != j
            assert np.all(np.abs(qvel) <= speed)
            assert np.all(qo[others] + x[others] >= lo[others] - 1e-12)
            assert np.all(qo[others] + x[others] <= hi[others] + 1e-12)
    # no velocity limit: back inside in one tick
    qo = q.copy()
    qo[0] = hi[0] + 0.3
    qvel = tree.ik_step({"attachment_site": T}, qo, dt, velocity_limits=np.inf)
    assert qo[0] + qvel[0] * dt <= hi[0] + 1e-12


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "franka_fr3"])
def test_one_frame_of_an_arm_is_the_chains_step(robot: str) -> None:
    """One soft frame of an arm runs chain.ik_step's kernel: the same problem as the tree's own
    levels pose (the residual's exact derivative, the box), so the same step to rounding where
    it is unique, and the same cost where it is not (a position target of a redundant arm at
    its velocity limits); a tree that is not an arm keeps the levels."""
    from poekin.wholebody.step import solve_step, step_problem

    tree = poekin.load_tree(load_quiet(robot))
    chain = poekin.load(load_quiet(robot))
    frame = "attachment_site"
    lo, hi = tree.joint_limits[:, 0], tree.joint_limits[:, 1]
    rng = np.random.default_rng(27)
    q = rng.uniform(lo, hi, (200, tree.nq))
    T = tree.pose(np.clip(q + rng.normal(0.0, 0.3, q.shape), lo, hi), frame)
    for options in ({}, {"velocity_limits": 1.0}, {"gain": 0.5, "damping": 1e-6}):
        fast = tree.ik_step({frame: T}, q, 0.01, **options)
        levels = solve_step(step_problem(tree, {frame: T}, q, 0.01, **options))
        scale = np.abs(levels).max(axis=-1, keepdims=True)
        assert np.all(np.abs(fast - levels) <= 1e-9 * scale), options
        assert np.array_equal(fast, chain.ik_step(T, q, 0.01, **options))
    point = {"position_only": {frame}, "velocity_limits": 2.0}
    fast = tree.ik_step({frame: T}, q, 0.01, **point)
    problem = step_problem(tree, {frame: T}, q, 0.01, **point)
    levels = solve_step(problem)

    def cost(qvel: np.ndarray) -> np.ndarray:
        x = qvel * 0.01
        r = np.einsum("bij,bj->bi", problem.C, x) - problem.d
        return np.sum(r * r, axis=1) + problem.damping * np.sum(x * x, axis=1)

    assert np.all(np.abs(cost(fast) - cost(levels)) <= 1e-12 * (1.0 + cost(levels)))
    assert np.all(fast * 0.01 >= problem.lo - 1e-15) and np.all(fast * 0.01 <= problem.hi + 1e-15)
    assert tree._ik_cache["arm_chains"][frame] is not None
    g1 = poekin.load_tree(load_quiet("unitree_g1"))
    assert g1._arm_chain("left_elbow_roll_link") is None  # a floating base, other limbs
