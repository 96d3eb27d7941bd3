"""``poekin ik`` (issue 21 item 5): every answer the command prints or writes is checked by
MuJoCo's ``mj_forward`` and the joint limits (never by the solver's own residual); exit codes 0,
1 and 2; the ``--json`` keys; ``--all`` on the UR5e; ``--deg`` both ways; batches from files,
with an unreachable row; trees; position-only targets. Bad input is in test_cli's BAD_INPUTS."""

from __future__ import annotations

import io
import json
import pathlib
from typing import Any

import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_pose, run
from test_ik_numerical import arm, mj_poses

import poekin
from poekin.cli import _ik
from poekin.cli._args import JointSpace
from poekin.ik._angles import within_limits
from poekin.io.fileio import read_array

TOL = 1e-10  # the command's default tolerances
Q_TRUE = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])  # a UR5e configuration within its limits
JSON_KEYS = [
    "robot",
    "frame",
    "target",
    "position_only",
    "joints",
    "deg",
    "q",
    "success",
    "pos_err",
    "ori_err",
    "iterations",
    "attempts",
    "seed",
]


def pose_args(T: np.ndarray) -> list[str]:
    """``--pose`` values for a pose: x y z, then its unit quaternion w x y z, every bit kept."""
    return [repr(float(x)) for x in (*T[:3, 3], *poekin.rotation_to_quat(T[:3, :3]))]


def ur5e_target(q: np.ndarray = Q_TRUE) -> np.ndarray:
    loaded, chain = arm("ur5e")
    return mj_poses(loaded, chain, q[None])[0]  # MuJoCo's pose, not poekin's


def assert_reaches(name: str, q: np.ndarray, T: np.ndarray, tol: float = TOL) -> None:
    """``q`` (rad; ``(m, n)``) within the limits and at the targets ``T`` by MuJoCo."""
    loaded, chain = arm(name)
    q = np.asarray(q).reshape(-1, chain.n_joints)
    assert within_limits(q, chain.limits).all(), "an answer outside the joint limits"
    pos, ori = poekin.pose_errors(np.broadcast_to(T, (len(q), 4, 4)), mj_poses(loaded, chain, q))
    assert pos.max() <= tol + MJ_TOL and ori.max() <= tol + MJ_TOL, (pos.max(), ori.max())


def only_notes(err: str) -> bool:
    """No error on stderr: notes at most (the XML-only models' kinematics-only note)."""
    return all(line.startswith("poekin: note: ") for line in err.splitlines())


def ik_json(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict[str, Any]]:
    code, out, _ = run(capsys, "ik", *argv, "--json")
    return code, json.loads(out)


# --- one pose --------------------------------------------------------------------------------


def test_one_pose_json_is_checked_by_mujoco(capsys: pytest.CaptureFixture[str]) -> None:
    T = ur5e_target()
    code, got = ik_json(capsys, "universal_robots_ur5e", "--pose", *pose_args(T))
    assert code == 0 and list(got) == JSON_KEYS
    assert got["success"] is True and got["frame"] == "attachment_site" and got["seed"] == 0
    assert got["pos_err"] <= TOL and got["ori_err"] <= TOL
    assert got["iterations"] >= 1 and got["attempts"] >= 1
    assert_reaches("ur5e", np.array(got["q"]), T)
    # the same seed, the same bits; another seed, another start
    assert ik_json(capsys, "universal_robots_ur5e", "--pose", *pose_args(T))[1] == got
    other = ik_json(capsys, "universal_robots_ur5e", "--pose", *pose_args(T), "--seed", "7")[1]
    assert other["seed"] == 7 and other["success"] and other["q"] != got["q"]
    assert_reaches("ur5e", np.array(other["q"]), T)


def test_text_output_names_every_joint_with_its_unit(capsys: pytest.CaptureFixture[str]) -> None:
    T = ur5e_target()
    code, out, err = run(capsys, "ik", "universal_robots_ur5e", "--pose", *pose_args(T))
    lines = out.splitlines()
    assert code == 0 and only_notes(err)
    assert lines[0].startswith("universal_robots_ur5e  frame 'attachment_site'  target xyz")
    assert lines[1].startswith("SOLVED: residual ") and "tolerances 1e-10 m, 1e-10 rad" in lines[1]
    _, chain = arm("ur5e")
    rows = [ln.split() for ln in lines[2:]]
    assert [r[0] for r in rows] == list(chain.joint_names) and {r[2] for r in rows} == {"rad"}
    assert_reaches("ur5e", np.array([float(r[1]) for r in rows]), T, tol=1e-6)  # 6 decimals


