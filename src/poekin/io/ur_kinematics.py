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

The angles are read as ROS reads them (URDF rpy). ``ur_calibration`` computes them with Eigen's
``eulerAngles(0, 1, 2)``, whose angles mean ``R = Rx(roll) Ry(pitch) Rz(yaw)``; the two readings
agree to second order in the small angles (3 to 7 micrometres and microradians for the two real
UR10e calibrations in ur_calibration's tests), so ROS's ``tool0``, and this chain, can differ
from the controller's by that much.

Lengths are metres, angles radians.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import Chain
from poekin.errors import InputError
from poekin.io.params import UR5E_JOINT_NAMES, UR_DH_LENGTHS

__all__ = [
    "UR_JOINT_NAMES",
    "UR_ORIGIN_KEYS",
    "UR_SEGMENTS",
    "nominal_model",
    "ur_chain",
    "urdf_rpy",
]

FloatArray = NDArray[np.float64]

#: The segments of a ``kinematics:`` file, base to tip: segment ``i`` places joint ``i``.
UR_SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: The numbers of each segment, in the order :func:`ur_chain` takes them.
UR_ORIGIN_KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
#: The joints ``ur_description`` names, base to tip (the Menagerie UR5e's too).
UR_JOINT_NAMES: tuple[str, ...] = UR5E_JOINT_NAMES

# ur_macro.xacro's fixed joints after wrist_3_link: rpy of wrist_3-flange, then flange-tool0.
_FLANGE_RPY = (0.0, -np.pi / 2.0, -np.pi / 2.0)
_TOOL0_RPY = (np.pi / 2.0, 0.0, np.pi / 2.0)
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


def _origin(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> FloatArray:
    return np.asarray(lie.homogeneous(urdf_rpy(roll, pitch, yaw), [x, y, z]), dtype=np.float64)


def _origins(origins: ArrayLike) -> FloatArray:
    rows = np.asarray(origins, dtype=np.float64)
    if rows.shape != (6, 6) or not np.all(np.isfinite(rows)):
        raise InputError(
            f"a UR arm needs 6 segment origins of 6 finite numbers each (x, y, z, roll, pitch, "
            f"yaw), base to tip; got shape {rows.shape}"
        )
    return rows


def ur_chain(origins: ArrayLike, *, robot: str = "") -> Chain:
    """The chain from UR's ``base`` frame to ``tool0`` that ur_description builds from these
    segment origins.

    Args:
        origins: ``(6, 6)`` rows ``x, y, z, roll, pitch, yaw`` (m, rad) of the segments
            :data:`UR_SEGMENTS`, base to tip, as a ``kinematics:`` file gives them.
        robot: the chain's robot label.

    Returns:
        A :class:`Chain` of the six revolute joints :data:`UR_JOINT_NAMES` (no limits: the file
        holds none), frame ``"tool0"``, whose ``fk(q)`` is ``T_base_tool0``.
    """
    rows = _origins(origins)
    frames = np.zeros((6, 4, 4))  # joint i's link frame at q = 0: it turns about its z axis
    T = np.eye(4)
    for i, row in enumerate(rows):
        T = T @ _origin(*row)
        frames[i] = T
    z, o = frames[:, :3, 2], frames[:, :3, 3]
    home = T @ _origin(0.0, 0.0, 0.0, *_FLANGE_RPY) @ _origin(0.0, 0.0, 0.0, *_TOOL0_RPY)
    return Chain(
        joint_names=UR_JOINT_NAMES,
        joint_types=("revolute",) * 6,
        screws=np.hstack([z, -np.cross(z, o)]),
        home=home,
        frame="tool0",
        robot=robot,
    )


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
