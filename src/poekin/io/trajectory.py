"""The trajectory file: joint values through time, what ``poekin path`` writes, ``poekin view
--play`` plays and ``poekin plot-trajectory`` draws.

A :class:`Trajectory` holds samples ``t (K,)`` (seconds, strictly increasing) and ``q (K, n)``:
a chain's joint values (:meth:`poekin.Chain.follow`, :func:`poekin.motion.retime`) or a tree's
whole ``qpos`` in MuJoCo's layout (:func:`poekin.motion.track`); optionally the velocities
``qd`` and accelerations ``qdd`` (``(K, n)`` each), the robot it was made for, one name per
column of ``q`` (:func:`qpos_column_names` for a tree's ``qpos``), the limits it was timed
within (``vel_limits (n,)``, ``acc_limits (n,)``, ``pos_limits (n, 2)``), and where a path
stopped early: the ``fraction`` of it reached, the ``reason`` in words and the sample
``stop_index`` where it stopped.

The file is a NumPy ``.npz`` archive of plain arrays, read without unpickling
(``allow_pickle=False``): numbers as float64 (``stop_index`` an integer), texts as NumPy unicode
arrays, each optional entry absent when not set, and ``format`` = ``"poekin-trajectory"`` with
``version`` = 1. An archive saved by hand with ``numpy.savez("traj.npz", t=t, q=q)`` (no
``format`` entry) reads as well. SI units and radians throughout.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import zipfile
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import InputError, did_you_mean
from poekin.io.fileio import check_new_file, write_array

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = [
    "FORMAT",
    "VERSION",
    "Trajectory",
    "load_trajectory",
    "qpos_column_names",
    "trajectory_from",
]

FloatArray = NDArray[np.float64]

#: The ``format`` entry of a trajectory file, and the version of its layout.
FORMAT = "poekin-trajectory"
VERSION = 1

_ARRAYS = ("t", "q", "qd", "qdd", "vel_limits", "acc_limits", "pos_limits")
_TEXTS = ("robot", "reason")
_KEYS = (*_ARRAYS, *_TEXTS, "joint_names", "fraction", "stop_index", "format", "version")
_QPOS_WORDS = {"free": ("x", "y", "z", "qw", "qx", "qy", "qz"), "ball": ("qw", "qx", "qy", "qz")}


def qpos_column_names(tree: Tree) -> tuple[str, ...]:
    """One name per ``qpos`` column of ``tree``, for :attr:`Trajectory.joint_names`: a hinge's
    or slide's joint name, ``name[x]`` ... ``name[qz]`` for a free joint's seven numbers and
    ``name[qw]`` ... ``name[qz]`` for a ball joint's four (mimic followers have none)."""
    names: list[str] = []
    for name, kind, mimic in zip(tree.joint_names, tree.joint_types, tree.mimics, strict=True):
        if mimic is not None:
            continue
        words = _QPOS_WORDS.get(kind)
        names += [name] if words is None else [f"{name}[{w}]" for w in words]
    return tuple(names)


