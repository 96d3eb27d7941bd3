"""The viewer's IK mode: what the scene shows for a target pose of the end frame, pure
computation on poekin's own IK and FK (no viser), so it is tested without a browser.

A target ``T_world_target`` is solved from the configuration shown (:func:`reach`): the arm
moves there if it can and stays on its branch, or shows its best fit and the residual.

* **The solve.** :meth:`Chain.ik <poekin.chain.Chain.ik>` for a bare parameter set,
  :meth:`Tree.ik <poekin.tree.Tree.ik>` over the joints on the path to the end frame for a
  tree (every other joint, a floating base included, held). The first attempt starts at the
  configuration shown, so a dragged target moves the arm continuously. If that attempt fails,
  the solver restarts from seeded random configurations (the target may need another branch:
  a joint limit in the way); if those fail too, the target is out of reach and the arm shows
  the first attempt's best fit (it stays where the drag led it rather than jumping to another
  branch's fit).
* **Every solution.** Where the chain's geometry admits a closed form
  (:meth:`Chain.ik_all <poekin.chain.Chain.ik_all>`), each of its valid solutions is a ghost
  arm to pick; a reachable target the numerical solve missed takes the one nearest the
  configuration shown.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.errors import AnalyticIKError, InputError
from poekin.ik import IKResult
from poekin.ik.numerical import check_targets
from poekin.verification.verify import pose_errors
from poekin.viewer.scene import Subject, joint_anchors, link_frames, snapshot_base

__all__ = [
    "IKSupport",
    "Reach",
    "end_pose",
    "follow",
    "ghost_poses",
    "pick",
    "reach",
    "same_configuration",
    "support",
]

FloatArray = NDArray[np.float64]
How = Literal["current", "restart", "analytic", "best fit", "follow", "picked"]

#: Revolute angles (rad) and slides (m) closer than this are one configuration.
SAME_Q_TOL = 1e-6


@dataclasses.dataclass(frozen=True)
class IKSupport:
    """Whether the IK mode works for a subject's end frame.

    Attributes:
        numerical: None when the numerical solve applies, else why not (one line, e.g. a
            mimic joint on the path, or no joint to move).
        analytic: None when :meth:`~poekin.chain.Chain.ik_all` applies (its ghosts are
            shown), else why not: the :class:`~poekin.errors.AnalyticIKError`'s message.
    """

    numerical: str | None
    analytic: str | None

    @property
    def available(self) -> bool:
        """Whether the IK mode can be turned on."""
        return self.numerical is None


def support(subject: Subject) -> IKSupport:
    """Which solves apply to the subject's end frame (read from its joints and screws)."""
    from poekin.ik.analytic import geometry
    from poekin.ik.trees import plan

    numerical = None
    if subject.n_joints == 0:
        numerical = f"no hinge or slide joint moves {subject.frame!r}: nothing to solve"
    elif subject.tree is not None:
        try:
            plan(subject.tree, subject.frame)
        except InputError as exc:
            numerical = str(exc)
    analytic = numerical
    if analytic is None:
        try:
            geometry(subject.chain)
        except AnalyticIKError as exc:
            analytic = str(exc)
    return IKSupport(numerical, analytic)


@dataclasses.dataclass(frozen=True, eq=False)
class Reach:
    """What the scene shows for a target.

    Attributes:
        target: ``(4, 4)`` ``T_world_target``, the pose asked of the end frame.
        qpos: ``(nq,)`` the configuration shown (MuJoCo's layout; a bare chain: its joint
            values), within the joint limits: the solution, or the best fit.
        success: the end frame reaches the target (1e-10 m and 1e-10 rad, position only
            with ``position_only``).
        pos_err: distance from the end frame at ``qpos`` to the target (m).
        ori_err: geodesic angle between their rotations (rad).
        how: ``"current"``: the first attempt, from the configuration shown, succeeded;
            ``"restart"``: a restart from a random configuration did; ``"analytic"``: the
            closed-form solution nearest the configuration shown; ``"best fit"``: out of reach,
            the first attempt's least-squares fit; ``"follow"``: the target was put at the end
            frame (:func:`follow`); ``"picked"``: a closed-form solution picked (:func:`pick`).
        solutions: ``(m, nq)`` each valid closed-form solution as a whole configuration (the
            joints off the path as in ``qpos``), each once; ``(0, nq)`` where there is none,
            or no closed form.
        current: the index in ``solutions`` of ``qpos``'s configuration (angles equal up to
            whole turns), or -1.
    """

    target: FloatArray
    qpos: FloatArray
    success: bool
    pos_err: float
    ori_err: float
    how: How
    solutions: FloatArray
    current: int

    @property
    def ghosts(self) -> list[int]:
        """Indices in :attr:`solutions` drawn as ghost arms: all but the one shown."""
        return [k for k in range(len(self.solutions)) if k != self.current]


