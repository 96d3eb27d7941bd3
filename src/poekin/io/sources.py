"""Finding and compiling models: Menagerie names, MJCF paths, and kinematics-only loading.

This is the only module that reads model files, and it never writes one. Models are compiled
for kinematics only: mesh, height field, skin and texture files are not read, since they cannot
move any body or site frame (body frames come from the XML; meshes only move geom frames and
shape inertia). Only when a free body that MuJoCo aligns with its inertial frame (``alignfree``)
takes that frame from mesh or height field geoms are those files read, so that its pose is
MuJoCo's. So a model folder whose asset files are absent (as in a partial Menagerie clone)
compiles too, and a complete one compiles in milliseconds instead of reading megabytes of meshes.

poekin looks for every mesh, height field, skin and texture file where MuJoCo would
(``meshdir``, ``texturedir`` and ``assetdir``, ``strippath``, absolute paths, assets declared in
``<include>`` files or in sub-models attached with ``<model file=...>``). Then it turns each
geom or site that names a mesh or height field it does not read into a tiny sphere, drops
those assets, and, only if the model does not compile so, floors body mass and inertia so that
bodies whose geometry is gone still compile. A missing texture is dropped and unlinked from
materials and lights; a texture whose files exist stays, as a one-pixel flat colour, so
materials keep their links. Body and site frames, joint axes and anchors, and hence every
pose, are unchanged by this; only collision, rendering and inertia differ. Masses and centres
of mass are the complete model's wherever the XML gives them (an explicit ``<inertial>``, as
most Menagerie robots have) or primitive geoms do; the bodies whose mass MuJoCo would compute
from a mesh or height field not read are listed in :attr:`LoadedModel.unknown_masses`, and
:func:`poekin.load_tree` leaves their masses unknown. Files that are missing are named once (an
:class:`AssetsStrippedWarning`); files that exist and were merely not read are not. One case
cannot keep its poses and is refused with a :class:`ModelError`: a free body that MuJoCo aligns
with its inertial frame when missing geometry shaped that frame. A missing ``<include>`` or
sub-model file is an error too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import pathlib
import re
import warnings
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, TypeAlias

from poekin.errors import (
    MenagerieUnavailableError,
    ModelError,
    UnknownRobotError,
    did_you_mean,
)

if TYPE_CHECKING:  # MuJoCo is imported when a model is first loaded, not with poekin
    import mujoco

    # A model element that reads a file.
    _Asset: TypeAlias = mujoco.MjsMesh | mujoco.MjsHField | mujoco.MjsSkin | mujoco.MjsTexture

__all__ = [
    "BUILTIN_ROBOTS",
    "AssetsStrippedWarning",
    "LoadedModel",
    "MuJoCoWarning",
    "Resolved",
    "kinematics_spec",
    "load_model",
    "resolve_source",
]

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


class AssetsStrippedWarning(UserWarning):
    """Asset files were missing, so the model was loaded for kinematics only."""


class MuJoCoWarning(UserWarning):
    """MuJoCo warned while reading or compiling the model (e.g. of a URDF limit it ignores)."""


@dataclasses.dataclass(frozen=True)
class LoadedModel:
    """A compiled MuJoCo model and where it came from.

    Attributes:
        model: the compiled ``mujoco.MjModel``.
        robot: the Menagerie name given, or the file name for a path.
        short_name: a short name for labels: the model file's stem (``ur5e``).
        xml_path: the MJCF file that was compiled.
        files: the model's files that exist on disk (XML, includes, assets), for hashing,
            whether or not the kinematics-only compile read them.
        stripped: what was missing and stripped, as the warning says it (empty if nothing).
        origin: where a Menagerie robot's files came from, in words (empty for a path given):
            a clone at ``MENAGERIE_ROOT``, the ``mujoco_menagerie`` download cache, or poekin's
            built-in copy.
        unknown_masses: the MuJoCo ids of the bodies whose ``body_mass`` and ``body_ipos`` may
            not be the complete model's, which :func:`poekin.load_tree` leaves unknown (NaN):
            those whose mass MuJoCo computes from mesh or height field files that were not read
            (missing, or not read without ``read_assets``), and any raised by the mass floor.
            Every other body's are the complete model's: those of an explicit ``<inertial>``
            or of primitive geoms.
    """

    model: mujoco.MjModel
    robot: str
    short_name: str
    xml_path: pathlib.Path
    files: tuple[pathlib.Path, ...]
    stripped: tuple[str, ...] = ()
    origin: str = ""
    unknown_masses: tuple[int, ...] = ()


def _looks_like_path(source: str) -> bool:
    return os.sep in source or "/" in source or "." in pathlib.PurePath(source).name


@dataclasses.dataclass(frozen=True)
class Resolved:
    """Where a source's model file is: ``path``, a ``robot`` label, its ``origin`` in words
    (empty for a file path the user gave), and whether it is poekin's ``builtin`` copy (XML only
    by design: loaded without a note of its missing meshes)."""

    path: pathlib.Path
    robot: str
    origin: str = ""
    builtin: bool = False


def _check_kind(path: pathlib.Path) -> None:
    """Refuse a file whose suffix names no model format, before MuJoCo tries to read it."""
    if path.suffix.lower() not in _MODEL_SUFFIXES:
        said = f"its suffix {path.suffix!r}" if path.suffix else "it has no suffix"
        raise ModelError(
            f"{path}: {said} is not a model format poekin reads: an MJCF file (.xml, .mjcf) or "
            "a URDF file (.urdf), any case"
        )


def resolve_source(source: str | os.PathLike[str]) -> Resolved:
    """Turn a Menagerie robot name or a model path into the model file to read.

    A path is used as it is (any case of ``.xml``, ``.mjcf``, ``.urdf``). A Menagerie name is
    resolved by ``mujoco_menagerie``: a clone at ``MENAGERIE_ROOT`` if set, else its download
    cache, downloading if needed; for the robots poekin ships (:data:`BUILTIN_ROBOTS`), its own
    copy when ``MENAGERIE_ROOT`` is not set and the cache does not hold the robot, so nothing
    is downloaded.

    Raises:
        ModelError: the path does not exist, is a directory, or names no model format.
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
        _check_kind(path)
        return Resolved(path.resolve(), path.name)
    if _looks_like_path(text):
        raise ModelError(f"model file not found: {text}; check the path")
    return _resolve_menagerie(text)


