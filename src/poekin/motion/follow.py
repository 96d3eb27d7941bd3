"""IK along a pose path: joint values for every sample of a path, the branch kept
(:meth:`poekin.Chain.follow`).

**The path.** ``T_path`` is either ``(N, 4, 4)`` poses at the path parameters ``s = 0, 1/(N-1),
..., 1`` (``N >= 2``), the path between two consecutive samples being the screw motion between
them (:func:`~poekin.motion.paths.screw_path`), or a callable ``s -> (..., 4, 4)`` (such as
``lambda s: line_path(T0, T1, s)``), first sampled at ``samples`` uniform ``s``.

**The samples.** ``q0`` must put the end frame on the path's start (within ``tol`` and
``ori_tol``); it is the first sample. Each sample starts from the last:

* where the chain has a closed form (:meth:`poekin.Chain.ik_all`: the UR arms, spherical
  wrists), every sample is the closed-form solution of one branch, the one ``q0`` is on. A
  branch of :func:`poekin.ik.analytic.ik_all` is a set of configuration signs (for three
  parallel axes, the UR's: shoulder, wrist and elbow), so the branch is never switched: where
  it ends (a singularity, the edge of the workspace) the path stops. Its angles are taken
  continuously (whole turns added), so a joint that would have to turn through its limit
  stops the path there. The samples are solved in batches, all at once;
* elsewhere (the FR3's seven joints), :meth:`poekin.Chain.ik` from the previous sample, one
  attempt (random restarts would jump to another solution). No posture pull: the damped least
  squares step from the previous sample is already the least-norm one, and ``chain.ik``'s
  ``posture=`` costs some 5 ms a solve, a thousand times the warm-started solve.

**Re-sampling.** Between two samples ``q_i`` and ``q_{i+1}`` a controller interpolates in joint
space. The tool's deviation there is measured at the midpoint, ``chain.fk((q_i + q_{i+1}) / 2)``
against the path's pose at ``(s_i + s_{i+1}) / 2`` (MoveIt's check since moveit#3618), and the
interval is bisected until the position deviation is at most ``tol`` (0.1 mm) and the
rotation's at most ``ori_tol`` (1e-3 rad: a point 10 cm from the end frame's origin strays by
at most 0.1 mm more), and no joint moves more than ``max_step`` between samples.

**Where it stops.** An interval that still fails when it spans less than :data:`S_RESOLUTION`
of ``s`` ends the path at its first sample, with the reason:

* ``"joint_limit"``: the next sample needs a joint beyond its limit (``joint`` names it);
* ``"unreachable"``: no configuration reaches the next pose (no closed-form branch; the
  numerical solve's random restarts find none);
* ``"singular"``: the next pose is reachable, but not from here without leaving the branch or
  moving more than ``max_step``, at a configuration whose Jacobian's smallest singular value
  (``sigma_min``) is below :data:`SINGULAR_TOL`;
* ``"jump"``: the same away from any singularity;
* ``"collision"`` (asked for with ``obstacles=``): a sample where a checked pair of the robot's
  collision geometry, with itself or an obstacle, is closer than ``margin``
  (:meth:`poekin.Tree.in_collision`). The samples are checked once the path is followed; the
  path ends at the sample before the first colliding one, and ``pair`` names the closest pair
  there (the stretch between two samples is not checked).

A path followed to its end has reason ``"done"`` and ``fraction`` 1. No I/O here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin._poe import as_joint_values
from poekin.errors import AnalyticIKError, InputError
from poekin.ik import analytic
from poekin.motion.paths import screw_path

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.tree import Tree

__all__ = [
    "DEFAULT_MAX_STEP",
    "DEFAULT_ORI_TOL",
    "DEFAULT_SAMPLES",
    "DEFAULT_TOL",
    "SINGULAR_TOL",
    "S_RESOLUTION",
    "FollowResult",
    "Reason",
    "collision_stop",
    "follow",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Reason = Literal["done", "joint_limit", "singular", "unreachable", "jump", "collision"]
PathFunction = Callable[[FloatArray], ArrayLike]

#: The largest move of any joint between two samples (rad, or m for a prismatic joint).
DEFAULT_MAX_STEP = 0.1
#: The tool's largest position deviation from the path between samples (m).
DEFAULT_TOL = 1e-4
#: Its largest rotation deviation (rad).
DEFAULT_ORI_TOL = 1e-3
#: A callable path's first samples (uniform in ``s``), before re-sampling.
DEFAULT_SAMPLES = 11
#: An interval of ``s`` shorter than this is not bisected again: where it fails, the path stops.
S_RESOLUTION = 1e-9
#: A stop at a configuration whose world Jacobian's smallest singular value is below this is
#: ``"singular"`` (m/rad and rad/rad mixed, as the Jacobian's columns ``[w; v]`` are).
SINGULAR_TOL = 1e-4

#: A tree's stop: the attempts (random restarts) that decide whether the path's next pose is
#: reachable at all, with the held frames where they are.
RESTARTS = 20

_SOLVED = 1e-9  # a closed-form branch solves its pose when it is within this (m and rad)
_RIGID_TOL = 1e-6  # a path's rotation blocks must be orthonormal to this


@dataclasses.dataclass(frozen=True)
class FollowResult:
    """The joint path that follows a pose path, and where and why it stopped. Immutable.

    Attributes:
        q: ``(K, n)`` joint values, one row per sample (rad, m); ``q[0]`` is ``q0``.
        s: ``(K,)`` each sample's path parameter, increasing from 0 to ``fraction``.
        T: ``(K, 4, 4)`` the end frame's poses at ``q`` (``chain.fk(q)``): on the path at ``s``.
        fraction: how far along the path it got, ``s[-1]`` (1 when done).
        reason: ``"done"``, ``"joint_limit"``, ``"singular"``, ``"unreachable"`` or ``"jump"``
            (:mod:`poekin.motion.follow` says what each means).
        detail: one line saying where and why it stopped (``""`` when done).
        joint: with ``"joint_limit"``, the name of the joint at its limit; else None.
        sigma_min: with ``"singular"``, ``"jump"`` and ``"unreachable"``, the smallest singular
            value of the world Jacobian at ``q[-1]`` (small at the workspace's edge too); else
            None.
        branch: where the closed form served, the index of the branch kept in
            :meth:`~poekin.Chain.ik_all`'s order (for three parallel axes, the UR's: bit 2 the
            shoulder, bit 1 the wrist, bit 0 the elbow; :attr:`signs`); else None.
        max_deviation: the largest position deviation from the path at the samples' midpoints
            (m), at most ``tol``.
        max_ori_deviation: the largest rotation deviation there (rad), at most ``ori_tol``.
        pair: with ``"collision"``, the names of the closest pair at the first colliding
            sample (robot geoms or obstacles); else None.
    """

    q: FloatArray
    s: FloatArray
    T: FloatArray
    fraction: float
    reason: Reason
    detail: str
    joint: str | None
    sigma_min: float | None
    branch: int | None
    max_deviation: float
    max_ori_deviation: float
    pair: tuple[str, str] | None = None

    @property
    def done(self) -> bool:
        """True when the whole path was followed."""
        return self.reason == "done"

    @property
    def signs(self) -> tuple[int, int, int] | None:
        """:attr:`branch` as its three configuration signs (+1 for a branch's first root, -1
        for its second), in :meth:`~poekin.Chain.ik_all`'s order of branch axes: for three
        parallel axes (the UR arms) shoulder, wrist, elbow, where the wrist's +1 is ``q5 > 0``
        and the elbow's +1 is ``q3 < 0``; None without the closed form."""
        if self.branch is None:
            return None
        b = self.branch
        return (1 - 2 * (b >> 2 & 1), 1 - 2 * (b >> 1 & 1), 1 - 2 * (b & 1))


