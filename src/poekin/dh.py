"""Denavit-Hartenberg tables: forward kinematics, exact conversion to a PoE :class:`Chain`, and
extraction of a table from any serial chain.

Conventions (``convention=``):

* ``"standard"`` (Denavit & Hartenberg): row ``i`` is ``Rot_z(theta_i) Trans_z(d_i)
  Trans_x(a_i) Rot_x(alpha_i)``; joint ``i`` turns about (or slides along) ``z_{i-1}``.
* ``"modified"`` (Craig): row ``i`` is ``Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i)
  Trans_z(d_i)``; joint ``i`` turns about ``z_i``. The row stores ``a_{i-1}, alpha_{i-1}`` in
  its ``a, alpha`` fields.

A revolute joint adds ``q_i`` to ``theta_i = theta_offset_i + q_i``; a prismatic one adds it to
``d_i``. The pose of the end frame is ``T_world_frame(q) = base T_1(q_1) ... T_n(q_n) tool``.
Lengths are metres, angles radians.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import Chain, JointType, as_joint_values, check_pose, readonly_array
from poekin.errors import InputError

__all__ = [
    "CONVENTIONS",
    "NEAR_PARALLEL_SIN",
    "PARALLEL_SIN",
    "Convention",
    "DHTable",
    "dh_from_chain",
    "joint_lines",
    "nearest_dh",
]

Convention = Literal["standard", "modified"]
CONVENTIONS: tuple[Convention, ...] = ("standard", "modified")
FloatArray = NDArray[np.float64]

#: Two joint axes count as parallel when the sine of the angle between them is below this. Axes
#: a model declares parallel agree to ~1e-16; a deliberately tilted axis is tilted by far more.
PARALLEL_SIN = 1e-8
# Two axis lines count as intersecting (or coincident) when closer than this, in metres.
_INTERSECT_DIST = 1e-12
#: Axes closer than this to parallel (sine of the angle), but not parallel, put their common
#: normal far away (d ~ offset / sine^2): DH is ill-conditioned there, and extraction says so.
#: A calibrated arm's "parallel" axes are 1 to 10 mrad apart (the real arm in ur_calibration's
#: documentation has d2 = +439 m and d3 = -446 m at 1.4 and 6.9 mrad), so this is 0.05 (3 deg).
NEAR_PARALLEL_SIN = 0.05


def _link_matrices(
    convention: Convention, theta: FloatArray, d: FloatArray, a: FloatArray, alpha: FloatArray
) -> FloatArray:
    """``(..., n, 4, 4)`` row transforms from ``(..., n)`` theta, d and ``(n,)`` a, alpha."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.broadcast_to(np.cos(alpha), ct.shape), np.broadcast_to(np.sin(alpha), ct.shape)
    a = np.broadcast_to(a, ct.shape)
    T = np.zeros((*ct.shape, 4, 4))
    if convention == "standard":  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        T[..., 0, :] = np.stack([ct, -st * ca, st * sa, a * ct], axis=-1)
        T[..., 1, :] = np.stack([st, ct * ca, -ct * sa, a * st], axis=-1)
        T[..., 2, 1] = sa
        T[..., 2, 2] = ca
        T[..., 2, 3] = d
    else:  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
        T[..., 0, :] = np.stack([ct, -st, np.zeros_like(ct), a], axis=-1)
        T[..., 1, :] = np.stack([st * ca, ct * ca, -sa, -sa * d], axis=-1)
        T[..., 2, :] = np.stack([st * sa, ct * sa, ca, ca * d], axis=-1)
    T[..., 3, 3] = 1.0
    return T


