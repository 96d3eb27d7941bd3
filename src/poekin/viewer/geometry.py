"""The robot's drawable parts: triangle meshes, each fixed in one body's frame.

* MJCF and Menagerie models: the geoms MuJoCo compiled, meshes (``mesh_vert``, ``mesh_face``) and
  primitives (``geom_size``), placed by ``geom_pos`` and ``geom_quat`` and coloured by their
  material or ``rgba``; the groups MuJoCo's own viewer shows (0, 1 and 2). The mesh files are
  read by MuJoCo (:func:`poekin.io.sources.load_model` with ``read_assets=True``): poekin has no
  mesh parser of its own.
* URDF: each link's ``<visual>`` elements, mesh files loaded by trimesh.
* Where a mesh file is missing (the XML-only Menagerie models) or there is nothing to draw, and
  for a bare parameter set: a stand-in, capsules between joint anchors
  (:func:`poekin.viewer.scene.skeleton`).

The viewer sends each part once and then only moves its body (:mod:`poekin.viewer.app`).
Needs trimesh (the extra ``view``) for primitives and capsules.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.viewer.scene import Subject, skeleton

if TYPE_CHECKING:
    import mujoco

    from poekin.io.sources import LoadedModel

__all__ = ["Geometry", "Part", "mjcf_geometry", "stand_in", "urdf_geometry"]

FloatArray = NDArray[np.float64]
STAND_IN_COLOR = (150, 165, 190)
_VISIBLE_GROUPS = 3  # MuJoCo's viewer shows geom groups 0, 1 and 2 by default
_STAND_IN_RADIUS = 0.022  # of the robot's extent


@dataclasses.dataclass(frozen=True, eq=False)
class Part:
    """A triangle mesh fixed in body ``body`` (an index into :attr:`Subject.body_names`).

    ``vertices`` ``(V, 3)`` are in the body's frame (m), ``faces`` ``(F, 3)`` index them.
    """

    body: int
    name: str
    vertices: NDArray[np.float32]
    faces: NDArray[np.uint32]
    color: tuple[int, int, int]
    opacity: float = 1.0


@dataclasses.dataclass(frozen=True, eq=False)
class Geometry:
    """A robot's parts, and one line for the panel saying what they are (``note``);
    ``stand_in`` when they are the capsule stand-in."""

    parts: tuple[Part, ...]
    note: str
    stand_in: bool = False

    @property
    def n_triangles(self) -> int:
        return sum(len(p.faces) for p in self.parts)


def _trimesh() -> Any:
    import trimesh

    return trimesh


def _placed(mesh: Any, R: FloatArray, p: FloatArray) -> tuple[FloatArray, NDArray[np.uint32]]:
    v = np.asarray(mesh.vertices, dtype=np.float64) @ R.T + p
    return v, np.asarray(mesh.faces, dtype=np.uint32)


def _capsule(a: FloatArray, b: FloatArray, radius: float) -> tuple[FloatArray, NDArray[np.uint32]]:
    """A capsule from ``a`` to ``b``: trimesh's along z, turned onto ``b - a``."""
    d = b - a
    length = float(np.linalg.norm(d))
    mesh = _trimesh().creation.capsule(height=length, radius=radius, count=[12, 6])
    z = d / length
    axis = np.cross([0.0, 0.0, 1.0], z)
    angle = np.arctan2(np.linalg.norm(axis), z[2])
    n = np.linalg.norm(axis)
    rot = (
        lie.exp_so3(axis / n * angle)
        if n > 1e-12
        else np.diag([1.0, -1.0, -1.0] if z[2] < 0 else [1.0, 1.0, 1.0])
    )
    return _placed(mesh, np.asarray(rot, dtype=np.float64), (a + b) / 2)


def _merge(
    pieces: Sequence[tuple[int, str, FloatArray, NDArray[np.uint32], tuple[int, int, int], float]],
) -> tuple[Part, ...]:
    """One part per body, colour and opacity: fewer scene nodes to send and move."""
    groups: dict[tuple[int, tuple[int, int, int], float], list[Any]] = {}
    for body, name, v, f, color, opacity in pieces:
        groups.setdefault((body, color, opacity), []).append((name, v, f))
    parts = []
    for (body, color, opacity), items in groups.items():
        offsets = np.cumsum([0] + [len(v) for _, v, _ in items[:-1]])
        parts.append(
            Part(
                body=body,
                name="+".join(name for name, _, _ in items),
                vertices=np.concatenate([v for _, v, _ in items]).astype(np.float32),
                faces=np.concatenate(
                    [f + o for (_, _, f), o in zip(items, offsets, strict=True)]
                ).astype(np.uint32),
                color=color,
                opacity=opacity,
            )
        )
    return tuple(parts)