def _chain_slots(subject: Subject) -> list[int]:
    """Where the chain's joint values sit in ``qpos``."""
    if subject.tree is None:
        return list(range(subject.n_joints))
    assert subject.chain.qpos_indices is not None  # support() refused mimic joints
    return list(subject.chain.qpos_indices)


def same_configuration(subject: Subject, a: ArrayLike, b: ArrayLike) -> NDArray[np.bool_]:
    """``(...,)`` whether chain joint values ``a`` and ``b`` (``(..., n)``, broadcast) are one
    configuration: revolute angles equal up to whole turns, slides equal, within
    :data:`SAME_Q_TOL`."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    revolute = np.array([t == "revolute" for t in subject.chain.joint_types])
    d = np.where(revolute, np.angle(np.exp(1j * d)), d)
    same: NDArray[np.bool_] = np.all(np.abs(d) <= SAME_Q_TOL, axis=-1)
    return same


def _analytic(subject: Subject, x: FloatArray, target: FloatArray) -> FloatArray:
    """``(m, nq)`` the valid closed-form solutions for ``target``, each once, as ``x`` with the
    chain's joints replaced."""
    chain = subject.chain
    in_base = np.asarray(lie.inverse(snapshot_base(subject, x)), dtype=np.float64) @ target
    found = chain.ik_all(in_base)
    q = found.q[found.valid]
    earlier = np.tril(same_configuration(subject, q[:, None], q[None, :]), -1)
    keep = q[~earlier.any(axis=1)]  # each configuration once: the first of its repeats
    out = np.tile(x, (len(keep), 1))
    out[:, _chain_slots(subject)] = keep
    return out


def _current(subject: Subject, solutions: FloatArray, x: FloatArray) -> int:
    slots = _chain_slots(subject)
    same = np.flatnonzero(same_configuration(subject, solutions[:, slots], x[slots]))
    return int(same[0]) if same.size else -1


def _solve(
    subject: Subject, x: FloatArray, target: FloatArray, position_only: bool, attempts: int
) -> IKResult:
    """Chain.ik or Tree.ik from ``x``; ``q`` the whole configuration."""
    if subject.tree is None:
        return subject.chain.ik(
            target, x, position_only=position_only, max_attempts=attempts, seed=0
        )
    if subject.tool is not None:  # the tree solves for the frame that carries the tool
        target = target @ np.asarray(lie.inverse(subject.tool), dtype=np.float64)
    found: IKResult = subject.tree.ik(
        target,
        subject.frame,
        x,
        warm_start=True,
        position_only=position_only,
        max_attempts=attempts,
        seed=0,
    )
    return found


