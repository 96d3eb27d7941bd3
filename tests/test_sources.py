"""Resolving sources and kinematics-only loading of model folders with missing assets."""

from __future__ import annotations

import hashlib
import os
import pathlib
import shutil
import warnings

import mujoco
import numpy as np
import pytest
from helpers import assert_close, load_quiet

from poekin import (
    AssetsStrippedWarning,
    MenagerieUnavailableError,
    ModelError,
    UnknownRobotError,
    load_model,
)

MENAGERIE = pathlib.Path(os.environ["MENAGERIE_ROOT"])
UR5E_DIR = MENAGERIE / "universal_robots_ur5e"


def _digest(folder: pathlib.Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_menagerie_name_and_path_give_the_same_model() -> None:
    by_name = load_model("universal_robots_ur5e")
    by_path = load_model(UR5E_DIR / "ur5e.xml")
    assert by_name.xml_path == by_path.xml_path
    assert by_name.robot == "universal_robots_ur5e"
    assert by_path.robot == "ur5e.xml"
    assert by_name.short_name == "ur5e"
    assert by_name.stripped == ()
    assert len(by_name.files) == 21  # ur5e.xml and its 20 meshes


def test_complete_model_loads_without_a_note() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_model("universal_robots_ur5e")


def test_stripped_model_has_the_same_frames(tmp_path: pathlib.Path) -> None:
    """The UR5e XML without its meshes: same body and site poses as the complete model."""
    shutil.copy(UR5E_DIR / "ur5e.xml", tmp_path)
    with pytest.warns(AssetsStrippedWarning, match=r"ur5e.xml.*20 missing mesh files") as rec:
        bare = load_model(tmp_path / "ur5e.xml")
    assert len(rec) == 1
    full = load_model("universal_robots_ur5e").model
    d_full, d_bare = mujoco.MjData(full), mujoco.MjData(bare.model)
    rng = np.random.default_rng(0)
    for _ in range(50):
        d_full.qpos[:] = d_bare.qpos[:] = rng.uniform(-6, 6, size=full.nq)
        mujoco.mj_kinematics(full, d_full)
        mujoco.mj_kinematics(bare.model, d_bare)
        assert_close("xpos", d_bare.xpos, d_full.xpos, 0.0)
        assert_close("xmat", d_bare.xmat, d_full.xmat, 0.0)
        assert_close("site_xpos", d_bare.site_xpos, d_full.site_xpos, 0.0)
        assert_close("site_xmat", d_bare.site_xmat, d_full.site_xmat, 0.0)


@pytest.mark.parametrize(
    "robot",
    [
        "franka_emika_panda",
        "franka_fr3",
        "universal_robots_ur10e",
        "ufactory_lite6",
        "rethink_robotics_sawyer",
        "trs_so_arm100",
        "unitree_go2",
        "aloha",
    ],
)
def test_xml_only_menagerie_models_load_and_stay_untouched(robot: str) -> None:
    before = _digest(MENAGERIE / robot)
    with pytest.warns(AssetsStrippedWarning, match="kinematics only"):
        loaded = load_model(robot)
    assert loaded.stripped
    assert loaded.model.njnt > 0
    assert _digest(MENAGERIE / robot) == before


def test_included_files_are_part_of_the_model_files() -> None:
    names = {p.name for p in load_quiet("aloha").files}
    assert {"aloha.xml", "joint_position_actuators.xml", "keyframe_ctrl.xml"} <= names


def test_missing_texture_is_stripped(tmp_path: pathlib.Path) -> None:
    (tmp_path / "m.xml").write_text(
        """<mujoco><asset><texture name="t" type="2d" file="gone.png"/>
        <material name="m" texture="t"/></asset><worldbody><body>
        <joint axis="0 0 1"/><geom size=".1" material="m"/><site name="s"/></body>
        </worldbody></mujoco>"""
    )
    with pytest.warns(AssetsStrippedWarning, match="1 missing texture"):
        loaded = load_model(tmp_path / "m.xml")
    assert loaded.model.ntex == 0


def test_unknown_robot_suggests_near_miss() -> None:
    with pytest.raises(UnknownRobotError, match="did you mean 'universal_robots_ur5e'"):
        load_model("universal_robots_ur5")


def test_missing_file() -> None:
    with pytest.raises(ModelError, match=r"model file not found: nowhere/robot.xml"):
        load_model("nowhere/robot.xml")


def test_directory_instead_of_file() -> None:
    with pytest.raises(ModelError, match=r"is a directory.*ur5e.xml"):
        load_model(UR5E_DIR)


def test_malformed_xml(tmp_path: pathlib.Path) -> None:
    (tmp_path / "bad.xml").write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(ModelError, match=r"cannot read .*bad\.xml"):
        load_model(tmp_path / "bad.xml")


def test_xml_that_mujoco_rejects(tmp_path: pathlib.Path) -> None:
    (tmp_path / "rejected.xml").write_text(
        '<mujoco><worldbody><body><joint type="hinge" range="1 -1" limited="true"/>'
        '<geom size=".1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(ModelError, match=r"rejected\.xml"):
        load_model(tmp_path / "rejected.xml")


def test_robot_missing_under_menagerie_root(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MENAGERIE_ROOT", str(tmp_path))
    with pytest.raises(MenagerieUnavailableError, match=r"MENAGERIE_ROOT=.*set MENAGERIE_ROOT"):
        load_model("unitree_go2")


def test_download_that_cannot_happen(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No local clone and no reachable archive: one clear error naming the fix."""
    monkeypatch.delenv("MENAGERIE_ROOT")
    monkeypatch.setenv("MENAGERIE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MENAGERIE_BASE_URL", (tmp_path / "no-archives").as_uri())
    with pytest.raises(MenagerieUnavailableError, match="set MENAGERIE_ROOT to a local"):
        load_model("universal_robots_ur5e")