def stand_in(
    subject: Subject,
    why: str,
    *,
    tips: Mapping[int, Sequence[Any]] | None = None,
    color: tuple[int, int, int] = STAND_IN_COLOR,
    opacity: float = 1.0,
) -> Geometry:
    """Capsules between joint anchors (:func:`~poekin.viewer.scene.skeleton`), a radius of 2.2%
    of the robot's size; ``why`` ends the panel's note (e.g. "12 mesh files are missing")."""
    radius = _STAND_IN_RADIUS * subject.extent
    pieces = []
    for k, seg in enumerate(skeleton(subject, tips)):
        v, f = _capsule(np.array(seg.a), np.array(seg.b), radius)
        pieces.append((seg.body, f"capsule{k}", v, f, color, opacity))
    note = "stand-in: capsules between joint anchors" + (f" ({why})" if why else "")
    return Geometry(_merge(pieces), note, stand_in=True)


# --- MJCF ---------------------------------------------------------------------------------------


def _geom_tips(model: mujoco.MjModel, subject: Subject) -> dict[int, list[FloatArray]]:
    """Each body's geom centres in its frame, by the subject's body index (stand-in tips)."""
    import mujoco

    names = {n: b for b, n in enumerate(subject.body_names)}
    tips: dict[int, list[FloatArray]] = {}
    for g in range(model.ngeom):
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g]))
        if body in names:
            tips.setdefault(names[body], []).append(np.array(model.geom_pos[g]))
    return tips


def _primitive(model: mujoco.MjModel, g: int) -> Any | None:
    """The trimesh of primitive geom ``g`` in its own frame, or None (plane, height field...)."""
    import mujoco

    creation = _trimesh().creation
    kind, size = int(model.geom_type[g]), np.array(model.geom_size[g], dtype=np.float64)
    t = mujoco.mjtGeom
    if kind == t.mjGEOM_SPHERE:
        return creation.icosphere(subdivisions=2, radius=size[0])
    if kind == t.mjGEOM_ELLIPSOID:
        sphere = creation.icosphere(subdivisions=2, radius=1.0)
        sphere.vertices = sphere.vertices * size
        return sphere
    if kind == t.mjGEOM_CAPSULE:
        return creation.capsule(height=2 * size[1], radius=size[0], count=[16, 8])
    if kind == t.mjGEOM_CYLINDER:
        return creation.cylinder(radius=size[0], height=2 * size[1], sections=24)
    if kind == t.mjGEOM_BOX:
        return creation.box(extents=2 * size)
    return None


def _color(model: mujoco.MjModel, g: int) -> tuple[tuple[int, int, int], float]:
    mat = int(model.geom_matid[g])
    rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
    rgb = tuple(round(float(c) * 255) for c in rgba[:3])
    return (rgb[0], rgb[1], rgb[2]), float(rgba[3])


def mjcf_geometry(loaded: LoadedModel, subject: Subject) -> Geometry:
    """The parts of a model MuJoCo compiles (see the module docstring).

    ``loaded`` is the kinematics-only compile (:func:`poekin.io.sources.load_model`); when it had to
    strip missing mesh files, the result is the stand-in. Otherwise the model is compiled again,
    reading its meshes (the slow part: 0.7 s for the UR5e's 30 MB of OBJ files).
    """
    import mujoco

    from poekin.io.sources import load_model

    missing = [s for s in loaded.stripped if "mesh" in s]
    if missing:
        return stand_in(
            subject,
            f"{'; '.join(missing)} in {loaded.xml_path.name}",
            tips=_geom_tips(loaded.model, subject),
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = load_model(loaded.xml_path, read_assets=True).model
    names = {n: b for b, n in enumerate(subject.body_names)}
    pieces = []
    n_mesh = n_prim = 0
    for g in range(model.ngeom):
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g]))
        color, alpha = _color(model, g)
        if body not in names or model.geom_group[g] >= _VISIBLE_GROUPS or alpha == 0.0:
            continue
        R = np.asarray(lie.quat_to_rotation(model.geom_quat[g]), dtype=np.float64)
        p = np.array(model.geom_pos[g], dtype=np.float64)
        if int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_MESH:
            m = int(model.geom_dataid[g])
            va, nv = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
            fa, nf = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
            v = np.asarray(model.mesh_vert[va : va + nv], dtype=np.float64) @ R.T + p
            f = np.asarray(model.mesh_face[fa : fa + nf], dtype=np.uint32)
            n_mesh += 1
        else:
            mesh = _primitive(model, g)
            if mesh is None:
                continue
            v, f = _placed(mesh, R, p)
            n_prim += 1
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
        pieces.append((names[body], name, v, f, color, alpha))
    if not pieces:
        return stand_in(subject, f"{loaded.xml_path.name} has no visible geoms")
    what = [
        f"{n} {w}{'es' if w == 'mesh' and n != 1 else 's' if n != 1 else ''}"
        for n, w in ((n_mesh, "mesh"), (n_prim, "primitive"))
        if n
    ]
    return Geometry(_merge(pieces), f"the model's {' and '.join(what)} (MuJoCo's compile)")


