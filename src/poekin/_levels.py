"""A tree's poses level by level, isomorphic subtrees side by side as stacked arrays.

The reference path of :class:`poekin.tree.Tree` (the compiled kernel's specification, and what
JAX and PyTorch run). Sibling subtrees of the same shape (the go2's four legs, aloha's two
arms) are *lanes*; the bodies at one place of ``m`` lanes are a *group*, whose poses are
``(m, 3, 3, ...)`` rotations and ``(m, 3, ...)`` points, and each joint moves all ``m`` bodies
in a few array operations (the ``*_stacked`` formulas of :mod:`poekin._pose`). A group takes
the kernel's shortcuts (an identity rotation, a zero offset or anchor, a hinge about a
coordinate axis) where all its bodies allow them. Every entry is computed by the operations
:mod:`poekin._pose` would apply to it alone, in the same order, so the results are the
kernel's but for signs of zero. Lanes come first and the batch axes last, so that each
operation runs over contiguous memory.

Why: written entry by entry, a tree was one expression per output entry (~1,300 operations
for the go2). XLA on the CPU fused each output's whole chain into that output's loop and
computed the chain again there, so the forward pass cost more than forward plus backward,
and Inductor compiled the graph for minutes. By groups the go2 is four steps of a few dozen
operations, each body's pose is computed once, and both compile it in seconds.

The joint values are gathered once per kind, in group order, into one array each (every
hinge's angle, every slide's position, every ball's or free joint's quaternion), so that
sines, cosines and unit quaternions take one operation each and each group reads a
contiguous slice. Constants are nested tuples of Python floats until a call makes them arrays
of its library, dtype and device (so JAX and torch.compile see constants, not NumPy arrays).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from poekin import _pose, arrays, lie

__all__ = [
    "Block",
    "Constants",
    "Group",
    "Lib",
    "Plan",
    "Poses",
    "SiteGroup",
    "Step",
    "batch_last",
    "body_pose",
    "body_poses",
    "evaluate",
    "expand",
    "frames_array",
    "joint_axis_anchor",
    "plan",
    "take",
]

FloatArray = NDArray[np.float64]
Pairs = tuple[tuple[int, int], ...]  # (group, lane) of each body or site
Nested = tuple[Any, ...]  # constants: nested tuples of Python floats


class Constants(NamedTuple):
    """A tree's offsets, axes and anchors as arrays of one library, leading axes allowed: the
    fields of :class:`poekin.tree.TreeParams`."""

    body_pos: Any  # (..., nb, 3)
    body_rot: Any  # (..., nb, 3, 3)
    joint_axes: Any  # (..., nj, 3)
    joint_anchors: Any  # (..., nj, 3)
    site_pos: Any  # (..., ns, 3)
    site_rot: Any  # (..., ns, 3, 3)


class Step(NamedTuple):
    """The ``n``-th joint of every body of a group, all of one kind."""

    kind: str  # "revolute", "prismatic", "ball" or "free"
    joints: tuple[int, ...]
    start: int  # the first of this step's values among its kind's (quaternions: ball, free)
    position_start: int  # a free joint's first value among the free joints' positions
    along: int | None  # every hinge turns about coordinate axis ``along`` (model constants)
    signs: Nested | None  # (m,) the hinges' directions along it; None: all +1
    zero_anchor: bool  # every anchor is exactly zero (model constants)
    axis: Nested  # (m, 3)
    anchor: Nested  # (m, 3)
    W: Nested  # (m, 3, 3) [axis]
    W2: Nested  # (m, 3, 3) [axis]^2


class Group(NamedTuple):
    """The bodies at one place of ``m`` isomorphic subtrees (their *lanes*), lane by lane."""

    bodies: tuple[int, ...]
    parent: int  # the group of their parents (-1: the world), each parent ``repeat`` times
    repeat: int
    fixed: str  # the offset: "none" (identity, zero), "translate" (identity) or "general"
    rot: Nested  # (m, 3, 3)
    pos: Nested  # (m, 3)
    steps: tuple[Step, ...]


class SiteGroup(NamedTuple):
    """Sites at one place of a group's lanes (one per body), or every site on the world."""

    sites: tuple[int, ...]
    parent: int  # body group, or -1: the world
    fixed: str
    rot: Nested
    pos: Nested


class Block(NamedTuple):
    """``k`` isomorphic sibling subtrees: in each lane of the enclosing block, ``k`` lanes,
    whose frames come out one lane after another. ``items``: group indices (one frame per
    lane) and blocks, in depth-first order."""

    k: int
    items: tuple[Any, ...]  # int | Block


