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
import inspect
import types
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _pose, arrays, lie
from poekin._poe import (
    ChainParams,
    Column,
    _Model,
    _Screw,
    _ScrewTerms,
    _shown,
    _traced_screws,
    as_joint_values,
    check_shape,
    keep_chain_terms,
    poe,
    pose_of,
    real_array,
    space_jacobian,
    world_columns,
)
from poekin.errors import InputError, did_you_mean
from poekin.kernel import _fast
from poekin.kernel._fast import Form

if TYPE_CHECKING:
    from poekin.ik.analytic import IKSolutions
    from poekin.ik.numerical import IKResult
    from poekin.motion.follow import FollowResult

__all__ = [
    "IDENTITY",
    "JACOBIAN_CONVENTIONS",
    "QUAT_TOL",
    "Chain",
    "ChainParams",
    "JacobianConvention",
    "JointType",
    "as_joint_values",
    "check_jacobian_convention",
    "check_pose",
    "jacobian_from_world",
    "poe",
    "pos_quat_poses",
    "readonly_array",
    "real_array",
    "relative_jacobian",
    "rigid_transform",
]

JointType = Literal["revolute", "prismatic"]
FloatArray = NDArray[np.float64]

#: The ``(4, 4)`` identity, read-only: the base and tool of a chain that has none.
IDENTITY = np.eye(4)
IDENTITY.flags.writeable = False

# A user-given screw axis must be unit length to this tolerance. Screws derived from MuJoCo are
# unit to ~1e-16 (the compiler normalises axes); hand-typed tables are usually good to ~1e-6.
_UNIT_TOL = 1e-6


# Chain.as_tree's builder, poekin.tree.tree_of_chain: poekin.tree (which imports this module,
# and which poekin's __init__ imports) registers it, so that the model's two classes import
# each other in one direction only
_TREE_OF_CHAIN: list[Callable[[Chain], Any]] = []


def register_tree_of_chain(build: Callable[[Chain], Any]) -> None:
    """Set :meth:`Chain.as_tree`'s builder (poekin.tree does, when imported)."""
    _TREE_OF_CHAIN[:] = [build]


@functools.cache
def _numerical() -> types.ModuleType:
    """:mod:`poekin.ik.numerical`, imported at first use (it imports this module's users)."""
    from poekin.ik import numerical

    return numerical


@functools.cache
def _analytic() -> types.ModuleType:
    """:mod:`poekin.ik.analytic`, imported at first use."""
    from poekin.ik import analytic

    return analytic


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


#: A quaternion given with a position (``x y z qw qx qy qz``) must have a norm within this of 1;
#: it is then scaled to unit length, which does not change the rotation it stands for. Any
#: other, zero included, is refused, never normalised: it is most likely a typo.
QUAT_TOL = 1e-6
_QUAT_TOL_TEXT = f"{QUAT_TOL:.0e}".replace("e-0", "e-")  # 1e-6


def pos_quat_poses(rows: FloatArray, where: Callable[[int], str]) -> FloatArray:
    """``(N, 7)`` finite rows ``x y z qw qx qy qz`` (m, quaternion w first) as ``(N, 4, 4)``
    poses. ``where(k)`` names row ``k`` in a message.

    Raises:
        InputError: a quaternion whose norm is not within :data:`QUAT_TOL` of 1 (zero
            included); the message offers the unit quaternion it may stand for.
    """
    T = np.tile(np.eye(4), (len(rows), 1, 1))
    T[:, :3, 3] = rows[:, :3]
    quat = rows[:, 3:]
    norm = np.linalg.norm(quat, axis=-1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > QUAT_TOL)
    if bad.size:
        k = int(bad[0])
        shown = " ".join(f"{x:g}" for x in quat[k])
        if norm[k] == 0:
            raise InputError(
                f"{where(k)}: the quaternion is zero ({shown}); give a unit quaternion "
                "QW QX QY QZ, such as 1 0 0 0 for the world's orientation"
            )
        unit = " ".join(f"{x:.9g}" for x in quat[k] / norm[k])
        raise InputError(
            f"{where(k)}: the quaternion QW QX QY QZ = {shown} has norm {norm[k]:.9g}, not 1 "
            f"(|q| must be within {_QUAT_TOL_TEXT} of 1; poekin does not normalise it): give a "
            f"unit quaternion, such as {unit}"
        )
    T[:, :3, :3] = lie.quat_to_rotation(quat / norm[:, None])
    return T


def rigid_transform(T: Any, name: str) -> FloatArray:
    """``T`` as a new ``(4, 4)`` float64 rigid transform.

    ``T`` is a ``(4, 4)`` matrix (its rotation orthonormal with det +1 to 1e-6, used as given;
    its last row ``[0, 0, 0, 1]``) or seven numbers ``x y z qw qx qy qz`` (m, and a quaternion
    w first whose norm is within :data:`QUAT_TOL` of 1, scaled to unit length).

    Raises:
        InputError: anything else (another shape, not numbers, NaN or inf, a reflection, a
            zero quaternion...); the message starts with ``name``.
    """
    try:
        shape: tuple[int, ...] | None = np.shape(T)
    except ValueError:  # ragged nested lists
        shape = None
    if shape not in ((4, 4), (7,)):
        got = f"an array of shape {shape}" if shape else _shown(T)
        raise InputError(
            f"{name} must be a (4, 4) rigid transform or 7 numbers x y z qw qx qy qz (m, unit "
            f"quaternion w first), got {got}"
        )
    arr = as_joint_values(T, shape[-1], what=f"{name} entries")
    if shape == (7,):
        pose: FloatArray = pos_quat_poses(arr[None], lambda _: name)[0]
        return pose
    check_pose(arr, name)
    return np.array(arr, dtype=np.float64)


JacobianConvention = Literal["space", "body", "world"]
JACOBIAN_CONVENTIONS: tuple[JacobianConvention, ...] = ("space", "body", "world")


def jacobian_from_world(
    columns: Sequence[Column], pose: _pose.Pose, convention: str
) -> list[Column]:
    """World columns ``[w; v_frame]`` of the frame at ``pose = (R, p)`` in ``convention``:
    ``"world"`` as they are, ``"space"`` ``[w; v_frame - w x p]`` (the twist in the world
    frame), ``"body"`` both halves turned into the frame by ``R^T``."""
    check_jacobian_convention(convention)
    if convention == "world":
        return list(columns)
    R, p = pose
    out = []
    for c in columns:
        if convention == "space":
            wp = _pose.cross(c[:3], p)
            out.append((c[0], c[1], c[2], c[3] - wp[0], c[4] - wp[1], c[5] - wp[2]))
        else:
            R_t = _pose.transpose(R)
            out.append((*_pose.mat_vec(R_t, c[:3]), *_pose.mat_vec(R_t, c[3:])))
    return out