def _array(value: ArrayLike, name: str, where: str, shape: tuple[int, ...]) -> FloatArray:
    """``value`` as a finite float64 array of ``shape``, else :class:`InputError`."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise InputError(f"{where}: {name} holds {arr.dtype} values; give real numbers")
    if arr.shape != shape:
        want = "(" + ", ".join(map(str, shape)) + (",)" if len(shape) == 1 else ")")
        raise InputError(f"{where}: {name} has shape {arr.shape}, expected {want}")
    x = np.array(arr, dtype=np.float64)
    bad = ~np.isfinite(x)
    if name in ("vel_limits", "acc_limits", "pos_limits"):
        bad = np.isnan(x)  # inf: no limit
    if bad.any():
        at = tuple(int(i) for i in np.argwhere(bad)[0])
        raise InputError(f"{where}: {name}{list(at)} is {x[at]}; every value must be finite")
    return x


@dataclasses.dataclass(frozen=True, eq=False)
class Trajectory:
    """Joint values through time, with what the plot and the viewer show beside them.

    Attributes:
        t: ``(K,)`` the sample times, s, strictly increasing (``K >= 2``).
        q: ``(K, n)`` joint values at ``t`` (rad, m): a chain's, or a tree's whole ``qpos``.
        qd: ``(K, n)`` velocities (rad/s, m/s), or None (the plot then differentiates ``q``).
        qdd: ``(K, n)`` accelerations (rad/s², m/s²), or None.
        robot: the robot it was made for: a Menagerie name or a model path ("" if not said).
        joint_names: ``(n,)`` one name per column of ``q``, or ``()``.
        vel_limits: ``(n,)`` velocity limits, > 0 (inf: none), or None.
        acc_limits: ``(n,)`` acceleration limits, > 0 (inf: none), or None.
        pos_limits: ``(n, 2)`` position limits ``[lower, upper]`` (-inf, inf: none), or None.
        fraction: how far along its path the motion got, in ``[0, 1]``, or None.
        reason: why it stopped there, in words ("" if it did not stop early).
        stop_index: the sample where it stopped (``0..K-1``), or None: at the last sample when
            ``fraction`` is below 1.

    The keyword ``where`` (not a field) names the trajectory in error messages: its file,
    for :func:`load_trajectory`.

    Raises:
        InputError: any field of the wrong shape or value; the message names it (and
            ``where``, the file it came from, for :func:`load_trajectory`).
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray | None = None
    qdd: FloatArray | None = None
    robot: str = ""
    joint_names: tuple[str, ...] = ()
    vel_limits: FloatArray | None = None
    acc_limits: FloatArray | None = None
    pos_limits: FloatArray | None = None
    fraction: float | None = None
    reason: str = ""
    stop_index: int | None = None
    where: dataclasses.InitVar[str] = "trajectory"

    def __post_init__(self, where: str) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        t = np.asarray(self.t)
        if t.ndim != 1 or t.shape[0] < 2:
            raise InputError(
                f"{where}: t must be (K,) sample times with K >= 2, got shape {t.shape}"
            )
        K = t.shape[0]
        t = _array(t, "t", where, (K,))
        steps = np.diff(t)
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0)) + 1
            raise InputError(
                f"{where}: t must increase strictly, but t[{k}] = {t[k]:g} s follows "
                f"t[{k - 1}] = {t[k - 1]:g} s"
            )
        put("t", t)
        q = np.asarray(self.q)
        if q.ndim != 2 or q.shape[0] != K or q.shape[1] < 1:
            raise InputError(
                f"{where}: q must be (K, n) = ({K}, n) joint values, one row per time of t, "
                f"got shape {q.shape}"
            )
        n = q.shape[1]
        put("q", _array(q, "q", where, (K, n)))
        for name in ("qd", "qdd", "vel_limits", "acc_limits", "pos_limits"):
            value = getattr(self, name)
            if value is not None:
                shape = {"vel_limits": (n,), "acc_limits": (n,), "pos_limits": (n, 2)}
                put(name, _array(value, name, where, shape.get(name, (K, n))))
        for name in ("vel_limits", "acc_limits"):
            lim = getattr(self, name)
            if lim is not None and np.any(lim <= 0):
                j = int(np.argmax(lim <= 0))
                raise InputError(
                    f"{where}: {name} must be > 0 (inf: no limit), got {lim[j]:g} for joint {j}"
                )
        if self.pos_limits is not None and np.any(self.pos_limits[:, 0] > self.pos_limits[:, 1]):
            j = int(np.argmax(self.pos_limits[:, 0] > self.pos_limits[:, 1]))
            lo, hi = self.pos_limits[j]
            raise InputError(
                f"{where}: pos_limits of joint {j} are upside down ({lo:g} > {hi:g}); give "
                "[lower, upper]"
            )
        put("robot", _text(self.robot, "robot", where))
        put("reason", _text(self.reason, "reason", where))
        names = tuple(_text(s, "joint_names", where) for s in self.joint_names)
        if names and len(names) != n:
            raise InputError(
                f"{where}: joint_names names {len(names)} columns, q has {n}: give one name per "
                "column"
            )
        twice = [s for k, s in enumerate(names) if s in names[:k]]
        if twice:
            raise InputError(f"{where}: joint_names names {twice[0]!r} twice")
        put("joint_names", names)
        if self.fraction is not None:
            f = float(self.fraction)
            if not 0.0 <= f <= 1.0:
                raise InputError(f"{where}: fraction must be in [0, 1], got {f:g}")
            put("fraction", f)
        if self.stop_index is not None:
            index = self.stop_index
            if isinstance(index, bool) or not isinstance(index, int | np.integer):
                raise InputError(f"{where}: stop_index must be a sample index, got {index!r}")
            if not 0 <= index < K:
                raise InputError(f"{where}: stop_index must be in 0..{K - 1}, got {index}")
            put("stop_index", int(index))

    @property
    def n(self) -> int:
        """Columns of ``q``."""
        return int(self.q.shape[1])

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]``, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def stopped(self) -> bool:
        """Whether the path stopped early: ``fraction`` below 1, or a ``stop_index`` set."""
        return (self.fraction is not None and self.fraction < 1.0) or self.stop_index is not None

    @property
    def stop_time(self) -> float | None:
        """The time where the path stopped (s): ``t[stop_index]``, else the last sample's when
        it stopped early; None if it did not."""
        if not self.stopped:
            return None
        return float(self.t[-1 if self.stop_index is None else self.stop_index])

    def stop_words(self) -> str:
        """Where the path stopped, in words: ``"stopped at 62.5%: joint limit: elbow_joint"``
        (the fraction and the reason where known); "" if it did not stop early."""
        if not self.stopped:
            return ""
        at = "" if self.fraction is None else f" at {100 * self.fraction:.1f}%"
        return f"stopped{at}" + (f": {self.reason}" if self.reason else "")

    def column_names(self) -> tuple[str, ...]:
        """``joint_names``, or ``q[0]`` ... ``q[n-1]`` without them."""
        return self.joint_names or tuple(f"q[{j}]" for j in range(self.n))

    def arrays(self) -> dict[str, NDArray[Any]]:
        """What the file holds: every set entry as a plain NumPy array (texts as unicode)."""
        out: dict[str, NDArray[Any]] = {"format": np.array(FORMAT), "version": np.array(VERSION)}
        for name in _ARRAYS:
            value = getattr(self, name)
            if value is not None:
                out[name] = np.asarray(value, dtype=np.float64)
        for name in _TEXTS:
            if getattr(self, name):
                out[name] = np.array(getattr(self, name), dtype=np.str_)
        if self.joint_names:
            out["joint_names"] = np.array(self.joint_names, dtype=np.str_)
        if self.fraction is not None:
            out["fraction"] = np.array(self.fraction, dtype=np.float64)
        if self.stop_index is not None:
            out["stop_index"] = np.array(self.stop_index, dtype=np.int64)
        return out

    def save(self, path: str | os.PathLike[str], *, force: bool = False) -> pathlib.Path:
        """Write the trajectory to ``path`` (a ``.npz`` file), in one step (a failed write
        leaves no file).

        Args:
            path: the file; its suffix must be ``.npz``.
            force: replace an existing file (else refused).

        Returns:
            The path written.

        Raises:
            InputError: another suffix, an existing file without ``force``, or a path the OS
                refuses.
        """
        p = pathlib.Path(path)
        if p.suffix.lower() != ".npz":
            raise InputError(f"{p}: a trajectory file is a .npz archive; give a path ending .npz")
        check_new_file(p, "trajectory", force=force)
        arrays = self.arrays()
        return write_array(
            p, arrays.pop("t"), name="t", columns=(), extras=arrays, what="trajectory"
        )