class Plan(NamedTuple):
    """How to evaluate a tree, from its structure and constants: built once per tree."""

    expand: tuple[tuple[int, ...], Nested, Nested] | None  # qpos -> expanded slots
    hinges: tuple[int, ...]  # each hinge's slot in the expanded qpos, in group order
    hinge_refs: Nested | None
    slides: tuple[int, ...]
    slide_refs: Nested | None
    quats: tuple[int, ...]  # a ball's or free joint's first quaternion slot
    frees: tuple[int, ...]  # a free joint's first position slot
    groups: tuple[Group, ...]
    sites: tuple[SiteGroup, ...]
    blocks: tuple[Block, ...]  # the world's subtrees
    group_sites: tuple[tuple[int, ...], ...]  # each group's site groups
    world_sites: int | None  # the site group on the world
    body_order: tuple[int, ...] | None  # where each body comes out, unless in order
    site_order: tuple[int, ...] | None
    bodies: Pairs  # each body's (group, lane)
    site_lanes: Pairs  # each site's (site group, lane)
    joints: tuple[tuple[int, int, int], ...]  # each joint's (group, step, lane)


class Poses(NamedTuple):
    """Every group's stacked poses, and with ``joints``, every step's world axes and anchors
    before it moves (MuJoCo's ``xaxis``, ``xanchor``), ``(m, 3, ...)`` each. The lane axis has
    length 1 where every lane shares a value (it broadcasts), the batch axes length 1 where a
    value is the same for every configuration."""

    rotations: tuple[Any, ...]  # (m or 1, 3, 3, ...) per group
    points: tuple[Any, ...]  # (m or 1, 3, ...)
    site_rotations: tuple[Any, ...]  # per site group
    site_points: tuple[Any, ...]
    axes: tuple[tuple[Any, ...], ...]  # per group, per step
    anchors: tuple[tuple[Any, ...], ...]


def _nested(a: Any) -> Nested:
    return tuple(_nested(e) for e in a) if np.ndim(a) else float(a)  # type: ignore[return-value]


_CLASSES = ("none", "translate", "general")


def _fixed(R: FloatArray, t: FloatArray) -> str:
    """The offset's shortcut class (the most general of several)."""
    if R.ndim == 3:
        return max((_fixed(r, v) for r, v in zip(R, t, strict=True)), key=_CLASSES.index)
    if not np.array_equal(R, np.eye(3)):
        return "general"
    return "translate" if np.any(t) else "none"


def _refs(values: list[float]) -> Nested | None:
    return tuple(values) if any(values) else None


def _isomorphic_runs(bodies: Sequence[int], shape: Callable[[int], Any]) -> list[list[int]]:
    """``bodies`` cut into runs of consecutive ones with isomorphic subtrees."""
    runs: list[list[int]] = []
    for b in bodies:
        if runs and shape(runs[-1][0]) == shape(b):
            runs[-1].append(b)
        else:
            runs.append([b])
    return runs


def _order(
    items: Sequence[Any], m: int, leaf: Callable[[int], list[Sequence[int]]]
) -> list[list[int]]:
    """The frames ``items`` put out for each of ``m`` lanes (:func:`_assemble`'s order), from
    ``leaf(group)``: the frame of each lane, per place."""
    rows: list[list[int]] = [[] for _ in range(m)]
    for item in items:
        if isinstance(item, Block):
            inner = _order(item.items, m * item.k, leaf)
            for j in range(m):
                for i in range(item.k):
                    rows[j].extend(inner[j * item.k + i])
        else:
            for ids in leaf(item):
                for j in range(m):
                    rows[j].append(ids[j])
    return rows


