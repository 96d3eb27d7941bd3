"""Inverse kinematics of one frame of a tree: :meth:`poekin.Tree.ik`.

The solve runs over the hinge and slide joints on the path from the world to the frame; every
other joint is held at ``qpos``. A ball or free joint on the path (a floating base) is held
too: the chain then starts at the body it moves (:meth:`poekin.Tree.chain` with ``base``), and
each target is brought into that body's frame, ``T_base_target = T_world_base(qpos)^-1 T``,
before the chain's solve (:func:`poekin.ik.numerical.solve`). The answer is the whole ``qpos``.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import arrays, lie
from poekin.errors import InputError
from poekin.ik.numerical import IKResult, Settings, broadcast_together, check_targets, solve

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.tree import Tree

__all__ = ["TreePlan", "plan", "solve_tree"]

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True)
class TreePlan:
    """How a tree's frame is solved for: the chain of its free joints, from ``base`` (a body
    held by a ball or free joint, or None for the world), and where they are in ``qpos``."""

    chain: Chain
    base: str | None
    indices: tuple[int, ...]


def plan(tree: Tree, frame: str) -> TreePlan:
    """The :class:`TreePlan` of ``frame`` (kept with the tree after the first call).

    Raises:
        UnknownFrameError: no such frame.
        InputError: a mimic joint on the path (its value is tied to another joint's: this
            solver moves independent joints only), a ball or free joint after a hinge or
            slide on the path, or no hinge or slide joint to solve for.
    """
    cache = tree._ik_cache
    if frame not in cache:
        cache[frame] = _plan(tree, frame)
    found: TreePlan = cache[frame]
    return found


def _plan(tree: Tree, frame: str) -> TreePlan:
    joints = tree.path_joints(frame)
    names = tree.joint_names
    for k in joints:
        mimic = tree.mimics[k]
        if mimic is not None:
            raise InputError(
                f"joint {names[k]!r} on the path to {frame!r} mimics {mimic.leader!r}: Tree.ik "
                "moves independent joints only; solve tree.chain(frame) with chain.ik, which "
                "treats every joint as independent, or choose a frame whose path has no mimic"
            )
    held = [i for i, k in enumerate(joints) if tree.joint_types[k] in ("ball", "free")]
    last = held[-1] if held else -1
    for k in joints[: last + 1]:
        if tree.joint_types[k] in ("revolute", "prismatic"):
            raise InputError(
                f"joint {names[joints[last]]!r} ({tree.joint_types[joints[last]]}) follows the "
                f"hinge or slide joint {names[k]!r} on the path to {frame!r}: Tree.ik solves "
                "the hinge and slide joints below the last ball or free joint only"
            )
    if last == len(joints) - 1:
        raise InputError(f"no hinge or slide joint on the path to {frame!r}: nothing to solve")
    base = None if last < 0 else tree.body_names[int(tree.joint_bodies[joints[last]])]
    chain = tree.chain(frame, base=base)
    assert chain.qpos_indices is not None  # no mimic joint on the path
    return TreePlan(chain, base, chain.qpos_indices)


def solve_tree(
    tree: Tree,
    T: ArrayLike,
    frame: str,
    qpos: ArrayLike | None,
    *,
    warm_start: bool,
    seed: int,
    options: Settings,
    collision: tuple[tuple[Any, ...], float, tuple[Any, ...]] | None = None,
) -> IKResult:
    """:meth:`poekin.Tree.ik`; ``collision``: ``(obstacles, margin, ignore)`` of
    ``avoid=True`` (:mod:`poekin.ik.collision_free`), validated."""
    how = plan(tree, frame)
    if arrays.namespace_of([T, qpos], "targets and qpos")[1] is not None:
        raise InputError(
            "Tree.ik takes NumPy arrays; for JAX arrays or PyTorch tensors, solve "
            "tree.chain(frame) with chain.ik (targets in the chain's base frame)"
        )
    if not isinstance(warm_start, bool | np.bool_):
        raise InputError(f"warm_start must be True or False, got {warm_start!r:.40}")
    q = tree.qpos0 if qpos is None else tree._as_qpos(qpos)
    targets, q = broadcast_together(check_targets(T), q, "qpos")
    if how.base is not None:
        targets = lie.inverse(tree.pose(q, how.base)) @ targets
    start: Any = q[..., list(how.indices)] if warm_start else None
    if collision is None:
        found = solve(how.chain, np.ascontiguousarray(targets), start, seed=seed, options=options)
    else:
        from poekin.ik import collision_free

        joints = [tree.joint_names.index(name) for name in how.chain.joint_names]
        scene = collision_free.Scene(
            tree,
            how.indices,
            tuple(int(tree._dof_adr[k]) for k in joints),
            *collision,
        )
        found = collision_free.solve(
            how.chain,
            np.ascontiguousarray(targets),
            start,
            q,
            seed=seed,
            options=options,
            scene=scene,
        )
    out = np.array(q, dtype=np.float64)  # a copy, every other joint as given
    out[..., list(how.indices)] = found.q
    return dataclasses.replace(found, q=out)