@dataclasses.dataclass(frozen=True, eq=False)
class DHTable:
    """A Denavit-Hartenberg table of ``n`` rows plus base and tool transforms. Immutable.

    Attributes:
        convention: ``"standard"`` or ``"modified"`` (see the module docstring).
        a, alpha, d, theta_offset: ``(n,)`` row parameters (m, rad). In the modified
            convention row ``i`` holds ``a_{i-1}`` and ``alpha_{i-1}``. For a prismatic joint
            ``d`` is the offset at ``q = 0``; for a revolute one ``theta_offset`` is.
        joint_types: ``n`` of ``"revolute"`` / ``"prismatic"``.
        joint_names: ``n`` names; default ``joint1 ... jointn``.
        base: ``(4, 4)`` ``T_world_frame0``.
        tool: ``(4, 4)`` ``T_framen_end``.
        frame: name of the end frame.
        robot: where the table came from ("" if typed by hand).
        notes: free choices made when the table was extracted from a chain (parallel axes...).
    """

    convention: Convention
    a: FloatArray
    alpha: FloatArray
    d: FloatArray
    theta_offset: FloatArray
    joint_types: tuple[JointType, ...]
    joint_names: tuple[str, ...] = ()
    base: FloatArray = dataclasses.field(default_factory=lambda: np.eye(4))
    tool: FloatArray = dataclasses.field(default_factory=lambda: np.eye(4))
    frame: str = "ee"
    robot: str = ""
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if self.convention not in CONVENTIONS:
            raise InputError(
                f"unknown DH convention {self.convention!r}; use 'standard' (Denavit-Hartenberg) "
                "or 'modified' (Craig)"
            )
        n = len(self.joint_types)
        set_(self, "joint_types", tuple(self.joint_types))
        for t in self.joint_types:
            if t not in ("revolute", "prismatic"):
                raise InputError(f"unknown joint type {t!r}; use 'revolute' or 'prismatic'")
        names = tuple(self.joint_names) or tuple(f"joint{i + 1}" for i in range(n))
        if len(names) != n:
            raise InputError(f"{n} joint types but {len(names)} joint names")
        set_(self, "joint_names", names)
        for field in ("a", "alpha", "d", "theta_offset"):
            set_(self, field, readonly_array(getattr(self, field), (n,), field))
        for field in ("base", "tool"):
            T = readonly_array(getattr(self, field), (4, 4), field)
            check_pose(T, field)
            set_(self, field, T)
        set_(self, "notes", tuple(self.notes))

    @property
    def n_joints(self) -> int:
        """Number of rows (joints) ``n``."""
        return len(self.joint_types)

    def link_transforms(self, q: ArrayLike) -> FloatArray:
        """``(..., n, 4, 4)`` row transforms ``T_i(q_i)`` for ``(..., n)`` joint values."""
        q = as_joint_values(q, self.n_joints)
        prismatic = np.array([t == "prismatic" for t in self.joint_types], dtype=bool)
        theta = self.theta_offset + np.where(prismatic, 0.0, q)
        d = self.d + np.where(prismatic, q, 0.0)
        return _link_matrices(self.convention, theta, d, self.a, self.alpha)

    def fk(self, q: ArrayLike) -> FloatArray:
        """``T_world_frame(q) = base T_1(q_1) ... T_n(q_n) tool``.

        Args:
            q: ``(..., n)`` joint values (rad, m).

        Returns:
            ``(..., 4, 4)`` poses of the end frame.
        """
        links = self.link_transforms(q)
        T = np.broadcast_to(self.base, (*links.shape[:-3], 4, 4))
        for i in range(self.n_joints):
            T = T @ links[..., i, :, :]
        return np.asarray(T @ self.tool)

    def joint_frames(self) -> FloatArray:
        """``(n, 4, 4)`` pose at ``q = 0`` of a frame whose z axis is joint ``i``'s axis line.

        Standard convention: frame ``i-1`` (before row ``i``); modified: frame ``i``.
        """
        links = self.link_transforms(np.zeros(self.n_joints))
        frames = np.zeros((self.n_joints, 4, 4))
        T = self.base.copy()
        for i in range(self.n_joints):
            after = T @ links[i]
            frames[i] = T if self.convention == "standard" else after
            T = after
        return frames

    def to_chain(self) -> Chain:
        """The same kinematics as a PoE :class:`Chain` (space screws and ``M``), exactly.

        Joint ``i``'s screw is the z axis of :meth:`joint_frames` ``[i]``: ``[z; -z x o]`` if
        revolute, ``[0; z]`` if prismatic. ``M = fk(0)``.
        """
        frames = self.joint_frames()
        z, o = frames[:, :3, 2], frames[:, :3, 3]
        revolute = np.array([t == "revolute" for t in self.joint_types], dtype=bool)[:, None]
        screws = np.where(revolute, np.hstack([z, -np.cross(z, o)]), np.hstack([0 * z, z]))
        return Chain(
            joint_names=self.joint_names,
            joint_types=self.joint_types,
            screws=screws.reshape(self.n_joints, 6),
            home=self.fk(np.zeros(self.n_joints)),
            frame=self.frame,
            robot=self.robot,
        )

    def rows(self) -> list[dict[str, Any]]:
        """The rows as dicts ``{a, alpha, d, theta_offset, joint_type, joint}``."""
        return [
            {
                "a": float(a),
                "alpha": float(al),
                "d": float(d),
                "theta_offset": float(th),
                "joint_type": t,
                "joint": name,
            }
            for a, al, d, th, t, name in zip(
                self.a,
                self.alpha,
                self.d,
                self.theta_offset,
                self.joint_types,
                self.joint_names,
                strict=True,
            )
        ]

    def describe(self) -> dict[str, Any]:
        """A JSON-ready dict ``{convention, rows, base, tool}`` (plus robot, frame, notes)."""
        return {
            "convention": self.convention,
            "rows": self.rows(),
            "base": self.base.tolist(),
            "tool": self.tool.tolist(),
            "robot": self.robot,
            "frame": self.frame,
            "notes": list(self.notes),
        }

    def param_names(self) -> list[tuple[str, str, str, str]]:
        """Per row, the textbook names of its ``(a, alpha, d, theta)`` entries, e.g. ``a2``.

        The modified convention's ``a`` and ``alpha`` carry the index of the previous joint.
        """
        shift = 1 if self.convention == "modified" else 0
        return [
            (f"a{i - shift}", f"alpha{i - shift}", f"d{i}", f"theta{i}")
            for i in range(1, self.n_joints + 1)
        ]

    def __repr__(self) -> str:
        source = f"{self.robot!r}, " if self.robot else ""
        return f"DHTable({source}{self.convention}, {self.n_joints} rows, frame={self.frame!r})"


