"""What the viewer shows of collision: the robot's collision geoms and the obstacles, where they
are at a configuration, which of them collide, and the witness points of the pairs that are
close. Pure computation on :mod:`poekin.collision` (no viser), so it is tested without a browser.

* :func:`collision_scene` gathers the shapes: the robot's collision geoms
  (:func:`poekin.collision.model_of`: capsules, cylinders, boxes, spheres, ellipsoids, planes,
  meshes as their convex hulls) and the world obstacles given, in that order, each with a name
  (a pair's names in :class:`~poekin.collision.Distances`) and the frame it moves with;
* :meth:`CollisionScene.poses` places them at ``qpos``: a robot geom at MuJoCo's
  ``geom_xpos``/``geom_xmat``, an obstacle at its pose (in the world, or on its frame);
* :meth:`CollisionScene.state` asks :meth:`Tree.distances <poekin.tree.Tree.distances>` once,
  with the margin as its ``margin``, and gives the shapes in a penetrating pair (drawn red) and
  the pairs closer than the margin, closest first (their witness points drawn);
* :func:`shapes` gives each shape's triangles in its own frame, as MuJoCo collides it: a mesh as
  its convex hull (MuJoCo's own, ``mesh_graph``), a plane as a square; needs trimesh (the extra
  ``view``) for the primitives;
* :func:`read_obstacles` reads an obstacle file (``poekin view --obstacles FILE.json``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import pathlib
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.chain import as_joint_values
from poekin.collision import Box, Capsule, Distances, Mesh, Plane, Sphere, model_of
from poekin.collision.model import GEOM_TYPES
from poekin.collision.obstacles import Obstacle, as_obstacles, kind_of, mjcf_size
from poekin.errors import InputError, ModelError, did_you_mean
from poekin.tree import Tree

__all__ = [
    "DEFAULT_MARGIN",
    "CollisionScene",
    "CollisionState",
    "Shape",
    "collision_scene",
    "read_obstacles",
    "shapes",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

DEFAULT_MARGIN = 0.02  # m: pairs closer than this show their witness points
PLANE_HALF_SIZE = 1.0  # m: a plane without a size of its own is drawn as a 2 m square
_WORLD, _BASE = -1, -2  # owners that are no frame of the tree
_KINDS = {"box": Box, "sphere": Sphere, "capsule": Capsule, "plane": Plane, "mesh": Mesh}


@dataclasses.dataclass(frozen=True, eq=False)
class CollisionState:
    """Collision at one configuration, as the viewer draws it.

    Attributes:
        qpos: ``(nq,)`` the configuration.
        margin: pairs closer than this (m) are :attr:`near`.
        distances: :meth:`Tree.distances <poekin.tree.Tree.distances>` at ``qpos`` with this
            ``margin`` (pairs farther apart are ``inf``).
        colliding: ``(S,)`` whether each shape (robot geoms, then obstacles) is in a pair that
            penetrates (distance < 0): drawn red.
        near: ``(K,)`` indices of the pairs closer than ``margin``, closest first.
        poses: ``(S, 4, 4)`` each shape's world pose (:meth:`CollisionScene.poses`).
    """

    qpos: FloatArray
    margin: float
    distances: Distances
    colliding: NDArray[np.bool_]
    near: IntArray
    poses: FloatArray

    @property
    def witness(self) -> FloatArray:
        """``(K, 2, 3)`` the witness points of the :attr:`near` pairs (m, world frame): on the
        pair's first shape, then on its second."""
        return np.asarray(self.distances.points[self.near], dtype=np.float64)

    @property
    def near_distance(self) -> FloatArray:
        """``(K,)`` the :attr:`near` pairs' signed distances (m)."""
        return np.asarray(self.distances.distance[self.near], dtype=np.float64)

    @property
    def near_pairs(self) -> tuple[tuple[str, str], ...]:
        """The :attr:`near` pairs' names."""
        return tuple(self.distances.pairs[p] for p in self.near.tolist())

    @property
    def n_colliding(self) -> int:
        """How many pairs penetrate."""
        return int(np.count_nonzero(self.distances.distance < 0))