def relative_jacobian(
    J_frame: Any, J_ref: Any, T_world_frame: Any, T_world_ref: Any, convention: str
) -> Any:
    """The Jacobian of ``T_ref_frame(q) = T_world_ref^-1 T_world_frame``: how a frame moves as
    seen from another, moving or not, frame ``ref``, which takes the world's role.

    Args:
        J_frame, J_ref: ``(..., 6, n)`` world-convention Jacobians of both frames (rows
            ``[w; v_origin]`` in world coordinates, as ``Tree.jacobian(..., "world")``), over the
            same ``n`` velocities.
        T_world_frame, T_world_ref: ``(..., 4, 4)`` their poses.
        convention: ``"world"``: ``[w; v]``, the angular velocity of ``frame`` relative to
            ``ref`` and the velocity of its origin in ``ref``, both in ``ref``'s coordinates;
            ``"space"``: the twist of ``T_ref_frame`` in ``ref``'s frame; ``"body"``: in
            ``frame``'s (:func:`jacobian_from_world` with ``ref`` as the world).

    Returns:
        ``(..., 6, n)``, of the inputs' library.
    """
    check_jacobian_convention(convention)
    kind = arrays.kind_of(J_frame)
    xp = np if kind is None else arrays.namespace(kind)
    R_ref, p_ref = pose_of(T_world_ref)
    R_frame, p_frame = pose_of(T_world_frame)
    R_t = _pose.transpose(R_ref)
    d = (p_frame[0] - p_ref[0], p_frame[1] - p_ref[1], p_frame[2] - p_ref[2])
    columns = []
    for c in range(J_frame.shape[-1]):
        f = [J_frame[..., r, c] for r in range(6)]
        a = [J_ref[..., r, c] for r in range(6)]
        arm = _pose.cross(a[:3], d)  # the velocity of ref's points where frame's origin is
        w = [f[k] - a[k] for k in range(3)]
        v = [f[3 + k] - a[3 + k] - arm[k] for k in range(3)]
        columns.append((*_pose.mat_vec(R_t, w), *_pose.mat_vec(R_t, v)))
    pose = (_pose.mat_mat(R_t, R_frame), _pose.mat_vec(R_t, d))  # T_ref_frame
    like = xp.zeros_like(J_frame[..., 0, 0])
    return jacobian_array(jacobian_from_world(columns, pose, convention), xp, like)


def jacobian_array(columns: Sequence[Column], xp: Any, like: Any) -> Any:
    """``(..., 6, n)`` from ``n`` columns of six entries."""
    entries = [c[r] for r in range(6) for c in columns]
    return _pose.stack(entries, (6, len(columns)), xp, like)


def check_jacobian_convention(convention: object) -> None:
    """Raise :class:`InputError` (naming the valid ones) unless ``convention`` is one of
    :data:`JACOBIAN_CONVENTIONS`."""
    if convention not in JACOBIAN_CONVENTIONS:
        raise InputError(
            f"unknown Jacobian convention {convention!r}: "
            f"{did_you_mean(str(convention), list(JACOBIAN_CONVENTIONS))}"
        )


def zeros_like_batch(q: Any, xp: Any) -> Any:
    """Zeros of ``q``'s batch shape (all axes but the last), dtype and device."""
    return xp.zeros_like(q[..., 0]) if q.shape[-1] else xp.sum(q, axis=-1)


