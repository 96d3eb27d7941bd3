"""Pose planning (issue #22, item 3): greedy D-optimal poses within the limits that identify the
parameters; judged by the observability of the design and by calibrating a MuJoCo-perturbed
robot on them."""

from __future__ import annotations

import time
import warnings

import numpy as np
import pytest
from helpers import load_quiet, mj_pose

import poekin
from poekin.calibration import calibrate, model_of, plan_poses
from poekin.calibration.plan import (
    draw_candidates,
    make_plan,
    pose_constraints,
    quality,
    sampling_chain,
)
from poekin.calibration.simulate import simulate_robot
from poekin.errors import InputError
from poekin.verification.verify import pose_errors, sample_joint_values

pytestmark = pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")


def _load(robot: str) -> poekin.Chain:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load(robot)


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "franka_fr3"])
@pytest.mark.parametrize("measure", ["pose", "position"])
def test_planned_poses_beat_random_ones_within_the_limits(robot: str, measure: str) -> None:
    chain = _load(robot)
    n = 20 if measure == "pose" else 30
    q = plan_poses(chain, n, measure=measure)  # type: ignore[arg-type]
    assert q.shape == (n, chain.n_joints)
    assert chain.limits is not None
    assert np.all(q >= chain.limits[:, 0]) and np.all(q <= chain.limits[:, 1])
    assert len({tuple(row) for row in q}) == n  # no pose twice
    model = model_of(chain, measure)  # type: ignore[arg-type]
    o1, _ = quality(model, q)  # D-optimal: O1, not the condition number, is what it raises
    for seed in range(3):  # random designs of the same size, within the same limits
        random_q = sample_joint_values(sampling_chain(chain), n, seed=seed, within_limits=True)
        assert o1 > quality(model, random_q)[0]


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "franka_fr3"])
def test_planned_poses_calibrate_the_robot_better_than_random_ones(robot: str) -> None:
    """What planning is for: 12 planned poses calibrate a MuJoCo-perturbed robot better than 12
    random ones within the limits, judged against its true poses on 300 random configurations
    (mean over 4 robots and noise draws; about 0.6x on this machine's runs)."""
    chain = _load(robot)
    planned = plan_poses(chain, 12)
    errors: dict[str, list[float]] = {"planned": [], "random": []}
    for seed in range(4):
        sim = simulate_robot(robot, seed=seed)
        q_test = sample_joint_values(sampling_chain(chain), 300, seed=50 + seed, within_limits=True)
        truth = sim.poses(q_test)
        random_q = sample_joint_values(
            sampling_chain(chain), 12, seed=60 + seed, within_limits=True
        )
        for name, q in (("planned", planned), ("random", random_q)):
            measured = sim.measure(q, noise_m=1e-4, noise_rad=1e-4, seed=seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", poekin.errors.CalibrationWarning)
                result = calibrate(chain, q, measured, folds=0)
            pos, _ = pose_errors(truth, result.chain.fk(q_test))
            errors[name].append(float(np.sqrt(np.mean(pos**2))))
    assert np.mean(errors["planned"]) < 0.85 * np.mean(errors["random"]), errors


def test_plans_are_deterministic_for_a_seed() -> None:
    chain = _load("universal_robots_ur5e")
    a = plan_poses(chain, 12, seed=4, candidates=500)
    assert np.array_equal(a, plan_poses("universal_robots_ur5e", 12, seed=4, candidates=500))
    assert not np.array_equal(a, plan_poses(chain, 12, seed=5, candidates=500))
    assert poekin.plan_poses is plan_poses


def test_a_planned_calibration_identifies_every_parameter() -> None:
    chain = _load("franka_fr3")
    q = plan_poses(chain, 20)
    sim = simulate_robot("franka_fr3", seed=8)
    measured = sim.measure(q, noise_m=1e-4, noise_rad=1e-4, seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", poekin.errors.CalibrationWarning)  # no warning at all
        result = calibrate(chain, q, measured, folds=0)
    assert result.identifiable == result.expected_identifiable == 34
    q_test = sample_joint_values(sampling_chain(chain), 200, seed=9, within_limits=True)
    pos, ori = pose_errors(sim.poses(q_test), result.chain.fk(q_test))
    assert np.sqrt(np.mean(pos**2)) < 0.15e-3 and np.sqrt(np.mean(ori**2)) < 0.15e-3


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n": 5}, "plan at least 6"),
        ({"n": 20, "measure": "position"}, "plan at least 10"),
        ({"n": 10, "measure": "orientation"}, "measure must be 'pose' or 'position'"),
        ({"n": 10, "candidates": 5}, "candidates must be a whole number, 10 or more"),
        ({"n": 2.5}, "whole number"),
        # issue 26: the constraints
        ({"n": 10, "ranges": {"elbow": (0, 1)}}, "no joint 'elbow' in the chain; did you mean"),
        ({"n": 10, "ranges": {"elbow_joint": (1, 0)}}, r"\(1, 0\): give low below high"),
        (
            {"n": 10, "ranges": {"elbow_joint": (0, 4)}},
            r"not within the joint's limits \[-3.1415, 3.1415\] rad",
        ),
        ({"n": 10, "ranges": {"elbow_joint": (0, np.nan)}}, "two finite numbers in rad or m"),
        ({"n": 10, "ranges": {"elbow_joint": "0 1"}}, "two finite numbers in rad or m"),
        ({"n": 10, "ranges": [("elbow_joint", 0, 1)]}, "ranges must map joint names"),
        ({"n": 10, "above_z": np.inf}, "above_z must be a finite height in m"),
        ({"n": 10, "above_z": "0.05"}, "above_z must be a finite height in m"),
        ({"n": 10, "box": ((0, 0, 0), (1, 1))}, r"box must be \(\(xmin, ymin, zmin\)"),
        (
            {"n": 10, "box": ((0, 1, 0), (1, 0, 1))},
            "box: ymin 1 is not below ymax 0; give the lower corner, then",
        ),
        (
            {"n": 10, "above_z": 1.2},
            r"only 0 of 200,000 random configurations within the joint limits put the end frame "
            r"at z >= 1.2 m, too few for 10 poses: ask for a lower height",
        ),
    ],
)
def test_bad_plans_raise(kwargs: dict[str, object], message: str) -> None:
    n = kwargs.pop("n")
    if kwargs.get("measure") == "position" and n == 20:
        n = 9
    with pytest.raises(InputError, match=message):
        plan_poses("universal_robots_ur5e", n, **kwargs)  # type: ignore[arg-type]


