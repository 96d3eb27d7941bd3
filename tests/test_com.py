"""The whole robot's centre of mass, ``Tree.com``, and its Jacobian, ``Tree.com_jacobian``:
against MuJoCo's ``subtree_com[0]`` and ``mj_jacSubtreeCom`` on Menagerie robots and a model of
every joint type, against Pinocchio on a URDF, against JAX's and PyTorch's derivatives of
``com``; the masses the loaders read (explicit ``<inertial>`` kept exactly by a kinematics-only
compile, those of unread meshes left unknown), and the errors."""

from __future__ import annotations

import dataclasses
import pathlib
import re
from typing import Any

import mujoco
import numpy as np
import pytest
from array_libs import LIBRARIES, load
from helpers import MJ_TOL, assert_close, load_quiet, mesh_menagerie, pinocchio_q
from test_tree import FEATURES_XML

import poekin
from poekin import InputError, ModelError, URDFError
from poekin.io.import_mujoco import tree_from_model
from poekin.io.import_urdf import tree_from_urdf
from poekin.tree import Tree

DATA = pathlib.Path(__file__).parent / "data" / "urdf"
ROBOTS = ["unitree_go2", "franka_emika_panda", "aloha", "universal_robots_ur5e"]
N_SAMPLES = 200
BATCH_SHAPES = [(), (1,), (3, 1, 2)]
# a body's mass and centre of mass, as MuJoCo compiles them from an <inertial>: no arithmetic
EXACT = 0.0


