"""The robot cell: a tool on the flange and the robot's base placed in the world
(:meth:`Chain.with_tool`, :meth:`Chain.with_base`, ``poekin.load(..., base=, tool=)``,
:meth:`Tree.with_base`).

Every path (FK in space and body form, the three Jacobians, numerical IK, the closed form; the
compiled kernel, the NumPy reference, JAX and PyTorch) is checked against MuJoCo's compile of
the same cell, made by editing the model (``mujoco.MjSpec``): the robot attached inside a parent
body posed at the base, and the tool a site on a body welded to the flange (posed where the
flange site is). MuJoCo then composes both with its own code, in ``mj_kinematics``. IK answers are
checked by that model's FK and the joint limits, never by the solver's residual.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import pathlib
import pickle
from collections.abc import Sequence

import mujoco
import numpy as np
import pytest
from array_libs import LIBRARIES
from array_libs import load as load_lib
from helpers import assert_close, load_quiet

import poekin
from poekin import InputError, lie
from poekin.chain import Chain
from poekin.dh import dh_from_chain
from poekin.ik.analytic import solve_numpy
from poekin.io.sources import kinematics_spec

Pose7 = tuple[float, ...]


def unit_pose(x: float, y: float, z: float, *quat: float) -> Pose7:
    """``x y z qw qx qy qz`` with the quaternion scaled to unit length (the same floats go to
    MuJoCo and to poekin)."""
    q = np.asarray(quat, dtype=np.float64)
    return (x, y, z, *(float(v) for v in q / np.linalg.norm(q)))


# a base on a table, turned about an oblique axis; a tool off the flange's axis, tilted
BASE = unit_pose(0.42, -0.27, 0.81, 0.9, 0.12, -0.21, 0.33)
TOOL = unit_pose(0.013, -0.021, 0.164, 0.7, 0.31, 0.1, -0.22)
BASE_2 = unit_pose(-1.3, 0.6, 0.05, 0.2, -0.5, 0.7, 0.4)
TOOL_2 = unit_pose(0.05, 0.0, 0.02, 0.95, 0.0, 0.3, 0.0)

# poekin against MuJoCo on a placed arm. Both round at ~1e-16 of the cell's size (the base
# 0.95 m from the world's origin, the arms' reach about 1 m), over 6-7 joints. Measured, 2,000
# configurations: UR5e and Lite6 up to 1.4e-14 (FK, either form, and Jacobians), Panda up to
# 2.7e-14 (fk_body, whose unplaced form is 1.7e-14 from MuJoCo already): the placement adds
# rounding of the size the arm has without it. The project's bar for unplaced arms is MJ_TOL.
CELL_TOL = 4e-14
# an IK answer: MuJoCo's pose of the answer within this of the target (the solver's tolerance
# is 1e-10; MuJoCo's and poekin's FK differ by CELL_TOL)
IK_TOL = 1e-9


def _texts(values: Sequence[float] | np.ndarray) -> list[str]:
    """Numbers as command-line arguments, every bit kept."""
    return [repr(float(v)) for v in values]


@dataclasses.dataclass(frozen=True)
class Cell:
    """MuJoCo's model of a robot with bases (outermost first) and tools (flange first)."""

    model: mujoco.MjModel
    site: int
    qpos_indices: tuple[int, ...]
    limits: np.ndarray

    def _each(self, q: np.ndarray) -> tuple[mujoco.MjData, np.ndarray]:
        d = mujoco.MjData(self.model)
        rows = np.asarray(q, dtype=np.float64).reshape(-1, len(self.qpos_indices))
        return d, rows

    def poses(self, q: np.ndarray) -> np.ndarray:
        """``(..., 4, 4)`` world poses of the tool site for ``(..., n)`` joint values."""
        d, rows = self._each(q)
        out = np.empty((len(rows), 4, 4))
        for k, row in enumerate(rows):
            d.qpos[list(self.qpos_indices)] = row
            mujoco.mj_kinematics(self.model, d)
            out[k] = np.eye(4)
            out[k, :3, :3] = d.site_xmat[self.site].reshape(3, 3)
            out[k, :3, 3] = d.site_xpos[self.site]
        return out.reshape(*np.shape(q)[:-1], 4, 4)

    def jacobians(self, q: np.ndarray, convention: str) -> np.ndarray:
        """``(..., 6, n)`` Jacobians of the tool site from ``mj_jacSite``: world as MuJoCo
        gives them (``[jacr; jacp]``), space ``[w; v - w x p]``, body both rotated by ``R^T``."""
        d, rows = self._each(q)
        cols = list(self.qpos_indices)  # hinges and slides: qvel index = qpos index here
        out = np.empty((len(rows), 6, len(cols)))
        jacp, jacr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        for k, row in enumerate(rows):
            d.qpos[cols] = row
            mujoco.mj_forward(self.model, d)
            mujoco.mj_jacSite(self.model, d, jacp, jacr, self.site)
            w, v = jacr[:, cols], jacp[:, cols]
            p, R = d.site_xpos[self.site], d.site_xmat[self.site].reshape(3, 3)
            if convention == "space":
                v = v - np.cross(w.T, p).T
            elif convention == "body":
                w, v = R.T @ w, R.T @ v
            out[k] = np.vstack([w, v])
        return out.reshape(*np.shape(q)[:-1], 6, len(cols))

    def sample(self, count: int, seed: int) -> np.ndarray:
        lo = np.maximum(self.limits[:, 0], -np.pi)
        hi = np.minimum(self.limits[:, 1], np.pi)
        return np.random.default_rng(seed).uniform(lo, hi, (count, len(lo)))

    def check_answers(self, q: np.ndarray, T: np.ndarray, ok: np.ndarray, what: str) -> None:
        """Where ``ok``, ``q`` is within the limits and MuJoCo's pose of it is ``T``."""
        q, T, ok = np.asarray(q), np.asarray(T), np.asarray(ok, dtype=bool)
        lo, hi = self.limits[:, 0], self.limits[:, 1]
        assert np.all((q[ok] >= lo) & (q[ok] <= hi)), f"{what}: an answer outside the limits"
        assert_close(f"{what}: MuJoCo's pose of the answers", self.poses(q[ok]), T[ok], IK_TOL)


