"""The kinematic tree: every body and site of a model, every joint type, all poses in one pass.

A :class:`Tree` is the whole model, where a :class:`~poekin.chain.Chain` is one path of it.
Bodies come parent before child. Each body sits at a fixed pose in its parent (``body_pos``,
``body_rot``), then its joints move it, in order, exactly as MuJoCo's ``mj_kinematics`` does:

* revolute (hinge): a rotation by ``position - ref`` about ``axis`` through ``anchor``;
* prismatic (slide): a translation by ``position - ref`` along ``axis``;
* ball: a rotation by the unit quaternion ``qpos[a:a+4]`` (``wxyz``) about ``anchor``;
* free: the body's world pose is ``qpos[a:a+3]`` and the quaternion ``qpos[a+3:a+7]``; the body's
  fixed pose is then not used (MuJoCo allows free joints on top-level bodies only).

``axis`` and ``anchor`` are in the body frame. Quaternions in ``qpos`` are normalised the way
MuJoCo normalises them (:func:`poekin.lie.quat_normalize`): an unnormalised quaternion means
the rotation of its unit version, and a zero one the identity.

``qpos`` uses MuJoCo's layout: the independent joints in order, 7 numbers for a free joint,
4 for a ball joint, 1 for a hinge or slide. A *mimic* joint (from URDF) has no entry, whether
it comes before or after its leader: its position is ``multiplier * qpos[leader] + offset``.

Frames: every body, then every site. A site sits at a fixed pose in its body (or the world).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import _levels, _pose, arrays, lie
from poekin._poe import Column, as_joint_values, check_shape
from poekin.chain import (
    IDENTITY,
    Chain,
    JacobianConvention,
    JointType,
    check_jacobian_convention,
    generic_inputs,
    jacobian_array,
    jacobian_from_world,
    readonly_array,
    register_tree_of_chain,
    relative_jacobian,
    rigid_transform,
    zeros_like_batch,
)
from poekin.errors import InputError, ModelError, UnknownFrameError, did_you_mean
from poekin.kernel import _fast
from poekin.kernel._fast import Form

if TYPE_CHECKING:
    from poekin.collision.query import Distances

__all__ = ["Mimic", "Tree", "TreeJointType", "TreeParams"]

TreeJointType = Literal["revolute", "prismatic", "ball", "free"]
FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_QPOS_SIZE: dict[str, int] = {"revolute": 1, "prismatic": 1, "ball": 4, "free": 7}
_DOF: dict[str, int] = {"revolute": 1, "prismatic": 1, "ball": 3, "free": 6}
_QPOS_WORDS = {"ball": "qw qx qy qz", "free": "x y z qw qx qy qz"}
_ANGULAR = ("rx", "ry", "rz")
_IDENTITY_QUAT = (1.0, 0.0, 0.0, 0.0)
# Axes and fixed rotations from a model file are unit / orthonormal to ~1e-16; hand-made ones
# (URDF rpy, typed axes) to ~1e-12. Beyond this the model is wrong, not rounded.
_UNIT_TOL = 1e-9


@dataclasses.dataclass(frozen=True)
class Mimic:
    """A joint that follows another: ``position = multiplier * leader + offset`` (URDF mimic)."""

    leader: str
    multiplier: float = 1.0
    offset: float = 0.0


def _index_array(a: ArrayLike, n: int, name: str) -> IntArray:
    arr = np.array(a, dtype=np.intp).reshape(-1)
    if arr.shape != (n,):
        raise InputError(f"{name} must have {n} entries, got {arr.shape[0]}")
    arr.flags.writeable = False
    return arr


def _unit_rows(a: FloatArray, name: str, labels: Sequence[str]) -> None:
    norms = np.linalg.norm(a, axis=-1)
    for label, norm in zip(labels, norms, strict=True):
        if abs(norm - 1.0) > _UNIT_TOL:
            raise InputError(f"{name} of {label!r} must be a unit vector, got norm {norm:.6g}")


def _rotations(a: FloatArray, name: str, labels: Sequence[str]) -> None:
    for label, R in zip(labels, a, strict=True):
        if not np.allclose(R.T @ R, np.eye(3), atol=_UNIT_TOL) or np.linalg.det(R) < 0:
            raise InputError(f"{name} of {label!r} is not a rotation (orthonormal, det +1)")


class TreeParams(NamedTuple):
    """A tree's kinematic parameters as arrays of any library: leaves to differentiate.

    A named tuple, so JAX (a pytree) and PyTorch (``torch.func``, ``torch.compile``) take it
    with no registration. Leading batch axes broadcast against those of ``qpos``. Values are
    used as given: a rotation that is not orthonormal or an axis that is not unit length gives
    what the formulas make of it (:meth:`Tree.with_parameters` checks them).

    Attributes:
        body_pos: ``(..., nb, 3)`` body origins in their parents' frames (m).
        body_rot: ``(..., nb, 3, 3)`` body orientations in their parents' frames.
        joint_axes: ``(..., nj, 3)`` unit joint axes in their bodies' frames.
        joint_anchors: ``(..., nj, 3)`` the points joints turn about, in their bodies' frames.
        site_pos: ``(..., ns, 3)`` site positions in their bodies' frames.
        site_rot: ``(..., ns, 3, 3)`` site orientations in their bodies' frames.
    """

    body_pos: Any
    body_rot: Any
    joint_axes: Any
    joint_anchors: Any
    site_pos: Any
    site_rot: Any


class _TreeLayout(NamedTuple):
    """The tree's structure as Python ints and floats, for the reference path's Jacobians (so
    that tracers, torch.compile's included, see constants rather than NumPy arrays)."""

    dof: tuple[int, ...]  # each joint's first Jacobian column
    scale: tuple[float, ...]  # each joint's column multiplier (a mimic's, else 1)
    joint_body: tuple[int, ...]
    paths: tuple[tuple[int, ...], ...]  # each frame's path joints, base to tip


def _add_column(column: Column, add: Sequence[Any], scale: float) -> Column:
    return tuple(c + scale * a for c, a in zip(column, add, strict=True))  # type: ignore[return-value]


def _axpy(y: _pose.Vec, a: float, x: Sequence[Any]) -> _pose.Vec:
    """``y + a x``, entry by entry."""
    return (y[0] + a * x[0], y[1] + a * x[1], y[2] + a * x[2])


def _scaled(a: float, x: Sequence[Any]) -> _pose.Vec:
    """``a x``, entry by entry."""
    return (a * x[0], a * x[1], a * x[2])


@dataclasses.dataclass(frozen=True, eq=False)
class Tree:
    """A kinematic tree of bodies, joints and sites. Immutable; build it with
    :func:`poekin.load_tree`, or directly from arrays.

    Attributes:
        body_names: ``nb`` body names, parents before children (the world is not a body).
        body_parents: ``(nb,)`` index of each body's parent, ``-1`` for the world.
        body_pos: ``(nb, 3)`` body origin in its parent's frame (m).
        body_rot: ``(nb, 3, 3)`` body orientation in its parent's frame.
        joint_names: ``nj`` joint names, grouped by body in body order.
        joint_types: ``"revolute"``, ``"prismatic"``, ``"ball"`` or ``"free"`` each.
        joint_bodies: ``(nj,)`` the body each joint moves.
        joint_axes: ``(nj, 3)`` unit axis in the body frame (unused for ball and free).
        joint_anchors: ``(nj, 3)`` the point the joint turns about, in the body frame.
        joint_refs: ``(nj,)`` the hinge/slide position at which the joint is at its home pose
            (MuJoCo's ``ref``, the joint's ``qpos0``); 0 for ball and free joints.
        joint_limits: ``(nj, 2)`` hinge/slide limits (rad, m), ``-inf``/``inf`` if none.
        mimics: ``nj`` entries, a :class:`Mimic` for a joint that follows another, else None.
        site_names: ``ns`` site names.
        site_bodies: ``(ns,)`` the body each site is fixed to, ``-1`` for the world.
        site_pos, site_rot: ``(ns, 3)``, ``(ns, 3, 3)`` site pose in its body's frame.
        qpos0: ``(nq,)`` the default configuration (MuJoCo's ``qpos0``); if not given (empty),
            the home pose: hinges and slides at ``ref``, ball joints at the identity, a free
            joint at its body's fixed pose.
        robot: the model's name or file.
        body_mass: ``(nb,)`` each body's mass (kg; MuJoCo's ``body_mass``), ``>= 0``, or NaN
            where it is not known; empty (the default): no mass known. :meth:`com` needs them.
        body_com: ``(nb, 3)`` each body's centre of mass in its own frame (m; MuJoCo's
            ``body_ipos``), finite where the mass is known; empty with ``body_mass``.
        joint_velocity_limits: ``(nj,)`` each joint's largest speed (rad/s, m/s; a URDF's
            ``<limit velocity>``), ``inf`` for none (MuJoCo has none); empty: none. What
            :meth:`ik_step` keeps the step within when it is given no ``velocity_limits``.
        qpos_adr: ``(nj,)`` where each joint's numbers start in ``qpos`` (a mimic joint: its
            leader's) (derived).
    """

    body_names: tuple[str, ...]
    body_parents: IntArray
    body_pos: FloatArray
    body_rot: FloatArray
    joint_names: tuple[str, ...]
    joint_types: tuple[TreeJointType, ...]
    joint_bodies: IntArray
    joint_axes: FloatArray
    joint_anchors: FloatArray
    joint_refs: FloatArray
    joint_limits: FloatArray
    mimics: tuple[Mimic | None, ...]
    site_names: tuple[str, ...] = ()
    site_bodies: IntArray = dataclasses.field(default_factory=lambda: np.zeros(0, np.intp))
    site_pos: FloatArray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    site_rot: FloatArray = dataclasses.field(default_factory=lambda: np.zeros((0, 3, 3)))
    qpos0: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0))
    robot: str = ""
    body_mass: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0))
    body_com: FloatArray = dataclasses.field(default_factory=lambda: np.zeros((0, 3)))
    joint_velocity_limits: FloatArray = dataclasses.field(default_factory=lambda: np.zeros(0))
    qpos_adr: IntArray = dataclasses.field(init=False, repr=False)
    _slots: IntArray = dataclasses.field(init=False, repr=False)
    _slot_scale: FloatArray = dataclasses.field(init=False, repr=False)
    _slot_offset: FloatArray = dataclasses.field(init=False, repr=False)
    _body_joints: tuple[tuple[int, ...], ...] = dataclasses.field(init=False, repr=False)
    _nq: int = dataclasses.field(init=False, repr=False)
    _nv: int = dataclasses.field(init=False, repr=False)
    _full_adr: IntArray = dataclasses.field(init=False, repr=False)
    _dof_adr: IntArray = dataclasses.field(init=False, repr=False)  # each joint's first qvel column
    _kernel: Any = dataclasses.field(init=False, repr=False, compare=False)
    _spec: Any = dataclasses.field(init=False, repr=False, compare=False)
    # (frame name, convention) -> compiled Jacobian, built at first use
    _jacobian_kernels: dict[tuple[str, str], Any] = dataclasses.field(
        init=False, repr=False, compare=False
    )
    # frame name -> how Tree.ik solves for it (poekin.ik.trees.TreePlan), built at first use
    _ik_cache: dict[str, Any] = dataclasses.field(init=False, repr=False, compare=False)
    _layout_text: str = dataclasses.field(init=False, repr=False, compare=False)
    _plan: _levels.Plan = dataclasses.field(init=False, repr=False, compare=False)
    _static: _TreeLayout = dataclasses.field(init=False, repr=False, compare=False)
    # T_world_base that with_base folded into the top-level bodies and the world's sites
    _base: FloatArray | None = dataclasses.field(default=None, repr=False, kw_only=True)
    # the model file poekin.load_tree read (its collision geometry is read from it), or ""
    _source_file: str = dataclasses.field(default="", repr=False, compare=False, kw_only=True)
    # the collision model (poekin.collision.model_of), built at first use
    _collision: dict[str, Any] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        nb, nj, ns = len(self.body_names), len(self.joint_names), len(self.site_names)
        for name in ("body_names", "joint_names", "joint_types", "mimics", "site_names"):
            set_(self, name, tuple(getattr(self, name)))
        if len(self.joint_types) != nj or len(self.mimics) != nj:
            raise InputError(f"{nj} joint names need {nj} joint types and {nj} mimic entries")
        set_(self, "body_parents", _index_array(self.body_parents, nb, "body_parents"))
        set_(self, "body_pos", readonly_array(self.body_pos, (nb, 3), "body_pos"))
        set_(self, "body_rot", readonly_array(self.body_rot, (nb, 3, 3), "body_rot"))
        set_(self, "joint_bodies", _index_array(self.joint_bodies, nj, "joint_bodies"))
        set_(self, "joint_axes", readonly_array(self.joint_axes, (nj, 3), "joint_axes"))
        set_(self, "joint_anchors", readonly_array(self.joint_anchors, (nj, 3), "joint_anchors"))
        set_(self, "joint_refs", readonly_array(self.joint_refs, (nj,), "joint_refs"))
        limits = np.array(self.joint_limits, dtype=np.float64)
        if (
            limits.shape != (nj, 2)
            or np.any(np.isnan(limits))
            or np.any(limits[:, 0] > limits[:, 1])
        ):
            raise InputError(f"joint_limits must be ({nj}, 2) with lower <= upper")
        limits.flags.writeable = False
        set_(self, "joint_limits", limits)
        set_(self, "site_bodies", _index_array(self.site_bodies, ns, "site_bodies"))
        set_(self, "site_pos", readonly_array(self.site_pos, (ns, 3), "site_pos"))
        set_(self, "site_rot", readonly_array(self.site_rot, (ns, 3, 3), "site_rot"))
        self._check_masses()
        speeds = np.array(self.joint_velocity_limits, dtype=np.float64)
        if speeds.size == 0:
            speeds = np.full(nj, np.inf)
        if speeds.shape != (nj,) or np.any(np.isnan(speeds)) or np.any(speeds <= 0):
            raise InputError(
                f"joint_velocity_limits must be ({nj},) numbers > 0 (inf for none), or empty"
            )
        speeds.flags.writeable = False
        set_(self, "joint_velocity_limits", speeds)
        if self._base is not None:
            base = rigid_transform(self._base, "base")
            base.flags.writeable = False
            set_(self, "_base", base)
        self._check_topology()
        _rotations(self.body_rot, "body_rot", self.body_names)
        _rotations(self.site_rot, "site_rot", self.site_names)
        hinges = [k for k, t in enumerate(self.joint_types) if t in ("revolute", "prismatic")]
        _unit_rows(self.joint_axes[hinges], "the axis", [self.joint_names[k] for k in hinges])
        self._layout()
        qpos0 = self._default_qpos() if np.size(self.qpos0) == 0 else self.qpos0
        set_(self, "qpos0", readonly_array(qpos0, (self.nq,), "qpos0"))
        spec = _fast.TreeSpec(
            nq=self.nq,
            body_parents=self.body_parents.tolist(),
            body_pos=self.body_pos,
            body_rot=self.body_rot,
            body_joints=self._body_joints,
            joint_types=self.joint_types,
            joint_axes=self.joint_axes,
            joint_anchors=self.joint_anchors,
            joint_refs=self.joint_refs,
            slot_of_joint=self._full_adr.tolist(),
            slots=self._slots.tolist(),
            slot_scale=self._slot_scale.tolist(),
            slot_offset=self._slot_offset.tolist(),
            site_bodies=self.site_bodies.tolist(),
            site_pos=self.site_pos,
            site_rot=self.site_rot,
        )
        set_(self, "_spec", spec)
        set_(self, "_kernel", _fast.tree_program(spec))
        set_(self, "_jacobian_kernels", {})
        set_(self, "_ik_cache", {})
        set_(self, "_collision", {})
        # computed now, not cached at first use: torch.compile cannot trace a cache's lock
        set_(self, "_layout_text", self._layout_words())
        set_(
            self,
            "_plan",
            _levels.plan(
                self.body_parents.tolist(),
                self._body_joints,
                self.joint_types,
                self._full_adr.tolist(),
                self.joint_refs.tolist(),
                self.site_bodies.tolist(),
                (self._slots.tolist(), self._slot_scale.tolist(), self._slot_offset.tolist()),
                _levels.Constants(*(getattr(self, name) for name in TreeParams._fields)),
            ),
        )
        layout = _TreeLayout(
            dof=tuple(int(d) for d in self._dof_adr),
            scale=tuple(1.0 if m is None else float(m.multiplier) for m in self.mimics),
            joint_body=tuple(int(b) for b in self.joint_bodies),
            paths=tuple(self.path_joints(f) for f in self.frame_names),
        )
        set_(self, "_static", layout)

    def _check_topology(self) -> None:
        if not self.body_names and not self.site_names:
            raise InputError("the model has no body and no site: no frame to pose")
        for b, parent in enumerate(self.body_parents):
            if not -1 <= parent < b:
                raise InputError(
                    f"body {self.body_names[b]!r}: parent index {parent} must come before it "
                    "(bodies are ordered parent before child; -1 is the world)"
                )
        if np.any(np.diff(self.joint_bodies) < 0) or np.any(
            (self.joint_bodies < 0) | (self.joint_bodies >= len(self.body_names))
        ):
            raise InputError("joint_bodies must be valid body indices, grouped in body order")
        if np.any((self.site_bodies < -1) | (self.site_bodies >= len(self.body_names))):
            raise InputError("site_bodies must be body indices or -1 (the world)")
        for k, (name, kind) in enumerate(zip(self.joint_names, self.joint_types, strict=True)):
            if kind not in _QPOS_SIZE:
                raise InputError(
                    f"joint {name!r}: unknown type {kind!r}; use one of {sorted(_QPOS_SIZE)}"
                )
            b = self.joint_bodies[k]
            if kind == "free" and (
                np.count_nonzero(self.joint_bodies == b) != 1 or self.body_parents[b] != -1
            ):
                raise InputError(
                    f"free joint {name!r} must be the only joint of a body whose parent is "
                    "the world"
                )

    def _check_masses(self) -> None:
        """``body_mass`` and ``body_com`` as read-only float64 arrays: both empty (no mass
        known), or ``(nb,)`` masses, each ``>= 0`` or NaN (unknown), and ``(nb, 3)`` centres,
        finite where the mass is known."""
        nb = len(self.body_names)
        mass = np.array(self.body_mass, dtype=np.float64)
        com = np.array(self.body_com, dtype=np.float64)
        if mass.size == 0 and com.size == 0:
            mass, com = np.zeros(0), np.zeros((0, 3))
        elif mass.shape != (nb,) or com.shape != (nb, 3):
            raise InputError(
                f"body_mass and body_com must have shapes ({nb},) and ({nb}, 3), or both be "
                f"empty (no mass known); got {mass.shape} and {com.shape}"
            )
        known = ~np.isnan(mass)
        for b in np.flatnonzero(known & ~(np.isfinite(mass) & (mass >= 0))):
            raise InputError(
                f"body_mass of {self.body_names[b]!r} is {mass[b]}; a mass is finite and >= 0 "
                "(NaN: unknown)"
            )
        for b in np.flatnonzero(known & ~np.all(np.isfinite(com), axis=-1)):
            raise InputError(
                f"body_com of {self.body_names[b]!r} contains NaN or inf, but its mass is known"
            )
        for a in (mass, com):
            a.flags.writeable = False
        object.__setattr__(self, "body_mass", mass)
        object.__setattr__(self, "body_com", com)

    def _layout(self) -> None:
        """qpos addresses, and the gather that expands qpos to one slot set per joint.

        Two passes, so that a follower may come before its leader: the independent joints take
        their ``qpos`` (and ``qvel``) addresses in joint order, then each follower takes its
        leader's.
        """
        set_ = object.__setattr__
        names = {n: k for k, n in enumerate(self.joint_names)}
        leaders = [self._leader(k, names) for k in range(len(self.joint_names))]
        adr = np.zeros(len(self.joint_names), dtype=np.intp)
        dof_adr = np.zeros(len(self.joint_names), dtype=np.intp)
        nq = nv = 0
        for k, kind in enumerate(self.joint_types):
            if leaders[k] < 0:
                adr[k], nq = nq, nq + _QPOS_SIZE[kind]
                dof_adr[k], nv = nv, nv + _DOF[kind]
        slots: list[int] = []
        scale: list[float] = []
        offset: list[float] = []
        for k, (kind, mimic) in enumerate(zip(self.joint_types, self.mimics, strict=True)):
            if mimic is None:
                size = _QPOS_SIZE[kind]
                slots.extend(range(adr[k], adr[k] + size))
                scale.extend([1.0] * size)
                offset.extend([0.0] * size)
                continue
            # moves with its leader: its qpos is the leader's, its velocity column adds to the
            # leader's
            adr[k], dof_adr[k] = adr[leaders[k]], dof_adr[leaders[k]]
            slots.append(int(adr[k]))
            scale.append(float(mimic.multiplier))
            offset.append(float(mimic.offset))
        adr.flags.writeable = False
        set_(self, "qpos_adr", adr)
        set_(self, "_slots", np.array(slots, dtype=np.intp))
        set_(self, "_slot_scale", np.array(scale))
        set_(self, "_slot_offset", np.array(offset))
        set_(self, "_nq", nq)
        set_(self, "_nv", nv)
        sizes = [_QPOS_SIZE[t] for t in self.joint_types]
        full_adr = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.intp)
        full_adr.flags.writeable = False
        set_(self, "_full_adr", full_adr)
        set_(self, "_dof_adr", dof_adr)
        set_(
            self,
            "_body_joints",
            tuple(
                tuple(int(k) for k in np.flatnonzero(self.joint_bodies == b))
                for b in range(len(self.body_names))
            ),
        )

    def _leader(self, k: int, names: dict[str, int]) -> int:
        """The index of joint ``k``'s leader, -1 for an independent joint.

        Raises:
            InputError: the leader is no joint, follows another joint itself, or is not a hinge
                or slide, or joint ``k`` is not.
        """
        mimic = self.mimics[k]
        if mimic is None:
            return -1
        name, leader = self.joint_names[k], names.get(mimic.leader)
        if leader is None:
            raise InputError(
                f"joint {name!r} mimics {mimic.leader!r}, which is no joint: "
                f"{did_you_mean(mimic.leader, list(names))}"
            )
        followed = self.mimics[leader]
        if followed is not None:
            raise InputError(
                f"joint {name!r} mimics {mimic.leader!r}, which mimics {followed.leader!r} "
                "itself: a leader must be a joint that mimics none"
            )
        hinge_or_slide = ("revolute", "prismatic")
        if self.joint_types[k] not in hinge_or_slide or (
            self.joint_types[leader] not in hinge_or_slide
        ):
            raise InputError(f"mimic joint {name!r}: leader and follower must be hinge/slide")
        return leader

    def _default_qpos(self) -> FloatArray:
        q = np.zeros(self.nq)
        for k, kind in enumerate(self.joint_types):
            a = self.qpos_adr[k]
            if self.mimics[k] is not None:
                continue
            if kind == "free":
                b = self.joint_bodies[k]
                q[a : a + 3] = self.body_pos[b]
                q[a + 3 : a + 7] = lie.rotation_to_quat(self.body_rot[b])
            elif kind == "ball":
                q[a : a + 4] = _IDENTITY_QUAT
            else:
                q[a] = self.joint_refs[k]
        return q

    # --- sizes and names ------------------------------------------------------------------

    @property
    def nq(self) -> int:
        """Length of ``qpos``."""
        return self._nq

    @property
    def nv(self) -> int:
        """Degrees of freedom (MuJoCo's ``nv``): 6 per free, 3 per ball, 1 per hinge/slide."""
        return self._nv

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Every body, then every site: the frames :meth:`fk` returns, in that order."""
        return self.body_names + self.site_names

    @property
    def n_frames(self) -> int:
        return len(self.body_names) + len(self.site_names)

    def qpos_layout(self) -> str:
        """The qpos layout in words: ``qpos = [base (free: x y z qw qx qy qz), j1, ...]``."""
        return self._layout_text

    def _layout_words(self) -> str:
        parts = [
            name if kind in ("revolute", "prismatic") else f"{name} ({kind}: {_QPOS_WORDS[kind]})"
            for name, kind, mimic in zip(
                self.joint_names, self.joint_types, self.mimics, strict=True
            )
            if mimic is None
        ]
        return f"qpos = [{', '.join(parts)}]"

    def frame_index(self, frame: str) -> int:
        """Index of ``frame`` in :attr:`frame_names`; a site wins over a body of the same name.

        Raises:
            UnknownFrameError: no such body or site; the message lists them.
        """
        if frame in self.site_names:
            return len(self.body_names) + self.site_names.index(frame)
        if frame in self.body_names:
            return self.body_names.index(frame)
        raise UnknownFrameError(
            f"no site or body named {frame!r}: {did_you_mean(frame, list(self.frame_names))}"
        )

    # --- forward kinematics ---------------------------------------------------------------

    def full_qpos(self, qpos: ArrayLike) -> FloatArray:
        """``qpos`` with an entry for every joint, mimic followers included.

        ``(..., nq) -> (..., nq_full)``: each joint's numbers in joint order, starting at
        :attr:`full_qpos_adr`; a follower's value is ``multiplier * leader + offset``. This is
        MuJoCo's layout for a model where every joint has its own ``qpos`` entry (MuJoCo's
        compile of the same URDF); without mimic joints it is ``qpos`` itself.
        """
        return self._expand(self._as_qpos(qpos))

    @property
    def full_qpos_adr(self) -> IntArray:
        """``(nj,)`` where each joint's numbers start in :meth:`full_qpos`."""
        return self._full_adr

    def _expand(self, qpos: FloatArray) -> FloatArray:
        """One set of slots per joint: mimic joints get ``multiplier * leader + offset``."""
        return qpos[..., self._slots] * self._slot_scale + self._slot_offset

    def _poses(
        self, qpos: Any, xp: Any, like: Any, params: _levels.Constants | None, joints: bool
    ) -> tuple[_levels.Poses, _levels.Lib]:
        """Every body's and site's world pose for ``qpos (..., nq)`` (an array of ``xp``), and
        with ``joints`` every joint's world axis and anchor before it moves (MuJoCo's
        ``xaxis`` and ``xanchor``), group by group (:mod:`poekin._levels`), the batch axes
        last; ``params``: offsets, axes and anchors to use instead of the tree's own."""
        trailing = (2, 3, 2, 2, 2, 3)  # TreeParams: (n, 3) or (n, 3, 3) each
        ranks = (
            [] if params is None else [a.ndim - t for a, t in zip(params, trailing, strict=True)]
        )
        batch = max([qpos.ndim - 1, *ranks])
        lib = _levels.Lib(xp, like, batch)
        if params is not None:
            params = _levels.Constants(
                *(
                    _levels.batch_last(a, t, batch, xp)
                    for a, t in zip(params, trailing, strict=True)
                )
            )
        x = _levels.expand(self._plan, _levels.batch_last(qpos, 1, batch, xp), lib)
        return _levels.evaluate(self._plan, x, lib, params, joints=joints), lib

    def _frames(
        self, qpos: Any, xp: Any, like: Any, params: _levels.Constants | None, form: Form
    ) -> Any:
        """:meth:`fk` of ``qpos`` (an array of ``xp``) on the reference path."""
        poses, lib = self._poses(qpos, xp, like, params, joints=False)
        return _levels.frames_array(poses, self._plan, form, lib)

    @_fast.fast_method("_kernel")
    def fk(
        self,
        qpos: ArrayLike,
        out: FloatArray | None = None,
        form: Form = "4x4",
        *,
        params: TreeParams | None = None,
    ) -> FloatArray:
        """World poses of every frame (bodies, then sites) in one pass.

        Args:
            qpos: ``(..., nq)`` in MuJoCo's qpos layout (rad, m, quaternions ``wxyz``): a NumPy
                array (or anything NumPy converts), a JAX array or a PyTorch tensor.
            out: a C-contiguous float64 array of the result's shape to write into (returned);
                if an error is raised its contents are unspecified. NumPy only.
            form: ``"4x4"``, ``"3x4"`` or ``"pos_quat"``, as for :meth:`Chain.fk`.
            params: body offsets, joint axes and anchors, site offsets to use instead of the
                tree's own (:meth:`parameters`), e.g. to differentiate with respect to them.

        Returns:
            ``(..., n_frames, 4, 4)`` (or ``(..., n_frames, 3, 4)``, ``(..., n_frames, 7)``):
            ``T_world_frame`` for each of :attr:`frame_names`; a NumPy float64 array for NumPy
            input, else of ``qpos``'s library, device and float dtype, unchecked for NaN and
            inf (see :mod:`poekin.arrays`).
        """
        # the kernel has run already where it takes the arguments as they are (fast_method)
        if params is not None or arrays.kind_of(qpos) is not None:
            form = _fast.check_form(form)
            xp, q, like, constants = self._inputs(qpos, out, params)
            return self._frames(q, xp, like, constants, form)  # type: ignore[no-any-return]
        frames = (self.n_frames,)
        return _fast.evaluate(self._kernel, qpos, out, form, self._as_qpos, self._fk_numpy, frames)

    def pose(self, qpos: ArrayLike, frame: str, relative_to: str | None = None) -> FloatArray:
        """The pose of one frame: ``T_world_frame``, or with ``relative_to`` the frame's pose in
        that frame, ``T_relative_frame = T_world_relative^-1 T_world_frame``.

        Args:
            qpos: ``(..., nq)`` in MuJoCo's qpos layout.
            frame, relative_to: body or site names.

        Returns:
            ``(..., 4, 4)`` poses.

        Example:
            >>> tree = poekin.load_tree("unitree_go2")
            >>> T_base_foot = tree.pose(tree.qpos0, "FL_calf", relative_to="base")

        Raises:
            UnknownFrameError: no such frame.
        """
        index = self.frame_index(frame)
        reference = None if relative_to is None else self.frame_index(relative_to)
        T = self.fk(qpos)
        T_frame = T[..., index, :, :]
        if reference is None:
            return T_frame
        T_ref = T[..., reference, :, :]
        return lie.inverse(T_ref) @ T_frame

    def _fk_numpy(self, qpos: FloatArray) -> FloatArray:
        """:meth:`fk` on the reference path with NumPy (the compiled kernel's specification),
        for float64 ``qpos`` of shape ``(..., nq)`` that :meth:`fk` has validated."""
        return self._frames(qpos, np, zeros_like_batch(qpos, np), None, "4x4")  # type: ignore[no-any-return]

    def _as_qpos(self, qpos: ArrayLike) -> FloatArray:
        return as_joint_values(qpos, self.nq, what="qpos values", layout=self._layout_text)

    def _inputs(
        self, qpos: Any, out: Any, params: TreeParams | None
    ) -> tuple[Any, Any, Any, _levels.Constants | None]:
        """The generic path's namespace, ``qpos`` as its array, zeros of the batch shape (the
        result's dtype and device) and ``params`` as arrays of that library and dtype (None:
        the tree's own constants)."""
        if params is not None and not isinstance(params, TreeParams):
            raise InputError(
                f"params must be a TreeParams (see tree.parameters()), got {type(params).__name__}"
            )
        leaves = () if params is None else tuple(params)
        xp, q, like = generic_inputs(
            qpos, self.nq, leaves, out, what="qpos values", layout=self._layout_text
        )
        if params is None:
            return xp, q, like, None
        nb, nj, ns = len(self.body_names), len(self.joint_names), len(self.site_names)
        shapes = {
            "body_pos": (nb, 3),
            "body_rot": (nb, 3, 3),
            "joint_axes": (nj, 3),
            "joint_anchors": (nj, 3),
            "site_pos": (ns, 3),
            "site_rot": (ns, 3, 3),
        }
        values = []
        for name, shape in shapes.items():
            a = arrays.convert(getattr(params, name), xp, q.dtype, q)
            check_shape(a, shape, f"params.{name}")
            values.append(a)
        return xp, q, like, _levels.Constants(*values)

    def parameters(self, like: Any = None) -> TreeParams:
        """The body offsets, joint axes and anchors and site offsets as :class:`TreeParams`:
        read-only NumPy arrays, or, with ``like`` (a JAX array or PyTorch tensor), new arrays of
        its library, float dtype and device, ready to differentiate and to pass to :meth:`fk`
        or :meth:`jacobian` as ``params``."""
        values = [getattr(self, name) for name in TreeParams._fields]
        if like is None:
            return TreeParams(*values)
        xp, _ = arrays.namespace_of([like])
        dtype = arrays.float_dtype(xp, [like])
        return TreeParams(*(arrays.convert(a, xp, dtype, like) for a in values))

    def with_parameters(self, params: TreeParams) -> Tree:
        """A new tree with the offsets, axes and anchors of ``params`` (arrays of any library,
        copied to NumPy float64), the rest this tree's; validated as any tree is (rotations
        orthonormal, hinge and slide axes of unit length).

        Raises:
            InputError: invalid parameters, or traced values (inside ``jit``, ``grad``...).
        """
        if not isinstance(params, TreeParams):
            raise InputError(f"params must be a TreeParams, got {type(params).__name__}")
        return dataclasses.replace(
            self,
            **{
                name: arrays.as_numpy(getattr(params, name), f"params.{name}")
                for name in TreeParams._fields
            },
        )

    @property
    def base(self) -> FloatArray:
        """``(4, 4)`` ``T_world_base``: where :meth:`with_base` placed the model (the product
        of every placement, the identity if none). The top-level bodies' poses include it."""
        return IDENTITY if self._base is None else self._base

    def with_base(self, T_world_base: ArrayLike) -> Tree:
        """This tree placed in a new world frame: every body and site pose becomes
        ``T_world_base T_base_frame(qpos)``, where ``T_base_frame`` is this tree's
        (:meth:`fk`, the Jacobians, :meth:`ik` and :meth:`chain` follow; a chain from the
        world records the base, as :meth:`Chain.with_base <poekin.chain.Chain.with_base>`
        does). The top-level bodies and the sites fixed to the world move; nothing else.
        Bases compose as :meth:`Chain.with_base <poekin.chain.Chain.with_base>`'s do.

        Args:
            T_world_base: the model's world frame in the new world: a ``(4, 4)`` rigid
                transform, or seven numbers ``x y z qw qx qy qz`` (m, unit quaternion w first).

        Raises:
            InputError: ``T_world_base`` is not a rigid transform; or the model has a free
                joint, whose ``qpos`` places its body in the world already (set it there).
        """
        B = rigid_transform(T_world_base, "base")
        free = [k for k, t in enumerate(self.joint_types) if t == "free"]
        if free:
            k = free[0]
            raise InputError(
                f"the model has a free joint, {self.joint_names[k]!r}: its qpos (x y z qw qx "
                f"qy qz) places {self.body_names[self.joint_bodies[k]]!r} in the world already, "
                "so a base would not move it; pose the robot there instead"
            )
        R, p = B[:3, :3], B[:3, 3]
        top = self.body_parents == -1
        body_pos, body_rot = self.body_pos.copy(), self.body_rot.copy()
        body_pos[top], body_rot[top] = self.body_pos[top] @ R.T + p, R @ self.body_rot[top]
        world = self.site_bodies == -1
        site_pos, site_rot = self.site_pos.copy(), self.site_rot.copy()
        site_pos[world], site_rot[world] = self.site_pos[world] @ R.T + p, R @ self.site_rot[world]
        return dataclasses.replace(
            self,
            body_pos=body_pos,
            body_rot=body_rot,
            site_pos=site_pos,
            site_rot=site_rot,
            _base=B @ self.base,
        )

    # --- Jacobians ------------------------------------------------------------------------

    def jacobian(
        self,
        qpos: ArrayLike,
        frame: str,
        convention: JacobianConvention = "world",
        *,
        params: TreeParams | None = None,
        relative_to: str | None = None,
    ) -> FloatArray:
        """Jacobian of ``frame`` (a body or site name): ``(..., 6, nv)``.

        Columns follow MuJoCo's velocity layout (``qvel``): one per hinge or slide joint, three
        per ball joint (angular velocity about the body's own axes), six per free joint (linear
        velocity along the world axes, then angular velocity about the body's own axes). Rows
        are ``[w; v_frame]`` in world coordinates, ``v_frame`` the velocity of the frame's
        origin: MuJoCo's ``mj_jacBody``/``mj_jacSite`` as ``[jacr; jacp]``, and
        :meth:`Chain.jacobian_world` for a chain. A mimic joint adds its column, times its
        multiplier, to its leader's. ``convention="space"`` or ``"body"`` gives the rows of
        :meth:`Chain.jacobian_space` / :meth:`Chain.jacobian_body` instead
        (:func:`poekin.chain.jacobian_from_world`). ``qpos`` and ``params`` as for
        :meth:`fk`, and the result in ``qpos``'s library, as there.

        With ``relative_to`` (a body or site name, as for :meth:`pose`), the Jacobian of
        ``T_relative_frame(qpos)``, that frame in the world's role
        (:func:`poekin.chain.relative_jacobian`): the rows of ``"world"`` in its coordinates,
        ``"space"`` the twist in it, ``"body"`` in ``frame``.

        Raises:
            UnknownFrameError: no such frame.
            InputError: ``qpos`` is not ``(..., nq)`` finite numbers, or an unknown convention.
        """
        if relative_to is not None:
            check_jacobian_convention(convention)
            index, reference = self.frame_index(frame), self.frame_index(relative_to)
            T = self.fk(qpos, params=params)
            return relative_jacobian(  # type: ignore[no-any-return]
                self.jacobian(qpos, frame, "world", params=params),
                self.jacobian(qpos, relative_to, "world", params=params),
                T[..., index, :, :],
                T[..., reference, :, :],
                convention,
            )
        # the one-call fast path: a frame and convention seen before (so valid) and qpos the
        # kernel takes as it is
        if params is None and type(qpos) is np.ndarray:
            try:
                kernel = self._jacobian_kernels.get((frame, convention))
            except TypeError:  # unhashable: refused below
                kernel = None
            if kernel is not None:
                J: FloatArray | None = kernel.run(qpos)
                if J is not None:
                    return J
        check_jacobian_convention(convention)
        index = self.frame_index(frame)
        if params is not None or arrays.kind_of(qpos) is not None:
            xp, q, like, constants = self._inputs(qpos, None, params)
            columns = self._jacobian_columns(q, xp, like, constants, index, convention)
            return jacobian_array(columns, xp, like)  # type: ignore[no-any-return]
        kernel = self._jacobian_kernel(frame, index, convention)
        return _fast.run_checked(
            kernel,
            qpos,
            self._as_qpos,
            lambda checked: self._jacobian_numpy(checked, index, convention),
        )

    def _jacobian_kernel(self, frame: str, index: int, convention: str) -> Any:
        """The compiled Jacobian of frame ``frame`` (at ``index``), built at the first call."""
        key = (frame, convention)
        if key not in self._jacobian_kernels:
            scale = [1.0 if m is None else m.multiplier for m in self.mimics]
            self._jacobian_kernels[key] = _fast.tree_jacobian_program(
                self._spec,
                index,
                dof_adr=self._dof_adr.tolist(),
                dof_scale=scale,
                nv=self.nv,
                convention=convention,
            )
        return self._jacobian_kernels[key]

    def _jacobian_numpy(self, qpos: FloatArray, index: int, convention: str) -> FloatArray:
        """:meth:`jacobian` on the reference path with NumPy, for validated ``qpos``."""
        like = zeros_like_batch(qpos, np)
        columns = self._jacobian_columns(qpos, np, like, None, index, convention)
        return jacobian_array(columns, np, like)  # type: ignore[no-any-return]

    def _jacobian_columns(
        self,
        qpos: Any,
        xp: Any,
        like: Any,
        constants: _levels.Constants | None,
        index: int,
        convention: str,
    ) -> list[Column]:
        """The ``nv`` columns of frame ``index``'s Jacobian in ``convention``, entry by entry:
        each joint on the frame's path adds, times its mimic multiplier, its world axes
        ``a`` and levers ``a x (p_frame - anchor)`` (a free joint: the world axes first)."""
        poses, lib = self._poses(qpos, xp, like, constants, joints=True)
        T_frame = _levels.frame_pose(poses, self._plan, index, lib)
        p_frame = T_frame[1]
        zero: Column = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        J: list[Column] = [zero] * self.nv
        static = self._static
        for k in static.paths[index]:
            kind, d, b, scale = (
                self.joint_types[k],
                static.dof[k],
                static.joint_body[k],
                static.scale[k],
            )
            axis, anchor = _levels.joint_axis_anchor(poses, self._plan, k)
            if kind == "prismatic":
                J[d] = _add_column(J[d], (0.0, 0.0, 0.0, *axis), scale)
                continue
            if kind == "revolute":
                turning, about = [axis], anchor
            else:  # ball, free: about the body's own axes, the columns of R_b
                R_b, p_b = _levels.body_pose(poses, self._plan, b)
                turning = [(R_b[0][j], R_b[1][j], R_b[2][j]) for j in range(3)]
                about = anchor if kind == "ball" else p_b
                if kind == "free":
                    for e in range(3):
                        J[d + e] = tuple(1.0 if r == 3 + e else 0.0 for r in range(6))  # type: ignore[assignment]
                    d += 3
            reach = tuple(p_frame[i] - about[i] for i in range(3))
            for m, a in enumerate(turning):
                J[d + m] = _add_column(J[d + m], (*a, *_pose.cross(a, reach)), scale)
        return jacobian_from_world(J, T_frame, convention)

    # --- centre of mass -------------------------------------------------------------------

    def com(self, qpos: ArrayLike) -> FloatArray:
        """The whole robot's centre of mass in the world frame, ``(..., 3)``:
        ``sum_b m_b (R_b c_b + p_b) / sum_b m_b`` over every body ``b``, ``(R_b, p_b)`` its
        pose (:meth:`fk`), ``m_b`` and ``c_b`` its :attr:`body_mass` and :attr:`body_com`.

        MuJoCo's ``data.subtree_com[0]`` (the world body has no mass). A whole-body IK target:
        e.g. a humanoid's centre of mass held over its support polygon (:meth:`com_jacobian`).
        ``qpos`` as for :meth:`fk` (NumPy, JAX or PyTorch), the result in its library.

        Raises:
            ModelError: the masses are not known (an empty or NaN :attr:`body_mass`), or they
                sum to 0.
            InputError: ``qpos`` is not ``(..., nq)`` finite numbers.

        Example:
            >>> tree = poekin.load_tree("unitree_go2")
            >>> tree.com(tree.qpos0).shape
            (3,)
        """
        mass, centre, total = self._mass_terms()
        T = self.fk(qpos)
        nb = len(self.body_names)
        xp, _ = arrays.namespace_of([T])
        c = arrays.convert(centre, xp, T.dtype, T)
        m = arrays.convert(mass, xp, T.dtype, T)
        R = T[..., :nb, :3, :3]  # entry by entry, not matmul: no reduced-precision product
        x = T[..., :nb, :3, 3] + (
            (R[..., 0] * c[:, 0:1] + R[..., 1] * c[:, 1:2]) + R[..., 2] * c[:, 2:3]
        )
        return xp.sum(x * m[:, None], axis=-2) / total  # type: ignore[no-any-return]

    def com_jacobian(self, qpos: ArrayLike) -> FloatArray:
        """The Jacobian of :meth:`com`, ``(..., 3, nv)``: the centre of mass's world velocity
        is ``com_jacobian(qpos) @ qvel``.

        Columns as :meth:`jacobian`'s (MuJoCo's ``qvel``: a free joint's linear velocity along
        the world axes, then its angular velocity about the body's own axes; a mimic joint's
        column, times its multiplier, added to its leader's); MuJoCo's ``mj_jacSubtreeCom`` of
        the world body. Each joint moves its body's subtree: a hinge's column is
        ``a x (sum m_b x_b - M_sub anchor) / M`` over the subtree's bodies, a slide's
        ``M_sub a / M``. ``qpos`` as for :meth:`fk`, the result in its library.

        Raises:
            ModelError: as for :meth:`com`.
            InputError: ``qpos`` is not ``(..., nq)`` finite numbers.
        """
        mass, centre, total = self._mass_terms()
        xp, q, like, _ = self._inputs(qpos, None, None)
        poses, lib = self._poses(q, xp, like, None, joints=True)
        bodies = _levels.body_poses(poses, self._plan, lib)
        # each body's subtree: its mass, and its bodies' masses times their centres' positions
        sub_mass = [float(m) for m in mass]
        moment: list[_pose.Vec] = []
        for b, (R, p) in enumerate(bodies):
            if sub_mass[b] == 0.0:
                moment.append(_pose.ORIGIN)
                continue
            x = _pose.mat_vec(R, tuple(float(v) for v in centre[b]))
            moment.append(_scaled(sub_mass[b], (p[0] + x[0], p[1] + x[1], p[2] + x[2])))
        for b in range(len(bodies) - 1, -1, -1):
            parent = int(self.body_parents[b])
            if parent >= 0 and sub_mass[b] != 0.0:
                moment[parent] = _axpy(moment[parent], 1.0, moment[b])
                sub_mass[parent] += sub_mass[b]
        J: list[_pose.Vec] = [_pose.ORIGIN] * self.nv
        static = self._static
        for k, kind in enumerate(self.joint_types):
            b, d = static.joint_body[k], static.dof[k]
            share, scale = sub_mass[b], static.scale[k] / total
            if share == 0.0:
                continue
            axis, anchor = _levels.joint_axis_anchor(poses, self._plan, k)
            if kind == "prismatic":
                J[d] = _axpy(J[d], scale * share, axis)
                continue
            if kind == "revolute":
                turning, about = [axis], anchor
            else:  # ball, free: about the body's own axes, the columns of R_b
                R_b, p_b = bodies[b]
                turning = [(R_b[0][j], R_b[1][j], R_b[2][j]) for j in range(3)]
                about = anchor if kind == "ball" else p_b
                if kind == "free":  # moves its subtree along the world axes
                    for e, unit in enumerate(_pose.IDENTITY):
                        J[d + e] = _scaled(share / total, unit)
                    d += 3
            lever = _axpy(moment[b], -share, about)
            for j, a in enumerate(turning):
                J[d + j] = _axpy(J[d + j], scale, _pose.cross(a, lever))
        entries = [J[c][r] for r in range(3) for c in range(self.nv)]
        return _pose.stack(entries, (3, self.nv), xp, like)  # type: ignore[no-any-return]

    def _mass_terms(self) -> tuple[FloatArray, FloatArray, float]:
        """:attr:`body_mass`, :attr:`body_com` and the total mass, once they are known.

        Raises:
            ModelError: no mass known, a body's unknown, or a total mass of 0; one line.
        """
        label = f"{self.robot}: " if self.robot else ""
        if self.body_names and self.body_mass.size == 0:
            raise ModelError(
                f"{label}the body masses are not known (body_mass is empty), so neither is the "
                "centre of mass: load the model from a file that gives them (MJCF, URDF "
                "<inertial>), or give the Tree body_mass and body_com"
            )
        unknown = [self.body_names[b] for b in np.flatnonzero(np.isnan(self.body_mass))]
        if unknown:
            listed = 6
            shown = ", ".join(repr(name) for name in unknown[:listed])
            more = f" and {len(unknown) - listed} more" if len(unknown) > listed else ""
            raise ModelError(
                f"{label}the mass of {shown}{more} is not known (NaN in body_mass), so neither "
                "is the centre of mass: poekin leaves a mass unknown where MuJoCo would compute "
                "it from mesh files that were not read; with the files present, "
                "poekin.load_tree(poekin.load_model(source, read_assets=True)) reads them"
            )
        total = float(np.sum(self.body_mass))
        if not total > 0.0:
            raise ModelError(
                f"{label}the bodies' masses sum to 0, so the centre of mass is undefined; give "
                "body_mass"
            )
        return self.body_mass, self.body_com, total

    def qpos_names(self) -> tuple[str, ...]:
        """A name for each of the ``nq`` entries of ``qpos``: a hinge or slide joint's name,
        ``name[qw]`` ... ``name[qz]`` for a ball joint, ``name[x]`` ``name[y]`` ``name[z]`` then
        ``name[qw]`` ... for a free joint. Mimic joints have no entry."""
        return self._entry_names({k: tuple(words.split()) for k, words in _QPOS_WORDS.items()})

    def dof_names(self) -> tuple[str, ...]:
        """A name for each of the ``nv`` Jacobian columns (MuJoCo's ``qvel``): a hinge or slide
        joint's name, ``name[rx]``... for a ball joint, ``name[x]``... then ``name[rx]``... for a
        free joint (linear along world x y z, then angular about the body's axes)."""
        return self._entry_names({"ball": _ANGULAR, "free": ("x", "y", "z", *_ANGULAR)})

    def _entry_names(self, parts: dict[str, tuple[str, ...]]) -> tuple[str, ...]:
        """Each independent joint's name, or ``name[part]`` for each of a ball or free joint's
        ``parts``."""
        names: list[str] = []
        for name, kind, mimic in zip(self.joint_names, self.joint_types, self.mimics, strict=True):
            if mimic is not None:
                continue
            if kind in ("revolute", "prismatic"):
                names.append(name)
            else:
                names.extend(f"{name}[{part}]" for part in parts[kind])
        return tuple(names)

    # --- serial chains --------------------------------------------------------------------

    def _frame_body(self, index: int) -> int:
        nb = len(self.body_names)
        return index if index < nb else int(self.site_bodies[index - nb])

    def path_joints(self, frame: str) -> tuple[int, ...]:
        """Indices of the joints between the world and ``frame``, base to tip."""
        return self._path_joints_of_body(self._frame_body(self.frame_index(frame)))

    def chain(self, frame: str, base: str | None = None) -> Chain:
        """The serial PoE chain from the world (or the body ``base``) to ``frame``, a body or
        site name.

        The chain's joint values are the positions of the joints on the path, as stored in
        ``qpos`` (a mimic joint becomes an independent joint of the chain). Joints off the path
        do not move ``frame``. With ``base``, the chain starts in that body's frame: its screws
        and home pose are in the base's coordinates, its joints those between the base and
        ``frame`` (``T_base_frame``; e.g. a leg from a floating base, whose own free joint the
        chain leaves out).

        Raises:
            UnknownFrameError: no such frame, or no body ``base``.
            ModelError: a ball or free joint lies on the path (PoE chains are hinge/slide);
                use :meth:`fk` for such frames, or a ``base`` below it; ``base`` is not on the
                path to ``frame``.
        """
        index = self.frame_index(frame)
        joints = self.path_joints(frame)
        start = -1
        if base is not None:
            start = self._base_body(base, frame)
            joints = joints[len(self._path_joints_of_body(start)) :]
        for k in joints:
            if self.joint_types[k] in ("ball", "free"):
                raise ModelError(
                    f"joint {self.joint_names[k]!r} on the path to {frame!r} is a "
                    f"{self.joint_types[k]} joint; a PoE chain holds hinge and slide joints only: "
                    "use the whole tree, poekin.load_tree(...), with tree.pose(qpos, frame) and "
                    "tree.jacobian(qpos, frame) ('poekin fk/jacobian --tree' on the command "
                    "line), or choose a frame whose path has none"
                )
        x = self._expand(self.qpos0)
        x[self._full_adr[list(joints)]] = 0.0  # every chain joint at position 0
        lib = _levels.Lib(np, np.zeros(()), 0)
        poses = _levels.evaluate(self._plan, x, lib, None, joints=True)
        home = _levels.frames_array(poses, self._plan, "4x4", lib)[index]
        axes = np.zeros((len(joints), 3))
        anchors = np.zeros((len(joints), 3))
        for row, k in enumerate(joints):
            axis_w, anchor_w = _levels.joint_axis_anchor(poses, self._plan, k)
            axes[row], anchors[row] = axis_w, anchor_w
        if start >= 0:  # everything in the base's frame: T_base_world = (R^T, -R^T p)
            body_start = _levels.body_pose(poses, self._plan, start)
            T_world_base = _pose.to_array(body_start, "4x4", np, np.zeros(()))
            R, p = T_world_base[:3, :3], T_world_base[:3, 3]
            home = lie.inverse(T_world_base) @ home
            axes, anchors = axes @ R, (anchors - p) @ R
        screws = np.zeros((len(joints), 6))
        types: list[JointType] = []
        for row, k in enumerate(joints):
            axis, anchor = axes[row], anchors[row]
            if self.joint_types[k] == "revolute":
                screws[row, :3] = axis
                screws[row, 3:] = -np.cross(axis, anchor)
                types.append("revolute")
            else:
                screws[row, 3:] = axis
                types.append("prismatic")
        independent = all(self.mimics[k] is None for k in joints)
        return Chain(
            joint_names=tuple(self.joint_names[k] for k in joints),
            joint_types=tuple(types),
            screws=screws,
            home=home,
            limits=self.joint_limits[list(joints)],
            frame=frame,
            robot=self.robot,
            qpos_indices=tuple(int(self.qpos_adr[k]) for k in joints) if independent else None,
            _base=self._base if start < 0 else None,
            _tree=self if start < 0 and independent else None,
        )

    def ik(
        self,
        T: ArrayLike | Mapping[str, ArrayLike],
        frame: Any = None,
        qpos: ArrayLike | None = None,
        *,
        warm_start: bool = False,
        seed: int = 0,
        pos_tol: float = 1e-10,
        ori_tol: float = 1e-10,
        position_only: Any = False,
        orientation_only: Any = None,
        orientation_weight: float = 0.3,
        max_iterations: int = 50,
        max_attempts: int | None = None,
        hold: Any = None,
        weights: Mapping[str, float] | None = None,
        posture: float | ArrayLike = 0.0,
        freeze: Collection[str] = (),
        avoid: bool = False,
        obstacles: Any = (),
        margin: float = 0.005,
        ignore: Collection[tuple[str, str]] = (),
    ) -> Any:
        """Inverse kinematics: the ``qpos`` that puts one frame, or many at once, at targets.

        **One frame**, ``tree.ik(T, frame, qpos)``: numerical inverse kinematics over the
        hinge and slide joints on the path to ``frame``, every other joint held at ``qpos``.
        One arm of a two-armed robot or one leg of a quadruped: the other arm, the other legs
        and a floating base keep their values. A ball or free joint on the path is held too,
        and the joints below it are solved in its body's frame. The options, the algorithm and
        the result (an :class:`~poekin.ik.IKResult`, ``q`` the whole ``(..., nq)`` qpos) are
        those of :meth:`poekin.Chain.ik`.

        **Many frames**, ``tree.ik(targets, qpos, hold=..., ...)`` with a dict of frame names
        to targets (:mod:`poekin.wholebody`): every joint is solved for at once, a floating
        base and ball joints too (on their group: quaternions stay unit). ``hold`` names
        frames that are constraints, met to ``pos_tol``/``ori_tol`` whenever they can be, the
        others are weighted least squares in their null space, and ``posture`` pulls toward
        ``qpos`` in what redundancy is left. Limits are constraints: every iterate is inside
        them. The first attempt starts at ``qpos``; further ones (up to ``max_attempts``,
        default 20) from drawn starts, as the module's docstring says. Returns a
        :class:`~poekin.wholebody.WholeBodyResult`.

        Args:
            T: ``(..., 4, 4)`` targets ``T_world_frame`` (world frame); or a dict of frame
                names (bodies, sites, or ``"com"``, the centre of mass) to targets: a pose
                ``(..., 4, 4)``, a point ``(..., 3)`` for a frame in ``position_only`` (and the
                CoM), a rotation ``(..., 3, 3)`` for one in ``orientation_only``.
            frame: the body or site to place (one frame); with a dict, ``qpos`` may come here.
            qpos: ``(..., nq)`` the values of every joint (MuJoCo's layout), broadcast against
                the targets; default :attr:`qpos0`.
            warm_start: one frame: start the first attempt at ``qpos``'s values of the solved
                joints, rather than at a random configuration.
            seed: the random starts' seed.
            pos_tol: success: position within this (m) ...
            ori_tol: ... and orientation within this (rad), for every frame.
            position_only: one frame: True to reach its position only; many: the names of the
                frames placed by position only.
            orientation_only: many: the names of the frames placed by orientation only.
            orientation_weight: metres per radian in the least-squares residual.
            max_iterations: iterations per attempt.
            max_attempts: attempts per target (default 100 for one frame, 20 for many).
            hold: many: the names of the frames met exactly (contacts, e.g. the feet).
            weights: many: frame name to weight (default 1) of a soft frame's cost.
            posture: many: a weight ``> 0`` (or one ``>= 0`` per ``qvel`` entry) of the pull
                toward ``qpos`` in the null space of the targets: the solution nearest
                ``qpos`` in the norm ``sum w_i dq_i^2`` (only the ratios matter: the targets
                come first); the floating base is never pulled.
            freeze: many: names of joints kept at ``qpos`` (a humanoid's fingers).
            avoid: one frame: keep every checked collision pair (the robot with itself and
                with ``obstacles``, the joints held at ``qpos`` included) at least ``margin``
                apart, a constraint inside the solve (:mod:`poekin.ik.collision_free`, as
                :meth:`poekin.Chain.ik`); ``success`` then also means collision-free.
            obstacles, margin, ignore: with ``avoid``: as for :meth:`distances` (``margin``
                the distance kept, m, default 5 mm).

        Returns:
            One frame: an :class:`~poekin.ik.IKResult` whose ``q`` is the whole ``(..., nq)``
            qpos. Many: a :class:`~poekin.wholebody.WholeBodyResult`.

        Raises:
            UnknownFrameError: no such frame (the message suggests one).
            InputError: bad targets, ``qpos`` or options; for one frame, a mimic joint on the
                path, or a ball or free joint below a hinge or slide one; for many, a frame
                both held and weighted, options naming frames without a target.
            HeldFramesError: held frames whose targets cannot be met together (an InputError).

        Example:
            >>> tree = poekin.load_tree("aloha")
            >>> qpos = poekin.sample_qpos(tree, 1, seed=1, within_limits=True)[0]
            >>> T = tree.pose(qpos, "left/gripper")
            >>> found = tree.ik(T, "left/gripper")  # the right arm stays at qpos0
            >>> bool(found.success), found.q.shape
            (True, (16,))
        """
        from poekin.ik.numerical import settings

        listed = [not (isinstance(a, tuple | list) and len(a) == 0) for a in (obstacles, ignore)]
        collision = None
        if avoid is not False or any(listed) or margin != 0.005:
            from poekin.collision.avoid import check_margin
            from poekin.collision.obstacles import as_obstacles

            if avoid is not True:
                raise InputError(
                    "obstacles=, margin= and ignore= take effect with avoid=True: pass it"
                    if avoid is False
                    else f"avoid must be True or False, got {avoid!r:.40}"
                )
            if isinstance(T, Mapping):
                raise InputError(
                    "avoid=True solves one frame, tree.ik(T, frame, qpos, avoid=True); a dict "
                    "of targets does not take it yet (issue #29)"
                )
            collision = (as_obstacles(obstacles), check_margin(margin, "ik"), tuple(ignore))
        if isinstance(T, Mapping):
            from poekin.wholebody import solve

            if frame is not None and qpos is not None:
                raise InputError(
                    "with a dict of targets, give qpos once: tree.ik(targets, qpos) or "
                    "tree.ik(targets, qpos=qpos)"
                )
            if warm_start:
                raise InputError(
                    "warm_start is for one frame; with a dict of targets the first attempt "
                    "always starts at qpos"
                )
            options = settings(
                pos_tol=pos_tol,
                ori_tol=ori_tol,
                orientation_weight=orientation_weight,
                max_iterations=max_iterations,
                max_attempts=20 if max_attempts is None else max_attempts,
            )
            return solve(
                self,
                T,
                qpos if frame is None else frame,
                hold=hold,
                position_only=None if position_only is False else position_only,
                orientation_only=orientation_only,
                weights=weights,
                posture=posture,
                freeze=freeze,
                seed=seed,
                options=options,
            )
        from poekin.ik.trees import solve_tree

        many = {
            "hold": hold is not None,
            "orientation_only": orientation_only is not None,
            "weights": weights is not None,
            "posture": not (isinstance(posture, int | float) and posture == 0),
            "freeze": bool(freeze),
        }
        used = [name for name, given in many.items() if given]
        if used or not isinstance(frame, str):
            what = f"{used[0]}= is" if used else "a frame name is needed"
            raise InputError(
                f"{what} for a dict of targets: tree.ik({{frame: T, ...}}, qpos, ...); one "
                "frame is tree.ik(T, frame, qpos)"
            )
        options = settings(
            pos_tol=pos_tol,
            ori_tol=ori_tol,
            position_only=position_only,
            orientation_weight=orientation_weight,
            max_iterations=max_iterations,
            max_attempts=100 if max_attempts is None else max_attempts,
        )
        return solve_tree(
            self,
            T,
            frame,
            qpos,
            warm_start=warm_start,
            seed=seed,
            options=options,
            collision=collision,
        )

    def follow(
        self,
        T_path: Any,
        qpos0: ArrayLike,
        frame: str,
        *,
        hold: Any = None,
        max_step: float = 0.1,
        tol: float = 1e-4,
        ori_tol: float = 1e-3,
        samples: int | None = None,
        freeze: Collection[str] = (),
        position_only: Collection[str] = (),
        obstacles: Any = None,
        margin: float = 0.0,
        ignore: Collection[tuple[str, str]] = (),
    ) -> Any:
        """IK along a pose path for one frame, the whole body solved, other frames held: the
        tree's :meth:`poekin.Chain.follow` (:func:`poekin.motion.follow.follow_tree`).

        Each sample is :meth:`ik` with a dict of targets (``frame`` at the path's pose, each
        frame of ``hold`` where it is at ``qpos0``, met exactly) from the previous sample; the
        path is re-sampled until ``frame`` stays within ``tol`` and ``ori_tol`` of it between
        samples and nothing moves more than ``max_step``, and it stops where it cannot go on
        (``reason`` ``"joint_limit"``, ``"unreachable"`` or ``"jump"``).

        Args:
            T_path: ``(N, 4, 4)`` poses of ``frame`` at ``s = 0, 1/(N-1), ..., 1`` (joined by
                screw motions), or a callable taking ``(m,)`` path parameters to ``(m, 4, 4)``.
            qpos0: ``(nq,)`` the start, ``frame`` on the path's start.
            frame: the body or site that follows the path.
            hold: frames held where they are at ``qpos0`` (a name or names: the feet).
            max_step: the largest move between two samples of a joint, of the base's position
                or of a quaternion's angle (rad, m), > 0.
            tol, ori_tol: the largest deviation of ``frame`` from the path between samples (m,
                rad), > 0.
            samples: a callable path's first samples (11), >= 2.
            freeze: joints kept at ``qpos0`` (the fingers).
            position_only: held frames held by their position only (a quadruped's feet,
                which turn as the body moves).
            obstacles: check every sample for collisions (with itself and these obstacles;
                ``[]``: itself alone): the path ends before the first colliding sample,
                reason ``"collision"``, ``pair`` the pair. None (the default): no check.
            margin, ignore: with ``obstacles``: as for :meth:`in_collision`.

        Returns:
            A :class:`~poekin.motion.follow.FollowResult` with ``q`` ``(K, nq)`` (``qpos``) and
            ``T`` the poses of ``frame``.

        Raises:
            UnknownFrameError: ``frame`` or a held frame names no body or site.
            InputError: as :meth:`poekin.Chain.follow`, and ``frame`` held too.
        """
        from poekin.motion.follow import collision_stop, follow_tree

        if obstacles is not None:  # checked before the path is followed
            from poekin.collision.avoid import check_margin
            from poekin.collision.obstacles import as_obstacles

            checks = (as_obstacles(obstacles), check_margin(margin, "follow"), tuple(ignore))
        found = follow_tree(
            self,
            T_path,
            qpos0,
            frame,
            hold=hold,
            max_step=max_step,
            tol=tol,
            ori_tol=ori_tol,
            samples=samples,
            freeze=tuple(freeze),
            position_only=tuple(position_only),
        )
        if obstacles is None:
            return found
        return collision_stop(found, self, np.asarray(found.q), *checks)

    def distances(
        self,
        qpos: ArrayLike,
        obstacles: Any = (),
        *,
        margin: float = float("inf"),
        ignore: Collection[tuple[str, str]] = (),
    ) -> Distances:
        """The signed distance and witness points of every checked collision pair.

        The pairs are the model's collision geoms as MuJoCo pairs them (``contype`` and
        ``conaffinity``, no body with its parent, ``<exclude>``, ``<pair>``; for a URDF, no
        link with an adjacent one), then each geom with each obstacle, and the obstacles
        with each other (never two fixed to the world): :mod:`poekin.collision.model`. Each
        is measured by MuJoCo's ``mj_geomDistance`` on the geoms' poses from :meth:`fk`.

        Args:
            qpos: ``(..., nq)`` configurations (MuJoCo's layout).
            obstacles: :class:`poekin.collision.Box`, ``Sphere``, ``Capsule``, ``Plane`` or
                ``Mesh`` (one or a list), in the world or attached to a frame.
            margin: pairs farther apart than this (m) are not measured (distance ``inf``,
                points NaN); default: every pair measured.
            ignore: pairs of names (geoms, bodies or obstacles) not to check.

        Returns:
            A :class:`~poekin.collision.Distances`: ``distance (..., P)`` (m, negative: the
            penetration depth), ``points (..., P, 2, 3)`` in the world frame, and ``pairs``,
            the ``P`` pairs' names.

        Raises:
            ModelError: the tree was not loaded from a model file, or its collision meshes
                are missing (poekin's built-in copies have no mesh files).
            InputError: bad ``qpos``, obstacles, ``margin`` or ``ignore``.
            UnknownFrameError: an obstacle attached to a frame that the tree does not have.

        Example:
            >>> tree = poekin.load_tree("universal_robots_ur5e")
            >>> found = tree.distances([0.0, -1.57, 1.57, 0.0, 0.0, 0.0])
            >>> bool((found.distance > 0).all())
            True
        """
        from poekin.collision.query import distances

        return distances(self, qpos, obstacles, margin=margin, ignore=ignore)

    def min_distance(
        self,
        qpos: ArrayLike,
        obstacles: Any = (),
        *,
        ignore: Collection[tuple[str, str]] = (),
    ) -> FloatArray:
        """``(...)`` the smallest signed distance (m) over every pair :meth:`distances`
        checks (``inf`` where there is none); arguments and errors as there."""
        from poekin.collision.query import min_distance

        return min_distance(self, qpos, obstacles, ignore=ignore)

    def in_collision(
        self,
        qpos: ArrayLike,
        obstacles: Any = (),
        *,
        margin: float = 0.0,
        ignore: Collection[tuple[str, str]] = (),
    ) -> NDArray[np.bool_]:
        """``(...)`` whether any pair that :meth:`distances` checks is closer than ``margin``
        (m; 0: whether any two geoms penetrate, touching is not a collision); arguments and
        errors as there."""
        from poekin.collision.query import in_collision

        return in_collision(self, qpos, obstacles, margin=margin, ignore=ignore)

    def ik_step(
        self,
        targets: Mapping[str, ArrayLike],
        qpos: ArrayLike,
        dt: float,
        *,
        hold: Any = None,
        position_only: Any = None,
        orientation_only: Any = None,
        weights: Mapping[str, float] | None = None,
        posture: float | ArrayLike = 0.0,
        velocity_limits: ArrayLike | None = None,
        gain: float = 1.0,
        damping: float = 1e-12,
        orientation_weight: float = 0.3,
        freeze: Collection[str] = (),
    ) -> FloatArray:
        """One control tick of differential IK: the joint velocity toward the targets.

        The least-squares step of :mod:`poekin.wholebody.step` from ``qpos``: the held
        frames' velocity exactly zero, the soft frames moved ``gain`` of the way to their
        targets (weighted, damped by ``damping``), the posture (toward
        :attr:`qpos0`) in what redundancy is left, and every hinge and slide joint within its
        limits at ``qpos + qvel dt`` and within ``velocity_limits``. Integrate the answer as
        MuJoCo does (``mj_integratePos``: a free joint's linear part in the world frame, its
        angular part and a ball joint's about the body's own axes).

        One soft frame of an arm (a tree whose every joint is a hinge or slide on that
        frame's path), without held frames, weights, posture or frozen joints, is the problem
        of :meth:`Chain.ik_step <poekin.Chain.ik_step>`, and runs its compiled kernel.

        Args:
            targets: frame names (or ``"com"``) to targets, as for :meth:`ik`.
            qpos: ``(..., nq)`` the configuration now (MuJoCo's layout); the batch broadcasts
                against the targets' (4,096 environments in one call).
            dt: the tick (s).
            hold, position_only, orientation_only, weights, posture, freeze: as for
                :meth:`ik`.
            velocity_limits: the largest speed of each ``qvel`` entry (rad/s, m/s): one
                number, or ``(nv,)`` with ``inf`` for none; default the model's
                (:attr:`joint_velocity_limits`: a URDF's ``<limit velocity>``; an MJCF has
                none).
            gain: the fraction of each soft frame's error removed in one tick (1: all of it).
            damping: the step's Tikhonov damping (m^2).
            orientation_weight: metres per radian in the residual.

        Returns:
            ``(..., nv)`` joint velocities (MuJoCo's ``qvel`` layout; frozen joints 0).

        Raises:
            UnknownFrameError, InputError: as for :meth:`ik`; a bad ``dt``, ``gain``,
                ``damping`` or ``velocity_limits``.
        """
        if (
            type(targets) is dict
            and len(targets) == 1
            and hold is None
            and orientation_only is None
            and weights is None
            and type(posture) is float
            and posture == 0.0
            and not freeze
        ):  # one frame of an arm: the compiled step of its chain, the same problem
            qvel = self._chain_step(
                targets, qpos, dt, position_only, velocity_limits, gain, damping, orientation_weight
            )
            if qvel is not None:
                return qvel
        from poekin.wholebody.step import solve_step, step_problem

        return solve_step(
            step_problem(
                self,
                targets,
                qpos,
                dt,
                hold=hold,
                position_only=position_only,
                orientation_only=orientation_only,
                weights=weights,
                posture=posture,
                velocity_limits=velocity_limits,
                gain=gain,
                damping=damping,
                orientation_weight=orientation_weight,
                freeze=freeze,
            )
        )

    def _chain_step(
        self,
        targets: dict[str, ArrayLike],
        qpos: ArrayLike,
        dt: float,
        position_only: object,
        velocity_limits: ArrayLike | None,
        gain: float,
        damping: float,
        orientation_weight: float,
    ) -> FloatArray | None:
        """:meth:`ik_step` of one soft frame (no held frame, posture, weight or frozen joint)
        by :meth:`Chain.ik_step <poekin.Chain.ik_step>`, the compiled kernel's, where the tree
        is that frame's chain (:meth:`_arm_chain`): the same problem (the frame's residual rows
        and their exact derivative, the damping, the box of the limits and the velocity
        limits), which the chain solves by the box's active set rather than the null-space
        levels. None where that does not serve, or where the chain refuses the arguments: the
        usual path then solves, or says what is wrong."""
        ((frame, T),) = targets.items()
        if type(frame) is not str:
            return None
        if position_only is None:
            point = False
        elif position_only == frame or (
            isinstance(position_only, set | frozenset | list | tuple)
            and len(position_only) > 0
            and all(name == frame for name in position_only)
        ):
            point = True
        else:
            return None
        arms = self._ik_cache.setdefault("arm_chains", {})  # frame: _arm_chain's answer
        if frame not in arms:
            arms[frame] = self._arm_chain(frame)
        arm = arms[frame]
        q = qpos if type(qpos) is np.ndarray else np.asarray(qpos)
        if arm is None or q.dtype != np.float64 or q.ndim < 1 or q.shape[-1] != self.nq:
            return None
        chain, model_limits = arm
        try:
            qvel: FloatArray = chain.ik_step(
                T,
                q,
                dt,
                velocity_limits=model_limits if velocity_limits is None else velocity_limits,
                gain=gain,
                damping=damping,
                position_only=point,
                orientation_weight=orientation_weight,
            )
        except InputError:
            return None
        return qvel

    def _arm_chain(self, frame: str) -> tuple[Chain, FloatArray | None] | None:
        """The chain of ``frame`` where the tree is that chain, in qpos and qvel alike (every
        joint on the frame's path in qpos order, each a hinge or a slide, none a mimic), with
        the model's velocity limits for its step (None where there are none); else None (a
        tree with joints off the path, a floating base, mimic joints)."""
        try:
            joints = self.path_joints(frame)
        except UnknownFrameError:
            return None
        plain = all(t in ("revolute", "prismatic") for t in self.joint_types) and all(
            m is None for m in self.mimics
        )
        every = list(range(len(self.joint_names)))
        if not plain or list(joints) != every:
            return None
        if list(self.qpos_adr) != every or list(self._dof_adr) != every:
            return None
        from poekin.wholebody.step import model_velocity_limits

        limits = model_velocity_limits(None, self)
        return self.chain(frame), None if np.all(np.isinf(limits)) else limits

    def _path_joints_of_body(self, body: int) -> tuple[int, ...]:
        path = []
        while body >= 0:
            path.append(body)
            body = int(self.body_parents[body])
        return tuple(k for b in reversed(path) for k in self._body_joints[b])

    def _base_body(self, base: str, frame: str) -> int:
        """The index of body ``base``, which must lie on the path from the world to ``frame``."""
        if base not in self.body_names:
            raise UnknownFrameError(
                f"no body named {base!r}: {did_you_mean(base, list(self.body_names))}"
            )
        b = self.body_names.index(base)
        body = self._frame_body(self.frame_index(frame))
        while body >= 0 and body != b:
            body = int(self.body_parents[body])
        if body != b:
            raise ModelError(
                f"body {base!r} is not on the path from the world to {frame!r}: a chain's base "
                "must be the frame's body or one of its ancestors"
            )
        return b

    def __repr__(self) -> str:
        source = f"{self.robot!r}, " if self.robot else ""
        return (
            f"Tree({source}{len(self.body_names)} bodies, {len(self.joint_names)} joints, "
            f"{len(self.site_names)} sites, nq={self.nq}, nv={self.nv})"
        )

    def describe(self) -> dict[str, Any]:
        """A JSON-ready summary: bodies with parents, joints with types and qpos addresses."""
        return {
            "robot": self.robot,
            "nq": self.nq,
            "nv": self.nv,
            "bodies": [
                {"name": n, "parent": self.body_names[p] if p >= 0 else "world"}
                for n, p in zip(self.body_names, self.body_parents, strict=True)
            ],
            "joints": [
                {
                    "name": n,
                    "type": t,
                    "body": self.body_names[b],
                    "qpos_adr": int(a),
                    **({"mimic": dataclasses.asdict(m)} if m is not None else {}),
                }
                for n, t, b, a, m in zip(
                    self.joint_names,
                    self.joint_types,
                    self.joint_bodies,
                    self.qpos_adr,
                    self.mimics,
                    strict=True,
                )
            ],
            "sites": [
                {"name": n, "body": self.body_names[b] if b >= 0 else "world"}
                for n, b in zip(self.site_names, self.site_bodies, strict=True)
            ],
        }