def plan(
    body_parents: Sequence[int],
    body_joints: Sequence[Sequence[int]],
    joint_types: Sequence[str],
    joint_slots: Sequence[int],
    joint_refs: Sequence[float],
    site_bodies: Sequence[int],
    expansion: tuple[Sequence[int], Sequence[float], Sequence[float]],
    constants: Constants,
) -> Plan:
    """The plan of a tree: isomorphic sibling subtrees as lanes, their bodies grouped by place,
    and where each kind of joint finds its values.

    Subtrees are isomorphic when their bodies' joints have the same kinds (and hinges the same
    coordinate axis, if any), their bodies the same number of sites and their children are
    isomorphic in order; offsets and anchors may differ (a group then takes the shortcut all
    its bodies allow). ``joint_slots[k]`` is where joint ``k``'s numbers start in the expanded
    qpos, whose entry ``j`` is ``qpos[sources[j]] * scale[j] + offset[j]``
    (``expansion = (sources, scale, offset)``); ``constants`` (NumPy float64) are the model's.
    """
    nb = len(body_parents)
    children: list[list[int]] = [[] for _ in range(nb)]
    roots: list[int] = []
    for b, parent in enumerate(body_parents):
        (children[parent] if parent >= 0 else roots).append(b)
    sites_of: list[list[int]] = [[] for _ in range(nb)]
    on_world: list[int] = []
    for s, b in enumerate(site_bodies):
        (sites_of[b] if b >= 0 else on_world).append(s)

    def along(k: int) -> int | None:
        axis = lie.coordinate_axis(constants.joint_axes[k])
        return axis[0] if axis is not None and joint_types[k] == "revolute" else None

    shapes: dict[int, Any] = {}

    def shape(b: int) -> Any:
        if b not in shapes:
            joints = tuple((joint_types[k], along(k)) for k in body_joints[b])
            shapes[b] = (joints, len(sites_of[b]), tuple(shape(c) for c in children[b]))
        return shapes[b]

    slots: dict[str, list[int]] = {"revolute": [], "prismatic": [], "quat": [], "free": []}
    refs: dict[str, list[float]] = {"revolute": [], "prismatic": []}
    groups: list[Group] = []
    site_groups: list[SiteGroup] = []
    group_sites: list[tuple[int, ...]] = []
    body_at: dict[int, tuple[int, int]] = {}
    joint_at: dict[int, tuple[int, int, int]] = {}

    def steps(g: int, bodies: list[int]) -> tuple[Step, ...]:
        out = []
        for n in range(len(body_joints[bodies[0]])):
            joints = [body_joints[b][n] for b in bodies]
            kind, turn = joint_types[joints[0]], along(joints[0])
            values = kind if kind in refs else "quat"
            start, position_start = len(slots[values]), len(slots["free"])
            for j, k in enumerate(joints):
                slots[values].append(joint_slots[k] + (3 if kind == "free" else 0))
                if kind == "free":
                    slots["free"].append(joint_slots[k])
                if kind in refs:
                    refs[kind].append(float(joint_refs[k]))
                joint_at[k] = (g, n, j)
            W = [_pose.hat(_nested(constants.joint_axes[k])) for k in joints]
            signs = [float(np.sign(constants.joint_axes[k]).sum()) for k in joints]
            out.append(
                Step(
                    kind=kind,
                    joints=tuple(joints),
                    start=start,
                    position_start=position_start,
                    along=turn,
                    signs=None if turn is None or set(signs) == {1.0} else tuple(signs),
                    zero_anchor=not np.any(constants.joint_anchors[joints]),
                    axis=_nested(constants.joint_axes[joints]),
                    anchor=_nested(constants.joint_anchors[joints]),
                    W=tuple(W),
                    W2=tuple(_pose.mat_mat(w, w) for w in W),
                )
            )
        return tuple(out)

    def add(bodies: list[int], parent: int, repeat: int) -> tuple[Any, ...]:
        """Groups for the lanes ``bodies`` (their subtrees isomorphic), depth first."""
        g = len(groups)
        for j, b in enumerate(bodies):
            body_at[b] = (g, j)
        groups.append(
            Group(
                bodies=tuple(bodies),
                parent=parent,
                repeat=repeat,
                fixed=_fixed(constants.body_rot[bodies], constants.body_pos[bodies]),
                rot=_nested(constants.body_rot[bodies]),
                pos=_nested(constants.body_pos[bodies]),
                steps=steps(g, bodies),
            )
        )
        placed = []
        for t in range(len(sites_of[bodies[0]])):
            ss = [sites_of[b][t] for b in bodies]
            placed.append(len(site_groups))
            site_groups.append(
                SiteGroup(
                    sites=tuple(ss),
                    parent=g,
                    fixed=_fixed(constants.site_rot[ss], constants.site_pos[ss]),
                    rot=_nested(constants.site_rot[ss]),
                    pos=_nested(constants.site_pos[ss]),
                )
            )
        group_sites.append(tuple(placed))
        items: list[Any] = [g]
        c = 0
        for run in _isomorphic_runs(children[bodies[0]], shape):
            k = len(run)
            inner = add([children[b][c + i] for b in bodies for i in range(k)], g, k)
            if k == 1:  # the same lanes: their frames in line with these
                items.extend(inner)
            else:
                items.append(Block(k, inner))
            c += k
        return tuple(items)

    blocks = tuple(Block(len(run), add(run, -1, 1)) for run in _isomorphic_runs(roots, shape))
    world_sites = None
    if on_world:
        world_sites = len(site_groups)
        site_groups.append(
            SiteGroup(
                sites=tuple(on_world),
                parent=-1,
                fixed=_fixed(constants.site_rot[on_world], constants.site_pos[on_world]),
                rot=_nested(constants.site_rot[on_world]),
                pos=_nested(constants.site_pos[on_world]),
            )
        )
    body_rows = _order(blocks, 1, lambda g: [groups[g].bodies])
    site_rows = _order(blocks, 1, lambda g: [site_groups[s].sites for s in group_sites[g]])
    body_seq = body_rows[0]
    site_seq = site_rows[0] + list(on_world)
    sources, scale, offset = (tuple(v) for v in expansion)
    identity = (
        sources == tuple(range(len(sources))) and set(scale) <= {1.0} and set(offset) <= {0.0}
    )
    return Plan(
        expand=None if identity else (tuple(map(int, sources)), _nested(scale), _nested(offset)),
        hinges=tuple(slots["revolute"]),
        hinge_refs=_refs(refs["revolute"]),
        slides=tuple(slots["prismatic"]),
        slide_refs=_refs(refs["prismatic"]),
        quats=tuple(slots["quat"]),
        frees=tuple(slots["free"]),
        groups=tuple(groups),
        sites=tuple(site_groups),
        blocks=blocks,
        group_sites=tuple(group_sites),
        world_sites=world_sites,
        body_order=None
        if body_seq == list(range(nb))
        else tuple(body_seq.index(b) for b in range(nb)),
        site_order=None
        if site_seq == list(range(len(site_bodies)))
        else tuple(site_seq.index(s) for s in range(len(site_bodies))),
        bodies=tuple(body_at[b] for b in range(nb)),
        site_lanes=tuple(
            next(
                (g, j) for g, sg in enumerate(site_groups) for j, t in enumerate(sg.sites) if t == s
            )
            for s in range(len(site_bodies))
        ),
        joints=tuple(joint_at[k] for k in range(len(joint_types))),
    )


