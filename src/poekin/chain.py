"""The serial-chain model: screw axes, home pose, and Product-of-Exponentials forward kinematics.

Conventions (the same everywhere in poekin): a screw axis or twist is ``[w; v]`` (angular part
first), lengths are metres, angles radians, poses are homogeneous ``4x4`` matrices.

Space form (screws ``S_i`` in the world frame at ``q = 0``)::

    T_world_frame(q) = exp([S_1] q_1) ... exp([S_n] q_n) M

Body form (screws ``B_i = Ad(M^-1) S_i`` in the end frame at ``q = 0``)::

    T_world_frame(q) = M exp([B_1] q_1) ... exp([B_n] q_n)
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _fast, lie
from poekin._fast import Form
from poekin.errors import InputError, did_you_mean

__all__ = [
    "JACOBIAN_CONVENTIONS",
    "Chain",
    "JacobianConvention",
    "JointType",
    "as_joint_values",
    "check_jacobian_convention",
    "check_pose",
    "jacobian_from_world",
    "poe",
    "readonly_array",
]

JointType = Literal["revolute", "prismatic"]
FloatArray = NDArray[np.float64]

# A user-given screw axis must be unit length to this tolerance. Screws derived from MuJoCo are
# unit to ~1e-16 (the compiler normalises axes); hand-typed tables are usually good to ~1e-6.
_UNIT_TOL = 1e-6


def readonly_array(a: ArrayLike, shape: tuple[int, ...], name: str) -> FloatArray:
    arr = np.array(a, dtype=np.float64)  # always a copy: the chain owns its arrays
    if arr.shape != shape:
        raise InputError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or inf")
    arr.flags.writeable = False
    return arr


def check_pose(T: FloatArray, name: str) -> None:
    """Raise :class:`InputError` unless ``(4, 4)`` ``T`` is a rigid transform (to 1e-6)."""
    R = T[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=_UNIT_TOL) or np.linalg.det(R) < 0:
        raise InputError(f"{name}: the rotation block is not orthonormal with det +1")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError(f"{name}: the last row must be [0, 0, 0, 1]")


def as_joint_values(
    q: ArrayLike, n: int, *, what: str = "joint values", layout: str = ""
) -> FloatArray:
    """Validate joint values ``q`` of shape ``(..., n)`` and return them as float64.

    Integers and float32 are accepted and converted. Anything non-numeric, a wrong last axis,
    NaN or inf raises :class:`~poekin.errors.InputError`; ``what`` names the values in the
    message, and ``layout`` (if given) is appended to a wrong-shape message.
    """
    try:
        arr = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise InputError(f"{what} must be numbers, got {q!r:.60}") from e
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise InputError(
            f"expected {n} {what} (shape (..., {n})), got an array of shape {arr.shape}"
            + (f"; {layout}" if layout else "")
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what} contain NaN or inf; every value must be finite")
    return arr


@dataclasses.dataclass(frozen=True)
class _ScrewTerms:
    """Per-joint constants of ``exp([S] q)`` for unit screws ``S = [w; v]``, computed once.

    With ``|w| = 1`` (or ``w = 0, |v| = 1``), the rotation needs no small-angle branch
    (:func:`poekin.lie.axis_rotation`: exact ``cos``/``sin`` entries about a coordinate axis, else
    Rodrigues) and neither does the Murray-Li-Sastry form of the translation::

        R = I + sin(q) W + (1 - cos q) W^2
        p = (r - R r) + q u,   r = w x v,   u = (w . v) w  (u = v if w = 0)

    ``r`` is the point of the axis nearest the origin, so, unlike the textbook
    ``G(q) v = (q I + (1 - cos q) W + (q - sin q) W^2) v``, no term grows with ``q`` and
    cancels: the rounding stays at the size of the robot, not of ``q`` times it.
    """

    w: FloatArray  # (n, 3) rotation axes (0 for a prismatic screw)
    r: FloatArray  # (n, 3) w x v
    u: FloatArray  # (n, 3) (w . v) w, or v for a prismatic screw

    @classmethod
    def of(cls, screws: FloatArray) -> _ScrewTerms:
        w, v = screws[:, :3], screws[:, 3:]
        revolute = np.linalg.norm(w, axis=-1, keepdims=True) > 0
        u = np.where(revolute, np.sum(w * v, axis=-1, keepdims=True) * w, v)
        return cls(w, np.cross(w, v), u)


def _joint_factors(terms: _ScrewTerms, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``exp([S_i] q_i)`` of every joint as ``R (..., n, 3, 3)`` and ``p (..., n, 3)``."""
    R_i = np.empty((*q.shape, 3, 3))
    for i, w in enumerate(terms.w):
        R_i[..., i, :, :] = lie.axis_rotation(w, q[..., i]) if w.any() else np.eye(3)
    p_i = (terms.r - lie.rotate(R_i, terms.r)) + q[..., None] * terms.u
    return R_i, p_i