def test_an_unreachable_pose_exits_1_with_the_best_fit(capsys: pytest.CaptureFixture[str]) -> None:
    T = ur5e_target()
    T[:3, 3] = [2.5, 0.0, 0.5]  # the UR5e reaches 0.85 m
    code, got = ik_json(capsys, "universal_robots_ur5e", "--pose", *pose_args(T))
    assert code == 1 and got["success"] is False and got["attempts"] == 100
    loaded, chain = arm("ur5e")
    q = np.array(got["q"])
    assert within_limits(q, chain.limits)
    pos, _ = poekin.pose_errors(T, mj_poses(loaded, chain, q[None])[0])
    assert got["pos_err"] == pytest.approx(float(pos), rel=1e-9) and pos > 1.5
    code, out, _ = run(capsys, "ik", "universal_robots_ur5e", "--pose", *pose_args(T))
    assert code == 1 and out.splitlines()[1].startswith("NOT SOLVED: residual 1.")


def test_deg_round_trip(capsys: pytest.CaptureFixture[str]) -> None:
    """fk --deg gives a pose; ik --deg from --q0 in degrees answers that configuration, in
    degrees; fk --deg of the answer gives the pose back."""
    q_deg = [f"{x:.6f}" for x in np.degrees(Q_TRUE)]
    code, out, _ = run(
        capsys,
        "fk",
        "universal_robots_ur5e",
        "--q",
        *q_deg,
        "--deg",
        "--form",
        "pos_quat",
        "--json",
    )
    pose = [repr(x) for x in json.loads(out)["pos_quat"]]
    code, got = ik_json(capsys, "universal_robots_ur5e", "--pose", *pose, "--q0", *q_deg, "--deg")
    assert code == 0 and got["deg"] is True and got["iterations"] <= 3
    np.testing.assert_allclose(got["q"], np.array(q_deg, float), atol=1e-9)  # degrees
    T = ur5e_target(np.radians(np.array(q_deg, float)))
    assert_reaches("ur5e", np.radians(got["q"]), T)
    code, out, _ = run(capsys, "fk", "universal_robots_ur5e", "--q", *map(repr, got["q"]), "--deg")
    assert code == 0
    back = np.array([[float(x) for x in ln.split()] for ln in out.splitlines()[1:]])
    np.testing.assert_allclose(back, T, atol=1e-6)  # as printed: 6 decimals


def test_all_gives_every_ur5e_solution(capsys: pytest.CaptureFixture[str]) -> None:
    T = ur5e_target()
    code, got = ik_json(capsys, "universal_robots_ur5e", "--pose", *pose_args(T), "--all")
    assert code == 0 and got["success"] is True
    assert {"solutions", "valid", "q", "pos_err", "ori_err", "geometry"} <= set(got)
    solutions, valid = np.array(got["solutions"]), np.array(got["valid"])
    assert solutions.shape == (8, 6) and valid.shape == (8,) and valid.sum() >= 2
    np.testing.assert_array_equal(got["q"], solutions[valid])
    assert_reaches("ur5e", solutions[valid], T, tol=1e-12)
    gap = np.abs(np.angle(np.exp(1j * (solutions[valid] - Q_TRUE)))).max(axis=-1)
    assert gap.min() < 1e-9, "the configuration the target came from is among the solutions"
    code, out, _ = run(capsys, "ik", "universal_robots_ur5e", "--pose", *pose_args(T), "--all")
    lines = out.splitlines()
    assert code == 0 and lines[1].startswith("SOLVED: three parallel axes (2, 3, 4)")
    rows = [ln.split() for ln in lines[4:]]
    assert len(rows) == 8 and [r[1] == "yes" for r in rows] == valid.tolist()


# --- batches ---------------------------------------------------------------------------------


