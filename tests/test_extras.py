"""Optional features: the install hint is true for how poekin was installed."""

from __future__ import annotations

import json
import sys
from importlib import metadata

import pytest

from poekin import _extras
from poekin.errors import MissingExtraError, PoekinError

REQUIRES = [
    "numpy>=2",
    'yourdfpy>=0.0.56; extra == "urdf"',
    "viser >=1.1 ; extra == 'view'",
    'trimesh>=4.0; extra == "view"',
    'pyyaml>=6; extra == "dev"',
]


class _Dist:
    def __init__(self, direct_url: dict[str, object] | None) -> None:
        self.text = None if direct_url is None else json.dumps(direct_url)
        self.requires = REQUIRES

    def read_text(self, name: str) -> str | None:
        assert name == "direct_url.json"
        return self.text


@pytest.mark.parametrize(
    ("direct_url", "expected"),
    [
        ({"url": "file:///home/me/poe%20kin", "dir_info": {"editable": True}},
         'pip install -e "/home/me/poe kin[urdf]"'),
        # README's install (a wheel built from a checkout), a folder, a URL: no index has poekin
        ({"url": "file:///tmp/dist/poekin-0.1.0-cp311-cp311-linux_x86_64.whl",
          "archive_info": {}}, 'pip install "yourdfpy>=0.0.56"'),
        ({"url": "file:///home/me/poekin", "dir_info": {}}, 'pip install "yourdfpy>=0.0.56"'),
        ({"url": "https://example.org/poekin.whl", "archive_info": {}},
         'pip install "yourdfpy>=0.0.56"'),
        (None, 'pip install "poekin[urdf]"'),  # from an index
    ],
)  # fmt: skip
def test_install_command(
    direct_url: dict[str, object] | None, expected: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(metadata, "distribution", lambda name: _Dist(direct_url))
    _extras._installed_from.cache_clear()
    try:
        assert _extras.install_command("urdf") == expected
        if direct_url is not None and "editable" not in str(direct_url):
            view = 'pip install "viser>=1.1" "trimesh>=4.0"'
            assert _extras.install_command("view") == view
            # metadata without the extra (an old wheel): the extra's name is all there is
            assert _extras.install_command("nosuch") == 'pip install "poekin[nosuch]"'
    finally:
        _extras._installed_from.cache_clear()


def test_not_installed_at_all(monkeypatch: pytest.MonkeyPatch) -> None:
    def missing(name: str) -> None:
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(metadata, "distribution", missing)
    _extras._installed_from.cache_clear()
    try:
        assert _extras.install_command("view") == 'pip install "poekin[view]"'
    finally:
        _extras._installed_from.cache_clear()


def test_require(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _extras.require("json", "none", "parsing") is json
    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # makes the import fail
    with pytest.raises(MissingExtraError) as info:
        _extras.require("yourdfpy", "urdf", "reading arm.urdf", instead="or use MJCF")
    assert isinstance(info.value, PoekinError) and isinstance(info.value, ImportError)
    assert str(info.value) == (
        "reading arm.urdf needs yourdfpy, which is not installed: "
        f"{_extras.install_command('urdf')} (or use MJCF)"
    )


def test_require_installed_does_not_import(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, "csv", raising=False)
    _extras.require_installed("csv", "none", "writing")
    assert "csv" not in sys.modules
    with pytest.raises(MissingExtraError, match=r"'poekin view' needs no_such_module_xyz, which"):
        _extras.require_installed("no_such_module_xyz", "view", "'poekin view'")