def space_jacobian(terms: _ScrewTerms, screws: FloatArray, q: FloatArray) -> FloatArray:
    """``(..., 6, n)`` space Jacobian: column ``i`` is ``Ad(T_{i-1}) S_i`` with
    ``T_{i-1} = exp([S_1] q_1) ... exp([S_{i-1}] q_{i-1})``, rows ``[w; v]``.

    ``Ad((R, p)) [w; v] = [R w; p x R w + R v]``; the partial products use the same joint
    factors as :func:`poe`.
    """
    R_i, p_i = _joint_factors(terms, q)
    batch, n = q.shape[:-1], screws.shape[0]
    J = np.empty((*batch, 6, n))
    R: FloatArray = np.broadcast_to(np.eye(3), (*batch, 3, 3))
    p = np.zeros((*batch, 3))
    for i in range(n):
        w = lie.rotate(R, screws[i, :3])
        J[..., :3, i] = w
        J[..., 3:, i] = np.cross(p, w) + lie.rotate(R, screws[i, 3:])
        p = p + lie.rotate(R, p_i[..., i, :])
        R = lie.rotate_compose(R, R_i[..., i, :, :]).astype(np.float64, copy=False)
    return J


JacobianConvention = Literal["space", "body", "world"]
JACOBIAN_CONVENTIONS: tuple[JacobianConvention, ...] = ("space", "body", "world")


def _columns_cross(J_w: FloatArray, p: FloatArray) -> FloatArray:
    """``w_i x p`` for every column ``w_i`` of ``J_w (..., 3, n)`` and one ``p (..., 3)``."""
    return np.swapaxes(np.cross(np.swapaxes(J_w, -1, -2), p[..., None, :]), -1, -2)


def jacobian_from_world(J: FloatArray, T: FloatArray, convention: str) -> FloatArray:
    """A world Jacobian ``J (..., 6, n)`` (rows ``[w; v_frame]``) of the frame at ``T (..., 4,
    4)`` in ``convention``: ``"world"`` as it is, ``"space"`` ``[w; v_frame - w x p]`` (the
    twist in the world frame), ``"body"`` both rows turned into the frame by ``R^T``."""
    check_jacobian_convention(convention)
    if convention == "world":
        return J
    if convention == "space":
        out: FloatArray = J.copy()
        out[..., 3:, :] = J[..., 3:, :] - _columns_cross(J[..., :3, :], T[..., :3, 3])
        return out
    R_t = np.swapaxes(T[..., :3, :3], -1, -2)
    body: FloatArray = np.concatenate([R_t @ J[..., :3, :], R_t @ J[..., 3:, :]], axis=-2)
    return body


def check_jacobian_convention(convention: object) -> None:
    """Raise :class:`InputError` (naming the valid ones) unless ``convention`` is one of
    :data:`JACOBIAN_CONVENTIONS`."""
    if convention not in JACOBIAN_CONVENTIONS:
        raise InputError(
            f"unknown Jacobian convention {convention!r}: "
            f"{did_you_mean(str(convention), list(JACOBIAN_CONVENTIONS))}"
        )


