"""Finding and compiling models: Menagerie names, MJCF paths, and kinematics-only loading.

This is the only module that reads model files, and it never writes one. A model folder whose
asset files are absent (as in a partial Menagerie clone) still compiles. poekin looks for every
mesh, height field, skin and texture file where MuJoCo would (``meshdir``, ``texturedir`` and
``assetdir``, ``strippath``, absolute paths, assets declared in ``<include>`` files or in
sub-models attached with ``<model file=...>``). Then it turns each geom or site that names a
missing mesh or height field into a tiny sphere, unlinks missing textures from materials and
lights, drops the missing assets, floors body mass and inertia so that bodies whose geometry is
gone still compile, and says so once (an :class:`AssetsStrippedWarning`). Body and site frames,
joint axes and anchors, and hence every pose, are unchanged by this; only collision, rendering and
inertia differ. One case cannot keep its poses and is refused with a :class:`ModelError`: a free
body that MuJoCo aligns with its inertial frame (``alignfree``) when missing geometry shaped that
frame. A missing ``<include>`` or sub-model file is an error too.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
import re
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Sequence
from typing import TypeAlias

import mujoco

from poekin.errors import (
    MenagerieUnavailableError,
    ModelError,
    UnknownRobotError,
    did_you_mean,
)

__all__ = ["AssetsStrippedWarning", "LoadedModel", "load_model", "resolve_source"]

_MODEL_SUFFIXES = (".xml", ".mjcf", ".urdf")
_MENAGERIE_FIX = (
    "set MENAGERIE_ROOT to a local mujoco_menagerie clone, or pass a path to the model's XML file"
)
# Stand-in radius for a geom or site whose mesh or height field is missing, and mass/inertia floors
# so that bodies whose geometry is gone still compile. Neither changes any frame pose.
_STUB_RADIUS = 1e-3
_MIN_MASS = 1e-6
_MIN_INERTIA = 1e-12
_XML_KINDS = {"include": "included file", "model": "sub-model file"}

# A model element that reads a file.
_Asset: TypeAlias = mujoco.MjsMesh | mujoco.MjsHField | mujoco.MjsSkin | mujoco.MjsTexture


class AssetsStrippedWarning(UserWarning):
    """Asset files were missing, so the model was loaded for kinematics only."""


@dataclasses.dataclass(frozen=True)
class LoadedModel:
    """A compiled MuJoCo model and where it came from.

    Attributes:
        model: the compiled ``mujoco.MjModel``.
        robot: the Menagerie name given, or the file name for a path.
        short_name: a short name for labels: the model file's stem (``ur5e``).
        xml_path: the MJCF file that was compiled.
        files: the model's files that exist on disk (XML, includes, assets), for hashing.
        stripped: what was removed for a kinematics-only load (empty if nothing).
    """

    model: mujoco.MjModel
    robot: str
    short_name: str
    xml_path: pathlib.Path
    files: tuple[pathlib.Path, ...]
    stripped: tuple[str, ...] = ()


def _looks_like_path(source: str) -> bool:
    return os.sep in source or "/" in source or source.lower().endswith(_MODEL_SUFFIXES)


def resolve_source(source: str | os.PathLike[str]) -> tuple[pathlib.Path, str]:
    """Turn a Menagerie robot name or a model path into ``(xml_path, robot_label)``.

    Raises:
        ModelError: the path does not exist or is a directory.
        UnknownRobotError: not a path, and not a Menagerie robot name.
        MenagerieUnavailableError: a known robot that cannot be fetched here.
    """
    text = os.fspath(source)
    path = pathlib.Path(text).expanduser()
    if path.is_dir():
        candidates = sorted(p.name for p in path.glob("*.xml"))
        hint = f" (it holds {', '.join(candidates[:6])})" if candidates else ""
        raise ModelError(f"{text} is a directory; pass the model's XML file inside it{hint}")
    if path.is_file():
        return path.resolve(), path.name
    if _looks_like_path(text):
        raise ModelError(f"model file not found: {text}; check the path")
    return _resolve_menagerie(text), text


def _resolve_menagerie(name: str) -> pathlib.Path:
    import mujoco_menagerie as mm

    try:
        robot = mm.get(name)
    except mm.UnknownRobotError:
        raise UnknownRobotError(
            f"unknown robot {name!r} (not a file, not a Menagerie name): "
            f"{did_you_mean(name, mm.names(), listed=8)}"
        ) from None
    try:
        xml = pathlib.Path(robot.xml(robot.default_model))
    except mm.MenagerieError as e:
        root = os.environ.get("MENAGERIE_ROOT")
        where = f" under MENAGERIE_ROOT={root}" if root else " (no network for the download?)"
        raise MenagerieUnavailableError(
            f"Menagerie robot {name!r} is not available{where}: {_MENAGERIE_FIX}"
        ) from e
    if not xml.is_file():
        raise MenagerieUnavailableError(
            f"Menagerie robot {name!r}: {xml} is missing; {_MENAGERIE_FIX}"
        )
    return xml


def _first_line(e: Exception) -> str:
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    return lines[0] if lines else type(e).__name__


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


@dataclasses.dataclass(frozen=True)
class _ModelXml:
    """The XML files that make up a model, found where MuJoCo looks for them.

    Attributes:
        files: the main file, then its ``<include>`` and sub-model (``<asset><model>``) files.
        submodel_dirs: the sub-models' folders, which their own asset paths are relative to.
    """

    files: tuple[pathlib.Path, ...]
    submodel_dirs: tuple[pathlib.Path, ...]


def _xml_references(path: pathlib.Path) -> list[tuple[str, str]]:
    """``("include", file)`` and ``("model", file)`` for each XML file that ``path`` names.

    A file that does not parse names nothing here; MuJoCo then reports it with its line number.
    """
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return []
    includes = [("include", e.get("file", "")) for e in root.iter("include")]
    return includes + [("model", e.get("file", "")) for e in root.iterfind(".//asset/model")]


def _find_xml(
    main: pathlib.Path, naming: pathlib.Path, model_dir: pathlib.Path, kind: str, name: str
) -> pathlib.Path:
    """The file that an ``<include>`` or ``<model>`` in ``naming`` reads, as MuJoCo resolves it.

    An include is relative to the folder of the model it belongs to (the main model or a
    sub-model), else to the folder of the file that names it; a sub-model is relative to the
    folder of its model.

    Raises:
        ModelError: no such file.
    """
    folders = [model_dir, naming.parent] if kind == "include" else [model_dir]
    candidates = list(dict.fromkeys(folder / name for folder in folders))
    for path in candidates:
        if path.is_file():
            return path.resolve()
    where = " or ".join(str(p) for p in candidates)
    raise ModelError(
        f"{main.name}: {_XML_KINDS[kind]} {name!r} named in {naming.name} is missing (looked for "
        f"{where}); restore the file or fix its path"
    )


def _model_xml(xml_path: pathlib.Path) -> _ModelXml:
    """Follow ``<include>`` and ``<model file=...>`` from ``xml_path``, recursively.

    Raises:
        ModelError: a file named there does not exist.
    """
    files = [xml_path]
    submodel_dirs: list[pathlib.Path] = []
    pending = [(xml_path, xml_path.parent)]
    while pending:
        path, model_dir = pending.pop()
        for kind, name in _xml_references(path):
            child = _find_xml(xml_path, path, model_dir, kind, name)
            if child in files:
                continue  # MuJoCo rejects a file included twice; it says so itself
            files.append(child)
            if kind == "model":
                submodel_dirs.append(child.parent)
            pending.append((child, model_dir if kind == "include" else child.parent))
    return _ModelXml(tuple(files), tuple(dict.fromkeys(submodel_dirs)))


def _asset_files(spec: mujoco.MjSpec) -> Iterator[tuple[_Asset, str]]:
    """Every file-backed asset with each file it reads (a cube texture can read six)."""
    for asset in [*spec.meshes, *spec.hfields, *spec.skins]:
        if asset.file:
            yield asset, asset.file
    for texture in spec.textures:
        for file in [texture.file, *texture.cubefiles]:
            if file:
                yield texture, file


def _candidates(
    spec: mujoco.MjSpec, xml: _ModelXml, asset: _Asset, file: str
) -> list[pathlib.Path]:
    """Where MuJoCo reads ``file`` of ``asset`` from: the rules of compiler ``meshdir``.

    ``strippath`` drops the file's folders; then an absolute file, else an absolute ``meshdir``
    (``texturedir`` for textures; ``assetdir`` sets both), is used as it is, which is what
    pathlib's ``/`` does; a relative one is under the model's folder. Assets of an attached
    sub-model keep its compiler and are under its folder; the spec does not say which
    sub-model's, so each sub-model's folder is a candidate.
    """
    compiler = asset.compiler
    folder = compiler.texturedir if isinstance(asset, mujoco.MjsTexture) else compiler.meshdir
    if spec.strippath:
        file = re.split(r"[/\\]", file)[-1]
    bases = [pathlib.Path(spec.modelfiledir)] if compiler is spec.compiler else xml.submodel_dirs
    return [base / folder / file for base in bases]


def _scan_assets(spec: mujoco.MjSpec, xml: _ModelXml) -> tuple[list[pathlib.Path], list[_Asset]]:
    """The asset files that exist, and the assets with a file that does not."""
    found: list[pathlib.Path] = []
    missing: dict[int, _Asset] = {}
    for asset, file in _asset_files(spec):
        hits = [p for p in _candidates(spec, xml, asset, file) if p.is_file()]
        if hits:
            found.append(hits[0])
        else:
            missing.setdefault(id(asset), asset)
    return found, list(missing.values())


def _tiny_spheres(elements: Sequence[mujoco.MjsGeom | mujoco.MjsSite]) -> int:
    """Make geoms or sites tiny spheres that name no mesh; their frames stay as they are.

    Whatever the type: a primitive geom that names a mesh is fitted to it, so its own size means
    nothing without the mesh. A geom keeps its group, mass and density.
    """
    for e in elements:
        e.type = mujoco.mjtGeom.mjGEOM_SPHERE
        e.size = [_STUB_RADIUS, 0.0, 0.0]
        e.meshname = ""
    return len(elements)


def _spheres_note(geoms: int, sites: int) -> str:
    named = [_count(n, noun) for n, noun in ((geoms, "geom"), (sites, "site")) if n]
    made = "a tiny sphere" if geoms + sites == 1 else "tiny spheres"
    return f" ({' and '.join(named)} made {made})" if named else ""


def _adds_inertia(geom: mujoco.MjsGeom) -> bool:
    """Whether ``geom`` counts towards its body's mass, centre of mass and inertia."""
    body = geom.parent
    compiler = body.compiler
    from_geoms = compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_TRUE or (
        compiler.inertiafromgeom == mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
        and not body.explicitinertial
    )
    low, high = compiler.inertiagrouprange
    massless = geom.mass == 0 or (math.isnan(geom.mass) and geom.density == 0)
    return bool(from_geoms and low <= geom.group <= high and not massless)