def test_a_batch_with_an_unreachable_row_exits_1(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    loaded, chain = arm("ur5e")
    q_true = np.random.default_rng(5).uniform(chain.limits[:, 0], chain.limits[:, 1], (30, 6))
    T = mj_poses(loaded, chain, q_true)
    T[7, :3, 3] = [0.0, 2.5, 0.5]
    np.save(tmp_path / "T.npy", T)
    code, out, err = run(
        capsys, "ik", "universal_robots_ur5e", "--input", str(tmp_path / "T.npy"), "--output",
        str(tmp_path / "q.npz"),
    )  # fmt: skip
    assert code == 1 and only_notes(err)
    assert "NOT SOLVED: 1 of 30 targets (row 7), worst residual" in out
    with np.load(tmp_path / "q.npz") as saved:
        q, success = saved["q"], saved["success"]
        assert list(saved["joints"]) == list(chain.joint_names)
        assert set(saved) == {"q", "joints", "success", "pos_err", "ori_err", "iterations",
                              "attempts"}  # fmt: skip
    assert q.shape == (30, 6) and np.flatnonzero(~success).tolist() == [7]
    assert_reaches("ur5e", q[success], T[success])
    assert within_limits(q, chain.limits).all()
    # a .npy holds q only, and a note says where the flags go
    code, _, err = run(
        capsys, "ik", "universal_robots_ur5e", "--input", str(tmp_path / "T.npy"), "--output",
        str(tmp_path / "q.npy"),
    )  # fmt: skip
    assert code == 1 and only_notes(err) and "holds q only: write a .npz" in err
    np.testing.assert_array_equal(np.load(tmp_path / "q.npy"), q)


@pytest.mark.parametrize(
    "header", ["x,y,z,qw,qx,qy,qz", "qw,qx,qy,qz,x,y,z", "y,x,z,qz,qy,qx,qw", "T"]
)
def test_a_target_files_columns_are_read_by_their_header(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str], header: str
) -> None:
    """Issue 26: columns were read by position whatever the header said (``y,x,z,...``
    solved the wrong targets). In any order the header gives, the solutions reach the poses
    MuJoCo computes, row for row; a 4x4 file's T00..T33 likewise, shuffled."""
    loaded, chain = arm("ur5e")
    q_true = np.random.default_rng(6).uniform(chain.limits[:, 0], chain.limits[:, 1], (8, 6))
    T = mj_poses(loaded, chain, q_true)
    if header == "T":
        names = [f"T{i}{j}" for i in range(4) for j in range(4)]
        values = {n: T[:, int(n[1]), int(n[2])] for n in names}
        names = names[::-1]
    else:
        quat = poekin.rotation_to_quat(T[:, :3, :3])
        values = dict(zip("xyz", T[:, :3, 3].T, strict=True))
        values |= dict(zip(["qw", "qx", "qy", "qz"], quat.T, strict=True))
        names = header.split(",")
    rows = np.stack([values[n] for n in names], axis=1)
    path = tmp_path / "targets.csv"
    lines = [",".join(names), "# a comment line", *(",".join(f"{x:.17g}" for x in r) for r in rows)]
    path.write_text("\n".join(lines) + "\n")
    code, _, err = run(capsys, "ik", "universal_robots_ur5e", "--input", str(path), "--output",
                       str(tmp_path / "q.npy"))  # fmt: skip
    assert code == 0 and only_notes(err), err
    q = np.load(tmp_path / "q.npy")
    pos, ori = poekin.pose_errors(T, mj_poses(loaded, chain, q))
    assert pos.max() <= 1e-10 + MJ_TOL and ori.max() <= 1e-10 + MJ_TOL


