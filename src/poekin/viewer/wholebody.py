"""The viewer's whole-body IK mode: a handle on each of several frames of a tree, and the whole
robot solved by :meth:`Tree.ik <poekin.tree.Tree.ik>` with a dict of targets when one is
dragged. Pure computation (no viser), so it is tested without a browser.

* **The targets.** Each chosen frame has a target, at first its own pose. A drag of one handle
  (:func:`drag`) asks for every frame at once: the dragged frame at the handle's new pose, the
  others at their current targets, the held frames (``hold``, contacts such as the feet) as
  constraints met exactly.
* **The solve.** The first attempt starts at the configuration shown (one attempt: a small
  drag is solved in a few iterations, so the robot moves continuously). If it misses, a few more
  attempts (:data:`RESTART_ATTEMPTS`, a drag stays interactive) start from the first one's fit
  and from drawn configurations; if they miss too, the robot shows the first attempt's best fit:
  the held frames met, the others as near as they get, the robot where the drag led it rather
  than on another branch's fit.
* **Anything else** that changes the configuration (a slider, ``viewer.q``) puts every target
  back at its frame (:func:`follow`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import HeldFramesError, InputError, UnknownFrameError, did_you_mean
from poekin.ik.numerical import check_targets
from poekin.verification.verify import pose_errors

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = [
    "ORIENTATION_WEIGHT",
    "RESTART_ATTEMPTS",
    "TOL",
    "Handles",
    "WholeBodyReach",
    "check_handles",
    "drag",
    "follow",
    "solve",
    "targets_after_drag",
]

FloatArray = NDArray[np.float64]
How = Literal["follow", "current", "restart", "best fit"]

#: Attempts of the second solve, after the first attempt from the configuration shown missed:
#: the first attempt's fit again, then drawn starts. Few, so that a drag past the robot's reach
#: stays interactive (each drawn attempt of the G1's four frames takes some 0.1 to 1 s).
RESTART_ATTEMPTS = 2
#: A frame is reached within this (m and rad): :meth:`Tree.ik`'s default tolerances.
TOL = 1e-10
#: Metres per radian when the frames' errors are compared (the worst frame): the solver's own.
ORIENTATION_WEIGHT = 0.3


@dataclasses.dataclass(frozen=True)
class Handles:
    """The frames with a handle (bodies or sites of the tree, in the order given) and those of
    them that are held (met exactly: contacts), in the same order."""

    frames: tuple[str, ...]
    hold: tuple[str, ...]

    @property
    def soft(self) -> tuple[str, ...]:
        """The frames that are not held: weighted least squares below the held ones."""
        return tuple(f for f in self.frames if f not in self.hold)


def _names(names: str | Collection[str] | None, what: str) -> list[str]:
    if names is None:
        return []
    if isinstance(names, str):  # "a,b": empty pieces ("a,", "") name nothing
        names = [n.strip() for n in names.split(",") if n.strip()]
    out = list(names)
    for name in out:
        if not isinstance(name, str) or not name:
            raise InputError(f"{what}: frame names, got {name!r}")
    twice = sorted({n for n in out if out.count(n) > 1})
    if twice:
        raise InputError(f"{what} names {twice[0]!r} twice: give each frame once")
    return out


def check_handles(
    tree: Tree, frames: str | Collection[str], hold: str | Collection[str] | None = None
) -> Handles:
    """The frames to put handles on (names, or one comma-separated string) and the held ones,
    checked against the tree.

    Raises:
        UnknownFrameError: a frame the tree does not have; the message suggests the nearest.
        InputError: no frame, a frame given twice, a held frame that has no handle.
    """
    names = _names(frames, "frames")
    if not names:
        raise InputError("whole-body IK needs at least one frame to put a handle on")
    valid = list(tree.frame_names)
    for name in names:
        if name not in valid:
            raise UnknownFrameError(
                f"whole-body IK: no site or body named {name!r}: {did_you_mean(name, valid)}"
            )
    held = _names(hold, "hold")
    for name in held:
        if name not in names:
            chosen = ", ".join(repr(n) for n in names)
            raise InputError(
                f"held frame {name!r} has no handle: hold names some of the frames ({chosen})"
            )
    return Handles(tuple(names), tuple(n for n in names if n in held))


@dataclasses.dataclass(frozen=True, eq=False)
class WholeBodyReach:
    """What the scene shows in the whole-body IK mode.

    Attributes:
        handles: the frames with a handle and the held ones.
        targets: frame name to ``(4, 4)`` ``T_world_target``, one per handle, in its order.
        qpos: ``(nq,)`` the configuration shown (MuJoCo's layout), within the joint limits.
        success: every frame within :data:`TOL` (m and rad) of its target.
        frame_errors: frame name to ``(pos_err, ori_err)`` at ``qpos`` (m, rad), from
            :meth:`Tree.fk <poekin.tree.Tree.fk>`, in the handles' order.
        how: ``"follow"``: the targets were put at the frames (:func:`follow`); ``"current"``:
            the first attempt, from the configuration shown, reached them; ``"restart"``: a
            further attempt did; ``"best fit"``: missed, the first attempt's best fit (the held
            frames met whenever they can be).
        attempts: attempts run (0 for ``"follow"``).
        iterations: their iterations (not those of a first attempt that missed the held
            frames, which :meth:`Tree.ik` does not report).
    """

    handles: Handles
    targets: dict[str, FloatArray]
    qpos: FloatArray
    success: bool
    frame_errors: dict[str, tuple[float, float]]
    how: How
    attempts: int
    iterations: int

    @property
    def worst(self) -> tuple[str, float, float]:
        """The frame farthest from its target (position plus :data:`ORIENTATION_WEIGHT` times
        the angle), with its ``(pos_err, ori_err)``; the first frame where all are equal."""
        name = max(
            self.handles.frames,
            key=lambda f: self.frame_errors[f][0] + ORIENTATION_WEIGHT * self.frame_errors[f][1],
        )
        return (name, *self.frame_errors[name])

    @property
    def held_error(self) -> float:
        """The largest error (m or rad) of a held frame; 0 without held frames."""
        return max((max(self.frame_errors[f]) for f in self.handles.hold), default=0.0)

    def missed(self, frame: str) -> bool:
        """Whether ``frame`` is farther than :data:`TOL` from its target."""
        return max(self.frame_errors[frame]) > TOL


def _result(
    tree: Tree,
    handles: Handles,
    targets: Mapping[str, FloatArray],
    x: FloatArray,
    how: How,
    attempts: int = 0,
    iterations: int = 0,
) -> WholeBodyReach:
    poses = tree.fk(x)
    errors = {}
    for frame in handles.frames:
        pos, ori = pose_errors(targets[frame], poses[tree.frame_index(frame)])
        errors[frame] = (float(pos), float(ori))
    reached = all(max(e) <= TOL for e in errors.values())
    return WholeBodyReach(
        handles=handles,
        targets={f: np.array(targets[f], dtype=np.float64) for f in handles.frames},
        qpos=np.array(x, dtype=np.float64),
        success=how != "best fit" and reached,
        frame_errors=errors,
        how=how,
        attempts=attempts,
        iterations=iterations,
    )


def _qpos(tree: Tree, qpos: ArrayLike) -> FloatArray:
    x = np.asarray(qpos, dtype=np.float64)
    if x.shape != (tree.nq,):
        raise InputError(f"qpos must have shape ({tree.nq},), got {x.shape}")
    return x


def follow(tree: Tree, handles: Handles, qpos: ArrayLike) -> WholeBodyReach:
    """Every target at its frame's pose at ``qpos`` ``(nq,)``: reached, by ``qpos`` itself."""
    x = _qpos(tree, qpos)
    poses = tree.fk(x)
    targets = {f: poses[tree.frame_index(f)] for f in handles.frames}
    return _result(tree, handles, targets, x, "follow")


