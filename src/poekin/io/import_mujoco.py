"""Reading a :class:`~poekin.tree.Tree` and PoE :class:`~poekin.chain.Chain` from a compiled
MuJoCo model.

Nothing here is typed by hand. The tree takes every body and site offset, joint axis, anchor and
``ref`` from the compiled ``MjModel``, so MJCF ``<default>`` classes, ``childclass``,
``euler``/``axisangle``/``xyaxes`` frames and ``compiler angle`` are already resolved by MuJoCo.
A chain is the tree walked once with its joints at ``q = 0`` (every other joint at ``qpos0``):
the world-frame joint axes and anchors are the space-frame screw axes, and the frame's pose is
the home pose ``M``::

    hinge:  S = [w; -w x p]      slide:  S = [0; w]

Because MuJoCo rotates a hinge by ``qpos - qpos0``, evaluating at ``qpos = 0`` already accounts
for a non-zero ``ref``: ``chain.fk(q)`` and ``data.qpos[...] = q; mj_forward`` describe the same
pose for the same numbers.
"""

from __future__ import annotations

import functools
from collections.abc import Collection
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.chain import Chain, JointType
from poekin.errors import UnknownFrameError, did_you_mean
from poekin.tree import Tree, TreeJointType

if TYPE_CHECKING:
    import mujoco

__all__ = [
    "FrameKind",
    "chain_from_model",
    "find_frame",
    "frame_pose",
    "site_and_body_names",
    "tree_from_model",
]

FrameKind = Literal["site", "body"]
_CHAIN_JOINTS: tuple[JointType, ...] = ("revolute", "prismatic")


@functools.cache
def _joint_types() -> dict[int, TreeJointType]:
    """MuJoCo's joint types by ``mjtJoint`` value (MuJoCo is imported when first needed)."""
    import mujoco

    return {
        int(mujoco.mjtJoint.mjJNT_HINGE): "revolute",
        int(mujoco.mjtJoint.mjJNT_SLIDE): "prismatic",
        int(mujoco.mjtJoint.mjJNT_BALL): "ball",
        int(mujoco.mjtJoint.mjJNT_FREE): "free",
    }


def _names(
    model: mujoco.MjModel, kind: Literal["site", "body", "joint"], start: int, stop: int
) -> list[str]:
    """Names of the ``kind`` objects ``start, ..., stop - 1``; unnamed ones as ``site3``, ..."""
    import mujoco

    obj = {
        "site": mujoco.mjtObj.mjOBJ_SITE,
        "body": mujoco.mjtObj.mjOBJ_BODY,
        "joint": mujoco.mjtObj.mjOBJ_JOINT,
    }[kind]
    return [mujoco.mj_id2name(model, obj, i) or f"{kind}{i}" for i in range(start, stop)]


def site_and_body_names(model: mujoco.MjModel) -> tuple[list[str], list[str]]:
    """Names of every site and every body except the world (unnamed ones as ``site3``, ...)."""
    return _names(model, "site", 0, model.nsite), _names(model, "body", 1, model.nbody)


def find_frame(model: mujoco.MjModel, frame: str | None) -> tuple[FrameKind, int, str]:
    """Resolve a site or body name to ``(kind, id, name)``. Sites take precedence.

    With ``frame=None`` the model's only site is used.

    Raises:
        UnknownFrameError: no such site or body, or None given and the model has not exactly one
            site. The message lists the candidates.
    """
    sites, bodies = site_and_body_names(model)
    if frame is None:
        if len(sites) == 1:
            return "site", 0, sites[0]
        what = f"{len(sites)} sites" if sites else "no sites"
        raise UnknownFrameError(
            f"the model has {what}, so name the end frame with --frame / frame=: "
            f"{did_you_mean('', sites + bodies)}"
        )
    if frame in sites:
        return "site", sites.index(frame), frame
    if frame in bodies:
        return "body", bodies.index(frame) + 1, frame
    raise UnknownFrameError(
        f"no site or body named {frame!r}: {did_you_mean(frame, sites + bodies)}"
    )