#: Menagerie robots whose model files poekin ships (XML and license, no meshes: kinematics
#: only), by name: the main model file of each, in ``poekin/data/NAME/`` (its ``SOURCE.md`` gives
#: the upstream commits and licenses).
BUILTIN_ROBOTS: dict[str, str] = {
    "aloha": "aloha.xml",
    "franka_emika_panda": "panda.xml",
    "franka_fr3": "fr3.xml",
    "rethink_robotics_sawyer": "sawyer.xml",
    "trs_so_arm100": "so_arm100.xml",
    "ufactory_lite6": "lite6.xml",
    "unitree_g1": "g1.xml",
    "unitree_go2": "go2.xml",
    "universal_robots_ur10e": "ur10e.xml",
    "universal_robots_ur5e": "ur5e.xml",
}


def _builtin(name: str) -> pathlib.Path:
    from importlib import resources

    return pathlib.Path(str(resources.files("poekin") / "data" / name / BUILTIN_ROBOTS[name]))


def _unknown_robot(name: str, names: list[str]) -> UnknownRobotError:
    """The error for a name that is not a Menagerie robot, suggesting the names that contain it
    (``ur5e``: ``universal_robots_ur5e``) or are spelled like it."""
    low = name.lower()
    containing = [n for n in names if low in n.lower()] if len(low) >= 2 else []
    if containing:
        shown = ", ".join(repr(n) for n in containing[:6])
        more = f" ({len(containing) - 6} more)" if len(containing) > 6 else ""
        return UnknownRobotError(
            f"unknown robot {name!r} (not a file, not a Menagerie name): did you mean "
            f"{shown}{more}?"
        )
    return UnknownRobotError(
        f"unknown robot {name!r} (not a file, not a Menagerie name): "
        f"{did_you_mean(name, names, listed=8)}"
    )


def _resolve_menagerie(name: str) -> Resolved:
    import mujoco_menagerie as mm

    try:
        robot = mm.get(name)
    except mm.UnknownRobotError:
        raise _unknown_robot(name, mm.names()) from None
    root = os.environ.get("MENAGERIE_ROOT")
    cache = mm.Cache()
    if not root and name in BUILTIN_ROBOTS and not cache.is_cached(robot):
        return Resolved(
            _builtin(name),
            name,
            f"poekin's built-in copy of Menagerie's {name} (XML only; set MENAGERIE_ROOT to use "
            "your own clone)",
            builtin=True,
        )
    try:
        xml = pathlib.Path(robot.xml(robot.default_model, cache))
    except mm.MenagerieError as e:
        where = f" under MENAGERIE_ROOT={root}" if root else " (no network for the download?)"
        raise MenagerieUnavailableError(
            f"Menagerie robot {name!r} is not available{where}: {_MENAGERIE_FIX}"
        ) from e
    if not xml.is_file():
        raise MenagerieUnavailableError(
            f"Menagerie robot {name!r}: {xml} is missing; {_MENAGERIE_FIX}"
        )
    origin = "the Menagerie clone at MENAGERIE_ROOT" if root else "the Menagerie download cache"
    return Resolved(xml, name, origin)


