"""Pose planning (issue #22, item 3): greedy D-optimal poses within the limits that identify the
parameters; judged by the observability of the design and by calibrating a MuJoCo-perturbed
robot on them."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import poekin
from poekin.calibration import calibrate, model_of, plan_poses
from poekin.calibration.plan import quality, sampling_chain
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

    monkeypatch.setattr("sys.stderr", Terminal())
    with _calibrate._bar(500, "plan", "pose") as step:
        assert step is not None
        step(250)
    with _calibrate._bar(50, "plan", "pose") as step:
        assert step is None  # a short plan takes well under 2 s: no bar