def test_a_plan_is_bounded_and_reports_its_progress(monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 26: --plan 100000 ran for minutes with no output. A plan holds at most
    MAX_POSES (one line says why), and its steps report to a progress callback, which the
    command line draws as a bar on a terminal, without changing the plan."""
    import io

    from poekin.cli import _calibrate

    chain = poekin.load("universal_robots_ur5e")
    with pytest.raises(InputError, match=r"100000 poses: plan at most 1000 \(a tracker"):
        plan_poses(chain, 100_000)
    seen: list[int] = []
    planned = plan_poses(chain, 12, candidates=300, progress=seen.append)
    assert seen == list(range(1, 13))
    assert np.array_equal(planned, plan_poses(chain, 12, candidates=300))

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    terminal = Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    with _calibrate._bar(50, "plan", "pose") as step:
        assert step is not None
        step(50)  # a short plan: done before the bar's delay, the terminal left as it was
    assert terminal.getvalue() == ""
    monkeypatch.setattr(_calibrate, "_BAR_DELAY", 0.05)
    with _calibrate._bar(500, "plan", "pose") as step:
        assert step is not None
        time.sleep(0.1)  # a step that takes longer than the delay shows the bar
        step(250)
    assert "plan:  50%" in terminal.getvalue()
    with pytest.raises(InputError, match=r"60,000 candidates: plan from at most 50,000"):
        plan_poses(chain, 12, candidates=60_000)  # issue 26: 1,000,000 took 10 GB, silently


# --- constraints (issue 26: 17 of 40 planned UR5e poses put the flange below its base) ---------


def _mj_positions(robot: str, chain: poekin.Chain, q: np.ndarray) -> np.ndarray:
    """``(N, 3)`` the end frame's origin from MuJoCo's mj_forward, not poekin's FK."""
    loaded = load_quiet(robot)
    assert chain.qpos_indices is not None
    qpos = np.tile(loaded.model.qpos0, (len(q), 1))
    qpos[:, list(chain.qpos_indices)] = q
    return mj_pose(loaded.model, qpos, chain.frame)[:, :3, 3]


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "franka_fr3"])
def test_above_z_keeps_the_end_frame_off_the_table(robot: str) -> None:
    chain = _load(robot)
    free = plan_poses(chain, 40)
    assert np.any(_mj_positions(robot, chain, free)[:, 2] < 0)  # what the issue saw
    plan = make_plan(chain, 40, above_z=0.05, candidates=4000)
    z = _mj_positions(robot, chain, plan.q)[:, 2]
    assert np.all(z >= 0.05 - 1e-12), np.min(z)
    assert plan.q.shape == (40, chain.n_joints) and len({tuple(r) for r in plan.q}) == 40
    assert chain.limits is not None
    assert np.all(plan.q >= chain.limits[:, 0]) and np.all(plan.q <= chain.limits[:, 1])
    # the candidates: those of the unconstrained draw that MuJoCo puts at 0.05 m or higher
    # (enough of 4,000: none drawn more)
    pool = sample_joint_values(sampling_chain(chain), 4000, seed=0, within_limits=True)
    assert plan.drawn == 4000
    assert plan.kept == int(np.sum(_mj_positions(robot, chain, pool)[:, 2] >= 0.05)) >= 2000
    # still a design: better than random poses that meet the same constraint
    model = model_of(chain, "pose")
    o1 = quality(model, plan.q)[0]
    for seed in range(3):
        random_q = draw_candidates(chain, plan.constraints, 40, seed=seed + 1)[0][:40]
        assert len(random_q) == 40 and o1 > quality(model, random_q)[0]


