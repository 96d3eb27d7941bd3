"""Named parameter sets equal what load() derives from the model, and agree with mj_forward."""

from __future__ import annotations

import mujoco
import numpy as np
from helpers import MJ_TOL, assert_close, load_quiet, mj_frame_pose

from poekin import UR5E_HOME, UR5E_SCREWS, fk_ur5e_poe, load, ur5e_chain

# Derived screws carry the model's float rounding (0.9999999999999996 for 1): a few ulps.
DERIVED_TOL = 1e-14


def test_ur5e_constants_equal_derived_parameters() -> None:
    derived = load("universal_robots_ur5e")
    assert_close("UR5E_SCREWS", UR5E_SCREWS, derived.screws, DERIVED_TOL)
    assert_close("UR5E_HOME", UR5E_HOME, derived.home, DERIVED_TOL)
    named = ur5e_chain()
    assert named.joint_names == derived.joint_names
    assert_close("limits", named.limits, derived.limits, 0.0)


def test_fk_ur5e_poe_matches_mj_forward() -> None:
    loaded = load_quiet("universal_robots_ur5e")
    model, data = loaded.model, mujoco.MjData(loaded.model)
    q = np.random.default_rng(0).uniform(-2 * np.pi, 2 * np.pi, size=(500, 6))
    expected = np.empty((500, 4, 4))
    for k in range(500):
        data.qpos[:] = q[k]
        mujoco.mj_forward(model, data)
        expected[k] = mj_frame_pose(model, data, "site", 0)
    assert_close("fk_ur5e_poe", fk_ur5e_poe(q), expected, MJ_TOL)