# --- URDF ---------------------------------------------------------------------------------------


def _resolve_urdf_mesh(filename: str, urdf_dir: pathlib.Path) -> pathlib.Path | None:
    """Where a URDF mesh ``filename`` is: a path relative to the URDF's folder, an absolute or
    ``file://`` path, or ``package://PKG/REST`` looked up as ``PKG/REST`` or ``REST`` in the
    URDF's folder and the folders above it (there is no ROS to ask)."""
    if filename.startswith("file://"):
        filename = filename[len("file://") :]
    if filename.startswith("package://"):
        rest = filename[len("package://") :]
        tails = [rest, rest.split("/", 1)[1] if "/" in rest else rest]
        for folder in [urdf_dir, *urdf_dir.parents]:
            for tail in tails:
                if (folder / tail).is_file():
                    return folder / tail
        return None
    path = pathlib.Path(filename)
    path = path if path.is_absolute() else urdf_dir / path
    return path if path.is_file() else None


def urdf_geometry(path: str | os.PathLike[str], subject: Subject) -> Geometry:
    """Each link's ``<visual>`` (boxes, cylinders, spheres and mesh files, the meshes loaded by
    trimesh); the stand-in if a mesh file cannot be found or there are none."""
    from poekin.io.import_urdf import parse_urdf

    trimesh = _trimesh()
    urdf_path = pathlib.Path(path)
    robot = parse_urdf(str(urdf_path), visuals=True)
    names = {n: b for b, n in enumerate(subject.body_names)}
    named = {m.name: m for m in robot.materials if m.name}
    pieces = []
    missing: list[str] = []
    for link in robot.links:
        if link.name not in names:
            continue  # the world link
        for k, visual in enumerate(link.visuals):
            origin = (
                np.eye(4) if visual.origin is None else np.asarray(visual.origin, dtype=np.float64)
            )
            geom = visual.geometry
            mesh = None
            if geom.box is not None:
                mesh = trimesh.creation.box(extents=np.asarray(geom.box.size, dtype=np.float64))
            elif geom.cylinder is not None:
                mesh = trimesh.creation.cylinder(
                    radius=geom.cylinder.radius, height=geom.cylinder.length, sections=24
                )
            elif geom.sphere is not None:
                mesh = trimesh.creation.icosphere(subdivisions=2, radius=geom.sphere.radius)
            elif geom.mesh is not None:
                file = _resolve_urdf_mesh(geom.mesh.filename, urdf_path.parent)
                if file is None:
                    missing.append(geom.mesh.filename)
                    continue
                mesh = trimesh.load(file, force="mesh")
                if geom.mesh.scale is not None:
                    mesh.apply_scale(np.asarray(geom.mesh.scale, dtype=np.float64))
            if mesh is None:
                continue
            color = (180, 180, 180)
            material = visual.material
            if material is not None and material.color is None:  # a robot-level material
                material = named.get(material.name, material)
            if (
                material is not None
                and material.color is not None
                and material.color.rgba is not None
            ):
                rgba = material.color.rgba
                color = (
                    round(rgba[0] * 255),
                    round(rgba[1] * 255),
                    round(rgba[2] * 255),
                )
            v, f = _placed(mesh, origin[:3, :3], origin[:3, 3])
            pieces.append((names[link.name], f"{link.name}/visual{k}", v, f, color, 1.0))
    if missing:
        shown = ", ".join(missing[:3]) + (", ..." if len(missing) > 3 else "")
        return stand_in(
            subject,
            f"{len(missing)} mesh file{'s' if len(missing) != 1 else ''} not found: {shown}",
        )
    if not pieces:
        return stand_in(subject, f"{urdf_path.name} has no visual geometry")
    return Geometry(
        _merge(pieces),
        f"the URDF's {len(pieces)} visual{'s' if len(pieces) != 1 else ''} (meshes by trimesh)",
    )