@dataclasses.dataclass(frozen=True, eq=False)
class CollisionScene:
    """A robot's collision geoms and the world obstacles: what they are, and where.

    Made by :func:`collision_scene`. Shape ``k`` (``S`` = ``G`` robot geoms, then the
    obstacles) sits at ``local[k]`` in its owner: a frame of ``tree.fk`` (a body, or a site an
    obstacle is attached to), the tree's base (a geom of the world body) or the world.

    Attributes:
        tree: the robot.
        obstacles: the obstacles, as given.
        names: ``S`` names: the robot's geom names (:attr:`CollisionModel.geom_names
            <poekin.collision.CollisionModel.geom_names>`), then the obstacles' (``name``, else
            ``box0``, ``sphere1``, ...: the kind and the place among the obstacles).
        kinds: ``S`` MuJoCo geom types (``"capsule"``, ``"box"``, ``"mesh"``, ...).
        n_robot: ``G``, how many of the shapes are the robot's.
        owners: ``(S,)`` each shape's frame index in ``tree.fk``; -1 the world, -2 the base.
        local: ``(S, 4, 4)`` each shape's pose in its owner.
        pairs: the ``P`` pairs :meth:`Tree.distances <poekin.tree.Tree.distances>` checks, by
            name, in its order.
        pair_shapes: ``(P, 2)`` the same pairs as indices into :attr:`names`.
    """

    tree: Tree
    obstacles: tuple[Obstacle, ...]
    names: tuple[str, ...]
    kinds: tuple[str, ...]
    n_robot: int
    owners: IntArray
    local: FloatArray
    pairs: tuple[tuple[str, str], ...]
    pair_shapes: IntArray

    def poses(self, qpos: ArrayLike) -> FloatArray:
        """``(..., S, 4, 4)`` each shape's world pose at ``qpos`` ``(..., nq)``: a robot geom's
        frame (MuJoCo's ``geom_xpos``, ``geom_xmat``), an obstacle's own frame.

        Raises:
            InputError: ``qpos`` is not ``(..., nq)`` finite numbers.
        """
        frames = np.asarray(self.tree.fk(qpos), dtype=np.float64)
        batch = frames.shape[:-3]
        fixed = np.broadcast_to(np.stack([np.eye(4), self.tree.base]), (*batch, 2, 4, 4))
        # owner -1 (the world) is the frame after the tree's, -2 (the base) the one after that
        every = np.concatenate([frames, fixed], axis=-3)
        index = np.where(self.owners >= 0, self.owners, frames.shape[-3] - 1 - self.owners)
        return np.asarray(every[..., index, :, :] @ self.local, dtype=np.float64)

    def state(self, qpos: ArrayLike, margin: float = DEFAULT_MARGIN) -> CollisionState:
        """Collision at one configuration ``qpos`` ``(nq,)``: one query,
        ``tree.distances(qpos, obstacles, margin=margin)``.

        Raises:
            InputError: ``qpos`` is not one configuration, or ``margin`` is not a number >= 0.
        """
        value = _margin(margin)
        x = np.array(
            as_joint_values(qpos, self.tree.nq, what="qpos values", layout=self.tree.qpos_layout()),
            dtype=np.float64,
        )
        if x.ndim != 1:
            raise InputError(
                f"one configuration of {self.tree.nq} qpos values, got shape {x.shape}"
            )
        found = self.tree.distances(x, self.obstacles, margin=value)
        d = found.distance
        colliding = np.zeros(len(self.names), dtype=bool)
        colliding[self.pair_shapes[d < 0].ravel()] = True
        close = np.flatnonzero(d < value)
        near = close[np.argsort(d[close], kind="stable")]
        return CollisionState(
            qpos=x,
            margin=value,
            distances=found,
            colliding=colliding,
            near=near.astype(np.intp),
            poses=self.poses(x),
        )


def _margin(margin: Any) -> float:
    try:
        value = float(margin)
    except (TypeError, ValueError):
        raise InputError(
            f"the collision margin must be a number (m), got {type(margin).__name__}"
        ) from None
    if not math.isfinite(value) or value < 0:
        raise InputError(f"the collision margin must be a finite distance >= 0 (m), got {value}")
    return value


def _obstacle_names(obstacles: tuple[Obstacle, ...]) -> list[str]:
    """Each obstacle's name in a query's pairs: its own, else its kind and place (``box0``)."""
    return [o.name or f"{kind_of(o)}{k}" for k, o in enumerate(obstacles)]