def _text(value: Any, name: str, where: str) -> str:
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if not isinstance(value, str):
        raise InputError(f"{where}: {name} must be text, got {type(value).__name__}")
    if "\x00" in value:  # NumPy's unicode arrays drop trailing NULs: it would not read back
        raise InputError(f"{where}: {name} {value!r} holds a NUL character; remove it")
    return value


def _entry(archive: Mapping[str, NDArray[Any]], name: str, where: str) -> Any:
    """Entry ``name`` of the archive as the field takes it: a text, names, a number, an
    array."""
    arr = archive[name]
    if name in (*_TEXTS, "joint_names", "format"):
        if arr.dtype.kind != "U" or arr.ndim != (1 if name == "joint_names" else 0):
            shape = "(n,) array" if name == "joint_names" else "0-d array"
            raise InputError(
                f"{where}: {name} must be a {shape} of text, got {arr.dtype} {arr.shape}"
            )
        return tuple(arr.tolist()) if name == "joint_names" else str(arr)
    if arr.dtype.kind not in "biuf":
        raise InputError(f"{where}: {name} holds {arr.dtype} values; give real numbers")
    if name in ("fraction", "stop_index", "version"):
        if arr.shape != ():
            raise InputError(f"{where}: {name} must be one number, got shape {arr.shape}")
        if name == "fraction":
            return float(arr)
        if arr.dtype.kind not in "biu":
            raise InputError(f"{where}: {name} must be an integer, got {arr.item()!r}")
        return int(arr)
    return arr


