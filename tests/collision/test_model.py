"""poekin.collision.model: which geoms are read and which pairs are checked.

The pairs are checked against MuJoCo's own collision filter: ``mj_collision`` on the same
model with every geom's (and every ``<pair>``'s) margin at 100 m reports a contact for each
pair that it tests and for no other. The broad phase reads each body's margin, so
``body_margin`` is set too; boxes become spheres there, as MuJoCo's box-box function reports
no contact for boxes far apart whatever the margin (the filter does not depend on shapes).
So its contacts' geom pairs are MuJoCo's candidate set.
"""

from __future__ import annotations

import pathlib
import sysconfig

import mujoco
import numpy as np
import pytest
from helpers import load_quiet, mesh_menagerie

import poekin
from poekin.collision import model_of
from poekin.errors import InputError, ModelError

FAR = 100.0  # m: a margin every pair of these models is within


def _erd() -> pathlib.Path:
    """example-robot-data's robots folder (URDFs with STL collision meshes; a dev dependency)."""
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    found = site / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
    if not found.is_dir():
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return found


def mujoco_pairs(model: mujoco.MjModel, qpos: np.ndarray | None = None) -> set[frozenset[str]]:
    """MuJoCo's candidate pairs, as sets of two geom labels (``name`` or ``body#k``)."""
    box = model.geom_type == mujoco.mjtGeom.mjGEOM_BOX
    model.geom_type[box] = mujoco.mjtGeom.mjGEOM_SPHERE  # MuJoCo's box-box misses far pairs
    model.geom_margin[:] = FAR
    model.body_margin[:] = FAR  # what the broad phase reads: each body's largest geom margin
    model.pair_margin[:] = FAR
    data = mujoco.MjData(model)
    if qpos is not None:
        data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    labels = _labels(model)
    return {frozenset((labels[c.geom[0]], labels[c.geom[1]])) for c in data.contact}


def _labels(model: mujoco.MjModel) -> list[str]:
    """Each geom's label as poekin names it: its name, else its body's (with ``#k`` where the
    body has several unnamed geoms that collide)."""
    out = []
    collide = [
        g
        for g in range(model.ngeom)
        if model.geom_contype[g] or model.geom_conaffinity[g] or g in set(model.pair_geom1)
    ]
    for g in range(model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        if name:
            out.append(name)
            continue
        b = int(model.geom_bodyid[g])
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "world"
        siblings = [
            h
            for h in collide
            if model.geom_bodyid[h] == b
            and not mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, h)
        ]
        if g not in siblings:  # a visual geom: in no pair
            out.append(f"visual{g}")
        else:
            out.append(body if len(siblings) == 1 else f"{body}#{siblings.index(g)}")
    return out


def poekin_pairs(tree: poekin.Tree) -> set[frozenset[str]]:
    return {frozenset(p) for p in model_of(tree).pair_names()}


RULES = """
<mujoco>
  <option><flag filterparent="{filterparent}"/></option>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" pos="0 0 -1"/>
    <geom name="post" type="box" size="0.1 0.1 0.1" pos="2 0 0"/>
    <body name="a" pos="0 0 0.5">
      <joint name="ja" type="hinge" axis="0 0 1"/>
      <geom name="a_ball" type="sphere" size="0.1"/>
      <geom name="a_bits" type="box" size="0.1 0.1 0.1" pos="0.3 0 0" contype="2"
        conaffinity="0"/>
      <geom name="a_ghost" type="sphere" size="0.05" pos="0 0.3 0" contype="0" conaffinity="0"/>
      <body name="b" pos="0 0 0.5">
        <joint name="jb" type="hinge" axis="0 1 0"/>
        <geom name="b_cap" type="capsule" size="0.05 0.2"/>
        <body name="c" pos="0 0 0.5">
          <geom name="c_ell" type="ellipsoid" size="0.1 0.05 0.08"/>
          <body name="d" pos="0 0 0.3">
            <joint name="jd" type="hinge" axis="1 0 0"/>
            <geom name="d_cyl" type="cylinder" size="0.05 0.1" conaffinity="2"/>
            <geom type="sphere" size="0.03" pos="0 0 0.2"/>
            <geom type="box" size="0.03 0.03 0.03" pos="0 0 0.3"/>
          </body>
        </body>
      </body>
    </body>
    <body name="e" pos="1 0 0.5">
      <joint name="je" type="slide" axis="0 0 1"/>
      <geom name="e_box" type="box" size="0.1 0.2 0.1"/>
      <body name="f" pos="0 0 0.4">
        <joint name="jf" type="hinge" axis="0 0 1"/>
        <geom name="f_ball" type="sphere" size="0.05"/>
      </body>
    </body>
  </worldbody>
  <contact>
    <exclude body1="e" body2="a"/>
    <pair geom1="a_ghost" geom2="f_ball"/>
    <pair geom1="b_cap" geom2="e_box"/>
  </contact>
</mujoco>
"""


