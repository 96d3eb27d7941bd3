"""What a whole-body solve is asked: frames, their targets, their modes, weights and holds.

A target is given per frame, a body or site name of the tree (or ``"com"``, the whole
robot's centre of mass): a ``(..., 4, 4)`` pose ``T_world_frame``, or for a frame placed by
position only a ``(..., 3)`` point (a pose is accepted too: its translation is used), or for
a frame placed by orientation only a ``(..., 3, 3)`` rotation (or a pose: its rotation block).
Every target broadcasts against the others and against ``qpos``'s batch axes.

Each task contributes rows to the residual, in world coordinates, as
:mod:`poekin.ik.numerical` defines them for one frame: ``k e_o`` (three rows, ``k`` the
orientation weight in m/rad) and ``e_p`` (three rows, m), with their Jacobian as it does (the
exact derivative of ``e_o``, :func:`poekin.ik.numerical.jacobian_rows`). A soft task's rows are
multiplied by ``sqrt(weight)``, so that its cost is ``weight |r|^2``. Held tasks are
constraints and have no weight.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import InputError, UnknownFrameError, did_you_mean
from poekin.ik.numerical import check_targets
from poekin.kernel._fast import rigid_targets

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = ["COM", "Mode", "Task", "Tasks", "parse"]

FloatArray = NDArray[np.float64]
Mode = Literal["pose", "position", "orientation"]

COM = "com"  # the name of the centre-of-mass task
_ROWS: dict[str, int] = {"pose": 6, "position": 3, "orientation": 3}


@dataclasses.dataclass(frozen=True)
class Task:
    """One frame's target.

    Attributes:
        name: the frame's name (``"com"`` for the centre of mass).
        index: the frame's index in :attr:`poekin.Tree.frame_names`, -1 for the CoM.
        mode: ``"pose"``, ``"position"`` or ``"orientation"``.
        held: a constraint (met exactly) rather than a weighted least-squares term.
        weight: the cost's factor for a soft task (1 for a held one).
        R: ``(..., 3, 3)`` the target rotation (the identity where unused).
        p: ``(..., 3)`` the target position (m; zeros where unused).
    """

    name: str
    index: int
    mode: Mode
    held: bool
    weight: float
    R: FloatArray
    p: FloatArray

    @property
    def rows(self) -> int:
        """Residual rows: 6 for a pose, 3 for a position or an orientation."""
        return _ROWS[self.mode]


@dataclasses.dataclass(frozen=True)
class Tasks:
    """Every task of a solve, held ones first, with the batch shape of their targets."""

    tasks: tuple[Task, ...]
    batch: tuple[int, ...]


def _names(value: object, what: str) -> frozenset[str]:
    if value is None:
        return frozenset()
    if isinstance(value, str):
        return frozenset({value})
    if not isinstance(value, Collection) or not all(isinstance(v, str) for v in value):
        raise InputError(f"{what} must be a frame name or a collection of names, got {value!r:.60}")
    return frozenset(value)


def _check_known(names: Collection[str], targets: Mapping[str, Any], what: str) -> None:
    for name in sorted(names):
        if name not in targets:
            raise InputError(
                f"{what} names {name!r}, which has no target: "
                f"{did_you_mean(name, list(targets))}; give it a target too"
            )


def _frame_index(tree: Tree, name: str) -> int:
    if name == COM:
        return -1
    try:
        return tree.frame_index(name)
    except UnknownFrameError:
        raise UnknownFrameError(
            f"no site or body named {name!r} to place: "
            f"{did_you_mean(name, [*tree.frame_names, COM])} (or {COM!r}, the centre of mass)"
        ) from None


def _finite(arr: FloatArray, name: str) -> FloatArray:
    if not np.all(np.isfinite(arr)):
        raise InputError(f"the target of {name!r} contains NaN or inf; every entry must be finite")
    return arr


def _target(value: ArrayLike, name: str, mode: Mode) -> tuple[FloatArray, FloatArray]:
    """``(R, p)`` of one frame's target, validated for its mode."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(
            f"the target of {name!r} must be an array of numbers, got {type(value).__name__}"
        ) from None
    shape = arr.shape
    if shape[-2:] == (4, 4):
        # a plain pose of a control tick: the kernel's one pass (check_targets' own fast path)
        T = arr if rigid_targets(arr) else _checked(_finite(arr, name), name)
        R, p = T[..., :3, :3], T[..., :3, 3]
        if mode == "position":
            R = np.broadcast_to(np.eye(3), R.shape)
        elif mode == "orientation":
            p = np.zeros(p.shape)
        return R, p
    if mode == "position" and shape[-1:] == (3,):
        return np.broadcast_to(np.eye(3), (*shape[:-1], 3, 3)), _finite(arr, name)
    if mode == "orientation" and shape[-2:] == (3, 3):
        T = np.zeros((*shape[:-2], 4, 4))
        T[..., :3, :3] = _finite(arr, name)
        T[..., 3, 3] = 1.0
        return _checked(T, name)[..., :3, :3], np.zeros((*shape[:-2], 3))
    wanted = {
        "pose": "(..., 4, 4)",
        "position": "(..., 3) or a pose (..., 4, 4)",
        "orientation": "(..., 3, 3) or a pose (..., 4, 4)",
    }[mode]
    raise InputError(f"the target of {name!r} ({mode}) must have shape {wanted}, got {shape}")