def mj_com(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's whole-model centre of mass ``(n, 3)`` and its Jacobian ``(n, 3, nv)``: the
    world body's subtree (the world has no mass) after ``mj_forward``."""
    assert model.body_mass[0] == 0.0
    data = mujoco.MjData(model)
    com, jac = np.empty((len(qpos), 3)), np.empty((len(qpos), 3, model.nv))
    for n, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        com[n] = data.subtree_com[0]
        mujoco.mj_jacSubtreeCom(model, data, jac[n], 0)
    return com, jac


def check_against_mujoco(tree: Tree, model: mujoco.MjModel, qpos: np.ndarray, what: str) -> None:
    com, jac = mj_com(model, qpos)
    assert_close(f"{what}: com", tree.com(qpos), com, MJ_TOL)
    assert_close(f"{what}: com_jacobian", tree.com_jacobian(qpos), jac, MJ_TOL)


# --- against MuJoCo ---------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ROBOTS)
def test_menagerie_com_matches_mujoco(robot: str) -> None:
    loaded = load_quiet(robot)
    tree = poekin.load_tree(loaded)
    assert_close("body_mass", tree.body_mass, loaded.model.body_mass[1:], EXACT)
    assert_close("body_com", tree.body_com, loaded.model.body_ipos[1:], EXACT)
    qpos = poekin.sample_qpos(tree, N_SAMPLES, seed=11, within_limits=True)
    check_against_mujoco(tree, loaded.model, qpos, robot)


def test_every_joint_type_matches_mujoco() -> None:
    """Ball and free joints, anchors off the body origin, slides, two free-floating trees, a
    world site and a massless mocap body: masses from primitive geoms."""
    model = mujoco.MjModel.from_xml_string(FEATURES_XML)
    tree = tree_from_model(model)
    assert {"ball", "free", "prismatic", "revolute"} <= set(tree.joint_types)
    assert tree.body_mass[tree.body_names.index("target")] == 0.0
    check_against_mujoco(tree, model, poekin.sample_qpos(tree, N_SAMPLES, seed=12), "features")


@pytest.mark.parametrize("batch", BATCH_SHAPES)
def test_batch_axes_are_kept(go2: Tree, batch: tuple[int, ...]) -> None:
    n = int(np.prod(batch))
    flat = poekin.sample_qpos(go2, n, seed=13, within_limits=True)
    qpos = flat.reshape(*batch, go2.nq)
    com, jac = go2.com(qpos), go2.com_jacobian(qpos)
    assert com.shape == (*batch, 3)
    assert jac.shape == (*batch, 3, go2.nv)
    assert_close("com", com.reshape(n, 3), go2.com(flat), EXACT)
    assert_close("com_jacobian", jac.reshape(n, 3, go2.nv), go2.com_jacobian(flat), EXACT)
    expected, expected_jac = mj_com(load_quiet("unitree_go2").model, flat)
    assert_close("com vs MuJoCo", com.reshape(n, 3), expected, MJ_TOL)
    assert_close("com_jacobian vs MuJoCo", jac.reshape(n, 3, go2.nv), expected_jac, MJ_TOL)


def test_with_base_moves_the_com_with_the_model() -> None:
    ur5e = poekin.load_tree(load_quiet("universal_robots_ur5e"))
    B = np.eye(4)
    B[:3, :3] = poekin.lie.quat_to_rotation(np.array([0.9, 0.1, -0.3, 0.2]) / np.sqrt(0.95))
    B[:3, 3] = [0.4, -1.0, 0.3]
    placed = ur5e.with_base(B)
    qpos = poekin.sample_qpos(ur5e, 20, seed=14, within_limits=True)
    assert_close("com", placed.com(qpos), ur5e.com(qpos) @ B[:3, :3].T + B[:3, 3], 1e-15)
    assert_close(
        "com_jacobian", placed.com_jacobian(qpos), B[:3, :3] @ ur5e.com_jacobian(qpos), 1e-15
    )


# --- JAX and PyTorch --------------------------------------------------------------------------


@pytest.mark.parametrize("name", LIBRARIES)
def test_arrays_of_jax_and_torch_and_their_derivatives(go2: Tree, name: str) -> None:
    """The NumPy answers, in the library's arrays; and ``com_jacobian``'s hinge columns are the
    library's derivatives of ``com`` (the free joint's quaternion has 4 qpos entries for its 3
    velocity columns, so only its linear columns compare)."""
    lib = load(name)
    qpos = poekin.sample_qpos(go2, 5, seed=15, within_limits=True)
    com = go2.com(lib.asarray(qpos))
    jac = go2.com_jacobian(lib.asarray(qpos))
    assert type(com) is type(lib.asarray(qpos)) and lib.dtype(jac) == "float64"
    assert_close(f"{name} com", lib.numpy(com), go2.com(qpos), 1e-15)
    assert_close(f"{name} com_jacobian", lib.numpy(jac), go2.com_jacobian(qpos), 1e-15)
    derivative = lib.numpy(lib.jacobian(go2.com, lib.asarray(qpos)))  # (5, 3, nq)
    J = go2.com_jacobian(qpos)
    assert_close("hinges", derivative[:, :, 7:], J[:, :, 6:], 1e-14)
    assert_close("free joint, linear", derivative[:, :, :3], J[:, :, :3], 1e-14)


# --- URDF, against Pinocchio ------------------------------------------------------------------


def _pinocchio_columns(model: Any, tree: Tree, qpos: np.ndarray) -> np.ndarray:
    """``(n, model.nv, tree.nv)``: Pinocchio's velocity columns onto poekin's (MuJoCo's). A
    follower (a joint of its own in Pinocchio) adds its column times its multiplier to its
    leader's; a free flyer's linear velocity is in its body's frame, MuJoCo's in the world's."""
    from poekin import lie

    dof_names = tree.dof_names()
    to_tree = np.zeros((len(qpos), model.nv, tree.nv))
    for j in range(1, model.njoints):
        name, joint = model.names[j], model.joints[j]
        v = joint.idx_v
        if name == "root_joint":
            k = 0
            R = lie.quat_to_rotation(lie.quat_normalize(qpos[:, 3:7]))
            to_tree[:, v : v + 3, 0:3] = np.swapaxes(R, -1, -2)  # v_local = R^T v_world
            to_tree[:, v + 3 : v + 6, 3:6] = np.eye(3)
            continue
        k = tree.joint_names.index(name)
        mimic = tree.mimics[k]
        leader = name if mimic is None else mimic.leader
        to_tree[:, v, dof_names.index(leader)] = 1.0 if mimic is None else mimic.multiplier
    return to_tree


@pytest.mark.parametrize("floating_base", [False, True])
def test_urdf_com_matches_pinocchio(floating_base: bool) -> None:
    """Pinocchio reads ``<inertial>`` itself (urdfdom), and merges a fixed joint's child link's
    mass into its parent's body. With a fixed base it appends the root link's mass to the
    universe, which its centre of mass leaves out, where MuJoCo (and poekin) count it: that
    mass, fixed in the world, is added back here."""
    import pinocchio as pin

    path = str(DATA / "com_tree.urdf")
    tree = tree_from_urdf(path, floating_base=floating_base)
    model = pin.buildModelFromUrdf(path, *([pin.JointModelFreeFlyer()] if floating_base else []))
    data = model.createData()
    fixed = model.inertias[0]  # the universe's: the root link's with a fixed base
    assert (fixed.mass > 0) != floating_base
    qpos = poekin.sample_qpos(tree, N_SAMPLES, seed=16, within_limits=True)
    moving = sum(model.inertias[j].mass for j in range(1, model.njoints))
    total = moving + fixed.mass
    assert_close("total mass", tree.body_mass.sum(), total, 1e-14)
    com, jac = np.empty((len(qpos), 3)), np.empty((len(qpos), 3, model.nv))
    for n, q in enumerate(pinocchio_q(model, tree, qpos)):
        c = pin.centerOfMass(model, data, q)
        jac[n] = pin.jacobianCenterOfMass(model, data, q) * (moving / total)
        com[n] = (moving * c + fixed.mass * fixed.lever) / total
    assert_close("com", tree.com(qpos), com, MJ_TOL)
    to_tree = _pinocchio_columns(model, tree, qpos)
    assert_close("com_jacobian", tree.com_jacobian(qpos), jac @ to_tree, MJ_TOL)


def test_urdf_masses_are_mujocos_reading() -> None:
    """The same URDF compiled by MuJoCo (fixed links kept as bodies, in poekin's order): each
    link's <mass> and <inertial><origin xyz>; the massless link is 0 (MuJoCo floors it)."""
    loaded = load_quiet(str(DATA / "com_tree.urdf"))
    tree = tree_from_urdf(DATA / "com_tree.urdf")
    names = [mujoco.mj_id2name(loaded.model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, 13)]
    assert names == list(tree.body_names)
    sensor = tree.body_names.index("sensor")
    assert loaded.unknown_masses == (sensor + 1,)  # MuJoCo's floor gave it 1e-6 kg
    assert (tree.body_mass[sensor], *tree.body_com[sensor]) == (0.0, 0.0, 0.0, 0.0)
    known = np.arange(len(names)) != sensor
    assert_close("mass", tree.body_mass[known], loaded.model.body_mass[1:][known], EXACT)
    assert_close("com", tree.body_com[known], loaded.model.body_ipos[1:][known], EXACT)


def _urdf_link(inertial: str) -> str:
    return (
        f'<robot name="r"><link name="base"/><link name="arm">{inertial}</link>'
        '<joint name="j" type="continuous"><parent link="base"/><child link="arm"/></joint>'
        "</robot>"
    )


@pytest.mark.parametrize(
    ("inertial", "message"),
    [
        ("<inertial><origin xyz='0 0 1'/></inertial>", "link 'arm': <inertial> has no <mass"),
        ("<inertial><mass/></inertial>", "link 'arm': <inertial> has no <mass"),
        ("<inertial><mass value='-1'/></inertial>", "link 'arm': <mass value=\"-1\"> is negative"),
        ("<inertial><mass value='nan'/></inertial>", "'nan' is not a finite number"),
        ("<inertial><mass value='1 2'/></inertial>", "has 2 numbers; give one number"),
        (
            "<inertial><origin xyz='0 1'/><mass value='1'/></inertial>",
            "link 'arm': <origin xyz=\"0 1\"> has 2 numbers; give 3 numbers",
        ),
        ("<inertial><mass value='1'/></inertial><inertial/>", "has 2 <inertial> elements"),
        ("<inertial><mass value='1'/><mass value='2'/></inertial>", "has 2 <mass> elements"),
    ],
)
def test_malformed_inertials_are_refused(
    tmp_path: pathlib.Path, inertial: str, message: str
) -> None:
    path = tmp_path / "robot.urdf"
    path.write_text(_urdf_link(inertial))
    with pytest.raises(URDFError, match=re.escape(message)):
        tree_from_urdf(path)


def test_urdf_inertial_reads_mass_and_origin_only(tmp_path: pathlib.Path) -> None:
    """The inertia tensor is not read (nor checked); rpy turns it, not the centre."""
    path = tmp_path / "robot.urdf"
    path.write_text(
        _urdf_link(
            "<inertial><origin xyz='0.1 -0.2 0.3' rpy='1 2 3'/><mass value='2.5'/>"
            "<inertia ixx='not a number'/></inertial>"
        )
    )
    tree = tree_from_urdf(path)
    np.testing.assert_array_equal(tree.body_mass, [0.0, 2.5])
    np.testing.assert_array_equal(tree.body_com, [[0.0, 0.0, 0.0], [0.1, -0.2, 0.3]])


# --- masses of a kinematics-only compile --------------------------------------------------------


def test_complete_ur5e_masses_are_the_stripped_copys(tmp_path: pathlib.Path) -> None:
    """Explicit <inertial> everywhere: the built-in copy (no meshes) and a clone with its
    meshes (not read) have the masses of MuJoCo's complete compile, which reads them."""
    folder = mesh_menagerie() / "universal_robots_ur5e"
    full = mujoco.MjModel.from_xml_path(str(folder / "ur5e.xml"))
    for source in (folder / "ur5e.xml", "universal_robots_ur5e"):
        loaded = load_quiet(str(source))
        assert loaded.unknown_masses == ()
        tree = poekin.load_tree(loaded)
        assert_close(f"{source}: body_mass", tree.body_mass, full.body_mass[1:], EXACT)
        assert_close(f"{source}: body_com", tree.body_com, full.body_ipos[1:], EXACT)
        qpos = poekin.sample_qpos(tree, 50, seed=17, within_limits=True)
        check_against_mujoco(tree, full, qpos, str(source))


# A cube mesh (10 cm) for models whose masses come from it.
CUBE_OBJ = "\n".join(
    [
        *(f"v {x} {y} {z}" for x in (-0.05, 0.05) for y in (-0.05, 0.05) for z in (-0.05, 0.05)),
        "f 1 3 4 2",
        "f 5 6 8 7",
        "f 1 2 6 5",
        "f 3 7 8 4",
        "f 1 5 7 3",
        "f 2 4 8 6",
    ]
)
MESH_MASSES_XML = """
<mujoco>
  <compiler {compiler}/>
  <asset><mesh name="cube" file="cube.obj"/></asset>
  <worldbody>
    <body name="explicit" pos="0 0 0.5">
      <joint name="j1" axis="0 0 1"/>
      <inertial pos="0.1 0.02 -0.03" mass="3.5" diaginertia="0.01 0.02 0.03"/>
      <geom type="mesh" mesh="cube"/>
      <body name="from_mesh" pos="0.3 0 0">
        <joint name="j2" axis="0 1 0"/>
        <geom type="mesh" mesh="cube" pos="0.05 0 0" {density}/>
        <geom type="mesh" mesh="cube" mass="0" pos="0 0.2 0"/>
        <body name="frame" pos="0 0 0.2"><site name="tip"/></body>
      </body>
      <body name="from_primitives" pos="0 0.3 0">
        <joint name="j3" axis="1 0 0"/>
        <geom type="capsule" size="0.02 0.1" pos="0 0.1 0"/>
        <geom type="mesh" mesh="cube" mass="0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _mesh_model(tmp_path: pathlib.Path, compiler: str = "", density: str = "") -> pathlib.Path:
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    path = tmp_path / "robot.xml"
    path.write_text(MESH_MASSES_XML.format(compiler=compiler, density=density))
    return path


def _unknown(loaded: poekin.LoadedModel) -> list[str]:
    body = mujoco.mjtObj.mjOBJ_BODY
    return [mujoco.mj_id2name(loaded.model, body, b) for b in loaded.unknown_masses]


def test_masses_of_meshes_not_read_are_unknown(tmp_path: pathlib.Path) -> None:
    """A kinematics-only compile does not read the cube, so "from_mesh" (whose mass MuJoCo
    computes from it) is unknown, whether the file is there or missing; every other body has
    the complete model's mass (a massless one 0, not a floor); reading the file gives all."""
    path = _mesh_model(tmp_path)
    full = mujoco.MjModel.from_xml_path(str(path))
    assert full.body("explicit").mass == 3.5 and full.body("frame").mass == 0.0
    qpos = poekin.sample_qpos(tree_from_model(full), N_SAMPLES, seed=18)
    complete = poekin.load_tree(poekin.load_model(path, read_assets=True))
    assert_close("body_mass", complete.body_mass, full.body_mass[1:], EXACT)
    check_against_mujoco(complete, full, qpos, "meshes read")
    loaded = poekin.load_model(path)
    (tmp_path / "cube.obj").unlink()
    with pytest.warns(poekin.AssetsStrippedWarning, match="1 missing mesh file"):
        missing = poekin.load_model(path)
    for stripped in (loaded, missing):
        assert _unknown(stripped) == ["from_mesh"]
        tree = poekin.load_tree(stripped)
        known = np.array([name != "from_mesh" for name in tree.body_names])
        assert np.isnan(tree.body_mass[~known]).all() and np.isnan(tree.body_com[~known]).all()
        assert_close("known masses", tree.body_mass[known], full.body_mass[1:][known], EXACT)
        assert_close("known centres", tree.body_com[known], full.body_ipos[1:][known], EXACT)
        for method in (tree.com, tree.com_jacobian):
            with pytest.raises(ModelError) as info:
                method(qpos)
            message = str(info.value)
            assert "the mass of 'from_mesh' is not known" in message and "\n" not in message
            assert "read_assets=True" in message


def test_a_floor_applied_leaves_the_masses_it_may_have_raised_unknown(
    tmp_path: pathlib.Path,
) -> None:
    """A stand-in sphere of nearly no density does not compile (its inertia under MuJoCo's
    mjMINVAL), so masses are floored: the massless "frame" then weighs the floor, so it is
    unknown too; the poses are still the complete model's."""
    path = _mesh_model(tmp_path, density='density="0.001"')
    full = mujoco.MjModel.from_xml_path(str(path))
    loaded = poekin.load_model(path)
    assert _unknown(loaded) == ["from_mesh", "frame"]
    assert loaded.model.body("frame").mass > 0.0 == full.body("frame").mass
    qpos = poekin.sample_qpos(tree_from_model(full), 20, seed=19)
    tree = poekin.load_tree(loaded)
    assert_close("poses", tree.fk(qpos), tree_from_model(full).fk(qpos), EXACT)


@pytest.mark.filterwarnings("ignore:compiler attribute 'settotalmass' is deprecated")
def test_settotalmass_makes_every_mass_unknown_if_one_is(tmp_path: pathlib.Path) -> None:
    """compiler settotalmass scales every body by the total, which a stand-in changes."""
    loaded = poekin.load_model(_mesh_model(tmp_path, compiler='settotalmass="10"'))
    assert _unknown(loaded) == ["explicit", "from_mesh", "frame", "from_primitives"]
    assert (
        poekin.load_model(
            _mesh_model(tmp_path, compiler='settotalmass="10"'), read_assets=True
        ).unknown_masses
        == ()
    )


def test_an_unknown_mass_from_a_folder_without_meshes() -> None:
    """A Menagerie robot whose base takes its mass from its meshes (SO-ARM100) names it."""
    tree = poekin.load_tree(load_quiet("trs_so_arm100"))
    with pytest.raises(ModelError, match=r"^trs_so_arm100: the mass of 'Base' is not known"):
        tree.com(tree.qpos0)


# --- the fields, and the errors ---------------------------------------------------------------


def _tree(**masses: Any) -> Tree:
    """Two bodies on a hinge and a slide."""
    return Tree(
        body_names=("a", "b"),
        body_parents=[-1, 0],
        body_pos=[[0.0, 0.0, 0.1], [0.3, 0.0, 0.0]],
        body_rot=[np.eye(3), np.eye(3)],
        joint_names=("j1", "j2"),
        joint_types=("revolute", "prismatic"),
        joint_bodies=[0, 1],
        joint_axes=[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]],
        joint_anchors=np.zeros((2, 3)),
        joint_refs=np.zeros(2),
        joint_limits=[[-np.inf, np.inf]] * 2,
        mimics=(None, None),
        **masses,
    )