@pytest.mark.parametrize("filterparent", ["enable", "disable"])
def test_pairs_are_mujocos_on_a_model_of_every_rule(
    tmp_path: pathlib.Path, filterparent: str
) -> None:
    """Welds (c has no joint), parent-child, <exclude>, both <pair>s (one with a geom that
    collides with nothing else, one that the rules would not give), contype bits,
    the world's geoms (never with each other), every primitive; with filterparent on and off."""
    path = tmp_path / "rules.xml"
    path.write_text(RULES.format(filterparent=filterparent))
    tree = poekin.load_tree(path)
    expected = mujoco_pairs(mujoco.MjModel.from_xml_path(str(path)))
    assert poekin_pairs(tree) == expected
    assert frozenset(("a_ghost", "f_ball")) in expected  # the rules as the test means them
    assert frozenset(("a_ball", "e_box")) not in expected
    assert frozenset(("a_ball", "f_ball")) in expected  # a <pair> leaves its bodies' others
    assert (frozenset(("b_cap", "d#0")) in expected) == (filterparent == "disable")


def test_ur5e_collision_geoms_are_its_capsules_and_cylinder() -> None:
    """The built-in copy (no mesh files) serves: its collision geoms are primitives."""
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    cm = model_of(tree)
    assert cm.geom_types == ("capsule",) * 8 + ("cylinder",)
    reference = load_quiet("universal_robots_ur5e").model  # the kinematics compile: same geoms
    colliding = [g for g in range(reference.ngeom) if reference.geom_contype[g]]
    np.testing.assert_array_equal(cm.geom_sizes, reference.geom_size[colliding])
    bodies = [tree.body_names[b] for b in cm.geom_bodies]
    names = [
        mujoco.mj_id2name(reference, mujoco.mjtObj.mjOBJ_BODY, int(reference.geom_bodyid[g]))
        for g in colliding
    ]
    assert bodies == names
    assert poekin_pairs(tree) == mujoco_pairs(reference)
    assert model_of(tree) is cm  # built once per tree


def test_ur5e_complete_model_gives_the_same_geoms() -> None:
    tree = poekin.load_tree(mesh_menagerie() / "universal_robots_ur5e" / "ur5e.xml")
    builtin = model_of(poekin.load_tree(load_quiet("universal_robots_ur5e")))
    cm = model_of(tree)
    assert cm.geom_names == builtin.geom_names
    np.testing.assert_array_equal(cm.geom_pos, builtin.geom_pos)


@pytest.mark.parametrize("robot", ["unitree_g1", "franka_fr3"])
def test_xml_only_copy_with_collision_meshes_says_so(robot: str) -> None:
    tree = poekin.load_tree(load_quiet(robot))
    with pytest.raises(ModelError, match=r"collision geometry needs \d+ mesh file\(s\) that are "):
        model_of(tree)


def test_tree_from_arrays_has_no_collision_model() -> None:
    tree = poekin.load(load_quiet("universal_robots_ur5e")).as_tree()
    with pytest.raises(ModelError, match="knows no model file"):
        tree.distances(np.zeros(6))


def test_a_base_moves_world_geoms_but_not_the_pairs(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "rules.xml"
    path.write_text(RULES.format(filterparent="enable"))
    tree = poekin.load_tree(path)
    moved = tree.with_base([0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    assert model_of(moved).pair_names() == model_of(tree).pair_names()
    qpos = np.array([0.3, -0.2, 0.5, 0.1, 0.4])
    np.testing.assert_allclose(
        moved.distances(qpos).distance, tree.distances(qpos).distance, atol=1e-12
    )


def _panda() -> pathlib.Path:
    return _erd() / "panda_description" / "urdf" / "panda.urdf"


def _urdf_reference(path: pathlib.Path) -> mujoco.MjModel:
    """MuJoCo's own compile of a URDF from example-robot-data, its package:// paths replaced
    by hand, every link a body."""
    spec = mujoco.MjSpec.from_file(str(path))
    share = path.parents[3]
    for mesh in spec.meshes:
        mesh.file = mesh.file.replace("package://example-robot-data", str(share))
    spec.compiler.fusestatic = False
    return spec.compile()


def test_urdf_collision_geoms_and_pairs_are_mujocos() -> None:
    """The Panda's STL collision meshes and finger boxes, found through package:// (a folder
    of that name above the URDF); the adjacent-links rule is MuJoCo's on the same URDF."""
    tree = poekin.load_tree(_panda())
    cm = model_of(tree)
    reference = _urdf_reference(_panda())
    assert cm.geom_types == ("mesh",) * 9 + ("box",) * 8
    assert poekin_pairs(tree) == mujoco_pairs(reference)
    assert frozenset(("panda_link1", "panda_link2")) not in poekin_pairs(tree)  # adjacent
    assert frozenset(("panda_link1", "panda_link3")) in poekin_pairs(tree)


def test_ignore_drops_pairs_by_geom_or_body_name() -> None:
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    qpos = np.zeros(6)
    every = tree.distances(qpos).pairs
    fewer = tree.distances(
        qpos, ignore=[("wrist_3_link", "wrist_1_link"), ("forearm_link", "shoulder_link")]
    ).pairs
    gone = set(every) - set(fewer)
    assert gone == {
        ("wrist_1_link", "wrist_3_link"),
        ("shoulder_link", "forearm_link#0"),
        ("shoulder_link", "forearm_link#1"),
    }


@pytest.mark.parametrize(
    ("ignore", "message"),
    [
        (
            [("wrist_3_lnk", "base")],
            "no collision geom, body or obstacle named 'wrist_3_lnk': did ",
        ),
        (["wrist_3_link"], "each entry is a pair of names"),
    ],
)
def test_ignore_bad_input(ignore: list[object], message: str) -> None:
    tree = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    with pytest.raises(InputError, match=message):
        tree.distances(np.zeros(6), ignore=ignore)