# --- inputs ------------------------------------------------------------------------------------


def _positive(value: object, name: str, unit: str) -> float:
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or not math.isfinite(float(value)) or float(value) <= 0:  # type: ignore[arg-type]
        raise InputError(f"follow: {name} must be a number > 0 ({unit}), got {value!r:.40}")
    return float(value)  # type: ignore[arg-type]


def _rigid(T: FloatArray, name: Callable[[int], str]) -> None:
    """Raise unless every ``(m, 4, 4)`` of ``T`` is a finite rigid transform; ``name(k)``
    names pose ``k`` in the message."""
    finite = np.all(np.isfinite(T), axis=(-2, -1))
    if not finite.all():
        raise InputError(f"follow: {name(int(np.argmin(finite)))} has NaN or inf entries")
    R = T[:, :3, :3]
    gram = np.einsum("kji,kjl->kil", R, R)
    det = np.sum(np.cross(R[:, :, 0], R[:, :, 1]) * R[:, :, 2], axis=-1)
    bad = np.any(np.abs(gram - np.eye(3)) > _RIGID_TOL, axis=(-2, -1)) | (det < 0)
    bad |= np.any(T[:, 3, :] != np.array([0.0, 0.0, 0.0, 1.0]), axis=-1)
    if np.any(bad):
        raise InputError(
            f"follow: {name(int(np.argmax(bad)))} is not a rigid transform: its rotation block "
            f"must be orthonormal with det +1 (to {_RIGID_TOL:g}) and its last row [0, 0, 0, 1]"
        )