# --- gathers by constant indices -------------------------------------------------------------


def _runs(indices: Sequence[int]) -> list[tuple[int, int, int]]:
    """``indices`` as slices ``(start, stop, step)``: maximal runs of one positive step."""
    runs: list[tuple[int, int, int]] = []
    i = 0
    while i < len(indices):
        j = i + 1
        step = indices[j] - indices[i] if j < len(indices) else 1
        if step > 0:
            while j < len(indices) and indices[j] - indices[j - 1] == step:
                j += 1
        else:
            step = 1
        runs.append((indices[i], indices[j - 1] + 1, step))
        i = j
    return runs


def take(a: Any, indices: Sequence[int], xp: Any) -> Any:
    """``a``'s entries ``indices`` along its first axis, as slices joined by one concat: a
    gather by constant indices that every library traces and differentiates cheaply (JAX turns
    the derivative of a gather into a scatter, which XLA constant-folds for minutes when the
    cotangent is a constant)."""
    if list(indices) == list(range(a.shape[0])):
        return a
    parts = [a[slice(*run)] for run in _runs(indices)]
    return parts[0] if len(parts) == 1 else xp.concat(parts, axis=0)


def broadcast_shape(*shapes: Sequence[Any]) -> tuple[Any, ...]:
    """The shape ``shapes`` broadcast to (in plain Python, so that symbolic sizes pass)."""
    n = 0
    for s in shapes:
        n = max(n, len(s))
    out = []
    for i in range(n):
        size: Any = 1
        for s in shapes:
            k = i - n + len(s)
            if k >= 0 and s[k] != 1:
                size = s[k]
        out.append(size)
    return tuple(out)


def _at_len(lanes: Sequence[Any], j: int) -> int:
    """Lane ``j`` of a sequence of lanes: 0 where there is one for all."""
    return j if len(lanes) > 1 else 0


def _at(a: Any, j: int) -> int:
    """Lane ``j`` of ``a``: 0 where ``a`` has one lane for all (it broadcasts)."""
    return j if a.shape[0] > 1 else 0


def _repeat(a: Any, k: int, xp: Any) -> Any:
    """Each of ``a``'s lanes (its first axis) ``k`` times in a row."""
    m = a.shape[0]
    if k == 1 or m == 1:
        return a
    rest = tuple(a.shape[1:])
    return xp.reshape(xp.broadcast_to(a[:, None], (m, k, *rest)), (m * k, *rest))


class Lib(NamedTuple):
    """An array library as a call uses it: its namespace, an array of the result's dtype and
    device to make constants like, and the number of batch axes, which come last."""

    xp: Any
    like: Any
    batch: int

    def const(self, values: Nested) -> Any:
        """Model constants as an array, with a length-1 axis for each batch axis."""
        if arrays.kind_of(self.like) == "torch":
            a = self.xp.asarray(values, dtype=self.like.dtype, device=self.like.device)
        else:
            a = self.xp.asarray(values, dtype=self.like.dtype)
        return self.xp.reshape(a, (*a.shape, *(1,) * self.batch)) if self.batch else a


def batch_last(a: Any, trailing: int, batch: int, xp: Any) -> Any:
    """``a (*B, *T)`` with ``trailing`` axes ``T`` as ``(*T, 1, ..., 1, *B)``: ``batch``
    batch axes, last (as :func:`evaluate` takes its arrays)."""
    nb = a.ndim - trailing
    a = xp.permute_dims(a, (*range(nb, a.ndim), *range(nb)))
    if nb == batch:
        return a
    return xp.reshape(a, (*a.shape[:trailing], *(1,) * (batch - nb), *a.shape[trailing:]))


