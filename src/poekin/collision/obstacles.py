"""World obstacles: boxes, spheres, capsules, planes and convex meshes, each at a pose.

An obstacle is a frozen dataclass, checked when it is made: its sizes (m) are finite and
``> 0``, its ``pose`` a rigid transform (a ``(4, 4)`` matrix whose rotation is orthonormal
with det +1, or seven numbers ``x y z qw qx qy qz``), a mesh's vertices finite and not flat.
``pose`` is ``T_world_obstacle``, or with ``frame`` (a body or site of the robot) the
obstacle's pose in that frame, so that it moves with it (a part held in the gripper). The
shapes are MuJoCo's, in the obstacle's own frame:

* :class:`Box`: half sizes along x, y, z, centred at the origin;
* :class:`Sphere`: a radius, centred at the origin;
* :class:`Capsule`: a radius and the half length of its segment along z;
* :class:`Plane`: the plane ``z = 0``, its normal ``+z``; everything below it is inside;
* :class:`Mesh`: the convex hull of vertices, given or read from an STL, OBJ or MSH file.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
from typing import Any, TypeAlias

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.errors import InputError

__all__ = ["Box", "Capsule", "Mesh", "Obstacle", "Plane", "Sphere", "rigid_pose"]

FloatArray = NDArray[np.float64]

_ROTATION_TOL = 1e-6  # orthonormality of a given rotation, as poekin's other poses
_QUAT_TOL = 1e-6
_MESH_SUFFIXES = (".stl", ".obj", ".msh")


def _identity() -> FloatArray:
    return np.eye(4)


def rigid_pose(T: Any, what: str) -> FloatArray:
    """``T`` as a read-only ``(4, 4)`` float64 rigid transform.

    Args:
        T: a ``(4, 4)`` matrix (rotation orthonormal with det +1 to 1e-6, last row
            ``0 0 0 1``) or seven numbers ``x y z qw qx qy qz`` (a unit quaternion, w first).
        what: the name the error message starts with.

    Raises:
        InputError: another shape, NaN or inf, a rotation that is not one, a quaternion that
            is not unit.
    """
    try:
        arr = np.array(T, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(
            f"{what} must be a (4, 4) rigid transform or 7 numbers x y z qw qx qy qz, got "
            f"{type(T).__name__}"
        ) from None
    if arr.shape not in ((4, 4), (7,)):
        raise InputError(
            f"{what} must be a (4, 4) rigid transform or 7 numbers x y z qw qx qy qz, got shape "
            f"{arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what} contains NaN or inf: give finite numbers")
    if arr.shape == (7,):
        norm = float(np.linalg.norm(arr[3:]))
        if abs(norm - 1.0) > _QUAT_TOL:
            raise InputError(
                f"{what}: the quaternion qw qx qy qz has norm {norm:.9g}, not 1: give a unit "
                "quaternion"
            )
        pose = np.eye(4)
        pose[:3, :3] = lie.quat_to_rotation(arr[3:] / norm)
        pose[:3, 3] = arr[:3]
        arr = pose
    R = arr[:3, :3]
    if not np.array_equal(arr[3], [0.0, 0.0, 0.0, 1.0]):
        raise InputError(f"{what}: the last row of a rigid transform is 0 0 0 1, got {arr[3]}")
    if not np.allclose(R.T @ R, np.eye(3), atol=_ROTATION_TOL) or np.linalg.det(R) < 0:
        raise InputError(
            f"{what} is not a rigid transform: its rotation is not orthonormal with det +1"
        )
    arr.flags.writeable = False
    return arr


def _size(value: Any, what: str) -> float:
    """``value`` as a finite float ``> 0`` (a size in metres)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number (m), got {type(value).__name__}") from None
    if not math.isfinite(x) or x <= 0:
        raise InputError(f"{what} must be a finite size > 0 (m), got {x}")
    return x


def _frame(frame: Any, what: str) -> str | None:
    if frame is not None and not (isinstance(frame, str) and frame):
        raise InputError(f"{what}: frame must be a body or site name, or None for the world")
    return frame