class _Path:
    """A pose path at any ``s`` in [0, 1]: samples joined by screw motions, or a callable."""

    def __init__(self, T_path: ArrayLike | PathFunction, samples: int | None) -> None:
        self.function: PathFunction | None = None
        if callable(T_path):
            count = DEFAULT_SAMPLES if samples is None else samples
            if isinstance(count, bool) or not isinstance(count, int) or count < 2:
                raise InputError(
                    f"follow: samples must be an integer >= 2 (a callable path's first "
                    f"samples), got {count!r:.40}"
                )
            self.function = T_path
            self.grid = np.linspace(0.0, 1.0, count)
            self.poses = self.at(self.grid)
            return
        if samples is not None:
            raise InputError(
                "follow: samples is for a callable path; an array path's samples are its poses "
                "(N, 4, 4): leave samples out"
            )
        try:
            poses = np.array(T_path, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(
                "follow: T_path must be poses (N, 4, 4) or a callable s -> (..., 4, 4), got "
                f"{type(T_path).__name__}"
            ) from None
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) < 2:
            raise InputError(
                f"follow: T_path must be at least 2 poses (N, 4, 4) at s = 0 ... 1, or a "
                f"callable s -> (..., 4, 4), got an array of shape {poses.shape}"
            )
        _rigid(poses, lambda k: f"T_path[{k}]")
        self.samples = poses
        self.grid = np.linspace(0.0, 1.0, len(poses))
        self.poses = poses

    def at(self, s: FloatArray) -> FloatArray:
        """``(m, 4, 4)`` poses at ``(m,)`` path parameters in [0, 1]."""
        if self.function is None:
            n = len(self.samples) - 1
            x = s * n
            j = np.minimum(np.floor(x).astype(np.int64), n - 1)
            return screw_path(self.samples[j], self.samples[j + 1], x - j)
        try:
            out = np.asarray(self.function(s), dtype=np.float64)
        except InputError:
            raise
        except (TypeError, ValueError) as e:
            raise InputError(
                f"follow: the path function failed on s of shape {s.shape}: {e}"
            ) from None
        if out.shape != (len(s), 4, 4):
            raise InputError(
                f"follow: the path function must return poses (..., 4, 4) in the shape of s: "
                f"for s of shape {s.shape}, got {out.shape}"
            )
        _rigid(out, lambda k: f"the path function's pose at s = {s[k]:.6g}")
        return out