# --- extraction -------------------------------------------------------------------------------


def _rot_z_to(z: FloatArray) -> FloatArray:
    """The smallest rotation taking world z onto unit ``z``: world x moves as little as it can."""
    k = np.array([-z[1], z[0], 0.0])  # e_z x z: sin(angle) times the unit rotation axis
    s = float(np.linalg.norm(k))
    if s < 1e-15:  # z is +-e_z up to rounding
        return np.eye(3) if z[2] > 0.0 else np.diag([1.0, -1.0, -1.0])  # none, or pi about x
    # Rodrigues with sin = s, 1 - cos = 1 - z[2] and a unit axis. The form K + K^2 / (1 + cos)
    # would turn the ~1e-16 non-unitness of z into an error of 1e-16 / (1 + cos) near -e_z.
    K = lie.hat_so3(k / s)
    return np.asarray(np.eye(3) + s * K + (1.0 - z[2]) * (K @ K), dtype=np.float64)


def _angle_about(u: FloatArray, v: FloatArray, axis: FloatArray) -> float:
    """Signed angle from ``u`` to ``v`` about ``axis`` (all unit, u and v normal to axis)."""
    return float(np.arctan2(np.cross(u, v) @ axis, u @ v))


def _std_step(
    F: FloatArray, x_new: FloatArray, d: float, a: float, u: FloatArray
) -> tuple[float, float, float, float, FloatArray]:
    """Parameters ``(theta, d, a, alpha)`` and the frame ``F Rz Tz Tx Rx`` built from them."""
    z, xF = F[:3, 2], F[:3, 0]
    theta = _angle_about(xF, x_new, z)
    alpha = float(np.arctan2(np.cross(z, u) @ x_new, z @ u))
    link = _link_matrices("standard", np.array(theta), np.array(d), np.array(a), np.array(alpha))
    return theta, d, a, alpha, F @ link


def _to_line(
    F: FloatArray, point: FloatArray, u: FloatArray, parallel_sin: float
) -> tuple[float, float, float, float, FloatArray, str]:
    """One standard-DH step from frame ``F`` (z on the current axis) to the line
    ``point + s u``: the common normal gives ``x``, ``a`` and ``d``. Returns the row, the new
    frame, and which free choice was made ("" if none, "parallel", "coincident")."""
    z, o = F[:3, 2], F[:3, 3]
    cross = np.cross(z, u)
    s = float(np.linalg.norm(cross))
    w0 = point - o
    if s < parallel_sin:  # parallel: the common normal through o, so d = 0
        r = w0 - z * (w0 @ z)
        a = float(np.linalg.norm(r))
        if a < _INTERSECT_DIST:
            return (*_std_step(F, F[:3, 0], 0.0, 0.0, u), "coincident")
        return (*_std_step(F, r / a, 0.0, a, u), "parallel")
    # Foot of the normal on z: t = (z - (z.u) u).w0 / |z x u|^2, with z - (z.u) u = u x (z x u)
    # so that nearly parallel axes lose no digits to cancellation.
    t = float(np.cross(u, cross) @ w0) / (s * s)
    x = cross / s
    a = float((w0 - z * t) @ x)  # the normal's signed length along z x u
    if abs(a) < _INTERSECT_DIST:
        a = 0.0
    elif a < 0.0:
        x, a = -x, -a
    return (*_std_step(F, x, t, a, u), "")


