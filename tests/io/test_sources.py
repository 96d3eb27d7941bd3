"""Resolving sources and kinematics-only loading of model folders with missing assets."""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import re
import shutil
import struct
import subprocess
import sys
import warnings
import zlib
from collections.abc import Sequence

import mujoco
import numpy as np
import pytest
from helpers import MJ_TOL, assert_close, load_quiet, mesh_menagerie

import poekin
from poekin import (
    AssetsStrippedWarning,
    LoadedModel,
    MenagerieUnavailableError,
    ModelError,
    MuJoCoWarning,
    UnknownRobotError,
    load_model,
)
from poekin.io.sources import BUILTIN_ROBOTS

MENAGERIE = pathlib.Path(os.environ["MENAGERIE_ROOT"])  # poekin's built-in copies: XML only
UR5E_DIR = MENAGERIE / "universal_robots_ur5e"


@pytest.fixture
def complete_ur5e(monkeypatch: pytest.MonkeyPatch) -> pathlib.Path:
    """The UR5e folder of a Menagerie clone with its meshes, which MENAGERIE_ROOT then names."""
    root = mesh_menagerie()
    monkeypatch.setenv("MENAGERIE_ROOT", str(root))
    return root / "universal_robots_ur5e"


def _digest(folder: pathlib.Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_the_builtin_models_are_the_upstream_files_their_source_lists() -> None:
    """Every file of poekin's built-in robots (src/poekin/data, which the tests read as
    MENAGERIE_ROOT) is in its SOURCE.md with its size and sha256 (an unmodified upstream copy),
    every file listed is there, and none is a mesh; each robot folder is in BUILTIN_ROBOTS with
    its main model file, and holds its license."""
    data = pathlib.Path(poekin.__file__).parent / "data"
    assert data == MENAGERIE
    table = re.findall(
        r"^\| (\S+) \| (\d+) \| ([0-9a-f]{64}) \| .+ \|$",
        (MENAGERIE / "SOURCE.md").read_text(),
        re.M,
    )
    listed = {path: (int(size), sha) for path, size, sha in table}
    files = {
        p.relative_to(MENAGERIE).as_posix(): p.read_bytes()
        for p in MENAGERIE.rglob("*")
        if p.is_file() and p.name != "SOURCE.md"
    }
    assert sorted(listed) == sorted(files)
    for path, content in files.items():
        assert (len(content), hashlib.sha256(content).hexdigest()) == listed[path], path
        assert path.endswith((".xml", "/LICENSE", "/LICENSE.md")), path
    folders = sorted(p.name for p in MENAGERIE.iterdir() if p.is_dir())
    assert folders == sorted(BUILTIN_ROBOTS)
    for robot, xml in BUILTIN_ROBOTS.items():
        assert (MENAGERIE / robot / xml).is_file(), robot
        assert list((MENAGERIE / robot).glob("LICENSE*")), f"{robot} has no license file"


# The robots poekin ships: those the docs' examples load (the FR3, SO-100, ALOHA, go2, ...).
SHIPPED = [
    "aloha",
    "franka_emika_panda",
    "franka_fr3",
    "rethink_robotics_sawyer",
    "trs_so_arm100",
    "ufactory_lite6",
    "unitree_g1",
    "unitree_go2",
    "universal_robots_ur10e",
    "universal_robots_ur5e",
]

# Runs in a fresh interpreter on a fresh machine (no MENAGERIE_ROOT, an empty download cache,
# nowhere to download from): each robot named on its command line, how long its load took, where
# it came from, any warning, and the largest gap between poekin's FK of every body and site and
# mj_forward's, on random configurations within the limits.
_OFFLINE_BUILTINS = """
import json, sys, time, warnings
import mujoco, numpy as np, poekin
out = {}
for robot in sys.argv[1:]:
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        loaded = poekin.load_model(robot)
        tree = poekin.load_tree(loaded)
    seconds = time.perf_counter() - start
    model, data = loaded.model, mujoco.MjData(loaded.model)
    qpos = poekin.sample_qpos(tree, 20, seed=1, within_limits=True)
    got = tree.fk(qpos)
    gap, nb = 0.0, model.nbody - 1
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        rot = np.concatenate([data.xmat[1:].reshape(-1, 3, 3), data.site_xmat.reshape(-1, 3, 3)])
        pos = np.concatenate([data.xpos[1:], data.site_xpos])
        gap = max(gap, float(np.abs(got[k, :, :3, :3] - rot).max()))
        gap = max(gap, float(np.abs(got[k, :, :3, 3] - pos).max()))
    out[robot] = {
        "seconds": seconds,
        "origin": loaded.origin,
        "xml": str(loaded.xml_path),
        "frames": tree.n_frames,
        "expected_frames": nb + model.nsite,
        "gap": gap,
        "warnings": [str(w.message) for w in said],
    }
json.dump(out, sys.stdout)
"""


def test_builtin_robots_load_offline_at_once_and_match_mj_forward(
    fresh_machine: None, tmp_path: pathlib.Path
) -> None:
    """Issue #26: offline, every robot but the UR5e failed by name after about 8 s. Each
    built-in robot now loads by name from poekin's own copy (the origin says so), silently
    and without waiting for a network, and its FK is MuJoCo's."""
    proc = subprocess.run(
        [sys.executable, "-c", _OFFLINE_BUILTINS, *SHIPPED],
        capture_output=True,
        text=True,
        check=False,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout)
    assert sorted(found) == sorted(BUILTIN_ROBOTS) == sorted(SHIPPED)
    data = pathlib.Path(poekin.__file__).parent / "data"
    for robot, got in found.items():
        assert got["origin"].startswith(f"poekin's built-in copy of Menagerie's {robot} "), robot
        assert got["xml"] == str(data / robot / BUILTIN_ROBOTS[robot])
        assert got["warnings"] == [], robot  # the built-in copies are XML only by design
        assert got["seconds"] < 2.0, robot  # compiles in milliseconds; a download wait is 8 s
        assert got["frames"] == got["expected_frames"] > 1, robot
        assert got["gap"] < MJ_TOL, robot
    assert not (tmp_path / "menagerie-cache").exists()


def test_menagerie_name_and_path_give_the_same_model() -> None:
    by_name = load_quiet("universal_robots_ur5e")
    by_path = load_quiet(str(UR5E_DIR / "ur5e.xml"))
    assert by_name.xml_path == by_path.xml_path == UR5E_DIR / "ur5e.xml"
    assert by_name.robot == "universal_robots_ur5e"
    assert by_path.robot == "ur5e.xml"
    assert by_name.short_name == "ur5e"
    assert by_name.files == by_path.files == (UR5E_DIR / "ur5e.xml",)


def test_complete_model_loads_without_a_note(complete_ur5e: pathlib.Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded = load_model("universal_robots_ur5e")
    assert loaded.xml_path == complete_ur5e / "ur5e.xml"
    assert loaded.stripped == ()
    assert len(loaded.files) == 21  # ur5e.xml and its 20 meshes


def test_stripped_model_has_the_same_frames(
    tmp_path: pathlib.Path, complete_ur5e: pathlib.Path
) -> None:
    """The UR5e XML without its meshes: same body and site poses as the complete model."""
    shutil.copy(complete_ur5e / "ur5e.xml", tmp_path)
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


KINEMATIC_FIELDS = (
    "body_pos",
    "body_quat",
    "jnt_pos",
    "jnt_axis",
    "site_pos",
    "site_quat",
    "qpos0",
)
POSE_FIELDS = ("xpos", "xmat", "site_xpos", "site_xmat")


def _assert_bitwise_kinematics(
    ours: mujoco.MjModel, full: mujoco.MjModel, qpos: Sequence[np.ndarray]
) -> None:
    """``ours`` has ``full``'s frames and joints, and poses them bit for bit like ``full`` does
    (mj_kinematics) at every ``qpos``."""
    for kind, count in (("body", "nbody"), ("joint", "njnt"), ("site", "nsite")):
        assert getattr(ours, count) == getattr(full, count), count
        names = [[getattr(m, kind)(i).name for i in range(getattr(m, count))] for m in (ours, full)]
        assert names[0] == names[1], kind
    for field in KINEMATIC_FIELDS:
        assert np.array_equal(getattr(ours, field), getattr(full, field)), field
    d_ours, d_full = mujoco.MjData(ours), mujoco.MjData(full)
    for q in qpos:
        d_ours.qpos[:] = d_full.qpos[:] = q
        mujoco.mj_kinematics(ours, d_ours)
        mujoco.mj_kinematics(full, d_full)
        for field in POSE_FIELDS:
            assert np.array_equal(getattr(d_ours, field), getattr(d_full, field)), field


def test_ur5e_kinematics_only_compile_equals_the_full_compile_bitwise(
    complete_ur5e: pathlib.Path,
) -> None:
    """The complete UR5e folder compiles without reading its 20 meshes (about 30 MB), yet its
    frames, joints and poses are those of MuJoCo's full compile of the same file, bit for bit."""
    before = _digest(complete_ur5e)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded = load_model("universal_robots_ur5e")
    full = mujoco.MjModel.from_xml_path(str(complete_ur5e / "ur5e.xml"))
    assert loaded.xml_path == complete_ur5e / "ur5e.xml"
    assert (full.nmesh, loaded.model.nmesh) == (20, 0)  # no mesh was read
    assert len(loaded.files) == 21 and loaded.stripped == ()  # the meshes are still its files
    qpos = np.random.default_rng(0).uniform(-2 * np.pi, 2 * np.pi, size=(1000, full.nq))
    _assert_bitwise_kinematics(loaded.model, full, list(qpos))
    assert _digest(complete_ur5e) == before


@pytest.mark.parametrize(
    "robot",
    [
        "universal_robots_ur5e",
        "franka_emika_panda",
        "franka_fr3",
        "universal_robots_ur10e",
        "ufactory_lite6",
        "rethink_robotics_sawyer",
        "trs_so_arm100",
        "unitree_g1",
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


# --- Kinematics-only loading of incomplete model folders -------------------------------------
# Each case is a complete model folder, written by the test (the first file is the model), the
# asset files to delete from a copy of it, and what the one-line note must say about the copy.
# "{dir}" in a file stands for the folder's absolute path.

# A tetrahedron whose centroid and principal axes are off the body frame, so a stub changes inertia.
TET_OBJ = "v 0 0 0\nv 0.1 0 0\nv 0 0.12 0\nv 0 0 0.15\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
ARM = """<body name="arm" pos="0.1 0 0.5" euler="10 20 30"><joint axis="0 1 0" ref="0.2"/>{geoms}
  <site name="tip" pos="0.2 0.01 0"/></body>"""


def _png(width: int = 2, height: int = 2) -> bytes:
    """A tiny RGB PNG image."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    rows = b"".join(b"\0" + bytes([200, 120, 40] * width) for _ in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    pixels = chunk(b"IDAT", zlib.compress(rows))
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + pixels + chunk(b"IEND", b"")


def _hfield() -> bytes:
    """A 2 x 2 height field in MuJoCo's binary format."""
    return struct.pack("<2i4f", 2, 2, 0.0, 0.5, 1.0, 0.2)


def _skin(body: str) -> bytes:
    """A one-triangle SKN skin bound to ``body``."""
    head = struct.pack("<4i9f3i", 3, 0, 1, 1, 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0, 0, 1, 2)
    bone = body.encode().ljust(40, b"\0") + struct.pack(
        "<7fi3i3f", 0, 0, 0, 1, 0, 0, 0, 3, 0, 1, 2, 1, 1, 1
    )
    return head + bone


def _mjcf(body: str, asset: str = "", compiler: str = "", extra: str = "") -> str:
    return (
        f"<mujoco><compiler {compiler}/><asset>{asset}</asset>"
        f"<worldbody>{body}</worldbody>{extra}</mujoco>"
    )


CASES: dict[str, tuple[dict[str, str | bytes], tuple[str, ...], str]] = {
    "mesh geoms, a fitted box and a mesh site": (
        {
            "robot.xml": _mjcf(
                compiler='meshdir="assets"',
                asset='<mesh name="tet" file="tet.obj"/>'
                '<mesh name="wedge" file="wedge.obj" scale="1 2 1"/>',
                body='<geom type="mesh" mesh="wedge"/>'
                '<body name="upper" pos="0 0 0.3" euler="10 20 30"><joint type="ball"/>'
                '<geom type="mesh" mesh="tet"/><geom type="box" size="1 1 1" mesh="wedge"/>'
                '<site name="marker" type="mesh" mesh="tet" pos="0.01 0 0"/>'
                '<body name="lower" pos="0.2 0 0" quat="0.9 0.1 0.3 0.2">'
                '<joint axis="0 1 0" ref="0.3"/><joint type="slide" axis="1 0 0"/>'
                '<geom type="mesh" mesh="tet" pos="0.05 0 0"/><site name="tip" pos="0.3 0.01 0"/>'
                "</body></body>",
            ),
            "assets/tet.obj": TET_OBJ,
            "assets/wedge.obj": TET_OBJ,
        },
        ("assets/tet.obj", "assets/wedge.obj"),
        r"2 missing mesh files \(4 geoms and 1 site made tiny spheres\)$",
    ),
    "textures, cube textures, materials and a light": (
        {
            "robot.xml": _mjcf(
                compiler='texturedir="textures"',
                asset='<texture name="wood" type="2d" file="wood.png"/>'
                '<texture name="cube" type="cube" fileright="r.png" fileleft="l.png" fileup="u.png"'
                ' filedown="d.png" filefront="f.png" fileback="b.png"/>'
                '<texture name="sky" type="skybox" file="sky.png"/>'
                '<texture name="grid" type="2d" builtin="checker" width="8" height="8"/>'
                '<material name="m1" texture="wood"/><material name="m2" texture="cube"/>'
                '<material name="m3" texture="grid"/>',
                body='<light type="spot" texture="wood" pos="0 0 2"/>'
                + ARM.format(
                    geoms='<geom size="0.1" material="m1"/><geom size="0.05" material="m2"/>'
                ),
            ),
            **{f"textures/{n}.png": _png() for n in ("wood", "r", "l", "u", "d", "f", "b", "sky")},
        },
        ("textures/wood.png", "textures/u.png"),
        r"stripped 2 missing texture files$",
    ),
    "height field (meshdir)": (
        {
            "robot.xml": _mjcf(
                compiler='meshdir="terrain"',
                asset='<hfield name="ground" file="ground.bin" size="1 1 0.1 0.05"/>',
                body='<geom type="hfield" hfield="ground"/>'
                + ARM.format(geoms='<geom size="0.1"/>'),
            ),
            "terrain/ground.bin": _hfield(),
        },
        ("terrain/ground.bin",),
        r"stripped 1 missing height field file \(1 geom made a tiny sphere\)$",
    ),
    "skin (meshdir)": (
        {
            "robot.xml": _mjcf(
                compiler='meshdir="skins"',
                body=ARM.format(geoms='<geom size="0.1"/>'),
                extra='<deformable><skin name="cloth" file="cloth.skn"/></deformable>',
            ),
            "skins/cloth.skn": _skin("arm"),
        },
        ("skins/cloth.skn",),
        r"stripped 1 missing skin file$",
    ),
    "assets declared in an include, nested include": (
        {
            "robot.xml": '<mujoco><compiler meshdir="assets"/><include file="parts/assets.xml"/>'
            '<worldbody><include file="parts/arm.xml"/></worldbody></mujoco>',
            # Asset paths in an included file are relative to the main model's folder.
            "parts/assets.xml": '<mujoco><asset><mesh name="tet" file="tet.obj"/></asset></mujoco>',
            # A nested include not found next to the main model is looked up next to its includer.
            "parts/arm.xml": '<mujoco><body name="arm" pos="0 0 0.5"><joint axis="0 1 0"/>'
            '<geom type="mesh" mesh="tet"/><include file="hand.xml"/></body></mujoco>',
            "parts/hand.xml": '<mujoco><body name="hand" pos="0.1 0 0"><joint axis="1 0 0"/>'
            '<geom type="mesh" mesh="tet"/><site name="tip"/></body></mujoco>',
            "assets/tet.obj": TET_OBJ,
        },
        ("assets/tet.obj",),
        r"stripped 1 missing mesh file \(2 geoms made tiny spheres\)$",
    ),
    "assetdir with texturedir": (
        {
            "robot.xml": _mjcf(
                compiler='assetdir="shared" texturedir="pictures"',
                asset='<mesh name="tet" file="tet.obj"/><material name="m" texture="wood"/>'
                '<texture name="wood" type="2d" file="wood.png"/>',
                body=ARM.format(geoms='<geom type="mesh" mesh="tet" material="m"/>'),
            ),
            "shared/tet.obj": TET_OBJ,
            "pictures/wood.png": _png(),
        },
        ("shared/tet.obj", "pictures/wood.png"),
        r"1 missing mesh file \(1 geom made a tiny sphere\); 1 missing texture file$",
    ),
    "relative meshdir out of the model's folder": (
        {
            "model/robot.xml": _mjcf(
                compiler='meshdir="../meshes"',
                asset='<mesh name="tet" file="tet.obj"/>',
                body=ARM.format(geoms='<geom type="mesh" mesh="tet"/>'),
            ),
            "meshes/tet.obj": TET_OBJ,
        },
        ("meshes/tet.obj",),
        r"1 missing mesh file",
    ),
    "absolute meshdir": (
        {
            "robot.xml": _mjcf(
                compiler='meshdir="{dir}/meshes"',
                asset='<mesh name="tet" file="tet.obj"/>',
                body=ARM.format(geoms='<geom type="mesh" mesh="tet"/>'),
            ),
            "meshes/tet.obj": TET_OBJ,
        },
        ("meshes/tet.obj",),
        r"1 missing mesh file",
    ),
    "absolute mesh file": (
        {
            "robot.xml": _mjcf(
                compiler='meshdir="meshes"',
                asset='<mesh name="tet" file="{dir}/elsewhere/tet.obj"/>',
                body=ARM.format(geoms='<geom type="mesh" mesh="tet"/>'),
            ),
            "elsewhere/tet.obj": TET_OBJ,
        },
        ("elsewhere/tet.obj",),
        r"1 missing mesh file",
    ),
    "strippath": (
        {
            "robot.xml": _mjcf(
                compiler='strippath="true" meshdir="assets"',
                asset='<mesh name="tet" file="C:\\cad\\export/tet.obj"/>',
                body=ARM.format(geoms='<geom type="mesh" mesh="tet"/>'),
            ),
            "assets/tet.obj": TET_OBJ,
        },
        ("assets/tet.obj",),
        r"1 missing mesh file",
    ),
    "attached sub-model with its own meshdir": (
        {
            "scene.xml": _mjcf(
                asset='<model name="hand" file="hand/hand.xml"/>',
                body=ARM.format(
                    geoms='<geom size="0.05"/><attach model="hand" body="palm" prefix="h-"/>'
                ),
            ),
            "hand/hand.xml": _mjcf(
                compiler='meshdir="meshes"',
                asset='<mesh name="tet" file="tet.obj"/>',
                body='<body name="palm" pos="0.2 0 0"><joint axis="1 0 0"/>'
                '<geom type="mesh" mesh="tet" density="0.001"/><site name="s"/></body>',
            ),
            "hand/meshes/tet.obj": TET_OBJ,
        },
        ("hand/meshes/tet.obj",),
        r"1 missing mesh file \(1 geom made a tiny sphere\)$",
    ),
    # A light mesh: its tiny sphere stub would be below MuJoCo's minimum mass without a floor.
    "body left massless": (
        {
            "robot.xml": _mjcf(
                asset='<mesh name="tet" file="tet.obj"/>',
                body=ARM.format(geoms='<geom type="mesh" mesh="tet" density="0.001"/>'),
            ),
            "tet.obj": TET_OBJ,
        },
        ("tet.obj",),
        r"1 missing mesh file",
    ),
}

FREE_MESH = '<geom type="mesh" mesh="tet"/>'


def _free_body_files(compiler: str, joint: str, inside: str) -> dict[str, str | bytes]:
    """A model with one free body named obj, and its mesh."""
    site = '<site name="s" pos="0.05 0.02 0.01"/>'
    body = f'<body name="obj" pos="0.3 0.2 1" euler="10 20 30">{joint}{inside}{site}</body>'
    mesh = '<mesh name="tet" file="tet.obj"/>'
    return {"robot.xml": _mjcf(compiler=compiler, asset=mesh, body=body), "tet.obj": TET_OBJ}


# Free bodies whose frame MuJoCo would not align with a stripped geom's inertia: they load.
ALIGN_OK = {
    "explicit inertial": (
        'alignfree="true"',
        "<freejoint/>",
        FREE_MESH
        + '<inertial pos="0.01 0.02 0.03" quat="0.9 0.1 0.2 0.3" mass="1" diaginertia="1 2 3"/>',
    ),
    "geom outside inertiagrouprange": (
        'alignfree="true" inertiagrouprange="0 1"',
        "<freejoint/>",
        '<geom size="0.02" pos="0.1 0 0"/><geom type="mesh" mesh="tet" group="2"/>',
    ),
    "massless visual geom": (
        'alignfree="true"',
        "<freejoint/>",
        '<geom size="0.02" pos="0.1 0 0"/><geom type="mesh" mesh="tet" density="0"/>',
    ),
    "freejoint align false": ('alignfree="true"', '<freejoint align="false"/>', FREE_MESH),
    "alignfree off": ("", "<freejoint/>", FREE_MESH),
    "free body with a child": (
        'alignfree="true"',
        "<freejoint/>",
        FREE_MESH + '<body pos="0.1 0 0"><joint axis="0 0 1"/><geom size="0.01"/></body>',
    ),
}
CASES.update(
    {
        f"alignfree: {name}": (_free_body_files(*parts), ("tet.obj",), r"1 missing mesh file")
        for name, parts in ALIGN_OK.items()
    }
)

# Free bodies that MuJoCo aligns with an inertial frame that the missing mesh shapes: refused.
ALIGN_REFUSED = {
    "compiler alignfree": ('alignfree="true"', "<freejoint/>", FREE_MESH),
    "freejoint align": ("", '<freejoint align="true"/>', FREE_MESH),
    "fitted primitive": ('alignfree="true"', "<freejoint/>", '<geom type="box" mesh="tet"/>'),
    "static child fused into it": (
        'alignfree="true" fusestatic="true"',
        "<freejoint/>",
        '<geom size="0.02"/><body pos="0.1 0 0">' + FREE_MESH + "</body>",
    ),
}


def _write(folder: pathlib.Path, files: dict[str, str | bytes]) -> pathlib.Path:
    """Write ``files`` under ``folder``; return the first (the model)."""
    for name, content in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content.replace("{dir}", str(folder)))
    return folder / next(iter(files))


def _complete_and_bare(
    root: pathlib.Path, files: dict[str, str | bytes], removed: tuple[str, ...]
) -> tuple[pathlib.Path, pathlib.Path]:
    """The model in a complete folder, and in a copy of it without the ``removed`` files."""
    full = _write(root / "full", files)
    bare = _write(root / "bare", files)
    for name in removed:
        (root / "bare" / name).unlink()
    return full, bare


def _all_files(folder: pathlib.Path) -> set[pathlib.Path]:
    return {p.resolve() for p in folder.rglob("*") if p.is_file()}


def _random_qpos(model: mujoco.MjModel, rng: np.random.Generator) -> np.ndarray:
    """Joint values far from ``qpos0``, with unit quaternions for ball and free joints."""
    qpos = model.qpos0 + rng.uniform(-3, 3, size=model.nq)
    quat_at = {mujoco.mjtJoint.mjJNT_FREE: 3, mujoco.mjtJoint.mjJNT_BALL: 0}
    for j in range(model.njnt):
        if model.jnt_type[j] in quat_at:
            quat = rng.normal(size=4)
            adr = model.jnt_qposadr[j] + quat_at[model.jnt_type[j]]
            qpos[adr : adr + 4] = quat / np.linalg.norm(quat)
    return qpos


def _assert_same_frames(full: mujoco.MjModel, bare: mujoco.MjModel) -> None:
    """Every body and site pose of ``bare`` equals ``full``'s at ``qpos0`` and random joints."""
    names = [[m.body(i).name for i in range(m.nbody)] for m in (full, bare)]
    assert names[0] == names[1]
    assert (bare.nq, bare.nsite) == (full.nq, full.nsite) and full.nsite > 0
    assert_close("qpos0", bare.qpos0, full.qpos0, 0.0)
    d_full, d_bare = mujoco.MjData(full), mujoco.MjData(bare)
    rng = np.random.default_rng(7)
    for i in range(6):
        d_full.qpos[:] = d_bare.qpos[:] = full.qpos0 if i == 0 else _random_qpos(full, rng)
        mujoco.mj_forward(full, d_full)
        mujoco.mj_forward(bare, d_bare)
        for field in ("xpos", "xmat", "site_xpos", "site_xmat"):
            assert_close(field, getattr(d_bare, field), getattr(d_full, field), MJ_TOL)


def _load_complete(xml: pathlib.Path) -> LoadedModel:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return load_model(xml)


@pytest.mark.parametrize("case", list(CASES))
def test_incomplete_folder_keeps_every_frame(tmp_path: pathlib.Path, case: str) -> None:
    """The copy loads with one note saying what was stripped, the complete model's frames, and
    its files untouched; the complete model loads without a note. Both list exactly their files."""
    files, removed, note = CASES[case]
    full_xml, bare_xml = _complete_and_bare(tmp_path, files, removed)
    before = _digest(tmp_path)
    full = _load_complete(full_xml)
    with pytest.warns(AssetsStrippedWarning) as record:
        bare = load_model(bare_xml)
    assert len(record) == 1, [str(r.message) for r in record]
    message = str(record[0].message)
    assert "\n" not in message and message.startswith(f"{bare_xml.name}: loaded for kinematics")
    assert re.search(note, message), message
    assert set(full.files) == _all_files(tmp_path / "full")
    assert set(bare.files) == _all_files(tmp_path / "bare")
    assert _digest(tmp_path) == before
    _assert_same_frames(full.model, bare.model)


def test_stripped_textures_leave_materials(tmp_path: pathlib.Path) -> None:
    """Materials and lights stay, without the textures whose files are gone; the others stay."""
    files, removed, _ = CASES["textures, cube textures, materials and a light"]
    _, bare_xml = _complete_and_bare(tmp_path, files, removed)
    with pytest.warns(AssetsStrippedWarning):
        bare = load_model(bare_xml).model
    assert {bare.texture(i).name for i in range(bare.ntex)} == {"sky", "grid"}
    texids = {m: int(bare.mat_texid[bare.material(m).id].max()) for m in ("m1", "m2", "m3")}
    assert texids == {"m1": -1, "m2": -1, "m3": bare.texture("grid").id}
    assert bare.light_texid.tolist() == [-1]


@pytest.mark.parametrize("case", list(ALIGN_REFUSED))
def test_free_body_aligned_with_missing_inertia_is_refused(
    tmp_path: pathlib.Path, case: str
) -> None:
    """Its frame (and what its qpos means) came from the missing mesh: no pose to keep."""
    files = _free_body_files(*ALIGN_REFUSED[case])
    full_xml, bare_xml = _complete_and_bare(tmp_path, files, ("tet.obj",))
    full = _load_complete(full_xml).model
    assert not np.allclose(full.body("obj").pos, [0.3, 0.2, 1])  # MuJoCo did align it
    before = _digest(tmp_path)
    with pytest.raises(ModelError, match=r"free body 'obj' is aligned with its inertial frame"):
        load_model(bare_xml)
    assert _digest(tmp_path) == before


# Complete folders: every case above, and the free bodies whose aligned frame their mesh shapes.
COMPLETE = {name: files for name, (files, _, _) in CASES.items()} | {
    f"alignfree, mesh read: {name}": _free_body_files(*parts)
    for name, parts in ALIGN_REFUSED.items()
}


@pytest.mark.parametrize("case", list(COMPLETE))
def test_complete_folder_poses_like_the_full_compile(tmp_path: pathlib.Path, case: str) -> None:
    """With every file present, the kinematics-only compile (which reads no mesh, height field,
    skin or texture file unless an aligned free body's inertia needs it) poses every frame bit
    for bit like MuJoCo's full compile, writes nothing, and says nothing."""
    xml = _write(tmp_path, COMPLETE[case])
    before = _digest(tmp_path)
    loaded = _load_complete(xml)
    full = mujoco.MjModel.from_xml_path(str(xml))
    assert loaded.stripped == () and set(loaded.files) == _all_files(tmp_path)
    rng = np.random.default_rng(3)
    _assert_bitwise_kinematics(
        loaded.model, full, [full.qpos0] + [_random_qpos(full, rng) for _ in range(20)]
    )
    assert _digest(tmp_path) == before


def _binary_stl(obj: str) -> bytes:
    """The triangles of a Wavefront OBJ text as a binary STL file."""
    lines = [ln.split() for ln in obj.splitlines()]
    vertices = [[float(x) for x in ln[1:]] for ln in lines if ln[0] == "v"]
    faces = [[vertices[int(i) - 1] for i in ln[1:]] for ln in lines if ln[0] == "f"]
    triangles = b"".join(
        struct.pack("<12fH", 0.0, 0.0, 0.0, *(x for v in face for x in v), 0) for face in faces
    )
    return b"\0" * 80 + struct.pack("<I", len(faces)) + triangles


@pytest.mark.parametrize("fmt", ["obj", "stl"])
def test_aligned_free_body_reads_only_its_own_mesh(tmp_path: pathlib.Path, fmt: str) -> None:
    """A free body aligned with its inertial frame (alignfree) gets MuJoCo's aligned pose: the
    mesh that shapes that frame is read. The arm's mesh, which cannot move a frame, is not."""
    mesh = TET_OBJ.encode() if fmt == "obj" else _binary_stl(TET_OBJ)
    xml = _write(
        tmp_path,
        {
            "robot.xml": _mjcf(
                compiler='alignfree="true" meshdir="assets"',
                asset=f'<mesh name="tet" file="tet.{fmt}"/><mesh name="wedge" file="wedge.obj"/>',
                body='<body name="obj" pos="0.3 0.2 1" euler="10 20 30"><freejoint/>'
                '<geom type="mesh" mesh="tet"/><geom type="mesh" mesh="wedge" density="0"/>'
                '<site name="s" pos="0.05 0.02 0.01"/></body>'
                + ARM.format(geoms='<geom type="mesh" mesh="wedge"/>'),
            ),
            f"assets/tet.{fmt}": mesh,
            "assets/wedge.obj": TET_OBJ,
        },
    )
    before = _digest(tmp_path)
    loaded = _load_complete(xml)
    full = mujoco.MjModel.from_xml_path(str(xml))
    assert not np.allclose(full.body("obj").pos, [0.3, 0.2, 1])  # MuJoCo did align it
    assert (full.nmesh, loaded.model.nmesh) == (2, 1)
    assert loaded.model.mesh(0).name == "tet"
    rng = np.random.default_rng(5)
    _assert_bitwise_kinematics(
        loaded.model, full, [full.qpos0] + [_random_qpos(full, rng) for _ in range(50)]
    )
    assert set(loaded.files) == _all_files(tmp_path)
    assert _digest(tmp_path) == before


def test_present_asset_files_are_not_read(tmp_path: pathlib.Path) -> None:
    """Files that cannot move a frame are not opened: unreadable ones load without a word, with
    the frames of the model whose files are good. One that an aligned frame needs is read."""
    good = {
        "robot.xml": _mjcf(
            asset='<mesh name="tet" file="tet.obj"/>'
            '<texture name="wood" type="2d" file="wood.png"/><material name="m" texture="wood"/>',
            body=ARM.format(geoms='<geom type="mesh" mesh="tet" material="m"/>'),
        ),
        "tet.obj": TET_OBJ,
        "wood.png": _png(),
    }
    full = mujoco.MjModel.from_xml_path(str(_write(tmp_path / "good", good)))
    bad = _write(tmp_path / "bad", good | {"tet.obj": "not a mesh\n", "wood.png": b"not a png"})
    with pytest.raises(ValueError, match="at least 4 vertices"):
        mujoco.MjModel.from_xml_path(str(bad))  # MuJoCo's full compile reads them
    loaded = _load_complete(bad)
    assert loaded.model.nmesh == 0 and loaded.model.ntex == 1  # a one-pixel placeholder
    assert loaded.model.mat_texid[0].max() == 0
    assert set(loaded.files) == _all_files(tmp_path / "bad")
    rng = np.random.default_rng(1)
    _assert_bitwise_kinematics(loaded.model, full, [_random_qpos(full, rng) for _ in range(10)])
    aligned = _write(
        tmp_path / "aligned", _free_body_files('alignfree="true"', "<freejoint/>", FREE_MESH)
    )
    (tmp_path / "aligned" / "tet.obj").write_text("not a mesh\n")
    with pytest.raises(ModelError, match=r"MuJoCo rejected .*robot\.xml: .*at least 4 vertices"):
        load_model(aligned)


def test_nested_include_prefers_the_main_models_folder(tmp_path: pathlib.Path) -> None:
    """MuJoCo looks for a nested include next to the main model first, then next to its includer."""
    xml = _write(
        tmp_path,
        {
            "m.xml": '<mujoco><worldbody><include file="parts/a.xml"/></worldbody></mujoco>',
            "parts/a.xml": '<mujoco><include file="b.xml"/></mujoco>',
            "b.xml": '<mujoco><body name="main_folder"/></mujoco>',
            "parts/b.xml": '<mujoco><body name="includer_folder"/></mujoco>',
        },
    )
    loaded = _load_complete(xml)
    assert loaded.model.body(1).name == "main_folder"
    names = {p.relative_to(tmp_path.resolve()).as_posix() for p in loaded.files}
    assert names == {"m.xml", "parts/a.xml", "b.xml"}


@pytest.mark.parametrize(
    ("files", "message"),
    [
        (
            {"m.xml": '<mujoco><include file="parts/gone.xml"/></mujoco>'},
            r"^m\.xml: included file 'parts/gone\.xml' named in m\.xml is missing",
        ),
        (
            {
                "m.xml": '<mujoco><include file="parts/a.xml"/></mujoco>',
                "parts/a.xml": '<mujoco><include file="gone.xml"/></mujoco>',
            },
            r"included file 'gone\.xml' named in a\.xml is missing \(looked for \S+/gone\.xml "
            r"or \S+/parts/gone\.xml\); restore",
        ),
        (
            {"m.xml": '<mujoco><asset><model name="k" file="kid.xml"/></asset></mujoco>'},
            r"sub-model file 'kid\.xml' named in m\.xml is missing",
        ),
    ],
)
def test_missing_xml_file_is_an_error(
    tmp_path: pathlib.Path, files: dict[str, str | bytes], message: str
) -> None:
    xml = _write(tmp_path, files)
    with pytest.raises(ModelError, match=message) as info:
        load_model(xml)
    assert "\n" not in str(info.value)


def test_every_menagerie_model_compiles() -> None:
    """Every full model (not an include-only fragment) of every robot folder, no manual steps."""
    models = sorted(p for p in MENAGERIE.glob("*/*.xml") if "<worldbody" in p.read_text())
    folders = {p.parent for p in MENAGERIE.glob("*/*.xml")}
    assert {p.parent for p in models} == folders
    before = _digest(MENAGERIE)
    for xml in models:
        model = load_quiet(str(xml)).model
        assert model.nbody > 1 and model.njnt > 0, xml
    assert _digest(MENAGERIE) == before


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


def test_download_that_cannot_happen(fresh_machine: None) -> None:
    """No local clone and no reachable archive, for a robot poekin does not ship: one clear
    error naming the fix."""
    assert "unitree_h1" not in BUILTIN_ROBOTS
    with pytest.raises(MenagerieUnavailableError, match="set MENAGERIE_ROOT to a local"):
        load_model("unitree_h1")


def test_mujoco_warnings_are_notes_not_a_log_file(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """MuJoCo warns of a URDF joint with lower = upper (and ignores the limit): one note, and
    no MUJOCO_LOG.TXT in the working folder, where MuJoCo's own handler would append it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "locked.urdf").write_text(
        '<robot name="r"><link name="a"/><link name="b"/><joint name="lock" type="revolute">'
        '<parent link="a"/><child link="b"/><limit lower="0" upper="0" effort="1" velocity="1"/>'
        "</joint></robot>"
    )
    with pytest.warns(MuJoCoWarning) as notes:
        load_model("locked.urdf")
    assert [str(n.message) for n in notes if n.category is MuJoCoWarning] == [
        "locked.urdf: MuJoCo: joint 'lock' has equal lower and upper limits, limit ignored"
    ]
    assert list(tmp_path.iterdir()) == [tmp_path / "locked.urdf"]
    assert mujoco.get_mju_user_warning() is None, "MuJoCo's own handler is back"
