"""Named parameter sets: robots' PoE parameters written out as numbers.

These are for teaching and cross-checking. :func:`poekin.load` derives the same numbers from
the model; a test proves that the two agree.

Menagerie UR5e (``universal_robots_ur5e/ur5e.xml``), space frame = MuJoCo world frame, end frame
``attachment_site``. The base body is turned 180 deg about z (``quat="0 0 0 -1"``), so the arm
reaches along -x at ``q = 0``; that is also why the Lynch & Park Example 4.5 table (base frame
not turned, UR5 dimensions) is metres away from this model.

Also here, as published (cite these, not poekin, when you use them):

* ``lynch-park-ur5``: the UR5 of K. M. Lynch and F. C. Park, *Modern Robotics: Mechanics,
  Planning, and Control*, Cambridge University Press, 2017, Example 4.5 (Fig. 4.5), in PoE form.
* ``ur5-dh`` and ``ur5e-dh``: Universal Robots' standard-convention DH tables for the UR5 (CB3)
  and the UR5e, from their support article 45257.

:data:`PARAM_SETS` lists every named set; :func:`named_params` returns one by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.chain import Chain
from poekin.dh import DHTable
from poekin.errors import UnknownParamsError, did_you_mean

__all__ = [
    "LYNCH_PARK_UR5_H1",
    "LYNCH_PARK_UR5_H2",
    "LYNCH_PARK_UR5_HOME",
    "LYNCH_PARK_UR5_L1",
    "LYNCH_PARK_UR5_L2",
    "LYNCH_PARK_UR5_SCREWS",
    "LYNCH_PARK_UR5_W1",
    "LYNCH_PARK_UR5_W2",
    "PARAM_SETS",
    "UR5E_DH",
    "UR5E_HOME",
    "UR5E_JOINT_NAMES",
    "UR5E_SCREWS",
    "UR5_DH",
    "UR_DH_LENGTHS",
    "fk_ur5e_poe",
    "lynch_park_ur5_chain",
    "named_params",
    "ur5e_chain",
]

# Link dimensions of the Menagerie UR5e in metres, read off ur5e.xml body offsets.
UR5E_SHOULDER_HEIGHT = 0.163  # base -> shoulder_link, z
UR5E_SHOULDER_OFFSET = 0.138  # shoulder_link -> upper_arm_link, y
UR5E_ELBOW_OFFSET = 0.131  # upper_arm_link -> forearm_link, -y
UR5E_UPPER_ARM = 0.425  # upper_arm_link -> forearm_link, along the arm
UR5E_FOREARM = 0.392  # forearm_link -> wrist_1_link, along the arm
UR5E_WRIST_1 = 0.127  # wrist_1_link -> wrist_2_link
UR5E_WRIST_2 = 0.100  # wrist_2_link -> wrist_3_link
UR5E_WRIST_3 = 0.100  # wrist_3_link -> attachment_site

_REACH = UR5E_UPPER_ARM + UR5E_FOREARM  # 0.817: shoulder axis to wrist axes, along -x
_WRIST_Y = UR5E_SHOULDER_OFFSET - UR5E_ELBOW_OFFSET + UR5E_WRIST_1  # 0.134
_WRIST_3_Z = UR5E_SHOULDER_HEIGHT - UR5E_WRIST_2  # 0.063

UR5E_JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)

#: ``(6, 6)`` space-frame screw axes ``S_i = [w; v]`` at ``q = 0``, ``v = -w x p_i`` for a point
#: ``p_i`` on joint axis ``i``.
UR5E_SCREWS: NDArray[np.float64] = np.array(
    [
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        [0.0, -1.0, 0.0, UR5E_SHOULDER_HEIGHT, 0.0, 0.0],
        [0.0, -1.0, 0.0, UR5E_SHOULDER_HEIGHT, 0.0, UR5E_UPPER_ARM],
        [0.0, -1.0, 0.0, UR5E_SHOULDER_HEIGHT, 0.0, _REACH],
        [0.0, 0.0, -1.0, _WRIST_Y, -_REACH, 0.0],
        [0.0, -1.0, 0.0, _WRIST_3_Z, 0.0, _REACH],
    ]
)

#: ``(4, 4)`` home pose ``M = T_world_attachment_site(q = 0)``.
UR5E_HOME: NDArray[np.float64] = np.array(
    [
        [1.0, 0.0, 0.0, -_REACH],
        [0.0, 0.0, -1.0, -(_WRIST_Y + UR5E_WRIST_3)],
        [0.0, 1.0, 0.0, _WRIST_3_Z],
        [0.0, 0.0, 0.0, 1.0],
    ]
)

_UR5E_LIMITS = np.array([[-6.28319, 6.28319]] * 2 + [[-3.1415, 3.1415]] + [[-6.28319, 6.28319]] * 3)


def ur5e_chain() -> Chain:
    """The Menagerie UR5e to ``attachment_site`` as a :class:`Chain`, from the constants above."""
    return Chain(
        joint_names=UR5E_JOINT_NAMES,
        joint_types=("revolute",) * 6,
        screws=UR5E_SCREWS,
        home=UR5E_HOME,
        limits=_UR5E_LIMITS,
        frame="attachment_site",
        robot="universal_robots_ur5e",
        qpos_indices=tuple(range(6)),
    )


_UR5E = ur5e_chain()


def fk_ur5e_poe(q: ArrayLike) -> NDArray[np.float64]:
    """Menagerie UR5e space-frame PoE: ``(..., 6)`` joint values (rad) -> ``(..., 4, 4)``
    ``T_world_attachment_site``."""
    return _UR5E.fk(q)


# --- Modern Robotics (Lynch & Park 2017), Example 4.5: the UR5 -----------------------------------
#
# Dimensions exactly as the book prints them (Fig. 4.5), in metres. The space frame {s} is at the
# base with z up; at q = 0 the arm lies along +x.
LYNCH_PARK_UR5_W1 = 0.109  # W1: base (x-z plane) to the wrist-2 axis (joint 5), along y
LYNCH_PARK_UR5_W2 = 0.082  # W2: wrist-2 axis to the end frame, along y (the wrist-3 axis)
LYNCH_PARK_UR5_L1 = 0.425  # L1: upper arm, shoulder-lift axis to elbow axis, along x
LYNCH_PARK_UR5_L2 = 0.392  # L2: forearm, elbow axis to wrist-1 axis, along x
LYNCH_PARK_UR5_H1 = 0.089  # H1: base to the shoulder-lift, elbow and wrist-1 axes, along z
LYNCH_PARK_UR5_H2 = 0.095  # H2: wrist-1 axis down to the wrist-3 axis, along -z (wrist-2 axis)

_W1, _W2 = LYNCH_PARK_UR5_W1, LYNCH_PARK_UR5_W2
_L1, _L2 = LYNCH_PARK_UR5_L1, LYNCH_PARK_UR5_L2
_H1, _H2 = LYNCH_PARK_UR5_H1, LYNCH_PARK_UR5_H2

#: ``(6, 6)`` space-frame screw axes ``S_i = [w; v]`` of Lynch & Park, Example 4.5, as printed.
LYNCH_PARK_UR5_SCREWS: NDArray[np.float64] = np.array(
    [
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, -_H1, 0.0, 0.0],
        [0.0, 1.0, 0.0, -_H1, 0.0, _L1],
        [0.0, 1.0, 0.0, -_H1, 0.0, _L1 + _L2],
        [0.0, 0.0, -1.0, -_W1, _L1 + _L2, 0.0],
        [0.0, 1.0, 0.0, _H2 - _H1, 0.0, _L1 + _L2],
    ]
)

#: ``(4, 4)`` home pose ``M = T_sb(q = 0)`` of Lynch & Park, Example 4.5, as printed.
LYNCH_PARK_UR5_HOME: NDArray[np.float64] = np.array(
    [
        [-1.0, 0.0, 0.0, _L1 + _L2],
        [0.0, 0.0, 1.0, _W1 + _W2],
        [0.0, 1.0, 0.0, _H1 - _H2],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


def lynch_park_ur5_chain() -> Chain:
    """The UR5 of Modern Robotics, Example 4.5, as a :class:`Chain` (no joint limits).

    Source: K. M. Lynch and F. C. Park, *Modern Robotics: Mechanics, Planning, and Control*,
    Cambridge University Press, 2017, Example 4.5, Fig. 4.5. The screws and ``M`` are
    :data:`LYNCH_PARK_UR5_SCREWS` and :data:`LYNCH_PARK_UR5_HOME`, exactly as printed. Its base
    frame is not the Menagerie UR5e's (see the module docstring), so it is not a model of that
    file.
    """
    return Chain(
        joint_names=UR5E_JOINT_NAMES,
        joint_types=("revolute",) * 6,
        screws=LYNCH_PARK_UR5_SCREWS,
        home=LYNCH_PARK_UR5_HOME,
        frame="ee",
        robot="lynch-park-ur5",
    )


# --- Universal Robots' published DH tables ------------------------------------------------------
#
# Source: Universal Robots, "DH parameters for calculations of kinematics and dynamics", support
# article 45257, https://www.universal-robots.com/articles/ur/application-installation/
# dh-parameters-for-calculations-of-kinematics-and-dynamics/ (valid for CB3 software 3.7.0 and
# e-Series software 5.1.0). Standard (Denavit-Hartenberg) convention, metres and radians, all
# theta offsets 0, a1 = a4 = a5 = a6 = 0 and d2 = d3 = 0. UR's "a" is Wikipedia's "r" (the
# common-normal length); UR's a2, a3 are negative because their x axes point back along the arm.
_UR_ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)


def _ur_dh(robot: str, d1: float, a2: float, a3: float, d4: float, d5: float, d6: float) -> DHTable:
    """A UR standard-DH table from its six nonzero lengths (m), base to flange."""
    return DHTable(
        convention="standard",
        a=np.array([0.0, a2, a3, 0.0, 0.0, 0.0]),
        alpha=np.array(_UR_ALPHA),
        d=np.array([d1, 0.0, 0.0, d4, d5, d6]),
        theta_offset=np.zeros(6),
        joint_types=("revolute",) * 6,
        joint_names=UR5E_JOINT_NAMES,
        frame="flange",
        robot=robot,
    )


#: The six nonzero lengths ``(d1, a2, a3, d4, d5, d6)`` (m) of every UR model's standard DH
#: table, as Universal Robots publishes them (article 45257, and its linked UR20 and UR30 pages;
#: see the comment above). ``ur_description``'s ``config/<model>/default_kinematics.yaml`` holds
#: the same numbers. :mod:`poekin.io.ur_kinematics` names the model of a calibration file by them.
UR_DH_LENGTHS: Mapping[str, tuple[float, float, float, float, float, float]] = MappingProxyType(
    {
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
)

#: UR5 (CB3) standard DH table, base to tool flange, as Universal Robots publishes it (article
#: 45257; see the comment above for the full citation).
UR5_DH: DHTable = _ur_dh("ur5-dh", *UR_DH_LENGTHS["ur5"])

#: UR5e standard DH table, base to tool flange, as Universal Robots publishes it (article 45257;
#: see the comment above for the full citation).
UR5E_DH: DHTable = _ur_dh("ur5e-dh", *UR_DH_LENGTHS["ur5e"])


# --- registry ---------------------------------------------------------------------------------

#: Every named parameter set, with a one-line description. :func:`named_params` builds them.
PARAM_SETS: Mapping[str, str] = MappingProxyType(
    {
        "lynch-park-ur5": "UR5 in PoE form, Lynch & Park, Modern Robotics (2017), Example 4.5",
        "ur5-dh": "UR5 (CB3) standard DH table published by Universal Robots, base to flange",
        "ur5e-dh": "UR5e standard DH table published by Universal Robots, base to flange",
        "ur5e-poe": "Menagerie UR5e in PoE form to attachment_site (UR5E_SCREWS, UR5E_HOME)",
    }
)


def named_params(name: str) -> Chain | DHTable:
    """The parameter set called ``name`` (a key of :data:`PARAM_SETS`).

    Returns:
        A :class:`Chain` (PoE sets) or a :class:`~poekin.dh.DHTable` (DH sets). Both are
        immutable, so the shared module constants may be returned.

    Raises:
        UnknownParamsError: ``name`` is not in :data:`PARAM_SETS`; the message lists the names.
    """
    if name == "lynch-park-ur5":
        return lynch_park_ur5_chain()
    if name == "ur5-dh":
        return UR5_DH
    if name == "ur5e-dh":
        return UR5E_DH
    if name == "ur5e-poe":
        return ur5e_chain()
    raise UnknownParamsError(
        f"unknown parameter set {name!r}: {did_you_mean(str(name), PARAM_SETS)}"
    )
