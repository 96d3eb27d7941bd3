"""What the viewer draws at a configuration: pure computation on poekin's own FK and Jacobians.

No viser and no matplotlib here, so every number the viewer and ``poekin draw`` show can be
tested against :meth:`Tree.fk <poekin.tree.Tree.fk>`, :meth:`Chain.fk <poekin.chain.Chain.fk>`
and the Jacobians directly.

A :class:`Subject` is what is shown: a whole tree (from a model file) or a bare parameter set
(a :class:`~poekin.chain.Chain` or :class:`~poekin.dh.DHTable` typed by hand), and the PoE chain to
one end frame. Its configuration is ``qpos`` in MuJoCo's layout (for a bare chain: its ``n`` joint
values). :func:`snapshot` gives everything to draw at one ``qpos``:

* body (link) poses, and every frame's pose;
* the end frame ``T(q)`` and the home pose ``M`` (a ghost frame);
* each joint's screw axis at the current ``q``, in space form ``S_i(q) = Ad(T_{i-1}) S_i``
  (column ``i`` of ``J_s(q)``, world coordinates) and body form ``B_i(q)`` (column ``i`` of
  ``J_b(q)``, end-frame coordinates). Both are the same line in space, the joint's axis: they
  are its coordinates in two frames. At ``q = 0`` they are the chain's ``S_i`` and
  ``B_i = Ad(M^-1) S_i``;
* the PoE partial products ``T_k = e^[S1]q1 ... e^[Sk]qk M``, ``k = 0..n`` (``T_0 = M``,
  ``T_n = T(q)``), equal to ``M e^[B1]q1 ... e^[Bk]qk``.

A frame behind a ball or free joint (a floating base) has no PoE chain from the world; its chain
starts at the body of the last such joint instead (:func:`floating_chain`), whose pose the tree
gives: ``T_world_frame = T_world_base(qpos) e^[S1]q1 ... e^[Sn]qn M`` with ``S_i`` and ``M`` in
that body's frame.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import (
    Chain,
    JacobianConvention,
    as_joint_values,
    check_jacobian_convention,
    rigid_transform,
)
from poekin.dh import Convention, DHTable, dh_from_chain, joint_lines
from poekin.errors import InputError, ModelError
from poekin.tree import Tree
from poekin.verification.diagnose import Diagnosis, diagnose
from poekin.verification.verify import pose_errors

__all__ = [
    "FORMS",
    "Comparison",
    "Control",
    "Form",
    "Ghost",
    "Segment",
    "Snapshot",
    "Subject",
    "axis_pose",
    "compare",
    "controls",
    "default_frame",
    "dh_frames",
    "floating_chain",
    "format_matrix",
    "ghost",
    "jacobian",
    "joint_anchors",
    "link_frames",
    "make_subject",
    "manipulability",
    "nearest_point",
    "pose_summary",
    "screw_kind",
    "skeleton",
    "snapshot",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
Form = Literal["space", "body"]
FORMS: tuple[Form, ...] = ("space", "body")
ScrewKind = Literal["revolute", "pitched", "prismatic"]

_PITCH_TOL = 1e-9  # m/rad: below this a revolute screw counts as a pure rotation
_MIN_SEGMENT = 1e-6  # m: shorter skeleton segments are not drawn
_UNLIMITED_REVOLUTE = (-2.0 * math.pi, 2.0 * math.pi)
_UNLIMITED_SLIDE = (-1.0, 1.0)


# --- what is shown --------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Subject:
    """A robot to show: its whole tree (if it has one) and the PoE chain to one end frame.

    Build it with :func:`make_subject`.

    Attributes:
        chain: the PoE chain to ``frame``: from the world, or, behind a ball or free joint,
            from body ``base_body`` (its screws and ``M`` in that body's frame).
        frame: the end frame's name.
        tree: the whole model, or None for a bare parameter set.
        base_body: index (in ``tree.body_names``) of the body the chain starts from, or None
            when it starts from the world.
        slots: ``(n,)`` where each chain joint's value is in ``tree.full_qpos(qpos)``
            (``0..n-1`` for a bare chain).
        table: the DH table the parameters were given as (a bare DH parameter set), else None.
        keyframes: the model's named configurations (MJCF ``<keyframe>``), ``{name: qpos}``.
        name: a label: the robot or parameter set.
        tool: ``T_frame_tool``, a tool the chain carries on ``frame`` (its end frame is then
            the tool's: :meth:`~poekin.chain.Chain.with_tool`), or None.
    """

    chain: Chain
    frame: str
    tree: Tree | None = None
    base_body: int | None = None
    slots: IntArray = dataclasses.field(default_factory=lambda: np.zeros(0, np.intp))
    table: DHTable | None = None
    keyframes: Mapping[str, FloatArray] = dataclasses.field(default_factory=dict)
    name: str = ""
    tool: FloatArray | None = None
    _dh: dict[str, DHTable] = dataclasses.field(default_factory=dict, repr=False)

    @property
    def end_name(self) -> str:
        """The end frame as labels name it: ``frame``, or the tool and the frame it is on."""
        return self.frame if self.tool is None else f"{self.chain.frame} on {self.frame}"

    @property
    def nq(self) -> int:
        """Length of the configuration: the tree's ``nq``, or the bare chain's ``n``."""
        return self.tree.nq if self.tree is not None else self.chain.n_joints

    @property
    def qpos0(self) -> FloatArray:
        """The default configuration: the tree's ``qpos0``, or zeros for a bare chain."""
        return self.tree.qpos0.copy() if self.tree is not None else np.zeros(self.nq)

    @property
    def n_joints(self) -> int:
        """Joints of the chain to the end frame."""
        return self.chain.n_joints

    def check_qpos(self, qpos: ArrayLike) -> FloatArray:
        """``qpos`` as a float64 ``(nq,)`` array, or :class:`InputError` naming the layout."""
        if self.tree is not None:
            what, layout = "qpos values", self.tree.qpos_layout()
        else:
            what, layout = "joint values", ""
        x = as_joint_values(qpos, self.nq, what=what, layout=layout)
        if x.ndim != 1:
            raise InputError(f"one configuration of {self.nq} {what}, got shape {x.shape}")
        return np.array(x, dtype=np.float64)

    def chain_q(self, qpos: FloatArray) -> FloatArray:
        """The chain's ``(n,)`` joint values in ``qpos``."""
        if self.tree is None:
            return np.asarray(qpos, dtype=np.float64)
        return np.asarray(self.tree.full_qpos(qpos)[self.slots], dtype=np.float64)

    @property
    def body_names(self) -> tuple[str, ...]:
        """The bodies that geometry hangs on: the tree's, or a bare chain's links
        ``base, link1 .. linkn`` (link ``i`` moves with joint ``i``)."""
        if self.tree is not None:
            return self.tree.body_names
        return ("base", *(f"link{i + 1}" for i in range(self.n_joints)))

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Frames shown with "all frames": the tree's bodies and sites, or a bare chain's links
        and its end frame."""
        if self.tree is not None:
            return self.tree.frame_names
        return (*self.body_names, self.frame)

    def dh(self, convention: Convention) -> DHTable:
        """The chain's DH table in ``convention``: the one given, else extracted (cached)."""
        if self.table is not None and self.table.convention == convention:
            return self.table
        if convention not in self._dh:
            self._dh[convention] = dh_from_chain(self.chain, convention)
        return self._dh[convention]

    @property
    def extent(self) -> float:
        """The robot's size (m) at ``qpos0``, for scaling triads, arrows and stand-ins: the
        diagonal of the box around its frame origins, joint points and home pose; at least
        0.1 m."""
        snap = snapshot(self, self.qpos0)
        points = np.vstack([snap.frames[:, :3, 3], snap.home[None, :3, 3], snap.points])
        return max(float(np.linalg.norm(points.max(axis=0) - points.min(axis=0))), 0.1)


def default_frame(tree: Tree) -> str:
    """The end frame shown when none is named: the model's only site when a hinge or slide
    joint moves it, else the first frame (bodies, then sites) with the most hinge and slide
    joints on its path.

    Raises:
        ModelError: the model has no body and no site.
    """
    if not tree.frame_names:
        raise ModelError(f"{tree.robot or 'the model'} has no body or site to show")

    def moving(frame: str) -> int:
        return sum(
            tree.joint_types[k] in ("revolute", "prismatic") for k in tree.path_joints(frame)
        )

    sites = tree.site_names
    if len(sites) == 1 and moving(sites[0]):
        return sites[0]
    return max(tree.frame_names, key=moving)  # the first of equals


def floating_chain(tree: Tree, frame: str) -> tuple[Chain, int | None]:
    """The PoE chain to ``frame``, and the body it starts from (None: the world).

    Without a ball or free joint on the path this is ``tree.chain(frame)``. Otherwise the chain
    holds the hinge and slide joints of the bodies after the last such joint's body (the
    *base*), its screws and ``M`` in the base body's frame, taken from the tree at the
    configuration where those joints are 0 (``qpos0`` elsewhere): ``S_i = Ad(T_world_base^-1)
    J_s[:, i]`` and ``M = T_world_base^-1 T_world_frame``. Then ``T_world_frame(qpos) =
    T_world_base(qpos) chain.fk(q)``.

    Raises:
        UnknownFrameError: no such frame.
        ModelError: a mimic joint lies on the path below a ball or free joint.
    """
    path = tree.path_joints(frame)
    floating = [k for k in path if tree.joint_types[k] in ("ball", "free")]
    if not floating:
        return tree.chain(frame), None
    base = int(tree.joint_bodies[floating[-1]])
    joints = [k for k in path if tree.joint_bodies[k] > base]
    if any(tree.mimics[k] is not None for k in joints):
        raise ModelError(
            f"a mimic joint lies on the path to {frame!r} below a {tree.joint_types[floating[-1]]} "
            "joint: the viewer cannot pose it as a chain; choose another frame"
        )
    qpos = tree.qpos0.copy()
    qpos[tree.qpos_adr[joints]] = 0.0
    poses = tree.fk(qpos)
    index = tree.frame_index(frame)
    to_base = np.asarray(lie.inverse(poses[base]), dtype=np.float64)
    columns = [tree.dof_names().index(tree.joint_names[k]) for k in joints]
    J = tree.jacobian(qpos, frame, "space")[:, columns]
    screws = (np.asarray(lie.adjoint(to_base)) @ J).T
    chain = Chain(
        joint_names=tuple(tree.joint_names[k] for k in joints),
        joint_types=tuple(
            "revolute" if tree.joint_types[k] == "revolute" else "prismatic" for k in joints
        ),
        screws=screws.reshape(len(joints), 6),
        home=to_base @ poses[index],
        limits=tree.joint_limits[joints].reshape(len(joints), 2),
        frame=frame,
        robot=tree.robot,
        qpos_indices=tuple(int(tree.qpos_adr[k]) for k in joints),
    )
    return chain, base


def make_subject(
    model: Tree | Chain | DHTable,
    frame: str | None = None,
    *,
    keyframes: Mapping[str, ArrayLike] | None = None,
    name: str = "",
    tool: ArrayLike | None = None,
) -> Subject:
    """What to show for a tree (with an end frame) or a bare parameter set.

    Args:
        model: a whole tree, or a chain or DH table typed by hand.
        frame: the tree's end frame (a body or site); None: :func:`default_frame`. A chain's
            or table's own end frame is used whatever this says, unless it differs (an error).
        keyframes: named configurations of the tree (``{name: qpos}``).
        name: a label; default the robot's name.
        tool: ``T_frame_tool``, a tool on the end frame (a ``(4, 4)`` rigid transform or ``x y
            z qw qx qy qz``): the end frame shown, solved for and compared is then the tool's.

    Raises:
        UnknownFrameError: no such frame in the tree.
        InputError: a frame named for a bare parameter set that is not its own, a keyframe
            of the wrong length, a tool that is no rigid transform or on a frame behind a
            ball or free joint.
    """
    T_tool = None if tool is None else rigid_transform(tool, "tool")
    if isinstance(model, Tree):
        end = frame if frame is not None else default_frame(model)
        chain, base = floating_chain(model, end)
        if T_tool is not None:
            if base is not None:
                raise InputError(
                    f"a tool on {end!r}, which sits behind a ball or free joint: the viewer "
                    "places a tool on a frame the world's joints move; choose another frame"
                )
            chain = chain.with_tool(T_tool)
        path = [k for k in model.path_joints(end) if model.joint_names[k] in chain.joint_names]
        keys = {
            k: as_joint_values(v, model.nq, what=f"qpos values of keyframe {k!r}").copy()
            for k, v in (keyframes or {}).items()
        }
        return Subject(
            chain=chain,
            frame=end,
            tree=model,
            base_body=base,
            slots=np.array(model.full_qpos_adr[path], dtype=np.intp).reshape(-1),
            keyframes=keys,
            name=name or model.robot,
            tool=T_tool,
        )
    table = model if isinstance(model, DHTable) and T_tool is None else None
    chain = model.to_chain() if isinstance(model, DHTable) else model
    if frame is not None and frame != chain.frame:
        raise InputError(f"a parameter set has one end frame, {chain.frame!r}; got frame {frame!r}")
    end = chain.frame
    if T_tool is not None:
        chain = chain.with_tool(T_tool)
    return Subject(
        chain=chain,
        frame=end,
        slots=np.arange(chain.n_joints, dtype=np.intp),
        table=table,
        name=name or chain.robot or "your parameters",
        tool=T_tool,
    )


# --- controls ---------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Control:
    """One joint's control in the panel.

    ``kind`` is the joint type; ``adr`` where its numbers start in ``qpos``; ``lower`` and
    ``upper`` the slider's range for a hinge or slide (its limits, else +-2 pi rad or +-1 m).
    A ball joint's ``qpos`` is a quaternion ``wxyz``, a free joint's ``x y z`` then one.
    """

    joint: str
    kind: Literal["revolute", "prismatic", "ball", "free"]
    adr: int
    lower: float = 0.0
    upper: float = 0.0


def controls(subject: Subject) -> list[Control]:
    """A control for each independent joint of the subject (mimic followers have none)."""
    if subject.tree is None:
        chain = subject.chain
        assert chain.limits is not None
        return [
            Control(name, kind, i, *_slider_range(kind, chain.limits[i]))
            for i, (name, kind) in enumerate(zip(chain.joint_names, chain.joint_types, strict=True))
        ]
    tree = subject.tree
    out = []
    for k, (name, kind) in enumerate(zip(tree.joint_names, tree.joint_types, strict=True)):
        if tree.mimics[k] is not None:
            continue
        rng = (
            _slider_range(kind, tree.joint_limits[k])
            if kind in ("revolute", "prismatic")
            else (0, 0)
        )
        out.append(Control(name, kind, int(tree.qpos_adr[k]), *rng))
    return out


def _slider_range(kind: str, limits: FloatArray) -> tuple[float, float]:
    default = _UNLIMITED_REVOLUTE if kind == "revolute" else _UNLIMITED_SLIDE
    lo = float(limits[0]) if np.isfinite(limits[0]) else default[0]
    hi = float(limits[1]) if np.isfinite(limits[1]) else default[1]
    return lo, hi


# --- one configuration ------------------------------------------------------------------------


def link_frames(chain: Chain, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The PoE partial products of ``chain`` at ``(n,)`` joint values ``q``.

    Returns:
        ``partial (n + 1, 4, 4)``: ``T_k = e^[S1]q1 ... e^[Sk]qk M`` (``chain.fk`` with the
        joints after ``k`` at 0), and ``links (n + 1, 4, 4)``: ``P_k = e^[S1]q1 ... e^[Sk]qk =
        T_k M^-1``, the pose of link ``k`` (the part that joint ``k`` moves) relative to its
        pose at ``q = 0``. Both in the chain's base frame.
    """
    n = chain.n_joints
    Q = np.tile(np.asarray(q, dtype=np.float64), (n + 1, 1))
    Q[np.arange(n)[None, :] >= np.arange(n + 1)[:, None]] = 0.0
    partial = chain.fk(Q)
    links = partial @ np.asarray(lie.inverse(chain.home), dtype=np.float64)
    links[:, 3] = [0.0, 0.0, 0.0, 1.0]
    return partial, links


def screw_kind(screw: FloatArray) -> ScrewKind:
    """``"prismatic"`` (``w = 0``), ``"pitched"`` (``w . v != 0``) or ``"revolute"``."""
    if not np.any(screw[:3]):
        return "prismatic"
    return "pitched" if abs(float(screw[:3] @ screw[3:])) > _PITCH_TOL else "revolute"


def _on_axis(screws: FloatArray, points: FloatArray) -> FloatArray:
    """Each point moved to the foot of its perpendicular on its screw's axis line (revolute and
    pitched screws: the line through ``w x v`` along ``w``); prismatic screws keep theirs."""
    out = np.array(points, dtype=np.float64)
    for i, S in enumerate(screws):
        w, v = S[:3], S[3:]
        if np.any(w):
            r0 = np.cross(w, v)
            out[i] = r0 + w * (w @ (points[i] - r0))
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything drawn at one configuration; poses are world poses ``(4, 4)``.

    Attributes:
        qpos: the configuration; q: the chain's joint values in it.
        base: ``T_world_base``, where the chain starts (identity for a fixed base).
        T: the end frame ``T(q)``; home: ``M`` placed on the base, ``T_world_base M``.
        bodies: ``(nb, 4, 4)`` each of :attr:`Subject.body_names`.
        frames: ``(nf, 4, 4)`` each of :attr:`Subject.frame_names`.
        screws: ``(n, 6)`` ``S_i(q)`` in world coordinates; body_screws: ``(n, 6)`` ``B_i(q)``
            in end-frame coordinates.
        points: ``(n, 3)`` a point on each joint's axis (its anchor); a slide joint's anchor.
        partial: ``(n + 1, 4, 4)`` ``T_k`` for ``k = 0..n``.
    """

    qpos: FloatArray
    q: FloatArray
    base: FloatArray
    T: FloatArray
    home: FloatArray
    bodies: FloatArray
    frames: FloatArray
    screws: FloatArray
    body_screws: FloatArray
    points: FloatArray
    partial: FloatArray


def joint_anchors(subject: Subject, bodies: FloatArray) -> FloatArray:
    """``(..., n, 3)`` each chain joint's anchor in the world, from the world poses ``(..., nb,
    4, 4)`` of :attr:`Subject.body_names`: a tree joint's anchor in its body, a bare chain's
    axis point at ``q = 0`` (:func:`~poekin.dh.joint_lines`) in its link."""
    chain = subject.chain
    if subject.tree is not None:
        tree = subject.tree
        joints = [tree.joint_names.index(j) for j in chain.joint_names]
        which = np.asarray(tree.joint_bodies, dtype=np.intp)[joints]
        local = np.asarray(tree.joint_anchors, dtype=np.float64)[joints]
    else:
        which = np.arange(chain.n_joints)  # joint i + 1 turns with link i
        local = joint_lines(chain)[1]
    T = bodies[..., which, :, :]
    out: FloatArray = np.einsum("...ij,...j->...i", T[..., :3, :3], local) + T[..., :3, 3]
    return out.reshape(*bodies.shape[:-3], chain.n_joints, 3)


def snapshot(subject: Subject, qpos: ArrayLike) -> Snapshot:
    """What to draw at ``qpos`` (``(nq,)``, MuJoCo's layout; a bare chain: its joint values).

    Raises:
        InputError: ``qpos`` is not ``nq`` finite numbers.
    """
    x = subject.check_qpos(qpos)
    chain, q = subject.chain, subject.chain_q(x)
    partial, links = link_frames(chain, q)
    S = chain.jacobian_space(q).T
    B = chain.jacobian_body(q).T
    if subject.tree is not None:
        frames = subject.tree.fk(x)
        bodies = frames[: len(subject.tree.body_names)]
        base = bodies[subject.base_body] if subject.base_body is not None else np.eye(4)
    else:
        base = np.eye(4)
        bodies = links
        frames = np.concatenate([links, partial[-1:]])
    anchors = joint_anchors(subject, bodies)
    screws = S @ np.asarray(lie.adjoint(base), dtype=np.float64).T
    return Snapshot(
        qpos=x,
        q=q,
        base=base,
        T=base @ partial[-1],
        home=base @ chain.home,
        bodies=bodies,
        frames=frames,
        screws=screws.reshape(-1, 6),
        body_screws=B.reshape(-1, 6),
        points=_on_axis(screws.reshape(-1, 6), anchors),
        partial=base @ partial,
    )


def jacobian(
    subject: Subject, qpos: ArrayLike, convention: JacobianConvention = "space"
) -> tuple[FloatArray, tuple[str, ...]]:
    """The end frame's Jacobian ``(6, n)`` in ``convention`` (``space``, ``body``, ``world``),
    rows ``[w; v]``, and its column names.

    A chain from the world: ``chain.jacobian_<convention>(q)``, one column per joint. Behind a
    ball or free joint: ``tree.jacobian(qpos, frame, convention)``, MuJoCo's ``qvel`` columns.
    """
    check_jacobian_convention(convention)
    x = subject.check_qpos(qpos)
    if subject.base_body is not None:
        assert subject.tree is not None
        return subject.tree.jacobian(x, subject.frame, convention), subject.tree.dof_names()
    J = getattr(subject.chain, f"jacobian_{convention}")(subject.chain_q(x))
    return np.asarray(J, dtype=np.float64), subject.chain.joint_names


def manipulability(J: FloatArray) -> tuple[FloatArray, float]:
    """Singular values of ``J (6, m)`` (largest first) and Yoshikawa's manipulability: their
    product, which is ``sqrt(det(J J^T))`` for ``m >= 6`` (``sqrt(det(J^T J))`` for ``m < 6``,
    the volume spanned in the ``m`` directions the arm can move in)."""
    sigma = np.asarray(np.linalg.svd(J, compute_uv=False), dtype=np.float64)
    return sigma, float(np.prod(sigma)) if sigma.size else 0.0


def dh_frames(subject: Subject, table: DHTable, qpos: ArrayLike) -> FloatArray:
    """``(n + 2, 4, 4)`` world poses of DH frames ``0..n`` at ``qpos``, then the end frame
    (frame ``n`` times the tool): ``base T_1(q_1) ... T_i(q_i)`` on the chain's base."""
    x = subject.check_qpos(qpos)
    links = table.link_transforms(subject.chain_q(x))
    base = snapshot_base(subject, x)
    out = np.empty((table.n_joints + 2, 4, 4))
    F = base @ table.base
    out[0] = F
    for i in range(table.n_joints):
        F = F @ links[i]
        out[i + 1] = F
    out[-1] = F @ table.tool
    return out


def snapshot_base(subject: Subject, qpos: FloatArray) -> FloatArray:
    """``T_world_base`` at ``qpos`` (identity for a chain from the world)."""
    if subject.base_body is None or subject.tree is None:
        return np.eye(4)
    return np.asarray(subject.tree.fk(qpos)[subject.base_body], dtype=np.float64)


# --- your parameters against the model ----------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Comparison:
    """A parameter set shown beside the model: :func:`poekin.diagnose`'s result.

    ``yours`` is the set as a chain, in its own base frame; ``diagnosis.aligned`` is the same
    moved by the base alignment into the model's base frame.
    """

    yours: Chain
    diagnosis: Diagnosis
    name: str

    def chain(self, aligned: bool) -> Chain:
        return self.diagnosis.aligned if aligned else self.yours


def compare(subject: Subject, params: Chain | DHTable, name: str = "") -> Comparison:
    """Diagnose ``params`` against the subject's chain (same joints, base to tip), placed on
    the subject's base with its tool (if it has them).

    Raises:
        InputError: a different number of joints.
    """
    yours = params.to_chain() if isinstance(params, DHTable) else params
    mine = subject.chain
    placed = yours  # your arm on the model's base, with its tool: the same cell
    if not np.array_equal(mine.base, np.eye(4)):
        placed = placed.with_base(mine.base)
    if subject.tool is not None:
        placed = placed.with_tool(subject.tool)
    d = diagnose(params if placed is yours else placed, mine)
    return Comparison(placed, d, name or yours.robot or "your parameters")


@dataclasses.dataclass(frozen=True, eq=False)
class Ghost:
    """Your parameters at the model's joint values, placed on the model's base.

    Attributes:
        links: ``(n + 1, 4, 4)`` world poses of your links (``base, link1 .. linkn``).
        T: your end frame; home: your ``M``.
        screws: ``(n, 6)`` your ``S_i(q)`` in world coordinates; points: a point on each axis.
        pos_err, ori_err: the distance (m) and angle (rad) from the model's end frame to yours.
    """

    links: FloatArray
    T: FloatArray
    home: FloatArray
    screws: FloatArray
    points: FloatArray
    pos_err: float
    ori_err: float


def ghost(comparison: Comparison, snap: Snapshot, *, aligned: bool) -> Ghost:
    """Your parameters (as given, or after the base alignment) at the model's ``snap.q``, on the
    model's base frame ``snap.base``, and the end-frame error against ``snap.T``."""
    chain = comparison.chain(aligned)
    partial, links = link_frames(chain, snap.q)
    screws = chain.jacobian_space(snap.q).T @ np.asarray(lie.adjoint(snap.base)).T
    _, points0 = joint_lines(chain)
    world_links = snap.base @ links
    anchors = np.array(
        [world_links[i] @ np.append(points0[i], 1.0) for i in range(chain.n_joints)]
    ).reshape(-1, 4)[:, :3]
    T = snap.base @ partial[-1]
    pos, ori = pose_errors(snap.T, T)
    return Ghost(
        links=world_links,
        T=T,
        home=snap.base @ chain.home,
        screws=screws.reshape(-1, 6),
        points=_on_axis(screws.reshape(-1, 6), anchors),
        pos_err=float(pos),
        ori_err=float(ori),
    )


# --- stand-in skeleton --------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Segment:
    """A link of the stand-in skeleton: from ``a`` to ``b`` (m), both in body ``body``'s frame."""

    body: int
    a: tuple[float, float, float]
    b: tuple[float, float, float]


def _segment(body: int, a: ArrayLike, b: ArrayLike) -> Segment | None:
    pa, pb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if np.linalg.norm(pb - pa) < _MIN_SEGMENT:
        return None
    return Segment(body, (float(pa[0]), float(pa[1]), float(pa[2])), tuple(map(float, pb)))  # type: ignore[arg-type]


def skeleton(
    subject: Subject, tips: Mapping[int, Sequence[ArrayLike]] | None = None
) -> list[Segment]:
    """The stand-in links: capsules between joint anchors, each fixed in one body.

    A tree's body goes from its first joint's anchor (its origin if it has no joint) to each
    child body's attachment (the child's first anchor, in this body's frame) and each of its
    sites; a body with neither goes to the farthest of its ``tips`` (e.g. its geoms' centres),
    if any. A bare chain's link ``i`` goes from joint ``i``'s axis point to joint ``i+1``'s (the
    first from its base's origin, the last one to ``M``'s origin), as
    :func:`~poekin.dh.joint_lines` places them at ``q = 0``. A tool is a capsule from the frame
    that carries it to the tool frame's origin.
    """
    out: list[Segment | None] = []
    if subject.tree is None:
        chain = subject.chain
        _, points = joint_lines(chain)
        stops = [chain.base[:3, 3], *points, chain.home[:3, 3]]
        out = [_segment(i, stops[i], stops[i + 1]) for i in range(len(stops) - 1)]
        return [s for s in out if s is not None]
    tree = subject.tree

    def anchor(b: int) -> FloatArray:
        joints = np.flatnonzero(tree.joint_bodies == b)
        return tree.joint_anchors[joints[0]] if joints.size else np.zeros(3)

    for b in range(len(tree.body_names)):
        a = anchor(b)
        targets = [
            tree.body_pos[c] + tree.body_rot[c] @ anchor(int(c))
            for c in np.flatnonzero(tree.body_parents == b)
        ]
        targets += [tree.site_pos[s] for s in np.flatnonzero(tree.site_bodies == b)]
        if not targets and tips and tips.get(b):
            far = max(
                (np.asarray(t, dtype=np.float64) for t in tips[b]),
                key=lambda t: float(np.linalg.norm(t - a)),
            )
            targets = [far]
        out += [_segment(b, a, t) for t in targets]
    if subject.tool is not None:  # the tool: from the frame that carries it to its origin
        f, nb = tree.frame_index(subject.frame), len(tree.body_names)
        b, R, p = (
            (f, np.eye(3), np.zeros(3))
            if f < nb
            else (int(tree.site_bodies[f - nb]), tree.site_rot[f - nb], tree.site_pos[f - nb])
        )
        out.append(_segment(b, p, p + R @ subject.tool[:3, 3]))
    return [s for s in out if s is not None]


# --- readouts -----------------------------------------------------------------------------------


def pose_summary(T: FloatArray) -> dict[str, tuple[float, ...]]:
    """``{"position": (x, y, z), "quat_wxyz": (w, x, y, z), "rpy": (roll, pitch, yaw)}`` of a
    pose, quaternion with ``w >= 0``."""
    quat = np.asarray(lie.rotation_to_quat(T[:3, :3]), dtype=np.float64)
    return {
        "position": tuple(float(x) for x in T[:3, 3]),
        "quat_wxyz": tuple(float(x) for x in quat),
        "rpy": tuple(float(x) for x in lie.rotation_to_rpy(T[:3, :3])),
    }


def format_matrix(M: ArrayLike, digits: int = 6) -> list[str]:
    """Rows of ``M`` with ``digits`` decimals, aligned, ``-0`` printed as ``0``."""
    A = np.atleast_2d(np.asarray(M, dtype=np.float64))
    width = digits + 4 + max(1, len(str(int(np.max(np.abs(A), initial=0.0)))))
    return [" ".join(f"{x + 0.0:{width}.{digits}f}" for x in row) for row in A]


def axis_pose(point: ArrayLike, direction: ArrayLike) -> FloatArray:
    """``(..., 4, 4)`` frames at ``point`` ``(..., 3)`` whose z axis is the unit ``direction``
    ``(..., 3)``, turned from the world by the smallest rotation that does it (how a screw axis
    is drawn)."""
    z = np.asarray(direction, dtype=np.float64)
    z = z / np.linalg.norm(z, axis=-1, keepdims=True)
    k = np.cross([0.0, 0.0, 1.0], z)
    s = np.linalg.norm(k, axis=-1, keepdims=True)
    turned = s[..., 0] >= 1e-12
    angle = np.arctan2(s, z[..., 2:3])
    axis = np.where(turned[..., None], k / np.where(s > 0, s, 1.0), [1.0, 0.0, 0.0])
    R = np.asarray(lie.exp_so3(axis * np.where(turned[..., None], angle, 0.0)), dtype=np.float64)
    # z = -e_z exactly: half a turn about x
    R = np.where((~turned & (z[..., 2] < 0))[..., None, None], np.diag([1.0, -1.0, -1.0]), R)
    T = np.zeros((*z.shape[:-1], 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = np.asarray(point, dtype=np.float64)
    T[..., 3, 3] = 1.0
    return T


def nearest_point(screw: FloatArray, point: FloatArray, reference: ArrayLike) -> FloatArray:
    """The point of a screw's axis line nearest ``reference`` (its foot): the end of the
    moment arm ``r`` in ``v = -w x r + h w``. A prismatic screw has no line: ``point``."""
    w = screw[:3]
    if not np.any(w):
        return np.asarray(point, dtype=np.float64)
    ref = np.asarray(reference, dtype=np.float64)
    return np.asarray(point + w * (w @ (ref - point)), dtype=np.float64)
