"""Deriving a PoE :class:`~poekin.chain.Chain` from a compiled MuJoCo model.

Nothing here is typed by hand. MuJoCo's own ``mj_kinematics`` is run once with the chain's
joints at ``q = 0`` (every other joint at its reference ``qpos0``); the world-frame joint axes
(``xaxis``) and anchors (``xanchor``) it reports are the space-frame screw axes, and the frame's
pose is the home pose ``M``::

    hinge:  S = [w; -w x p]      slide:  S = [0; w]

Because MuJoCo rotates a hinge by ``qpos - qpos0``, evaluating at ``qpos = 0`` already accounts
for a non-zero ``ref``: ``chain.fk(q)`` and ``data.qpos[...] = q; mj_forward`` describe the same
pose for the same numbers.
"""

from __future__ import annotations

import os
from typing import Literal

import mujoco
import numpy as np
from numpy.typing import NDArray

from poekin.chain import Chain, JointType
from poekin.errors import ModelError, UnknownFrameError, did_you_mean
from poekin.sources import LoadedModel, load_model

__all__ = [
    "FrameKind",
    "chain_from_model",
    "find_frame",
    "frame_pose",
    "load",
    "site_and_body_names",
]

FrameKind = Literal["site", "body"]
_JOINT_TYPES: dict[int, JointType] = {
    int(mujoco.mjtJoint.mjJNT_HINGE): "revolute",
    int(mujoco.mjtJoint.mjJNT_SLIDE): "prismatic",
}


def _name(model: mujoco.MjModel, obj: mujoco.mjtObj, i: int, prefix: str) -> str:
    return mujoco.mj_id2name(model, obj, i) or f"{prefix}{i}"


def site_and_body_names(model: mujoco.MjModel) -> tuple[list[str], list[str]]:
    """Names of every site and every body except the world (unnamed ones as ``site3``, ...)."""
    sites = [_name(model, mujoco.mjtObj.mjOBJ_SITE, i, "site") for i in range(model.nsite)]
    bodies = [_name(model, mujoco.mjtObj.mjOBJ_BODY, i, "body") for i in range(1, model.nbody)]
    return sites, bodies


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
    kind, fid, name = find_frame(model, frame)
    body = int(model.site_bodyid[fid]) if kind == "site" else fid
    path = []
    while body > 0:
        path.append(body)
        body = int(model.body_parentid[body])
    joints = [
        j
        for b in reversed(path)
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b])
    ]
    for j in joints:
        if int(model.jnt_type[j]) not in _JOINT_TYPES:
            jtype = mujoco.mjtJoint(int(model.jnt_type[j])).name.removeprefix("mjJNT_").lower()
            raise ModelError(
                f"joint {_name(model, mujoco.mjtObj.mjOBJ_JOINT, j, 'joint')!r} on the path to "
                f"{name!r} is a {jtype} joint; a PoE chain holds hinge and slide joints only "
                "(choose a frame whose path has none, e.g. relative to a body after it)"
            )

    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    qpos_indices = [int(model.jnt_qposadr[j]) for j in joints]
    data.qpos[qpos_indices] = 0.0
    mujoco.mj_kinematics(model, data)

    screws = np.zeros((len(joints), 6))
    for row, j in enumerate(joints):
        w = data.xaxis[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            screws[row, :3] = w
            screws[row, 3:] = -np.cross(w, data.xanchor[j])
        else:
            screws[row, 3:] = w
    home = frame_pose(data, kind, fid)
    limits = np.where(
        model.jnt_limited[joints, None].astype(bool),
        model.jnt_range[joints],
        [-np.inf, np.inf],
    )
    return Chain(
        joint_names=tuple(_name(model, mujoco.mjtObj.mjOBJ_JOINT, j, "joint") for j in joints),
        joint_types=tuple(_JOINT_TYPES[int(model.jnt_type[j])] for j in joints),
        screws=screws,
        home=home,
        limits=limits,
        frame=name,
        robot=robot,
        qpos_indices=tuple(qpos_indices),
    )


def load(source: str | os.PathLike[str] | LoadedModel, frame: str | None = None) -> Chain:
    """Load a PoE chain from a Menagerie robot name or an MJCF path.

    Args:
        source: e.g. ``"universal_robots_ur5e"`` (resolved by ``mujoco_menagerie``, which honours
            ``MENAGERIE_ROOT``), a path to an MJCF file, or an already loaded model.
        frame: the end frame, a site or body name; None means the model's only site.

    Returns:
        The chain of hinge and slide joints from the world to ``frame``.

    Example:
        >>> chain = poekin.load("universal_robots_ur5e")  # frame: attachment_site
        >>> chain.fk([0.0, -1.57, 1.57, 0.0, 0.0, 0.0]).shape
        (4, 4)
    """
    loaded = source if isinstance(source, LoadedModel) else load_model(source)
    return chain_from_model(loaded.model, frame, robot=loaded.robot)