def _unlink_textures(spec: mujoco.MjSpec, names: set[str]) -> None:
    """Make the materials and lights that use the textures ``names`` use none instead."""
    for material in spec.materials:
        material.textures = ["" if t in names else t for t in material.textures]
    for light in spec.lights:
        if light.texture in names:
            light.texture = ""


def _floor_inertia(spec: mujoco.MjSpec) -> None:
    """Floor every body's mass and inertia, far below any real part's, so that a moving body
    whose geometry is gone still compiles. Each attached sub-model has its own compiler."""
    for compiler in {id(b.compiler): b.compiler for b in spec.bodies}.values():
        compiler.boundmass = max(compiler.boundmass, _MIN_MASS)
        compiler.boundinertia = max(compiler.boundinertia, _MIN_INERTIA)


def _strip_for_kinematics(
    spec: mujoco.MjSpec, missing: list[_Asset]
) -> tuple[tuple[str, ...], list[mujoco.MjsGeom]]:
    """Remove the missing assets and every reference to them.

    Returns:
        The note's parts (what was stripped, per kind), and the geoms made tiny spheres that
        counted towards their body's inertia.
    """
    meshes, hfields, skins, textures = (
        [a for a in missing if isinstance(a, kind)]
        for kind in (mujoco.MjsMesh, mujoco.MjsHField, mujoco.MjsSkin, mujoco.MjsTexture)
    )
    mesh_names = {a.name for a in meshes if a.name}
    hfield_names = {a.name for a in hfields if a.name}
    mesh_geoms = [g for g in spec.geoms if g.meshname in mesh_names]
    hfield_geoms = [g for g in spec.geoms if g.hfieldname in hfield_names]
    n_sites = _tiny_spheres([s for s in spec.sites if s.meshname in mesh_names])
    _tiny_spheres(mesh_geoms + hfield_geoms)
    for g in hfield_geoms:
        g.hfieldname = ""
    _unlink_textures(spec, {a.name for a in textures if a.name})
    for asset in missing:
        spec.delete(asset)
    _floor_inertia(spec)
    parts = [
        (meshes, "missing mesh file", _spheres_note(len(mesh_geoms), n_sites)),
        (hfields, "missing height field file", _spheres_note(len(hfield_geoms), 0)),
        (textures, "missing texture file", ""),
        (skins, "missing skin file", ""),
    ]
    note = tuple(_count(len(assets), noun) + more for assets, noun, more in parts if assets)
    return note, [g for g in mesh_geoms + hfield_geoms if _adds_inertia(g)]