def frame_pose(
    data: mujoco.MjData, kind: FrameKind, fid: int, out: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """``(4, 4)`` world pose of a site or body from ``data`` (after ``mj_kinematics``), written
    into ``out`` if given."""
    T = np.eye(4) if out is None else out
    xpos, xmat = (data.site_xpos, data.site_xmat) if kind == "site" else (data.xpos, data.xmat)
    T[:3, :3] = xmat[fid].reshape(3, 3)
    T[:3, 3] = xpos[fid]
    return T


def _site_offsets(model: mujoco.MjModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each site's ``(pos (nsite, 3), rot (nsite, 3, 3))`` in its body, as ``mj_kinematics``
    applies them.

    Where the compiler found a site on its body's frame or inertial frame (``site_sameframe``,
    to its own tolerance: a 1e-7 rad rotation counts), MuJoCo copies that frame's position
    and/or rotation instead of applying ``site_pos`` and ``site_quat`` (``mj_local2Global``), so
    poekin does too. The inertial frame is itself the body's frame where ``body_sameframe`` says.
    """
    import mujoco

    same = mujoco.mjtSameFrame
    pos = np.array(model.site_pos, dtype=np.float64)
    rot = np.asarray(lie.quat_to_rotation(model.site_quat), dtype=np.float64)
    for s in range(model.nsite):
        frame, b = int(model.site_sameframe[s]), int(model.site_bodyid[s])
        if frame in (same.mjSAMEFRAME_INERTIA, same.mjSAMEFRAME_INERTIAROT):
            inertia = int(model.body_sameframe[b])
            body_rot = inertia in (same.mjSAMEFRAME_BODY, same.mjSAMEFRAME_BODYROT)
            rot[s] = np.eye(3) if body_rot else lie.quat_to_rotation(model.body_iquat[b])
            if frame == same.mjSAMEFRAME_INERTIA:
                at_body = inertia == same.mjSAMEFRAME_BODY
                pos[s] = 0.0 if at_body else model.body_ipos[b]
        elif frame in (same.mjSAMEFRAME_BODY, same.mjSAMEFRAME_BODYROT):
            rot[s] = np.eye(3)
            if frame == same.mjSAMEFRAME_BODY:
                pos[s] = 0.0
    return pos, rot


def tree_from_model(
    model: mujoco.MjModel,
    *,
    robot: str = "",
    unknown_masses: Collection[int] = (),
    source_file: str = "",
) -> Tree:
    """The whole kinematic tree of a compiled MuJoCo model: every body, joint and site.

    Body and site offsets, joint axes, anchors and ``ref`` (``qpos0``) are read from the
    compiled model, so ``<default>`` classes, ``childclass``, ``euler``/``axisangle`` frames and
    the like are already resolved. Mocap bodies sit at their model pose, and sites as
    :func:`_site_offsets` says. Masses and centres of mass are ``body_mass`` and ``body_ipos``,
    NaN for the MuJoCo body ids in ``unknown_masses`` (those a kinematics-only compile got
    wrong: :attr:`poekin.io.sources.LoadedModel.unknown_masses`). ``source_file``: the model
    file ``model`` was compiled from, which :meth:`Tree.distances` reads the collision geometry
    from (empty: none known).
    """

    def quat(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(lie.quat_to_rotation(q), dtype=np.float64)

    joints = range(model.njnt)
    site_names, body_names = site_and_body_names(model)
    types = [_joint_types()[int(model.jnt_type[j])] for j in joints]
    hinge_like = [t in _CHAIN_JOINTS for t in types]
    limits = np.where(
        (model.jnt_limited.astype(bool) & np.array(hinge_like, dtype=bool))[:, None],
        model.jnt_range,
        [-np.inf, np.inf],
    )
    refs = np.array([model.qpos0[model.jnt_qposadr[j]] if hinge_like[j] else 0.0 for j in joints])
    site_pos, site_rot = _site_offsets(model)
    body_mass = np.array(model.body_mass[1:], dtype=np.float64)
    body_com = np.array(model.body_ipos[1:], dtype=np.float64)
    unknown = [b - 1 for b in unknown_masses]
    body_mass[unknown], body_com[unknown] = np.nan, np.nan
    return Tree(
        body_names=tuple(body_names),
        body_parents=model.body_parentid[1:] - 1,
        body_pos=model.body_pos[1:],
        body_rot=quat(model.body_quat[1:]),
        joint_names=tuple(_names(model, "joint", 0, model.njnt)),
        joint_types=tuple(types),
        joint_bodies=model.jnt_bodyid - 1,
        joint_axes=model.jnt_axis,
        joint_anchors=model.jnt_pos,
        joint_refs=refs,
        joint_limits=limits,
        mimics=(None,) * model.njnt,
        site_names=tuple(site_names),
        site_bodies=model.site_bodyid - 1,
        site_pos=site_pos,
        site_rot=site_rot,
        qpos0=model.qpos0,
        robot=robot,
        body_mass=body_mass,
        body_com=body_com,
        _source_file=source_file,
    )


def chain_from_model(model: mujoco.MjModel, frame: str | None = None, *, robot: str = "") -> Chain:
    """The hinge/slide chain from the world to ``frame`` (a site or body name).

    Args:
        model: a compiled MuJoCo model.
        frame: site or body name; None means the model's only site.
        robot: a label stored in the chain.

    Raises:
        UnknownFrameError: see :func:`find_frame`.
        ModelError: a ball or free joint lies on the path to the frame.
    """
    _, _, name = find_frame(model, frame)
    return tree_from_model(model, robot=robot).chain(name)