def expand(plan: Plan, x: Any, lib: Lib) -> Any:
    """The expanded joint values ``(nq_full, ...)`` of ``x (nq, ...)``: each joint's own
    numbers, a mimic follower's ``multiplier * leader + offset`` (``x`` itself for trees
    without followers)."""
    if plan.expand is None:
        return x
    slots, scale, offset = plan.expand
    x = take(x, slots, lib.xp)
    if set(scale) != {1.0}:
        x = x * lib.const(scale)
    if any(offset):
        x = x + lib.const(offset)
    return x


def _joint_values(plan: Plan, x: Any, lib: Lib) -> dict[str, Any]:
    """Each kind's values in group order, computed once: the hinges' sines and cosines, the
    slides' positions, the unit quaternions (normalised as MuJoCo does, entries ``w x y z``)
    and the free joints' positions; ``(n, ...)`` each."""
    xp = lib.xp
    out: dict[str, Any] = {}
    if plan.hinges:
        th = take(x, plan.hinges, xp)
        if plan.hinge_refs is not None:
            th = th - lib.const(plan.hinge_refs)
        (out["sin"],), (out["cos"],) = _pose.sincos([th], xp)
    if plan.slides:
        out["slide"] = take(x, plan.slides, xp)
        if plan.slide_refs is not None:
            out["slide"] = out["slide"] - lib.const(plan.slide_refs)
    if plan.quats:
        quat = [take(x, [a + i for a in plan.quats], xp) for i in range(4)]
        out["quat"] = _pose.settle(list(_pose.quat_normalize(quat, xp)), xp)
    if plan.frees:
        out["free"] = [take(x, [a + i for a in plan.frees], xp) for i in range(3)]
    return out


def _fixed_offset(R: Any, p: Any, fixed: str, rot: Any, pos: Any, xp: Any) -> tuple[Any, Any]:
    """:func:`poekin._pose.compose_const`: the offset ``(rot, pos)`` after the poses ``(R, p)``."""
    if fixed == "general":
        return _pose.compose_stacked(R, p, rot, pos, xp)
    if fixed == "translate":
        return R, p + _pose.mat_vec_stacked(R, pos, xp)
    return R, p


def _joint(
    R: Any, p: Any, step: Step, values: dict[str, Any], lib: Lib, c: Any, general: bool
) -> tuple[Any, Any]:
    """The poses ``(R, p)`` moved by ``step``'s joints (the kernel's HINGE, AXIS, SLIDE, BALL
    and FREE operations); ``c``: the step's constants (axis, anchor, W, W2) in the call's
    library; ``general``: no shortcut (parameters)."""
    xp = lib.xp
    m = len(step.joints)
    at = slice(step.start, step.start + m)
    if step.kind == "free":
        unit = [q[at] for q in values["quat"]]
        where = slice(step.position_start, step.position_start + m)
        return _pose.stack_mat(_pose.quat_matrix(unit), xp), xp.stack(
            [v[where] for v in values["free"]], axis=1
        )
    if step.kind == "prismatic":
        return R, p + c["axis_world"] * values["slide"][at][:, None]
    anchor = None if step.zero_anchor and not general else c["anchor"]
    if step.kind == "ball":
        R_j = _pose.stack_mat(_pose.quat_matrix([q[at] for q in values["quat"]]), xp)
    else:
        s, co = values["sin"][at], values["cos"][at]
        if step.along is not None and not general:
            if step.signs is not None:
                s = s * lib.const(step.signs)
            return _pose.axis_turn_stacked(R, p, step.along, s, co, anchor, xp)
        eye = lib.const((_pose.IDENTITY,))
        R_j = _pose.rodrigues_stacked(c["W"], c["W2"], s, 1.0 - co, eye)
    if anchor is None:  # the turn about the origin: no translation (but signs of zero)
        return _pose.mat_mat_stacked(R, R_j, xp), p
    return _pose.compose_stacked(R, p, R_j, _pose.about_point_stacked(R_j, anchor, xp), xp)


def _placed(
    parent: tuple[Any, Any] | None, group: Group | SiteGroup, lib: Lib, params: Constants | None
) -> tuple[Any, Any]:
    """The poses of a group's bodies or sites at their fixed offsets from their parents' poses
    ``parent`` (None: the world's, the identity): the model's offsets with their shortcut, or
    those of ``params`` (no shortcut)."""
    xp = lib.xp
    if params is None:
        rot, pos, fixed = lib.const(group.rot), lib.const(group.pos), group.fixed
    elif isinstance(group, SiteGroup):
        rot, pos = take(params.site_rot, group.sites, xp), take(params.site_pos, group.sites, xp)
        fixed = "general"
    else:
        rot, pos = take(params.body_rot, group.bodies, xp), take(params.body_pos, group.bodies, xp)
        fixed = "general"
    if parent is None:
        return rot, pos  # the world's pose, then the offset (compose_const)
    return _fixed_offset(*parent, fixed, rot, pos, xp)