def mujoco_cell(
    robot: str, frame: str, bases: Sequence[Pose7] = (), tools: Sequence[Pose7] = ()
) -> Cell:
    """The model of ``robot`` (its spec as poekin compiles it for kinematics) edited into a
    cell: a body at ``frame`` (a site: where it is; a body: its origin) carrying a body per tool
    but the last, and the last tool as the site ``cell_tool``; the whole model then attached
    inside nested bodies posed at ``bases`` (outermost first)."""
    loaded = load_quiet(robot)
    m0 = loaded.model
    spec = kinematics_spec(robot)
    site = mujoco.mj_name2id(m0, mujoco.mjtObj.mjOBJ_SITE, frame)
    if site >= 0:
        body = spec.body(m0.body(int(m0.site_bodyid[site])).name)
        mount = body.add_body(name="cell_mount", pos=m0.site_pos[site], quat=m0.site_quat[site])
    else:
        mount = spec.body(frame)
    for k, tool in enumerate(tools):
        if k == len(tools) - 1:
            mount.add_site(name="cell_tool", pos=tool[:3], quat=tool[3:])
        else:
            mount = mount.add_body(name=f"cell_tool_{k}", pos=tool[:3], quat=tool[3:])
    if not tools:
        mount.add_site(name="cell_tool")
    prefix = ""
    if bases:
        cell = mujoco.MjSpec()
        for option in ("integrator", "impratio", "cone"):  # else MuJoCo warns of a conflict
            setattr(cell.option, option, getattr(spec.option, option))
        parent = cell.worldbody
        for k, b in enumerate(bases):
            parent = parent.add_body(name=f"cell_base_{k}", pos=b[:3], quat=b[3:])
        prefix = "robot/"
        cell.attach(spec, frame=parent.add_frame(), prefix=prefix)
        spec = cell
    model = spec.compile()
    chain = poekin.load(loaded, frame)
    assert chain.qpos_indices is not None
    # the edit changed nothing of the robot: its joints and limits are the model's
    assert model.nq == m0.nq and np.array_equal(model.jnt_range, m0.jnt_range)
    return Cell(model, model.site(prefix + "cell_tool").id, chain.qpos_indices, chain.limits)


ARMS = [
    ("universal_robots_ur5e", "attachment_site"),
    ("ufactory_lite6", "attachment_site"),
    ("franka_emika_panda", "hand"),
]


@pytest.fixture(scope="module", params=ARMS, ids=[a[0] for a in ARMS])
def arm(request: pytest.FixtureRequest) -> tuple[Chain, Chain, Cell]:
    """The arm as loaded, the same arm placed on ``BASE`` with ``TOOL``, and MuJoCo's cell."""
    robot, frame = request.param
    bare = poekin.load(load_quiet(robot), frame)
    placed = bare.with_base(BASE).with_tool(TOOL)
    return bare, placed, mujoco_cell(robot, frame, [BASE], [TOOL])


# --- forward kinematics and Jacobians ------------------------------------------------------