def test_a_box_holds_every_planned_position() -> None:
    robot = "universal_robots_ur5e"
    chain = _load(robot)
    box = ((-0.6, -0.7, 0.1), (0.2, 0.7, 0.8))
    free = _mj_positions(robot, chain, plan_poses(chain, 20, measure="position"))
    assert not np.all((free >= box[0]) & (free <= box[1]))
    plan = make_plan(chain, 20, measure="position", box=box, above_z=0.3)
    p = _mj_positions(robot, chain, plan.q)
    assert np.all((p >= np.array(box[0]) - 1e-12) & (p <= np.array(box[1]) + 1e-12)), p
    assert np.all(p[:, 2] >= 0.3 - 1e-12)
    assert plan.constraints.region_text() == (
        "z >= 0.3 m and x in [-0.6, 0.2], y in [-0.7, 0.7], z in [0.1, 0.8] m"
    )


def test_joint_ranges_narrow_the_draw() -> None:
    chain = _load("universal_robots_ur5e")
    ranges = {"shoulder_lift_joint": (-np.pi, 0.0), "wrist_2_joint": (0.5, 2.0)}
    plan = make_plan(chain, 30, ranges=ranges, above_z=0.05)
    for name, (lo, hi) in ranges.items():
        k = chain.joint_names.index(name)
        assert np.all((plan.q[:, k] >= lo) & (plan.q[:, k] <= hi)), name
    assert np.ptp(plan.q[:, 0]) > np.pi  # the others still range over their limits
    assert list(plan.constraints.ranged) == [False, True, False, False, True, False]
    assert np.all(_mj_positions("universal_robots_ur5e", chain, plan.q)[:, 2] >= 0.05 - 1e-12)
    # a chain without limits takes a range wider than a turn as it is given
    unlimited = poekin.load_params("lynch-park-ur5")
    assert isinstance(unlimited, poekin.Chain)
    q = plan_poses(unlimited, 12, ranges={"elbow_joint": (-5.0, 5.0)}, candidates=400)
    assert np.max(np.abs(q[:, 2])) <= 5.0
    pool, _ = draw_candidates(
        unlimited, pose_constraints(unlimited, {"elbow_joint": (-5.0, 5.0)}), 400, seed=0
    )
    assert np.max(np.abs(pool[:, 2])) > np.pi  # not clipped to one turn as the limits are


def test_without_constraints_the_plan_is_what_it_was() -> None:
    """The pool is the draw plan_poses always made (sample_joint_values of the sampling chain),
    and a height and a box that every pose meets leave the plan as it is."""
    chain = _load("universal_robots_ur5e")
    none = pose_constraints(chain)
    assert not none.filters and not none.ranged.any()
    pool, drawn = draw_candidates(chain, none, 500, seed=4)
    assert drawn == 500
    expected = sample_joint_values(sampling_chain(chain), 500, seed=4, within_limits=True)
    assert np.array_equal(pool, expected)
    free = make_plan(chain, 12, seed=4, candidates=500)
    assert (free.drawn, free.kept) == (500, 500)
    everywhere = make_plan(
        chain, 12, seed=4, candidates=500, above_z=-10.0, box=((-5, -5, -5), (5, 5, 5))
    )
    assert np.array_equal(free.q, everywhere.q) and everywhere.kept == 500


def test_more_candidates_are_drawn_when_few_meet_the_constraints() -> None:
    robot = "universal_robots_ur5e"
    chain = _load(robot)
    plan = make_plan(chain, 12, above_z=0.8)  # about 1 in 13 candidates reaches 0.8 m
    assert plan.drawn > 2000 and plan.drawn % 2000 == 0 and plan.kept >= 2000
    assert np.all(_mj_positions(robot, chain, plan.q)[:, 2] >= 0.8 - 1e-12)
    assert np.array_equal(plan.q, plan_poses(robot, 12, above_z=0.8))  # deterministic
    with pytest.raises(InputError, match=r"only 0 of 200,000 .* z >= 1.5 m, too few for 12"):
        plan_poses(chain, 12, above_z=1.5)  # beyond the arm's reach