def _step_constants(step: Step, lib: Lib, params: Constants | None) -> dict[str, Any]:
    """A step's axis and anchor (and for general hinges ``W``, ``W2``) in the call's library:
    the model's, or gathered from ``params`` (``W`` then built from the axes)."""
    xp = lib.xp
    if params is None:
        c = {"axis": lib.const(step.axis), "anchor": lib.const(step.anchor)}
        if step.kind == "revolute" and step.along is None:
            c["W"], c["W2"] = lib.const(step.W), lib.const(step.W2)
        return c
    axis = take(params.joint_axes, step.joints, xp)
    c = {"axis": axis, "anchor": take(params.joint_anchors, step.joints, xp)}
    if step.kind == "revolute":
        W = _pose.stack_mat(_pose.hat((axis[:, 0], axis[:, 1], axis[:, 2])), xp)
        c["W"], c["W2"] = W, _pose.mat_mat_stacked(W, W, xp)
    return c


def evaluate(
    plan: Plan, x: Any, lib: Lib, params: Constants | None, *, joints: bool = False
) -> Poses:
    """Every body's and site's world pose from the expanded joint values ``x (nq_full, ...)``
    (:func:`expand`), and with ``joints`` every joint's world axis and anchor before it moves.
    Arrays hold lanes first and batch axes last: rotations ``(m, 3, 3, ...)``, points
    ``(m, 3, ...)``.

    ``params``: offsets, axes and anchors to use (arrays of the call's library, as
    :func:`batch_last` makes them, no shortcuts, so that derivatives with respect to them are
    right), or None for the model's own (with the kernel's shortcuts).
    """
    xp = lib.xp
    general = params is not None
    values = _joint_values(plan, x, lib)
    Rs: list[Any] = []
    ps: list[Any] = []
    axes: list[tuple[Any, ...]] = []
    anchors: list[tuple[Any, ...]] = []
    for group in plan.groups:
        parent = None
        if group.parent >= 0:
            parent = (
                _repeat(Rs[group.parent], group.repeat, xp),
                _repeat(ps[group.parent], group.repeat, xp),
            )
        R, p = _placed(parent, group, lib, params)
        step_axes, step_anchors = [], []
        for step in group.steps:
            c = _step_constants(step, lib, params)
            if step.kind == "prismatic" or joints:
                c["axis_world"] = _pose.mat_vec_stacked(R, c["axis"], xp)
            if joints:
                step_axes.append(c["axis_world"])
                step_anchors.append(p + _pose.mat_vec_stacked(R, c["anchor"], xp))
            R, p = _joint(R, p, step, values, lib, c, general)
        Rs.append(R)
        ps.append(p)
        axes.append(tuple(step_axes))
        anchors.append(tuple(step_anchors))
    site_Rs, site_ps = [], []
    for sites in plan.sites:
        parent = None if sites.parent < 0 else (Rs[sites.parent], ps[sites.parent])
        R, p = _placed(parent, sites, lib, params)
        site_Rs.append(R)
        site_ps.append(p)
    return Poses(tuple(Rs), tuple(ps), tuple(site_Rs), tuple(site_ps), tuple(axes), tuple(anchors))


# --- reading the results ----------------------------------------------------------------------


def _mat(R: Any) -> _pose.Mat:
    """The entries ``(m, ...)`` of rotations ``R (m, 3, 3, ...)``."""
    return tuple(tuple(R[:, r, c] for c in range(3)) for r in range(3))  # type: ignore[return-value]


def _pose_of(R: Any, p: Any, j: int) -> _pose.Pose:
    jr, jp = _at(R, j), _at(p, j)
    return (
        tuple(tuple(R[jr, r, c] for c in range(3)) for r in range(3)),  # type: ignore[return-value]
        (p[jp, 0], p[jp, 1], p[jp, 2]),
    )


def body_pose(poses: Poses, plan: Plan, b: int) -> _pose.Pose:
    """Body ``b``'s world pose as entries (arrays of the batch axes)."""
    g, j = plan.bodies[b]
    return _pose_of(poses.rotations[g], poses.points[g], j)


def joint_axis_anchor(poses: Poses, plan: Plan, k: int) -> tuple[_pose.Vec, _pose.Vec]:
    """Joint ``k``'s world axis and anchor before it moves, as entries (from ``joints=True``)."""
    g, n, j = plan.joints[k]
    axis, anchor = poses.axes[g][n], poses.anchors[g][n]
    ja, jb = _at(axis, j), _at(anchor, j)
    return (axis[ja, 0], axis[ja, 1], axis[ja, 2]), (anchor[jb, 0], anchor[jb, 1], anchor[jb, 2])