def test_fk_of_a_placed_arm_is_mujocos_in_every_form_and_path(
    arm: tuple[Chain, Chain, Cell],
) -> None:
    bare, placed, cell = arm
    q = cell.sample(500, seed=1)
    bare.fk(q), bare.jacobian_space(q)  # the unplaced chain's kernels run first
    expected = cell.poses(q)
    assert_close("fk (kernel)", placed.fk(q), expected, CELL_TOL)
    assert_close("fk_body (kernel)", placed.fk_body(q), expected, CELL_TOL)
    assert_close("fk (NumPy reference)", placed._fk_numpy(q), expected, CELL_TOL)
    assert_close("fk_body (NumPy reference)", placed._fk_body_numpy(q), expected, CELL_TOL)
    assert_close("fk one q", placed.fk(q[0]), expected[0], CELL_TOL)
    assert_close("fk (3, 1, 2) batch", placed.fk(q[:6].reshape(3, 1, 2, -1)),
                 expected[:6].reshape(3, 1, 2, 4, 4), CELL_TOL)  # fmt: skip
    pos_quat = placed.fk(q, form="pos_quat")
    assert_close("fk pos_quat", pos_quat[:, :3], expected[:, :3, 3], CELL_TOL)
    rotations = lie.quat_to_rotation(pos_quat[:, 3:])
    assert_close("fk pos_quat", rotations, expected[:, :3, :3], CELL_TOL)


@pytest.mark.parametrize("convention", ["space", "body", "world"])
def test_jacobians_of_a_placed_arm_are_mujocos(
    arm: tuple[Chain, Chain, Cell], convention: str
) -> None:
    _, placed, cell = arm
    q = cell.sample(300, seed=2)
    expected = cell.jacobians(q, convention)
    got = getattr(placed, f"jacobian_{convention}")(q)
    assert_close(f"jacobian_{convention} (kernel)", got, expected, CELL_TOL)
    reference = placed._jacobian_numpy(convention, q)
    assert_close(f"jacobian_{convention} (NumPy reference)", reference, expected, CELL_TOL)


@pytest.mark.parametrize("name", LIBRARIES)
def test_jax_and_pytorch_fk_and_jacobians_of_a_placed_arm_are_mujocos(
    arm: tuple[Chain, Chain, Cell], name: str
) -> None:
    lib = load_lib(name)
    _, placed, cell = arm
    q = cell.sample(50, seed=3)
    x = lib.asarray(q)
    assert_close(f"{name} fk", lib.numpy(placed.fk(x)), cell.poses(q), CELL_TOL)
    assert_close(f"{name} fk_body", lib.numpy(placed.fk_body(x)), cell.poses(q), CELL_TOL)
    params = placed.parameters(like=x)  # the differentiable path: no shortcut on the values
    assert_close(
        f"{name} fk with params", lib.numpy(placed.fk(x, params=params)), cell.poses(q), CELL_TOL
    )
    for convention in ("space", "body", "world"):
        J = lib.numpy(getattr(placed, f"jacobian_{convention}")(x))
        assert_close(f"{name} jacobian_{convention}", J, cell.jacobians(q, convention), CELL_TOL)


# --- inverse kinematics --------------------------------------------------------------------


def test_ik_of_a_placed_arm_reaches_mujocos_poses(arm: tuple[Chain, Chain, Cell]) -> None:
    bare, placed, cell = arm
    q_true = cell.sample(200, seed=4)
    T = cell.poses(q_true)  # targets of the tool, in the cell's world
    assert bare.ik(bare.fk(q_true[:5])).success.all()  # the unplaced chain's IK caches first
    found = placed.ik(T)
    assert found.success.all()
    cell.check_answers(found.q, T, found.success, "ik")
    assert not bare.ik(T[:20]).success.all()  # the targets are not the flange's in its base