@pytest.mark.parametrize("form", ["matrix", "pos_quat"])
def test_what_fk_writes_ik_reads(
    form: str, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """fk's (N, 16) and (N, 7) text rows back to joint values, checked by MuJoCo."""
    loaded, chain = arm("ur5e")
    q_true = np.random.default_rng(6).uniform(chain.limits[:, 0], chain.limits[:, 1], (20, 6))
    np.save(tmp_path / "q.npy", q_true)
    poses, answers = str(tmp_path / "T.csv"), str(tmp_path / "q_ik.txt")
    argv = ["universal_robots_ur5e", "--input", str(tmp_path / "q.npy"), "--output", poses]
    assert run(capsys, "fk", *argv, "--form", form)[0] == 0
    code, out, _ = run(capsys, "ik", "universal_robots_ur5e", "--input", poses, "--output", answers)
    assert code == 0 and "SOLVED: all 20 targets" in out
    assert_reaches("ur5e", read_array(answers), mj_poses(loaded, chain, q_true))


def test_what_ik_writes_with_its_flags_fk_reads(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An .npz of answers holds q beside success and the residuals: fk reads its q, and the
    poses are MuJoCo's; an archive with several arrays and none named q is refused."""
    loaded, chain = arm("ur5e")
    q_true = np.random.default_rng(7).uniform(chain.limits[:, 0], chain.limits[:, 1], (10, 6))
    np.save(tmp_path / "q.npy", q_true)
    poses, answers, again = (str(tmp_path / n) for n in ("T.npz", "q_ik.npz", "T_ik.npy"))
    robot = "universal_robots_ur5e"
    assert run(capsys, "fk", robot, "--input", str(tmp_path / "q.npy"), "--output", poses)[0] == 0
    assert run(capsys, "ik", robot, "--input", poses, "--output", answers)[0] == 0
    assert set(np.load(answers)) >= {"q", "success", "pos_err", "ori_err"}
    assert run(capsys, "fk", robot, "--input", answers, "--output", again)[0] == 0
    T = np.load(again)
    pos, ori = poekin.pose_errors(mj_poses(loaded, chain, q_true), T)
    assert pos.max() <= 1e-10 and ori.max() <= 1e-10  # ik's tolerances, by MuJoCo's poses
    np.savez(tmp_path / "two.npz", a=q_true, b=q_true)
    code, _, err = run(
        capsys,
        "fk",
        robot,
        "--input",
        str(tmp_path / "two.npz"),
        "--output",
        str(tmp_path / "T_two.npy"),
    )
    assert code == 2 and "or one with an array named 'q'" in err


def test_all_on_a_batch_marks_invalid_branches_nan(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    loaded, chain = arm("ur5e")
    q_true = np.random.default_rng(7).uniform(chain.limits[:, 0], chain.limits[:, 1], (10, 6))
    T = mj_poses(loaded, chain, q_true)
    T[2, :3, 3] *= 5  # out of reach
    np.save(tmp_path / "T.npy", T)
    code, out, _ = run(
        capsys, "ik", "universal_robots_ur5e", "--input", str(tmp_path / "T.npy"), "--output",
        str(tmp_path / "q.npz"), "--all",
    )  # fmt: skip
    assert code == 1 and "NOT SOLVED: 1 of 10 targets have no valid solution (row 2)" in out
    with np.load(tmp_path / "q.npz") as saved:
        q, valid = saved["q"], saved["valid"]
    assert q.shape == (10, 8, 6) and not valid[2].any() and valid.any(axis=1).sum() == 9
    assert np.isnan(q[~valid]).all() and np.isfinite(q[valid]).all()
    which = np.nonzero(valid)[0]
    assert_reaches("ur5e", q[valid], T[which], tol=1e-12)


def test_a_progress_bar_splits_the_batch_without_changing_a_bit(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    loaded, chain = arm("panda")
    q_true = np.random.default_rng(8).uniform(chain.limits[:, 0], chain.limits[:, 1], (25, 7))
    np.save(tmp_path / "T.npy", mj_poses(loaded, chain, q_true))
    argv = ["ik", "franka_emika_panda", "--frame", "hand", "--input", str(tmp_path / "T.npy")]
    assert run(capsys, *argv, "--output", str(tmp_path / "whole.npy"))[0] == 0

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    calls: list[int] = []
    solve = poekin.Chain.ik

    def counting(self: poekin.Chain, T: np.ndarray, *args: Any, **kwargs: Any) -> Any:
        calls.append(len(T))
        return solve(self, T, *args, **kwargs)

    monkeypatch.setattr(poekin.Chain, "ik", counting)
    monkeypatch.setattr(_ik, "CHUNK", 10)
    monkeypatch.setattr("sys.stderr", Terminal())
    assert run(capsys, *argv, "--output", str(tmp_path / "split.npy"))[0] == 0
    assert calls == [10, 10, 5]
    np.testing.assert_array_equal(np.load(tmp_path / "split.npy"), np.load(tmp_path / "whole.npy"))
    assert_reaches("panda", np.load(tmp_path / "whole.npy"), mj_poses(loaded, chain, q_true))


# --- trees, parameter sets, position-only ------------------------------------------------------


def test_tree_frame_holds_the_other_joints(capsys: pytest.CaptureFixture[str]) -> None:
    model = load_quiet("aloha").model
    tree = poekin.load_tree(load_quiet("aloha"))
    qpos = poekin.sample_qpos(tree, 2, seed=1, within_limits=True)
    T = mj_pose(model, qpos[:1], "left/gripper")[0]
    held = [repr(float(x)) for x in qpos[1]]  # another configuration to hold the right arm at
    code, got = ik_json(
        capsys, "aloha", "--tree", "--frame", "left/gripper", "--pose", *pose_args(T), "--qpos",
        *held,
    )  # fmt: skip
    q = np.array(got["q"])
    assert code == 0 and got["success"] and len(got["joints"]) == tree.nq == len(q)
    assert got["solved"] == [f"left/{j}" for j in ("waist", "shoulder", "elbow", "forearm_roll",
                                                    "wrist_angle", "wrist_rotate")]  # fmt: skip
    np.testing.assert_array_equal(q[6:], qpos[1, 6:])
    pos, ori = poekin.pose_errors(T, mj_pose(model, q[None], "left/gripper")[0])
    assert pos <= TOL + MJ_TOL and ori <= TOL + MJ_TOL
    code, out, _ = run(capsys, "ik", "aloha", "--tree", "--frame", "left/gripper", "--pose",
                       *pose_args(T))  # fmt: skip
    assert code == 0 and out.splitlines()[-1] == (
        "the other 10 qpos values held at qpos0 (--json gives the whole qpos)"
    )


def test_a_tree_batch_writes_whole_qpos(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = load_quiet("aloha").model
    tree = poekin.load_tree(load_quiet("aloha"))
    qpos = poekin.sample_qpos(tree, 8, seed=4, within_limits=True)
    np.save(tmp_path / "T.npy", mj_pose(model, qpos, "right/gripper"))
    code, out, _ = run(
        capsys, "ik", "aloha", "--tree", "--frame", "right/gripper", "--input",
        str(tmp_path / "T.npy"), "--output", str(tmp_path / "qpos.npz"),
    )  # fmt: skip
    assert code == 0 and "SOLVED: all 8 targets" in out
    with np.load(tmp_path / "qpos.npz") as saved:
        q = saved["q"]
    assert q.shape == (8, tree.nq) and (q[:, :8] == tree.qpos0[:8]).all()  # the left arm held
    limits = JointSpace.of_tree(tree).limits  # +-inf where a qpos entry has none
    assert ((q >= limits[:, 0]) & (q <= limits[:, 1])).all()
    pos, ori = poekin.pose_errors(
        mj_pose(model, qpos, "right/gripper"), mj_pose(model, q, "right/gripper")
    )
    assert pos.max() <= TOL + MJ_TOL and ori.max() <= TOL + MJ_TOL


def test_position_only_takes_three_numbers(capsys: pytest.CaptureFixture[str]) -> None:
    loaded = load_quiet("trs_so_arm100")
    chain = poekin.load(loaded, "Fixed_Jaw")
    q = np.random.default_rng(9).uniform(chain.limits[:, 0], chain.limits[:, 1], (1, 5))
    p = mj_poses(loaded, chain, q)[0, :3, 3]
    code, got = ik_json(
        capsys,
        "trs_so_arm100",
        "--frame",
        "Fixed_Jaw",
        "--pose",
        *(repr(float(x)) for x in p),
        "--position-only",
    )
    assert code == 0 and got["success"] and got["position_only"] is True
    reached = mj_poses(loaded, chain, np.array([got["q"]]))[0, :3, 3]
    assert np.linalg.norm(reached - p) <= TOL + MJ_TOL
    assert within_limits(np.array(got["q"]), chain.limits)


def test_a_parameter_set_is_solved(capsys: pytest.CaptureFixture[str]) -> None:
    """--params: a DH table, checked by the table's own DH product (not the PoE solver's FK)."""
    table = poekin.named_params("ur5e-dh")
    T = table.fk(Q_TRUE)
    code, got = ik_json(capsys, "--params", "ur5e-dh", "--pose", *pose_args(T))
    assert code == 0 and got["success"] and got["robot"] == "ur5e-dh"
    pos, ori = poekin.pose_errors(T, table.fk(np.array(got["q"])))
    assert pos <= TOL + 1e-12 and ori <= TOL + 1e-12


def test_all_refines_a_calibrated_arm_and_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 26: --all on a calibrated UR refused (0.07 deg from parallel); it refines the
    nearest ideal geometry's branches now, with a note, and --no-refine refuses as before."""
    cal = str(pathlib.Path(__file__).resolve().parents[1] / "data" / "ur" / "ur5e_calibration.yaml")
    argv = ["ik", "--params", cal, "--pose", "0.4", "0.2", "0.5", "0", "1", "0", "0", "--all"]
    code, out, err = run(capsys, *argv)
    assert code == 0 and "is near, not on, the closed form's geometry (axes 2 and 3" in err
    assert (
        "SOLVED: nearest three parallel axes (2, 3, 4), axes 5 and 6 meet, refined: 8 of 8" in out
    )
    chain = poekin.load_params(cal)
    rows = [ln.split() for ln in out.splitlines() if ln.strip()[:1].isdigit()]
    q = np.array([[float(x) for x in r[2:]] for r in rows])
    target = poekin.homogeneous(np.diag([1.0, -1.0, -1.0]), [0.4, 0.2, 0.5])  # quat 0 1 0 0
    pos, ori = poekin.pose_errors(chain.fk(q), target)
    assert pos.max() < 1e-5 and ori.max() < 1e-5  # q as printed, to 6 decimals
    code, out, err = run(capsys, *argv, "--no-refine")
    assert code == 2 and "axes 2 and 3 are not parallel: 0.07 deg" in err and out == ""
