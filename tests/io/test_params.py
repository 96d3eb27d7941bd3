"""Named parameter sets: the Menagerie UR5e constants equal what load() derives and agree with
mj_forward; the textbook and vendor sets reproduce their published numbers."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet, mj_frame_pose
from numpy.typing import NDArray
from scipy.linalg import expm

from poekin import UR5E_HOME, UR5E_SCREWS, Chain, PoekinError, fk_ur5e_poe, load, ur5e_chain
from poekin.dh import DHTable
from poekin.errors import UnknownParamsError
from poekin.io.params import (
    LYNCH_PARK_UR5_HOME,
    LYNCH_PARK_UR5_SCREWS,
    PARAM_SETS,
    UR5_DH,
    UR5E_DH,
    UR5E_JOINT_NAMES,
    lynch_park_ur5_chain,
    named_params,
)

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


# --- Modern Robotics (Lynch & Park 2017), Example 4.5 -----------------------------------------
# The book's dimensions (Fig. 4.5), typed here from the book, not from poekin.io.params.
W1, W2, L1, L2, H1, H2 = 0.109, 0.082, 0.425, 0.392, 0.089, 0.095
# Building the book's numbers (e.g. L1 + L2) rounds by an ulp or two of ~1 m: 1e-15 is tight.
BOOK_TOL = 1e-15
# The printed home pose M and body-frame list B_i = Ad(M^-1) S_i.
BOOK_HOME = [[-1, 0, 0, L1 + L2], [0, 0, 1, W1 + W2], [0, 1, 0, H1 - H2], [0, 0, 0, 1]]
BOOK_BODY_SCREWS = [
    [0, 1, 0, W1 + W2, 0, L1 + L2],
    [0, 0, 1, H2, -L1 - L2, 0],
    [0, 0, 1, H2, -L2, 0],
    [0, 0, 1, H2, 0, 0],
    [0, -1, 0, -W2, 0, 0],
    [0, 0, 1, 0, 0, 0],
]


def test_lynch_park_constants_are_the_printed_table() -> None:
    M = BOOK_HOME
    S = [
        [0, 0, 1, 0, 0, 0],
        [0, 1, 0, -H1, 0, 0],
        [0, 1, 0, -H1, 0, L1],
        [0, 1, 0, -H1, 0, L1 + L2],
        [0, 0, -1, -W1, L1 + L2, 0],
        [0, 1, 0, H2 - H1, 0, L1 + L2],
    ]
    assert_close("LYNCH_PARK_UR5_HOME", LYNCH_PARK_UR5_HOME, M, 0.0)
    assert_close("LYNCH_PARK_UR5_SCREWS", LYNCH_PARK_UR5_SCREWS, S, 0.0)


def test_lynch_park_body_screws_match_the_book() -> None:
    # Example 4.5 also prints the body-frame list B_i = Ad(M^-1) S_i.
    chain = lynch_park_ur5_chain()
    assert_close("body_screws", chain.body_screws, BOOK_BODY_SCREWS, BOOK_TOL)
    assert chain.joint_names == UR5E_JOINT_NAMES
    assert (chain.robot, chain.frame) == ("lynch-park-ur5", "ee")


def test_lynch_park_worked_example() -> None:
    # The book's result for theta_2 = -pi/2, theta_5 = pi/2, others 0 (printed to the mm).
    q = [0.0, -np.pi / 2, 0.0, 0.0, np.pi / 2, 0.0]
    T_book = [[0, -1, 0, 0.095], [1, 0, 0, 0.109], [0, 0, 1, 0.988], [0, 0, 0, 1]]
    chain = lynch_park_ur5_chain()
    assert_close("fk", chain.fk(q), T_book, 1e-12)
    assert_close("fk_body", chain.fk_body(q), T_book, 1e-12)


def _twist_matrix(S: NDArray[np.float64]) -> NDArray[np.float64]:
    w, v = S[:3], S[3:]
    return np.array(
        [[0, -w[2], w[1], v[0]], [w[2], 0, -w[0], v[1]], [-w[1], w[0], 0, v[2]], [0, 0, 0, 0]]
    )


def test_lynch_park_fk_equals_a_plain_matrix_exponential_product() -> None:
    chain = lynch_park_ur5_chain()
    for q in np.random.default_rng(7).uniform(-np.pi, np.pi, size=(20, 6)):
        T = np.eye(4)
        for S, qi in zip(chain.screws, q, strict=True):
            T = T @ expm(_twist_matrix(S) * qi)
        assert_close("fk vs expm", chain.fk(q), T @ chain.home, 1e-14)


# --- Universal Robots' DH tables ----------------------------------------------------------------
# Published values (UR support article 45257), typed here from the article.
UR5_PUBLISHED = {"d1": 0.089159, "a2": -0.425, "a3": -0.39225, "d4": 0.10915, "d5": 0.09465}
UR5_PUBLISHED["d6"] = 0.0823
UR5E_PUBLISHED = {"d1": 0.1625, "a2": -0.425, "a3": -0.3922, "d4": 0.1333, "d5": 0.0997}
UR5E_PUBLISHED["d6"] = 0.0996
UR_ALPHA = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]


def _reference_dh_fk(p: dict[str, float], q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard DH by hand: T = prod_i Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)."""
    a = [0, p["a2"], p["a3"], 0, 0, 0]
    d = [p["d1"], 0, 0, p["d4"], p["d5"], p["d6"]]

    def rz(t: float) -> NDArray[np.float64]:
        c, s = np.cos(t), np.sin(t)
        return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])

    def rx(t: float) -> NDArray[np.float64]:
        c, s = np.cos(t), np.sin(t)
        return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])

    def trans(x: float, z: float) -> NDArray[np.float64]:
        T = np.eye(4)
        T[0, 3], T[2, 3] = x, z
        return T

    T = np.eye(4)
    for i in range(6):
        T = T @ rz(q[i]) @ trans(0, d[i]) @ trans(a[i], 0) @ rx(UR_ALPHA[i])
    return T