@pytest.mark.parametrize("name", LIBRARIES)
def test_jax_and_pytorch_ik_of_a_placed_arm_reach_mujocos_poses(name: str) -> None:
    """One arm: JAX compiles the solve for each chain (15 s); the FK and Jacobians it solves
    with are checked on every arm above."""
    lib = load_lib(name)
    robot = "universal_robots_ur5e"
    placed = poekin.load(load_quiet(robot), base=BASE, tool=TOOL)
    cell = mujoco_cell(robot, "attachment_site", [BASE], [TOOL])
    T = cell.poses(cell.sample(12, seed=5))
    found = placed.ik(lib.asarray(T))
    ok = lib.numpy(found.success)
    assert ok.all()
    cell.check_answers(lib.numpy(found.q), T, ok, f"{name} ik")


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "ufactory_lite6"])
def test_every_closed_form_branch_of_a_placed_arm_is_checked_by_mujoco(robot: str) -> None:
    """``ik_all`` is written on the screws and M, which carry the base and the tool: every
    valid branch is an exact solution in MuJoCo's cell, the generating q is among them, and
    the placed arm has the branches the unplaced one has for the flange's pose in its base."""
    bare = poekin.load(load_quiet(robot))
    placed = bare.with_base(BASE).with_tool(TOOL)
    cell = mujoco_cell(robot, "attachment_site", [BASE], [TOOL])
    q_true = cell.sample(400, seed=6)
    T = cell.poses(q_true)
    flange = bare.fk(q_true)
    unplaced = bare.ik_all(flange)  # the unplaced chain's closed-form structure first
    found = placed.ik_all(T)
    k = found.q.shape[-2]
    assert found.valid.any(axis=-1).all()
    assert np.array_equal(found.valid.sum(axis=-1), unplaced.valid.sum(axis=-1))
    targets = np.broadcast_to(T[:, None], (len(T), k, 4, 4))
    cell.check_answers(found.q, targets, found.valid, "ik_all")
    q_ref, valid_ref = solve_numpy(placed, T)  # the NumPy reference, the kernel's twin
    assert np.array_equal(valid_ref, found.valid)
    cell.check_answers(q_ref, targets, valid_ref, "ik_all (NumPy reference)")
    turns = np.angle(np.exp(1j * (found.q - q_true[:, None, :])))  # wrapped differences
    nearest = np.where(found.valid, np.abs(turns).max(axis=-1), np.inf).min(axis=-1)
    assert nearest.max() < 1e-8, "the generating q is not among the valid branches"


# --- composition, loading and the tree ------------------------------------------------------


def test_tools_and_bases_compose_as_nested_bodies_in_mujoco() -> None:
    """``with_tool(A).with_tool(B)``: B in A's frame; ``with_base(A).with_base(B)``: A's world
    placed at B. MuJoCo nests the bodies: base B holds base A, tool A holds tool B."""
    robot = "universal_robots_ur5e"
    bare = poekin.load(load_quiet(robot))
    chain = bare.with_base(BASE).with_base(BASE_2).with_tool(TOOL).with_tool(TOOL_2)
    cell = mujoco_cell(robot, "attachment_site", [BASE_2, BASE], [TOOL, TOOL_2])
    q = cell.sample(300, seed=7)
    assert_close("fk", chain.fk(q), cell.poses(q), CELL_TOL)
    assert_close("fk_body", chain.fk_body(q), cell.poses(q), CELL_TOL)
    assert_close("jacobian_world", chain.jacobian_world(q), cell.jacobians(q, "world"), CELL_TOL)
    B, B_2, T, T_2 = (poekin.chain.rigid_transform(x, "") for x in (BASE, BASE_2, TOOL, TOOL_2))
    assert_close("base", chain.base, B_2 @ B, 1e-15)
    assert_close("tool", chain.tool, T @ T_2, 1e-15)
    once = bare.with_base(B_2 @ B).with_tool(T @ T_2)
    assert_close("in one step", once.fk(q), chain.fk(q), CELL_TOL)


def test_a_placed_chain_records_what_it_holds_and_keeps_the_rest() -> None:
    bare = poekin.load(load_quiet("universal_robots_ur5e"))
    assert np.array_equal(bare.base, np.eye(4)) and np.array_equal(bare.tool, np.eye(4))
    placed = bare.with_base(BASE).with_tool(TOOL, frame="gripper")
    assert placed.frame == "gripper" and bare.with_tool(TOOL).frame == "tool"
    assert placed.with_base(BASE).frame == "gripper"
    for same in ("joint_names", "joint_types", "robot", "qpos_indices"):
        assert getattr(placed, same) == getattr(bare, same)
    assert np.array_equal(placed.limits, bare.limits)
    assert not placed.base.flags.writeable and not placed.tool.flags.writeable
    assert repr(placed).endswith("with base and tool)") and "with" not in repr(bare)
    for copied in (pickle.loads(pickle.dumps(placed)), copy.deepcopy(placed)):
        assert np.array_equal(copied.base, placed.base) and copied.frame == "gripper"
        assert np.array_equal(copied.tool, placed.tool)
    # the record survives new parameters (calibration), and the unplaced arm is recovered
    again = placed.with_parameters(placed.parameters())
    assert np.array_equal(again.base, placed.base) and np.array_equal(again.tool, placed.tool)
    robot = placed._unplaced()
    assert_close("unplaced screws", robot.screws, bare.screws, 1e-15)
    assert_close("unplaced home", robot.home, bare.home, 1e-15)
    # the MuJoCo bookkeeping still holds: fk of the model's qpos entries is the tool's pose
    cell = mujoco_cell("universal_robots_ur5e", "attachment_site", [BASE], [TOOL])
    d = mujoco.MjData(cell.model)
    d.qpos[:] = cell.sample(1, seed=8)[0]
    assert_close("qpos_indices", placed.fk(d.qpos[list(placed.qpos_indices or ())]),
                 cell.poses(d.qpos[None])[0], CELL_TOL)  # fmt: skip