def _reason(e: Exception) -> str:
    """MuJoCo's whole message on one line (it puts the element and line number on the next)."""
    lines = [ln.strip() for ln in str(e).splitlines() if ln.strip()]
    return "; ".join(lines) if lines else type(e).__name__


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
    import xml.etree.ElementTree as ET

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
    import mujoco

    compiler = asset.compiler
    folder = compiler.texturedir if isinstance(asset, mujoco.MjsTexture) else compiler.meshdir
    if spec.strippath:
        file = re.split(r"[/\\]", file)[-1]
    bases = [pathlib.Path(spec.modelfiledir)] if compiler is spec.compiler else xml.submodel_dirs
    return [base / folder / file for base in bases]


def _scan_assets(
    spec: mujoco.MjSpec, xml: _ModelXml
) -> tuple[list[pathlib.Path], list[_Asset], list[_Asset]]:
    """The asset files that exist, the assets with a file that does not, and the others."""
    found: list[pathlib.Path] = []
    missing: dict[int, _Asset] = {}
    present: dict[int, _Asset] = {}
    for asset, file in _asset_files(spec):
        hits = [p for p in _candidates(spec, xml, asset, file) if p.is_file()]
        if hits:
            found.append(hits[0])
            present.setdefault(id(asset), asset)
        else:
            missing.setdefault(id(asset), asset)
    return found, list(missing.values()), [a for k, a in present.items() if k not in missing]


def _tiny_spheres(elements: Sequence[mujoco.MjsGeom | mujoco.MjsSite]) -> None:
    """Make geoms or sites tiny spheres that name no mesh; their frames stay as they are.

    Whatever the type: a primitive geom that names a mesh is fitted to it, so its own size means
    nothing without the mesh. A geom keeps its group, mass and density.
    """
    import mujoco

    for e in elements:
        e.type = mujoco.mjtGeom.mjGEOM_SPHERE
        e.size = [_STUB_RADIUS, 0.0, 0.0]
        e.meshname = ""


def _spheres_note(geoms: int, sites: int) -> str:
    named = [_count(n, noun) for n, noun in ((geoms, "geom"), (sites, "site")) if n]
    made = "a tiny sphere" if geoms + sites == 1 else "tiny spheres"
    return f" ({' and '.join(named)} made {made})" if named else ""


def _adds_inertia(geom: mujoco.MjsGeom) -> bool:
    """Whether ``geom`` counts towards its body's mass, centre of mass and inertia."""
    import mujoco

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


def _flat_texture(texture: mujoco.MjsTexture) -> None:
    """Make ``texture`` a one-pixel flat colour that reads no file. Its name, type, and the
    materials and lights that use it stay."""
    import mujoco

    texture.file = ""
    texture.cubefiles = [""] * 6
    texture.content_type = ""
    texture.builtin = mujoco.mjtBuiltin.mjBUILTIN_FLAT
    texture.width = texture.height = 1
    texture.gridsize = [1, 1]


def _floor_inertia(spec: mujoco.MjSpec) -> None:
    """Floor every body's mass and inertia, far below any real part's, so that a moving body
    whose geometry is gone still compiles. Each attached sub-model has its own compiler."""
    for compiler in {id(b.compiler): b.compiler for b in spec.bodies}.values():
        compiler.boundmass = max(compiler.boundmass, _MIN_MASS)
        compiler.boundinertia = max(compiler.boundinertia, _MIN_INERTIA)


@dataclasses.dataclass(frozen=True)
class _Stub:
    """A geom made a tiny sphere that counted towards its body's inertia.

    Attributes:
        geom: the geom.
        asset: ``("mesh" | "hfield", name)`` of the asset it named.
        missing: whether that asset's file is missing (else it exists but was not read).
    """

    geom: mujoco.MjsGeom
    asset: tuple[str, str]
    missing: bool


