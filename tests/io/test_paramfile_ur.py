"""UR's calibration file (the ``kinematics:`` YAML that ur_calibration writes) read as the robot.

Checked against ur_description's chain written out here as homogeneous matrices, against
Universal Robots' published DH tables (numbers written here), and against the Menagerie UR5e
(through MuJoCo). Bad files give one InputError line; the CLI reads the file wherever it reads a
parameter file.
"""

from __future__ import annotations

import math
import pathlib
from typing import Any

import doc_blocks as db
import mujoco
import numpy as np
import pytest
import yaml
from helpers import assert_close
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin import DHTable, InputError, dh_from_chain
from poekin.cli import main
from poekin.io.paramfile import load_params, params_from_dict
from poekin.io.params import UR5E_JOINT_NAMES
from poekin.io.sources import kinematics_spec
from poekin.io.ur_kinematics import UR_ORIGIN_KEYS, ur_chain

REPO = pathlib.Path(__file__).resolve().parents[2]
CALIBRATION = REPO / "tests" / "data" / "ur" / "ur5e_calibration.yaml"  # synthetic (see its header)
HASH = "calib_7351942216840930177"
SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
Q = np.random.default_rng(22).uniform(-2 * np.pi, 2 * np.pi, size=(2000, 6))
# The chain against the matrix product below: both round, ~1e-15 at |q| <= 2 pi (measured
# 1.1e-15 on these 2000 q). A wrong rpy order, a missing flange or tool0 turn, or a joint turning
# about another axis is off by 2e-7 and more (the file's smallest angle is 2.9e-7 rad).
PRODUCT_TOL = 3e-15
# UR's files write pi/2 as 1.570796327, 2.05e-10 rad off; three such angles in a chain.
PRINTED_TOL = 1e-9


# --- ur_description's chain, written out ----------------------------------------------------------
#
# urdf/ur_macro.xacro (Universal_Robots_ROS2_Description 2.4.5): every segment is a joint
# <origin xyz rpy> (URDF rpy: R = Rz(yaw) Ry(pitch) Rx(roll)), every joint turns about its local z;
# shoulder_pan_joint's parent is base_link_inertia, turned by rpy (0, 0, pi) from base_link, and
# the controller's 'base' is base_link turned by rpy (0, 0, pi); after wrist_3_link come the fixed
# joints wrist_3-flange, rpy (0, -pi/2, -pi/2), and flange-tool0, rpy (pi/2, 0, pi/2).


def _rx(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _h(R: np.ndarray, p: Any = (0.0, 0.0, 0.0)) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def _urdf_origin(xyz: Any, rpy: Any, order: str = "urdf") -> np.ndarray:
    roll, pitch, yaw = rpy
    R = _rz(yaw) @ _ry(pitch) @ _rx(roll) if order == "urdf" else _rx(roll) @ _ry(pitch) @ _rz(yaw)
    return _h(R, xyz)


def reference_fk(kin: dict[str, Any], q: np.ndarray, *, order: str = "urdf") -> np.ndarray:
    """``T_base_tool0(q)`` as ur_description's URDF composes it."""
    T_base_link_base = _urdf_origin((0, 0, 0), (0, 0, np.pi))
    T_base_link_inertia = _urdf_origin((0, 0, 0), (0, 0, np.pi))
    T = np.linalg.inv(T_base_link_base) @ T_base_link_inertia  # base -> base_link_inertia
    for name, qi in zip(SEGMENTS, q, strict=True):
        s = kin[name]
        origin = _urdf_origin((s["x"], s["y"], s["z"]), (s["roll"], s["pitch"], s["yaw"]), order)
        T = T @ origin @ _h(_rz(qi))
    flange = _urdf_origin((0, 0, 0), (0, -np.pi / 2, -np.pi / 2))
    tool0 = _urdf_origin((0, 0, 0), (np.pi / 2, 0, np.pi / 2))
    return T @ flange @ tool0


def reference_axes(kin: dict[str, Any]) -> np.ndarray:
    """``(6, 3)`` joint axes in ``base`` at q = 0: each joint frame's z."""
    T, axes = np.eye(4), []
    for name in SEGMENTS:
        s = kin[name]
        T = T @ _urdf_origin((s["x"], s["y"], s["z"]), (s["roll"], s["pitch"], s["yaw"]))
        axes.append(T[:3, 2])
    return np.array(axes)


def _calibration() -> dict[str, Any]:
    kin: dict[str, Any] = yaml.safe_load(CALIBRATION.read_text())["kinematics"]
    return kin


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), u @ v))