@dataclasses.dataclass(frozen=True, eq=False)
class Box:
    """A box centred at its pose, its edges along the pose's axes.

    Attributes:
        half_sizes: ``(3,)`` half lengths along x, y, z (m), each ``> 0``.
        pose: ``T_world_box`` (or ``T_frame_box`` with ``frame``), ``(4, 4)``.
        frame: a body or site the box moves with; None: fixed in the world.
        name: how result pairs name it (default ``box<k>``, ``k`` its place among the
            obstacles).
    """

    half_sizes: tuple[float, float, float]
    pose: FloatArray = dataclasses.field(default_factory=_identity)
    frame: str | None = None
    name: str = ""

    def __post_init__(self) -> None:
        try:
            sizes = np.array(self.half_sizes, dtype=np.float64)
        except (TypeError, ValueError):
            sizes = np.zeros(0)
        if sizes.shape != (3,):
            raise InputError(
                f"Box: half_sizes must be 3 numbers (m), along x, y and z, got {self.half_sizes!r}"
            )
        axes = "xyz"
        object.__setattr__(
            self,
            "half_sizes",
            tuple(_size(s, f"Box: half size along {a}") for s, a in zip(sizes, axes, strict=True)),
        )
        object.__setattr__(self, "pose", rigid_pose(self.pose, "Box: pose"))
        object.__setattr__(self, "frame", _frame(self.frame, "Box"))


@dataclasses.dataclass(frozen=True, eq=False)
class Sphere:
    """A sphere centred at its pose's origin.

    Attributes:
        radius: (m) ``> 0``.
        pose: ``(4, 4)`` as :class:`Box`'s.
        frame: as :class:`Box`'s.
        name: default ``sphere<k>``.
    """

    radius: float
    pose: FloatArray = dataclasses.field(default_factory=_identity)
    frame: str | None = None
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _size(self.radius, "Sphere: radius"))
        object.__setattr__(self, "pose", rigid_pose(self.pose, "Sphere: pose"))
        object.__setattr__(self, "frame", _frame(self.frame, "Sphere"))


@dataclasses.dataclass(frozen=True, eq=False)
class Capsule:
    """A capsule: the points within ``radius`` of the segment from ``-half_length`` to
    ``+half_length`` along its pose's z axis (MuJoCo's capsule).

    Attributes:
        radius: (m) ``> 0``.
        half_length: half the segment's length (m) ``> 0``.
        pose: ``(4, 4)`` as :class:`Box`'s.
        frame: as :class:`Box`'s.
        name: default ``capsule<k>``.
    """

    radius: float
    half_length: float
    pose: FloatArray = dataclasses.field(default_factory=_identity)
    frame: str | None = None
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius", _size(self.radius, "Capsule: radius"))
        object.__setattr__(self, "half_length", _size(self.half_length, "Capsule: half_length"))
        object.__setattr__(self, "pose", rigid_pose(self.pose, "Capsule: pose"))
        object.__setattr__(self, "frame", _frame(self.frame, "Capsule"))


@dataclasses.dataclass(frozen=True, eq=False)
class Plane:
    """The plane ``z = 0`` of its pose, its normal ``+z``: a floor or a table top without
    edges. Everything below it counts as inside (a point 1 cm under it is 1 cm deep).

    Attributes:
        pose: ``(4, 4)`` as :class:`Box`'s.
        frame: as :class:`Box`'s.
        name: default ``plane<k>``.
    """

    pose: FloatArray = dataclasses.field(default_factory=_identity)
    frame: str | None = None
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", rigid_pose(self.pose, "Plane: pose"))
        object.__setattr__(self, "frame", _frame(self.frame, "Plane"))


def _read_mesh(path: pathlib.Path) -> FloatArray:
    """The vertices of a mesh file in its own frame, as MuJoCo reads the file (scaled by 1).

    MuJoCo moves a mesh to its centre of mass and principal axes when it compiles it; the
    geom's frame in the compiled model undoes that, so the vertices are given back in the
    file's frame.

    Raises:
        InputError: no such file, a suffix MuJoCo does not read, or a file it cannot read.
    """
    import mujoco

    if not path.is_file():
        raise InputError(f"Mesh: no mesh file {str(path)!r}: check the path")
    if path.suffix.lower() not in _MESH_SUFFIXES:
        raise InputError(
            f"Mesh: {path.name} is not a mesh file: MuJoCo reads .stl, .obj and .msh, or give "
            "the vertices as an (n, 3) array"
        )
    spec = mujoco.MjSpec()
    spec.add_mesh(name="mesh", file=str(path.resolve()))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="mesh")
    try:
        model = spec.compile()
    except Exception as e:
        reason = "; ".join(line.strip() for line in str(e).splitlines() if line.strip())
        raise InputError(f"Mesh: MuJoCo cannot read {path.name} as a mesh: {reason}") from None
    vert = np.array(model.mesh_vert[: int(model.mesh_vertnum[0])], dtype=np.float64)
    R = np.asarray(lie.quat_to_rotation(model.geom_quat[0]), dtype=np.float64)
    return np.asarray(vert @ R.T + model.geom_pos[0], dtype=np.float64)