def test_load_with_base_and_tool_is_the_chain_placed() -> None:
    loaded = load_quiet("universal_robots_ur5e")
    chain = poekin.load(loaded, base=BASE, tool=TOOL)
    placed = poekin.load(loaded).with_base(BASE).with_tool(TOOL)
    assert np.array_equal(chain.screws, placed.screws)
    assert np.array_equal(chain.home, placed.home)
    assert np.array_equal(chain.base, placed.base) and np.array_equal(chain.tool, placed.tool)
    assert chain.frame == "tool"
    matrix = poekin.load(loaded, base=poekin.chain.rigid_transform(BASE, "base"))
    assert np.array_equal(matrix.screws, poekin.load(loaded, base=BASE).screws)


@pytest.mark.parametrize("robot", ["universal_robots_ur5e", "aloha"])
def test_a_tree_with_a_base_poses_every_frame_as_mujoco(robot: str) -> None:
    """Every body and site of the placed model (two arms on one base for ALOHA) against the
    same model attached inside a body posed at the base; a chain from the world records it."""
    loaded = load_quiet(robot)
    tree = poekin.load_tree(loaded, base=BASE)
    cell = mujoco_cell(robot, tree.site_names[0], [BASE])
    d = mujoco.MjData(cell.model)
    qpos = poekin.sample_qpos(tree, 100, seed=9)
    ids = [
        (cell.model.body if f < len(tree.body_names) else cell.model.site)("robot/" + name).id
        for f, name in enumerate(tree.frame_names)
    ]
    nb = len(tree.body_names)
    expected = np.tile(np.eye(4), (len(qpos), len(ids), 1, 1))
    for k, row in enumerate(qpos):
        d.qpos[:] = row
        mujoco.mj_kinematics(cell.model, d)
        expected[k, :nb, :3, :3] = d.xmat[ids[:nb]].reshape(-1, 3, 3)
        expected[k, :nb, :3, 3] = d.xpos[ids[:nb]]
        expected[k, nb:, :3, :3] = d.site_xmat[ids[nb:]].reshape(-1, 3, 3)
        expected[k, nb:, :3, 3] = d.site_xpos[ids[nb:]]
    poses = tree.fk(qpos)
    assert_close("every frame", poses, expected, CELL_TOL)
    chain = tree.chain(tree.site_names[0])
    assert_close("base", chain.base, poekin.chain.rigid_transform(BASE, "base"), 0.0)
    assert_close("chain", chain.fk(qpos[:, list(chain.qpos_indices or ())]),
                 poses[:, tree.frame_index(chain.frame)], CELL_TOL)  # fmt: skip
    assert np.array_equal(tree.chain(tree.site_names[0], base=tree.body_names[0]).base,
                          np.eye(4))  # fmt: skip
    B_2 = poekin.chain.rigid_transform(BASE_2, "base")
    assert np.array_equal(tree.with_base(BASE_2).base, B_2 @ tree.base)


def test_a_floating_base_is_placed_by_its_qpos_not_by_base() -> None:
    with pytest.raises(InputError, match=r"free joint.*qpos \(x y z qw qx qy qz\) places"):
        poekin.load_tree(load_quiet("unitree_go2"), base=BASE)


# --- DH extraction --------------------------------------------------------------------------


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_of_a_placed_arm_keeps_the_robots_rows(convention: str) -> None:
    """The rows are the arm's own; the base goes before the table's base, the tool after its
    tool; the table's FK is MuJoCo's cell's. Extracted from the screws alone (the record
    dropped), the rows would hold the base's height and the tool's length."""
    robot = "universal_robots_ur5e"
    bare = poekin.load(load_quiet(robot))
    placed = bare.with_base(BASE).with_tool(TOOL)
    mine, theirs = dh_from_chain(bare, convention), dh_from_chain(placed, convention)
    for row in ("a", "d"):
        assert_close(row, getattr(theirs, row), getattr(mine, row), 1e-14)
    for row in ("alpha", "theta_offset"):  # angles, to a whole turn
        turn = np.angle(np.exp(1j * (getattr(theirs, row) - getattr(mine, row))))
        assert_close(row, turn, np.zeros_like(turn), 1e-14)
    B, T = (poekin.chain.rigid_transform(x, "") for x in (BASE, TOOL))
    assert_close("base", theirs.base, B @ mine.base, 1e-15)
    assert_close("tool", theirs.tool, mine.tool @ T, 1e-15)
    assert theirs.frame == "tool" and "the rows are the robot's own" in theirs.notes[-1]
    cell = mujoco_cell(robot, "attachment_site", [BASE], [TOOL])
    q = cell.sample(200, seed=10)
    assert_close("DH fk", theirs.fk(q), cell.poses(q), 1e-13)  # DH's own trigonometry
    forgotten = Chain(placed.joint_names, placed.joint_types, placed.screws, placed.home)
    assert not np.allclose(dh_from_chain(forgotten, convention).d, mine.d, atol=1e-3)


