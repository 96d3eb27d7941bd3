"""Optional features and the pip command that adds each, as true for how poekin was installed.

An install from a checkout (``pip install -e .``) gets ``pip install -e "/path/to/checkout[urdf]"``;
an install from an index or a wheel gets ``pip install "poekin[urdf]"``.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import json
import sys
from importlib import metadata
from types import ModuleType
from urllib.parse import unquote, urlparse

from poekin.errors import MissingExtraError

__all__ = ["install_command", "require", "require_installed"]


@functools.cache
def _source_checkout() -> str | None:
    """The folder poekin was installed from with ``pip install -e``, else None."""
    try:
        text = metadata.distribution("poekin").read_text("direct_url.json")
    except metadata.PackageNotFoundError:
        return None
    if not text:
        return None
    info = json.loads(text)
    url = urlparse(str(info.get("url", "")))
    if url.scheme != "file" or not info.get("dir_info", {}).get("editable"):
        return None
    return unquote(url.path)


def install_command(extra: str) -> str:
    """``pip install ...`` that adds the extra ``extra`` to this installation of poekin."""
    checkout = _source_checkout()
    if checkout is not None:
        return f'pip install -e "{checkout}[{extra}]"'
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
        name = package or module.split(".")[0]
        other = f" ({instead})" if instead else ""
        raise MissingExtraError(
            f"{purpose} needs {name}, which is not installed: {install_command(extra)}{other}"
        ) from e


def require_installed(module: str, extra: str, purpose: str) -> None:
    """Raise :class:`MissingExtraError` as :func:`require` does if ``module`` is not installed,
    without importing it (it may be slow to import, and not needed yet)."""
    if module in sys.modules:  # imported, or blocked with None
        installed = sys.modules[module] is not None
    else:
        installed = importlib.util.find_spec(module) is not None
    if not installed:
        raise MissingExtraError(
            f"{purpose} needs {module}, which is not installed: {install_command(extra)}"
        )
