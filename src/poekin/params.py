"""Named parameter sets: robots' PoE parameters written out as numbers.

These are for teaching and cross-checking. :func:`poekin.load` derives the same numbers from
the model; a test proves that the two agree.

Menagerie UR5e (``universal_robots_ur5e/ur5e.xml``), space frame = MuJoCo world frame, end frame
``attachment_site``. The base body is turned 180 deg about z (``quat="0 0 0 -1"``), so the arm
reaches along -x at ``q = 0``; that is also why the Lynch & Park Example 4.5 table (base frame
not turned, UR5 dimensions) is metres away from this model.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.chain import Chain

__all__ = ["UR5E_HOME", "UR5E_JOINT_NAMES", "UR5E_SCREWS", "fk_ur5e_poe", "ur5e_chain"]

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

UR5E_JOINT_NAMES = (
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
