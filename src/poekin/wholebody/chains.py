"""A chain's IK with a posture: :meth:`poekin.Chain.ik` with ``posture=``.

A redundant arm (seven joints for a six-number pose) reaches a target along a family of
configurations; a posture picks the one nearest a preferred configuration. The chain is
solved as a tree (:func:`chain_tree`: one body per joint, all at the world frame at ``q = 0``,
each joint turning about its space screw's axis, the end frame a site at the home pose ``M``,
so that the tree's FK is the chain's product of exponentials ``e^[S1]q1 ... e^[Sn]qn M``)
by :func:`poekin.wholebody.solve`, the posture its level 3: the pull toward ``q0``, per joint,
in the null space of the target.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from poekin.errors import InputError
from poekin.ik.numerical import IKResult, Settings

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.tree import Tree

__all__ = ["chain_tree", "solve_chain"]

_KEY = "wholebody-tree"


def chain_tree(chain: Chain) -> Tree:
    """The tree whose FK of ``q`` puts its site ``chain.frame`` at ``chain.fk(q)`` (kept with
    the chain after the first call)."""
    cache = chain._ik_cache
    if _KEY not in cache:
        cache[_KEY] = _tree(chain)
    tree: Tree = cache[_KEY]
    return tree


def _tree(chain: Chain) -> Tree:
    from poekin.tree import Tree

    n = chain.n_joints
    axes = np.zeros((n, 3))
    anchors = np.zeros((n, 3))
    for i, (kind, S) in enumerate(zip(chain.joint_types, chain.screws, strict=True)):
        if kind == "revolute":
            w, v = S[:3], S[3:]
            axes[i] = w
            anchors[i] = np.cross(w, v)  # a point on the axis: v = -w x q
        else:
            axes[i] = S[3:]
    return Tree(
        body_names=tuple(f"link{i + 1}" for i in range(n)),
        body_parents=np.arange(-1, n - 1),
        body_pos=np.zeros((n, 3)),
        body_rot=np.broadcast_to(np.eye(3), (n, 3, 3)),
        joint_names=chain.joint_names,
        joint_types=chain.joint_types,
        joint_bodies=np.arange(n),
        joint_axes=axes,
        joint_anchors=anchors,
        joint_refs=np.zeros(n),
        joint_limits=(np.tile([-np.inf, np.inf], (n, 1)) if chain.limits is None else chain.limits),
        mimics=(None,) * n,
        site_names=(chain.frame or "end",),
        site_bodies=np.array([n - 1]),
        site_pos=chain.home[None, :3, 3],
        site_rot=chain.home[None, :3, :3],
        robot=chain.robot,
    )


def solve_chain(
    chain: Chain,
    T: ArrayLike,
    q0: ArrayLike | None,
    *,
    posture: Any,
    seed: int,
    options: Settings,
) -> IKResult:
    """:meth:`poekin.Chain.ik` with a posture toward ``q0``."""
    from poekin.wholebody.solve import solve

    if q0 is None:
        raise InputError(
            "posture pulls toward q0: give q0, the preferred configuration (the first attempt "
            "starts there too)"
        )
    arr = np.asarray(posture, dtype=np.float64) if not isinstance(posture, bool) else None
    if arr is None or arr.shape not in ((), (chain.n_joints,)):
        raise InputError(
            f"posture must be a gain from 0 to 1, or {chain.n_joints} of them (one per joint), "
            f"got {posture!r:.60}"
        )
    if options.max_total_iterations is not None:
        raise InputError("max_total_iterations is for JAX and PyTorch; a posture solve is NumPy")
    tree = chain_tree(chain)
    frame = tree.site_names[0]
    found = solve(
        tree,
        {frame: T},
        q0,
        hold=None,
        position_only={frame} if options.position_only else None,
        orientation_only=None,
        weights=None,
        posture=arr,
        freeze=(),
        seed=seed,
        options=options,
    )
    pos, ori = found.frame_errors[frame]
    return IKResult(found.qpos, found.success, pos, ori, found.iterations, found.attempts)