def _asset_key(asset: _Asset) -> tuple[str, str]:
    """``(kind, name)`` as in :attr:`_Stub.asset`; the kind is empty for skins and textures."""
    import mujoco

    kinds = ((mujoco.MjsMesh, "mesh"), (mujoco.MjsHField, "hfield"))
    return next((k for cls, k in kinds if isinstance(asset, cls)), ""), asset.name


def _strip_for_kinematics(
    spec: mujoco.MjSpec, missing: list[_Asset], skipped: list[_Asset]
) -> tuple[tuple[str, ...], list[_Stub], bool]:
    """Remove the ``missing`` assets, and the ``skipped`` ones whose files exist but are not to be
    read, and every reference to them; a skipped texture stays, as a flat placeholder.

    Returns:
        The note's parts (what was missing, per kind; empty if nothing was), the geoms made
        tiny spheres that counted towards their body's inertia, and whether any asset other
        than a texture was removed (then bodies may need :func:`_compile_stripped`'s floor).
    """
    import mujoco

    meshes, hfields, skins, textures = (
        [a for a in missing if isinstance(a, kind)]
        for kind in (mujoco.MjsMesh, mujoco.MjsHField, mujoco.MjsSkin, mujoco.MjsTexture)
    )
    placeholders = [a for a in skipped if isinstance(a, mujoco.MjsTexture)]
    gone = [*missing, *(a for a in skipped if not isinstance(a, mujoco.MjsTexture))]
    lost_meshes = {a.name for a in meshes if a.name}
    lost_hfields = {a.name for a in hfields if a.name}
    mesh_names = {a.name for a in gone if isinstance(a, mujoco.MjsMesh) and a.name}
    hfield_names = {a.name for a in gone if isinstance(a, mujoco.MjsHField) and a.name}
    mesh_geoms = [g for g in spec.geoms if g.meshname in mesh_names]
    hfield_geoms = [g for g in spec.geoms if g.hfieldname in hfield_names]
    mesh_sites = [s for s in spec.sites if s.meshname in mesh_names]
    n_mesh_geoms = sum(g.meshname in lost_meshes for g in mesh_geoms)
    n_mesh_sites = sum(s.meshname in lost_meshes for s in mesh_sites)
    n_hfield_geoms = sum(g.hfieldname in lost_hfields for g in hfield_geoms)
    stubs = [
        _Stub(g, ("mesh", g.meshname), g.meshname in lost_meshes)
        for g in mesh_geoms
        if _adds_inertia(g)
    ] + [
        _Stub(g, ("hfield", g.hfieldname), g.hfieldname in lost_hfields)
        for g in hfield_geoms
        if _adds_inertia(g)
    ]
    _tiny_spheres(mesh_sites)
    _tiny_spheres(mesh_geoms + hfield_geoms)
    for g in hfield_geoms:
        g.hfieldname = ""
    _unlink_textures(spec, {a.name for a in gone if isinstance(a, mujoco.MjsTexture) and a.name})
    for asset in gone:
        spec.delete(asset)
    for texture in placeholders:
        _flat_texture(texture)
    parts = [
        (meshes, "missing mesh file", _spheres_note(n_mesh_geoms, n_mesh_sites)),
        (hfields, "missing height field file", _spheres_note(n_hfield_geoms, 0)),
        (textures, "missing texture file", ""),
        (skins, "missing skin file", ""),
    ]
    note = tuple(_count(len(assets), noun) + more for assets, noun, more in parts if assets)
    return note, stubs, bool(gone)


def _aligned_bodies(spec: mujoco.MjSpec, model: mujoco.MjModel) -> set[int]:
    """Ids of the bodies that MuJoCo moved onto their inertial frame.

    Those with a free joint whose ``align`` is on (``"auto"``: the compiler's ``alignfree``)
    and, once static children are fused (``fusestatic``), no child bodies.
    """
    import mujoco

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
    stubs: list[_Stub],
    xml_path: pathlib.Path,
) -> set[tuple[str, str]]:
    """Refuse a free body whose frame MuJoCo aligned with an inertial frame shaped by a stub of
    a missing asset; return the present assets whose stubs shaped such a frame, which are to be
    read after all.

    Raises:
        ModelError: such an asset's file is missing; the body's frame (and ``qpos``'s meaning)
            cannot be reproduced.
    """
    aligned = _aligned_bodies(spec, model)
    needed = set()
    for stub in stubs:
        body = stub.geom.parent  # after compiling: the body it was fused into, if any
        if body.id not in aligned:
            continue
        if stub.missing:
            name = body.name or f"#{body.id}"
            raise ModelError(
                f"{xml_path.name}: free body {name!r} is aligned with its inertial frame "
                "(compiler alignfree, or freejoint align), which depends on missing asset files, "
                "so its pose cannot be reproduced; restore the missing files"
            )
        needed.add(stub.asset)
    return needed