def poe(
    terms: _ScrewTerms, q: FloatArray, *, left: FloatArray | None, right: FloatArray | None
) -> FloatArray:
    """``left @ exp([S_1] q_1) ... exp([S_n] q_n) @ right`` for unit screws.

    The pure-NumPy reference path; the compiled kernel does the same arithmetic in the same
    order.

    Args:
        terms: the screws' constants, see :class:`_ScrewTerms`.
        q: ``(..., n)`` joint values.
        left, right: ``(4, 4)`` constant poses, or None for the identity.

    Returns:
        ``(..., 4, 4)`` poses.
    """
    batch = q.shape[:-1]
    R_i, p_i = _joint_factors(terms, q)
    R = np.broadcast_to(np.eye(3), (*batch, 3, 3))
    p = np.zeros((*batch, 3))
    factors = [(R_i[..., i, :, :], p_i[..., i, :]) for i in range(terms.r.shape[0])]
    if left is not None:
        factors.insert(0, (left[:3, :3], left[:3, 3]))
    if right is not None:
        factors.append((right[:3, :3], right[:3, 3]))
    for R_f, p_f in factors:
        p = p + lie.rotate(R, p_f)
        R = lie.rotate_compose(R, R_f).astype(np.float64, copy=False)
    T = np.zeros((*batch, 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


@dataclasses.dataclass(frozen=True, eq=False)
class Chain:
    """A serial chain of revolute and prismatic joints, as a PoE model. Immutable.

    Attributes:
        joint_names: ``n`` joint names, base to tip.
        joint_types: ``n`` of ``"revolute"`` / ``"prismatic"``.
        screws: ``(n, 6)`` space-frame unit screw axes ``S_i = [w; v]`` at ``q = 0``.
        home: ``(4, 4)`` ``M = T_world_frame(q = 0)``.
        limits: ``(n, 2)`` lower and upper joint limits (rad or m); ``-inf``/``inf`` if unlimited.
        frame: name of the end frame (site or body) that ``home`` and ``fk`` describe.
        robot: name of the robot or model file the chain came from ("" if typed by hand).
        qpos_indices: for a chain imported from MuJoCo, the index of each joint in ``qpos``, so
            ``chain.fk(data.qpos[list(chain.qpos_indices)])`` is the frame's pose; else None.
        body_screws: ``(n, 6)`` body-frame screws ``B_i = Ad(M^-1) S_i`` (derived).
    """

    joint_names: tuple[str, ...]
    joint_types: tuple[JointType, ...]
    screws: FloatArray
    home: FloatArray
    limits: FloatArray | None = None
    frame: str = "ee"
    robot: str = ""
    qpos_indices: tuple[int, ...] | None = None
    body_screws: FloatArray = dataclasses.field(init=False, repr=False)
    _space: _ScrewTerms = dataclasses.field(init=False, repr=False)
    _body: _ScrewTerms = dataclasses.field(init=False, repr=False)
    _space_kernel: Any = dataclasses.field(init=False, repr=False)
    _body_kernel: Any = dataclasses.field(init=False, repr=False)
    _jacobian_space_kernel: Any = dataclasses.field(init=False, repr=False)
    _jacobian_body_kernel: Any = dataclasses.field(init=False, repr=False)
    _jacobian_world_kernel: Any = dataclasses.field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        set_ = object.__setattr__
        set_(self, "joint_names", tuple(self.joint_names))
        set_(self, "joint_types", tuple(self.joint_types))
        if len(self.joint_types) != n:
            raise InputError(f"{n} joint names but {len(self.joint_types)} joint types")
        set_(self, "screws", readonly_array(self.screws, (n, 6), "screws"))
        set_(self, "home", readonly_array(self.home, (4, 4), "home"))
        limits = np.tile([-np.inf, np.inf], (n, 1)) if self.limits is None else self.limits
        lim = np.array(limits, dtype=np.float64)
        if lim.shape != (n, 2) or np.any(np.isnan(lim)) or np.any(lim[:, 0] > lim[:, 1]):
            raise InputError(f"limits must be (n, 2) = ({n}, 2) with lower <= upper")
        lim.flags.writeable = False
        set_(self, "limits", lim)
        if self.qpos_indices is not None:
            set_(self, "qpos_indices", tuple(int(i) for i in self.qpos_indices))
        self._check_screws()
        check_pose(self.home, "home pose M")
        body = lie.adjoint(lie.inverse(self.home)) @ self.screws.T
        body_screws = np.ascontiguousarray(body.T)
        body_screws.flags.writeable = False
        set_(self, "body_screws", body_screws)
        space, body = _ScrewTerms.of(self.screws), _ScrewTerms.of(self.body_screws)
        set_(self, "_space", space)
        set_(self, "_body", body)
        terms = dataclasses.astuple
        set_(self, "_space_kernel", _fast.chain_program(*terms(space), left=None, right=self.home))
        set_(self, "_body_kernel", _fast.chain_program(*terms(body), left=self.home, right=None))
        for c in JACOBIAN_CONVENTIONS:
            kernel = _fast.chain_jacobian_program(
                *terms(space), screws=self.screws, home=self.home, convention=c
            )
            set_(self, f"_jacobian_{c}_kernel", kernel)

    def _check_screws(self) -> None:
        for name, kind, S in zip(self.joint_names, self.joint_types, self.screws, strict=True):
            w, v = np.linalg.norm(S[:3]), np.linalg.norm(S[3:])
            if kind == "revolute" and abs(w - 1.0) > _UNIT_TOL:
                raise InputError(
                    f"joint {name!r}: a revolute screw needs a unit axis w, got |w| = {w:.6g}; "
                    "normalise it"
                )
            if kind == "prismatic" and (w > _UNIT_TOL or abs(v - 1.0) > _UNIT_TOL):
                raise InputError(
                    f"joint {name!r}: a prismatic screw is [0; v] with |v| = 1, "
                    f"got |w| = {w:.6g}, |v| = {v:.6g}"
                )
            if kind not in ("revolute", "prismatic"):
                raise InputError(
                    f"joint {name!r}: unknown joint type {kind!r}; use 'revolute' or 'prismatic'"
                )

    @property
    def n_joints(self) -> int:
        """Number of joints ``n``."""
        return len(self.joint_names)

    @_fast.fast_method("_space_kernel")
    def fk(self, q: ArrayLike, out: FloatArray | None = None, form: Form = "4x4") -> FloatArray:
        """Space-form PoE ``T_world_frame = exp([S_1] q_1) ... exp([S_n] q_n) M``.

        Args:
            q: ``(..., n)`` joint values, as MuJoCo stores them in ``qpos`` (rad, m).
            out: a C-contiguous float64 array of the result's shape to write into (returned);
                if an error is raised its contents are unspecified.
            form: ``"4x4"`` homogeneous matrices ``(..., 4, 4)``; ``"3x4"`` their top three
                rows ``[R | p]`` ``(..., 3, 4)``; ``"pos_quat"`` ``(..., 7)`` position then
                quaternion ``wxyz`` with ``w >= 0``.

        Returns:
            The pose of ``frame`` in the world (base) frame, for each configuration.
        """
        # the kernel has run already where it takes the arguments as they are (fast_method)
        kernel = self._space_kernel
        return _fast.evaluate(kernel, q, out, form, self._joint_values, self._fk_numpy)

    @_fast.fast_method("_body_kernel")
    def fk_body(
        self, q: ArrayLike, out: FloatArray | None = None, form: Form = "4x4"
    ) -> FloatArray:
        """Body-form PoE ``T_world_frame = M exp([B_1] q_1) ... exp([B_n] q_n)``.

        Same arguments and result as :meth:`fk`; equal to it to float precision.
        """
        kernel = self._body_kernel  # as in fk
        return _fast.evaluate(kernel, q, out, form, self._joint_values, self._fk_body_numpy)

    @_fast.fast_method("_jacobian_space_kernel")
    def jacobian_space(self, q: ArrayLike) -> FloatArray:
        """Space Jacobian ``J_s(q)``, ``(..., 6, n)``, rows ``[w; v]``: ``J_s q_dot`` is the end
        frame's twist in the world frame (Modern Robotics' ``JacobianSpace``; column ``i`` is
        ``Ad(T_{i-1}) S_i``). ``v`` is the velocity of the point at the world origin moving with
        the end frame, not of the frame's origin: see :meth:`jacobian_world` for that.
        """
        return self._jacobian("space", q)

    @_fast.fast_method("_jacobian_body_kernel")
    def jacobian_body(self, q: ArrayLike) -> FloatArray:
        """Body Jacobian ``J_b(q) = Ad(T^-1) J_s(q)``, ``(..., 6, n)``, rows ``[w; v]``: the end
        frame's twist in the end frame itself (Modern Robotics' ``JacobianBody``). It is
        :meth:`jacobian_world` with both rows turned into the end frame, ``R^T``."""
        return self._jacobian("body", q)

    @_fast.fast_method("_jacobian_world_kernel")
    def jacobian_world(self, q: ArrayLike) -> FloatArray:
        """World Jacobian, ``(..., 6, n)``, rows ``[w; v_frame]``, both in world coordinates:
        ``v_frame = v + w x p`` is the velocity of the end frame's origin ``p``. This is what
        MuJoCo's ``mj_jacSite``/``mj_jacBody`` return (as ``jacr``, ``jacp``) and Pinocchio's
        ``LOCAL_WORLD_ALIGNED`` (with its rows in the other order, ``[v; w]``)."""
        return self._jacobian("world", q)

    def _jacobian(self, convention: str, q: ArrayLike) -> FloatArray:
        """The compiled kernel's Jacobian for ``q`` to validate or convert first (the methods
        have tried the kernel on ``q`` as it is: fast_method), or the NumPy reference's."""
        kernel = getattr(self, f"_jacobian_{convention}_kernel")
        return _fast.run_checked(
            kernel,
            q,
            self._joint_values,
            functools.partial(self._jacobian_numpy, convention),
        )

    def _jacobian_numpy(self, convention: str, q: FloatArray) -> FloatArray:
        """The Jacobians' pure-NumPy reference path, for validated float64 ``q``."""
        J = space_jacobian(self._space, self.screws, q)
        if convention == "space":
            return J
        T = self._fk_numpy(q)
        J[..., 3:, :] = J[..., 3:, :] + _columns_cross(J[..., :3, :], T[..., :3, 3])
        return jacobian_from_world(J, T, convention)

    def _joint_values(self, q: ArrayLike) -> FloatArray:
        return as_joint_values(q, self.n_joints)

    def _fk_numpy(self, q: FloatArray) -> FloatArray:
        """:meth:`fk` on the pure-NumPy reference path (the compiled kernel's specification),
        for float64 ``q`` of shape ``(..., n)`` that :meth:`fk` has validated."""
        return poe(self._space, q, left=None, right=self.home)

    def _fk_body_numpy(self, q: FloatArray) -> FloatArray:
        """:meth:`fk_body` on the pure-NumPy reference path (``q`` as for :meth:`_fk_numpy`)."""
        return poe(self._body, q, left=self.home, right=None)

    def __repr__(self) -> str:
        joints = ", ".join(
            f"{n}({'R' if t == 'revolute' else 'P'})"
            for n, t in zip(self.joint_names, self.joint_types, strict=True)
        )
        source = f"{self.robot!r}, " if self.robot else ""
        return f"Chain({source}frame={self.frame!r}, joints=[{joints}])"

    def describe(self) -> dict[str, Any]:
        """A JSON-ready summary: joints, screws, body screws, home, limits."""
        return {
            "robot": self.robot,
            "frame": self.frame,
            "joints": [
                {
                    "name": n,
                    "type": t,
                    "screw": s.tolist(),
                    "body_screw": b.tolist(),
                    "limits": [float(lo), float(hi)],
                }
                for n, t, s, b, (lo, hi) in zip(
                    self.joint_names,
                    self.joint_types,
                    self.screws,
                    self.body_screws,
                    self.limits if self.limits is not None else [],
                    strict=True,
                )
            ],
            "home": self.home.tolist(),
        }