def _end_step(
    F: FloatArray, end: FloatArray, *, slide_only: bool
) -> tuple[float, float, float, float, FloatArray]:
    """The last row: put frame ``n`` at the end frame's origin where the row allows it.

    Standard (``slide_only=False``): ``d`` along the axis, ``a`` across it, ``alpha`` turns z
    towards the end frame's z. Modified (``slide_only=True``): only ``theta`` and ``d``; the
    part of the offset across the axis stays in the tool.
    """
    z, o = F[:3, 2], F[:3, 3]
    w0 = end[:3, 3] - o
    d = float(w0 @ z)
    r = w0 - z * d
    a = float(np.linalg.norm(r))
    ez, ex = end[:3, 2], end[:3, 0]
    if a > _INTERSECT_DIST:
        x = r / a
    elif np.linalg.norm(np.cross(z, ez)) > PARALLEL_SIN:
        x = np.cross(z, ez)
        x /= np.linalg.norm(x)
    else:
        x = ex - z * (ex @ z)
        x /= np.linalg.norm(x)
    if slide_only:
        return _std_step(F, x, d, 0.0, z)
    u = ez - x * (ez @ x)
    norm = float(np.linalg.norm(u))
    return _std_step(F, x, d, a, u / norm if norm > PARALLEL_SIN else z)


def joint_lines(chain: Chain) -> tuple[FloatArray, FloatArray]:
    """``(n, 3)`` unit directions and points of the joint axis lines at ``q = 0``.

    A revolute joint's point is the foot on its axis of the previous joint's point (world origin
    for the first). A prismatic joint only fixes a direction, so its line is placed through the
    previous joint's point.
    """
    n = chain.n_joints
    dirs, points = np.zeros((n, 3)), np.zeros((n, 3))
    prev = np.zeros(3)
    for i, (kind, S) in enumerate(zip(chain.joint_types, chain.screws, strict=True)):
        if kind == "revolute":
            w = S[:3] / np.linalg.norm(S[:3])
            p = np.cross(w, S[3:])  # the axis point nearest the origin
            prev = p + w * ((prev - p) @ w)
        else:
            w = S[3:] / np.linalg.norm(S[3:])
        dirs[i], points[i] = w, prev
    return dirs, points