def _rotation_angle(A: np.ndarray, B: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(A.T @ B) - 1.0) / 2.0, -1.0, 1.0)))


# --- the calibration file is ur_description's chain -----------------------------------------------


def test_calibration_file_is_ur_descriptions_chain() -> None:
    chain = load_params(CALIBRATION)
    assert isinstance(chain, poekin.Chain)
    kin = _calibration()
    T_ref = np.array([reference_fk(kin, q) for q in Q])
    assert_close("fk", chain.fk(Q), T_ref, PRODUCT_TOL)
    assert_close("fk_body", chain.fk_body(Q), T_ref, PRODUCT_TOL)
    assert chain.joint_names == UR5E_JOINT_NAMES and chain.frame == "tool0"
    assert chain.robot == f"ur5e, UR calibration {HASH}"
    assert np.all(np.isinf(chain.limits))  # the file holds no limits


_lengths = st.floats(-1.0, 1.0)
_angles = st.floats(-np.pi, np.pi)
_segment = st.tuples(_lengths, _lengths, _lengths, _angles, _angles, _angles)


@settings(max_examples=40, deadline=None)
@given(
    origins=st.lists(_segment, min_size=6, max_size=6),
    q=st.lists(st.floats(-2 * np.pi, 2 * np.pi), min_size=6, max_size=6),
)
def test_any_segments_give_ur_descriptions_chain(origins: list[Any], q: list[float]) -> None:
    """Not only UR-like files: any six origins (lengths up to 1 m, any angles) and any q."""
    kin = {
        name: dict(zip(UR_ORIGIN_KEYS, o, strict=True))
        for name, o in zip(SEGMENTS, origins, strict=True)
    }
    T_ref = reference_fk(kin, np.array(q))
    assert_close("fk", ur_chain(origins).fk(q), T_ref, 2e-14)  # |p| up to 6 m: rounding * 10


@pytest.mark.parametrize("wrong", ["eigen_xyz_order", "flange_for_tool0", "base_link_for_base"])
def test_the_reference_tells_a_wrong_chain_apart(wrong: str) -> None:
    """The comparison above can fail: each plausible mistake is far above PRODUCT_TOL. (Not one:
    wrist_3_link for tool0, since the flange and tool0 turns cancel.)"""
    kin, chain, q = _calibration(), load_params(CALIBRATION), Q[:200]
    T = np.array([reference_fk(kin, x, order="eigen" if wrong == "eigen_xyz_order" else "urdf")
                  for x in q])  # fmt: skip
    if wrong == "flange_for_tool0":
        T = T @ np.linalg.inv(_urdf_origin((0, 0, 0), (np.pi / 2, 0, np.pi / 2)))
    elif wrong == "base_link_for_base":  # ROS's REP-103 base_link, turned by pi about z
        T = _urdf_origin((0, 0, 0), (0, 0, np.pi)) @ T
    assert np.max(np.abs(chain.fk(q) - T)) > 2e-7