# --- bad input ------------------------------------------------------------------------------

_FLIP = np.diag([1.0, 1.0, -1.0, 1.0])
_SKEW = np.eye(4)
_SKEW[0, 1] = 0.01
_NAN = np.eye(4)
_NAN[0, 3] = np.nan
_ROW = np.eye(4)
_ROW[3, 0] = 0.5


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (
            np.eye(3),
            r"must be a \(4, 4\) rigid transform or 7 numbers .* got an array of shape \(3, 3\)",
        ),
        ([0, 0, 0.1], r"or 7 numbers x y z qw qx qy qz .* shape \(3,\)"),
        (None, r"rigid transform or 7 numbers .* got None"),
        ("0 0 0 1 0 0 0", r"got '0 0 0 1 0 0 0'"),
        ([[1, 0], [0, 1, 2]], r"rigid transform or 7 numbers"),
        (_FLIP, r"not orthonormal with det \+1"),
        (_SKEW, r"not orthonormal with det \+1"),
        (_ROW, r"last row must be \[0, 0, 0, 1\]"),
        (_NAN, r"entries contain NaN or inf"),
        ([0, 0, 0, 0, 0, 0, 0], r"the quaternion is zero .* such as 1 0 0 0"),
        ([0, 0, 0, 2, 0, 0, 0], r"has norm 2, not 1 .* such as 1 0 0 0"),
        ([0, 0, 0, 1j, 0, 0, 0], r"must be real numbers"),
        (["a", 0, 0, 1, 0, 0, 0], r"must be numbers, got 'a'"),
        ([0, 0, np.inf, 1, 0, 0, 0], r"NaN or inf"),
    ],
)
@pytest.mark.parametrize("place", ["tool", "base"])
def test_a_tool_or_base_that_is_no_rigid_transform_is_an_input_error(
    value: object, message: str, place: str
) -> None:
    chain = poekin.load(load_quiet("universal_robots_ur5e"))
    method = chain.with_tool if place == "tool" else chain.with_base
    with pytest.raises(InputError, match=rf"^{place}\b.*{message}"):
        method(value)  # type: ignore[arg-type]
    if value is None:  # load(..., tool=None): no tool
        return
    with pytest.raises(InputError, match=rf"^{place}\b.*{message}"):  # before the model is read
        poekin.load("no_such_robot", **{place: value})  # type: ignore[arg-type]
    if place == "base":
        with pytest.raises(InputError, match=rf"^base\b.*{message}"):
            poekin.load_tree("no_such_robot", base=value)  # type: ignore[arg-type]


@pytest.mark.parametrize("frame", ["", None, 3])
def test_a_tool_frame_needs_a_name(frame: object) -> None:
    with pytest.raises(InputError, match="frame must be a non-empty name"):
        poekin.load(load_quiet("universal_robots_ur5e")).with_tool(TOOL, frame=frame)  # type: ignore[arg-type]


# --- the viewer's scene (poekin view, poekin draw) -------------------------------------------


def test_the_viewers_scene_of_a_placed_arm_is_mujocos() -> None:
    """The meshes' bodies stand on the base, the end frame drawn is the tool's, the tool a
    capsule from the flange's body to the tool's origin, the screws in the new world."""
    from poekin.viewer import scene
    from poekin.viewer.loading import load_shown

    robot = "universal_robots_ur5e"
    loaded = load_quiet(robot)
    subject = load_shown(loaded, base=BASE, tool=TOOL).subject
    assert subject.end_name == "tool on attachment_site"
    cell = mujoco_cell(robot, "attachment_site", [BASE], [TOOL])
    d = mujoco.MjData(cell.model)
    for q in cell.sample(20, seed=11):
        snap = scene.snapshot(subject, q)
        assert_close("end frame", snap.T, cell.poses(q), CELL_TOL)
        d.qpos[:] = q
        mujoco.mj_kinematics(cell.model, d)
        for b, name in enumerate(subject.body_names):
            i = cell.model.body("robot/" + name).id
            assert_close(f"body {name}", snap.bodies[b, :3, 3], d.xpos[i], CELL_TOL)
            assert_close(f"body {name}", snap.bodies[b, :3, :3], d.xmat[i].reshape(3, 3), CELL_TOL)
        space = cell.jacobians(q, "space").T
        assert_close("screws S_i(q)", snap.screws, space, CELL_TOL)
        tool = scene.skeleton(subject)[-1]
        body = snap.bodies[tool.body]
        assert_close("the tool's capsule ends at the tool", body[:3, :3] @ tool.b + body[:3, 3],
                     snap.T[:3, 3], CELL_TOL)  # fmt: skip
    assert_close(
        "home", scene.snapshot(subject, np.zeros(6)).home, cell.poses(np.zeros(6)), CELL_TOL
    )