def test_a_hand_made_tree() -> None:
    """Body "a" turns about z at (0, 0, 0.1); "b" slides along a's x from 0.3."""
    tree = _tree(body_mass=[1.0, 3.0], body_com=[[0.2, 0.0, 0.0], [0.0, 0.1, 0.0]])
    assert not tree.body_mass.flags.writeable and not tree.body_com.flags.writeable
    com = (1.0 * np.array([0.2, 0, 0.1]) + 3.0 * np.array([0.5, 0.1, 0.1])) / 4.0
    assert_close("com", tree.com([0.0, 0.2]), com, 1e-16)
    # turning a by pi/2 about z: the centre moves along (-y, x); sliding b: 3/4 along x
    expected = np.array([[-com[1], 0.75], [com[0], 0.0], [0.0, 0.0]])
    assert_close("com_jacobian", tree.com_jacobian([0.0, 0.2]), expected, 1e-16)


def test_no_masses_known() -> None:
    tree = _tree()
    assert tree.body_mass.shape == (0,) and tree.body_com.shape == (0, 3)
    for method in (tree.com, tree.com_jacobian):
        with pytest.raises(
            ModelError, match=r"^the body masses are not known \(body_mass is empty\)"
        ):
            method([0.0, 0.0])


def test_masses_that_sum_to_zero() -> None:
    tree = _tree(body_mass=[0.0, 0.0], body_com=np.zeros((2, 3)))
    with pytest.raises(ModelError, match="masses sum to 0, so the centre of mass is undefined"):
        tree.com([0.0, 0.0])


