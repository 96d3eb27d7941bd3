"""Finding and compiling models: Menagerie names, MJCF paths, and kinematics-only loading.

This is the only module that reads model files. A model folder whose mesh or texture files are
absent (as in a partial Menagerie clone) still compiles: poekin swaps each missing mesh geom for
a tiny sphere, drops the missing assets, and says so once (an :class:`AssetsStrippedWarning`).
Body and site frames, joint axes and anchors, and hence every pose, are unchanged by this; only
collision, rendering and inertia differ.
"""

from __future__ import annotations

import dataclasses
import os
import pathlib
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator

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
# Stand-in radius for a geom whose mesh is missing, and mass/inertia floors so that bodies whose
# only geometry was a massless visual mesh still compile. Neither changes any frame pose.
_STUB_RADIUS = 1e-3
_MIN_MASS = 1e-6
_MIN_INERTIA = 1e-12


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


def _asset_path(spec: mujoco.MjSpec, directory: str, file: str) -> pathlib.Path:
    base = pathlib.Path(spec.modelfiledir or ".")
    return base / directory / file


def _asset_files(
    spec: mujoco.MjSpec,
) -> Iterator[tuple[mujoco.MjsMesh | mujoco.MjsTexture, pathlib.Path]]:
    """Every file-backed mesh and texture with each file it reads (a cube texture has six)."""
    for m in spec.meshes:
        if m.file:
            yield m, _asset_path(spec, spec.meshdir, m.file)
    for t in spec.textures:
        for f in [t.file, *getattr(t, "cubefiles", [])]:
            if f:
                yield t, _asset_path(spec, spec.texturedir, f)


def _missing_assets(spec: mujoco.MjSpec) -> tuple[list[mujoco.MjsMesh], list[mujoco.MjsTexture]]:
    missing: dict[int, mujoco.MjsMesh | mujoco.MjsTexture] = {}
    for asset, path in _asset_files(spec):
        if not path.is_file():
            missing.setdefault(id(asset), asset)
    meshes = [a for a in missing.values() if isinstance(a, mujoco.MjsMesh)]
    textures = [a for a in missing.values() if isinstance(a, mujoco.MjsTexture)]
    return meshes, textures


def _strip_for_kinematics(
    spec: mujoco.MjSpec, meshes: list[mujoco.MjsMesh], textures: list[mujoco.MjsTexture]
) -> tuple[str, ...]:
    mesh_names = {m.name for m in meshes}
    texture_names = {t.name for t in textures}
    n_geoms = 0
    for g in spec.geoms:
        if g.meshname in mesh_names:
            if g.type == mujoco.mjtGeom.mjGEOM_MESH:
                g.type = mujoco.mjtGeom.mjGEOM_SPHERE
                g.size = [_STUB_RADIUS, 0.0, 0.0]
            elif not g.size.any():
                g.size = [_STUB_RADIUS] * 3
            g.meshname = ""
            n_geoms += 1
    for mat in spec.materials:
        mat.textures = ["" if t in texture_names else t for t in mat.textures]
    for asset in [*meshes, *textures]:
        spec.delete(asset)
    spec.compiler.boundmass = max(spec.compiler.boundmass, _MIN_MASS)
    spec.compiler.boundinertia = max(spec.compiler.boundinertia, _MIN_INERTIA)
    stripped = []
    if meshes:
        stripped.append(f"{len(meshes)} missing mesh files ({n_geoms} geoms made tiny spheres)")
    if textures:
        stripped.append(f"{len(textures)} missing texture files")
    return tuple(stripped)


def _included_xml(xml_path: pathlib.Path) -> Iterator[pathlib.Path]:
    """The XML files pulled in by ``<include file=...>``, recursively (best effort)."""
    seen: set[pathlib.Path] = set()
    stack = [xml_path]
    while stack:
        path = stack.pop()
        try:
            root = ET.parse(path).getroot()
        except (ET.ParseError, OSError):
            continue
        for inc in root.iter("include"):
            child = (xml_path.parent / inc.get("file", "")).resolve()
            if child.is_file() and child not in seen:
                seen.add(child)
                stack.append(child)
                yield child


def _model_files(spec: mujoco.MjSpec, xml_path: pathlib.Path) -> tuple[pathlib.Path, ...]:
    files = {xml_path, *_included_xml(xml_path), *(path for _, path in _asset_files(spec))}
    return tuple(sorted(p.resolve() for p in files if p.is_file()))


def load_model(source: str | os.PathLike[str]) -> LoadedModel:
    """Resolve ``source`` and compile it with MuJoCo, kinematics-only if assets are missing.

    Args:
        source: a Menagerie robot name (``"universal_robots_ur5e"``) or a path to an MJCF file.

    Raises:
        ModelError (or a subclass): the model cannot be found, parsed or compiled.
    """
    xml_path, robot = resolve_source(source)
    try:
        spec = mujoco.MjSpec.from_file(str(xml_path))
    except Exception as e:  # MuJoCo raises ValueError for XML errors, but be robust
        raise ModelError(f"cannot read {xml_path}: {_first_line(e)}") from e
    files = _model_files(spec, xml_path)
    meshes, textures = _missing_assets(spec)
    stripped: tuple[str, ...] = ()
    if meshes or textures:
        stripped = _strip_for_kinematics(spec, meshes, textures)
        warnings.warn(
            f"{xml_path.name}: loaded for kinematics only, stripped {'; '.join(stripped)}",
            AssetsStrippedWarning,
            stacklevel=2,
        )
    try:
        model = spec.compile()
    except Exception as e:
        raise ModelError(f"MuJoCo rejected {xml_path}: {_first_line(e)}") from e
    return LoadedModel(model, robot, xml_path.stem, xml_path, files, stripped)