def test_a_parameter_set_in_the_viewer_stands_on_its_base_with_its_tool() -> None:
    from poekin.viewer import scene
    from poekin.viewer.loading import load_shown

    table = poekin.named_params("ur5e-dh")
    subject = load_shown(table, base=BASE, tool=TOOL).subject
    assert subject.end_name == f"tool on {table.frame}" and subject.table is None
    placed = table.to_chain().with_base(BASE).with_tool(TOOL)
    q = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    assert_close("end frame", scene.snapshot(subject, q).T, placed.fk(q), 1e-15)
    links = scene.skeleton(subject)
    assert_close("the first link starts at the base", links[0].a, BASE[:3], 1e-15)
    assert_close("the last ends at the tool", links[-1].b, placed.home[:3, 3], 1e-15)


def test_the_viewers_ik_drags_the_tool() -> None:
    """A target is the tool's pose: the tree solves for the flange under it, the closed-form
    ghosts are the placed chain's; MuJoCo's cell checks the configurations shown."""
    from poekin.viewer import ik
    from poekin.viewer.loading import load_shown

    robot = "universal_robots_ur5e"
    subject = load_shown(load_quiet(robot), base=BASE, tool=TOOL).subject
    cell = mujoco_cell(robot, "attachment_site", [BASE], [TOOL])
    for q in cell.sample(5, seed=12):
        target = cell.poses(q)
        reached = ik.reach(subject, subject.qpos0, target)
        assert reached.success and len(reached.solutions) > 0
        cell.check_answers(reached.qpos[None], target[None], np.array([True]), "shown")
        every = np.broadcast_to(target, (len(reached.solutions), 4, 4))
        cell.check_answers(reached.solutions, every, np.ones(len(every), bool), "ghosts")


def test_your_parameters_beside_a_placed_arm_stand_on_its_base_with_its_tool() -> None:
    from poekin.viewer import scene
    from poekin.viewer.loading import load_params_comparison, load_shown

    subject = load_shown(load_quiet("universal_robots_ur5e"), base=BASE, tool=TOOL).subject
    comparison = load_params_comparison(subject, "ur5e-dh")
    assert comparison is not None
    q = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    snap = scene.snapshot(subject, q)
    mine = scene.ghost(comparison, snap, aligned=False)
    assert mine.pos_err < 2e-3  # the two parameter sets of one arm: the model rounds to 1 mm
    unplaced = load_params_comparison(load_shown(load_quiet("universal_robots_ur5e")).subject,
                                      "ur5e-dh")  # fmt: skip
    assert unplaced is not None  # the same findings: a base and a tool both have
    d, d0 = comparison.diagnosis, unplaced.diagnosis
    assert len(d.findings) == len(d0.findings) and d.max_pos_err_m < 2e-3
    assert abs(d.max_pos_err_m - d0.max_pos_err_m) < 1e-9
    nominal = poekin.named_params("ur5e-dh").to_chain()
    assert_close(
        "yours, placed",
        comparison.yours.fk(q),
        nominal.with_base(BASE).with_tool(TOOL).fk(q),
        1e-15,
    )


def test_a_tool_on_a_floating_frame_or_a_base_under_a_free_joint_is_refused() -> None:
    from poekin.viewer.loading import load_shown

    go2 = load_quiet("unitree_go2")
    with pytest.raises(InputError, match="behind a ball or free joint"):
        load_shown(go2, "FL_calf", tool=TOOL)
    with pytest.raises(InputError, match="free joint"):
        load_shown(go2, base=BASE)
    with pytest.raises(InputError, match=r"^tool: the quaternion is zero"):
        load_shown("no_such_robot", tool=[0, 0, 0, 0, 0, 0, 0])


# --- the command line ------------------------------------------------------------------------


