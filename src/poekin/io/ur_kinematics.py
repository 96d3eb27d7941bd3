"""Universal Robots' kinematics files, read as the robot: :func:`ur_chain`.

UR's controller stores each arm's factory calibration. ``ur_calibration`` (ROS, in
``Universal_Robots_ROS2_Driver``) extracts it into a ``kinematics:`` YAML file, and
``ur_description`` (``Universal_Robots_ROS2_Description``) builds the robot from it. The file has
six segments, each the ``<origin xyz rpy>`` of one joint in its parent link, and a ``hash`` that
names the calibration::

    kinematics:
      shoulder:  {x: 0, y: 0, z: 0.1625, roll: 0, pitch: 0, yaw: 0}
      upper_arm: {x: 0, y: 0, z: 0, roll: 1.570796327, pitch: 0, yaw: 0}
      forearm:   ...
      wrist_1:   ...
      wrist_2:   ...
      wrist_3:   ...
      hash: calib_12788084448423163542

The chain is built exactly as ``urdf/ur_macro.xacro`` (ur_description 2.4.5, commit 2221ec0)
builds it, from UR's ``base`` frame (the frame the controller reports poses in) to ``tool0``
(the controller's tool flange with an all-zero TCP)::

    T_base_tool0(q) = O_shoulder Rz(q1) O_upper_arm Rz(q2) ... O_wrist_3 Rz(q6) F T

where ``O_s`` is segment ``s``'s origin: translation ``(x, y, z)``, then the rotation of URDF's
fixed-axis roll-pitch-yaw, ``R = Rz(yaw) Ry(pitch) Rx(roll)``; each joint turns about its link's
z axis (``<axis xyz="0 0 1"/>``); ``F`` is the fixed joint ``wrist_3-flange``, rpy
``(0, -pi/2, -pi/2)``, and ``T`` the fixed joint ``flange-tool0``, rpy ``(pi/2, 0, pi/2)``.
(``F T`` is the identity: ``tool0`` is ``wrist_3_link``'s own frame.)

The base: in ur_macro.xacro the shoulder joint's parent is ``base_link_inertia``, which the fixed
joint ``base_link-base_link_inertia`` turns by rpy ``(0, 0, pi)`` from ``base_link``; ``base`` is
turned from ``base_link`` by the same rpy ``(0, 0, pi)`` (joint ``base_link-base_fixed_joint``).
So ``T_base_base_link_inertia = Rz(pi)^-1 Rz(pi) = I``: the segments are posed in ``base``
itself. (ROS's ``base_link`` is REP-103 aligned, x forward; UR's ``base`` is it turned by pi about
z, so at ``q = 0`` the arm reaches along ``-x`` of ``base``, as on the teach pendant.)

The Menagerie UR5e (``universal_robots_ur5e``) uses the same frames: its world is UR's ``base``
and its ``attachment_site`` is turned like ``tool0`` (they agree to 6e-10 rad, the precision of
the file's ``1.570796327``). Its link lengths are rounded to the millimetre, so UR's nominal
UR5e is 0.2 to 0.7 mm from it in ``d1, a3, d4, d5, d6``.

The angles are read as ROS reads them (URDF rpy), by default. ``ur_calibration`` computes them
with Eigen's ``eulerAngles(0, 1, 2)``, whose angles mean ``R = Rx(roll) Ry(pitch) Rz(yaw)``; the
two readings agree to second order in the small angles (3 to 7 micrometres and microradians for
the two real UR10e calibrations in ur_calibration's tests), so ROS's ``tool0``, and this chain,
can differ from the controller's by that much. ``order="controller"`` reads (and
:func:`ur_origins` writes) the angles as ur_calibration meant them; ``order="description"``, the
default, as ur_description reads them. :data:`UR_YAML_ORDERS` lists the two.

:func:`ur_origins` is the way back: the segment origins of a chain that is a UR arm (calibrated
or not), in the layout of ur_description's ``default_kinematics.yaml``.

Lengths are metres, angles radians.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import Chain
from poekin.errors import InputError, did_you_mean
from poekin.io.params import UR5E_JOINT_NAMES, UR_DH_LENGTHS

__all__ = [
    "UR_JOINT_NAMES",
    "UR_ORIGIN_KEYS",
    "UR_SEGMENTS",
    "UR_YAML_ORDERS",
    "URYamlOrder",
    "default_origins",
    "nominal_model",
    "segment_rotation",
    "segment_rpy",
    "ur_chain",
    "ur_origins",
    "urdf_rpy",
]

FloatArray = NDArray[np.float64]

#: The segments of a ``kinematics:`` file, base to tip: segment ``i`` places joint ``i``.
UR_SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: The numbers of each segment, in the order :func:`ur_chain` takes them.
UR_ORIGIN_KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
#: The joints ``ur_description`` names, base to tip (the Menagerie UR5e's too).
UR_JOINT_NAMES: tuple[str, ...] = UR5E_JOINT_NAMES

# A chain is a UR arm's when each joint axis, at q = 0, is within these of the nearest model's.
# Calibrations move the axes by about a millimetre and a milliradian, and their encoder offsets,
# absorbed, turn each later axis about the earlier ones by up to a few tens of milliradians
# (30 mrad at 0.4 m: 12 mm). Another arm's axes are tens of centimetres or a right angle away.
_UR_LIKE_M, _UR_LIKE_RAD = 0.05, 0.1
# ur_macro.xacro's fixed joints after wrist_3_link: rpy of wrist_3-flange, then flange-tool0.
_FLANGE_RPY = (0.0, -np.pi / 2.0, -np.pi / 2.0)
_TOOL0_RPY = (np.pi / 2.0, 0.0, np.pi / 2.0)
URYamlOrder = Literal["description", "controller"]
#: How a segment's ``roll, pitch, yaw`` compose: ``"description"`` ``Rz(yaw) Ry(pitch)
#: Rx(roll)`` (URDF, as ur_description reads the file), ``"controller"`` ``Rx(roll) Ry(pitch)
#: Rz(yaw)`` (Eigen's ``eulerAngles(0, 1, 2)``, as ur_calibration writes it).
UR_YAML_ORDERS: tuple[URYamlOrder, ...] = ("description", "controller")

# A file is a model's (calibrated or not) when each of its six DH-like lengths is within this of
# the model's published one. Calibrations move them by about a millimetre; the closest two
# models (UR3 and UR3e, wrist_3 y) differ by 10 mm.
_SAME_MODEL = 0.005


def urdf_rpy(roll: float, pitch: float, yaw: float) -> FloatArray:
    """``(3, 3)`` rotation of a URDF ``rpy``: ``Rz(yaw) Ry(pitch) Rx(roll)`` (fixed axes: roll
    about x first, then pitch about y, then yaw about z)."""
    axes = np.eye(3)
    Rx, Ry, Rz = (
        np.asarray(lie.axis_rotation(axes[k], np.float64(angle)), dtype=np.float64)
        for k, angle in enumerate((roll, pitch, yaw))
    )
    return np.asarray(Rz @ Ry @ Rx, dtype=np.float64)


def segment_rotation(
    roll: float, pitch: float, yaw: float, order: URYamlOrder = "description"
) -> FloatArray:
    """``(3, 3)`` rotation of a segment's angles: ``Rz(yaw) Ry(pitch) Rx(roll)`` (``order=
    "description"``, URDF) or ``Rx(roll) Ry(pitch) Rz(yaw)`` (``"controller"``)."""
    check_order(order)
    if order == "description":
        return urdf_rpy(roll, pitch, yaw)
    # Rx Ry Rz = (Rz(-yaw) Ry(-pitch) Rx(-roll))^T
    return np.asarray(urdf_rpy(-roll, -pitch, -yaw).T, dtype=np.float64)


def segment_rpy(R: ArrayLike, order: URYamlOrder = "description") -> FloatArray:
    """``(3,)`` ``roll, pitch, yaw`` of a ``(3, 3)`` rotation, the inverse of
    :func:`segment_rotation` (pitch in ``[-pi/2, pi/2]``)."""
    check_order(order)
    M = np.asarray(R, dtype=np.float64)
    if order == "description":
        return np.asarray(lie.rotation_to_rpy(M), dtype=np.float64)
    return -np.asarray(lie.rotation_to_rpy(M.T), dtype=np.float64)


def check_order(order: str) -> None:
    """Refuse an orientation order that is not one of :data:`UR_YAML_ORDERS`."""
    if order not in UR_YAML_ORDERS:
        raise InputError(
            f"unknown UR YAML orientation order {order!r}: {did_you_mean(order, UR_YAML_ORDERS)}"
            " (description: Rz Ry Rx, as ur_description reads the file; controller: Rx Ry Rz, "
            "as ur_calibration writes it)"
        )


def _origin(row: FloatArray, order: URYamlOrder = "description") -> FloatArray:
    return np.asarray(
        lie.homogeneous(segment_rotation(row[3], row[4], row[5], order), row[:3]),
        dtype=np.float64,
    )


def _origins(origins: ArrayLike) -> FloatArray:
    rows = np.asarray(origins, dtype=np.float64)
    if rows.shape != (6, 6) or not np.all(np.isfinite(rows)):
        raise InputError(
            f"a UR arm needs 6 segment origins of 6 finite numbers each (x, y, z, roll, pitch, "
            f"yaw), base to tip; got shape {rows.shape}"
        )
    return rows


def _link_frames(rows: FloatArray, order: URYamlOrder) -> FloatArray:
    """``(6, 4, 4)``: joint ``i``'s link frame in ``base`` at ``q = 0`` (it turns about its z);
    the last is ``tool0``."""
    frames = np.zeros((6, 4, 4))
    T = np.eye(4)
    for i, row in enumerate(rows):
        T = T @ _origin(row, order)
        frames[i] = T
    return frames


def ur_chain(origins: ArrayLike, *, robot: str = "", order: URYamlOrder = "description") -> Chain:
    """The chain from UR's ``base`` frame to ``tool0`` that ur_description builds from these
    segment origins.

    Args:
        origins: ``(6, 6)`` rows ``x, y, z, roll, pitch, yaw`` (m, rad) of the segments
            :data:`UR_SEGMENTS`, base to tip, as a ``kinematics:`` file gives them.
        robot: the chain's robot label.
        order: how the angles compose (:data:`UR_YAML_ORDERS`): ``"description"`` as
            ur_description reads them, ``"controller"`` as ur_calibration computed them.

    Returns:
        A :class:`Chain` of the six revolute joints :data:`UR_JOINT_NAMES` (no limits: the file
        holds none), frame ``"tool0"``, whose ``fk(q)`` is ``T_base_tool0``.
    """
    frames = _link_frames(_origins(origins), order)
    z, o = frames[:, :3, 2], frames[:, :3, 3]
    flange = lie.homogeneous(urdf_rpy(*_FLANGE_RPY), np.zeros(3))
    tool0 = lie.homogeneous(urdf_rpy(*_TOOL0_RPY), np.zeros(3))
    return Chain(
        joint_names=UR_JOINT_NAMES,
        joint_types=("revolute",) * 6,
        screws=np.hstack([z, -np.cross(z, o)]),
        home=np.asarray(frames[-1] @ flange @ tool0, dtype=np.float64),
        frame="tool0",
        robot=robot,
    )


def default_origins(model: str) -> FloatArray:
    """``(6, 6)`` segment origins of ``model``'s published lengths (a key of
    :data:`~poekin.io.params.UR_DH_LENGTHS`) in the layout of ur_description's
    ``config/<model>/default_kinematics.yaml`` (with pi/2 where the files print 1.570796327)."""
    d1, a2, a3, d4, d5, d6 = UR_DH_LENGTHS[model]
    half = np.pi / 2.0
    return np.array(
        [
            [0.0, 0.0, d1, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, half, 0.0, 0.0],
            [a2, 0.0, 0.0, 0.0, 0.0, 0.0],
            [a3, 0.0, d4, 0.0, 0.0, 0.0],
            [0.0, -d5, 0.0, half, 0.0, 0.0],
            [0.0, d6, 0.0, half, np.pi, np.pi],
        ]
    )


def _turn_onto(a: FloatArray, b: FloatArray) -> FloatArray:
    """The smallest rotation taking unit ``a`` onto unit ``b`` (``a`` and ``b`` not opposite)."""
    k = np.cross(a, b)
    s = float(np.linalg.norm(k))
    angle = float(np.arctan2(s, float(a @ b)))
    if s == 0.0:
        return np.eye(3)
    return np.asarray(lie.exp_so3(k / s * angle), dtype=np.float64)


def _onto_line(F: FloatArray, w: FloatArray, point: FloatArray) -> FloatArray:
    """Frame ``F`` moved onto the line ``point + s w``: z turned onto ``w`` by the smallest
    rotation, the origin at its foot on the line."""
    out = np.eye(4)
    out[:3, :3] = _turn_onto(F[:3, 2], w) @ F[:3, :3]
    out[:3, 3] = point + w * float((F[:3, 3] - point) @ w)
    return out


def _line_distance(p: FloatArray, w: FloatArray, point: FloatArray) -> float:
    return float(np.linalg.norm(np.cross(p - point, w)))


def _angle(u: FloatArray, v: FloatArray) -> float:
    return float(np.arctan2(np.linalg.norm(np.cross(u, v)), u @ v))


def ur_origins(
    chain: Chain, *, order: URYamlOrder = "description"
) -> tuple[FloatArray, FloatArray, str]:
    """The segment origins of a UR arm's chain (in UR's ``base`` frame), the inverse of
    :func:`ur_chain`: ``ur_chain(origins).fk(q) @ tcp == chain.fk(q)``.

    Each joint's link frame is the nearest UR model's default one (:func:`default_origins`)
    moved onto the chain's axis line: its z turned onto the axis by the smallest rotation, its
    origin to the foot of the default one on the line. ``tool0`` is the chain's end frame moved
    so onto joint 6's axis when the end frame is within 50 mm and 0.1 rad of the model's
    ``tool0`` (a calibrated flange), else the model's ``tool0`` moved onto it (the end frame is
    a tool). The rest, ``tcp = T_tool0_frame``, is what the controller's TCP setting holds:
    identity (to rounding) for a chain that ends at ``tool0``.

    Args:
        chain: six revolute joints, base to tip, in UR's ``base`` frame (a UR calibration file,
            the Menagerie UR5e, a calibration's ``result.robot``).
        order: how the angles are to compose (:data:`UR_YAML_ORDERS`).

    Returns:
        ``(origins (6, 6), tcp (4, 4), model)``: rows ``x, y, z, roll, pitch, yaw`` (m, rad)
        of :data:`UR_SEGMENTS`; ``T_tool0_frame``; the nearest model's name.

    Raises:
        InputError: not six revolute joints, or an axis more than 50 mm or 0.1 rad from the
            nearest UR model's at ``q = 0`` (a calibration moves them by a millimetre and a
            milliradian, its encoder offsets by up to tens of milliradians).
    """
    check_order(order)
    if chain.n_joints != 6 or any(t != "revolute" for t in chain.joint_types):
        kinds = ", ".join(chain.joint_types) or "none"
        raise InputError(
            f"{chain.robot or 'the chain'} is not a UR arm: a UR kinematics file holds six "
            f"revolute joints, this chain has {chain.n_joints} ({kinds}); export it as a URDF"
        )
    w = chain.screws[:, :3] / np.linalg.norm(chain.screws[:, :3], axis=1)[:, None]
    points = np.cross(w, chain.screws[:, 3:])  # each axis line's point nearest the origin
    best: tuple[float, str, FloatArray, str] | None = None
    for model in UR_DH_LENGTHS:
        nominal = _link_frames(default_origins(model), "description")
        worst, why = 0.0, ""
        for i in range(6):
            dist = _line_distance(nominal[i, :3, 3], w[i], points[i])
            tilt = _angle(nominal[i, :3, 2], w[i])
            score = max(dist / _UR_LIKE_M, tilt / _UR_LIKE_RAD)
            if score > worst:
                worst = score
                why = (
                    f"joint {i + 1} ({chain.joint_names[i]})'s axis is {dist * 1e3:.3g} mm and "
                    f"{np.degrees(tilt):.3g} deg from {model}'s"
                )
        if best is None or worst < best[0]:
            best = (worst, model, nominal, why)
    assert best is not None
    worst, model, nominal, why = best
    if worst > 1.0:
        raise InputError(
            f"{chain.robot or 'the chain'} is not a UR arm in UR's base frame: {why}, the "
            f"nearest model (a UR kinematics file allows {_UR_LIKE_M * 1e3:g} mm and "
            f"{_UR_LIKE_RAD:g} rad); export it as a URDF, or, for a calibration, write "
            "result.robot (the robot's own base frame)"
        )
    frames = np.array([_onto_line(nominal[i], w[i], points[i]) for i in range(6)])
    home = chain.home
    tool0_like = (
        float(np.linalg.norm(home[:3, 3] - nominal[5, :3, 3])) <= _UR_LIKE_M
        and float(lie.rotation_angle(nominal[5, :3, :3].T @ home[:3, :3])) <= _UR_LIKE_RAD
    )
    if tool0_like:
        frames[5] = _onto_line(home, w[5], points[5])
    origins = np.zeros((6, 6))
    previous = np.eye(4)
    for i in range(6):
        segment = np.asarray(lie.inverse(previous), dtype=np.float64) @ frames[i]
        origins[i, :3] = segment[:3, 3]
        origins[i, 3:] = segment_rpy(segment[:3, :3], order)
        previous = frames[i]
    tcp = np.asarray(lie.inverse(frames[5]), dtype=np.float64) @ home
    tcp[3] = [0.0, 0.0, 0.0, 1.0]
    return origins, tcp, model


def nominal_model(origins: ArrayLike) -> str | None:
    """The UR model (``"ur5e"``, a key of :data:`~poekin.io.params.UR_DH_LENGTHS`) whose published
    lengths these segment origins have, within 5 mm each; None if no model's.

    The file's lengths are read where ur_description's defaults put them: ``d1`` the shoulder's
    z, ``a2`` the forearm's x, ``a3`` and ``d4`` wrist_1's x and z, ``d5`` minus wrist_2's y,
    ``d6`` wrist_3's y. A calibration moves them by about a millimetre.
    """
    rows = _origins(origins)
    lengths = np.array(
        [rows[0, 2], rows[2, 0], rows[3, 0], rows[3, 2], -rows[4, 1], rows[5, 1]],
    )
    for model, published in UR_DH_LENGTHS.items():
        if np.max(np.abs(lengths - np.array(published))) <= _SAME_MODEL:
            return model
    return None