def _join(parts: list[Any], xp: Any) -> Any:
    """``parts (m, n_i, ...)`` joined along their second axis. XLA fuses a concatenation of up
    to eight operands into the loop that computes them, but copies each of more than eight
    into place; more are therefore each padded to the whole length and added (exact: every
    entry but one added is a zero, which changes at most a zero's sign), which XLA fuses
    whatever their number."""
    if len(parts) <= 8:
        return parts[0] if len(parts) == 1 else xp.concat(parts, axis=1)
    total = sum(int(a.shape[1]) for a in parts)
    out, start = None, 0
    for a in parts:
        n = int(a.shape[1])
        pad = [(0, 0), (start, total - start - n), *((0, 0),) * (a.ndim - 2)]
        padded = xp.pad(a, pad)
        out = padded if out is None else out + padded
        start += n
    return out


def _assemble(items: Sequence[Any], m: int, leaf: Callable[[int], list[Any]], xp: Any) -> Any:
    """The frames of ``items`` for each of ``m`` lanes, ``(m, n, *form, ...)`` (None if none),
    in :func:`_order`'s order: a group's ``leaf`` poses ``(m, *form, ...)`` (one frame per
    lane each); a block's ``k`` lanes per lane one after another (a reshape)."""
    parts = []
    for item in items:
        if isinstance(item, Block):
            inner = _assemble(item.items, m * item.k, leaf, xp)
            if inner is not None:
                parts.append(xp.reshape(inner, (m, -1, *inner.shape[2:])))
        else:
            parts.extend(T[:, None] for T in leaf(item))
    return _join(parts, xp) if parts else None


def _form(R: Any, p: Any, form: str, m: int, batch: tuple[Any, ...], lib: Lib) -> Any:
    """Poses ``(R, p)`` of ``m`` lanes in ``form``: ``(m, 4, 4, *batch)``,
    ``(m, 3, 4, *batch)`` or ``(m, 7, *batch)``."""
    xp = lib.xp
    R = xp.broadcast_to(R, (m, 3, 3, *batch))
    p = xp.broadcast_to(p, (m, 3, *batch))
    if form == "pos_quat":
        return xp.concat([p, xp.stack(_pose.rotation_quat(_mat(R), xp), axis=1)], axis=1)
    top = xp.concat([R, p[:, :, None]], axis=2)
    if form == "3x4":
        return top
    bottom = xp.broadcast_to(lib.const((((0.0, 0.0, 0.0, 1.0),),)), (m, 1, 4, *batch))
    return xp.concat([top, bottom], axis=1)


def _frames_batch_last(poses: Poses, plan: Plan, form: str, lib: Lib) -> Any:
    """Every frame's pose (bodies, then sites), ``(n_frames, 4, 4, ...)``,
    ``(n_frames, 3, 4, ...)`` or ``(n_frames, 7, ...)``, the batch axes last: whole groups put
    in ``form``, a block's lanes one after another by a reshape, so that the frames of a tree
    whose bodies are in depth-first order (MuJoCo's) are a few concatenations of whole groups,
    which XLA fuses into the loops that compute them (one frame at a time, joining them cost
    JAX more than computing them)."""
    xp = lib.xp
    batch = _batch(poses, lib)
    groups = [
        _form(R, p, form, len(g.bodies), batch, lib)
        for R, p, g in zip(poses.rotations, poses.points, plan.groups, strict=True)
    ]
    sites = [
        _form(R, p, form, len(s.sites), batch, lib)
        for R, p, s in zip(poses.site_rotations, poses.site_points, plan.sites, strict=True)
    ]
    parts = []
    bodies = _assemble(plan.blocks, 1, lambda g: [groups[g]], xp)
    if bodies is not None:
        parts.append(bodies[0] if plan.body_order is None else take(bodies[0], plan.body_order, xp))
    on_bodies = _assemble(plan.blocks, 1, lambda g: [sites[s] for s in plan.group_sites[g]], xp)
    site_parts = [] if on_bodies is None else [on_bodies[0]]
    if plan.world_sites is not None:
        site_parts.append(sites[plan.world_sites])
    if site_parts:
        on_sites = _join([a[None] for a in site_parts], xp)[0]
        parts.append(on_sites if plan.site_order is None else take(on_sites, plan.site_order, xp))
    return _join([a[None] for a in parts], xp)[0]


def _batch(poses: Poses, lib: Lib) -> tuple[Any, ...]:
    """The batch shape of the results: ``lib.like``'s and the parameters' broadcast."""
    return broadcast_shape(
        tuple(lib.like.shape),
        *(tuple(R.shape[3:]) for R in (*poses.rotations, *poses.site_rotations)),
        *(tuple(p.shape[2:]) for p in (*poses.points, *poses.site_points)),
    )


def _is_jax(xp: Any) -> bool:
    return getattr(xp, "__name__", "") == "jax.numpy"