def test_the_command_line_places_the_arm_and_its_tool(capsys: pytest.CaptureFixture[str]) -> None:
    """``--base`` and ``--tool`` on fk, jacobian, ik (numerical and --all), screws and dh: the
    numbers MuJoCo's cell gives, or the placed chain's where MuJoCo has none (its screws)."""
    from helpers import run

    robot = "universal_robots_ur5e"
    cell = mujoco_cell(robot, "attachment_site", [BASE], [TOOL])
    placed = poekin.load(load_quiet(robot), base=BASE, tool=TOOL)
    where = ["--base", *_texts(BASE), "--tool", *_texts(TOOL)]
    q = cell.sample(1, seed=13)[0]
    T = cell.poses(q)

    def cli(*argv: str) -> dict[str, object]:
        code, out, err = run(capsys, *argv, *where, "--json")
        assert code == 0, err
        return json.loads(out)  # type: ignore[no-any-return]

    got = cli("fk", robot, "--q", *_texts(q))
    assert got["frame"] == "tool"
    assert_close("fk", np.array(got["T"]), T, CELL_TOL)
    for convention in ("space", "body", "world"):
        got = cli("jacobian", robot, "--q", *_texts(q), "--convention", convention)
        assert_close(f"jacobian {convention}", np.array(got["J"]), cell.jacobians(q, convention),
                     CELL_TOL)  # fmt: skip
    pose = [*_texts(T[:3, 3]), *_texts(lie.rotation_to_quat(T[:3, :3]))]
    got = cli("ik", robot, "--pose", *pose)
    assert got["success"] and got["frame"] == "tool"
    cell.check_answers(np.array([got["q"]]), T[None], np.array([True]), "poekin ik")
    got = cli("ik", robot, "--pose", *pose, "--all")
    q_all, valid = np.array(got["q"]), np.array(got["valid"])
    assert valid.any()
    cell.check_answers(q_all, np.broadcast_to(T, (len(q_all), 4, 4)), valid, "poekin ik --all")
    got = cli("screws", robot)
    assert got["frame"] == "tool"
    assert_close("screws", np.array([j["screw"] for j in got["joints"]]), placed.screws, 0.0)
    assert_close("home", np.array(got["home"]), placed.home, 0.0)
    got = cli("dh", robot)
    assert_close("dh base", np.array(got["base"]), dh_from_chain(placed).base, 0.0)
    assert_close("dh tool", np.array(got["tool"]), dh_from_chain(placed).tool, 0.0)


def test_the_command_lines_tree_modes_take_a_base(capsys: pytest.CaptureFixture[str]) -> None:
    from helpers import run

    robot = "universal_robots_ur5e"
    cell = mujoco_cell(robot, "attachment_site", [BASE])
    q = cell.sample(1, seed=14)[0]
    base = ["--base", *_texts(BASE)]
    code, out, err = run(capsys, "fk", robot, "--tree", "--frame", "wrist_2_link",
                         "--q", *_texts(q), *base, "--json")  # fmt: skip
    assert code == 0, err
    d = mujoco.MjData(cell.model)
    d.qpos[:] = q
    mujoco.mj_kinematics(cell.model, d)
    i = cell.model.body("robot/wrist_2_link").id
    T = np.array(json.loads(out)["T"])
    assert_close("fk --tree --base", T[:3, :3], d.xmat[i].reshape(3, 3), CELL_TOL)
    assert_close("fk --tree --base", T[:3, 3], d.xpos[i], CELL_TOL)
    pose = [*_texts(T[:3, 3]), *_texts(lie.rotation_to_quat(T[:3, :3]))]
    code, out, err = run(capsys, "ik", robot, "--tree", "--frame", "wrist_2_link",
                         "--pose", *pose, *base, "--json")  # fmt: skip
    assert code == 0, err
    d.qpos[:] = json.loads(out)["q"]
    mujoco.mj_kinematics(cell.model, d)
    assert_close("ik --tree --base", d.xpos[i], T[:3, 3], IK_TOL)
    assert_close("ik --tree --base", d.xmat[i].reshape(3, 3), T[:3, :3], IK_TOL)


def test_draw_shows_the_tool(tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]) -> None:
    from helpers import run

    out = tmp_path / "cell.png"
    code, _, err = run(capsys, "draw", "--q", *"000000", "--base", *_texts(BASE),
                       "--tool", *_texts(TOOL), "--out", str(out))  # fmt: skip
    assert code == 0 and out.stat().st_size > 0, err
    fig = poekin.draw(load_quiet("universal_robots_ur5e"), np.zeros(6), base=BASE, tool=TOOL)
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert "T(q): tool on attachment_site" in texts
