"""The package as installed: its data files, its entry points, and the main job with no setup.

CI runs this module a second time against the wheel installed in a fresh virtual environment,
with ``POEKIN_EXPECT_INSTALLED=1``: then poekin must not come from this checkout's ``src``.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
from importlib import metadata, resources
from urllib.parse import unquote, urlparse

import pytest

import poekin
from poekin import _extras

REPO = pathlib.Path(__file__).resolve().parents[1]


def _offline_env(tmp_path: pathlib.Path) -> dict[str, str]:
    """No MENAGERIE_ROOT, an empty download cache, and an address nothing answers at: a
    download attempt would fail with exit 2."""
    env = {k: v for k, v in os.environ.items() if k != "MENAGERIE_ROOT"}
    env["MENAGERIE_CACHE_DIR"] = str(tmp_path / "cache")
    env["MENAGERIE_BASE_URL"] = (tmp_path / "nothing-here").as_uri()
    return env


def test_where_poekin_comes_from() -> None:
    installed = not pathlib.Path(poekin.__file__).is_relative_to(REPO / "src")
    if os.environ.get("POEKIN_EXPECT_INSTALLED") == "1":
        assert installed, f"poekin was imported from {poekin.__file__}, not the installed wheel"
    assert metadata.version("poekin") == poekin.__version__


def test_the_builtin_robots_and_the_licenses_are_installed() -> None:
    """Every built-in robot's model files and its own license are in the package, and each
    license is among the distribution's license files; poekin's own license too."""
    from poekin.io.sources import BUILTIN_ROBOTS

    assert len(BUILTIN_ROBOTS) == 10
    data = resources.files("poekin") / "data"
    assert (
        (data / "universal_robots_ur5e" / "ur5e.xml")
        .read_text()
        .startswith('<mujoco model="ur5e">')
    )
    assert "ROS Industrial Consortium" in (data / "universal_robots_ur5e" / "LICENSE").read_text()
    assert "Trossen Robotics" in (data / "aloha" / "LICENSE").read_text()
    assert "Apache License" in (data / "franka_fr3" / "LICENSE").read_text()
    assert "franka_fr3/fr3.xml" in (data / "SOURCE.md").read_text()  # where each file is from
    assert (data / "aloha" / "keyframe_ctrl.xml").is_file()  # an included file
    assert (resources.files("poekin") / "py.typed").is_file()
    licenses = [str(f) for f in metadata.files("poekin") or [] if "licenses/" in str(f)]
    assert any(f.endswith("licenses/LICENSE") for f in licenses), licenses
    for robot, xml in BUILTIN_ROBOTS.items():
        assert (data / robot / xml).read_text().startswith("<mujoco"), robot
        names = [f.name for f in (data / robot).iterdir() if f.name.startswith("LICENSE")]
        assert len(names) == 1, robot
        if os.environ.get("POEKIN_EXPECT_INSTALLED") == "1":  # the wheel lists each one
            assert any(f.endswith(f"data/{robot}/{names[0]}") for f in licenses), robot


def test_a_builtin_robot_loads_offline(tmp_path: pathlib.Path) -> None:
    """Not only the UR5e: the docs' FR3 example works with no network (issue #26)."""
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "poekin",
            "ik",
            "franka_fr3",
            "--pose",
            *["0.5", "0", "0.4", "0", "1", "0", "0"],
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=tmp_path,
        env=_offline_env(tmp_path),
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert "SOLVED" in proc.stdout
    assert not (tmp_path / "cache").exists()  # nothing was fetched


def test_verify_runs_offline_on_the_builtin_ur5e(tmp_path: pathlib.Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "poekin", "verify", "--samples", "200"],
        capture_output=True,
        text=True,
        check=False,
        cwd=tmp_path,
        env=_offline_env(tmp_path),
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # no note: the built-in copy has no meshes by design
    lines = proc.stdout.splitlines()
    assert lines[1] == (
        "model: poekin's built-in copy of Menagerie's universal_robots_ur5e (XML only; set "
        "MENAGERIE_ROOT to use your own clone)"
    )
    assert lines[-1] == "PASS: tolerances 1e-05 m, 0.0001 rad"
    assert not (tmp_path / "cache").exists()  # nothing was fetched


def test_a_users_menagerie_root_wins(tmp_path: pathlib.Path) -> None:
    clone = tmp_path / "clone" / "universal_robots_ur5e"
    clone.mkdir(parents=True)
    builtin = resources.files("poekin") / "data" / "universal_robots_ur5e" / "ur5e.xml"
    (clone / "ur5e.xml").write_text(builtin.read_text())
    env = {**_offline_env(tmp_path), "MENAGERIE_ROOT": str(tmp_path / "clone")}
    proc = subprocess.run(
        [sys.executable, "-m", "poekin", "verify", "--samples", "20", "--json"],
        capture_output=True,
        text=True,
        check=False,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr
    assert f'"model_file": "{clone / "ur5e.xml"}"' in proc.stdout
    assert '"model_origin": "the Menagerie clone at MENAGERIE_ROOT"' in proc.stdout


@pytest.mark.parametrize("argv", [["poekin"], [sys.executable, "-m", "poekin"]])
def test_entry_points(argv: list[str]) -> None:
    if argv == ["poekin"]:
        script = pathlib.Path(sys.executable).parent / "poekin"
        if not script.exists():
            pytest.skip("no console script beside this interpreter")
        argv = [str(script)]
    proc = subprocess.run([*argv, "--version"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0 and proc.stdout.startswith(f"poekin {poekin.__version__} (")
    proc = subprocess.run([*argv, "fk", "--q", "1"], capture_output=True, text=True, check=False)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr


def test_a_missing_extra_names_what_installs_it() -> None:
    """Installed from a wheel (README's install, which no index repeats), the hint names the
    extra's own packages as pyproject.toml lists them; from a checkout, the checkout."""
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11

    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text())
    view = pyproject["project"]["optional-dependencies"]["view"]
    if os.environ.get("POEKIN_EXPECT_INSTALLED") == "1":
        expected = "pip install " + " ".join(f'"{r.replace(" ", "")}"' for r in view)
    else:
        # PEP 610's record of where pip installed poekin from: this checkout, unless poekin is
        # imported from here through PYTHONPATH while installed from another one (CI's
        # fresh-clone run), whose checkout the hint then rightly names
        direct_url = metadata.distribution("poekin").read_text("direct_url.json") or "{}"
        source = urlparse(json.loads(direct_url).get("url", ""))
        if source.scheme == "file" and pathlib.Path(unquote(source.path)) != REPO:
            pytest.skip(f"poekin is installed from {source.geturl()}, not from this checkout")
        expected = f'pip install -e "{REPO}[view]"'
    assert _extras.install_command("view") == expected


def test_the_installed_kernel_is_compiled() -> None:
    """A wheel whose C extension failed to build would fall back to NumPy silently."""
    if os.environ.get("POEKIN_EXPECT_INSTALLED") != "1" and not os.environ.get(
        "POEKIN_REQUIRE_COMPILED"
    ):
        pytest.skip("a checkout may be built without a compiler")
    assert poekin.compiled_kernel(), "poekin.kernel._kernel was not built into this installation"
