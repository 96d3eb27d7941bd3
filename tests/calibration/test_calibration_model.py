"""The calibration model (issue #22, items 1-2): a complete, minimal parametrisation.

Checked against things outside the code under test: the theoretical count 4R + 2P + 6 (3 fewer
with positions only), the numerical rank of every correction's Jacobian on rich data, finite
differences of the model's own poses, and the simulated robot against poekin's verified FK.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from helpers import MJ_TOL, assert_close

import poekin
from poekin import lie
from poekin.calibration.model import CalibrationModel, State, expected_identifiable, rotations
from poekin.calibration.simulate import simulate_robot
from poekin.verification.verify import pose_errors

pytestmark = pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")

ARMS = [
    ("universal_robots_ur5e", None, 30),
    ("universal_robots_ur10e", None, 30),
    ("franka_fr3", None, 34),
    ("franka_emika_panda", "hand", 34),
]


def _load(robot: str, frame: str | None) -> poekin.Chain:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load(robot, frame)


@pytest.mark.parametrize(("robot", "frame", "count"), ARMS)
@pytest.mark.parametrize("measure", ["pose", "position"])
def test_the_minimal_set_has_the_theoretical_count(
    robot: str, frame: str | None, count: int, measure: str
) -> None:
    chain = _load(robot, frame)
    model = CalibrationModel.of(chain, measure)  # type: ignore[arg-type]
    expected = count - (3 if measure == "position" else 0)
    assert expected_identifiable(chain, measure) == expected  # type: ignore[arg-type]
    assert len(model.free) == expected
    assert len(model.free) + len(model.redundant) == model.n_params


@pytest.mark.parametrize(("robot", "frame", "count"), ARMS[:3])
def test_rich_data_rank_of_all_corrections_is_the_count(
    robot: str, frame: str | None, count: int
) -> None:
    """The full, redundant set of 5R + 12 corrections spans exactly 4R + 2P + 6 directions on
    rich data (SVD, not the greedy selection), and the free set spans the same."""
    chain = _load(robot, frame)
    model = CalibrationModel.of(chain, "pose")
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (60, chain.n_joints))
    base = lie.exp_se3(np.array([0.3, -1.2, 2.0, 1.5, -0.4, 0.7]))
    x = np.random.default_rng(2).normal(scale=1e-3, size=model.n_params)
    state = State(base, x)
    J = model.rows(state, q)
    s = np.linalg.svd(J / np.linalg.norm(J, axis=0), compute_uv=False)
    assert int(np.sum(s > 1e-8 * s[0])) == count
    free = model.rows(state, q)[:, list(model.free)]
    s = np.linalg.svd(free / np.linalg.norm(free, axis=0), compute_uv=False)
    assert s[-1] > 1e-4 * s[0]  # full column rank, well conditioned


def test_redundant_corrections_are_named_by_what_moves_the_tool_alike() -> None:
    chain = _load("universal_robots_ur5e", None)
    model = CalibrationModel.of(chain, "pose")
    by_key = {
        model.params[r.param].key: [model.params[k].key for k in r.alike] for r in model.redundant
    }
    assert by_key["shoulder_pan_joint.offset"] == ["base.rz"]  # yaw of the base
    assert by_key["tool.rz"] == ["wrist_3_joint.offset"]  # the flange turns about joint 6
    # joint 1's whole line is the base's: none of its corrections is fitted
    assert {k for k in by_key if k.startswith("shoulder_pan_joint.")} >= {
        "shoulder_pan_joint.shift_a",
        "shoulder_pan_joint.shift_b",
        "shoulder_pan_joint.tilt_a",
        "shoulder_pan_joint.tilt_b",
    }
    positions = CalibrationModel.of(chain, "position")
    assert not positions.tool_turn_index  # a point has no orientation
    assert "wrist_3_joint.offset" not in [positions.params[k].key for k in positions.free]


@pytest.mark.parametrize("measure", ["pose", "position"])
def test_jacobian_matches_finite_differences(measure: str) -> None:
    chain = _load("franka_fr3", None)
    model = CalibrationModel.of(chain, measure)  # type: ignore[arg-type]
    rng = np.random.default_rng(3)
    x = rng.normal(scale=0.05, size=model.n_params)
    x[:6] = 0.0
    base = lie.exp_se3(rng.normal(size=6))
    state = State(base, x)
    q = rng.uniform(-3, 3, (4, chain.n_joints))
    T, D = model.jacobian(state, q)
    assert_close("poses", T, model.poses(state, q), 1e-15)
    h = 1e-6
    for k in range(model.n_params):
        plus, minus = x.copy(), x.copy()
        if k < 6:  # the base: a turn about its own axes, then a shift along them
            d = np.zeros(6)
            d[k] = h
            G = [np.eye(4), np.eye(4)]
            for G_, sign in zip(G, (1, -1), strict=True):
                G_[:3, :3], G_[:3, 3] = lie.exp_so3(sign * d[:3]), sign * d[3:]
            s_plus, s_minus = State(base @ G[0], x), State(base @ G[1], x)
        else:
            plus[k] += h
            minus[k] -= h
            s_plus, s_minus = State(base, plus), State(base, minus)
        T1, T0 = model.poses(s_plus, q), model.poses(s_minus, q)
        dw = lie.log_so3(T1[:, :3, :3] @ np.swapaxes(T0[:, :3, :3], 1, 2)) / (2 * h)
        dp = (T1[:, :3, 3] - T0[:, :3, 3]) / (2 * h)
        assert_close(model.params[k].key, D[:, :, k], np.concatenate([dw, dp], axis=1), 2e-8)


def test_calibrated_chain_absorbs_the_offsets() -> None:
    """The chain's FK for encoder readings equals the model's poses (offsets in the screws)."""
    chain = _load("universal_robots_ur5e", None)
    model = CalibrationModel.of(chain, "pose")
    rng = np.random.default_rng(4)
    x = rng.normal(scale=0.02, size=model.n_params)
    x[:6] = 0.0
    state = State(lie.exp_se3(rng.normal(size=6)), x)
    q = rng.uniform(-2 * np.pi, 2 * np.pi, (50, 6))
    calibrated = model.calibrated_chain(state)
    assert_close("fk", calibrated.fk(q), model.poses(state, q), 1e-14)
    robot = model.robot_chain(x)  # its own base frame, offsets not applied
    offsets = model.geometry(x).offsets
    assert_close("robot", state.base @ robot.fk(q + offsets), model.poses(state, q), 1e-14)


@pytest.mark.parametrize(
    ("robot", "frame"),
    [
        ("universal_robots_ur5e", None),
        ("franka_fr3", None),
        ("franka_emika_panda", "hand"),  # a body as the end frame
        ("trs_so_arm100", "Fixed_Jaw"),  # bodies turned with euler="..."
    ],
)
def test_simulated_robot_without_perturbation_is_the_model(robot: str, frame: str | None) -> None:
    """The simulation edits the model with MjSpec and poses it with mj_forward: unperturbed it
    gives poekin's FK, which tests/verification/test_verify.py checks against MuJoCo, to
    rounding."""
    chain = _load(robot, frame)
    sizes = dict.fromkeys(
        ("link_m", "link_rad", "axis_rad", "anchor_m", "tool_m", "tool_rad", "offset_rad"), 0.0
    )
    sim = simulate_robot(robot, frame, distance=0.0, **sizes)
    q = poekin.sample_joint_values(chain, 30, seed=2)
    pos, ori = pose_errors(sim.poses(q), chain.fk(q))
    assert pos.max() < MJ_TOL and ori.max() < MJ_TOL
    placed = simulate_robot(robot, frame, **sizes)
    assert abs(np.linalg.norm(placed.base[:3, 3]) - 2.0) < 1e-12
    pos, ori = pose_errors(placed.poses(q), placed.base @ chain.fk(q))
    assert pos.max() < 10 * MJ_TOL and ori.max() < MJ_TOL


def test_simulated_robot_differs_by_about_what_was_asked() -> None:
    chain = _load("universal_robots_ur5e", None)
    sim = simulate_robot(seed=3)
    assert 0.002 < float(np.sqrt(np.mean(sim.offsets**2))) < 0.03  # ~10 mrad
    q = poekin.sample_joint_values(chain, 200, seed=5)
    pos, ori = pose_errors(sim.poses(q), sim.base @ chain.fk(q))
    assert 0.003 < np.median(pos) < 0.03 and 0.005 < np.median(ori) < 0.05  # mm and mrad
    # the encoders' offsets: the joints stand at q + offsets
    unoffset = simulate_robot(seed=3, offset_rad=0.0)
    assert_close("offsets", unoffset.poses(q + sim.offsets), sim.poses(q), 1e-13)
    target = np.eye(4)
    target[:3, 3] = [0.0, 0.0, 0.1]  # a target 10 cm along the flange's z
    on_flange = simulate_robot(seed=3, target=target, tool_m=0.0, tool_rad=0.0)
    shifted = (on_flange.poses(q) @ np.linalg.inv(target))[:, :3, 3]
    assert_close("target", shifted, sim.poses(q)[:, :3, 3], 5e-3)  # ~1 mm tool change apart
    with pytest.raises(poekin.InputError, match=r"target must be a \(4, 4\) pose"):
        simulate_robot(target=np.eye(3))
    with pytest.raises(poekin.InputError, match="needs a site"):
        simulate_robot("franka_emika_panda", "hand", target=np.eye(4))
    noisy = sim.measure(q[:50], noise_m=1e-4, noise_rad=1e-4, seed=1)
    pos, ori = pose_errors(noisy, sim.poses(q[:50]))
    assert 0.5e-4 < np.sqrt(np.mean(pos**2)) / np.sqrt(3) < 2e-4
    assert sim.measure(q[:5], positions=True).shape == (5, 3)


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_rotations_are_lie_exp_so3(shape: tuple[int, ...]) -> None:
    """The fit's batched Rodrigues (matrix products) is poekin.lie.exp_so3, from zero and
    tiny angles (the series branch) to more than pi."""
    rng = np.random.default_rng(5)
    v = rng.normal(size=(*shape, 3)) * 10.0 ** rng.uniform(-12, 0.6, size=(*shape, 1))
    assert_close("exp", rotations(v), lie.exp_so3(v), 5e-16)
    identity = np.broadcast_to(np.eye(3), (*shape, 3, 3))
    assert_close("zero", rotations(np.zeros((*shape, 3))), identity, 0.0)
