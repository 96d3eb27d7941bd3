"""A robot's collision geometry: which geoms, on which bodies, and which pairs are checked.

The geometry is read from the model file the tree was loaded from, compiled by MuJoCo with its
mesh files:

* **MJCF**: every geom that MuJoCo would collide (``contype`` or ``conaffinity`` nonzero, or
  named in a ``<pair>``). Menagerie's models put these in a ``collision`` default class and
  their visual meshes in a class with ``contype="0" conaffinity="0"``, so visual geoms are left
  out by the same rule. Primitives (sphere, capsule, cylinder, box, plane, ellipsoid) keep
  their shapes; a mesh is its convex hull, as MuJoCo collides it.
* **URDF**: every link's ``<collision>`` elements, as MuJoCo reads them (each link a body,
  ``fusestatic`` off); ``package://`` mesh paths are found under ``ROS_PACKAGE_PATH``, or in
  a folder of that package's name above the URDF file.

The pairs are MuJoCo's own (``mj_collision``'s filter), so that ``mj_collision`` on the same
model tests the same ones:

* geoms on bodies welded together (the same body, bodies joined without a joint, or both fixed
  to the world) are never a pair;
* a body and its parent (after welding) are not either, unless one of them is the world or the
  model disables ``filterparent``;
* body pairs named in ``<exclude>`` are left out;
* ``contype``/``conaffinity``: geoms 1 and 2 are a pair when ``contype1 & conaffinity2`` or
  ``contype2 & conaffinity1`` is nonzero;
* the ``<pair>`` elements are pairs whatever the rules above say (a pair that both give is
  checked once);
* two geoms that MuJoCo has no collision function for (planes and height fields) are none.

For a URDF these rules are the adjacent-links rule (links joined by a fixed joint count as one
link), and a list of link pairs to ignore can be given (as an SRDF's disabled collisions).

A model whose mesh files are missing (poekin's built-in XML-only copies) loads only if no
collision geom needs them; otherwise it is a :class:`~poekin.errors.ModelError` naming them.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from poekin import lie
from poekin.errors import ModelError

if TYPE_CHECKING:
    import mujoco

__all__ = ["CollisionModel", "model_of"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

GEOM_TYPES = ("plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh")
_NO_FUNCTION = {"plane", "hfield"}  # MuJoCo collides neither with the other, nor with itself
_FRAME_TOL = 1e-9  # the collision compile's body frames against the tree's


@dataclasses.dataclass(frozen=True, eq=False)
class CollisionModel:
    """The collision geoms of a robot and the pairs checked, as MuJoCo's rules give them.

    Each geom sits at a fixed pose in a body of the tree: its world pose is
    ``tree.fk(qpos)[body] @ [geom_rot, geom_pos]`` (for a geom of the world,
    ``tree.base @ ...``). Made by :func:`model_of`.

    Attributes:
        source: the model file the geometry was read from.
        geom_names: ``G`` names: the geom's own, else its body's (``body#k`` where the body has
            several unnamed collision geoms, ``k`` counting them from 0).
        geom_types: ``G`` MuJoCo geom types (``"capsule"``, ``"mesh"``, ...).
        geom_bodies: ``(G,)`` each geom's body, an index of ``tree.body_names``; -1: the world.
        geom_sizes: ``(G, 3)`` MuJoCo's ``geom_size`` (m): radius, half length, half sizes.
        geom_pos: ``(G, 3)`` each geom's origin in its body's frame (m).
        geom_rot: ``(G, 3, 3)`` each geom's orientation in its body's frame.
        pairs: ``(P, 2)`` indices of the geoms of each checked pair.
        body_names: the tree's bodies.
        body_parents: ``(nb,)`` the tree's body parents.
        body_welds: ``(nb,)`` each body's rigid group (the body its welded set hangs from, a
            tree body index; -1: fixed to the world).
        filter_parent: whether a body and its parent are never a pair (MuJoCo's default).
        mj_model: the compiled ``mujoco.MjModel`` of the collision geoms alone (geom ``k`` is
            MuJoCo's geom ``k``), which the queries measure on.
        mj_spec: its ``mujoco.MjSpec``, to which the queries add obstacles.
    """

    source: str
    geom_names: tuple[str, ...]
    geom_types: tuple[str, ...]
    geom_bodies: IntArray
    geom_sizes: FloatArray
    geom_pos: FloatArray
    geom_rot: FloatArray
    pairs: IntArray
    body_names: tuple[str, ...]
    body_parents: IntArray
    body_welds: IntArray
    filter_parent: bool
    mj_model: Any = dataclasses.field(repr=False)
    mj_spec: Any = dataclasses.field(repr=False)
    # obstacle shapes -> (MjModel with them, their geom ids, their geoms' offsets), built once
    _with_obstacles: dict[Any, Any] = dataclasses.field(
        default_factory=dict, init=False, repr=False
    )

    @property
    def n_pairs(self) -> int:
        """The number of checked pairs of the robot's own geoms."""
        return int(self.pairs.shape[0])

    def pair_names(self) -> tuple[tuple[str, str], ...]:
        """Each checked pair's two geom names."""
        return tuple((self.geom_names[a], self.geom_names[b]) for a, b in self.pairs.tolist())

    def weld_of(self, body: int) -> int:
        """The rigid group of a tree body (-1: the world, also for ``body = -1``)."""
        return -1 if body < 0 else int(self.body_welds[body])

    def filtered(self, weld1: int, weld2: int) -> bool:
        """Whether two rigid groups are never a pair: the same group, or (with
        :attr:`filter_parent`, neither the world) one the other's parent."""
        if weld1 == weld2:
            return True
        if not self.filter_parent or weld1 < 0 or weld2 < 0:
            return False
        return self._weld_parent(weld1) == weld2 or self._weld_parent(weld2) == weld1

    def _weld_parent(self, weld: int) -> int:
        parent = int(self.body_parents[weld])
        return -1 if parent < 0 else int(self.body_welds[parent])


def _reason(e: Exception) -> str:
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    return "; ".join(lines) if lines else type(e).__name__


def _package_file(uri: str, urdf: pathlib.Path) -> str:
    """The file a ``package://NAME/rest`` URI names: ``NAME/rest`` under a folder of
    ``ROS_PACKAGE_PATH``, or a folder called ``NAME`` above the URDF (or beside one of its
    folders). A URI not found stays as it is (the missing files are named later)."""
    name, _, rest = uri[len("package://") :].partition("/")
    roots = [pathlib.Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    for root in roots:
        for candidate in (root / name / rest, root / rest):
            if candidate.is_file():
                return str(candidate)
    for folder in urdf.resolve().parents:
        for candidate in (folder / rest, folder / name / rest) if folder.name == name else ():
            if candidate.is_file():
                return str(candidate)
        if (folder / name / rest).is_file():
            return str(folder / name / rest)
    return uri


def _mesh_path(spec: mujoco.MjSpec, mesh: mujoco.MjsMesh, model_dir: pathlib.Path) -> pathlib.Path:
    """Where MuJoCo reads a mesh's file: absolute, else under ``meshdir`` (relative to the
    model's folder); ``strippath`` drops the file's own folders."""
    file = mesh.file
    if spec.strippath:
        file = file.replace("\\", "/").rsplit("/", 1)[-1]
    path = pathlib.Path(file)
    if path.is_absolute():
        return path
    folder = pathlib.Path(mesh.compiler.meshdir or spec.meshdir or "")
    return (folder if folder.is_absolute() else model_dir / folder) / path


def _collides(geom: mujoco.MjsGeom, paired: set[str]) -> bool:
    return bool(geom.contype or geom.conaffinity or (geom.name and geom.name in paired))


def _read_spec(path: pathlib.Path, free_root: bool) -> mujoco.MjSpec:
    import mujoco

    try:
        if path.suffix in (".xml", ".urdf"):
            spec = mujoco.MjSpec.from_file(str(path))
        else:  # MuJoCo picks its reader by these two suffixes, in lower case
            spec = mujoco.MjSpec.from_string(path.read_text(encoding="utf-8"))
            spec.modelfiledir = str(path.parent) + os.sep
    except Exception as e:
        raise ModelError(f"cannot read {path} for its collision geometry: {_reason(e)}") from e
    if path.suffix.lower() == ".urdf":
        spec.compiler.fusestatic = False  # every link a body, as poekin reads the URDF
        for mesh in spec.meshes:
            if mesh.file.startswith("package://"):
                mesh.file = _package_file(mesh.file, path)
        if free_root and len(spec.worldbody.bodies) == 1:
            spec.worldbody.bodies[0].add_freejoint()
    return spec


def _strip_visual(spec: mujoco.MjSpec, path: pathlib.Path) -> None:
    """Remove what collision does not need (geoms MuJoCo would not collide, meshes no
    collision geom uses, textures, materials, skins), floor masses so that bodies whose visual
    geoms shaped their inertia still compile, and check that every mesh file left exists.

    Raises:
        ModelError: a collision geom's mesh file is missing; the message names them.
    """
    paired = {name for p in spec.pairs for name in (p.geomname1, p.geomname2)}
    for geom in [g for g in spec.geoms if not _collides(g, paired)]:
        spec.delete(geom)
    for geom in spec.geoms:
        geom.material = ""
    for site in spec.sites:
        site.material = ""
    used = {g.meshname for g in spec.geoms if g.meshname}
    used |= {s.meshname for s in spec.sites if s.meshname}
    for mesh in [m for m in spec.meshes if m.name not in used]:
        spec.delete(mesh)
    for asset in [*spec.skins, *spec.materials, *spec.textures]:
        spec.delete(asset)
    for compiler in {id(b.compiler): b.compiler for b in spec.bodies}.values():
        compiler.boundmass = max(compiler.boundmass, 1e-6)
        compiler.boundinertia = max(compiler.boundinertia, 1e-12)
    model_dir = pathlib.Path(spec.modelfiledir or path.parent)
    missing = [
        (m.name, _mesh_path(spec, m, model_dir))
        for m in spec.meshes
        if m.file and not _mesh_path(spec, m, model_dir).is_file()
    ]
    if missing:
        names = ", ".join(f"{p.name}" for _, p in missing[:6])
        more = f" and {len(missing) - 6} more" if len(missing) > 6 else ""
        raise ModelError(
            f"{path.name}: its collision geometry needs {len(missing)} mesh file(s) that are "
            f"missing: {names}{more} (looked in {missing[0][1].parent}); this copy has no "
            "meshes (poekin's built-in copies are XML only): point MENAGERIE_ROOT at a complete "
            "Menagerie clone, or load the model file from a folder with its meshes"
        )


def _compile(spec: mujoco.MjSpec, path: pathlib.Path) -> mujoco.MjModel:
    try:
        return spec.compile()
    except Exception as e:
        raise ModelError(f"MuJoCo rejected {path.name}'s collision geometry: {_reason(e)}") from e


def _body_map(model: mujoco.MjModel, tree: Any, path: pathlib.Path) -> IntArray:
    """Each MuJoCo body's tree body index (-1: the world).

    Raises:
        ModelError: a body the tree does not have, or whose frame the collision compile puts
            elsewhere than the tree does (then the geoms would be misplaced).
    """
    import mujoco

    names = list(tree.body_names)
    out = np.full(model.nbody, -1, dtype=np.intp)
    base_inv = np.asarray(lie.inverse(tree.base), dtype=np.float64)
    for b in range(1, model.nbody):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or ""
        if name not in names:
            raise ModelError(
                f"{path.name}: the collision model's body {name or b!r} is not in the tree: "
                "load the tree from the same file"
            )
        k = names.index(name)
        out[b] = k
        if int(model.body_jntnum[b]) and tree.joint_types[tree._body_joints[k][0]] == "free":
            continue  # placed by qpos
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = tree.body_rot[k], tree.body_pos[k]
        if int(tree.body_parents[k]) < 0:
            T = base_inv @ T
        R = np.asarray(lie.quat_to_rotation(model.body_quat[b]), dtype=np.float64)
        off = max(np.abs(R - T[:3, :3]).max(), np.abs(model.body_pos[b] - T[:3, 3]).max())
        if off > _FRAME_TOL:
            raise ModelError(
                f"{path.name}: body {name!r} sits elsewhere in the collision compile than in "
                f"the tree (by {off:.3g}); poekin cannot place its geoms"
            )
    return out


def _geom_names(
    model: mujoco.MjModel, ids: list[int], bodies: IntArray, body_names: list[str]
) -> tuple[str, ...]:
    import mujoco

    own = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in ids]
    unnamed: dict[int, list[int]] = {}
    for k, g in enumerate(ids):
        if not own[k]:
            unnamed.setdefault(int(model.geom_bodyid[g]), []).append(k)
    names = list(own)
    for body, ks in unnamed.items():
        label = body_names[bodies[body]] if bodies[body] >= 0 else "world"
        for j, k in enumerate(ks):
            names[k] = label if len(ks) == 1 else f"{label}#{j}"
    seen: dict[str, int] = {}
    for k, name in enumerate(names):  # a geom named as another's body: keep both apart
        if name in seen:
            names[k] = f"{name}#{k}"
        seen[name] = k
    return tuple(names)


def _pairs(model: mujoco.MjModel, ids: list[int]) -> list[tuple[int, int]]:
    """MuJoCo's candidate pairs among the geoms ``ids`` (indices into ``ids``), as
    ``mj_collision`` filters them (the module's docstring)."""
    import mujoco

    index = {g: k for k, g in enumerate(ids)}
    weld, parent = model.body_weldid, model.body_parentid
    filter_parent = not (model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    excluded = {int(s) for s in model.exclude_signature}
    explicit = [(int(a), int(b)) for a, b in zip(model.pair_geom1, model.pair_geom2, strict=True)]
    types = [GEOM_TYPES[int(t)] if int(t) < len(GEOM_TYPES) else "sdf" for t in model.geom_type]
    out: list[tuple[int, int]] = []
    for i, g1 in enumerate(ids):
        for g2 in ids[i + 1 :]:
            b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
            w1, w2 = int(weld[b1]), int(weld[b2])
            if w1 == w2:
                continue
            if filter_parent and w1 and w2 and (w1 == weld[parent[w2]] or w2 == weld[parent[w1]]):
                continue
            signature = (min(b1, b2) << 16) + max(b1, b2)
            if signature in excluded:
                continue
            c1, a1 = int(model.geom_contype[g1]), int(model.geom_conaffinity[g1])
            c2, a2 = int(model.geom_contype[g2]), int(model.geom_conaffinity[g2])
            if not (c1 & a2 or c2 & a1):
                continue
            if types[g1] in _NO_FUNCTION and types[g2] in _NO_FUNCTION:
                continue
            out.append((index[g1], index[g2]))
    out += [(index[a], index[b]) for a, b in explicit if a in index and b in index]
    return sorted(set(out))


def build(tree: Any, source: str | os.PathLike[str]) -> CollisionModel:
    """The collision model of ``tree`` read from its model file ``source`` (MJCF or URDF).

    Raises:
        ModelError: the file cannot be read, a collision mesh file is missing, or the file's
            bodies are not the tree's.
    """
    import mujoco

    path = pathlib.Path(source)
    roots = [k for k, p in enumerate(tree.body_parents.tolist()) if p < 0]
    free_root = any(tree.joint_types[j] == "free" for k in roots for j in tree._body_joints[k])
    spec = _read_spec(path, free_root)
    _strip_visual(spec, path)
    model = _compile(spec, path)
    bodies = _body_map(model, tree, path)
    ids = list(range(model.ngeom))
    geom_bodies = np.array([bodies[model.geom_bodyid[g]] for g in ids], dtype=np.intp)
    names = _geom_names(model, ids, bodies, list(tree.body_names))
    types = tuple(GEOM_TYPES[int(model.geom_type[g])] for g in ids)
    welds = np.full(len(tree.body_names), -1, dtype=np.intp)
    for b in range(1, model.nbody):
        welds[bodies[b]] = bodies[model.body_weldid[b]]
    filter_parent = not (model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)

    def frozen(a: Any, dtype: Any = np.float64) -> Any:
        arr = np.array(a, dtype=dtype)
        arr.flags.writeable = False
        return arr

    pairs = _pairs(model, ids)
    return CollisionModel(
        source=str(path),
        geom_names=names,
        geom_types=types,
        geom_bodies=frozen(geom_bodies, np.intp),
        geom_sizes=frozen(model.geom_size[ids]),
        geom_pos=frozen(model.geom_pos[ids]),
        geom_rot=frozen(lie.quat_to_rotation(np.array(model.geom_quat[ids]))),
        pairs=frozen(np.array(pairs, dtype=np.intp).reshape(-1, 2), np.intp),
        body_names=tuple(tree.body_names),
        body_parents=frozen(tree.body_parents, np.intp),
        body_welds=frozen(welds, np.intp),
        filter_parent=bool(filter_parent),
        mj_model=model,
        mj_spec=spec,
    )


def model_of(tree: Any) -> CollisionModel:
    """The collision model of a tree loaded from a model file (:func:`poekin.load_tree`),
    built at first use and kept with the tree.

    Args:
        tree: a :class:`~poekin.Tree` from :func:`poekin.load_tree` (MJCF, Menagerie name or
            URDF).

    Raises:
        ModelError: the tree was built from arrays (it knows no model file), or as
            :func:`build` says.
    """
    source = getattr(tree, "_source_file", "")
    if not source:
        raise ModelError(
            "this tree knows no model file, so no collision geometry: load it with "
            "poekin.load_tree(...) from an MJCF or URDF file or a Menagerie name"
        )
    cache = tree._collision
    if "model" not in cache:
        cache["model"] = build(tree, source)
    return cache["model"]  # type: ignore[no-any-return]