def load_trajectory(path: str | os.PathLike[str], what: str = "trajectory") -> Trajectory:
    """The :class:`Trajectory` in the ``.npz`` file at ``path``.

    Args:
        path: the file.
        what: how messages name it (``"--play"``): ``"--play traj.npz: ..."``.

    Raises:
        InputError: no such file, not a NumPy ``.npz`` archive, an archive that is no
            trajectory (no ``t`` and ``q``, another ``format``, an entry it does not know), or
            an entry :class:`Trajectory` refuses (non-increasing ``t``, lengths that differ,
            NaN). The message names the file. Never a pickle.
    """
    p = pathlib.Path(path)
    where = f"{what} {os.fspath(path)}"
    if not p.is_file():
        raise InputError(f"{where}: no such file")
    if not zipfile.is_zipfile(p):
        raise InputError(
            f"{where} is not a NumPy .npz archive; save a trajectory with Trajectory.save, or "
            "numpy.savez(path, t=t, q=q)"
        )
    try:
        with np.load(p, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except ValueError as e:
        if "pickle" in str(e):
            raise InputError(f"{where} holds Python objects, not arrays of numbers") from None
        raise InputError(f"{where} is not a readable .npz archive: {e}") from None
    except (OSError, zipfile.BadZipFile) as e:
        raise InputError(f"{where} is not a readable .npz archive: {e}") from None
    fields = {name: _entry(arrays, name, where) for name in arrays if name in _KEYS}
    if "format" in fields and fields["format"] != FORMAT:
        raise InputError(f"{where} is a {fields['format']!r} file, not a trajectory ({FORMAT!r})")
    missing = [name for name in ("t", "q") if name not in fields]
    if missing:
        held = ", ".join(repr(k) for k in arrays) or "nothing"
        raise InputError(
            f"{where} is not a trajectory: it has no {' or '.join(missing)} (it holds {held}); "
            "a trajectory holds t (K,) and q (K, n)"
        )
    unknown = [name for name in arrays if name not in _KEYS]
    if unknown:
        raise InputError(
            f"{where}: unknown entry {unknown[0]!r}: {did_you_mean(unknown[0], _KEYS)}"
        )
    version = fields.pop("version", VERSION)
    if version != VERSION:
        raise InputError(
            f"{where} is a trajectory of version {version}; this poekin reads version {VERSION}"
        )
    fields.pop("format", None)
    return Trajectory(**fields, where=where)


def trajectory_from(
    value: Trajectory | str | os.PathLike[str], what: str = "trajectory"
) -> Trajectory:
    """``value`` itself if it is a :class:`Trajectory`, else the one in that file."""
    return value if isinstance(value, Trajectory) else load_trajectory(value, what)