def reach(
    subject: Subject,
    qpos: ArrayLike,
    T_world_target: ArrayLike,
    *,
    position_only: bool = False,
    ik_support: IKSupport | None = None,
) -> Reach:
    """Solve for ``T_world_target`` ``(4, 4)`` from the configuration ``qpos`` ``(nq,)`` (see
    the module docstring). ``ik_support`` is :func:`support` of the subject (computed if
    None). With ``position_only`` the closed form is not used (it needs a whole pose).

    Raises:
        InputError: the IK mode does not apply to the subject (the reason), ``qpos`` of the
            wrong length, or a target that is not a finite rigid transform.
    """
    ok = support(subject) if ik_support is None else ik_support
    if ok.numerical is not None:
        raise InputError(f"no IK for {subject.frame!r}: {ok.numerical}")
    x = subject.check_qpos(qpos)
    target = check_targets(T_world_target)
    if target.shape != (4, 4):
        raise InputError(f"one target pose (4, 4), got shape {target.shape}")
    found = _solve(subject, x, target, position_only, 1)
    how: How = "current"
    if not bool(found.success):
        again = _solve(subject, x, target, position_only, 100)
        how = "restart" if bool(again.success) else "best fit"
        found = again if again.success else found
    shown = np.asarray(found.q, dtype=np.float64)
    solutions = np.zeros((0, subject.nq))
    if ok.analytic is None and not position_only:
        solutions = _analytic(subject, x, target)
        if how == "best fit" and len(solutions):
            slots = _chain_slots(subject)
            nearest = np.argmin(np.sum((solutions[:, slots] - x[slots]) ** 2, axis=-1))
            shown, how = solutions[nearest], "analytic"
    return _result(subject, target, shown, how, solutions, position_only)


def follow(
    subject: Subject,
    qpos: ArrayLike,
    *,
    position_only: bool = False,
    ik_support: IKSupport | None = None,
) -> Reach:
    """The target put at the end frame of the configuration ``qpos``: reached, by ``qpos``
    itself, with the closed-form solutions of that pose (how the IK mode follows the sliders)."""
    ok = support(subject) if ik_support is None else ik_support
    x = subject.check_qpos(qpos)
    target = end_pose(subject, x)
    solutions = np.zeros((0, subject.nq))
    if ok.available and ok.analytic is None and not position_only:
        solutions = _analytic(subject, x, target)
    return _result(subject, target, x, "follow", solutions, position_only)


def pick(subject: Subject, reached: Reach, index: int) -> Reach:
    """The same target shown at its closed-form solution ``index`` (of ``reached.solutions``).

    Raises:
        InputError: no such solution; the message gives their number.
    """
    m = len(reached.solutions)
    if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < m:
        have = f"0..{m - 1}" if m else "none: no closed form here, or no solution within the limits"
        raise InputError(f"no closed-form solution {index!r}: the solutions are {have}")
    x = reached.solutions[int(index)]
    return _result(subject, reached.target, x, "picked", reached.solutions, False)


def _result(
    subject: Subject,
    target: FloatArray,
    x: FloatArray,
    how: How,
    solutions: FloatArray,
    position_only: bool,
) -> Reach:
    T = end_pose(subject, x)
    pos, ori = pose_errors(target, T)
    reached = float(pos) <= 1e-10 and (position_only or float(ori) <= 1e-10)
    return Reach(
        target=np.array(target, dtype=np.float64),
        qpos=np.array(x, dtype=np.float64),
        success=how != "best fit" and reached,
        pos_err=float(pos),
        ori_err=float(ori),
        how=how,
        solutions=solutions,
        current=_current(subject, solutions, x) if len(solutions) else -1,
    )


def ghost_poses(subject: Subject, solutions: FloatArray) -> tuple[FloatArray, FloatArray]:
    """World poses of the bodies ``(m, nb, 4, 4)`` (of :attr:`Subject.body_names`) and the
    joints' anchors ``(m, n, 3)`` at each of the ``(m, nq)`` configurations."""
    x = np.asarray(solutions, dtype=np.float64).reshape(-1, subject.nq)
    if subject.tree is not None:
        bodies = subject.tree.fk(x)[:, : len(subject.body_names)]
    else:
        links = [link_frames(subject.chain, q)[1] for q in x]
        bodies = np.array(links, dtype=np.float64).reshape(len(x), subject.n_joints + 1, 4, 4)
    return bodies, joint_anchors(subject, bodies)


def end_pose(subject: Subject, qpos: FloatArray) -> FloatArray:
    """``(4, 4)`` the end frame's world pose at ``qpos``: ``T_world_base chain.fk(q)``."""
    T = snapshot_base(subject, qpos) @ subject.chain.fk(subject.chain_q(qpos))
    return np.asarray(T, dtype=np.float64)