def _aligned_bodies(spec: mujoco.MjSpec, model: mujoco.MjModel) -> set[int]:
    """Ids of the bodies that MuJoCo moved onto their inertial frame.

    Those with a free joint whose ``align`` is on (``"auto"``: the compiler's ``alignfree``)
    and, once static children are fused (``fusestatic``), no child bodies.
    """
    parents = set(model.body_parentid[1:].tolist())
    aligned = set()
    for joint in spec.joints:
        on = joint.align == mujoco.mjtAlignFree.mjALIGNFREE_TRUE or (
            joint.align == mujoco.mjtAlignFree.mjALIGNFREE_AUTO and joint.compiler.alignfree
        )
        body = int(model.jnt_bodyid[joint.id])
        if joint.type == mujoco.mjtJoint.mjJNT_FREE and on and body not in parents:
            aligned.add(body)
    return aligned


def _check_alignment(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel,
    weighty: list[mujoco.MjsGeom],
    xml_path: pathlib.Path,
) -> None:
    """Refuse a free body whose frame MuJoCo aligned with an inertial frame shaped by a stub.

    Raises:
        ModelError: such a body exists; its frame (and ``qpos``'s meaning) would be wrong.
    """
    aligned = _aligned_bodies(spec, model)
    for geom in weighty:
        body = geom.parent  # after compiling: the body it was fused into, if any
        if body.id in aligned:
            name = body.name or f"#{body.id}"
            raise ModelError(
                f"{xml_path.name}: free body {name!r} is aligned with its inertial frame "
                "(compiler alignfree, or freejoint align), which depends on missing asset files, "
                "so its pose cannot be reproduced; restore the missing files"
            )