def dh_from_chain(
    chain: Chain, convention: Convention = "standard", *, parallel_tol: float = PARALLEL_SIN
) -> DHTable:
    """Extract a DH table whose FK equals ``chain.fk`` to float precision.

    Frames follow the joint axes and their common normals. The free choices, listed in the
    table's ``notes`` where they occur:

    * frame 0 sits on joint 1's axis at the foot of the world origin, turned from the world by
      the smallest rotation that aligns z with the axis (``base`` is the identity when joint 1
      is the world z axis);
    * parallel axes: the common normal through the previous frame's origin, so that ``d = 0``
      (standard ``d_i``, modified ``d_i`` of the earlier joint);
    * coincident axes: ``a = d = 0`` and the previous x axis is kept;
    * a prismatic axis is placed through the previous joint's axis point;
    * the last frame sits at the end frame's origin where the row allows it; ``tool`` holds the
      rest;
    * a chain placed with :meth:`~poekin.chain.Chain.with_base` or given a tool with
      :meth:`~poekin.chain.Chain.with_tool` keeps the robot's own rows: its base is put
      before the table's ``base`` and its tool after the table's ``tool``.

    Args:
        chain: any serial chain (revolute and prismatic joints).
        convention: ``"standard"`` or ``"modified"``.
        parallel_tol: axes closer than this to parallel (sine of the angle) are treated as
            parallel. The default only absorbs float rounding, so the table is exact. A model
            whose "parallel" axes are a little off (ufactory_lite6 rounds its quaternions, 7e-6
            rad) then gets a common normal kilometres away and FK rounding of ~1e-11 m; a larger
            ``parallel_tol`` gives a clean table instead, at the cost of the tilt it drops.
    """
    if convention not in CONVENTIONS:
        raise InputError(
            f"unknown DH convention {convention!r}; use 'standard' (Denavit-Hartenberg) or "
            "'modified' (Craig)"
        )
    robot = chain._unplaced()
    if robot is not chain:
        table = dh_from_chain(robot, convention, parallel_tol=parallel_tol)
        where = [
            f"its {k} in the table's {k}"
            for k in ("base", "tool")
            if getattr(chain, f"_{k}") is not None
        ]
        note = f"the chain is placed: {' and '.join(where)}; the rows are the robot's own"
        return dataclasses.replace(
            table,
            base=chain.base @ table.base,
            tool=table.tool @ chain.tool,
            notes=(*table.notes, note),
        )
    n = chain.n_joints
    dirs, points = joint_lines(chain)
    if n == 0:
        empty = np.zeros(0)
        return DHTable(
            convention,
            *(empty,) * 4,
            (),
            (),
            tool=chain.home,
            frame=chain.frame,
            robot=chain.robot,
            notes=(f"no joints between the world and {chain.frame!r}: the tool is the whole pose",),
        )
    base = np.asarray(lie.homogeneous(_rot_z_to(dirs[0]), points[0]), dtype=np.float64)
    a, alpha, d, theta = (np.zeros(n) for _ in range(4))
    notes: list[str] = []
    names = chain.joint_names
    F = base
    for i in range(n - 1):  # step i: from joint i's axis to joint i+1's (0-based)
        th, di, ai, al, F, choice = _to_line(F, points[i + 1], dirs[i + 1], parallel_tol)
        tilt = float(np.linalg.norm(np.cross(dirs[i], dirs[i + 1])))
        pair = f"joints {names[i]!r} and {names[i + 1]!r}"
        if choice and tilt > PARALLEL_SIN:
            notes.append(
                f"{pair} are {tilt:.2g} rad from parallel, treated as parallel (d{i + 1} = 0): "
                f"FK is off by about {tilt:.1g} rad times the reach"
            )
        elif choice == "parallel":
            notes.append(f"{pair} have parallel axes: chose d{i + 1} = 0")
        elif choice == "coincident":
            notes.append(f"{pair} share one axis line: a = d = 0, x axis kept")
        elif tilt < NEAR_PARALLEL_SIN:
            notes.append(
                f"{pair} are nearly parallel ({tilt:.2g} rad): DH is ill-conditioned here "
                f"(d{i + 1} = {di:.3g} m)"
            )
        theta[i], d[i] = th, di
        if convention == "standard":
            a[i], alpha[i] = ai, al
        else:
            a[i + 1], alpha[i + 1] = ai, al
    th, dn, an, al, F = _end_step(F, chain.home, slide_only=convention == "modified")
    theta[n - 1], d[n - 1] = th, dn
    if convention == "standard":
        a[n - 1], alpha[n - 1] = an, al
    for i, kind in enumerate(chain.joint_types):
        if kind == "prismatic":
            notes.append(
                f"joint {names[i]!r} is prismatic: its axis placed through the previous axis point"
            )
    tool = lie.inverse(F) @ chain.home
    tool[3] = [0.0, 0.0, 0.0, 1.0]
    return DHTable(
        convention,
        a,
        alpha,
        d,
        theta,
        chain.joint_types,
        names,
        base=base,
        tool=np.asarray(tool, dtype=np.float64),
        frame=chain.frame,
        robot=chain.robot,
        notes=tuple(notes),
    )


# --- the nearest table of a chain whose nearly parallel axes DH cannot hold well ----------------

_FIT_SAMPLES, _FIT_ITERATIONS = 500, 50


def _sample(chain: Chain, samples: int, seed: int) -> FloatArray:
    """``(samples, n)`` random q within the limits, ``[-pi, pi]`` (or +-1 m) where unlimited."""
    assert chain.limits is not None
    wide = np.where([t == "revolute" for t in chain.joint_types], np.pi, 1.0)
    low = np.maximum(chain.limits[:, 0], -wide)
    high = np.minimum(chain.limits[:, 1], wide)
    rng = np.random.default_rng(seed)
    return np.asarray(rng.uniform(low, high, size=(samples, chain.n_joints)), dtype=np.float64)