def generic_inputs(
    q: Any, n: int, leaves: Sequence[Any], out: Any, *, what: str = "joint values", layout: str = ""
) -> tuple[Any, Any, Any]:
    """The generic path's inputs: the namespace of ``q`` and the parameter ``leaves`` (JAX,
    PyTorch, or NumPy if neither), ``q`` as an ``(..., n)`` array of it in the result's float
    dtype (:mod:`poekin.arrays`), and zeros of the batch shape in that dtype, on that device.

    NumPy values are validated as :func:`as_joint_values` does; JAX and PyTorch values only by
    their shape (NaN and inf pass: see :mod:`poekin.arrays`).
    """
    xp, kind = arrays.namespace_of([q, *leaves], "q and params")
    if out is not None:
        raise InputError("out= takes NumPy arrays only; JAX and PyTorch results are new arrays")
    if kind is None:
        for leaf in leaves:
            if not np.all(np.isfinite(np.asarray(leaf, dtype=np.float64))):
                raise InputError("params contain NaN or inf; every value must be finite")
        checked = as_joint_values(q, n, what=what, layout=layout)
        return np, checked, zeros_like_batch(checked, np)
    anchor = next(a for a in (q, *leaves) if arrays.kind_of(a) is not None)
    try:
        dtype = arrays.float_dtype(xp, [q, *leaves])
        arr = arrays.convert(q, xp, dtype, anchor)
    except (TypeError, ValueError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(f"{what} must be numbers, got {q!r:.60}") from e
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise InputError(
            f"expected {n} {what} (shape (..., {n})), got an array of shape {tuple(arr.shape)}"
            + (f"; {layout}" if layout else "")
        )
    return xp, arr, zeros_like_batch(arr, xp)


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

    :meth:`with_base` and :meth:`with_tool` place the robot in a cell: the new chain's screws
    and home pose include the base and the tool, and its :attr:`base` and :attr:`tool` say which
    (:attr:`base` and :attr:`tool` record them; they do not act again on ``fk``).
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
    _constants: _Model = dataclasses.field(init=False, repr=False)
    _space_kernel: Any = dataclasses.field(init=False, repr=False)
    _body_kernel: Any = dataclasses.field(init=False, repr=False)
    _jacobian_space_kernel: Any = dataclasses.field(init=False, repr=False)
    _jacobian_body_kernel: Any = dataclasses.field(init=False, repr=False)
    _jacobian_world_kernel: Any = dataclasses.field(init=False, repr=False)
    # what inverse kinematics derives from the chain, at first use (poekin.ik.numerical)
    _ik_cache: dict[Any, Any] = dataclasses.field(init=False, repr=False, compare=False)
    # the compiled calls of ik(T[, q0]) and ik_all(T) with their other arguments at the
    # defaults, once the first call has built what they need (fast_method's (fn, *bound))
    _ik_quick: Any = dataclasses.field(default=None, init=False, repr=False, compare=False)
    _ik_all_quick: Any = dataclasses.field(default=None, init=False, repr=False, compare=False)
    # ik's defaults of pos_tol, ori_tol, position_only, orientation_weight, max_iterations and
    # max_attempts, the options of its call in C (read below the class from the signature as
    # written, whatever later wraps or replaces the method)
    _IK_DEFAULTS: ClassVar[tuple[float, float, bool, float, int, int]]
    # T_world_base and T_flange_tool that with_base and with_tool folded into screws and home
    _base: FloatArray | None = dataclasses.field(default=None, repr=False, kw_only=True)
    _tool: FloatArray | None = dataclasses.field(default=None, repr=False, kw_only=True)
    # the tree (loaded from a model file) whose joints from the world these are
    # (Tree.chain), which knows the robot's collision geometry; None: none known
    _tree: Any = dataclasses.field(default=None, repr=False, compare=False, kw_only=True)

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
        for placed in ("_base", "_tool"):
            if getattr(self, placed) is not None:
                value = rigid_transform(getattr(self, placed), placed[1:])
                value.flags.writeable = False
                set_(self, placed, value)
        self._check_screws()
        check_pose(self.home, "home pose M")
        body = lie.adjoint(lie.inverse(self.home)) @ self.screws.T
        body_screws = np.ascontiguousarray(body.T)
        body_screws.flags.writeable = False
        set_(self, "body_screws", body_screws)
        space, body = _ScrewTerms.of(self.screws), _ScrewTerms.of(self.body_screws)
        set_(self, "_space", space)
        set_(self, "_body", body)
        rows = [tuple(float(x) for x in row) for row in self.screws]
        set_(self, "_constants", _Model(space.joints(), rows, pose_of(self.home), body.joints()))
        set_(self, "_ik_cache", {})
        keep_chain_terms(self)
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

    @property
    def base(self) -> FloatArray:
        """``(4, 4)`` ``T_world_base``: where :meth:`with_base` placed the robot (the product of
        every placement, the identity if none). The screws and home pose include it."""
        return IDENTITY if self._base is None else self._base

    @property
    def tool(self) -> FloatArray:
        """``(4, 4)`` ``T_flange_tool``: the tool :meth:`with_tool` mounted (the product of
        every tool, the identity if none), in the frame it was mounted on. The home pose
        includes it."""
        return IDENTITY if self._tool is None else self._tool

    def with_tool(self, T_flange_tool: ArrayLike, *, frame: str = "tool") -> Chain:
        """This chain with a tool mounted on its end frame (the flange):
        ``T_world_tool(q) = T_world_flange(q) T_flange_tool``.

        Everything then describes the tool frame: :meth:`fk` and :meth:`fk_body`, the
        Jacobians, :meth:`ik` and :meth:`ik_all` (targets are the tool's poses), and
        :func:`~poekin.dh.dh_from_chain` (the robot's own rows, the tool in the table's
        ``tool``). The home pose becomes ``M T_flange_tool``; the space screws do not change.

        Tools compose: ``chain.with_tool(A).with_tool(B)`` is ``chain.with_tool(A @ B)``
        (``B`` is given in ``A``'s frame), and :attr:`tool` is their product.

        Args:
            T_flange_tool: the tool frame in the end frame: a ``(4, 4)`` rigid transform, or
                seven numbers ``x y z qw qx qy qz`` (m, unit quaternion w first).
            frame: the new end frame's name.

        Raises:
            InputError: ``T_flange_tool`` is not a rigid transform (:func:`rigid_transform`),
                or ``frame`` is not a non-empty string.

        Example:
            >>> chain = poekin.load("universal_robots_ur5e")
            >>> gripper = chain.with_tool([0, 0, 0.15, 1, 0, 0, 0])  # 15 cm along the flange's z
            >>> gripper.frame, float(gripper.tool[2, 3])
            ('tool', 0.15)
        """
        T = rigid_transform(T_flange_tool, "tool")
        if not isinstance(frame, str) or not frame:
            raise InputError(f"frame must be a non-empty name, got {frame!r:.40}")
        return dataclasses.replace(self, home=self.home @ T, frame=frame, _tool=self.tool @ T)

    def with_base(self, T_world_base: ArrayLike) -> Chain:
        """This chain with its base placed in a new world frame:
        ``T_world_frame(q) = T_world_base T_base_frame(q)``, where ``T_base_frame`` is this
        chain's :meth:`fk`.

        Everything then works in the new world: :meth:`fk`, the Jacobians (space: twists in
        the new world; world: its coordinates), :meth:`ik` and :meth:`ik_all` (targets in the
        new world) and :func:`~poekin.dh.dh_from_chain` (the robot's own rows, the base in the
        table's ``base``). The screws become ``Ad(T_world_base) S_i``, the home pose
        ``T_world_base M``; the body screws do not change.

        Bases compose: ``chain.with_base(A).with_base(B)`` is ``chain.with_base(B @ A)`` (the
        world of ``A`` placed at ``B``), and :attr:`base` is their product.

        Args:
            T_world_base: the robot's base frame in the new world: a ``(4, 4)`` rigid
                transform, or seven numbers ``x y z qw qx qy qz`` (m, unit quaternion w first).

        Raises:
            InputError: ``T_world_base`` is not a rigid transform (:func:`rigid_transform`).
        """
        B = rigid_transform(T_world_base, "base")
        screws = self.screws @ np.asarray(lie.adjoint(B), dtype=np.float64).T
        return dataclasses.replace(self, screws=screws, home=B @ self.home, _base=B @ self.base)

    def _unplaced(self) -> Chain:
        """The robot alone: this chain without its :attr:`base` and :attr:`tool` (its
        screws in the robot's base frame, its home pose the flange's)."""
        if self._base is None and self._tool is None:
            return self
        to_base = np.asarray(lie.inverse(self.base), dtype=np.float64)
        from_tool = np.asarray(lie.inverse(self.tool), dtype=np.float64)
        return dataclasses.replace(
            self,
            screws=self.screws @ np.asarray(lie.adjoint(to_base), dtype=np.float64).T,
            home=to_base @ self.home @ from_tool,
            _base=None,
            _tool=None,
        )

    @_fast.fast_method("_space_kernel")
    def fk(
        self,
        q: ArrayLike,
        out: FloatArray | None = None,
        form: Form = "4x4",
        *,
        params: ChainParams | None = None,
    ) -> FloatArray:
        """Space-form PoE ``T_world_frame = exp([S_1] q_1) ... exp([S_n] q_n) M``.

        Args:
            q: ``(..., n)`` joint values, as MuJoCo stores them in ``qpos`` (rad, m): a NumPy
                array (or anything NumPy converts), a JAX array or a PyTorch tensor.
            out: a C-contiguous float64 array of the result's shape to write into (returned);
                if an error is raised its contents are unspecified. NumPy only.
            form: ``"4x4"`` homogeneous matrices ``(..., 4, 4)``; ``"3x4"`` their top three
                rows ``[R | p]`` ``(..., 3, 4)``; ``"pos_quat"`` ``(..., 7)`` position then
                quaternion ``wxyz`` with ``w >= 0``.
            params: screws and home pose to use instead of the chain's own
                (:meth:`parameters`), e.g. JAX arrays or tensors with ``requires_grad`` to
                differentiate with respect to them; the joint types stay the chain's.

        Returns:
            The pose of ``frame`` in the world (base) frame, for each configuration: a NumPy
            float64 array for NumPy input, else an array of ``q``'s (or ``params``') library,
            device and float dtype (:mod:`poekin.arrays`). JAX and PyTorch values are not
            checked for NaN or inf (that would branch on traced values or wait for a device).
        """
        # the kernel has run already where it takes the arguments as they are (fast_method)
        return self._fk("space", q, out, form, params)  # type: ignore[no-any-return]

    @_fast.fast_method("_body_kernel")
    def fk_body(
        self,
        q: ArrayLike,
        out: FloatArray | None = None,
        form: Form = "4x4",
        *,
        params: ChainParams | None = None,
    ) -> FloatArray:
        """Body-form PoE ``T_world_frame = M exp([B_1] q_1) ... exp([B_n] q_n)``.

        Same arguments and result as :meth:`fk`; equal to it to float precision. With
        ``params``, ``B_i = Ad(M^-1) S_i`` of the given screws and home pose.
        """
        return self._fk("body", q, out, form, params)  # type: ignore[no-any-return]  # as in fk

    def _fk(
        self, form_of_poe: str, q: ArrayLike, out: Any, form: Any, params: ChainParams | None
    ) -> Any:
        """fk or fk_body for arguments the kernel has not taken as they are: JAX or PyTorch
        arrays or ``params`` (the generic path), or NumPy input to validate and convert."""
        kernel = self._space_kernel if form_of_poe == "space" else self._body_kernel
        if params is not None or arrays.kind_of(q) is not None:
            return self._fk_generic(form_of_poe, q, out, form, params)
        reference = self._fk_numpy if form_of_poe == "space" else self._fk_body_numpy
        return _fast.evaluate(kernel, q, out, form, self._joint_values, reference)

    def _fk_generic(
        self, form_of_poe: str, q: Any, out: Any, form: Any, params: ChainParams | None
    ) -> Any:
        form = _fast.check_form(form)
        xp, q, like = self._inputs(q, out, params)
        model = self._model(xp, q, params, body=form_of_poe == "body")
        th = [q[..., i] for i in range(self.n_joints)]
        if form_of_poe == "space":
            pose = poe(model.screws, th, xp, right=model.home)
        else:
            pose = poe(model.body, th, xp, left=model.home)
        return _pose.to_array(pose, form, xp, like)

    def _inputs(self, q: Any, out: Any, params: ChainParams | None) -> tuple[Any, Any, Any]:
        """The generic path's namespace, ``q`` as its array, and a zero array of the batch
        shape in the result's dtype and on its device."""
        if params is not None and not isinstance(params, ChainParams):
            got = type(params).__name__
            raise InputError(f"params must be a ChainParams (see chain.parameters()), got {got}")
        leaves = () if params is None else tuple(params)
        return generic_inputs(q, self.n_joints, leaves, out)

    def _model(self, xp: Any, q: Any, params: ChainParams | None, *, body: bool) -> _Model:
        """The chain's own constants (Python floats; coordinate-axis shortcuts), or those of
        ``params`` converted to ``q``'s library and dtype (general formulas only, so that
        derivatives with respect to them are right); body screws only if ``body``."""
        if params is None:
            return self._constants
        n = self.n_joints
        S = arrays.convert(params.screws, xp, q.dtype, q)
        M = arrays.convert(params.home, xp, q.dtype, q)
        check_shape(S, (n, 6), "params.screws")
        check_shape(M, (4, 4), "params.home")
        rows = [[S[..., i, j] for j in range(6)] for i in range(n)]
        prismatic = [t == "prismatic" for t in self.joint_types]
        home = pose_of(M)
        body_screws: tuple[_Screw, ...] = ()
        if body:  # B_i = Ad(M^-1) S_i = [R^T w; R^T (v + w x p)]
            R_t = _pose.transpose(home[0])
            B = []
            for row in rows:
                w, v = row[:3], row[3:]
                wp = _pose.cross(w, home[1])
                moved = (v[0] + wp[0], v[1] + wp[1], v[2] + wp[2])
                B.append([*_pose.mat_vec(R_t, w), *_pose.mat_vec(R_t, moved)])
            body_screws = _traced_screws(B, prismatic)
        return _Model(_traced_screws(rows, prismatic), rows, home, body_screws)

    def parameters(self, like: Any = None) -> ChainParams:
        """The screws and home pose as :class:`ChainParams`: read-only NumPy arrays, or, with
        ``like`` (a JAX array or PyTorch tensor), new arrays of its library, float dtype and
        device, ready to differentiate (``jax.grad``; ``requires_grad_()``) and to pass to
        :meth:`fk`, :meth:`fk_body` or the Jacobians as ``params``."""
        if like is None:
            return ChainParams(self.screws, self.home)
        xp, _ = arrays.namespace_of([like])
        dtype = arrays.float_dtype(xp, [like])
        return ChainParams(*(arrays.convert(a, xp, dtype, like) for a in (self.screws, self.home)))

    def with_parameters(self, params: ChainParams) -> Chain:
        """A new chain with the screws and home pose of ``params`` (arrays of any library,
        copied to NumPy float64), the rest (names, types, limits, frame, the record of
        :attr:`base` and :attr:`tool`) this chain's. It is
        validated as any chain is: unit screw axes, a rigid home pose.

        Raises:
            InputError: invalid parameters, or traced values (inside ``jit``, ``grad``...).
        """
        if not isinstance(params, ChainParams):
            raise InputError(f"params must be a ChainParams, got {type(params).__name__}")
        return dataclasses.replace(
            self,
            screws=arrays.as_numpy(params.screws, "params.screws"),
            home=arrays.as_numpy(params.home, "params.home"),
            _tree=None,  # the model file's geometry sits on its own kinematics, not these
        )

    @_fast.fast_method("_jacobian_space_kernel")
    def jacobian_space(self, q: ArrayLike, *, params: ChainParams | None = None) -> FloatArray:
        """Space Jacobian ``J_s(q)``, ``(..., 6, n)``, rows ``[w; v]``: ``J_s q_dot`` is the end
        frame's twist in the world frame (Modern Robotics' ``JacobianSpace``; column ``i`` is
        ``Ad(T_{i-1}) S_i``). ``v`` is the velocity of the point at the world origin moving with
        the end frame, not of the frame's origin: see :meth:`jacobian_world` for that.

        ``q`` and ``params`` as for :meth:`fk`; the result in ``q``'s library, as there.
        """
        return self._jacobian("space", q, params)

    @_fast.fast_method("_jacobian_body_kernel")
    def jacobian_body(self, q: ArrayLike, *, params: ChainParams | None = None) -> FloatArray:
        """Body Jacobian ``J_b(q) = Ad(T^-1) J_s(q)``, ``(..., 6, n)``, rows ``[w; v]``: the end
        frame's twist in the end frame itself (Modern Robotics' ``JacobianBody``). It is
        :meth:`jacobian_world` with both rows turned into the end frame, ``R^T``."""
        return self._jacobian("body", q, params)

    @_fast.fast_method("_jacobian_world_kernel")
    def jacobian_world(self, q: ArrayLike, *, params: ChainParams | None = None) -> FloatArray:
        """World Jacobian, ``(..., 6, n)``, rows ``[w; v_frame]``, both in world coordinates:
        ``v_frame = v + w x p`` is the velocity of the end frame's origin ``p``. This is what
        MuJoCo's ``mj_jacSite``/``mj_jacBody`` return (as ``jacr``, ``jacp``) and Pinocchio's
        ``LOCAL_WORLD_ALIGNED`` (with its rows in the other order, ``[v; w]``)."""
        return self._jacobian("world", q, params)

    def _jacobian(self, convention: str, q: ArrayLike, params: ChainParams | None) -> FloatArray:
        """The compiled kernel's Jacobian for ``q`` to validate or convert first (the methods
        have tried the kernel on ``q`` as it is: fast_method), the generic path's for JAX and
        PyTorch arrays or ``params``, or the NumPy reference's without a kernel."""
        if params is not None or arrays.kind_of(q) is not None:
            xp, q, like = self._inputs(q, None, params)
            columns = self._jacobian_columns(
                convention, self._model(xp, q, params, body=False), q, xp
            )
            return jacobian_array(columns, xp, like)  # type: ignore[no-any-return]
        kernel = getattr(self, f"_jacobian_{convention}_kernel")
        return _fast.run_checked(
            kernel,
            q,
            self._joint_values,
            functools.partial(self._jacobian_numpy, convention),
        )

    def _jacobian_columns(self, convention: str, model: _Model, q: Any, xp: Any) -> list[Column]:
        th = [q[..., i] for i in range(self.n_joints)]
        columns, end = space_jacobian(model.screws, model.rows, th, xp, model.home)
        if convention == "space":
            return columns
        return jacobian_from_world(world_columns(columns, end[1]), end, convention)

    def _jacobian_numpy(self, convention: str, q: FloatArray) -> FloatArray:
        """The Jacobians on the reference path with NumPy, for validated float64 ``q``."""
        columns = self._jacobian_columns(convention, self._constants, q, np)
        return jacobian_array(columns, np, zeros_like_batch(q, np))  # type: ignore[no-any-return]

    def _joint_values(self, q: ArrayLike) -> FloatArray:
        return as_joint_values(q, self.n_joints)

    def _fk_numpy(self, q: FloatArray) -> FloatArray:
        """:meth:`fk` on the reference path with NumPy (the compiled kernel's specification),
        for float64 ``q`` of shape ``(..., n)`` that :meth:`fk` has validated."""
        th = [q[..., i] for i in range(self.n_joints)]
        pose = poe(self._constants.screws, th, np, right=self._constants.home)
        return _pose.to_array(pose, "4x4", np, zeros_like_batch(q, np))  # type: ignore[no-any-return]

    def _fk_body_numpy(self, q: FloatArray) -> FloatArray:
        """:meth:`fk_body` on the reference path with NumPy (``q`` as for :meth:`_fk_numpy`)."""
        th = [q[..., i] for i in range(self.n_joints)]
        pose = poe(self._constants.body, th, np, left=self._constants.home)
        return _pose.to_array(pose, "4x4", np, zeros_like_batch(q, np))  # type: ignore[no-any-return]

    @_fast.fast_method("_ik_quick", names=("T", "q0"))
    def ik(
        self,
        T: ArrayLike,
        q0: ArrayLike | None = None,
        *,
        seed: int = 0,
        pos_tol: float = 1e-10,
        ori_tol: float = 1e-10,
        position_only: bool = False,
        orientation_weight: float = 0.3,
        max_iterations: int = 50,
        max_attempts: int = 100,
        max_total_iterations: int | None = None,
        params: ChainParams | None = None,
        nearest_branch: bool = False,
        posture: float | ArrayLike = 0.0,
        avoid: bool = False,
        obstacles: Any = (),
        margin: float = 0.005,
        ignore: Sequence[tuple[str, str]] = (),
    ) -> IKResult:
        """Joint values that put the end frame at ``T``: numerical inverse kinematics, inside
        the joint limits, batched (:mod:`poekin.ik.numerical` describes the algorithm).

        NumPy input runs in the compiled kernel. JAX arrays and PyTorch tensors (targets,
        ``q0`` or ``params``) run a solve that traces under ``jax.jit`` and
        ``jax.vmap``, and come back as the caller's arrays, with ``q`` differentiable with
        respect to ``T`` and ``params`` by the implicit function theorem
        (:mod:`poekin.ik.fixed`).

        Args:
            T: ``(..., 4, 4)`` targets ``T_world_frame``, in the chain's base (world) frame:
                rigid transforms (rotation orthonormal to 1e-6; the orientation is met to
                ``ori_tol`` only if it is orthonormal to about that; JAX and PyTorch values
                are not checked).
            q0: ``(..., n)`` starts, broadcast against the targets' batch axes (rad, m): the
                first attempt starts there (brought into the limits), so that a trajectory
                solved target by target stays on its branch. None: every attempt starts at a
                seeded random configuration within the limits.
            seed: the random starts' seed, an integer from 0 to 2**64 - 1. The same targets,
                ``q0``, seed and options give the same bits, whatever the batch, the
                target's place in it, the thread count or the vector width.
            pos_tol: success needs the frame's origin within this distance of the target's
                (m, > 0).
            ori_tol: and its rotation within this geodesic angle of the target's (rad, > 0).
            position_only: reach the target's position only, whatever the orientation (for
                5-joint arms and point targets); success on ``pos_tol`` alone.
            orientation_weight: metres per radian: how much one radian of orientation error
                weighs against one metre of position error in the least-squares residual
                (it shapes the path to a solution and the best fit of an unreachable
                target, not the tolerances).
            max_iterations: iterations per attempt (each one FK and Jacobian).
            max_attempts: attempts per target; the solve stops at the first success.
            max_total_iterations: JAX and PyTorch only: the iterations of a target's
                attempts together, at most (default 256). A target that needs more fails, with
                the best fit found so far; one that needs no more gets the NumPy solve's answer.
                The NumPy solve has no such budget (an :class:`InputError` if given).
            params: the screws and home pose to solve with instead of the chain's own
                (:meth:`parameters`): JAX arrays or tensors to differentiate the answer with
                respect to, or NumPy arrays (the NumPy solve of :meth:`with_parameters`).
            nearest_branch: with ``q0``, for a chain with a closed form (:meth:`ik_all`, a
                calibrated arm's refined one too): the valid branch nearest ``q0``, its
                angles the equivalents nearest ``q0`` (:func:`poekin.wrap`), where a target
                has one (``iterations`` 0 there), else the numerical solve from ``q0``. NumPy.
            posture: with ``q0``, for a redundant arm: a weight ``> 0`` (or one ``>= 0`` per
                joint) of the pull toward ``q0`` in the target's null space, so that of the
                configurations that reach the target the solve returns the one nearest ``q0``
                (in the norm ``sum w_i dq_i^2``: only the weights' ratios matter, the target
                comes first; :mod:`poekin.wholebody.chains`); 0, the default, is the usual
                solve. NumPy.
            avoid: keep every checked pair of the robot's collision geometry (with itself
                and with ``obstacles``) at least ``margin`` apart: a constraint inside the
                solve, linearised each iteration with the witness points' Jacobians
                (:mod:`poekin.ik.collision_free`; where the closed form of :meth:`ik_all`
                gives every answer, six joints and a whole pose, the valid branch nearest
                ``q0`` that keeps the margin); ``success`` then also means collision-free.
                Needs a chain loaded from a model file (:func:`poekin.load`). NumPy.
            obstacles: with ``avoid``: :class:`poekin.collision.Box`, ``Sphere``,
                ``Capsule``, ``Plane`` or ``Mesh`` obstacles, in the chain's world (its base
                frame) or attached to a frame of the model.
            margin: with ``avoid``: the distance every pair keeps (m, >= 0; default 5 mm).
            ignore: with ``avoid``: pairs of names (geoms, bodies, obstacles) not to check.

        Returns:
            An :class:`~poekin.ik.IKResult`: ``q`` ``(..., n)`` (always within the joint
            limits; a revolute angle is moved by whole turns into them, an unlimited one
            comes back in ``(-pi, pi]``), ``success``, ``pos_err`` (m), ``ori_err`` (rad),
            ``iterations`` and ``attempts`` ``(...,)``. An unreachable target gets
            ``success`` False and the least-squares best ``q`` found; it never raises.
            NumPy arrays, or arrays of the inputs' library, float dtype and device.

        Raises:
            InputError: targets of the wrong shape, not real numbers, not finite or not rigid
                transforms, ``q0`` of the wrong length or batch shape, a tolerance or weight
                that is not > 0, a count below 1, a bad seed, JAX arrays mixed with PyTorch
                tensors.

        Warns:
            JointLimitsWarning: NumPy ``q0`` outside the joint limits (the solve starts from it
                brought into them); JAX and PyTorch values are not checked.

        Example:
            >>> chain = poekin.load("universal_robots_ur5e")
            >>> found = chain.ik(chain.fk([0.3, -1.2, 1.4, -0.5, 1.1, 0.2]))
            >>> bool(found.success), found.q.shape
            (True, (6,))
        """
        if (
            avoid is False
            and params is None
            and max_total_iterations is None
            and nearest_branch is False
            and type(T) is np.ndarray
            and (q0 is None or type(q0) is np.ndarray)
            and type(posture) is float
            and posture == 0.0
            and type(obstacles) is tuple
            and not obstacles
            and type(ignore) is tuple
            and not ignore
            and margin == 0.005
        ):  # the kernel's path, with the least around it (issue 26: a single call's own cost)
            quick: IKResult | None = _numerical().solve_quick(
                self,
                T,
                q0,
                seed,
                pos_tol,
                ori_tol,
                position_only,
                orientation_weight,
                max_iterations,
                max_attempts,
            )
            if quick is not None:
                return quick  # None: the usual path validates, and says what is wrong
        solver = (pos_tol, ori_tol, position_only, orientation_weight, max_iterations, max_attempts)
        more = (max_total_iterations, params, nearest_branch, posture)
        return self._ik_general(T, q0, seed, solver, more, (avoid, obstacles, margin, ignore))

    def _ik_general(
        self,
        T: ArrayLike,
        q0: ArrayLike | None,
        seed: int,
        solver: tuple[float, float, bool, float, int, int],
        more: tuple[int | None, ChainParams | None, bool, float | ArrayLike],
        avoiding: tuple[Any, Any, float, Sequence[tuple[str, str]]],
    ) -> IKResult:
        """:meth:`ik` where the quick path does not serve (a method of its own: its closures
        would cost every call of :meth:`ik` their cells, issue 26), with its arguments in
        three groups: the numerical solve's own (``pos_tol`` to ``max_attempts``), the others
        of the solve (``max_total_iterations``, ``params``, ``nearest_branch``, ``posture``),
        and collision avoidance's."""
        pos_tol, ori_tol, position_only, orientation_weight, max_iterations, max_attempts = solver
        max_total_iterations, params, nearest_branch, posture = more
        avoid, obstacles, margin, ignore = avoiding
        if (
            avoid is not False
            or margin != 0.005
            or not (isinstance(obstacles, (tuple, list)) and len(obstacles) == 0)
            or not (isinstance(ignore, (tuple, list)) and len(ignore) == 0)
        ):
            return self._ik_avoid(
                T,
                q0,
                seed,
                _numerical().settings(
                    pos_tol=pos_tol,
                    ori_tol=ori_tol,
                    position_only=position_only,
                    orientation_weight=orientation_weight,
                    max_iterations=max_iterations,
                    max_attempts=max_attempts,
                ),
                (avoid, obstacles, margin, ignore),
                (max_total_iterations, params, nearest_branch, posture),
            )
        if not (isinstance(posture, (int, float)) and posture == 0):
            others = (max_total_iterations, params, nearest_branch)
            return self._ik_posture(T, q0, posture, seed, *solver, others)
        from poekin.ik.numerical import Settings, settings, solve

        def numpy_options() -> Settings:  # the NumPy solve's (the kernel's) settings
            return settings(
                pos_tol=pos_tol,
                ori_tol=ori_tol,
                position_only=position_only,
                orientation_weight=orientation_weight,
                max_iterations=max_iterations,
                max_attempts=max_attempts,
            )

        if nearest_branch is not False:
            from poekin.ik.analytic import nearest_branch as nearest

            if nearest_branch is not True:
                raise InputError(f"nearest_branch must be True or False, got {nearest_branch!r}")
            if q0 is None or position_only or params is not None or max_total_iterations:
                raise InputError(
                    "nearest_branch chooses among the closed-form solutions of whole poses by "
                    "their distance to q0: give q0, and leave out position_only, params and "
                    "max_total_iterations"
                )
            options = numpy_options()
            return nearest(self, T, q0, lambda: solve(self, T, q0, seed=seed, options=options))
        numpy = params is None and arrays.kind_of(T) is None
        budget = max_total_iterations
        kernel = numpy and budget is None and (q0 is None or arrays.kind_of(q0) is None)
        if kernel:  # the kernel's path, quickly
            return solve(self, T, q0, seed=seed, options=numpy_options())
        from poekin.ik import fixed

        kind = fixed.array_kind(T, q0, params)
        if kind is None and budget is not None:
            raise InputError(
                "max_total_iterations bounds the solve of JAX arrays and PyTorch tensors; the "
                "NumPy solve runs up to max_attempts attempts: leave it out, or lower "
                "max_attempts"
            )
        given: dict[str, Any] = {
            "pos_tol": pos_tol,
            "ori_tol": ori_tol,
            "position_only": position_only,
            "orientation_weight": orientation_weight,
            "max_iterations": max_iterations,
            "max_attempts": max_attempts,
        }
        if kind is not None:
            budget = fixed.DEFAULT_BUDGET if budget is None else budget
            return fixed.solve_arrays(
                self, T, q0, kind, seed=seed, params=params, max_total_iterations=budget, **given
            )
        chain = self if params is None else self.with_parameters(params)
        return solve(chain, T, q0, seed=seed, options=settings(**given))

    def as_tree(self) -> Any:
        """This chain as a :class:`~poekin.tree.Tree` with the same FK: one body per joint, all
        at the world frame at ``q = 0``, each joint turning (or sliding) about its space
        screw's axis, and the end frame a site at the home pose ``M``, so that the site's pose
        is ``e^[S1]q1 ... e^[Sn]qn M`` (kept with the chain after the first call). The
        whole-body solver (``tree.ik`` with a dict of targets) then serves the chain.

        Example:
            >>> chain = poekin.load("universal_robots_ur5e")
            >>> tree = chain.as_tree()
            >>> q = [0.3, -1.2, 1.4, -0.5, 1.1, 0.2]
            >>> bool(np.allclose(tree.pose(q, "attachment_site"), chain.fk(q), atol=1e-14))
            True
        """
        if "tree" not in self._ik_cache:
            self._ik_cache["tree"] = _TREE_OF_CHAIN[0](self)
        return self._ik_cache["tree"]

    def ik_step(
        self,
        T: ArrayLike,
        q: ArrayLike,
        dt: float,
        *,
        velocity_limits: ArrayLike | None = None,
        gain: float = 1.0,
        damping: float = 1e-12,
        position_only: bool = False,
        orientation_weight: float = 0.3,
        avoid: bool = False,
        obstacles: Any = (),
        margin: float = 0.005,
        avoid_gain: float = 0.85,
    ) -> Any:
        """One control tick of differential IK: the joint velocity that moves the end frame
        toward ``T`` in one ``dt``, every joint within its limits at ``q + qvel dt`` and
        within its velocity limit (:mod:`poekin.ik.step`: the box-constrained damped least
        squares that mink's ``solve_ik`` poses as a QP, solved by an active set).

        NumPy arrays, JAX arrays (under ``jax.jit`` and ``jax.vmap`` too) and PyTorch tensors;
        under JAX and PyTorch the velocity is differentiable with respect to ``T`` and ``q``
        (for the limits that are active). The same inputs give the same bits, whatever the
        batch.

        Args:
            T: ``(..., 4, 4)`` targets ``T_world_frame`` (rigid transforms).
            q: ``(..., n)`` the joint values now (rad, m); the batch broadcasts against the
                targets' (4,096 environments in one call).
            dt: the tick (s, > 0).
            velocity_limits: each joint's largest speed (rad/s, m/s): one number or ``(n,)``,
                ``inf`` for none (the default: a chain has no velocity limits of its own).
            gain: the fraction of the frame's error removed in one tick (1: all of it, as far
                as the limits allow).
            damping: the step's Tikhonov damping ``lam |qvel dt|^2`` (m^2).
            position_only: move the frame's origin only, whatever its orientation.
            orientation_weight: metres per radian in the residual.
            avoid: add mink's velocity damper for every checked collision pair (the robot
                with itself and with ``obstacles``) closer than ``margin`` + 5 cm:
                ``d_k + J_k qvel dt >= d_k - avoid_gain (d_k - margin)``, so that no pair
                closes more than ``avoid_gain`` of its gap above ``margin`` in one tick, and
                one closer than ``margin`` is pushed out (:mod:`poekin.collision.avoid`).
                NumPy; needs a chain loaded from a model file.
            obstacles, margin: with ``avoid``: the obstacles and the distance kept (m).
            avoid_gain: with ``avoid``: the damper's gain, in ``(0, 1]``.

        Returns:
            ``(..., n)`` joint velocities (rad/s, m/s), in the inputs' library.

        Raises:
            InputError: targets of the wrong shape or not rigid transforms, ``q`` of the wrong
                length, NaN (NumPy values are checked), a bad ``dt``, ``gain``, ``damping`` or
                ``velocity_limits``.

        Example:
            >>> chain = poekin.load("universal_robots_ur5e")
            >>> q = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
            >>> T = chain.fk(q + 0.01)
            >>> qvel = chain.ik_step(T, q, 0.002, velocity_limits=np.pi)
            >>> bool(np.all(np.abs(qvel) <= np.pi))
            True
        """
        from poekin.ik import step

        if avoid is not False:
            return self._ik_step_avoid(
                T,
                q,
                dt,
                (velocity_limits, gain, damping, position_only, orientation_weight),
                (avoid, obstacles, margin, avoid_gain),
            )
        if type(T) is np.ndarray and type(q) is np.ndarray:  # the kernel, with the least around it
            quick = step.step_quick(
                self, T, q, dt, velocity_limits, gain, damping, position_only, orientation_weight
            )
            if quick is not None:
                return quick
        s = _numerical().settings(
            position_only=position_only, orientation_weight=orientation_weight
        )
        return step.step(
            self,
            T,
            q,
            dt,
            velocity_limits=velocity_limits,
            gain=gain,
            damping=damping,
            s=s,
        )

    def _ik_avoid(
        self,
        T: ArrayLike,
        q0: ArrayLike | None,
        seed: int,
        options: Any,
        collision: tuple[Any, Any, Any, Any],
        others: tuple[Any, ...],
    ) -> IKResult:
        """:meth:`ik` with ``avoid`` (:mod:`poekin.ik.collision_free`)."""
        from poekin.collision.avoid import check_margin
        from poekin.collision.obstacles import as_obstacles
        from poekin.ik import collision_free
        from poekin.ik.numerical import check_seed

        avoid, obstacles, margin, ignore = collision
        if avoid is not True:
            raise InputError(
                "obstacles=, margin= and ignore= take effect with avoid=True: pass it"
                if avoid is False
                else f"avoid must be True or False, got {avoid!r:.40}"
            )
        if others[:3] != (None, None, False) or not (
            isinstance(others[3], int | float) and others[3] == 0
        ):
            raise InputError(
                "avoid=True is a NumPy solve of the chain's own parameters: it takes no "
                "max_total_iterations, params, nearest_branch or posture"
            )
        if arrays.kind_of(T) is not None or arrays.kind_of(q0) is not None:
            raise InputError("avoid=True takes NumPy arrays: convert JAX or PyTorch values first")
        scene = collision_free.chain_scene(
            self, as_obstacles(obstacles), check_margin(margin, "ik"), ignore
        )
        seed = check_seed(seed)
        return collision_free.solve(
            self, T, q0, scene.tree.qpos0, seed=seed, options=options, scene=scene
        )

    def _ik_step_avoid(
        self,
        T: ArrayLike,
        q: ArrayLike,
        dt: float,
        options: tuple[Any, ...],
        collision: tuple[Any, ...],
    ) -> FloatArray:
        """:meth:`ik_step` with ``avoid`` (:func:`poekin.ik.collision_free.step`)."""
        from poekin.collision.avoid import check_margin
        from poekin.collision.obstacles import as_obstacles
        from poekin.ik import collision_free, step
        from poekin.ik.numerical import broadcast_together, check_targets

        velocity_limits, gain, damping, position_only, orientation_weight = options
        avoid, obstacles, margin, avoid_gain = collision
        if avoid is not True:
            raise InputError(f"avoid must be True or False, got {avoid!r:.40}")
        if arrays.kind_of(T) is not None or arrays.kind_of(q) is not None:
            raise InputError("avoid=True takes NumPy arrays: convert JAX or PyTorch values first")
        g = step.positive_number(avoid_gain, "avoid_gain", "1/step", zero=False)
        if g > 1:
            raise InputError(f"avoid_gain must be in (0, 1], got {g}")
        dt = step.positive_number(dt, "dt", "s", zero=False)
        s = _numerical().settings(
            position_only=position_only, orientation_weight=orientation_weight
        )
        scene = collision_free.chain_scene(
            self, as_obstacles(obstacles), check_margin(margin, "ik_step"), ()
        )
        T_arr, q_arr = broadcast_together(
            check_targets(T), as_joint_values(q, self.n_joints, what="q values"), "q"
        )
        batch = q_arr.shape[:-1]
        reach = np.array(step._velocity_limits(velocity_limits, self.n_joints)) * dt
        qvel = collision_free.step(
            self,
            T_arr.reshape(-1, 4, 4),
            q_arr.reshape(-1, self.n_joints),
            dt,
            reach,
            step.positive_number(gain, "gain", "1/step", zero=True),
            step.positive_number(damping, "damping", "m^2", zero=True) + step.FLOOR,
            s,
            scene,
            g,
        )
        return qvel.reshape(*batch, self.n_joints)

    def _ik_posture(
        self,
        T: ArrayLike,
        q0: ArrayLike | None,
        posture: float | ArrayLike,
        seed: int,
        pos_tol: float,
        ori_tol: float,
        position_only: bool,
        orientation_weight: float,
        max_iterations: int,
        max_attempts: int,
        others: tuple[Any, ...],
    ) -> IKResult:
        """:meth:`ik` with a posture (:mod:`poekin.wholebody.chains`)."""
        from poekin.wholebody.chains import solve_chain

        if others != (None, None, False) or arrays.kind_of(T) is not None:
            raise InputError(
                "posture is a NumPy solve of the chain's own parameters: it takes no "
                "max_total_iterations, params or nearest_branch, and NumPy arrays only"
            )
        options = _numerical().settings(
            pos_tol=pos_tol,
            ori_tol=ori_tol,
            position_only=position_only,
            orientation_weight=orientation_weight,
            max_iterations=max_iterations,
            max_attempts=max_attempts,
        )
        return solve_chain(self, T, q0, posture=posture, seed=seed, options=options)

    @_fast.fast_method("_ik_all_quick", names=("T", "near"))
    def ik_all(
        self,
        T: ArrayLike,
        *,
        near: ArrayLike | None = None,
        refine: bool = True,
        obstacles: Any = None,
        collision_free: bool = False,
        margin: float = 0.0,
        ignore: Sequence[tuple[str, str]] = (),
    ) -> IKSolutions:
        """Every closed-form inverse kinematics solution: the joint values that put the end
        frame at ``T``, all branches at once (:mod:`poekin.ik.analytic`).

        For six revolute joints whose axes admit a closed form: three parallel axes (2, 3, 4)
        with axes 5 and 6 meeting (the UR arms), or a spherical wrist (axes 4, 5, 6 meeting)
        with axes 2 and 3 parallel, axes 1 and 2 meeting, or axes 2 and 3 meeting. The
        geometry is read from the screws (:func:`poekin.ik.analytic.geometry`). A calibrated
        arm, whose axes are only nearly so, gets the nearest ideal geometry's closed form with
        each branch refined on the arm itself (``result.geometry.nearest`` says how near).

        Args:
            T: ``(..., 4, 4)`` target poses ``T_world_frame`` of :attr:`frame`.
            near: ``(..., 6)`` joint values (the robot's current ones): the angles as their
                equivalents nearest them (:func:`poekin.wrap`), the branches ordered by their
                distance to them, valid ones first.
            refine: False refuses a chain only near a supported geometry instead of refining.
            obstacles: check each branch for collisions (the robot with itself, and with these
                :mod:`poekin.collision` obstacles; ``[]`` for itself alone): ``collides``
                ``(..., k)``. None (the default): no check. Needs a chain loaded from a model
                file (:func:`poekin.load`).
            collision_free: ``valid`` also requires the branch not to collide (checked with
                ``obstacles``, or the robot alone if None); with ``near``, the valid branches
                still come first.
            margin: a pair closer than this (m, >= 0) collides (0: only pairs that overlap).
            ignore: pairs of names (geoms, bodies, obstacles) not to check.

        Returns:
            :class:`~poekin.ik.analytic.IKSolutions`: ``q`` ``(..., k, 6)`` (``k = 8``),
            ``valid`` ``(..., k)``, ``collides`` ``(..., k)`` (with the check), and
            ``pos_err``, ``ori_err`` ``(..., k)``. Each angle is within the limits where a
            whole turn brings it there.

        Raises:
            AnalyticIKError: the chain fits no supported geometry; the message names the
                condition that fails and by how much.
            InputError: ``T`` is not ``(..., 4, 4)`` finite rigid transforms.
        """
        solutions: IKSolutions = _analytic().ik_all(self, T, near=near, refine=refine)
        if obstacles is None and collision_free is False and margin == 0.0 and not ignore:
            return solutions
        return self._branch_collisions(solutions, obstacles, collision_free, margin, ignore, near)

    def _branch_collisions(
        self,
        found: IKSolutions,
        obstacles: Any,
        collision_free: bool,
        margin: float,
        ignore: Sequence[tuple[str, str]],
        near: ArrayLike | None,
    ) -> IKSolutions:
        """:meth:`ik_all`'s ``collides``, and with ``collision_free`` its ``valid``."""
        from poekin.collision.avoid import check_margin
        from poekin.collision.obstacles import as_obstacles
        from poekin.ik.collision_free import chain_scene

        if not isinstance(collision_free, bool | np.bool_):
            raise InputError(f"collision_free must be True or False, got {collision_free!r:.40}")
        scene = chain_scene(self, as_obstacles(() if obstacles is None else obstacles), 0.0, ignore)
        q = found.q.reshape(-1, self.n_joints)
        qpos = scene.qpos(q, scene.tree.qpos0)
        hit = scene.tree.in_collision(
            qpos, scene.obstacles, margin=check_margin(margin, "ik_all"), ignore=scene.ignore
        )
        collides = np.asarray(hit, dtype=bool).reshape(found.valid.shape)
        valid = found.valid & ~collides if collision_free else found.valid
        order = np.argsort(~valid, axis=-1, kind="stable") if near is not None else None
        if order is None:
            return dataclasses.replace(found, valid=valid, collides=collides)
        return dataclasses.replace(
            found,
            q=np.take_along_axis(found.q, order[..., None], axis=-2),
            valid=np.take_along_axis(valid, order, axis=-1),
            collides=np.take_along_axis(collides, order, axis=-1),
        )

    def follow(
        self,
        T_path: ArrayLike | Callable[[FloatArray], ArrayLike],
        q0: ArrayLike,
        *,
        max_step: float = 0.1,
        tol: float = 1e-4,
        ori_tol: float = 1e-3,
        samples: int | None = None,
        obstacles: Any = None,
        margin: float = 0.0,
        ignore: Sequence[tuple[str, str]] = (),
    ) -> FollowResult:
        """Inverse kinematics along a path of end-frame poses: joint values for samples of it,
        each solved from the one before, the branch kept, re-sampled until the end frame stays
        within ``tol`` of the path between samples (:mod:`poekin.motion.follow` describes the
        algorithm, the stops and their reasons).

        Where the chain has a closed form (:meth:`ik_all`, the UR arms) every sample is on the
        branch ``q0`` is on, its configuration signs (shoulder, wrist, elbow) never switched;
        elsewhere (the FR3) each sample is :meth:`ik` from the one before.

        Args:
            T_path: ``(N, 4, 4)`` poses at ``s = 0, 1/(N-1), ..., 1`` (``N >= 2``; between two
                samples the path is the screw motion between them,
                :func:`poekin.motion.screw_path`), or a callable taking ``(m,)`` path
                parameters in [0, 1] to ``(m, 4, 4)`` poses, such as
                ``lambda s: poekin.motion.line_path(T0, T1, s)``.
            q0: ``(n,)`` the start (rad, m), within the joint limits, ``fk(q0)`` on the path's
                start (within ``tol`` and ``ori_tol``).
            max_step: the largest move of any joint between two samples (rad, m), > 0.
            tol: the largest distance of the end frame's origin from the path at the midpoint
                (in joint space) of two samples (m), > 0.
            ori_tol: the largest angle of its rotation from the path's there (rad), > 0.
            samples: a callable path's first samples, uniform in ``s`` (default 11), >= 2.
            obstacles: check every sample for collisions (the robot with itself and with
                these :mod:`poekin.collision` obstacles; ``[]``: itself alone): the path ends
                before the first colliding sample, reason ``"collision"``, ``pair`` the pair.
                None (the default): no check. Needs a chain loaded from a model file.
            margin: with ``obstacles``: a pair closer than this collides (m, >= 0).
            ignore: with ``obstacles``: pairs of names not to check.

        Returns:
            A :class:`~poekin.motion.follow.FollowResult`: ``q`` ``(K, n)``, ``s`` ``(K,)``,
            ``T`` ``(K, 4, 4)`` (the poses reached), ``fraction``, ``reason`` (``"done"``,
            ``"joint_limit"``, ``"singular"``, ``"unreachable"``, ``"jump"`` or
            ``"collision"``), ``detail``, ``joint`` (at its limit), ``sigma_min`` (where
            singular), ``branch``, ``pair`` (the colliding pair).

        Raises:
            InputError: a path that is not poses (nor a callable returning them), ``q0`` of
                the wrong length, outside the limits or off the path's start, a tolerance or
                ``max_step`` that is not > 0, ``samples`` below 2 or with an array path.

        Example:
            >>> chain = poekin.load("universal_robots_ur5e")
            >>> q0 = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
            >>> T0 = chain.fk(q0)
            >>> T1 = T0.copy()
            >>> T1[0, 3] += 0.1  # 10 cm along x
            >>> from poekin.motion import line_path
            >>> done = chain.follow(lambda s: line_path(T0, T1, s), q0)
            >>> done.reason, done.fraction, done.max_deviation <= 1e-4
            ('done', 1.0, True)
        """
        from poekin.motion.follow import collision_stop, follow

        if obstacles is not None:  # checked before the path is followed
            from poekin.collision.avoid import check_margin
            from poekin.collision.obstacles import as_obstacles
            from poekin.ik.collision_free import chain_scene

            scene = chain_scene(
                self, as_obstacles(obstacles), check_margin(margin, "follow"), ignore
            )
        found = follow(
            self, T_path, q0, max_step=max_step, tol=tol, ori_tol=ori_tol, samples=samples
        )
        if obstacles is None:
            return found
        qpos = scene.qpos(np.asarray(found.q), scene.tree.qpos0)
        return collision_stop(found, scene.tree, qpos, scene.obstacles, scene.margin, scene.ignore)

    def __repr__(self) -> str:
        joints = ", ".join(
            f"{n}({'R' if t == 'revolute' else 'P'})"
            for n, t in zip(self.joint_names, self.joint_types, strict=True)
        )
        source = f"{self.robot!r}, " if self.robot else ""
        placed = " and ".join(k for k in ("base", "tool") if getattr(self, f"_{k}") is not None)
        placed = f", with {placed}" if placed else ""
        return f"Chain({source}frame={self.frame!r}, joints=[{joints}]{placed})"

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


def _ik_defaults(method: Callable[..., Any]) -> tuple[float, float, bool, float, int, int]:
    """``method``'s (:meth:`Chain.ik`'s) defaults of the options its call in C takes."""
    given = inspect.signature(method).parameters
    names = ("pos_tol", "ori_tol", "position_only", "orientation_weight")
    counts = ("max_iterations", "max_attempts")
    defaults = (*(given[n].default for n in names), *(given[n].default for n in counts))
    return defaults  # type: ignore[return-value]


Chain._IK_DEFAULTS = _ik_defaults(Chain.ik)
