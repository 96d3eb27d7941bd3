"""The robot's drawable parts: MuJoCo's compiled primitives and meshes in their body frames,
URDF visuals (mesh files through trimesh), and the capsule stand-in where files are missing."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from helpers import assert_close

import poekin
from poekin.viewer import geometry, scene

trimesh = pytest.importorskip("trimesh")

MJCF = """
<mujoco>
  <asset><material name="red" rgba="1 0 0 1"/></asset>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body name="a" pos="0 0 0.5" euler="0 0 90">
      <joint name="j" type="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.2 0.3" pos="0.5 0 0" rgba="0 1 0 1"/>
      <geom type="sphere" size="0.05" material="red"/>
      <geom type="capsule" size="0.02 0.1" pos="0 0 0.2"/>
      <geom type="cylinder" size="0.03 0.1" group="3"/>
      <geom type="ellipsoid" size="0.1 0.05 0.02" pos="0 0.3 0" rgba="0 0 1 0"/>
      <site name="tip" pos="1 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_mjcf_primitives_in_their_body_frame(tmp_path: pathlib.Path) -> None:
    (tmp_path / "robot.xml").write_text(MJCF)
    loaded = poekin.load_model(tmp_path / "robot.xml")
    subject = scene.make_subject(poekin.tree_from_model(loaded.model), "tip")
    g = geometry.mjcf_geometry(loaded, subject)
    # the plane (world), the group-3 cylinder and the invisible ellipsoid are not drawn
    assert g.note == "the model's 3 primitives (MuJoCo's compile)" and not g.stand_in
    colors = {p.color: p for p in g.parts}
    box = colors[(0, 255, 0)]
    assert box.body == 0
    assert_close("box corners", box.vertices.min(axis=0), [0.4, -0.2, -0.3], 1e-6)
    assert_close("box corners", box.vertices.max(axis=0), [0.6, 0.2, 0.3], 1e-6)
    assert (255, 0, 0) in colors  # the material's colour, not the geom's
    assert all(p.faces.max() < len(p.vertices) for p in g.parts)


def test_stand_in_for_missing_meshes_names_them(tmp_path: pathlib.Path) -> None:
    xml = MJCF.replace("<asset>", '<asset><mesh name="m" file="gone.stl"/>').replace(
        '<site name="tip"', '<geom type="mesh" mesh="m"/><site name="tip"'
    )
    (tmp_path / "robot.xml").write_text(xml)
    with pytest.warns(poekin.AssetsStrippedWarning):
        loaded = poekin.load_model(tmp_path / "robot.xml")
    subject = scene.make_subject(poekin.tree_from_model(loaded.model), "tip")
    g = geometry.mjcf_geometry(loaded, subject)
    assert g.stand_in and g.note.startswith("stand-in: capsules between joint anchors (1 missing")
    # one capsule, from the joint's anchor to the site, radius 2.2% of the robot's size
    (part,) = g.parts
    radius = 0.022 * subject.extent
    assert_close("capsule reach", part.vertices[:, 0].max(), 1.0 + radius, 1e-6)


URDF = """<?xml version="1.0"?>
<robot name="meshy">
  <material name="teal"><color rgba="0 0.5 0.5 1"/></material>
  <link name="base">
    <visual><origin xyz="0 0 0.1" rpy="0 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry>
      <material name="teal"/></visual>
  </link>
  <link name="arm">
    <visual><origin xyz="0.3 0 0" rpy="0 0 0"/>
      <geometry><mesh filename="MESH" scale="2 2 2"/></geometry></visual>
    <visual><geometry><cylinder radius="0.02" length="0.4"/></geometry></visual>
    <visual><geometry><sphere radius="0.05"/></geometry></visual>
  </link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>
"""


@pytest.mark.parametrize("filename", ["package://mypkg/meshes/part.stl", "meshes/part.stl"])
def test_urdf_visuals_and_mesh_files(tmp_path: pathlib.Path, filename: str) -> None:
    folder = tmp_path / "mypkg"
    (folder / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=[0.1, 0.1, 0.1]).export(folder / "meshes" / "part.stl")
    urdf = folder / "robot.urdf"
    urdf.write_text(URDF.replace("MESH", filename))
    subject = scene.make_subject(poekin.load_tree(urdf))
    g = geometry.urdf_geometry(urdf, subject)
    assert not g.stand_in and g.note == "the URDF's 4 visuals (meshes by trimesh)"
    teal = [p for p in g.parts if p.color == (0, 128, 128)]
    assert len(teal) == 1 and teal[0].body == 0
    arm = [p for p in g.parts if p.body == 1]
    (part,) = arm  # the arm's three visuals, one colour: one part
    assert "arm/visual0" in part.name
    # the mesh: a 0.1 m box scaled by 2, centred at x = 0.3 in the arm's frame
    assert_close("mesh max x", part.vertices[:, 0].max(), 0.4, 1e-6)


def test_urdf_missing_mesh_is_a_stand_in() -> None:
    urdf = pathlib.Path("tests/data/urdf/package_meshes.urdf")
    subject = scene.make_subject(poekin.load_tree(urdf))
    g = geometry.urdf_geometry(urdf, subject)
    assert g.stand_in and "3 mesh files not found: package://no_such_pkg/meshes/base.dae" in g.note
    assert {p.body for p in g.parts} <= set(range(len(subject.body_names)))
    assert np.all(np.isfinite(np.concatenate([p.vertices for p in g.parts])))