@dataclasses.dataclass(frozen=True, eq=False)
class Mesh:
    """A convex mesh: the convex hull of its vertices, as MuJoCo collides any mesh.

    Attributes:
        vertices: ``(n, 3)`` vertices in the obstacle's own frame (m): given, or read from the
            mesh file (STL, OBJ, MSH) that ``source`` names. Read-only.
        pose: ``(4, 4)`` as :class:`Box`'s.
        frame: as :class:`Box`'s.
        name: default ``mesh<k>``.

    Made as ``Mesh(path_or_vertices, pose=T)``.
    """

    vertices: FloatArray
    pose: FloatArray = dataclasses.field(default_factory=_identity)
    frame: str | None = None
    name: str = ""

    def __post_init__(self) -> None:
        source: Any = self.vertices
        if isinstance(source, str | os.PathLike):
            vert = _read_mesh(pathlib.Path(source))
        else:
            try:
                vert = np.array(source, dtype=np.float64)
            except (TypeError, ValueError):
                raise InputError(
                    "Mesh: give a mesh file's path or an (n, 3) array of vertices, got "
                    f"{type(source).__name__}"
                ) from None
        if vert.ndim != 2 or vert.shape[1] != 3 or vert.shape[0] < 4:
            raise InputError(
                f"Mesh: vertices must be an (n, 3) array with n >= 4, got shape {vert.shape}"
            )
        if not np.all(np.isfinite(vert)):
            raise InputError("Mesh: the vertices contain NaN or inf: give finite numbers")
        centred = vert - vert.mean(axis=0)
        if np.linalg.matrix_rank(centred, tol=1e-9 * max(1.0, float(np.abs(vert).max()))) < 3:
            raise InputError(
                "Mesh: the vertices lie in a plane (or on a line): a convex mesh needs volume; "
                "use a Box for a thin plate"
            )
        vert.flags.writeable = False
        object.__setattr__(self, "vertices", vert)
        object.__setattr__(self, "pose", rigid_pose(self.pose, "Mesh: pose"))
        object.__setattr__(self, "frame", _frame(self.frame, "Mesh"))


Obstacle: TypeAlias = Box | Sphere | Capsule | Plane | Mesh

# MuJoCo's geom type and size of each kind
KIND = {Box: "box", Sphere: "sphere", Capsule: "capsule", Plane: "plane", Mesh: "mesh"}


def kind_of(obstacle: Any) -> str:
    """``"box"``, ``"sphere"``, ... for an obstacle.

    Raises:
        InputError: not one of poekin.collision's obstacles.
    """
    kind = KIND.get(type(obstacle))
    if kind is None:
        raise InputError(
            "obstacles must be poekin.collision.Box, Sphere, Capsule, Plane or Mesh, got "
            f"{type(obstacle).__name__}"
        )
    return kind


def as_obstacles(obstacles: Any) -> tuple[Obstacle, ...]:
    """``obstacles`` (one obstacle or an iterable of them) as a tuple, each checked."""
    if isinstance(obstacles, tuple(KIND)):
        obstacles = (obstacles,)
    try:
        found = tuple(obstacles)
    except TypeError:
        raise InputError(
            "obstacles must be a list of poekin.collision.Box, Sphere, Capsule, Plane or Mesh, "
            f"got {type(obstacles).__name__}"
        ) from None
    for obstacle in found:
        kind_of(obstacle)
    return found


def mjcf_size(obstacle: Obstacle) -> tuple[float, float, float]:
    """MuJoCo's ``geom_size`` of an obstacle's geom (a mesh's and a plane's: unused)."""
    if isinstance(obstacle, Box):
        return obstacle.half_sizes
    if isinstance(obstacle, Sphere):
        return (obstacle.radius, 0.0, 0.0)
    if isinstance(obstacle, Capsule):
        return (obstacle.radius, obstacle.half_length, 0.0)
    return (1.0, 1.0, 1.0)  # a plane's size only draws it; a mesh's comes from the mesh