def tree_of_chain(chain: Chain) -> Tree:
    """:meth:`poekin.Chain.as_tree`: ``chain`` as a tree with the same FK."""
    n = chain.n_joints
    axes = np.zeros((n, 3))
    anchors = np.zeros((n, 3))
    for i, (kind, S) in enumerate(zip(chain.joint_types, chain.screws, strict=True)):
        if kind == "revolute":
            axes[i] = S[:3]
            anchors[i] = np.cross(S[:3], S[3:])  # a point on the axis: v = -w x q
        else:
            axes[i] = S[3:]
    limits = np.tile([-np.inf, np.inf], (n, 1)) if chain.limits is None else chain.limits
    return Tree(
        body_names=tuple(f"link{i + 1}" for i in range(n)),
        body_parents=np.arange(-1, n - 1),
        body_pos=np.zeros((n, 3)),
        body_rot=np.broadcast_to(np.eye(3), (n, 3, 3)),
        joint_names=chain.joint_names,
        joint_types=chain.joint_types,
        joint_bodies=np.arange(n),
        joint_axes=axes,
        joint_anchors=anchors,
        joint_refs=np.zeros(n),
        joint_limits=limits,
        mimics=(None,) * n,
        site_names=(chain.frame or "end",),
        site_bodies=np.array([n - 1]),
        site_pos=chain.home[None, :3, 3],
        site_rot=chain.home[None, :3, :3],
        robot=chain.robot,
    )


register_tree_of_chain(tree_of_chain)