def collision_scene(tree: Tree, obstacles: Iterable[Obstacle] | Obstacle = ()) -> CollisionScene:
    """The robot's collision geoms and ``obstacles``, checked once at ``tree.qpos0``.

    Args:
        tree: a tree loaded from a model file (:func:`poekin.load_tree`).
        obstacles: :class:`~poekin.collision.Box`, ``Sphere``, ``Capsule``, ``Plane`` or
            ``Mesh`` obstacles (one, or a list).

    Raises:
        ModelError: the tree knows no model file, or its collision meshes are missing.
        InputError: bad obstacles (a name taken, not an obstacle).
        UnknownFrameError: an obstacle attached to a frame the tree does not have.
    """
    found = as_obstacles(obstacles)
    geometry = model_of(tree)
    pairs = tree.distances(tree.qpos0, found, margin=0.0).pairs  # checks the obstacles
    names = (*geometry.geom_names, *_obstacle_names(found))
    index = {name: k for k, name in enumerate(names)}
    owners = [_BASE if b < 0 else int(b) for b in geometry.geom_bodies.tolist()]
    local = np.tile(np.eye(4), (len(names), 1, 1))
    local[: len(owners), :3, :3] = geometry.geom_rot
    local[: len(owners), :3, 3] = geometry.geom_pos
    for k, obstacle in enumerate(found):
        owners.append(_WORLD if obstacle.frame is None else tree.frame_index(obstacle.frame))
        local[len(geometry.geom_names) + k] = obstacle.pose
    return CollisionScene(
        tree=tree,
        obstacles=found,
        names=names,
        kinds=(*geometry.geom_types, *(kind_of(o) for o in found)),
        n_robot=len(geometry.geom_names),
        owners=np.array(owners, dtype=np.intp),
        local=local,
        pairs=pairs,
        pair_shapes=np.array([(index[a], index[b]) for a, b in pairs], dtype=np.intp).reshape(
            -1, 2
        ),
    )


# --- triangles ----------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Shape:
    """A shape's triangles in its own frame (:meth:`CollisionScene.poses`).

    Attributes:
        name: the shape's name (:attr:`CollisionScene.names`).
        kind: its MuJoCo geom type.
        vertices: ``(V, 3)`` in the shape's frame (m).
        faces: ``(F, 3)`` indices of ``vertices``.
        obstacle: whether it is an obstacle (else one of the robot's geoms).
    """

    name: str
    kind: str
    vertices: NDArray[np.float32]
    faces: NDArray[np.uint32]
    obstacle: bool


def _hull(model: Any, g: int) -> tuple[FloatArray, NDArray[np.uint32]]:
    """Mesh geom ``g``'s convex hull, as MuJoCo computed it (``mesh_graph``: the hull's vertex
    count, its face count, then per vertex an edge address and its id in the mesh, the edges,
    and per face its three vertex ids in the mesh), in the geom's frame."""
    m = int(model.geom_dataid[g])
    va, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
    vertices = np.asarray(model.mesh_vert[va : va + nv], dtype=np.float64)
    graph = np.asarray(model.mesh_graph[int(model.mesh_graphadr[m]) :])
    n_vert, n_face = int(graph[0]), int(graph[1])
    start = 2 + 3 * n_vert + 3 * n_face  # after the counts, addresses, ids and edges
    faces = graph[start : start + 3 * n_face].reshape(n_face, 3)
    return vertices, faces.astype(np.uint32)


def _square(half: tuple[float, float]) -> tuple[FloatArray, NDArray[np.uint32]]:
    x, y = half
    vertices = np.array([[-x, -y, 0.0], [x, -y, 0.0], [x, y, 0.0], [-x, y, 0.0]])
    return vertices, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)


def _triangles(model: Any, g: int) -> tuple[FloatArray, NDArray[np.uint32]]:
    """Geom ``g`` of a compiled model, in the geom's frame."""
    import mujoco

    from poekin.viewer.geometry import _primitive

    kind = int(model.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_MESH:
        return _hull(model, g)
    if kind == mujoco.mjtGeom.mjGEOM_PLANE:
        size = [float(s) if s > 0 else PLANE_HALF_SIZE for s in model.geom_size[g][:2]]
        return _square((size[0], size[1]))
    mesh = _primitive(model, g)
    if mesh is None:
        raise ModelError(
            f"the viewer cannot draw collision geom {g}, a {GEOM_TYPES[kind]}: only primitives, "
            "planes and meshes"
        )
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.uint32)


def _obstacle_model(obstacles: tuple[Obstacle, ...]) -> Any:
    """A MuJoCo model with each obstacle as a geom of the world, at the identity: MuJoCo's
    primitives and mesh hulls, a mesh's re-centring in its ``geom_pos``, ``geom_quat``."""
    import mujoco

    spec = mujoco.MjSpec()
    for k, obstacle in enumerate(obstacles):
        kind = kind_of(obstacle)
        geom = spec.worldbody.add_geom(
            type=getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}"), size=mjcf_size(obstacle)
        )
        if isinstance(obstacle, Mesh):
            spec.add_mesh(name=f"mesh{k}", uservert=obstacle.vertices.ravel().tolist())
            geom.meshname = f"mesh{k}"
    return spec.compile()