def _start(
    chain: Chain, q0: ArrayLike, start: FloatArray, tol: float, ori_tol: float
) -> FloatArray:
    n = chain.n_joints
    try:
        q = np.array(q0, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"follow: q0 must be {n} joint values, got {q0!r:.60}") from None
    if q.shape != (n,):
        raise InputError(f"follow: q0 must be {n} joint values (shape ({n},)), got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise InputError("follow: q0 has NaN or inf entries; give finite joint values")
    limits = chain.limits
    assert limits is not None  # Chain.__post_init__ sets them
    out = np.flatnonzero((q < limits[:, 0]) | (q > limits[:, 1]))
    if out.size:
        k = int(out[0])
        raise InputError(
            f"follow: q0 is outside the joint limits: {chain.joint_names[k]!r} = {q[k]:.6g}, "
            f"limits [{limits[k, 0]:.6g}, {limits[k, 1]:.6g}]; start within them"
        )
    pos, ori = _errors(chain.fk(q)[None], start[None])
    if pos[0] > tol or ori[0] > ori_tol:
        raise InputError(
            f"follow: q0 puts the end frame {pos[0]:.3g} m and {ori[0]:.3g} rad from the path's "
            f"start (tol {tol:g} m, ori_tol {ori_tol:g} rad); start on the path, e.g. "
            "q0 = chain.ik(path_start, q0).q"
        )
    return q


# --- shared maths ------------------------------------------------------------------------------


def _errors(A: FloatArray, B: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(m,)`` position distances (m) and geodesic angles (rad) between ``(m, 4, 4)`` poses; the
    angle from ``|R_a - R_b|_F = 2 sqrt(2) sin(angle / 2)``, accurate near 0."""
    pos = np.linalg.norm(A[:, :3, 3] - B[:, :3, 3], axis=-1)
    frob = np.sqrt(np.sum((A[:, :3, :3] - B[:, :3, :3]) ** 2, axis=(-2, -1)))
    return pos, 2.0 * np.arcsin(np.minimum(frob / math.sqrt(8.0), 1.0))


def _wrap(x: FloatArray) -> FloatArray:
    """Angles into [-pi, pi)."""
    out: FloatArray = (x + np.pi) % (2.0 * np.pi) - np.pi
    return out


def _sigma_min(chain: Chain, q: FloatArray) -> float:
    return float(np.linalg.svd(chain.jacobian_world(q), compute_uv=False)[-1])


@dataclasses.dataclass(frozen=True)
class _Options:
    max_step: float
    tol: float
    ori_tol: float


@dataclasses.dataclass(frozen=True)
class _Stop:
    reason: Reason
    detail: str
    joint: str | None = None
    sigma_min: float | None = None


def _beyond(chain: Chain, q: FloatArray) -> int | None:
    """The joint of ``q`` ``(n,)`` furthest outside its limits, or None."""
    limits = chain.limits
    assert limits is not None
    over = np.maximum(limits[:, 0] - q, q - limits[:, 1])
    k = int(np.argmax(over))
    return k if over[k] > 0 else None


def _limit_stop(chain: Chain, k: int, q: FloatArray, s: float) -> _Stop:
    limits = chain.limits
    assert limits is not None
    side, value = ("upper", limits[k, 1]) if q[k] > limits[k, 1] else ("lower", limits[k, 0])
    name = chain.joint_names[k]
    return _Stop(
        "joint_limit",
        f"joint {name!r} reaches its {side} limit {value:.6g} at s = {s:.6g}",
        joint=name,
    )


def _jump_stop(chain: Chain, q: FloatArray, s: float, why: str) -> _Stop:
    sigma = _sigma_min(chain, q)
    if sigma < SINGULAR_TOL:
        return _Stop(
            "singular",
            f"singular at s = {s:.6g} (smallest singular value {sigma:.2g}): {why}",
            sigma_min=sigma,
        )
    return _Stop("jump", f"a jump at s = {s:.6g}: {why}", sigma_min=sigma)


def _unreachable(chain: Chain, q: FloatArray, s: float) -> _Stop:
    sigma = _sigma_min(chain, q)
    return _Stop(
        "unreachable",
        f"the path leaves the workspace at s = {s:.6g} (smallest singular value {sigma:.2g})",
        sigma_min=sigma,
    )


def _result(
    chain: Chain,
    q: FloatArray,
    s: FloatArray,
    dev: tuple[FloatArray, FloatArray],
    stop: _Stop | None,
    branch: int | None,
) -> FollowResult:
    q.flags.writeable = False
    s.flags.writeable = False
    T = chain.fk(q)
    T.flags.writeable = False
    pos, ori = dev
    return FollowResult(
        q=q,
        s=s,
        T=T,
        fraction=float(s[-1]) if stop is not None else 1.0,
        reason="done" if stop is None else stop.reason,
        detail="" if stop is None else stop.detail,
        joint=None if stop is None else stop.joint,
        sigma_min=None if stop is None else stop.sigma_min,
        branch=branch,
        max_deviation=float(np.max(pos, initial=0.0)),
        max_ori_deviation=float(np.max(ori, initial=0.0)),
    )


# --- the closed form: every sample on one branch, solved in batches -----------------------------


def _closed_branch(chain: Chain, T0: FloatArray, q0: FloatArray, max_step: float) -> int | None:
    """The closed-form branch ``q0`` is on at the path's start, or None: no closed form, or
    ``q0`` within ``max_step`` of no branch (a singular start, where the closed form's
    convention picks values of its own for the joints left free)."""
    try:
        analytic.nearest_geometry(chain)
    except AnalyticIKError:
        return None
    found = analytic.ik_all(chain, T0)
    gap = np.max(np.abs(_wrap(found.q - q0)), axis=-1)
    gap[~found.valid] = np.inf
    b = int(np.argmin(gap))
    return b if gap[b] <= max_step else None


def _branch_values(chain: Chain, branch: int, T: FloatArray) -> tuple[FloatArray, BoolArray]:
    """The branch's ``(m, 6)`` values for ``(m, 4, 4)`` poses, and where they solve them."""
    raw = analytic.ik_all(chain, T).q[:, branch]
    pos, ori = _errors(chain.fk(raw), T)
    return raw, (pos <= _SOLVED) & (ori <= _SOLVED)


def _continuous(q0: FloatArray, raw: FloatArray) -> FloatArray:
    """``q0`` then ``raw`` ``(m, 6)`` (angles known up to whole turns) as one path: each row
    the equivalent nearest the row before, by whole turns exactly."""
    steps = _wrap(np.diff(np.vstack([q0, raw]), axis=0))
    guess = q0 + np.cumsum(steps, axis=0)
    turned = raw + 2.0 * np.pi * np.round((guess - raw) / (2.0 * np.pi))
    out: FloatArray = np.vstack([q0, turned])
    return out


def _follow_closed(
    chain: Chain, path: _Path, q0: FloatArray, branch: int, opts: _Options
) -> FollowResult:
    """Every sample on ``branch``: the grid solved at once, then each interval that fails
    bisected, all of them in one batch per round."""
    limits = chain.limits
    assert limits is not None
    s = path.grid
    raw, solved = _branch_values(chain, branch, path.poses[1:])
    raw, solved = np.vstack([q0, raw]), np.concatenate([[True], solved])
    pos = np.full(len(s), np.nan)  # the midpoint deviations of the interval ending at a sample
    ori = np.full(len(s), np.nan)
    while True:
        u = int(np.argmin(solved)) if not solved.all() else len(s)  # the first one unsolved
        s, raw, solved = s[: u + 1], raw[: u + 1], solved[: u + 1]
        pos, ori = pos[: u + 1], ori[: u + 1]
        q = _continuous(q0, raw[1:u])
        outside = np.any((q < limits[:, 0]) | (q > limits[:, 1]), axis=-1)
        e = int(np.argmax(outside)) if outside.any() else len(q)  # samples [0, e) are usable
        unknown = np.flatnonzero(np.isnan(pos[1:e])) + 1
        if unknown.size:
            mid = 0.5 * (s[unknown - 1] + s[unknown])
            pos[unknown], ori[unknown] = _errors(
                chain.fk(0.5 * (q[unknown - 1] + q[unknown])), path.at(mid)
            )
        step = np.max(np.abs(np.diff(q[:e], axis=0)), axis=-1, initial=0.0)
        bad = (step > opts.max_step) | (pos[1:e] > opts.tol) | (ori[1:e] > opts.ori_tol)
        if e < len(s):  # into the first sample that is not usable
            bad = np.append(bad, True)
        small = np.diff(s[: len(bad) + 1]) < S_RESOLUTION
        dead = np.flatnonzero(bad & small)
        cut = int(dead[0]) if dead.size else len(bad)  # a stop at sample `cut`, if dead
        refine = np.flatnonzero(bad[:cut])
        if not refine.size:
            break
        keep = cut + 2 if dead.size else len(s)  # nothing past a dead interval counts
        new_s = 0.5 * (s[refine] + s[refine + 1])
        new_raw, new_solved = _branch_values(chain, branch, path.at(new_s))
        new = np.concatenate([np.zeros(keep, dtype=bool), np.ones(len(new_s), dtype=bool)])
        order = np.argsort(np.concatenate([s[:keep], new_s]), kind="stable")
        s = np.concatenate([s[:keep], new_s])[order]
        raw = np.vstack([raw[:keep], new_raw])[order]
        solved = np.concatenate([solved[:keep], new_solved])[order]
        changed = new[order]
        changed[1:] |= changed[:-1]  # a new sample's interval, and the one after it
        unknown_new = np.full(len(new_s), np.nan)
        pos = np.concatenate([pos[:keep], unknown_new])[order]
        ori = np.concatenate([ori[:keep], unknown_new])[order]
        pos[changed], ori[changed] = np.nan, np.nan
    dev = (pos[1 : cut + 1], ori[1 : cut + 1])
    if not dead.size:
        return _result(chain, q, s, dev, None, branch)
    at = float(s[cut])
    if cut + 1 == u:  # the branch does not reach the next pose
        T_next = path.at(s[cut + 1 : cut + 2])
        every = analytic.ik_all(chain, T_next)
        if not np.any((every.pos_err <= _SOLVED) & (every.ori_err <= _SOLVED)):
            stop = _unreachable(chain, q[cut], at)
        else:
            stop = _jump_stop(chain, q[cut], at, f"branch {branch} of the closed form ends here")
    elif cut + 1 == e:  # the next sample is beyond a joint's limit
        k = _beyond(chain, q[cut + 1])
        assert k is not None
        stop = _limit_stop(chain, k, q[cut + 1], at)
    else:
        stop = _jump_stop(
            chain, q[cut], at, f"a joint moves {step[cut]:.3g} rad within ds < {S_RESOLUTION:g}"
        )
    return _result(chain, q[: cut + 1], s[: cut + 1], dev, stop, branch)


# --- elsewhere: the numerical solve from the previous sample, one sample at a time ---------------


def _walk(
    path: _Path,
    q0: FloatArray,
    attempt: Callable[
        [tuple[float, FloatArray], float, FloatArray], tuple[FloatArray, str, tuple[float, float]]
    ],
    stop_at: Callable[[tuple[float, FloatArray], FloatArray, FloatArray, str], _Stop],
) -> tuple[FloatArray, FloatArray, tuple[FloatArray, FloatArray], _Stop | None]:
    """The samples along ``path`` from ``q0``, one at a time: ``attempt(a, s_b, T_b)`` solves
    the next from sample ``a`` and says what is wrong with it (``""``: nothing) and the
    midpoint's deviation; an interval that fails is bisected, its first half first, until it is
    shorter than :data:`S_RESOLUTION`, where ``stop_at(a, T_b, q_b, why)`` says why the path
    ends. Returns ``q (K, n)``, ``s (K,)``, the deviations ``(K - 1,)`` and the stop."""
    qs, ss = [q0], [0.0]
    pos_dev: list[float] = []
    ori_dev: list[float] = []
    pending: list[tuple[float, FloatArray]] = list(
        zip(path.grid[1:][::-1].tolist(), path.poses[1:][::-1], strict=True)
    )  # a stack: the next sample last
    stop: _Stop | None = None
    while pending:
        s_b, T_b = pending[-1]
        a = (ss[-1], qs[-1])
        q_b, why, dev = attempt(a, s_b, T_b)
        if not why:
            qs.append(q_b)
            ss.append(s_b)
            pos_dev.append(dev[0])
            ori_dev.append(dev[1])
            pending.pop()
        elif s_b - a[0] >= S_RESOLUTION:
            s_m = 0.5 * (a[0] + s_b)
            pending.append((s_m, path.at(np.array([s_m]))[0]))
        else:
            stop = stop_at(a, T_b, q_b, why)
            break
    return np.array(qs), np.array(ss), (np.array(pos_dev), np.array(ori_dev)), stop


def _follow_numerical(chain: Chain, path: _Path, q0: FloatArray, opts: _Options) -> FollowResult:
    """Each sample solved by ``chain.ik`` from the one before (one attempt); an interval that
    fails is bisected, its first half first."""
    revolute = np.array([t == "revolute" for t in chain.joint_types])

    def attempt(
        a: tuple[float, FloatArray], s_b: float, T_b: FloatArray
    ) -> tuple[FloatArray, str, tuple[float, float]]:
        q_a = a[1]
        found = chain.ik(T_b, q_a, max_attempts=1)
        # angles taken continuously: a joint that turned a whole turn back into its limits
        # would have to pass through them
        q_b = np.where(revolute, q_a + _wrap(found.q - q_a), found.q)
        why, dev = _why(chain, path, a, (s_b, q_b), bool(found.success), opts)
        return q_b, why, dev

    def stop_at(a: tuple[float, FloatArray], T_b: FloatArray, q_b: FloatArray, why: str) -> _Stop:
        return _numerical_stop(chain, a, T_b, q_b, why, opts)

    qs, ss, devs, stop = _walk(path, q0, attempt, stop_at)
    return _result(chain, qs, ss, devs, stop, None)


def _why(
    chain: Chain,
    path: _Path,
    a: tuple[float, FloatArray],
    b: tuple[float, FloatArray],
    success: bool,
    opts: _Options,
) -> tuple[str, tuple[float, float]]:
    """What is wrong with the step from sample ``a`` to ``b`` (``""``: nothing), and the
    deviation at its midpoint (m, rad; NaN where not measured)."""
    (s_a, q_a), (s_b, q_b) = a, b
    if not success:
        return "unsolved", (math.nan, math.nan)
    if _beyond(chain, q_b) is not None:
        return "limit", (math.nan, math.nan)
    step = float(np.max(np.abs(q_b - q_a)))
    if step > opts.max_step:
        return f"a joint moves {step:.3g} rad within ds < {S_RESOLUTION:g}", (math.nan, math.nan)
    mid = np.array([0.5 * (s_a + s_b)])
    p, o = _errors(chain.fk(0.5 * (q_a + q_b))[None], path.at(mid))
    if p[0] > opts.tol or o[0] > opts.ori_tol:
        return "the tool strays from the path between samples", (math.nan, math.nan)
    return "", (float(p[0]), float(o[0]))


def _numerical_stop(
    chain: Chain, a: tuple[float, FloatArray], T_b: FloatArray, q_b: FloatArray, why: str,
    opts: _Options,
) -> _Stop:  # fmt: skip
    """Why the numerical solve cannot go on from sample ``a`` to the pose ``T_b`` (``q_b``:
    the solve's answer there, taken continuously)."""
    s_a, q_a = a
    if why == "limit":
        k = _beyond(chain, q_b)
        assert k is not None
        return _limit_stop(chain, k, q_b, s_a)
    if why == "unsolved":
        free = dataclasses.replace(chain, limits=None)  # the same chain without its limits
        unlimited = free.ik(T_b, q_a, max_attempts=1)
        revolute = np.array([t == "revolute" for t in chain.joint_types])
        q_free = np.where(revolute, q_a + _wrap(unlimited.q - q_a), unlimited.q)
        k = _beyond(chain, q_free)
        near = np.max(np.abs(q_free - q_a)) <= opts.max_step
        if unlimited.success and near and k is not None:
            return _limit_stop(chain, k, q_free, s_a)
        if not chain.ik(T_b).success:  # random restarts: no configuration reaches it
            return _unreachable(chain, q_a, s_a)
        why = "the solve from the last sample finds no solution nearby"
    return _jump_stop(chain, q_a, s_a, why)


def follow(
    chain: Chain,
    T_path: ArrayLike | PathFunction,
    q0: ArrayLike,
    *,
    max_step: float = DEFAULT_MAX_STEP,
    tol: float = DEFAULT_TOL,
    ori_tol: float = DEFAULT_ORI_TOL,
    samples: int | None = None,
) -> FollowResult:
    """Joint values along a pose path from ``q0``, the branch kept (:meth:`poekin.Chain.follow`;
    the module's docstring describes the algorithm).

    Args:
        chain: the chain whose end frame follows the path.
        T_path: ``(N, 4, 4)`` poses of the end frame at ``s = 0, 1/(N-1), ..., 1`` (joined by
            screw motions), or a callable taking ``(m,)`` path parameters in [0, 1] to
            ``(m, 4, 4)`` poses.
        q0: ``(n,)`` the start, within the joint limits, its end frame on the path's start.
        max_step: the largest move of any joint between two samples (rad, m), > 0.
        tol: the largest position deviation from the path at the samples' midpoints (m), > 0.
        ori_tol: the largest rotation deviation there (rad), > 0.
        samples: a callable path's first samples (default :data:`DEFAULT_SAMPLES`), >= 2.

    Returns:
        A :class:`FollowResult`.

    Raises:
        InputError: a path that is not poses ``(N, 4, 4)`` (``N >= 2``) of finite rigid
            transforms nor a callable that returns them, ``q0`` of the wrong length, not finite,
            outside the limits or off the path's start, a tolerance or ``max_step`` that is not
            a number > 0, ``samples`` below 2 or given with an array path.
    """
    opts = _Options(
        _positive(max_step, "max_step", "rad"),
        _positive(tol, "tol", "m"),
        _positive(ori_tol, "ori_tol", "rad"),
    )
    path = _Path(T_path, samples)
    q = _start(chain, q0, path.poses[0], opts.tol, opts.ori_tol)
    branch = _closed_branch(chain, path.poses[0], q, opts.max_step)
    if branch is None:
        return _follow_numerical(chain, path, q, opts)
    return _follow_closed(chain, path, q, branch, opts)


# --- trees: one frame along the path, others held, the whole body solved ------------------------


def _tree_midpoint(tree: Tree, a: FloatArray, b: FloatArray) -> FloatArray:
    """The configuration half way from ``qpos`` ``a`` to ``b``: hinges, slides and a free
    joint's position linearly, every quaternion along the shorter arc."""
    from poekin.wholebody.space import quat_log_between, quat_times_exp, space

    mid = 0.5 * (a + b)
    for adr, _ in space(tree, ()).quats:
        w = quat_log_between(a[None, adr : adr + 4], b[None, adr : adr + 4])
        mid[adr : adr + 4] = quat_times_exp(a[None, adr : adr + 4], 0.5 * w)[0]
    return mid


def _tree_step(tree: Tree, a: FloatArray, b: FloatArray) -> float:
    """The largest move from ``a`` to ``b``: of a hinge or slide, a free joint's position, or a
    quaternion's angle (rad, m)."""
    from poekin.wholebody.space import quat_log_between, space

    sp = space(tree, ())
    moves = [np.abs(b[sp.scalar_q] - a[sp.scalar_q])]
    for adr, _ in sp.free_p:
        moves.append(np.abs(b[adr : adr + 3] - a[adr : adr + 3]))
    for adr, _ in sp.quats:
        w = quat_log_between(a[None, adr : adr + 4], b[None, adr : adr + 4])
        moves.append(np.linalg.norm(w, axis=-1))
    return float(np.max(np.concatenate(moves), initial=0.0))


def _tree_at_limit(tree: Tree, q: FloatArray) -> int | None:
    """A hinge or slide of ``qpos`` at one of its limits (within 1e-12), or None."""
    for k, kind in enumerate(tree.joint_types):
        if kind in ("revolute", "prismatic") and tree.mimics[k] is None:
            v, (lo, hi) = q[tree.qpos_adr[k]], tree.joint_limits[k]
            if abs(v - lo) <= 1e-12 or abs(v - hi) <= 1e-12:
                return k
    return None


def follow_tree(
    tree: Tree,
    T_path: ArrayLike | PathFunction,
    qpos0: ArrayLike,
    frame: str,
    *,
    hold: object = None,
    max_step: float = DEFAULT_MAX_STEP,
    tol: float = DEFAULT_TOL,
    ori_tol: float = DEFAULT_ORI_TOL,
    samples: int | None = None,
    freeze: tuple[str, ...] = (),
    position_only: tuple[str, ...] = (),
) -> FollowResult:
    """:meth:`poekin.Tree.follow`: ``frame`` along a pose path from ``qpos0``, the frames
    ``hold`` met exactly where they are at ``qpos0``, every joint of the tree solved for (a
    floating base too) by :meth:`poekin.Tree.ik` with a dict of targets from the previous
    sample, one attempt; re-sampled and stopped as :func:`follow` does (a tree has no closed
    form: ``branch`` and ``sigma_min`` are None). ``q`` is ``(K, nq)``, ``qpos``."""
    opts = _Options(
        _positive(max_step, "max_step", "rad"),
        _positive(tol, "tol", "m"),
        _positive(ori_tol, "ori_tol", "rad"),
    )
    path = _Path(T_path, samples)
    index = tree.frame_index(frame)  # an unknown frame: UnknownFrameError, with a suggestion
    q0 = as_joint_values(qpos0, tree.nq, what="qpos0 values", layout=tree.qpos_layout())
    if q0.shape != (tree.nq,):
        raise InputError(
            f"follow: qpos0 must be one configuration (shape ({tree.nq},)), got {q0.shape}"
        )
    held = [] if hold is None else ([hold] if isinstance(hold, str) else list(hold))  # type: ignore[call-overload]
    if frame in held:
        raise InputError(f"follow: {frame!r} both follows the path and is held; hold other frames")
    if frame in position_only:
        raise InputError(
            f"follow: {frame!r} follows the path's poses; position_only is for held frames"
        )
    poses = tree.fk(q0)
    fixed = {
        name: poses[tree.frame_index(name)][:3, 3]
        if name in position_only
        else poses[tree.frame_index(name)]
        for name in held
    }
    pos, ori = _errors(poses[index][None], path.poses[:1])
    if pos[0] > opts.tol or ori[0] > opts.ori_tol:
        raise InputError(
            f"follow: qpos0 puts {frame!r} {pos[0]:.3g} m and {ori[0]:.3g} rad from the path's "
            f"start (tol {opts.tol:g} m, ori_tol {opts.ori_tol:g} rad); start on the path"
        )

    def solve(T: FloatArray, start: FloatArray, attempts: int) -> tuple[FloatArray, bool]:
        found = tree.ik(
            {frame: T, **fixed},
            start,
            hold=set(held) or None,
            position_only=set(position_only) or None,
            freeze=freeze,
            max_attempts=attempts,
        )
        return np.asarray(found.qpos, dtype=np.float64), bool(found.success)

    def attempt(
        a: tuple[float, FloatArray], s_b: float, T_b: FloatArray
    ) -> tuple[FloatArray, str, tuple[float, float]]:
        s_a, q_a = a
        q_b, success = solve(T_b, q_a, 1)
        why = "" if success else "unsolved"
        if not why and _tree_step(tree, q_a, q_b) > opts.max_step:
            why = f"the body moves {_tree_step(tree, q_a, q_b):.3g} within ds < {S_RESOLUTION:g}"
        dev = (math.nan, math.nan)
        if not why:
            mid = tree.fk(_tree_midpoint(tree, q_a, q_b))[index]
            p, o = _errors(mid[None], path.at(np.array([0.5 * (s_a + s_b)])))
            dev = (float(p[0]), float(o[0]))
            if p[0] > opts.tol or o[0] > opts.ori_tol:
                why = "the frame strays from the path between samples"
        return q_b, why, dev

    def stop_at(a: tuple[float, FloatArray], T_b: FloatArray, q_b: FloatArray, why: str) -> _Stop:
        return _tree_stop(tree, solve, a, T_b, q_b, why)

    q, s, (pos_dev, ori_dev), stop = _walk(path, q0, attempt, stop_at)
    q.flags.writeable = False
    s.flags.writeable = False
    T = np.ascontiguousarray(tree.fk(q)[:, index])
    T.flags.writeable = False
    return FollowResult(
        q=q,
        s=s,
        T=T,
        fraction=float(s[-1]) if stop is not None else 1.0,
        reason="done" if stop is None else stop.reason,
        detail="" if stop is None else stop.detail,
        joint=None if stop is None else stop.joint,
        sigma_min=None,
        branch=None,
        max_deviation=float(np.max(pos_dev, initial=0.0)),
        max_ori_deviation=float(np.max(ori_dev, initial=0.0)),
    )


def _tree_stop(
    tree: Tree,
    solve: Callable[[FloatArray, FloatArray, int], tuple[FloatArray, bool]],
    a: tuple[float, FloatArray],
    T_b: FloatArray,
    q_b: FloatArray,
    why: str,
) -> _Stop:
    """Why the tree cannot go on from sample ``a`` to the pose ``T_b`` (``q_b``: the one-attempt
    solve's answer or best fit there)."""
    s_a, q_a = a
    if why == "unsolved":
        k = _tree_at_limit(tree, q_b)
        if k is not None:
            name = tree.joint_names[k]
            return _Stop(
                "joint_limit",
                f"joint {name!r} holds at its limit and the path cannot go on at s = {s_a:.6g}",
                joint=name,
            )
        if not solve(T_b, q_a, RESTARTS)[1]:
            return _Stop(
                "unreachable",
                f"no configuration reaches the path at s = {s_a:.6g} with the held frames "
                f"where they are ({RESTARTS} attempts)",
            )
        why = "the solve from the last sample finds no solution nearby"
    return _Stop("jump", f"a jump at s = {s_a:.6g}: {why}")


# --- collisions: the first colliding sample ends the path ---------------------------------------


def collision_stop(
    found: FollowResult,
    tree: Tree,
    qpos: FloatArray,
    obstacles: tuple[object, ...],
    margin: float,
    ignore: tuple[tuple[str, str], ...],
) -> FollowResult:
    """``found`` cut at its first sample whose configuration ``qpos (K, nq)`` (the tree's, for
    ``found.q``) has a checked pair closer than ``margin`` (m): reason ``"collision"``, the
    samples before it kept (the start alone if it collides), ``pair`` the closest pair there;
    ``found`` itself if no sample collides."""
    measured = tree.distances(qpos, obstacles, margin=margin, ignore=ignore)
    close = measured.distance < margin
    hit = np.flatnonzero(close.any(axis=-1))
    if not hit.size:
        return found
    k = int(hit[0])
    worst = int(np.argmin(measured.distance[k]))
    pair = measured.pairs[worst]
    depth = 1000 * float(measured.distance[k, worst])
    keep = max(k, 1)
    q, s, T = (np.array(a[:keep]) for a in (found.q, found.s, found.T))
    for a in (q, s, T):
        a.flags.writeable = False
    return dataclasses.replace(
        found,
        q=q,
        s=s,
        T=T,
        fraction=float(s[-1]) if k else 0.0,
        reason="collision",
        detail=(
            f"a collision at s = {float(found.s[k]):.6g}: {pair[0]} and {pair[1]} at "
            f"{depth:.1f} mm (margin {1000 * margin:.1f} mm)"
        ),
        joint=None,
        sigma_min=None,
        pair=pair,
    )
