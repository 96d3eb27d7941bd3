"""Optional features and the pip command that adds each, as true for how poekin was installed.

An install from a checkout (``pip install -e .``) gets ``pip install -e "/path/to/checkout[urdf]"``;
one from a wheel, an sdist or a folder (README's install, which no index can repeat) gets the
extra's own packages, ``pip install "yourdfpy>=0.0.56"``; one from an index gets
``pip install "poekin[urdf]"``.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import json
import re
import sys
from importlib import metadata
from types import ModuleType
from urllib.parse import unquote, urlparse

from poekin.errors import MissingExtraError

VIEW_MODULES = ("viser", "trimesh")  # what the extra ``view`` installs and the viewer imports

__all__ = [
    "VIEW_MODULES",
    "install_command",
    "missing_extra",
    "require",
    "require_installed",
    "require_view",
]


@functools.cache
def _installed_from() -> tuple[str | None, tuple[str, ...]]:
    """How poekin was installed: the checkout of ``pip install -e`` (else None), and, for an
    install from a file, a folder or a URL (no index can install it again), its requirements."""
    try:
        dist = metadata.distribution("poekin")
    except metadata.PackageNotFoundError:
        return None, ()
    text = dist.read_text("direct_url.json")
    if not text:
        return None, ()  # from an index
    info = json.loads(text)
    url = urlparse(str(info.get("url", "")))
    if url.scheme == "file" and info.get("dir_info", {}).get("editable"):
        return unquote(url.path), ()
    return None, tuple(dist.requires or ())


def _extra_requirements(requires: tuple[str, ...], extra: str) -> list[str]:
    """The requirements of ``extra`` in package metadata (``'viser>=1.1; extra == "view"'``)."""
    marker = re.compile(rf"""\bextra\s*==\s*["']{re.escape(extra)}["']""")
    return [r.split(";")[0].replace(" ", "") for r in requires if marker.search(r)]


def install_command(extra: str) -> str:
    """``pip install ...`` that adds the extra ``extra`` to this installation of poekin."""
    checkout, requires = _installed_from()
    if checkout is not None:
        return f'pip install -e "{checkout}[{extra}]"'
    packages = _extra_requirements(requires, extra)
    if packages:
        return "pip install " + " ".join(f'"{p}"' for p in packages)
    return f'pip install "poekin[{extra}]"'


def require(
    module: str, extra: str, purpose: str, *, package: str | None = None, instead: str = ""
) -> ModuleType:
    """Import ``module``, or raise :class:`MissingExtraError`: ``purpose`` (e.g. ``"reading
    robot.urdf"``) needs ``package`` (default: the module's name), the command that installs it,
    and what to do ``instead`` if anything."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise missing_extra(package or module.split(".")[0], extra, purpose, instead) from e


def missing_extra(package: str, extra: str, purpose: str, instead: str = "") -> MissingExtraError:
    """The error :func:`require` raises: ``purpose`` needs ``package``, the command that installs
    the extra ``extra``, and what to do ``instead`` if anything."""
    other = f" ({instead})" if instead else ""
    return MissingExtraError(
        f"{purpose} needs {package}, which is not installed: {install_command(extra)}{other}"
    )


def require_installed(module: str, extra: str, purpose: str) -> None:
    """Raise :class:`MissingExtraError` as :func:`require` does if ``module`` is not installed,
    without importing it (it may be slow to import, and not needed yet)."""
    if module in sys.modules:  # imported, or blocked with None
        installed = sys.modules[module] is not None
    else:
        installed = importlib.util.find_spec(module) is not None
    if not installed:
        raise missing_extra(module, extra, purpose)


def require_view(purpose: str) -> None:
    """Raise :class:`MissingExtraError` unless every module of the extra ``view`` is installed
    (``purpose``: ``"'poekin view'"``, ``"poekin.view"``), without importing them."""
    for module in VIEW_MODULES:
        require_installed(module, "view", purpose)