def _includes(xml_path: pathlib.Path) -> dict[str, bytes]:
    """Every file that ``xml_path`` and its includes name in ``<include>``, by the name written
    there, for a model that MuJoCo reads from a string."""
    found: dict[str, bytes] = {}
    pending = [xml_path]
    while pending:
        path = pending.pop()
        for kind, name in _xml_references(path):
            if kind == "include" and name not in found:
                child = _find_xml(xml_path, path, xml_path.parent, kind, name)
                found[name] = child.read_bytes()
                pending.append(child)
    return found


def _read_spec(xml_path: pathlib.Path, free_root: str | None = None) -> mujoco.MjSpec:
    """Parse the model (no asset file is read yet); with ``free_root``, give a URDF's root body
    a free joint of that name.

    Raises:
        ModelError: the XML cannot be parsed, or ``free_root`` is given for a model that is not
            a URDF with one root link.
    """
    import mujoco

    try:
        if xml_path.suffix in (".xml", ".urdf"):
            spec = mujoco.MjSpec.from_file(str(xml_path))
        else:  # MuJoCo picks its reader by these two suffixes, in lower case only
            spec = mujoco.MjSpec.from_string(
                xml_path.read_text(encoding="utf-8"), include=_includes(xml_path)
            )
            spec.modelfiledir = str(xml_path.parent) + os.sep
    except Exception as e:  # MuJoCo raises ValueError for XML errors, but be robust
        raise ModelError(f"cannot read {xml_path}: {_reason(e)}") from e
    if xml_path.suffix.lower() == ".urdf":
        spec.compiler.fusestatic = False  # keep fixed-joint links as bodies: they are frames
        _floor_inertia(spec)  # URDF links often have no <inertial>
    if free_root is not None:
        roots = spec.worldbody.bodies
        if xml_path.suffix.lower() != ".urdf" or len(roots) != 1:
            raise ModelError(
                f"{xml_path.name}: a floating base goes on the one root link of a URDF model"
            )
        roots[0].add_freejoint(name=free_root)
    return spec


@contextlib.contextmanager
def _mujoco_warnings() -> Iterator[list[str]]:
    """Collect MuJoCo's warnings in the list given, instead of MuJoCo's default: print them and
    append them to ``MUJOCO_LOG.TXT`` in the working folder."""
    import mujoco

    said: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(said.append)
    try:
        yield said
    finally:
        mujoco.set_mju_user_warning(previous)


def _compile(spec: mujoco.MjSpec, xml_path: pathlib.Path) -> mujoco.MjModel:
    try:
        return spec.compile()
    except Exception as e:
        raise ModelError(f"MuJoCo rejected {xml_path}: {_reason(e)}") from e


def _compile_stripped(
    spec: mujoco.MjSpec, xml_path: pathlib.Path, stripped: bool
) -> tuple[mujoco.MjModel, bool]:
    """Compile a spec whose assets were ``stripped`` (or not), and say whether masses were
    floored: only where it does not compile as it is (a moving body whose stand-in spheres
    weigh too little) are body mass and inertia floored (:func:`_floor_inertia`), and the spec
    compiled again. Masses stay the model's own wherever the floor is not needed: a massless
    body keeps its zero mass, as in the complete model."""
    if stripped:
        try:
            return spec.compile(), False
        except Exception:  # the floor's compile below says why if it is not the floor
            _floor_inertia(spec)
            return _compile(spec, xml_path), True
    return _compile(spec, xml_path), False


def _unknown_masses(
    spec: mujoco.MjSpec, model: mujoco.MjModel, stubs: list[_Stub], floored: bool
) -> tuple[int, ...]:
    """Ids of the bodies whose mass and centre of mass in ``model`` may not be the complete
    model's: those whose inertia the stand-ins of unread meshes or height fields shaped; with a
    floor (``floored``), those at or under it (their own mass may have been lower); and with
    compiler ``settotalmass``, which scales every body by the total, all bodies if any."""
    bodies = {stub.geom.parent.id for stub in stubs}  # after compiling: the fused body's
    if floored:
        bodies |= {b for b in range(1, model.nbody) if model.body_mass[b] <= _MIN_MASS}
    bodies.discard(0)  # the world has no mass
    if bodies and any(b.compiler.settotalmass > 0 for b in spec.bodies):
        return tuple(range(1, model.nbody))
    return tuple(sorted(bodies))