def _checked(T: FloatArray, name: str) -> FloatArray:
    """:func:`poekin.ik.numerical.check_targets` of frame ``name``'s target, its message
    naming the frame."""
    try:
        return check_targets(T)
    except InputError as e:
        raise InputError(f"the target of {name!r}{str(e).removeprefix('target')}") from None


def _weight(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InputError(f"the weight of {name!r} must be a number > 0, got {value!r:.40}")
    w = float(value)
    if not (math.isfinite(w) and w > 0):
        raise InputError(f"the weight of {name!r} must be a finite number > 0, got {w!r}")
    return w


def parse(
    tree: Tree,
    targets: Mapping[str, ArrayLike],
    *,
    hold: object = None,
    position_only: object = None,
    orientation_only: object = None,
    weights: Mapping[str, float] | None = None,
) -> Tasks:
    """The validated :class:`Tasks` of a solve.

    Raises:
        UnknownFrameError: a target for a frame the tree lacks (the message suggests one).
        InputError: no target; ``hold``, ``position_only``, ``orientation_only`` or ``weights``
            naming a frame without a target, a frame both position and orientation only, a
            held frame given a weight, a target of the wrong shape, NaN or inf, or targets
            whose batch shapes do not broadcast.
    """
    if not isinstance(targets, Mapping) or not targets:
        raise InputError(
            "targets must be a non-empty dict of frame name to target, e.g. "
            "{'left_foot': T_left_foot}"
        )
    for name in targets:
        if not isinstance(name, str):
            raise InputError(f"target names must be frame names (str), got {name!r:.40}")
    # the targets' frames first: a misspelt one is named with the tree's frames to choose
    # from, before hold and the others are checked against the targets' names
    indices = {name: _frame_index(tree, name) for name in targets}
    held = _names(hold, "hold")
    by_position = _names(position_only, "position_only")
    by_orientation = _names(orientation_only, "orientation_only")
    weights = {} if weights is None else weights
    if not isinstance(weights, Mapping):
        raise InputError(f"weights must be a dict of frame name to weight, got {weights!r:.60}")
    for names, what in (
        (held, "hold"),
        (by_position, "position_only"),
        (by_orientation, "orientation_only"),
        (weights.keys(), "weights"),
    ):
        _check_known(names, targets, what)
    both = sorted(by_position & by_orientation)
    if both:
        raise InputError(
            f"{both[0]!r} is both position_only and orientation_only: give it a pose target "
            "instead, or keep one of the two"
        )
    weighted_held = sorted(held & set(weights))
    if weighted_held:
        raise InputError(
            f"{weighted_held[0]!r} is held (a constraint, met exactly) and also given a "
            "weight (a soft target): drop it from hold or from weights"
        )
    tasks = []
    for name, value in targets.items():
        index = indices[name]
        mode: Mode = (
            "position"
            if name in by_position or index < 0
            else "orientation"
            if name in by_orientation
            else "pose"
        )
        if index < 0 and name in by_orientation:
            raise InputError(f"{COM!r} is a point: it has no orientation to place")
        R, p = _target(value, name, mode)
        tasks.append(
            Task(name, index, mode, name in held, _weight(weights.get(name, 1.0), name), R, p)
        )
    try:
        batch = np.broadcast_shapes(*(t.p.shape[:-1] for t in tasks))
    except ValueError:
        shapes = ", ".join(f"{t.name}: {t.p.shape[:-1]}" for t in tasks)
        raise InputError(f"the targets' batch shapes do not broadcast ({shapes})") from None
    ordered = tuple(sorted(tasks, key=lambda t: not t.held))  # stable: held first
    return Tasks(ordered, tuple(batch))