def load_model(source: str | os.PathLike[str]) -> LoadedModel:
    """Resolve ``source`` and compile it with MuJoCo, kinematics-only if assets are missing.

    Args:
        source: a Menagerie robot name (``"universal_robots_ur5e"``) or a path to an MJCF or
            URDF file. A URDF is compiled with ``fusestatic`` off, so that every link stays a
            body (poekin reads URDF itself with :func:`poekin.import_urdf.tree_from_urdf`;
            this compile is the reference it is verified against).

    Warns:
        AssetsStrippedWarning: asset files were missing; the one-line message says what was
            stripped. The poses are those of the complete model.

    Raises:
        ModelError (or a subclass): the model cannot be found, parsed or compiled, an included
            or sub-model file is missing, or missing files shaped a free body's aligned frame.
    """
    xml_path, robot = resolve_source(source)
    xml = _model_xml(xml_path)
    try:
        spec = mujoco.MjSpec.from_file(str(xml_path))
    except Exception as e:  # MuJoCo raises ValueError for XML errors, but be robust
        raise ModelError(f"cannot read {xml_path}: {_first_line(e)}") from e
    if xml_path.suffix.lower() == ".urdf":
        spec.compiler.fusestatic = False  # keep fixed-joint links as bodies: they are frames
        _floor_inertia(spec)  # URDF links often have no <inertial>
    found, missing = _scan_assets(spec, xml)
    files = tuple(sorted({p.resolve() for p in [*xml.files, *found]}))
    stripped, weighty = _strip_for_kinematics(spec, missing) if missing else ((), [])
    try:
        model = spec.compile()
    except Exception as e:
        raise ModelError(f"MuJoCo rejected {xml_path}: {_first_line(e)}") from e
    _check_alignment(spec, model, weighty, xml_path)
    if stripped:
        warnings.warn(
            f"{xml_path.name}: loaded for kinematics only, stripped {'; '.join(stripped)}",
            AssetsStrippedWarning,
            stacklevel=2,
        )
    return LoadedModel(model, robot, xml_path.stem, xml_path, files, stripped)
