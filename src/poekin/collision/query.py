"""Distances between a robot's collision geoms, and between them and obstacles, batched.

For each configuration, every geom's world pose is the tree's FK of its body times the geom's
pose in the body (:class:`~poekin.collision.model.CollisionModel`). Each pair of primitives is
then measured by :func:`poekin.collision.gjk.posed_pairs` (compiled: the closed forms, GJK and
EPA, the NumPy reference's bits), a pair with a mesh or a height field by MuJoCo's
``mj_geomDistance`` on the same poses: the signed distance (negative: the penetration depth)
and the two witness points. How exact each kind of pair is: docs/collision.md.

A query with a margin reports only the pairs nearer than it, and measures only those whose
bounds (bounding spheres, a box's faces, a cylinder's capsule) do not put them beyond it, as
MuJoCo's broad phase; :func:`in_collision` stops at each configuration's first pair that hits.

Obstacles are added to a copy of the model as geoms of bodies of their own; an obstacle
attached to a frame moves with it and, as a geom of that frame's body would, is not paired
with the geoms of its own rigid group or (after welding) of its parent.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.collision import gjk
from poekin.collision.gjk import Shapes, compose, first_false, posed_pairs, shapes
from poekin.collision.gjk import first_clear as first_clear_pairs
from poekin.collision.model import GEOM_TYPES, CollisionModel, model_of
from poekin.collision.obstacles import Mesh, Obstacle, as_obstacles, kind_of, mjcf_size
from poekin.collision.primitives import Distance
from poekin.errors import InputError, did_you_mean

__all__ = ["Distances", "distances", "in_collision", "min_distance"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
_NO_FUNCTION = {"plane", "hfield"}
PREPARED = 8  # scenes kept per tree (prepare)


@dataclasses.dataclass(frozen=True, eq=False)
class Distances:
    """The signed distance and witness points of every checked pair, per configuration.

    Attributes:
        distance: ``(..., P)`` signed distances (m): > 0 apart, < 0 the penetration depth;
            ``inf`` for a pair farther apart than the query's ``margin``.
        points: ``(..., P, 2, 3)`` the witness points in the world frame (m): on the first
            geom of the pair, then on the second (NaN where the distance is ``inf``).
        pairs: ``P`` pairs of names: robot geoms (their own names, else their bodies') and
            obstacles.
    """

    distance: FloatArray
    points: FloatArray
    pairs: tuple[tuple[str, str], ...]

    @property
    def colliding(self) -> NDArray[np.bool_]:
        """``(..., P)`` whether each pair penetrates (distance < 0)."""
        return self.distance < 0


@dataclasses.dataclass(frozen=True)
class _Scene:
    """A MuJoCo model with the robot's collision geoms and the obstacles, and how to pose
    them: geom ``k`` is at ``frames[..., frame[k]] @ local[k]`` (``frames`` the tree's FK,
    then its base, then the world)."""

    model: Any
    frame: IntArray
    local: FloatArray
    pairs: IntArray
    names: tuple[tuple[str, str], ...]


def _obstacle_model(collision: CollisionModel, obstacles: tuple[Obstacle, ...]) -> Any:
    """``(MjModel, (n, 4, 4) each obstacle geom's pose in the obstacle's frame)`` for these
    obstacle shapes, compiled once per collision model and set of shapes."""
    import mujoco

    key = tuple(
        (kind_of(o), o.vertices.tobytes() if isinstance(o, Mesh) else tuple(mjcf_size(o)))
        for o in obstacles
    )
    found = collision._with_obstacles.get(key)
    if found is not None:
        return found
    spec = collision.mj_spec.copy()
    types = {name: mujoco.mjtGeom(k) for k, name in enumerate(GEOM_TYPES)}
    for k, obstacle in enumerate(obstacles):
        kind = kind_of(obstacle)
        body = spec.worldbody.add_body()  # added last: the robot's geom ids stay
        geom = body.add_geom(type=types[kind], size=mjcf_size(obstacle), contype=0, conaffinity=0)
        if isinstance(obstacle, Mesh):
            name = f"poekin_obstacle_{k}"
            spec.add_mesh(name=name, uservert=obstacle.vertices.ravel().tolist())
            geom.meshname = name
    try:
        model = spec.compile()
    except Exception as e:
        reason = "; ".join(ln.strip() for ln in str(e).splitlines() if ln.strip())
        raise InputError(f"obstacles: MuJoCo cannot compile them: {reason}") from None
    first = len(collision.geom_names)
    offsets = np.tile(np.eye(4), (len(obstacles), 1, 1))
    offsets[:, :3, :3] = lie.quat_to_rotation(np.array(model.geom_quat[first:]))
    offsets[:, :3, 3] = model.geom_pos[first:]
    collision._with_obstacles[key] = found = (model, offsets)
    return found


def _names(obstacles: tuple[Obstacle, ...], taken: set[str]) -> list[str]:
    names = []
    for k, obstacle in enumerate(obstacles):
        name = obstacle.name or f"{kind_of(obstacle)}{k}"
        if name in taken:
            raise InputError(
                f"obstacle name {name!r} is taken (by a geom, a body or another obstacle): "
                "give it another name="
            )
        taken.add(name)
        names.append(name)
    return names


def _scene(
    tree: Any,
    collision: CollisionModel,
    obstacles: tuple[Obstacle, ...],
    ignore: Iterable[Any],
) -> _Scene:
    n_frames, n_geoms = tree.n_frames, len(collision.geom_names)
    base, world = n_frames, n_frames + 1
    frame = [base if b < 0 else int(b) for b in collision.geom_bodies.tolist()]
    local = np.tile(np.eye(4), (n_geoms + len(obstacles), 1, 1))
    local[:n_geoms, :3, :3], local[:n_geoms, :3, 3] = collision.geom_rot, collision.geom_pos
    welds = [collision.weld_of(int(b)) for b in collision.geom_bodies.tolist()]
    types = list(collision.geom_types)
    labels = [
        {n, collision.body_names[b] if b >= 0 else "world"}
        for n, b in zip(collision.geom_names, collision.geom_bodies.tolist(), strict=True)
    ]
    names = list(collision.geom_names)
    model = collision.mj_model
    if obstacles:
        model, offsets = _obstacle_model(collision, obstacles)
        taken = set(collision.geom_names) | set(collision.body_names) | {"world"}
        for k, (obstacle, name) in enumerate(zip(obstacles, _names(obstacles, taken), strict=True)):
            if obstacle.frame is None:
                frame.append(world)
                body = -1
            else:
                index = tree.frame_index(obstacle.frame)  # UnknownFrameError, with a suggestion
                frame.append(index)
                nb = len(tree.body_names)
                body = index if index < nb else int(tree.site_bodies[index - nb])
            local[n_geoms + k] = obstacle.pose @ offsets[k]
            welds.append(collision.weld_of(body))
            types.append(kind_of(obstacle))
            labels.append({name})
            names.append(name)
    pairs = [tuple(p) for p in collision.pairs.tolist()]
    for j in range(n_geoms, len(names)):
        for i in range(j):
            if collision.filtered(welds[i], welds[j]):
                continue
            if types[i] in _NO_FUNCTION and types[j] in _NO_FUNCTION:
                continue
            pairs.append((i, j))
    valid = sorted(set().union(*labels)) if labels else []
    keep = []
    dropped: list[tuple[str, str]] = []
    for entry in ignore:
        if not (isinstance(entry, tuple | list) and len(entry) == 2):
            raise InputError(f"ignore: each entry is a pair of names, got {entry!r}")
        for name in entry:
            if name not in valid:
                raise InputError(
                    f"ignore: no collision geom, body or obstacle named {name!r}: "
                    f"{did_you_mean(str(name), valid)}"
                )
        dropped.append((entry[0], entry[1]))
    for i, j in pairs:
        hit = any(
            (a in labels[i] and b in labels[j]) or (b in labels[i] and a in labels[j])
            for a, b in dropped
        )
        if not hit:
            keep.append((i, j))
    return _Scene(
        model=model,
        frame=np.array(frame, dtype=np.intp),
        local=local,
        pairs=np.array(keep, dtype=np.intp).reshape(-1, 2),
        names=tuple((names[i], names[j]) for i, j in keep),
    )


def _margin(margin: Any, what: str) -> float:
    try:
        value = float(margin)
    except (TypeError, ValueError):
        raise InputError(
            f"{what}: margin must be a number (m), got {type(margin).__name__}"
        ) from None
    if math.isnan(value) or value == -math.inf:
        raise InputError(f"{what}: margin must be a number (m) or inf, got {value}")
    return value


_MUJOCO_KINDS = {"mesh", "hfield"}  # pairs measured by MuJoCo's mj_geomDistance


def _shapes(scene: _Scene, n_geoms: int) -> tuple[list[str], FloatArray, list[Any]]:
    """The scene's shapes as :func:`poekin.collision.gjk.pair_distances` takes them: each
    geom's kind, its ``geom_size`` and, for a mesh, its vertices (MuJoCo's, in the geom's
    frame: the convex hull's support is theirs)."""
    model = scene.model
    kinds = [GEOM_TYPES[int(t)] for t in model.geom_type[:n_geoms]]
    vertices: list[Any] = []
    for g, kind in enumerate(kinds):
        if kind != "mesh":
            vertices.append(None)
            continue
        m = int(model.geom_dataid[g])
        start, count = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
        vertices.append(np.array(model.mesh_vert[start : start + count], dtype=np.float64))
    return kinds, np.array(model.geom_size[:n_geoms], dtype=np.float64), vertices


def _mujoco_pairs(
    scene: _Scene, poses: FloatArray, pairs: IntArray, margin: float, hit: bool = False
) -> tuple[FloatArray, FloatArray]:
    """``(B, p)`` distances and ``(B, p, 2, 3)`` witness points of ``pairs`` by MuJoCo's
    ``mj_geomDistance`` at the geoms' world ``poses (B, G, 4, 4)`` (``inf`` and NaN at
    ``margin`` or beyond). A pair whose bounding spheres (MuJoCo's ``geom_rbound``) lie beyond
    ``margin`` by 1e-6 m is not measured, as MuJoCo's own broad phase skips it; with ``hit``,
    a configuration's pairs after its first nearer than ``margin`` are not measured either."""
    import mujoco

    model = scene.model
    data = mujoco.MjData(model)
    n_geoms = poses.shape[1]
    distance = np.full((poses.shape[0], len(pairs)), np.inf)
    points = np.full((poses.shape[0], len(pairs), 2, 3), np.nan)
    if len(pairs) == 0:
        return distance, points
    origin = poses[..., :3, 3]  # (B, G, 3)
    gap = np.linalg.norm(origin[:, pairs[:, 0]] - origin[:, pairs[:, 1]], axis=-1)  # (B, p)
    rbound = np.asarray(model.geom_rbound)[pairs]  # (p, 2); a plane's is 0: no bound
    near = ~(gap - rbound.sum(axis=-1) > margin + 1e-6) | (rbound == 0).any(axis=-1)
    fromto = np.zeros(6)
    listed = pairs.tolist()
    for c in np.flatnonzero(near.any(axis=-1)).tolist():
        data.geom_xpos[:n_geoms] = poses[c, :, :3, 3]
        data.geom_xmat[:n_geoms] = poses[c, :, :3, :3].reshape(n_geoms, 9)
        for p in np.flatnonzero(near[c]).tolist():
            g1, g2 = listed[p]
            d = mujoco.mj_geomDistance(model, data, g1, g2, margin, fromto)
            if d < margin:
                distance[c, p] = d
                points[c, p] = fromto.reshape(2, 3)
                if hit:
                    break
    return distance, points


@dataclasses.dataclass(frozen=True, eq=False)
class Checked:
    """A scene ready to measure (:func:`prepare`): its pairs, each geom's frame of the tree's
    FK (``frame_of``, ``-1``: none) and pose on it (``local``, the tree's base applied), the
    shapes as :func:`poekin.collision.gjk.posed_pairs` takes them, and which pairs MuJoCo
    measures (``mesh``: a mesh or a height field)."""

    scene: _Scene
    frame_of: NDArray[np.int32]
    local: FloatArray
    shapes: Shapes
    mesh: NDArray[np.bool_]
    primitive_pairs: NDArray[np.int32]  # the pairs poekin measures, as the kernel reads them


def _obstacle_key(obstacle: Obstacle) -> tuple[Any, ...]:
    """What a prepared scene depends on of an obstacle: its shape, pose, frame and name."""
    shape = (
        obstacle.vertices.tobytes() if isinstance(obstacle, Mesh) else tuple(mjcf_size(obstacle))
    )
    return (kind_of(obstacle), shape, obstacle.pose.tobytes(), obstacle.frame, obstacle.name)


def prepare(tree: Any, obstacles: Any = (), ignore: Iterable[Any] = ()) -> Checked:
    """The pairs of ``tree``'s collision geoms and ``obstacles`` to check, less ``ignore``,
    ready for :func:`hits` (arguments as :func:`distances`). The last :data:`PREPARED` scenes
    of each tree are kept (a solve or a query called again with the same obstacles, their
    poses compared by value, does not build its scene again)."""
    collision = model_of(tree)
    obstacles = as_obstacles(obstacles)
    ignore = tuple(ignore)
    key = (tuple(_obstacle_key(o) for o in obstacles), repr(ignore))
    kept: dict[Any, Checked] = tree._collision.setdefault("prepared", {})
    found = kept.pop(key, None)
    if found is None:
        found = _prepare(tree, collision, obstacles, ignore)
    kept[key] = found  # the newest last; the oldest dropped beyond PREPARED
    while len(kept) > PREPARED:
        del kept[next(iter(kept))]
    return found


def _prepare(
    tree: Any, collision: CollisionModel, obstacles: tuple[Obstacle, ...], ignore: tuple[Any, ...]
) -> Checked:
    scene = _scene(tree, collision, obstacles, ignore)
    n = tree.n_frames
    on_base = scene.frame == n
    local = scene.local.copy()
    local[on_base] = tree.base @ scene.local[on_base]
    frame_of = np.where(scene.frame >= n, -1, scene.frame).astype(np.int32)
    kinds, sizes, vertices = _shapes(scene, len(frame_of))
    mesh = np.array(
        [_MUJOCO_KINDS & {kinds[i], kinds[j]} != set() for i, j in scene.pairs.tolist()],
        dtype=bool,
    ).reshape(-1)
    primitive = np.ascontiguousarray(scene.pairs[~mesh], dtype=np.int32).reshape(-1, 2)
    shaped = shapes(
        kinds, np.pad(sizes[:, :3], ((0, 0), (0, max(0, 3 - sizes.shape[1])))), vertices
    )
    return Checked(scene, frame_of, np.ascontiguousarray(local), shaped, mesh, primitive)


def _frames(tree: Any, qpos: ArrayLike) -> tuple[FloatArray, tuple[int, ...]]:
    """The tree's frames ``(B, F, 4, 4)`` at ``qpos`` (checked), and its batch shape."""
    frames = np.asarray(tree.fk(qpos), dtype=np.float64)
    return frames.reshape(-1, tree.n_frames, 4, 4), frames.shape[:-3]


def frames_of(tree: Any, qpos: FloatArray) -> Any:
    """The tree's frames at ``qpos (B, nq)`` (float64, finite) as :func:`hits` and
    :func:`first_clear` take them: ``(B, F, 4, 4)`` (:meth:`poekin.Tree.fk`), or where the
    collision kernel and the tree's FK are both compiled, ``(FK kernel, qpos)``, the frames
    the collision kernel computes as it goes (none kept in memory)."""
    if tree._kernel is not None and gjk._kernel is not None:
        return (tree._kernel, np.ascontiguousarray(qpos, dtype=np.float64))
    return _frames(tree, qpos)[0]


def _frames_array(frames: Any) -> FloatArray:
    """``(B, F, 4, 4)`` frames of :func:`frames_of`'s either form."""
    if isinstance(frames, tuple):
        kernel, qpos = frames
        return np.asarray(kernel.run(qpos), dtype=np.float64)
    return np.asarray(frames, dtype=np.float64)


def hits(checked: Checked, frames: Any, margin: float) -> NDArray[np.bool_]:
    """``(B,)`` whether some pair of ``checked`` is closer than ``margin`` at the tree's
    ``frames`` (:func:`frames_of`): the primitives compiled, each configuration stopping at
    its first pair that hits, then MuJoCo on the mesh pairs of the configurations they left
    clear."""
    c = checked
    hit = np.zeros(len(frames[1]) if isinstance(frames, tuple) else len(frames), dtype=bool)
    if c.scene.pairs.shape[0] == 0:
        return hit
    if not c.mesh.all():
        hit = np.asarray(
            posed_pairs(c.shapes, c.primitive_pairs, frames, c.frame_of, c.local, margin, True)
        )
    rest = np.flatnonzero(~hit)
    if c.mesh.any() and rest.size:
        poses = compose(_frames_array(frames)[rest], c.frame_of, c.local)
        d, _ = _mujoco_pairs(c.scene, poses, c.scene.pairs[c.mesh], margin, hit=True)
        hit[rest] = (d < margin).any(axis=-1)
    return hit


def first_clear(checked: Checked, frames: Any, margin: float, groups: Any) -> IntArray:
    """``(N,)`` for each group of configurations, ``frames[groups[i]:groups[i + 1]]`` (the
    tree's frames, :func:`frames_of`; ``groups (N + 1,)`` nondecreasing offsets), the index of
    its first configuration where no pair of ``checked`` is closer than ``margin`` (-1: none):
    as :func:`hits` on them all, but the compiled primitives stop at that configuration."""
    c = checked
    offsets = np.asarray(groups, dtype=np.int64)
    if c.scene.pairs.shape[0] and not c.mesh.any():
        return first_clear_pairs(
            c.shapes, c.primitive_pairs, frames, c.frame_of, c.local, margin, offsets
        )
    return first_false(hits(c, frames, margin), offsets)


def _measure(
    tree: Any, qpos: ArrayLike, obstacles: Any, margin: float, ignore: Iterable[Any]
) -> tuple[FloatArray, FloatArray, _Scene]:
    c = prepare(tree, obstacles, ignore)
    frames, batch = _frames(tree, qpos)
    B, n_pairs = frames.shape[0], c.scene.pairs.shape[0]
    distance = np.full((B, n_pairs), np.inf)
    points = np.full((B, n_pairs, 2, 3), np.nan)
    if n_pairs and not c.mesh.all():  # poekin's distances, compiled
        found = posed_pairs(c.shapes, c.primitive_pairs, frames, c.frame_of, c.local, margin)
        assert isinstance(found, Distance)
        distance[:, ~c.mesh], points[:, ~c.mesh] = found.distance, found.points
    if n_pairs and c.mesh.any():  # a mesh (MuJoCo's hull walk beats a support over V vertices)
        poses = compose(frames, c.frame_of, c.local)
        distance[:, c.mesh], points[:, c.mesh] = _mujoco_pairs(
            c.scene, poses, c.scene.pairs[c.mesh], margin
        )
    return (
        distance.reshape(*batch, n_pairs),
        points.reshape(*batch, n_pairs, 2, 3),
        c.scene,
    )


def distances(
    tree: Any,
    qpos: ArrayLike,
    obstacles: Any = (),
    *,
    margin: float = math.inf,
    ignore: Iterable[Any] = (),
) -> Distances:
    """:meth:`poekin.Tree.distances`: every checked pair's signed distance and witness points.

    Args:
        tree: a tree loaded from a model file (:func:`poekin.load_tree`).
        qpos: ``(..., nq)`` configurations (MuJoCo's layout).
        obstacles: :class:`~poekin.collision.Box`, ``Sphere``, ``Capsule``, ``Plane`` or
            ``Mesh`` obstacles (one, or a list).
        margin: pairs farther apart than this (m) are not measured: their distance is
            ``inf``, their points NaN (faster: bounds skip them). Default: all measured, but
            a height field's pairs, which MuJoCo measures only within a finite margin.
        ignore: pairs of names (geoms, bodies or obstacles, in either order) not to check,
            as an SRDF's disabled collisions.

    Returns:
        A :class:`Distances` with ``distance (..., P)``, ``points (..., P, 2, 3)`` and the
        ``P`` pairs' names.

    Raises:
        InputError: bad ``qpos``, obstacles, ``margin`` or ``ignore``.
        UnknownFrameError: an obstacle attached to a frame the tree does not have.
        ModelError: the tree knows no model file, or its collision meshes are missing.
    """
    value = _margin(margin, "distances")
    distance, points, scene = _measure(tree, qpos, obstacles, value, ignore)
    for a in (distance, points):
        a.flags.writeable = False
    return Distances(distance=distance, points=points, pairs=scene.names)


def min_distance(
    tree: Any, qpos: ArrayLike, obstacles: Any = (), *, ignore: Iterable[Any] = ()
) -> FloatArray:
    """:meth:`poekin.Tree.min_distance`: ``(...)`` the smallest signed distance over every
    checked pair (m; ``inf`` where there is no pair). Arguments as :func:`distances`."""
    distance, _, _ = _measure(tree, qpos, obstacles, math.inf, ignore)
    return np.asarray(distance.min(axis=-1, initial=np.inf), dtype=np.float64)


def in_collision(
    tree: Any,
    qpos: ArrayLike,
    obstacles: Any = (),
    *,
    margin: float = 0.0,
    ignore: Iterable[Any] = (),
) -> NDArray[np.bool_]:
    """:meth:`poekin.Tree.in_collision`: ``(...)`` whether any checked pair is closer than
    ``margin`` (m; 0: whether any penetrates; touching is not a collision). Arguments as
    :func:`distances`."""
    value = _margin(margin, "in_collision")
    checked = prepare(tree, obstacles, ignore)
    q: FloatArray = tree._as_qpos(qpos)  # checked: real, finite, (..., nq)
    found = hits(checked, frames_of(tree, q.reshape(-1, tree.nq)), value)
    return found.reshape(q.shape[:-1])