def nearest_dh(
    chain: Chain,
    convention: Convention = "standard",
    *,
    parallel_tol: float = NEAR_PARALLEL_SIN,
    samples: int = _FIT_SAMPLES,
    seed: int = 1,
) -> DHTable:
    """The DH table, with axes within ``parallel_tol`` of parallel made parallel, whose FK is
    nearest the chain's: least squares over random configurations.

    A calibrated arm's "parallel" axes are a few milliradians off, and its exact table
    (:func:`dh_from_chain`) puts their common normals metres away. Taken as parallel (``d =
    0``), DH keeps their tilt about the common normal (``alpha``) but cannot hold the tilt
    within their plane, so the table's FK is off by that tilt times the reach. This starts from
    that table and fits every other parameter (``a``, ``alpha``, ``theta_offset``, the other
    ``d``, base and tool) to the chain's poses, position errors and orientation errors times
    the chain's reach weighed alike (Levenberg-Marquardt, central differences): the remaining
    error is what DH with those axes parallel cannot hold.

    Args:
        chain: a serial chain.
        convention: ``"standard"`` or ``"modified"``.
        parallel_tol: axes closer than this to parallel (sine) are made parallel.
        samples, seed: the random configurations fitted on (within the limits).

    Returns:
        The table; its ``notes`` say which axes were made parallel.
    """
    start = dh_from_chain(chain, convention, parallel_tol=parallel_tol)
    n = chain.n_joints
    dirs, _ = joint_lines(chain)
    tilts = np.linalg.norm(np.cross(dirs[:-1], dirs[1:]), axis=1)
    fixed = np.flatnonzero(tilts < parallel_tol)  # steps whose d the parallel choice set to 0
    free_d = np.setdiff1d(np.arange(n), fixed)
    q = _sample(chain, samples, seed)
    T_ref = chain.fk(q)
    reach = max(float(np.max(np.linalg.norm(T_ref[:, :3, 3] - T_ref[:1, :3, 3], axis=1))), 1e-3)

    def table(x: FloatArray) -> DHTable:
        d = start.d.copy()
        d[free_d] = x[3 * n : 3 * n + len(free_d)]
        k = 3 * n + len(free_d)
        return dataclasses.replace(
            start,
            a=x[:n],
            alpha=x[n : 2 * n],
            theta_offset=x[2 * n : 3 * n],
            d=d,
            base=np.asarray(start.base @ lie.exp_se3(x[k : k + 6]), dtype=np.float64),
            tool=np.asarray(start.tool @ lie.exp_se3(x[k + 6 : k + 12]), dtype=np.float64),
        )

    def residual(x: FloatArray) -> FloatArray:
        T = table(x).fk(q)
        dp = T[:, :3, 3] - T_ref[:, :3, 3]
        dR = lie.log_so3(np.swapaxes(T_ref[:, :3, :3], -1, -2) @ T[:, :3, :3])
        return np.concatenate([dp.ravel(), reach * np.asarray(dR).ravel()])

    x = np.concatenate([start.a, start.alpha, start.theta_offset, start.d[free_d], np.zeros(12)])
    r = residual(x)
    cost, damping, step = float(r @ r), 1e-3, 1e-7
    for _ in range(_FIT_ITERATIONS):
        J = np.empty((len(r), len(x)))
        for j in range(len(x)):
            e = np.zeros_like(x)
            e[j] = step
            J[:, j] = (residual(x + e) - residual(x - e)) / (2 * step)
        A, g = J.T @ J, J.T @ r
        while damping < 1e12:
            dx = np.linalg.solve(A + damping * np.diag(np.diag(A) + 1e-12), -g)
            r_new = residual(x + dx)
            new_cost = float(r_new @ r_new)
            if new_cost < cost:
                break
            damping *= 10.0
        else:
            break
        done = cost - new_cost <= 1e-12 * cost
        x, r, cost, damping = x + dx, r_new, new_cost, max(damping / 10.0, 1e-12)
        if done:
            break
    pairs = ", ".join(f"{i + 1}-{i + 2}" for i in fixed)
    note = (
        f"fitted to the chain's FK on {samples} random q with axes {pairs} made parallel "
        "(the nearest table DH can give)"
    )
    return dataclasses.replace(table(x), notes=(*start.notes, note))