def shapes(scene: CollisionScene) -> tuple[Shape, ...]:
    """Every shape's triangles, in its frame (:meth:`CollisionScene.poses`): MuJoCo's
    primitives as trimesh draws them, meshes as MuJoCo's convex hulls, planes as squares
    (their size, else 2 m)."""
    geometry = model_of(scene.tree)
    out = []
    for g, name in enumerate(scene.names[: scene.n_robot]):
        v, f = _triangles(geometry.mj_model, g)
        out.append(Shape(name, scene.kinds[g], v.astype(np.float32), f, obstacle=False))
    if scene.obstacles:
        model = _obstacle_model(scene.obstacles)
        for k, name in enumerate(scene.names[scene.n_robot :]):
            v, f = _triangles(model, k)
            R = np.asarray(lie.quat_to_rotation(model.geom_quat[k]), dtype=np.float64)
            placed = v @ R.T + model.geom_pos[k]  # a mesh's vertices back in its own frame
            out.append(
                Shape(name, scene.kinds[scene.n_robot + k], placed.astype(np.float32), f, True)
            )
    return tuple(out)


# --- an obstacle file ---------------------------------------------------------------------------


def _entry(item: Any, k: int, folder: pathlib.Path, what: str) -> Obstacle:
    if not isinstance(item, dict):
        raise InputError(f'{what}: obstacle {k} must be an object with a "type", got {item!r:.40}')
    fields = dict(item)
    kind = fields.pop("type", None)
    if kind not in _KINDS:
        raise InputError(
            f"{what}: obstacle {k} has type {kind!r}: {did_you_mean(str(kind), list(_KINDS))}"
        )
    cls = _KINDS[kind]
    allowed = [f.name for f in dataclasses.fields(cls)]
    if kind == "mesh":
        allowed = ["file", *allowed]
        if "file" in fields:
            if "vertices" in fields:
                raise InputError(f'{what}: mesh {k} has both "file" and "vertices": give one')
            path = pathlib.Path(str(fields.pop("file")))
            fields["vertices"] = path if path.is_absolute() else folder / path
    unknown = [key for key in fields if key not in allowed]
    if unknown:
        raise InputError(
            f"{what}: {kind} {k} has no field {unknown[0]!r}: {did_you_mean(unknown[0], allowed)}"
        )
    try:
        return cls(**fields)  # type: ignore[no-any-return]
    except TypeError:
        needed = [
            f.name
            for f in dataclasses.fields(cls)
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        ]
        raise InputError(
            f"{what}: {kind} {k} needs {', '.join(repr(n) for n in needed)}"
            + (' (or "file")' if kind == "mesh" else "")
        ) from None
    except InputError as e:
        raise InputError(f"{what}: obstacle {k}: {e}") from None


def read_obstacles(path: str | os.PathLike[str]) -> tuple[Obstacle, ...]:
    """The obstacles of a JSON file: a list of objects, each with a ``type`` (``box``,
    ``sphere``, ``capsule``, ``plane``, ``mesh``) and the fields of that obstacle
    (:mod:`poekin.collision.obstacles`: ``half_sizes``, ``radius``, ``half_length``,
    ``vertices``, ``pose`` as 7 numbers ``x y z qw qx qy qz`` or a 4x4 list, ``frame``,
    ``name``); a mesh may name its ``file`` (STL, OBJ, MSH) instead of ``vertices``, relative
    to the JSON file's folder. For example
    ``[{"type": "box", "half_sizes": [0.3, 0.4, 0.02], "pose": [-0.55, 0, -0.02, 1, 0, 0, 0],
    "name": "table"}]``.

    Raises:
        InputError: no such file, not JSON, not a list of obstacles, an unknown type or field,
            a field missing, or a bad size or pose (each named, with the obstacle's place).
    """
    file = pathlib.Path(path)
    what = f"obstacles {file.name}"
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as e:
        raise InputError(f"{what}: cannot read it: {e.strerror or e}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{what} is not JSON: {e.msg} at line {e.lineno}") from None
    if not isinstance(data, list):
        raise InputError(
            f'{what} must hold a JSON list of obstacles, [{{"type": "box", ...}}, ...], got '
            f"{type(data).__name__}"
        )
    return tuple(_entry(item, k, file.parent, what) for k, item in enumerate(data))