# --- UR's default kinematics are UR's published DH tables ----------------------------------------
#
# Universal Robots' published standard DH lengths (d1, a2, a3, d4, d5, d6), article 45257 "DH
# parameters for calculations of kinematics and dynamics" (alpha = pi/2, 0, 0, pi/2, -pi/2, 0).
PUBLISHED_DH = {
    "ur3": (0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819),
    "ur5": (0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823),
    "ur10": (0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922),
    "ur3e": (0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
    "ur5e": (0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
    "ur10e": (0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
    "ur16e": (0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655),
    "ur20": (0.2363, -0.862, -0.7287, 0.201, 0.1593, 0.1543),
    "ur30": (0.2363, -0.637, -0.5037, 0.201, 0.1593, 0.1543),
}
CONTROLLER_HALF_PI = 1.570796327  # pi/2 as UR's controller and its files print it


def default_kinematics(model: str) -> dict[str, Any]:
    """``config/<model>/default_kinematics.yaml`` of ur_description: the published lengths in
    ur_calibration's layout, with the controller's pi/2 (the files' tiny wrist z values follow)."""
    d1, a2, a3, d4, d5, d6 = PUBLISHED_DH[model]
    half_pi, cos = CONTROLLER_HALF_PI, math.cos(CONTROLLER_HALF_PI)  # cos: -2.05e-10
    zero = {"x": 0.0, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0}
    return {
        "shoulder": {**zero, "z": d1},
        "upper_arm": {**zero, "roll": half_pi},
        "forearm": {**zero, "x": a2},
        "wrist_1": {**zero, "x": a3, "z": d4},
        "wrist_2": {**zero, "y": -d5, "z": d5 * cos, "roll": half_pi},
        "wrist_3": {**zero, "y": d6, "z": d6 * cos, "roll": math.pi - half_pi, "pitch": math.pi,
                    "yaw": math.pi},
        "hash": f"calib_{model}_default",
    }  # fmt: skip


def test_the_default_layout_is_the_files() -> None:
    """The tiny values config/ur5e/default_kinematics.yaml prints (16 digits, as yaml-cpp)."""
    kin = default_kinematics("ur5e")
    printed = [
        f"{kin[s][k]:.16g}" for s, k in (("wrist_2", "z"), ("wrist_3", "z"), ("wrist_3", "roll"))
    ]
    assert printed == ["-2.044881182297852e-11", "-2.042830148012698e-11", "1.570796326589793"]


def _dh(model: str, half_pi: float) -> DHTable:
    d1, a2, a3, d4, d5, d6 = PUBLISHED_DH[model]
    return DHTable(
        "standard",
        [0.0, a2, a3, 0.0, 0.0, 0.0],
        [half_pi, 0.0, 0.0, half_pi, -half_pi, 0.0],
        [d1, 0.0, 0.0, d4, d5, d6],
        [0.0] * 6,
        ("revolute",) * 6,
    )


@pytest.mark.parametrize("model", list(PUBLISHED_DH))
def test_default_kinematics_are_the_published_dh(model: str, tmp_path: pathlib.Path) -> None:
    path = tmp_path / f"{model}.yaml"
    path.write_text(yaml.safe_dump({"kinematics": default_kinematics(model)}))
    chain = load_params(path)
    assert isinstance(chain, poekin.Chain)
    q = Q[:500]
    # UR's table with pi/2, against the file's 1.570796327: the file's printed precision
    assert_close("fk vs published DH", chain.fk(q), _dh(model, np.pi / 2).fk(q), PRINTED_TOL)
    # with the controller's own 1.570796327: the same arm, to rounding
    assert_close("fk vs controller DH", chain.fk(q), _dh(model, CONTROLLER_HALF_PI).fk(q), 3e-15)
    assert chain.robot == f"{model}, UR calibration calib_{model}_default"


def test_an_arm_of_no_published_model_has_no_model_name() -> None:
    kin = default_kinematics("ur5e")
    kin["forearm"]["x"] = -0.5  # 75 mm from every model's a2
    chain = params_from_dict({"kinematics": kin}, "mine.yaml")
    assert chain.robot == "UR arm, UR calibration calib_ur5e_default"
    del kin["hash"]
    assert params_from_dict({"kinematics": kin}, "mine.yaml").robot == "UR arm"


# --- against the Menagerie UR5e -----------------------------------------------------------------
#
# The Menagerie UR5e (ur5e.xml) rounds UR's lengths to the millimetre: d1 0.163 (UR 0.1625),
# a3 0.392 (0.3922), d4 = 0.138 - 0.131 + 0.127 = 0.134 (0.1333), d5 0.1 (0.0997), d6 0.1 (0.0996).
MENAGERIE_ROUNDING_M = {"d1": 0.0005, "a3": 0.0002, "d4": 0.0007, "d5": 0.0003, "d6": 0.0004}


def _default_ur5e(tmp_path: pathlib.Path) -> pathlib.Path:
    path = tmp_path / "ur5e_default.yaml"
    path.write_text(yaml.safe_dump({"kinematics": default_kinematics("ur5e")}))
    return path


def test_default_ur5e_has_the_menagerie_frames(ur5e: poekin.Chain, tmp_path: pathlib.Path) -> None:
    """UR's base is the Menagerie's world, tool0 is turned like attachment_site: orientations
    agree to the file's printed precision everywhere; positions differ by the rounding only."""
    chain = load_params(_default_ur5e(tmp_path))
    pos, ori = poekin.pose_errors(ur5e.fk(Q), chain.fk(Q))
    assert np.max(ori) < PRINTED_TOL
    assert 1e-3 < np.max(pos) < 2e-3
    d = poekin.diagnose(chain, ur5e)
    assert {f.kind for f in d.findings} <= {"axis_offset", "link_length", "home_position"}
    lengths = {f.message.split(":")[0]: f.value for f in d.findings if f.kind == "link_length"}
    assert lengths.keys() == MENAGERIE_ROUNDING_M.keys()
    for name, value in MENAGERIE_ROUNDING_M.items():
        assert_close(name, lengths[name], value, 1e-12)


def _menagerie_with_urs_lengths() -> poekin.Chain:
    """The Menagerie UR5e with UR's published lengths typed into its bodies, through MuJoCo."""
    spec = kinematics_spec("universal_robots_ur5e")  # meshes or not
    spec.body("shoulder_link").pos = [0.0, 0.0, 0.1625]
    spec.body("wrist_1_link").pos = [0.0, 0.0, 0.3922]
    spec.body("wrist_2_link").pos = [0.0, 0.1333 - 0.138 + 0.131, 0.0]
    spec.body("wrist_3_link").pos = [0.0, 0.0, 0.0997]
    spec.site("attachment_site").pos = [0.0, 0.0996, 0.0]
    return poekin.chain_from_model(spec.compile(), "attachment_site")


def test_default_ur5e_matches_the_menagerie_with_urs_lengths(tmp_path: pathlib.Path) -> None:
    d = poekin.diagnose(
        _default_ur5e(tmp_path), _menagerie_with_urs_lengths(), pos_tol=PRINTED_TOL,
        ori_tol=PRINTED_TOL,
    )  # fmt: skip
    assert d.matches, d.report()
    assert d.max_ori_err_rad > 1e-11  # the 1.570796327 is there, and is all that is left


def _menagerie_at_zero() -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's joint axes (6, 3) and attachment_site pose (4, 4) of the UR5e at q = 0."""
    model = poekin.load_model("universal_robots_ur5e").model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "attachment_site")
    pose = _h(data.site_xmat[site].reshape(3, 3), data.site_xpos[site])
    return np.array(data.xaxis[:6]), pose


def test_calibration_against_the_menagerie_names_its_differences(ur5e: poekin.Chain) -> None:
    d = poekin.diagnose(str(CALIBRATION), ur5e)
    assert not d.matches and 1e-3 < d.max_pos_err_m < 5e-3 and d.max_ori_err_rad < 1e-2
    assert not d.base_aligned  # the same base: nothing to align
    axes_mj, site = _menagerie_at_zero()
    axes_ref = reference_axes(_calibration())
    tilts = {f.joint: f for f in d.findings if f.kind == "axis_tilted"}
    assert sorted(tilts) == [1, 2, 3, 4, 5]  # joint 1 keeps base's z
    for j, finding in tilts.items():
        expected = _angle(axes_ref[j], axes_mj[j])
        assert_close(f"tilt {j + 1}", finding.value, expected, 1e-12)
        assert f"axis tilted by {expected * 1000:.3g} mrad" in finding.message
    offsets = [f for f in d.findings if f.kind == "axis_offset"]
    assert offsets and all(f.value < 2e-3 and " mm (" in f.message for f in offsets)
    home = {f.kind: f for f in d.findings if f.kind.startswith("home")}
    T0 = reference_fk(_calibration(), np.zeros(6))
    assert_close("home off", home["home_position"].value, np.linalg.norm(T0[:3, 3] - site[:3, 3]),
                 1e-12)  # fmt: skip
    assert_close("home turn", home["home_rotation"].value,
                 _rotation_angle(site[:3, :3], T0[:3, :3]), 1e-9)  # fmt: skip
    # the arm's nearly parallel axes are named, and their far-away DH normals not compared
    near = [f.joint for f in d.findings if f.kind == "near_parallel"]
    assert near == [1, 2]
    lengths = [f for f in d.findings if f.kind == "link_length"]
    assert all(f.value < 2e-3 for f in lengths), [f.message for f in lengths]
    assert {f.message.split(":")[0] for f in lengths}.isdisjoint({"a2", "d2", "a3", "d3", "d4"})


def test_calibration_against_urs_nominal_ur5e() -> None:
    """Against UR's own nominal UR5e (a parameter set as the model): only the calibration."""
    d = poekin.diagnose(str(CALIBRATION), "ur5e-dh")
    T0 = reference_fk(_calibration(), np.zeros(6))
    N0 = _dh("ur5e", np.pi / 2).fk(np.zeros(6))
    home = {f.kind: f.value for f in d.findings if f.kind.startswith("home")}
    assert_close("home off", home["home_position"], np.linalg.norm(T0[:3, 3] - N0[:3, 3]), 1e-12)
    assert_close("home turn", home["home_rotation"], _rotation_angle(N0[:3, :3], T0[:3, :3]), 1e-9)
    lengths = {f.message.split(":")[0]: f.value for f in d.findings if f.kind == "link_length"}
    assert_close("d1", lengths["d1"], 0.1625 - 0.16238, 1e-12)  # the shoulder's z
    with pytest.raises(InputError, match="leave frame out"):
        poekin.diagnose(str(CALIBRATION), "ur5e-dh", frame="flange")


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_calibration_typed_as_a_dh_table(convention: str) -> None:
    """The file's chain as a DH table (d2 of hundreds of metres) diagnoses like the chain."""
    table = dh_from_chain(load_params(CALIBRATION), convention)  # type: ignore[arg-type]
    assert np.max(np.abs(table.d)) > 100.0  # the far-away normals the issue warns of
    d = poekin.diagnose(table, "ur5e-dh")
    assert [f.joint for f in d.findings if f.kind == "near_parallel"] == [1, 2]
    assert all(f.value < 1e-3 for f in d.findings if f.kind == "link_length")
    assert d.bisect[-1].max_pos_err_m < 1e-12


# --- the orientation order: ur_calibration's Rx Ry Rz against ur_description's Rz Ry Rx -----------


def test_controller_order_reads_the_angles_as_ur_calibration_wrote_them() -> None:
    """The two readings of this file differ measurably (0.5 um, 2.6 urad); each matches its own
    hand-written product (reference_fk above, which does not use poekin)."""
    q = Q[:500]
    description = load_params(CALIBRATION)
    controller = load_params(CALIBRATION, ur_yaml_order="controller")
    assert isinstance(controller, poekin.Chain)
    kin = _calibration()
    T_eigen = np.array([reference_fk(kin, x, order="eigen") for x in q])
    assert_close("controller", controller.fk(q), T_eigen, PRODUCT_TOL)
    T_urdf = np.array([reference_fk(kin, x) for x in q])
    assert_close("description", description.fk(q), T_urdf, PRODUCT_TOL)
    pos, ori = poekin.pose_errors(description.fk(q), controller.fk(q))
    assert 1e-7 < np.max(pos) < 1e-5 and 1e-6 < np.max(ori) < 1e-5  # micrometres apart


def test_controller_order_on_the_command_line(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    q = [0.3, -1.2, 1.1, -0.4, 1.3, 0.2]
    argv = ["fk", "--params", str(CALIBRATION), "--q", *map(str, q), "--json"]
    code, out, _ = _run(capsys, *argv, "--ur-yaml-order", "controller")
    assert code == 0
    T = json.loads(out)["T"]
    assert_close("T", T, reference_fk(_calibration(), np.array(q), order="eigen"), PRODUCT_TOL)
    code, out, _ = _run(capsys, "diagnose", "--params", str(CALIBRATION), "--against",
                        str(CALIBRATION), "--ur-yaml-order", "controller")  # fmt: skip
    assert code == 0 and "MATCH" in out  # both sides read alike


@pytest.mark.parametrize(
    "argv",
    [
        ["verify", "--params", "{cal}", "--json"],
        ["dh", "--params", "{cal}", "--json"],
        ["jacobian", "--params", "{cal}", "--q", "0", "-1", "1", "0", "1", "0", "--json"],
    ],
)
def test_every_command_takes_the_order(
    argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    """Each command that reads --params reads the file in the order asked: the numbers differ."""
    import json

    args = [a.format(cal=CALIBRATION) for a in argv]
    outputs = []
    for order in ("description", "controller"):
        code, out, err = _run(capsys, *args, "--ur-yaml-order", order)
        assert code in (0, 1) and "error" not in err, err
        result = json.loads(out)
        result.pop("params", None)  # verify names the file, or the chain read from it
        outputs.append(result)
    assert outputs[0] != outputs[1]


def test_an_unknown_order_is_refused() -> None:
    with pytest.raises(InputError, match="did you mean 'controller'"):
        load_params(CALIBRATION, ur_yaml_order="controler")  # type: ignore[arg-type]


# --- lengths no UR arm has ----------------------------------------------------------------------


def test_a_file_in_millimetres_is_refused(tmp_path: pathlib.Path) -> None:
    """ur_calibration's file with its x y z in millimetres put the flange 425 m away."""
    kin = _calibration()
    for name in SEGMENTS:
        for key in ("x", "y", "z"):
            kin[name][key] *= 1000.0
    path = tmp_path / "mm.yaml"
    path.write_text(yaml.safe_dump({"kinematics": kin}))
    with pytest.raises(InputError) as e:
        load_params(path)
    text = str(e.value)
    assert text.startswith(f"{path}: kinematics.forearm.x is -424.53")
    assert "look like millimetres (divided by 1000 they are a ur5e's)" in text


# --- bad files ----------------------------------------------------------------------------------


def _edit(change: str) -> dict[str, Any]:
    doc: dict[str, Any] = {"kinematics": _calibration() | {"hash": HASH}}
    kin = doc["kinematics"]
    if change == "missing_segment":
        del kin["wrist_2"]
    elif change == "misspelled_segment":
        kin["wrist1"] = kin.pop("wrist_1")
    elif change == "extra_segment":
        kin["wrist_4"] = dict(kin["wrist_3"])
    elif change == "missing_key":
        del kin["forearm"]["pitch"]
    elif change == "unknown_key":
        kin["shoulder"]["rol"] = kin["shoulder"].pop("roll")
    elif change == "text":
        kin["forearm"]["x"] = "abc"
    elif change == "quoted":
        kin["forearm"]["x"] = "-0.42453"
    elif change == "nan":
        kin["wrist_1"]["yaw"] = float("nan")
    elif change == "list_segment":
        kin["shoulder"] = [0, 0, 0.1625, 0, 0, 0]
    elif change == "not_a_mapping":
        doc["kinematics"] = [1, 2, 3]
    elif change == "hash_number":
        kin["hash"] = 12
    elif change == "with_rows":
        doc["rows"] = []
    return doc


BAD = [
    ("missing_segment", "'kinematics' has no 'wrist_2' segment"),
    ("misspelled_segment", "unknown segment 'wrist1': did you mean 'wrist_1'?"),
    ("extra_segment", "unknown segment 'wrist_4'"),
    ("missing_key", "kinematics.forearm has no 'pitch'"),
    ("unknown_key", "kinematics.shoulder has an unknown key 'rol': did you mean 'roll'?"),
    ("text", "kinematics.forearm.x must be a number, got a string ('abc')"),
    ("quoted", "drop the quotes"),
    ("nan", "kinematics.wrist_1.yaw is NaN"),
    ("list_segment", "kinematics.shoulder must be an object with x y z roll pitch yaw"),
    ("not_a_mapping", "'kinematics' must be an object with the segments shoulder"),
    ("hash_number", "kinematics.hash must be a string"),
    ("with_rows", "has both 'kinematics' (a UR calibration) and rows"),
]


@pytest.mark.parametrize(("change", "message"), BAD, ids=[c for c, _ in BAD])
def test_bad_file_gives_one_line(change: str, message: str, tmp_path: pathlib.Path) -> None:
    path = tmp_path / "cal.yaml"
    path.write_text(yaml.safe_dump(_edit(change)))
    with pytest.raises(InputError) as e:
        load_params(path)
    text = str(e.value)
    assert "\n" not in text and text.startswith(f"{path}: ") and message in text, text


# --- the command line ---------------------------------------------------------------------------


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_fk_reads_the_calibration(capsys: pytest.CaptureFixture[str]) -> None:
    import json

    q = [0.3, -1.2, 1.1, -0.4, 1.3, 0.2]
    code, out, _ = _run(capsys, "fk", "--params", str(CALIBRATION), "--q", *map(str, q), "--json")
    assert code == 0
    result = json.loads(out)
    assert result["frame"] == "tool0"
    assert_close("T", result["T"], reference_fk(_calibration(), np.array(q)), PRODUCT_TOL)


def test_diagnose_names_the_calibration_and_its_differences(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, _ = _run(capsys, "diagnose", "--params", str(CALIBRATION))
    lines = out.splitlines()
    assert code == 1
    assert lines[0].startswith(f"{CALIBRATION} (ur5e, UR calibration {HASH}) vs universal_robots")
    assert lines[1].startswith("MISMATCH: max error 0.00")
    assert "joint 3 (elbow_joint): axis tilted by " in out and " mrad (" in out
    assert "are not compared" in out and " m in yours vs " in out


def test_diagnose_default_against_urs_nominal_matches(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    default = str(_default_ur5e(tmp_path))
    code, out, _ = _run(capsys, "diagnose", "--params", default, "--against", "ur5e-dh")
    assert code == 0 and out.splitlines()[1].startswith("MATCH: max error "), out


@pytest.mark.parametrize(
    "argv",
    [
        ["jacobian", "--params", "{cal}", "--q", "0", "-1", "1", "0", "1", "0"],
        ["dh", "--params", "{cal}"],
        ["verify", "--params", "{cal}"],
        ["draw", "--params", "{cal}", "--out", "{tmp}/ghost.png"],
    ],
)
def test_every_command_reads_it(
    argv: list[str], capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    code, out, err = _run(capsys, *[a.format(cal=CALIBRATION, tmp=tmp_path) for a in argv])
    assert code in (0, 1) and "error" not in err, err  # 1: verify finds it is not the model
    if argv[0] == "dh":
        assert "nearly parallel" in err + out


# The lead merges these rows into tests/cli/test_cli.py's BAD_INPUTS.
# --- the user page ------------------------------------------------------------------------------

PAGE = REPO / "docs" / "ur_calibration.md"


def test_the_user_page_shows_this_synthetic_file() -> None:
    """docs/ur_calibration.md (run by tests/test_docs.py) writes the calibration it shows to
    my_robot_calibration.yaml: it must be this test file, key for key."""
    shown = [b for b in db.blocks(PAGE.read_text()) if b.file == "my_robot_calibration.yaml"]
    assert len(shown) == 1
    assert yaml.safe_load(shown[0].text) == yaml.safe_load(CALIBRATION.read_text())