@pytest.mark.parametrize(
    ("table", "published"),
    [(UR5_DH, UR5_PUBLISHED), (UR5E_DH, UR5E_PUBLISHED)],
    ids=["ur5", "ur5e"],
)
def test_ur_dh_tables_match_a_hand_written_product(
    table: DHTable, published: dict[str, float]
) -> None:
    q = np.random.default_rng(3).uniform(-2 * np.pi, 2 * np.pi, size=(50, 6))
    expected = np.array([_reference_dh_fk(published, qk) for qk in q])
    assert_close(f"{table.robot} fk", table.fk(q), expected, 1e-14)
    assert table.convention == "standard"
    assert table.joint_names == UR5E_JOINT_NAMES
    assert table.frame == "flange"
    assert_close("base", table.base, np.eye(4), 0.0)
    assert_close("tool", table.tool, np.eye(4), 0.0)


def test_ur5e_dh_flange_at_zero() -> None:
    p = UR5E_PUBLISHED
    # At q = 0 the arm lies along the base x axis (a2, a3 < 0: along -x). Frames 1-3 have z along
    # -y0, so d4 then (after alpha4 = pi/2 turns z to -z0) d5 drops the wrist, and alpha5 = -pi/2
    # turns z back to -y0 for d6. The flange: x = a2 + a3, y = -(d4 + d6), z = d1 - d5.
    expected = np.array([p["a2"] + p["a3"], -(p["d4"] + p["d6"]), p["d1"] - p["d5"]])
    assert_close("derived", expected, [-0.8172, -0.2329, 0.0628], 1e-15)
    T = UR5E_DH.fk(np.zeros(6))
    assert_close("flange position", T[:3, 3], expected, 1e-15)
    assert_close("flange z axis (tool points along -y0)", T[:3, 2], [0, -1, 0], 1e-15)
    assert_close("flange x axis (all theta 0: x never turns)", T[:3, 0], [1, 0, 0], 1e-15)


def test_ur5_dh_and_lynch_park_are_the_same_arm() -> None:
    # The book rounds UR's UR5 lengths to the millimetre and turns the base by pi about z; the
    # joint axes are the same lines in the same directions, so orientations agree exactly and
    # positions within the sum of the rounding differences (each length moves the end at most
    # by its own change).
    p = UR5_PUBLISHED
    rounding = (
        abs(p["d1"] - H1)
        + abs(-p["a2"] - L1)
        + abs(-p["a3"] - L2)
        + abs(p["d4"] - W1)
        + abs(p["d5"] - H2)
        + abs(p["d6"] - W2)
    )
    Rz_pi = np.diag([-1.0, -1.0, 1.0, 1.0])
    q = np.random.default_rng(5).uniform(-np.pi, np.pi, size=(50, 6))
    dh, poe = Rz_pi @ UR5_DH.fk(q), lynch_park_ur5_chain().fk(q)
    assert_close("rotation", dh[:, :3, :3], poe[:, :3, :3], 1e-14)
    assert_close("position", dh[:, :3, 3], poe[:, :3, 3], rounding)


# --- registry -----------------------------------------------------------------------------------


def test_named_params_types() -> None:
    expected = {"lynch-park-ur5": Chain, "ur5-dh": DHTable, "ur5e-dh": DHTable, "ur5e-poe": Chain}
    assert set(PARAM_SETS) == set(expected)
    for name, kind in expected.items():
        assert isinstance(named_params(name), kind), name
        assert PARAM_SETS[name] and "\n" not in PARAM_SETS[name]
    assert_close("ur5e-poe", named_params("ur5e-poe").fk(np.zeros(6)), UR5E_HOME, 0.0)


def test_named_params_typo() -> None:
    with pytest.raises(UnknownParamsError, match="did you mean 'lynch-park-ur5'") as info:
        named_params("lynch-park-ur")
    assert isinstance(info.value, LookupError) and isinstance(info.value, PoekinError)
    assert "'ur5e-dh'" in str(info.value)  # lists the valid names