def frame_pose(poses: Poses, plan: Plan, f: int, lib: Lib) -> _pose.Pose:
    """Frame ``f``'s (a body's, then a site's) world pose as entries (arrays of the batch
    axes). Under JAX from the frames as :func:`frames_array` joins them: so XLA gives each
    configuration the same bits wherever it sits in a batch (reading a group's arrays, it
    contracted later multiply-adds into FMAs differently at different batch positions, and a
    ``shard_map``'s result was not one device's)."""
    if _is_jax(lib.xp):
        T = _frames_batch_last(poses, plan, "3x4", lib)[f]
        R = tuple(tuple(T[r, c] for c in range(3)) for r in range(3))
        return R, (T[0, 3], T[1, 3], T[2, 3])  # type: ignore[return-value]
    nb = len(plan.bodies)
    if f < nb:
        return body_pose(poses, plan, f)
    g, j = plan.site_lanes[f - nb]
    return _pose_of(poses.site_rotations[g], poses.site_points[g], j)


def body_poses(poses: Poses, plan: Plan, lib: Lib) -> list[_pose.Pose]:
    """Every body's world pose as entries: :func:`frame_pose` of each, the frames joined once
    under JAX rather than once per body."""
    if not _is_jax(lib.xp):
        return [body_pose(poses, plan, b) for b in range(len(plan.bodies))]
    T = _frames_batch_last(poses, plan, "3x4", lib)
    return [
        (
            tuple(tuple(T[b, r, c] for c in range(3)) for r in range(3)),  # type: ignore[misc]
            (T[b, 0, 3], T[b, 1, 3], T[b, 2, 3]),
        )
        for b in range(len(plan.bodies))
    ]


def frames_array(poses: Poses, plan: Plan, form: str, lib: Lib) -> Any:
    """Every frame's pose (bodies, then sites), ``(..., n_frames, 4, 4)``,
    ``(..., n_frames, 3, 4)`` or ``(..., n_frames, 7)``: the batch axes (those of
    ``lib.like`` and of the parameters) first again, C-contiguous.

    Moving the batch axes first is a transposition. Under JAX, XLA fuses it with whole
    groups joined (:func:`_frames_batch_last`); NumPy and PyTorch copy slowly along short
    axes, so there every entry of every frame (an array of the batch) goes into its place in
    one stack, as the entry-by-entry path always did."""
    xp = lib.xp
    if _is_jax(xp):
        frames = _frames_batch_last(poses, plan, form, lib)
        trailing = 2 if form == "pos_quat" else 3  # the batch axes back in front
        return xp.permute_dims(frames, (*range(trailing, frames.ndim), *range(trailing)))
    batch = _batch(poses, lib)
    sources = [
        *zip(poses.rotations, poses.points, strict=True),
        *zip(poses.site_rotations, poses.site_points, strict=True),
    ]
    quats = [_pose.rotation_quat(_mat(R), xp) for R, _ in sources] if form == "pos_quat" else []
    ng = len(plan.groups)
    at = [*plan.bodies, *((ng + g, j) for g, j in plan.site_lanes)]
    # each group's entries lane by lane, by unstacking (PyTorch differentiates an entry taken
    # by indexing by zeroing its whole array)
    lanes = [
        (
            [
                [_pose.unstack(row, 0, xp) for row in _pose.unstack(lane, 0, xp)]
                for lane in _pose.unstack(R, 0, xp)
            ],
            [_pose.unstack(lane, 0, xp) for lane in _pose.unstack(p, 0, xp)],
            [_pose.unstack(e, 0, xp) for e in quats[g]] if quats else [],
        )
        for g, (R, p) in enumerate(sources)
    ]
    like = (
        lib.like
        if tuple(lib.like.shape) == batch
        else xp.zeros_like(xp.broadcast_to(lib.like, batch))
    )
    zero, one = xp.full_like(like, 0.0), xp.full_like(like, 1.0)
    bottom = [zero, zero, zero, one]
    entries: list[Any] = []
    for g, j in at:
        R_lanes, p_lanes, q_lanes = lanes[g]
        R, p = R_lanes[_at_len(R_lanes, j)], p_lanes[_at_len(p_lanes, j)]
        if form == "pos_quat":
            entries.extend([*p, *(q[_at_len(q, j)] for q in q_lanes)])
            continue
        for r in range(3):
            entries.extend([*R[r], p[r]])
        if form == "4x4":
            entries.extend(bottom)
    # every entry a dense array of the batch: PyTorch stacks one broadcast (strided) entry
    # among them three times slower
    torch = arrays.kind_of(like) == "torch"
    dense = [
        xp.broadcast_to(e, batch).contiguous()
        if torch and not isinstance(e, float) and tuple(e.shape) != batch
        else e
        for e in entries
    ]
    shape = (7,) if form == "pos_quat" else (3 if form == "3x4" else 4, 4)
    return _pose.stack(dense, (len(at), *shape), xp, like)
