"""A chain's IK with a posture: :meth:`poekin.Chain.ik` with ``posture=``.

A redundant arm (seven joints for a six-number pose) reaches a target along a family of
configurations; a posture picks the one nearest a preferred configuration. The chain is
solved as a tree (:meth:`poekin.Chain.as_tree`, whose FK is the chain's product of
exponentials) by :func:`poekin.wholebody.solve`, the posture its level 3: the pull toward
``q0``, per joint, in the null space of the target.
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


def chain_tree(chain: Chain) -> Tree:
    """The tree whose FK of ``q`` puts its site ``chain.frame`` at ``chain.fk(q)``:
    :meth:`poekin.Chain.as_tree` (kept with the chain)."""
    tree: Tree = chain.as_tree()
    return tree


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
            f"posture must be a weight >= 0, or {chain.n_joints} of them (one per joint), "
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
