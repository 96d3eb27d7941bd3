"""The viewer's playback of a trajectory (``poekin view --play traj.npz``): pure computation
(no viser), so it is tested without a browser.

* **The match.** A :class:`~poekin.io.trajectory.Trajectory` plays on the robot shown when its
  columns are that robot's configuration: the tree's whole ``qpos`` (the names, where the file
  has them, those of :func:`~poekin.io.trajectory.qpos_column_names`), or the joint values of
  the chain to the end frame (its joint names), the other joints at ``qpos0``. Anything else
  is refused with one line that says what the file holds and what the robot takes
  (:func:`playback_of`).
* **A time.** :meth:`Playback.qpos_at` interpolates between the two samples around any time
  (linearly; a ball or free joint's quaternion normalised after, the shorter way round), held
  at the ends.
* **The trace.** :func:`tool_trace` is the end frame's position at every sample: the polyline
  the viewer draws.
* **Real time.** A :class:`Clock` turns wall-clock seconds into trajectory time: play, pause,
  seek, and a stop at the end (play again starts over).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from poekin.errors import InputError
from poekin.io.trajectory import Trajectory, qpos_column_names

if TYPE_CHECKING:
    from poekin.viewer.scene import Subject

__all__ = ["Clock", "Playback", "playback_of", "tool_trace"]

FloatArray = NDArray[np.float64]


@dataclasses.dataclass(frozen=True, eq=False)
class Playback:
    """A trajectory as the robot shown plays it.

    Attributes:
        trajectory: the trajectory, as given.
        qpos: ``(K, nq)`` each sample as the subject's configuration (MuJoCo's ``qpos``
            layout; a bare chain: its joint values).
        quats: where each ball or free joint's quaternion starts in ``qpos`` (4 numbers each).
        what: what the columns were read as: ``"qpos"`` or ``"chain"``.
    """

    trajectory: Trajectory
    qpos: FloatArray
    quats: tuple[int, ...]
    what: str

    @property
    def t(self) -> FloatArray:
        """``(K,)`` the sample times, s."""
        return self.trajectory.t

    @property
    def start(self) -> float:
        """The first sample's time, s."""
        return float(self.t[0])

    @property
    def end(self) -> float:
        """The last sample's time, s."""
        return float(self.t[-1])

    def index(self, time: float) -> int:
        """The last sample at or before ``time`` (0 before the start)."""
        return max(int(np.searchsorted(self.t, time, side="right")) - 1, 0)

    def qpos_at(self, time: float) -> FloatArray:
        """``(nq,)`` the configuration at ``time`` (s): linear between the samples around it,
        each quaternion normalised after (the shorter way round); a sample's time gives that
        sample exactly, and the first or last is held outside ``[start, end]``."""
        t, x = self.t, self.qpos
        i = min(self.index(time), len(t) - 2)
        a = float(np.clip((time - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0))
        if a in (0.0, 1.0):  # a sample itself, to the bit
            return np.array(x[i + int(a)], dtype=np.float64)
        x0, x1 = x[i], x[i + 1].copy()
        for s in self.quats:
            if float(x0[s : s + 4] @ x1[s : s + 4]) < 0.0:
                x1[s : s + 4] = -x1[s : s + 4]
        out: FloatArray = (1.0 - a) * x0 + a * x1
        for s in self.quats:
            out[s : s + 4] /= np.linalg.norm(out[s : s + 4])
        return out


def _columns(names: tuple[str, ...], listed: int = 4) -> str:
    shown = ", ".join(names[:listed])
    return shown + (f", ... ({len(names)} in all)" if len(names) > listed else "")


def playback_of(subject: Subject, trajectory: Trajectory, what: str = "the trajectory") -> Playback:
    """``trajectory`` as ``subject`` plays it, or :class:`InputError` if it was made for
    another robot.

    Args:
        subject: the robot shown (:func:`poekin.viewer.scene.make_subject`).
        trajectory: its columns are the subject's ``qpos`` (``nq`` of them), or the joint values
            of its chain to the end frame (``n``); with ``joint_names``, those names in order.
        what: how the message names the trajectory (``"--play traj.npz"``).

    Raises:
        InputError: neither: the message says what the file holds (its robot, its columns)
            and what the robot shown takes, and how to play it on its own robot.
    """
    tree, chain = subject.tree, subject.chain
    n, names = trajectory.n, trajectory.joint_names
    layouts: list[tuple[str, tuple[str, ...]]] = []
    if tree is not None:
        layouts.append(("qpos", qpos_column_names(tree)))
    if tree is None or chain.n_joints != tree.nq or chain.joint_names != layouts[0][1]:
        layouts.append(("chain", chain.joint_names))
    for kind, columns in layouts:
        if n == len(columns) and (not names or names == columns):
            return _played(subject, trajectory, kind)
    made = f" (made for {trajectory.robot!r})" if trajectory.robot else ""
    takes = " or ".join(
        f"its {'qpos' if kind == 'qpos' else f'chain to {subject.frame!r}'}: {len(c)} "
        f"({_columns(c)})"
        for kind, c in layouts
    )
    held = f"{n} columns" + (f" ({_columns(names)})" if names else "")
    hint = (
        f": play it on its robot, poekin view {trajectory.robot} --play FILE"
        if trajectory.robot and trajectory.robot != subject.name
        else ""
    )
    raise InputError(f"{what}{made} holds {held}; {subject.name} takes {takes}{hint}")


def _played(subject: Subject, trajectory: Trajectory, kind: str) -> Playback:
    tree = subject.tree
    if tree is None:
        return Playback(trajectory, trajectory.q.copy(), (), kind)
    quats = tuple(
        int(tree.qpos_adr[k]) + (3 if t == "free" else 0)
        for k, t in enumerate(tree.joint_types)
        if t in ("free", "ball")
    )
    if kind == "qpos":
        return Playback(trajectory, trajectory.q.copy(), quats, kind)
    slots = []
    for name in subject.chain.joint_names:
        k = tree.joint_names.index(name)
        if tree.mimics[k] is not None:
            raise InputError(
                f"the chain's joint {name!r} follows another (a mimic joint): give the "
                "trajectory as the tree's qpos"
            )
        slots.append(int(tree.qpos_adr[k]))
    qpos = np.repeat(tree.qpos0[None], len(trajectory.t), axis=0)
    qpos[:, slots] = trajectory.q
    return Playback(trajectory, qpos, quats, kind)


def tool_trace(subject: Subject, qpos: FloatArray) -> FloatArray:
    """``(K, 3)`` the end frame's world position (the tool's, with one) at each configuration
    of ``qpos`` ``(K, nq)``: the same pose as the viewer's end frame, from the tree's FK of the
    chain's base and the chain's product of exponentials."""
    chain, tree = subject.chain, subject.tree
    x = np.asarray(qpos, dtype=np.float64)
    if tree is None:
        return np.asarray(chain.fk(x)[:, :3, 3], dtype=np.float64)
    q = np.asarray(tree.full_qpos(x)[:, subject.slots], dtype=np.float64)
    T = np.asarray(chain.fk(q), dtype=np.float64)
    if subject.base_body is not None:
        base = np.asarray(tree.fk(x)[:, subject.base_body], dtype=np.float64)
        T = base @ T
    return np.asarray(T[:, :3, 3], dtype=np.float64)


@dataclasses.dataclass
class Clock:
    """Trajectory time from the wall clock: ``now`` is any monotonic clock in seconds
    (:func:`time.monotonic`), passed in so that the clock itself is pure.

    Attributes:
        start: the first time, s.
        end: the last time, s; playing stops there.
        time: the time shown when paused (when playing, :meth:`at` gives it).
        playing: whether it advances.
    """

    start: float
    end: float
    time: float = 0.0
    playing: bool = False
    _wall: float = 0.0
    _from: float = 0.0

    def __post_init__(self) -> None:
        self.time = min(max(self.time, self.start), self.end)

    def at(self, now: float) -> float:
        """The trajectory time at wall time ``now``: the paused time, or the time played since
        :meth:`play` (held at ``end``)."""
        if not self.playing:
            return self.time
        return min(self._from + (now - self._wall), self.end)

    def play(self, now: float) -> None:
        """Advance in real time from the time shown; from ``start`` when it is at the end."""
        if self.time >= self.end:
            self.time = self.start
        self.playing, self._wall, self._from = True, now, self.time

    def pause(self, now: float) -> None:
        """Hold at the time reached."""
        self.time = self.at(now)
        self.playing = False

    def seek(self, time: float, now: float) -> None:
        """Show ``time`` (clamped to ``[start, end]``), and play on from it if playing."""
        self.time = min(max(float(time), self.start), self.end)
        self._wall, self._from = now, self.time

    def tick(self, now: float) -> float:
        """The time to show at ``now``; at the end, playing stops."""
        self.time = self.at(now)
        if self.playing and self.time >= self.end:
            self.playing = False
        return self.time