def solve(
    tree: Tree, handles: Handles, qpos: ArrayLike, targets: Mapping[str, ArrayLike]
) -> WholeBodyReach:
    """Solve for ``targets`` (a ``(4, 4)`` pose for every handle's frame) from ``qpos``
    ``(nq,)``, as the module's docstring says.

    Raises:
        InputError: ``qpos`` of the wrong length, a target missing, not a frame of the handles,
            or not a rigid transform.
        HeldFramesError: no attempt met the held frames' targets together (an InputError):
            the first attempt's miss is retried, the further attempts' is raised.
    """
    x = _qpos(tree, qpos)
    extra = sorted(set(targets) - set(handles.frames))
    if extra:
        raise InputError(f"a target for {extra[0]!r}, which has no handle")
    asked = {}
    for frame in handles.frames:
        if frame not in targets:
            raise InputError(f"no target for {frame!r}: every handle's frame needs one")
        T = check_targets(targets[frame])
        if T.shape != (4, 4):
            raise InputError(f"the target of {frame!r} is one pose (4, 4), got shape {T.shape}")
        asked[frame] = T
    hold = set(handles.hold)
    try:
        first = tree.ik(asked, x, hold=hold, max_attempts=1, seed=0)
    except HeldFramesError:  # missed from here: the further attempts may meet them
        first = None
    attempts, iterations = 1, 0
    if first is not None:
        iterations = int(first.iterations)
        if bool(first.success):
            return _result(tree, handles, asked, first.qpos, "current", attempts, iterations)
    start = x if first is None else first.qpos
    again = tree.ik(asked, start, hold=hold, max_attempts=RESTART_ATTEMPTS, seed=0)
    attempts += int(again.attempts)
    iterations += int(again.iterations)
    if bool(again.success):
        return _result(tree, handles, asked, again.qpos, "restart", attempts, iterations)
    fit = again.qpos if first is None else first.qpos
    return _result(tree, handles, asked, fit, "best fit", attempts, iterations)


def targets_after_drag(
    shown: WholeBodyReach, frame: str, T_world_target: ArrayLike
) -> dict[str, FloatArray]:
    """The targets a drag of ``frame``'s handle to ``T_world_target`` ``(4, 4)`` asks for: that
    frame's new pose, every other frame's current target.

    Raises:
        InputError: ``frame`` has no handle, or the pose is not a rigid transform.
    """
    if frame not in shown.handles.frames:
        raise InputError(f"no handle on {frame!r}: {did_you_mean(frame, shown.handles.frames)}")
    T = check_targets(T_world_target)
    if T.shape != (4, 4):
        raise InputError(f"one target pose (4, 4), got shape {T.shape}")
    targets = {f: shown.targets[f].copy() for f in shown.handles.frames}
    targets[frame] = T
    return targets


def drag(
    tree: Tree, shown: WholeBodyReach, frame: str, T_world_target: ArrayLike
) -> WholeBodyReach:
    """A drag of ``frame``'s handle to ``T_world_target``: every frame solved for at once, from
    the configuration shown (:func:`targets_after_drag`, :func:`solve`)."""
    targets = targets_after_drag(shown, frame, T_world_target)
    return solve(tree, shown.handles, shown.qpos, targets)