def _kinematics(
    xml_path: pathlib.Path, free_root: str | None, read_assets: bool
) -> tuple[
    mujoco.MjSpec, mujoco.MjModel, tuple[str, ...], tuple[pathlib.Path, ...], tuple[int, ...]
]:
    """The spec as compiled for kinematics (see :func:`load_model`), the model, what was
    stripped, the model's files, and the bodies whose masses the model does not know
    (:func:`_unknown_masses`)."""
    xml = _model_xml(xml_path)
    spec = _read_spec(xml_path, free_root)
    urdf = xml_path.suffix.lower() == ".urdf"  # floored already: _read_spec
    found, missing, present = _scan_assets(spec, xml)
    files = tuple(sorted({p.resolve() for p in [*xml.files, *found]}))
    stripped, stubs, gone = _strip_for_kinematics(spec, missing, [] if read_assets else present)
    model, floored = _compile_stripped(spec, xml_path, gone)
    needed = _check_alignment(spec, model, stubs, xml_path)
    if needed:  # read those files after all: compile again, with them
        spec = _read_spec(xml_path, free_root)
        _, missing, present = _scan_assets(spec, xml)
        kept = [a for a in present if _asset_key(a) not in needed]
        _, stubs, gone = _strip_for_kinematics(spec, missing, kept)
        model, floored = _compile_stripped(spec, xml_path, gone)
    unknown = _unknown_masses(spec, model, stubs, floored or urdf)
    return spec, model, stripped, files, unknown


def kinematics_spec(source: str | os.PathLike[str]) -> mujoco.MjSpec:
    """The ``mujoco.MjSpec`` of ``source`` that :func:`load_model` compiles (asset files not
    needed for kinematics left out), to edit and compile again: e.g. a robot that differs from
    its model (:mod:`poekin.calibration.simulate`). MuJoCo's warnings are dropped; load the
    model with :func:`load_model` to see them."""
    with _mujoco_warnings():
        spec, _, _, _, _ = _kinematics(resolve_source(source).path, None, False)
    return spec


def load_model(
    source: str | os.PathLike[str], *, free_root: str | None = None, read_assets: bool = False
) -> LoadedModel:
    """Resolve ``source`` and compile it with MuJoCo for kinematics.

    Mesh, height field, skin and texture files are not read, except the meshes and height
    fields that shape the inertial frame of a free body that MuJoCo aligns with it: every body
    and site pose, joint and ``qpos0`` is MuJoCo's full compile's, bit for bit; collision
    geometry, rendering and inertia are not.

    Args:
        source: a Menagerie robot name (``"universal_robots_ur5e"``) or a path to an MJCF or
            URDF file. A URDF is compiled with ``fusestatic`` off, so that every link stays a
            body (poekin reads URDF itself with :func:`poekin.io.import_urdf.tree_from_urdf`;
            this compile is the reference it is verified against).
        free_root: URDF only: give the root link a free joint of this name before compiling,
            as :func:`poekin.load_tree` does with ``floating_base=True``, so that the two can be
            compared.
        read_assets: read every asset file that exists (for drawing: the meshes); only the
            missing ones are stripped. Poses are the same either way.

    Warns:
        AssetsStrippedWarning: asset files were missing; the one-line message says what was
            stripped. The poses are those of the complete model.
        MuJoCoWarning: MuJoCo warned while reading or compiling (each warning once), which it would
            otherwise print and append to ``MUJOCO_LOG.TXT`` in the working folder.

    Raises:
        ModelError (or a subclass): the model cannot be found, parsed or compiled, an included
            or sub-model file is missing, or missing files shaped a free body's aligned frame.
    """
    resolved = resolve_source(source)
    xml_path = resolved.path
    with _mujoco_warnings() as said:
        _, model, stripped, files, unknown = _kinematics(xml_path, free_root, read_assets)
    for message in dict.fromkeys(said):
        warnings.warn(f"{xml_path.name}: MuJoCo: {message}", MuJoCoWarning, stacklevel=2)
    if stripped and not resolved.builtin:  # the built-in copy has no meshes by design, and says so
        warnings.warn(
            f"{xml_path.name}: loaded for kinematics only, stripped {'; '.join(stripped)}",
            AssetsStrippedWarning,
            stacklevel=2,
        )
    return LoadedModel(
        model, resolved.robot, xml_path.stem, xml_path, files, stripped, resolved.origin, unknown
    )