def test_unknown_masses_are_named() -> None:
    tree = dataclasses.replace(
        _tree(body_mass=[np.nan, 1.0], body_com=[[np.nan] * 3, [0.0] * 3]), robot="r"
    )
    with pytest.raises(ModelError, match=r"^r: the mass of 'a' is not known \(NaN in body_mass\)"):
        tree.com_jacobian([0.0, 0.0])


@pytest.mark.parametrize(
    ("masses", "message"),
    [
        ({"body_mass": [1.0, -2.0], "body_com": np.zeros((2, 3))}, "body_mass of 'b' is -2.0"),
        ({"body_mass": [np.inf, 1.0], "body_com": np.zeros((2, 3))}, "body_mass of 'a' is inf"),
        ({"body_mass": [1.0, 1.0], "body_com": [[0, 0, 0], [np.nan, 0, 0]]}, "body_com of 'b'"),
        ({"body_mass": [1.0, 1.0]}, r"shapes \(2,\) and \(2, 3\), or both be empty"),
        ({"body_mass": [1.0], "body_com": [[0.0] * 3]}, r"got \(1,\) and \(1, 3\)"),
    ],
)
def test_invalid_masses_are_refused(masses: dict[str, Any], message: str) -> None:
    with pytest.raises(InputError, match=message):
        _tree(**masses)


def test_with_parameters_keeps_the_masses(go2: Tree) -> None:
    moved = go2.with_parameters(go2.parameters())
    assert_close("body_mass", moved.body_mass, go2.body_mass, EXACT)
    assert_close("body_com", moved.body_com, go2.body_com, EXACT)
