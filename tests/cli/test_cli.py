"""The poekin command line: outputs, exit codes, and one-line errors without tracebacks."""

from __future__ import annotations

import csv
import json
import os
import pathlib
import subprocess
import sys
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from helpers import MJ_TOL, SUMMARY_KEYS, assert_close, assert_one_error_line, load_quiet, run

import poekin
from poekin import load
from poekin.cli import main
from poekin.verification.metrics import METRICS_HEADER

UR5E_XML = pathlib.Path(os.environ["MENAGERIE_ROOT"]) / "universal_robots_ur5e" / "ur5e.xml"


def test_verify_json(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "verify", "--samples", "200", "--json")
    result = json.loads(out)
    assert code == 0
    assert list(result) == SUMMARY_KEYS
    assert result["robot"] == "universal_robots_ur5e"
    assert result["frame"] == "attachment_site"
    assert result["samples"] == 200 and result["passed"] is True
    assert result["max_pos_err_m"] <= MJ_TOL and result["max_ori_err_rad"] <= MJ_TOL


def test_verify_text_plot_and_metrics(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    plot, metrics = tmp_path / "fk.png", tmp_path / "metrics.csv"
    code, out, _ = run(
        capsys, "verify", "--samples", "100", "--plot", str(plot), "--metrics", str(metrics)
    )
    assert code == 0
    assert "space PoE" in out and "body PoE" in out and "PASS" in out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, _, _ = run(capsys, "verify", "--samples", "100", "--seed", "3", "--metrics", str(metrics))
    assert code == 0
    with metrics.open(newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == METRICS_HEADER
    assert len(rows) == 1 + 16  # header once, 2 methods x 4 metrics per run
    records = [dict(zip(METRICS_HEADER, r, strict=True)) for r in rows[1:]]
    assert {r["metric"] for r in records} == {
        "max_pos_err_m",
        "median_pos_err_m",
        "max_ori_err_rad",
        "median_ori_err_rad",
    }
    assert {r["method"] for r in records} == {"space_poe", "body_poe"}
    assert {r["experiment"] for r in records} == {"fk_verify_ur5e"}
    assert {r["seed"] for r in records} == {"0", "3"}
    assert len({r["model_sha"] for r in records}) == 1
    assert all(float(r["value"]) <= MJ_TOL for r in records)


def test_verify_fails_with_exit_1_when_out_of_tolerance(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "verify", "--samples", "20", "--pos-tol", "1e-18", "--json")
    assert code == 1
    assert json.loads(out)["passed"] is False


def test_verify_other_robot_and_frame(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(
        capsys,
        "verify",
        "franka_emika_panda",
        "--frame",
        "hand",
        "--samples",
        "50",
        "--within-limits",
        "--json",
    )
    assert code == 0 and json.loads(out)["frame"] == "hand"
    assert err.count("\n") == 1 and "kinematics only" in err


def test_screws(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "screws", "universal_robots_ur5e", "--json")
    info = json.loads(out)
    chain = load("universal_robots_ur5e")
    assert code == 0
    assert_close("screws", [j["screw"] for j in info["joints"]], chain.screws, 0.0)
    assert_close("body screws", [j["body_screw"] for j in info["joints"]], chain.body_screws, 0.0)
    assert_close("home", info["home"], chain.home, 0.0)
    code, out, _ = run(capsys, "screws", str(UR5E_XML), "--body")
    assert code == 0 and "body screws B_i" in out and "wrist_3_joint" in out


def test_fk_single(capsys: pytest.CaptureFixture[str]) -> None:
    q = [0.1, -1.2, 1.3, 0.4, -0.5, 2.0]
    code, out, _ = run(capsys, "fk", "universal_robots_ur5e", "--json", "--q", *map(str, q))
    assert code == 0
    assert_close("T", json.loads(out)["T"], load("universal_robots_ur5e").fk(q), 0.0)
    code, out, _ = run(capsys, "fk", "universal_robots_ur5e", "--q", *map(str, q))
    assert code == 0 and out.startswith("T_world_attachment_site =")


def test_fk_batch_files(capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path) -> None:
    q = np.random.default_rng(0).uniform(-3, 3, size=(7, 6))
    np.save(tmp_path / "q.npy", q)
    out_path = tmp_path / "T.npy"
    argv = ["fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.npy")]
    code, _, _ = run(capsys, *argv, "--output", str(out_path))
    assert code == 0
    assert_close("T.npy", np.load(out_path), load("universal_robots_ur5e").fk(q), 0.0)
    before = out_path.read_bytes()
    code, _, err = run(capsys, *argv, "--output", str(out_path))
    assert code == 2 and "already exists" in err and "--force" in err
    assert out_path.read_bytes() == before


def test_jacobian_text_json_and_npy(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    chain = load("universal_robots_ur5e")
    q = [0.1, -1.2, 1.3, 0.4, -0.5, 0.6]
    argv = ["jacobian", "universal_robots_ur5e", "--q", *map(str, q)]
    code, text, _ = run(capsys, *argv)
    assert code == 0 and "J_space of 'attachment_site' (6 x 6), rows [w; v]" in text
    assert "columns: shoulder_pan_joint, shoulder_lift_joint" in text
    for convention in ("space", "body", "world"):
        code, text, _ = run(capsys, *argv, "--convention", convention, "--json")
        reply = json.loads(text)
        expected = getattr(chain, f"jacobian_{convention}")(q)
        assert code == 0 and reply["convention"] == convention
        assert_close(f"--json {convention}", reply["J"], expected, 0.0)
    batch = np.random.default_rng(0).uniform(-3, 3, (7, 6))
    np.save(tmp_path / "q.npy", batch)
    out_path = tmp_path / "J.npy"
    code, text, _ = run(
        capsys, "jacobian", "universal_robots_ur5e", "--convention", "world",
        "--input", str(tmp_path / "q.npy"), "--output", str(out_path),
    )  # fmt: skip
    assert code == 0 and "(7, 6, 6)" in text
    assert_close("J.npy", np.load(out_path), chain.jacobian_world(batch), 0.0)


def test_jacobian_of_a_tree_frame_behind_a_free_joint(capsys: pytest.CaptureFixture[str]) -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    qpos = poekin.sample_qpos(tree, 1, seed=3)[0]
    argv = ["jacobian", "unitree_go2", "--tree", "--frame", "FL_calf", "--json"]
    code, text, _ = run(capsys, *argv, "--convention", "body", "--q", *map(str, qpos))
    reply = json.loads(text)
    assert code == 0 and reply["columns"][:2] == ["joint0[x]", "joint0[y]"]
    assert len(reply["columns"]) == tree.nv == 18
    assert_close("--tree", reply["J"], tree.jacobian(qpos, "FL_calf", "body"), 0.0)


def _write(tmp_path: pathlib.Path, name: str, text: str) -> str:
    (tmp_path / name).write_text(text)
    return str(tmp_path / name)


_ON_LINUX = pytest.mark.skipif(
    not (os.path.isdir("/proc/self") and os.path.isdir("/sys/kernel")), reason="needs /proc, /sys"
)

POSE = ["0.4", "0.2", "0.3", "0", "1", "0", "0"]  # x y z qw qx qy qz: a pose the UR5e reaches
BAD_INPUTS = [
    (["ik", "universal_robots_ur5e", "--targets", "{tmp}/none.json"], "none.json: no such file"),
    (["ik", "universal_robots_ur5e", "--targets", "{bad_xml}"], "not JSON"),
    (
        [
            "ik",
            "universal_robots_ur5e",
            "--pose",
            "0.4",
            "0.2",
            "0.3",
            "0",
            "1",
            "0",
            "0",
            "--hold",
            "a",
        ],
        "--hold goes with --targets",
    ),
    (["verify", "universal_robots_ur5"], "did you mean 'universal_robots_ur5e'"),
    (["verify", "no/such/robot.xml"], "model file not found"),
    (["verify", "{tmp}"], "is a directory"),
    (["verify", "{bad_xml}"], "cannot read"),
    (["verify", "--frame", "atachment_site"], "did you mean 'attachment_site'"),
    (["verify", "franka_emika_panda"], "name the end frame"),
    (["verify", "--samples", "0"], "--samples must be at least 1"),
    (["verify", "--metrics", "{tmp}/missing/m.csv"], "does not exist"),
    (["verify", "--metrics", "{other_csv}"], "header differs"),
    (["verify", "--plot", "{tmp}/missing/fk.png"], "does not exist"),
    (["fk", "universal_robots_ur5e", "--q", "1", "2"], "expected 6 joint values"),
    (["fk", "universal_robots_ur5e", "--q", "0", "0", "nan", "0", "0", "0"], "NaN or inf"),
    (["fk", "universal_robots_ur5e", "--q", "0", "0", "inf", "0", "0", "0"], "NaN or inf"),
    (["fk", "universal_robots_ur5e"], "give joint values with --q"),
    (
        ["fk", "universal_robots_ur5e", "--input", "{tmp}/none.npy", "--output", "{tmp}/T.npy"],
        "no such file",
    ),
    (
        ["fk", "universal_robots_ur5e", "--input", "{bad_xml}", "--output", "{tmp}/T.npy"],
        "its suffix '.xml' names no format poekin knows: .npy, .npz, .csv, .txt",
    ),
    (["dh"], "give a model"),
    (["dh", "universal_robots_ur5e", "--params", "ur5e-dh"], "not both"),
    (["dh", "universal_robots_ur5e", "--parallel-tol", "0"], "--parallel-tol must be positive"),
    (["dh", "--params", "lynch-park-ur"], "did you mean 'lynch-park-ur5'"),
    (["fk", "--params", "ur5e-dh", "--q", "1"], "expected 6 joint values"),
    (["verify", "--against", "universal_robots_ur5e"], "goes with --params"),
    (["verify", "franka_fr3", "--params", "ur5e-dh", "--against", "universal_robots_ur5e"], "two"),
    (["verify", "--params", "ur5e-dh", "--against", "franka_fr3"], "has 7"),
    (["diagnose", "--params", "{bad_xml}"], ".json or .yaml"),
    (["diagnose", "--params", "ur5e-dh", "--against", "franka_fr3"], "6 joints but"),
    (["diagnose", "--params", "ur5e-dh", "--samples", "0"], "--samples must be at least 1"),
    (["diagnose", "--params", "ur5e-dh", "--pos-tol", "-1"], "--pos-tol must be a positive"),
    (["verify", "--ori-tol", "nan"], "--ori-tol must be a positive number"),
    (["diagnose", "--params", "ur5e-dh", "--plot", "{other_png}"], "already exists"),
    (["fk", "unitree_go2", "--all-frames", "--q", "0", "1"], "expected 19 qpos values"),
    (["fk", "unitree_go2", "--frame", "FL_calf", "--q", "0"], "free joint 'joint0'"),
    (["fk", "aloha", "--all-frames", "--frame", "left/gripper", "--q", "0"], "drop --frame"),
    (["verify", "aloha", "--all-frames", "--frame", "left/gripper"], "give no frame"),
    (["screws", "unitree_go2", "--frame", "imu"], "'joint0' on the path to 'imu' is a free"),
    (["verify", "{mj_rejects}"], "MuJoCo rejected"),
    (["fk", "--params", "{zero_axis}", "--q", *"000000"], "needs a unit axis w, got |w| = 0;"),
    (["fk", "--params", "{half_axis}", "--q", *"000000"], "needs a unit axis w, got |w| = 0.5"),
    (["verify", "--params", "{skewed_home}", "--against", "universal_robots_ur5e"], "orthonormal"),
    (["jacobian", "universal_robots_ur5e", "--q", "1", "2"], "expected 6 joint values"),
    (["jacobian", "universal_robots_ur5e"], "give joint values with --q"),
    (["jacobian", "unitree_go2", "--frame", "FL_calf", "--q", "0"], "pass --tree"),
    (["jacobian", "unitree_go2", "--tree", "--frame", "FL_clf", "--q", "0"], "'FL_calf'"),
    (["jacobian", "aloha", "--tree", "--q", "0"], "name the end frame with --frame"),
    (["jacobian", "--tree", "--params", "ur5e-dh", "--q", "0"], "not --params"),
    (["jacobian", "universal_robots_ur5e", "--output", "{tmp}/J.npy", "--q", "0"], "goes with"),
    # issue #15: what a new user hit
    (["verify", "--seed", "-1"], "--seed must be a whole number, 0 or more, got -1"),
    (["diagnose", "--params", "ur5e-dh", "--seed", "-1"], "--seed must be a whole number"),
    (["fk", "universal_robots_ur5e", "--q", "-inf", *"00000"], "NaN or inf"),
    (["verify", "--pos-tol", "-1e-3"], "--pos-tol must be a positive number, got -0.001"),
    (["verify", "--plot", "{tmp}/fig.pdf.bak"], "names no format poekin knows: .png, .pdf"),
    (["verify", "--plot", "{tmp}/fig"], "it has no suffix"),
    (["fk", "universal_robots_ur5e", "--input", "{q_npy}", "--output", "{tmp}/T.dat"], ".dat"),
    (
        ["fk", "universal_robots_ur5e", "--input", "{text_npy}", "--output", "{tmp}/T.npy"],
        "is not a NumPy .npy file",
    ),
    (
        ["fk", "universal_robots_ur5e", "--input", "{complex_npy}", "--output", "{tmp}/T.npy"],
        "holds complex numbers",
    ),
    (
        ["fk", "universal_robots_ur5e", "--input", "{q_npy}", "--output", "{tmp}/T.npy", "--json"],
        "--json prints the result of one --q",
    ),
    (["verify", "ur5e"], "did you mean 'universal_robots_ur5e'"),
    (["verify", "{readme}"], "is not a model format poekin reads"),
    (["verify", "{mismatched_xml}"], "XML_ERROR_MISMATCHED_ELEMENT"),
    (["jacobian", "unitree_go2", "--frame", "FL_calf", "--q", "0"], "sits behind the free joint"),
    (["fk", "universal_robots_ur5e", "--floating-base", "--q", *"000000"], "pass --tree too"),
    (["fk", "unitree_go2", "--relative-to", "bse", "--q", "0"], "did you mean 'base'"),
    (["fk", "--params", "ur5e-dh", "--tree", "--q", "0"], "not --params"),
    (["dh", "--params", "{deg_unit_typo}"], "'angle_unit' is 'degree'"),
    (["fk", "--params", "ur5e-dh", "--frame", "flange", "--q", *"000000"], "its own end frame"),
    # issue #17: poekin view and poekin draw
    (
        ["draw", "universal_robots_ur5", "--out", "{tmp}/a.png"],
        "did you mean 'universal_robots_ur5e'",
    ),
    (["draw", "--q", "1", "2", "--out", "{tmp}/a.png"], "expected 6 qpos values"),
    (["draw", "--out", "{tmp}/a.gif"], "names no format poekin knows: .png, .pdf"),
    (["draw", "--out", "{tmp}/missing/a.png"], "does not exist"),
    (["draw", "--q", *"0" * 5, "nan", "--out", "{tmp}/a.png"], "NaN or inf"),
    (
        ["draw", "--params", "lynch-park-ur", "--out", "{tmp}/a.png"],
        "did you mean 'lynch-park-ur5'",
    ),
    (
        ["draw", "--params", "ur5e-dh", "--frame", "wrist_1_link", "--out", "{tmp}/a.png"],
        "6 joints",
    ),
    (["view", "universal_robots_ur5", "--no-browser"], "did you mean 'universal_robots_ur5e'"),
    (["view", "--params", "lynch-park-ur", "--no-browser"], "did you mean 'lynch-park-ur5'"),
    (["view", "--frame", "atachment_site", "--no-browser"], "did you mean 'attachment_site'"),
    (["view", "--port", "70000", "--no-browser"], "--port must be in 0..65535"),
    # URDF files (issue 15): BAD_URDFS below. verify reads a URDF before MuJoCo compiles it,
    # so poekin's reason, naming the joint, comes first for what MuJoCo refuses too
    (["screws", "{rpy_of_4}"], "joint 'j': <origin rpy=\"0 0 1 0\"> has 4 numbers; give 3"),
    (["verify", "{rpy_of_4}"], "joint 'j': <origin rpy=\"0 0 1 0\"> has 4 numbers; give 3"),
    (["fk", "{two_axes}", "--q", "0"], "joint 'j' has 2 <axis> elements; keep one"),
    (["screws", "{xacro}"], "a xacro file, not URDF yet (it has $(find my_robot) in <mesh"),
    (["screws", "{mimic_no_joint}"], "joint 'j': <mimic> has no joint; name the joint it"),
    (["verify", "{mimic_cycle}"], "mimic joints form a cycle: j -> k -> j"),
    (["screws", "{world_only}"], "no link to pose"),
    (["verify", "{planar}"], "joint 'j' is planar"),
    # issue 20: every writer refuses a path it cannot write, before any work, in one line
    *[
        pytest.param(argv, message, marks=_ON_LINUX)
        for argv, message in [
            (
                ["verify", "--plot", "/proc/fk.png"],
                "cannot write the plot to /proc/fk.png: folder /proc is not writable",
            ),
            (
                ["draw", "--out", "/proc/a.png"],
                "cannot write the drawing to /proc/a.png: folder /proc is not writable",
            ),
            (
                ["diagnose", "--params", "ur5e-dh", "--plot", "/proc/w.png"],
                "cannot write the plot to /proc/w.png: folder /proc is not writable",
            ),
            (
                ["fk", "universal_robots_ur5e", "--input", "{q_npy}", "--output", "/sys/T.csv"],
                "cannot write the poses to /sys/T.csv: folder /sys is not writable",
            ),
            (
                [
                    "jacobian",
                    "universal_robots_ur5e",
                    "--input",
                    "{q_npy}",
                    "--output",
                    "/sys/J.npy",
                ],
                "cannot write the Jacobians to /sys/J.npy: folder /sys is not writable",
            ),
            (
                ["verify", "--metrics", "/proc/metrics.csv"],
                "cannot write metrics to /proc/metrics.csv: folder /proc is not writable",
            ),
        ]
    ],
    (
        ["fk", "universal_robots_ur5e", "--input", "{q_npy}", "--output", "{tmp}"],
        "is a folder; give a file path ending in one of .npy, .npz, .csv, .txt",
    ),
    (["verify", "--plot", "{tmp}"], "is a folder; give a file path ending in one of .png"),
    (["verify", "--metrics", "{tmp}"], "it is a directory; pass a file path"),
    (
        ["fk", "universal_robots_ur5e", "--input", "{q_npy}", "--output", "{other_csv}/T.npy"],
        "other.csv is a file, not a folder",
    ),
    (["draw", "--out", "{other_csv}/a.png"], "other.csv is a file, not a folder"),
    (["verify", "--samples", "100000000000"], "100000000000 samples need at least 27.6 TiB"),
    (["diagnose", "--params", "ur5e-dh", "--samples", "100000000000"], "samples need at least"),
    (
        ["fk", "universal_robots_ur5e", "--q", *"000000", "--input", "{q_npy}"],
        "both --q and --input were given; give one",
    ),
    (["draw", "--aligned", "--out", "{tmp}/a.png"], "give --params FILE|NAME too, or drop"),
    (["jacobian", "unitree_go2", "--relative-to", "bse", "--q", "0"], "did you mean 'base'"),
    (["jacobian", "aloha", "--all-frames", "--frame", "left/gripper", "--q", "0"], "drop --frame"),
    (["jacobian", "--params", "ur5e-dh", "--relative-to", "base", "--q", "0"], "not --params"),
    # UR calibration files (issue 22): BAD_UR_CALIBRATIONS below
    (["fk", "--params", "{ur_missing_segment}", "--q", *"000000"], "has no 'wrist_2' segment"),
    (["diagnose", "--params", "{ur_misspelled_segment}"], "did you mean 'wrist_1'?"),
    (["dh", "--params", "{ur_text}"], "kinematics.forearm.x must be a number"),
    (["verify", "--params", "{ur_extra_segment}"], "unknown segment 'wrist_4'"),
    (
        ["diagnose", "--params", "{ur_calibration}", "--against", "ur5e-dh", "--frame", "tool0"],
        "frame out",
    ),
    # parameter files that cannot be right, and export (issue 26)
    (["fk", "--params", "{ur_millimetres}", "--q", *"000000"], "lengths look like millimetres"),
    (
        ["ik", "--params", "{upside_down_limits}", "--pose", *POSE],
        "joint 'shoulder_lift_joint' has limits [1, -1]: the lower limit is above the upper",
    ),
    (["dh", "--params", "{millimetres}"], "farther than any arm reaches"),
    (["export", "ur5e-dh", "--to", "ur-yaml", "--output", "{tmp}/ur5e.json"], "ends in .yaml"),
    (["export", "ur5e-dh", "--to", "urdf", "--output", "{other_png}"], "ends in .urdf"),
    (["export", "lynch-park-ur5", "--to", "ur-yaml", "--output", "{tmp}/lp.yaml"], "not a UR arm"),
    (["export", "ur5e-dh", "--to", "urdf", "--output", "{tmp}/no/ur5e.urdf"], "does not exist"),
    (
        ["export", "ur5e-dh", "--frame", "flange", "--to", "urdf", "--output", "{tmp}/u.urdf"],
        "--frame names a model's frame",
    ),
    # the robot cell (issue 26): --base and --tool that are no rigid transforms, or misplaced
    (["fk", "--q", *"000000", "--tool", *"000", *"0000"], "--tool: the quaternion is zero"),
    (
        ["fk", "--q", *"000000", "--base", *"000", "0.7071", "0.7071", "0", "0"],
        "--base: the quaternion QW QX QY QZ = 0.7071 0.7071 0 0 has norm 0.99999041, not 1",
    ),
    (["jacobian", "--q", *"000000", "--tool", "nan", *"00", *"1000"], "--tool entries contain NaN"),
    (["ik", "--pose", *POSE, "--all", "--base", *"000", "2", *"000"], "--base: the quaternion"),
    (["screws", "--tool", *"000", *"0000"], "--tool: the quaternion is zero"),
    (["dh", "--params", "ur5e-dh", "--base", "inf", *"00", *"1000"], "--base entries contain"),
    (["draw", "--out", "{tmp}/a.png", "--tool", *"000", *"0000"], "--tool: the quaternion"),
    (["view", "--no-browser", "--base", *"000", *"0000"], "--base: the quaternion is zero"),
    (
        ["fk", "--tree", "--q", *"000000", "--tool", *"000", *"1000"],
        "--tool mounts a tool on the end frame of a chain; --tree, --all-frames and "
        "--relative-to pose the model's own bodies and sites",
    ),
    (
        ["ik", "aloha", "--tree", "--frame", "left/gripper", "--pose", *POSE, "--tool", *"0001000"],
        "--tool mounts a tool on the end frame of a chain",
    ),
    (
        ["fk", "unitree_go2", "--tree", "--q", "0", "--base", *"000", *"1000"],
        "its qpos (x y z qw qx qy qz) places 'base' in the world already, so a base would not",
    ),
    # poekin ik (issue 21): targets that are no poses, files, options that do not go together
    (["ik", "universal_robots_ur5e", "--pose", *POSE[:3], *"0000"], "the quaternion is zero"),
    (
        ["ik", "universal_robots_ur5e", "--pose", *POSE[:3], "0.7071", "0.7071", "0", "0"],
        "norm 0.99999041, not 1 (|q| must be within 1e-6 of 1; poekin does not normalise it): "
        "give a unit quaternion, such as 0.707106781 0.707106781 0 0",
    ),
    (["ik", "universal_robots_ur5e", "--pose", "nan", *POSE[1:]], "--pose holds NaN or inf"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE[:6]], "--pose takes 7 numbers"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE[:3]], "or pass --position-only"),
    (["ik", "universal_robots_ur5e"], "give a target with --pose X Y Z QW QX QY QZ"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--input", "{poses}"], "give one"),
    (["ik", "universal_robots_ur5e", "--input", "{poses}"], "--input needs --output"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--output", "{tmp}/q_ik.npy"], "goes with"),
    (
        ["ik", "universal_robots_ur5e", "--input", "{poses}", "--output", "{tmp}/q.npy", "--json"],
        "--json prints the answer for one --pose",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{not_rigid}", "--output", "{tmp}/q_ik.npy"],
        "target at index (1,) is not a rigid transform: its rotation block is not orthonormal",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{bad_quat_csv}", "--output", "{tmp}/q_ik.npy"],
        "bad_quat.csv line 2: the quaternion QW QX QY QZ = 1 1 0 0 has norm 1.41421356",
    ),
    # issue 26: a target file's header is read by name, and a message names the file's line
    (
        ["ik", "universal_robots_ur5e", "--input", "{quat_first}", "--output", "{tmp}/q_ik.npy"],
        "quat_first.csv line 3: the quaternion QW QX QY QZ = 0.4 0.2 0.3 1 has norm 1.1",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{abc_csv}", "--output", "{tmp}/q_ik.npy"],
        "abc.csv: unknown column 'a' in the header; name the columns of one layout, in any "
        "order: poses x,y,z,qw,qx,qy,qz; 4x4 matrices T00,T01,...,T33; points (with "
        "--position-only) x,y,z",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{typo_csv}", "--output", "{tmp}/q_ik.npy"],
        "typo.csv: unknown column 'qzz' in the header (did you mean 'qz'?)",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{points_csv}", "--output", "{tmp}/q_ik.npy"],
        "points.csv: the header x,y,z names no layout of targets",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{nan_poses}", "--output", "{tmp}/q_ik.npy"],
        "nan_poses.npy row 1 (from 0) holds NaN or inf",
    ),
    (  # issue 26: the file's own lines, never NumPy's row 0, and the column by its header
        ["ik", "universal_robots_ur5e", "--input", "{text_cell_csv}", "--output", "{tmp}/q_ik.npy"],
        "text_cell.csv line 4, column 'qw': 'zz' is not a number",
    ),
    (
        ["fk", "universal_robots_ur5e", "--input", "{nan_q_csv}", "--output", "{tmp}/T.npy"],
        "nan_q.csv line 3 holds NaN or inf; every value must be finite",
    ),
    (
        ["fk", "universal_robots_ur5e", "--input", "{nan_q_npy}", "--output", "{tmp}/T.npy"],
        "nan_q.npy row 1 (from 0) holds NaN or inf",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{q_npy}", "--output", "{tmp}/q_ik.npy"],
        "holds an array of shape (2, 6); give targets as (N, 4, 4) matrices",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{tmp}/none.npy", "--output", "{tmp}/q_ik.npy"],
        "no such file",
    ),
    (
        ["ik", "universal_robots_ur5e", "--input", "{poses}", "--output", "{other_csv}"],
        "already exists; pass --force",
    ),
    (["ik", "franka_fr3", "--pose", *POSE, "--all"], "ik_all needs 6 revolute joints"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--all", "--seed", "1"], "takes no --seed"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--q0", "1", "2"], "expected 6 --q0 values"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--seed", "-1"], "--seed must be a whole"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--pos-tol", "0"], "--pos-tol must be a"),
    (["ik", "universal_robots_ur5e", "--pose", *POSE, "--qpos", "0"], "pass --tree too"),
    (["ik", "unitree_go2", "--frame", "FL_calf", "--pose", *POSE], "pass --tree"),
    (
        ["ik", "aloha", "--tree", "--frame", "left/griper", "--pose", *POSE],
        "did you mean 'left/gripper'",
    ),
    (
        ["ik", "aloha", "--tree", "--frame", "left/gripper", "--pose", *POSE, "--qpos", "0"],
        "expected 16 --qpos values",
    ),
    pytest.param(
        ["ik", "universal_robots_ur5e", "--input", "{poses}", "--output", "/sys/q.npy"],
        "cannot write the joint values to /sys/q.npy: folder /sys is not writable",
        marks=_ON_LINUX,
    ),
    # issue #26: an empty batch printed "SOLVED: all 0 targets ... nan iterations"; fk wrote an
    # empty file from an .npy and refused an empty .csv: every --input without rows is refused
    (
        [
            "ik",
            "universal_robots_ur5e",
            "--input",
            "{empty_poses}",
            "--output",
            "{tmp}/answers.npy",
        ],
        "empty_poses.npy holds no numbers (an array of shape (0, 4, 4))",
    ),
    (
        [
            "ik",
            "universal_robots_ur5e",
            "--all",
            "--input",
            "{empty_poses}",
            "--output",
            "{tmp}/a.npy",
        ],
        "holds no numbers (an array of shape (0, 4, 4))",
    ),
    (
        ["fk", "universal_robots_ur5e", "--input", "{empty_q}", "--output", "{tmp}/T.npy"],
        "empty_q.npy holds no numbers (an array of shape (0, 6))",
    ),
    # issue #26: complex targets
    (
        ["ik", "universal_robots_ur5e", "--input", "{complex_poses}", "--output", "{tmp}/a.npy"],
        "holds complex numbers; give real numbers",
    ),
]

# {name}.yaml files for BAD_INPUTS: the synthetic UR5e calibration of tests/data/ur, edited
UR_CALIBRATION = pathlib.Path(__file__).parents[1] / "data" / "ur" / "ur5e_calibration.yaml"
BAD_UR_CALIBRATIONS: dict[str, Callable[[dict[str, Any]], object]] = {
    "ur_missing_segment": lambda k: k.pop("wrist_2"),
    "ur_misspelled_segment": lambda k: k.update(wrist1=k.pop("wrist_1")),
    "ur_text": lambda k: k["forearm"].update(x="abc"),
    "ur_extra_segment": lambda k: k.update(wrist_4=dict(k["wrist_3"])),
    "ur_millimetres": lambda k: [
        k[s].update({a: 1000 * k[s][a] for a in "xyz"}) for s in k if s != "hash"
    ],
}


def _ur_calibration(edit: Callable[[dict[str, Any]], object]) -> str:
    import yaml

    doc = yaml.safe_load(UR_CALIBRATION.read_text())
    edit(doc["kinematics"])
    return str(yaml.safe_dump(doc))


_LINKS = '<link name="base"/><link name="a"/>'
_ONE_JOINT = _LINKS + '<joint name="j" type="{}"><parent link="base"/><child link="a"/>{}</joint>'
_MESH = '<mesh filename="$(find my_robot)/base.stl"/>'
# {name}.urdf files for BAD_INPUTS
BAD_URDFS = {
    "rpy_of_4": _ONE_JOINT.format("continuous", '<origin rpy="0 0 1 0"/>'),
    "two_axes": _ONE_JOINT.format("continuous", '<axis xyz="0 0 1"/><axis xyz="0 1 0"/>'),
    "xacro": f"<link name='a'><visual><geometry>{_MESH}</geometry></visual></link>",
    "mimic_no_joint": _ONE_JOINT.format("continuous", '<mimic multiplier="2"/>'),
    "mimic_cycle": _ONE_JOINT.format("continuous", '<mimic joint="k"/>')
    + '<link name="b"/><joint name="k" type="continuous"><parent link="a"/><child link="b"/>'
    '<mimic joint="j"/></joint>',
    "world_only": '<link name="world"/>',
    "planar": _ONE_JOINT.format("planar", ""),
}


UR5E_DH_DICT = poekin.named_params("ur5e-dh").describe()


def _npy(path: pathlib.Path, array: np.ndarray) -> str:
    np.save(path, array)
    return str(path)


def _param_file(
    tmp_path: pathlib.Path,
    name: str,
    joint: int,
    screw: list[float],
    *,
    limits: list[float] | None = None,
    scale: float = 1.0,
) -> str:
    """The UR5e's screws as ``poekin screws --json`` writes them, one joint's screw replaced
    (an empty ``screw`` instead skews the home pose M), or its ``limits``, or every length
    times ``scale``."""
    described = load("universal_robots_ur5e").describe()
    if limits is not None:
        described["joints"][joint]["limits"] = limits
    elif scale != 1.0:
        for j in described["joints"]:
            j["screw"] = [*j["screw"][:3], *(scale * v for v in j["screw"][3:])]
        for row in described["home"][:3]:
            row[3] *= scale
    elif screw:
        described["joints"][joint]["screw"] = screw
    else:
        described["home"][0][0] = 2.0
    return _write(tmp_path, name, json.dumps(described))


@pytest.mark.parametrize(("argv", "message"), BAD_INPUTS)
def test_bad_input_gives_one_line_and_exit_2(
    argv: list[str], message: str, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = _write(tmp_path, "other.csv", "a,b,c\n1,2,3\n")
    other_png = _write(tmp_path, "other.png", "not really a picture")
    zero_axis_joint = '<joint type="hinge" axis="0 0 0"/><geom size="0.1"/>'
    fills = {
        "tmp": str(tmp_path),
        "bad_xml": _write(tmp_path, "bad.xml", "<mujoco><oops>"),
        "mj_rejects": _write(
            tmp_path,
            "rejected.xml",
            f"<mujoco><worldbody><body>{zero_axis_joint}</body></worldbody></mujoco>",
        ),
        "zero_axis": _param_file(tmp_path, "zero.json", 2, [0.0] * 6),
        "half_axis": _param_file(tmp_path, "half.json", 2, [0.0, -0.5, 0.0, 0.163, 0.0, 0.425]),
        "skewed_home": _param_file(tmp_path, "skewed.json", 0, []),
        "upside_down_limits": _param_file(tmp_path, "limits.json", 1, [], limits=[1, -1]),
        "millimetres": _param_file(tmp_path, "mm.json", 0, [], scale=1000.0),
        "other_csv": other,
        "other_png": other_png,
        "q_npy": _npy(tmp_path / "q.npy", np.zeros((2, 6))),
        "complex_npy": _npy(tmp_path / "complex.npy", np.zeros((2, 6)) + 1j),
        "text_npy": _write(tmp_path, "text.npy", "0,0,0,0,0,0\n"),
        "readme": _write(tmp_path, "README.md", "# not a robot\n"),
        "mismatched_xml": _write(tmp_path, "m.xml", "<mujoco>\n<worldbody>\n<oops>\n</mujoco>\n"),
        "deg_unit_typo": _write(
            tmp_path, "t.json", json.dumps({**UR5E_DH_DICT, "angle_unit": "degree"})
        ),
        "poses": _npy(tmp_path / "poses.npy", np.tile(np.eye(4), (2, 1, 1))),
        "not_rigid": _npy(tmp_path / "not_rigid.npy", np.stack([np.eye(4), np.diag([2, 1, 1, 1])])),
        "bad_quat_csv": _write(
            tmp_path, "bad_quat.csv", "0.4,0.2,0.3,1,0,0,0\n0.4,0.2,0.3,1,1,0,0\n"
        ),
        "quat_first": _write(
            tmp_path,
            "quat_first.csv",
            "qw,qx,qy,qz,x,y,z\n# x y z first, by mistake\n0.4,0.2,0.3,1,0,0,0\n",
        ),
        "abc_csv": _write(tmp_path, "abc.csv", "a,b,c,d,e,f,g\n0.4,0.2,0.3,1,0,0,0\n"),
        "typo_csv": _write(tmp_path, "typo.csv", "x,y,z,qw,qx,qy,qzz\n0.4,0.2,0.3,1,0,0,0\n"),
        "points_csv": _write(tmp_path, "points.csv", "x,y,z\n0.4,0.2,0.3\n"),
        "empty_poses": _npy(tmp_path / "empty_poses.npy", np.zeros((0, 4, 4))),
        "empty_q": _npy(tmp_path / "empty_q.npy", np.zeros((0, 6))),
        "complex_poses": _npy(tmp_path / "complex_poses.npy", np.tile(np.eye(4), (2, 1, 1)) + 0j),
        "nan_poses": _npy(
            tmp_path / "nan_poses.npy", np.array([[0.4, 0, 0, 1, 0, 0, 0], [np.nan] * 7])
        ),
        "text_cell_csv": _write(
            tmp_path,
            "text_cell.csv",
            "x,y,z,qw,qx,qy,qz\n0.4,0.2,0.3,1,0,0,0\n\n0.4,0.2,0.3,zz,0,0,0\n",
        ),
        "nan_q_csv": _write(tmp_path, "nan_q.csv", "# joints\n0,0,0,0,0,0\n0,nan,0,0,0,0\n"),
        "nan_q_npy": _npy(tmp_path / "nan_q.npy", np.array([[0.0] * 6, [0, np.inf, 0, 0, 0, 0]])),
    }
    fills |= {
        k: _write(tmp_path, f"{k}.urdf", f'<robot name="r">{v}</robot>')
        for k, v in BAD_URDFS.items()
    }
    fills |= {
        k: _write(tmp_path, f"{k}.yaml", _ur_calibration(edit))
        for k, edit in BAD_UR_CALIBRATIONS.items()
    }
    fills["ur_calibration"] = str(UR_CALIBRATION)
    before = pathlib.Path(other).read_bytes()
    listing = sorted(tmp_path.iterdir())
    code, out, err = run(capsys, *[a.format(**fills) for a in argv])
    assert code == 2
    assert_one_error_line(err, message)
    assert out == ""  # no partial output, such as a PASS line before a failed write
    assert pathlib.Path(other).read_bytes() == before
    assert sorted(tmp_path.iterdir()) == listing  # nothing written, no probe left behind


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_write_that_fails_after_the_run_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    """What no check can foresee, a full disk, still gives one line and exit 2."""
    code, out, err = run(capsys, "verify", "--samples", "10", "--metrics", "/dev/full")
    assert code == 2 and "PASS" in out
    assert_one_error_line(err, "cannot write metrics to /dev/full: No space left on device")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["verify", "--samples", "many"], "invalid int value"),
        (["teleport"], "invalid choice"),
        (["fk", "universal_robots_ur5e", "--q", "a", *"00000"], "invalid float value: 'a'"),
    ],
)
def test_argparse_errors_are_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.count("\n") == 1 and message in err and "--help" in err


def test_no_network_menagerie(capsys: pytest.CaptureFixture[str], fresh_machine: None) -> None:
    """A robot poekin does not ship (the FR3 it does: issue #26), with no network."""
    code, _, err = run(capsys, "verify", "unitree_h1")
    assert code == 2
    assert_one_error_line(
        err, "set MENAGERIE_ROOT to a local mujoco_menagerie clone, or pass a path"
    )


@pytest.mark.parametrize(
    "command", ["verify", "screws", "fk", "jacobian", "dh", "diagnose", "view", "draw"]
)
def test_every_command_has_help_with_an_example(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    assert f"poekin {command}" in capsys.readouterr().out.split("example")[1]


def test_console_script_runs_without_traceback(fresh_machine: None) -> None:
    """The installed entry point, in a real process: exit code and stderr as a user sees them."""
    proc = subprocess.run(
        [sys.executable, "-m", "poekin.cli", "fk", "universal_robots_ur5e", "--q", "1"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("poekin: error: expected 6 joint values")
    assert "Traceback" not in proc.stderr


# What each import costs a user who only verifies: none of these is needed for that.
NOT_FOR_VERIFY = [
    "matplotlib",
    "yaml",
    "yourdfpy",
    "tqdm",  # only for a progress bar on a terminal
    "numpy.ma",
    "glfw",  # MuJoCo's GL backend, which the command line never uses
    "poekin.verification.metrics",
    "poekin.verification.plotting",
]


def test_verify_imports_only_what_it_needs(fresh_machine: None) -> None:
    """``import poekin`` imports no MuJoCo, and ``poekin verify`` (the built-in UR5e) none of the
    modules it does not use; MUJOCO_GL is left as the user had it."""
    code = (
        "import os, sys\n"
        "import poekin\n"
        "print(sorted(m for m in ['mujoco', *NOT] if m in sys.modules))\n"
        "from poekin.cli import main\n"
        "assert main(['verify', '--samples', '20']) == 0\n"
        "print(sorted(m for m in NOT if m in sys.modules), 'mujoco' in sys.modules)\n"
        "print(os.environ.get('MUJOCO_GL'))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    proc = subprocess.run(
        [sys.executable, "-c", f"NOT = {NOT_FOR_VERIFY!r}\n{code}"],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    lines = proc.stdout.splitlines()
    assert lines[0] == "[]"
    assert lines[-2:] == ["[] True", "None"]
    assert proc.stderr == ""


# --- dh, diagnose, --params ---------------------------------------------------------------------


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_json_round_trips_through_params(
    convention: str, capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    code, out, _ = run(capsys, "dh", "franka_fr3", "--convention", convention, "--json")
    assert code == 0
    table = json.loads(out)
    assert table["convention"] == convention and len(table["rows"]) == 7
    assert set(table["rows"][0]) == {"a", "alpha", "d", "theta_offset", "joint_type", "joint"}
    assert np.array(table["base"]).shape == (4, 4) and np.array(table["tool"]).shape == (4, 4)
    path = tmp_path / "fr3_dh.json"
    path.write_text(out)
    code, out, _ = run(capsys, "verify", "--params", str(path), "--against", "franka_fr3", "--json")
    result = json.loads(out)
    assert code == 0 and result["passed"] is True
    assert result["max_pos_err_m"] <= 1e-12 and result["max_ori_err_rad"] <= 1e-12


def test_dh_text_names_the_convention_and_the_choices(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "dh", "universal_robots_ur5e")
    assert code == 0
    assert "standard (Denavit-Hartenberg)" in out
    assert "note: joints 'shoulder_lift_joint' and 'elbow_joint' have parallel axes" in out
    wrist_1 = next(ln for ln in out.splitlines() if ln.strip().startswith("wrist_1_joint"))
    assert wrist_1.split()[4] == "0.134000"  # d4 = 0.138 - 0.131 + 0.127 (ur5e.xml offsets)


def test_verify_a_published_table_shows_the_dh_row(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "verify", "--params", "ur5e-dh", "--samples", "100")
    assert code == 1  # UR's published numbers differ from the Menagerie model by millimetres
    assert "DH table" in out and "FAIL" in out and out.startswith("ur5e-dh against")


def test_fk_with_named_params(capsys: pytest.CaptureFixture[str]) -> None:
    q = ["0", "-1.5707963267948966", "0", "0", "1.5707963267948966", "0"]
    code, out, _ = run(capsys, "fk", "--params", "lynch-park-ur5", "--q", *q, "--json")
    assert code == 0
    # Modern Robotics Example 4.5 at this q, worked out in the book: (0.095, 0.109, 0.988) m.
    assert_close("p", np.array(json.loads(out)["T"])[:3, 3], [0.095, 0.109, 0.988], 1e-12)


def test_diagnose_exit_codes_and_plot(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    code, out, _ = run(capsys, "dh", "universal_robots_ur5e", "--json")
    own = tmp_path / "own.json"
    own.write_text(out)
    code, out, _ = run(capsys, "diagnose", "--params", str(own), "--samples", "200")
    assert code == 0 and out.splitlines()[1].startswith("MATCH")
    plot = tmp_path / "why.png"
    code, out, _ = run(capsys, "diagnose", "--params", "lynch-park-ur5", "--plot", str(plot))
    assert code == 1
    assert "MISMATCH" in out and "turned 180.0 deg" in out and "d1: 0.089 m" in out
    assert "home pose M" in out and "bisection" in out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, out, _ = run(capsys, "diagnose", "--params", "ur5e-dh", "--json")
    result = json.loads(out)
    assert code == 1 and result["matches"] is False
    assert any("d4: 0.1333 m in yours vs 0.134 m" in f["message"] for f in result["findings"])


GO2_STAND = ["0", "0", "0.3", "1", "0", "0", "0"] + ["0", "0.9", "-1.8"] * 4


def test_fk_all_frames_text_json_and_npy(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    T = tree.fk(np.array(GO2_STAND, dtype=float))
    code, out, _ = run(capsys, "fk", "unitree_go2", "--all-frames", "--q", *GO2_STAND)
    assert code == 0
    assert out.count("T_world_") == tree.n_frames == 14
    assert "T_world_FL_calf =" in out and "T_world_imu =" in out
    code, out, _ = run(capsys, "fk", "unitree_go2", "--all-frames", "--json", "--q", *GO2_STAND)
    frames = json.loads(out)["frames"]
    assert list(frames) == list(tree.frame_names)
    assert_close("json poses", np.array(list(frames.values())), T, 0.0)
    qpos = poekin.sample_qpos(tree, 5, seed=1)
    np.save(tmp_path / "q.npy", qpos)
    code, out, _ = run(
        capsys,
        "fk",
        "unitree_go2",
        "--all-frames",
        "--input",
        str(tmp_path / "q.npy"),
        "--output",
        str(tmp_path / "T.npy"),
    )
    assert code == 0 and "(5, 14, 4, 4)" in out and "FL_hip" in out
    assert_close("npy poses", np.load(tmp_path / "T.npy"), tree.fk(qpos), 0.0)


def test_verify_all_frames(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "verify", "aloha", "--all-frames", "--samples", "100")
    assert code == 0
    assert "every body and site" in out and "26 frames; worst" in out
    assert "tree FK" in out and "space PoE" in out and "body PoE" in out
    code, out, _ = run(capsys, "verify", "unitree_go2", "--all-frames", "--samples", "50", "--json")
    result = json.loads(out)
    assert code == 0 and result["frame"] == "all frames"
    assert len(result["frames"]) == 14
    assert max(f["max_pos_err_m"] for f in result["frames"].values()) <= MJ_TOL


def test_verify_a_frame_behind_a_free_joint_checks_the_tree(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, _ = run(capsys, "verify", "unitree_go2", "--frame", "FL_calf", "--samples", "50")
    assert code == 0
    assert "frame 'FL_calf'" in out and "tree FK" in out and "space PoE" not in out


# --- issue #15: what a new user hit ------------------------------------------------------------

Q_UR5E = ["0.1", "-1.2", "1.3", "0.4", "-0.5", "2.0"]


@pytest.mark.parametrize("command", [["verify"], ["diagnose", "--params", "ur5e-dh"]])
def test_a_negative_seed_is_one_line_and_exit_2(
    command: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run(capsys, *command, "--seed", "-1")
    assert code == 2 and out == ""
    assert_one_error_line(err, "--seed must be a whole number, 0 or more, got -1")


@pytest.mark.parametrize(
    "q",
    [
        ["0", "-1e-3", "0", "0", "0", "0"],
        ["-1e-3", "0", "0", "0", "0", "0"],
        ["-.5", "-1E+0", "-2.", "0.25", "-1.5e-1", "-0"],
    ],
)
def test_negative_numbers_in_any_form(q: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "fk", "universal_robots_ur5e", "--json", "--q", *q)
    assert code == 0, err
    expected = load("universal_robots_ur5e").fk([float(x) for x in q])
    assert_close("T", json.loads(out)["T"], expected, 0.0)


def test_minus_inf_is_a_number_then_refused_as_not_finite(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, _, err = run(capsys, "fk", "universal_robots_ur5e", "--q", "-inf", *"00000")
    assert code == 2
    assert_one_error_line(err, "NaN or inf")
    code, _, err = run(capsys, "verify", "--pos-tol", "-1e-3")
    assert code == 2
    assert_one_error_line(err, "--pos-tol must be a positive number, got -0.001")


@pytest.mark.parametrize("suffix", [".npy", ".npz", ".csv", ".txt"])
def test_fk_output_goes_exactly_where_asked_in_that_format(
    suffix: str, capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    q = np.random.default_rng(1).uniform(-3, 3, size=(4, 6))
    np.save(tmp_path / "q.npy", q)
    target = tmp_path / f"T{suffix}"
    code, out, _ = run(
        capsys, "fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.npy"),
        "--output", str(target),
    )  # fmt: skip
    assert code == 0 and f"written to {target}" in out
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["q.npy", target.name])
    expected = load("universal_robots_ur5e").fk(q)
    if suffix == ".npy":
        got = np.load(target)
    elif suffix == ".npz":
        got = np.load(target)["T"]
    else:
        got = np.loadtxt(target, delimiter="," if suffix == ".csv" else None, skiprows=1)
        got = got.reshape(4, 4, 4)
    assert_close(f"T{suffix}", got, expected, 0.0)


def test_fk_reads_joint_values_from_csv(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    (tmp_path / "q.csv").write_text("q1,q2,q3,q4,q5,q6\n" + ",".join(Q_UR5E) + "\n")
    code, _, err = run(
        capsys, "fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.csv"),
        "--output", str(tmp_path / "T.npy"),
    )  # fmt: skip
    assert code == 0, err
    expected = load("universal_robots_ur5e").fk([[float(x) for x in Q_UR5E]])
    assert_close("T", np.load(tmp_path / "T.npy"), expected, 0.0)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("q.npy", "0,0,0,0,0,0\n", "is not a NumPy .npy file"),
        ("complex.npy", None, "holds complex numbers"),
    ],
)
def test_input_files_that_are_not_what_they_say(
    name: str,
    content: str | None,
    message: str,
    capsys: pytest.CaptureFixture[str],
    tmp_path: pathlib.Path,
) -> None:
    path = tmp_path / name
    if content is None:
        np.save(path, np.zeros((2, 6)) + 1j)
    else:
        path.write_text(content)
    code, _, err = run(
        capsys, "fk", "universal_robots_ur5e", "--input", str(path),
        "--output", str(tmp_path / "T.npy"),
    )  # fmt: skip
    assert code == 2
    assert_one_error_line(err, message)
    assert "pickle" not in err and not (tmp_path / "T.npy").exists()


FIGURE_MAGIC = [(".pdf", b"%PDF"), (".svg", b"<?xml"), (".jpg", b"\xff\xd8"), (".PNG", b"\x89PNG")]


@pytest.mark.parametrize(("suffix", "magic"), FIGURE_MAGIC)
def test_verify_plot_in_the_format_its_suffix_names(
    suffix: str, magic: bytes, capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    plot = tmp_path / f"fig{suffix}"
    code, _, _ = run(capsys, "verify", "--samples", "20", "--plot", str(plot))
    assert code == 0
    assert plot.read_bytes().startswith(magic)


@pytest.mark.parametrize("name", ["fig", "fig.gif.bak", "fig.txt"])
def test_verify_plot_suffix_refused_before_any_work(
    name: str, capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    code, out, err = run(capsys, "verify", "--plot", str(tmp_path / name))
    assert code == 2 and out == ""
    assert_one_error_line(err, "names no format poekin knows: .png, .pdf, .svg")
    assert list(tmp_path.iterdir()) == []


def test_output_suffix_refused_before_any_work(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    np.save(tmp_path / "q.npy", np.zeros((2, 6)))
    code, out, err = run(
        capsys, "fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.npy"),
        "--output", str(tmp_path / "T.dat"),
    )  # fmt: skip
    assert code == 2 and out == ""
    assert_one_error_line(err, "--output")
    assert [p.name for p in tmp_path.iterdir()] == ["q.npy"]


def test_dh_columns_stay_apart_for_any_magnitude(capsys: pytest.CaptureFixture[str]) -> None:
    """ufactory_lite6's nearly parallel joints 2 and 3 put d2 at 27 km."""
    code, out, _ = run(capsys, "dh", "ufactory_lite6")
    assert code == 0
    lines = out.splitlines()
    header, rows = lines[1], lines[2:8]
    assert header == "  " + header.strip() and header.split()[:2] == ["joint", "type"]
    assert header.split()[2:] == ["a", "[m]", "alpha", "[rad]", "d", "[m]", "theta_off", "[rad]"]
    for row in rows:
        cells = row.split()
        assert len(cells) == 6, row
        assert [float(c) for c in cells[2:]]  # each a number of its own
    # right-aligned: every number ends where its column header ends
    for name in ("[m]", "alpha [rad]", "theta_off [rad]"):
        end = header.index(name) + len(name)
        assert all(row[end - 1] != " " and (len(row) == end or row[end] == " ") for row in rows)


def test_verify_json_has_every_figure_the_table_prints(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "verify", "--params", "ur5e-dh", "--samples", "50", "--json")
    result = json.loads(out)
    assert code == 1 and list(result) == SUMMARY_KEYS
    assert result["params"] == "ur5e-dh" and result["robot"] == "universal_robots_ur5e"
    assert result["pos_tol"] == 1e-5 and result["ori_tol"] == 1e-4
    assert result["sample_range"] == "in [-2 pi, 2 pi]"
    assert list(result["methods"]) == ["DH table", "space PoE", "body PoE"]
    code, text, _ = run(capsys, "verify", "--params", "ur5e-dh", "--samples", "50")
    keys = ("max_pos_err_m", "median_pos_err_m", "max_ori_err_rad", "median_ori_err_rad")
    for method, figures in result["methods"].items():
        row = next(ln for ln in text.splitlines() if ln.startswith(method))
        printed = [float(x) for x in row[len(method) :].split()]
        assert printed == pytest.approx([figures[k] for k in keys], rel=5e-3)


def test_a_malformed_model_keeps_mujocos_whole_reason(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    bad = _write(tmp_path, "bad.xml", "<mujoco>\n<worldbody>\n<body>\n<oops>\n</mujoco>\n")
    code, _, err = run(capsys, "verify", bad)
    assert code == 2
    assert_one_error_line(err, "XML_ERROR_MISMATCHED_ELEMENT")
    assert "Line number=4" in err
    geom = '<body><geom size="a"/></body>'
    bad = _write(tmp_path, "size.xml", f"<mujoco><worldbody>{geom}</worldbody></mujoco>")
    code, _, err = run(capsys, "verify", bad)
    assert_one_error_line(err, "bad format in attribute 'size'; Element 'geom', line 1")


def test_a_near_miss_matches_the_tail_of_a_robot_name(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "verify", "ur5e")
    assert code == 2
    assert_one_error_line(err, "did you mean 'universal_robots_ur5e'")


def test_model_kinds_by_suffix_in_any_case(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    urdf = tmp_path / "arm3.URDF"
    urdf.write_bytes(
        (pathlib.Path(__file__).parents[1] / "data" / "urdf" / "serial_arm.urdf").read_bytes()
    )
    code, out, err = run(capsys, "verify", str(urdf), "--samples", "20")
    assert code == 0 and "PASS" in out, err
    mjcf = tmp_path / "UR5E.XML"
    mjcf.write_bytes(UR5E_XML.read_bytes())
    code, out, err = run(capsys, "verify", str(mjcf), "--samples", "20")
    assert code == 0 and "PASS" in out, err
    readme = _write(tmp_path, "README.md", "# not a robot\n")
    code, _, err = run(capsys, "verify", readme)
    assert code == 2
    assert_one_error_line(err, "is not a model format poekin reads: an MJCF file (.xml, .mjcf)")


def test_one_tree_vocabulary_for_fk_and_jacobian(capsys: pytest.CaptureFixture[str]) -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    qpos = poekin.sample_qpos(tree, 1, seed=5)[0]
    q = [repr(float(x)) for x in qpos]
    for command in ("fk", "jacobian"):
        code, _, err = run(capsys, command, "unitree_go2", "--frame", "FL_calf", "--q", *q)
        assert code == 2
        assert_one_error_line(err, "sits behind the free joint 'joint0'")
        assert "pass --tree" in err and "--all-frames" not in err
    argv = ["fk", "unitree_go2", "--frame", "FL_calf", "--json", "--q", *q]
    code, out, _ = run(capsys, *argv, "--tree")
    assert code == 0
    assert_close("T", json.loads(out)["T"], tree.fk(qpos)[tree.frame_index("FL_calf")], 0.0)
    code, out, _ = run(
        capsys, "fk", "unitree_go2", "--frame", "FL_calf", "--relative-to", "base", "--json",
        "--q", *q,
    )  # fmt: skip
    assert code == 0 and json.loads(out)["relative_to"] == "base"
    T = tree.fk(qpos)
    T_base_calf = np.linalg.inv(T[tree.frame_index("base")]) @ T[tree.frame_index("FL_calf")]
    assert_close("T_base_FL_calf", json.loads(out)["T"], T_base_calf, 1e-15)
    argv = ["fk", "unitree_go2", "--frame", "FL_calf", "--relative-to", "base", "--q", *q]
    code, out, _ = run(capsys, *argv)
    assert out.startswith("T_base_FL_calf =")


def test_dh_of_a_model_without_joints_names_it(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    xml = _write(
        tmp_path,
        "nojoint.xml",
        '<mujoco><worldbody><body name="b" pos="0 0 1"><geom size="0.1"/>'
        '<site name="tip" pos="0 0 0.5"/></body></worldbody></mujoco>',
    )
    code, out, _ = run(capsys, "dh", xml, "--json")
    table = json.loads(out)
    assert code == 0 and table["rows"] == []
    assert table["robot"] == "nojoint.xml" and table["frame"] == "tip"
    tool = np.eye(4)
    tool[2, 3] = 1.5
    assert_close("tool", table["tool"], tool, 0.0)


def test_json_goes_with_q_not_with_input(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    np.save(tmp_path / "q.npy", np.zeros((2, 6)))
    code, out, err = run(
        capsys, "fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.npy"),
        "--output", str(tmp_path / "T.npy"), "--json",
    )  # fmt: skip
    assert code == 2 and out == ""
    assert_one_error_line(err, "--json prints the result of one --q")
    assert [p.name for p in tmp_path.iterdir()] == ["q.npy"]


def test_diagnose_a_table_typed_with_four_decimals(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    """UR's published UR5e table with pi/2 typed as 1.5708."""
    table = poekin.named_params("ur5e-dh").describe()
    for row in table["rows"]:
        row["alpha"] = round(row["alpha"], 4)
    path = tmp_path / "ur5e_1p5708.json"
    path.write_text(json.dumps(table))
    code, out, _ = run(capsys, "diagnose", "--params", str(path))
    assert code == 1
    line = next(ln for ln in out.splitlines() if "alpha1:" in ln)
    assert "1.5708 rad" in line and "1.570796 rad" in line and "+3.67e-06 rad" in line
    mismatch = next(ln for ln in out.splitlines() if ln.startswith("MISMATCH"))
    assert "aligning the base does not reduce it" in mismatch
    steps = [ln for ln in out.splitlines() if ln.startswith("  ") and "-> max error" in ln]
    assert steps and not any("unchanged" in s for s in steps)
    last = float(steps[-1].split("max error ")[1].split(" m")[0])
    assert last <= 1e-6  # the bisection reaches the tolerance
    errors = [float(s.split("max error ")[1].split(" m")[0]) for s in steps]
    assert errors == sorted(errors, reverse=True) and len(set(errors)) == len(errors)


def test_degrees_with_deg_and_a_note_without(
    capsys: pytest.CaptureFixture[str], fresh_machine: None
) -> None:
    """The built-in UR5e, which loads without a note of its own: only --deg's note is left."""
    chain = load("universal_robots_ur5e")
    degrees = ["0", "-90", "90", "0", "45", "0"]
    code, out, err = run(capsys, "fk", "universal_robots_ur5e", "--deg", "--json", "--q", *degrees)
    assert code == 0 and err == "" and json.loads(out)["deg"] is True
    expected = chain.fk(np.radians([float(x) for x in degrees]))
    assert_close("T --deg", json.loads(out)["T"], expected, 0.0)
    code, out, err = run(capsys, "fk", "universal_robots_ur5e", "--json", "--q", *degrees)
    assert code == 0
    assert err == (
        "poekin: note: revolute joint values up to 90 are read as radians (more than a turn); "
        "if they are degrees, pass --deg\n"
    )
    assert_close("T", json.loads(out)["T"], chain.fk([float(x) for x in degrees]), 0.0)


def test_deg_turns_only_the_hinges_of_a_whole_qpos(capsys: pytest.CaptureFixture[str]) -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    stand_deg = ["0", "0", "0.3", "1", "0", "0", "0"] + ["0", "51.5", "-103"] * 4
    argv = ["fk", "unitree_go2", "--all-frames", "--deg", "--json", "--q", *stand_deg]
    code, out, _ = run(capsys, *argv)
    qpos = np.array([float(x) for x in stand_deg])
    qpos[7:] = np.radians(qpos[7:])
    assert code == 0
    assert_close("poses", list(json.loads(out)["frames"].values()), tree.fk(qpos), 0.0)


def test_values_outside_the_joint_limits_get_a_note(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    code, _, err = run(capsys, "fk", "franka_fr3", "--q", *"0000000")
    assert code == 0
    # both joints whose range excludes 0, in one note (issue 20: not only the first)
    assert (
        "poekin: note: outside the joint limits: 'fr3_joint4' = 0 rad, not in [-3.0421, -0.1518]; "
        "'fr3_joint6' = 0 rad, not in [0.5445, 4.5169] (computed all the same)" in err
    )
    limits = load(load_quiet("franka_fr3")).limits
    q = np.tile(limits.mean(axis=1), (5, 1))  # within the limits
    q[2:4, 0] = 3.0  # fr3_joint1 is limited to +-2.7437
    q[4, 2] = -3.0  # fr3_joint3 to +-2.9007
    np.save(tmp_path / "q.npy", q)
    code, _, err = run(
        capsys, "fk", "franka_fr3", "--input", str(tmp_path / "q.npy"),
        "--output", str(tmp_path / "T.npy"),
    )  # fmt: skip
    assert code == 0
    assert (
        "3 of 5 configurations are outside the joint limits: 'fr3_joint1' in 2 rows (first row 2: "
        "3 rad), not in [-2.7437, 2.7437]; 'fr3_joint3' in 1 row (first row 4: -3 rad), not in "
        "[-2.9007, 2.9007] (computed all the same)" in err
    )


def test_printed_tables_have_no_rounding_noise_and_a_precision(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, _ = run(capsys, "screws", "universal_robots_ur5e")
    assert code == 0
    lines = out.splitlines()
    assert lines[1].split() == ["joint", "type", "wx", "wy", "wz", "vx", "vy", "vz"]
    assert "0.817000" in out and "-0.000000" not in out and "0.816999" not in out
    code, out, _ = run(capsys, "screws", "universal_robots_ur5e", "--precision", "2")
    assert "0.82" in out and "0.817" not in out
    code, out, _ = run(capsys, "fk", "universal_robots_ur5e", "--precision", "12", "--q", *"000000")
    assert "-0.817000000000" in out
    with pytest.raises(SystemExit) as exc:
        main(["dh", "universal_robots_ur5e", "--precision", "18"])
    assert exc.value.code == 2
    assert "must be a whole number from 0 to 17, got '18'" in capsys.readouterr().err


def test_version_and_python_dash_m() -> None:
    from poekin.cli import version

    text = version()
    assert text.startswith(f"poekin {poekin.__version__} (") and "NumPy" in text
    assert ("AVX" in text or "SSE2" in text) if poekin.compiled_kernel() else "NumPy path" in text
    for module in ("poekin", "poekin.cli"):
        proc = subprocess.run(
            [sys.executable, "-m", module, "--version"], capture_output=True, text=True, check=False
        )
        assert proc.returncode == 0 and proc.stdout == text + "\n", proc.stderr


def test_a_dh_file_in_degrees_without_saying_so_gets_a_note(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    table = poekin.named_params("ur5e-dh").describe()
    for row in table["rows"]:
        row["alpha"] = float(np.degrees(row["alpha"]))
    path = _write(tmp_path, "mine.json", json.dumps(table))
    code, _, err = run(capsys, "fk", "--params", path, "--q", *"000000")
    assert code == 0
    assert err == (
        f"poekin: note: {path}: rows[0].alpha = 90 is read as radians (more than a turn); if the "
        "table's angles are degrees, add angle_unit: deg\n"
    )
    table["angle_unit"] = "deg"
    path = _write(tmp_path, "mine_deg.json", json.dumps(table))
    code, out, err = run(capsys, "fk", "--params", path, "--json", "--q", *"000000")
    assert code == 0 and err == ""
    assert_close("T", json.loads(out)["T"], poekin.named_params("ur5e-dh").fk(np.zeros(6)), 1e-15)


def test_floating_base_from_the_command_line(capsys: pytest.CaptureFixture[str]) -> None:
    urdf = str(pathlib.Path(__file__).parents[1] / "data" / "urdf" / "serial_arm.urdf")
    tree = poekin.load_tree(urdf, floating_base=True)
    qpos = poekin.sample_qpos(tree, 1, seed=4)[0]
    q = [repr(float(x)) for x in qpos]
    argv = ["fk", urdf, "--floating-base", "--tree", "--frame", "tool0", "--json", "--q", *q]
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    assert_close("T", json.loads(out)["T"], tree.fk(qpos)[tree.frame_index("tool0")], 0.0)
    code, out, err = run(capsys, "verify", urdf, "--floating-base", "--samples", "30")
    assert code == 0 and "tree FK" in out and "every body and site" in out, err
    code, _, err = run(capsys, "fk", urdf, "--floating-base", "--q", *q)
    assert code == 2
    assert_one_error_line(err, "--floating-base gives a whole model's qpos: pass --tree too")
    code, _, err = run(capsys, "verify", "--floating-base")
    assert code == 2
    assert_one_error_line(err, "floating_base applies to URDF")


def test_verify_of_a_malformed_urdf_names_the_joint(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    """poekin reads a URDF before MuJoCo compiles it, so its message (naming the joint and the
    fix) comes first, not MuJoCo's 'attribute has too much data'."""
    text = (pathlib.Path(__file__).parents[1] / "data" / "urdf" / "serial_arm.urdf").read_text()
    bad = text.replace('rpy="0 0 0.3"', 'rpy="0 0 0.3 0"', 1)
    assert bad != text
    path = _write(tmp_path, "bad.urdf", bad)
    code, _, err = run(capsys, "verify", path)
    assert code == 2
    assert_one_error_line(err, "has 4 numbers; give 3 numbers (roll pitch yaw)")
    assert "joint '" in err


# --- issue 20: jacobian's frame options, fk's forms, writes the OS refuses ---------------------

GO2_STAND = ["0", "0", "0.3", "1", "0", "0", "0"] + ["0", "0.9", "-1.8"] * 4


def test_jacobian_takes_fks_frame_options(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    qpos = np.array([float(x) for x in GO2_STAND])
    argv = ["jacobian", "unitree_go2", "--frame", "FL_calf", "--relative-to", "base"]
    for convention in ("space", "body", "world"):
        code, out, _ = run(capsys, *argv, "--convention", convention, "--json", "--q", *GO2_STAND)
        reply = json.loads(out)
        expected = tree.jacobian(qpos, "FL_calf", convention, relative_to="base")
        assert code == 0 and reply["relative_to"] == "base" and reply["frame"] == "FL_calf"
        assert_close(f"--relative-to base, {convention}", reply["J"], expected, 0.0)
    code, out, _ = run(capsys, *argv, "--convention", "world", "--q", *GO2_STAND)
    assert out.startswith(
        "J_world of 'FL_calf' relative to 'base' (6 x 18), rows [w; v_frame] in 'base' coordinates"
    )
    # --all-frames: every frame's Jacobian along axis -3, in a file
    np.save(tmp_path / "qpos.npy", poekin.sample_qpos(tree, 5, seed=2))
    code, out, _ = run(
        capsys, "jacobian", "unitree_go2", "--all-frames", "--input", str(tmp_path / "qpos.npy"),
        "--output", str(tmp_path / "J.npz"),
    )  # fmt: skip
    assert code == 0 and "(5, 14, 6, 18)" in out
    with np.load(tmp_path / "J.npz") as saved:
        assert list(saved["frames"]) == list(tree.frame_names)
        for f, name in enumerate(tree.frame_names):
            expected = tree.jacobian(np.load(tmp_path / "qpos.npy"), name, "space")
            assert_close(name, saved["J"][:, f], expected, 0.0)


def test_fk_forms_pos_quat_and_xyz_rpy(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    """xyz_rpy is URDF's roll-pitch-yaw, R = Rz(yaw) Ry(pitch) Rx(roll): checked against
    SciPy's extrinsic 'xyz' Euler angles; pos_quat against SciPy's quaternion (w first)."""
    from scipy.spatial.transform import Rotation

    chain = load("universal_robots_ur5e")
    q = [0.1, -1.2, 1.3, 0.4, -0.5, 2.0]
    T = chain.fk(q)
    argv = ["fk", "universal_robots_ur5e", "--q", *map(str, q)]
    code, out, _ = run(capsys, *argv, "--form", "xyz_rpy", "--json")
    reply = json.loads(out)
    assert code == 0 and reply["form"] == "xyz_rpy"
    assert_close("xyz", reply["xyz_rpy"][:3], T[:3, 3], 0.0)
    assert_close(
        "rpy", reply["xyz_rpy"][3:], Rotation.from_matrix(T[:3, :3]).as_euler("xyz"), 1e-12
    )
    rebuilt = Rotation.from_euler("xyz", reply["xyz_rpy"][3:]).as_matrix()
    assert_close("Rz Ry Rx", rebuilt, T[:3, :3], 1e-12)
    code, out, _ = run(capsys, *argv, "--form", "pos_quat", "--json")
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    expected = np.array([w, x, y, z]) * np.sign(w)  # poekin's has w >= 0
    assert_close("quat", json.loads(out)["pos_quat"][3:], expected, 1e-12)
    code, out, _ = run(capsys, *argv, "--form", "xyz_rpy", "--precision", "3")
    lines = out.splitlines()
    assert lines[0] == "T_world_attachment_site ="
    assert lines[1].split()[:2] == ["xyz", "[m]"] and lines[2].split()[:2] == ["rpy", "[rad]"]
    assert [float(v) for v in lines[2].split()[2:]] == pytest.approx(
        Rotation.from_matrix(T[:3, :3]).as_euler("xyz"), abs=5e-4
    )
    # a batch: (N, 7) rows with named columns
    batch = np.random.default_rng(0).uniform(-3, 3, (4, 6))
    np.save(tmp_path / "q.npy", batch)
    out_csv = tmp_path / "P.csv"
    code, out, _ = run(
        capsys, "fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.npy"),
        "--output", str(out_csv), "--form", "pos_quat",
    )  # fmt: skip
    assert code == 0 and "poses pos_quat of shape (4, 7)" in out
    assert out_csv.read_text().splitlines()[0] == "x,y,z,qw,qx,qy,qz"
    rows = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    Tb = chain.fk(batch)
    assert_close("positions", rows[:, :3], Tb[:, :3, 3], 0.0)
    assert_close("rotations", poekin.quat_to_rotation(rows[:, 3:]), Tb[:, :3, :3], 1e-15)


def test_a_write_the_os_refuses_midway_is_one_line_and_leaves_nothing(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A check before the work cannot foresee everything (a disk that fills, a folder made
    read-only meanwhile): what the OS refuses while writing is one line too, naming the path."""
    import errno

    from poekin.io import fileio

    np.save(tmp_path / "q.npy", np.zeros((2, 6)))
    listing = sorted(tmp_path.iterdir())

    def refused(src: object, dst: object) -> None:
        raise OSError(errno.EROFS, "Read-only file system", str(dst))

    monkeypatch.setattr(fileio.os, "replace", refused)
    for argv in (
        ["fk", "universal_robots_ur5e", "--input", str(tmp_path / "q.npy"), "--output"],
        ["draw", "--out"],
    ):
        target = tmp_path / ("T.npy" if argv[0] == "fk" else "a.png")
        code, out, err = run(capsys, *argv, str(target))
        assert code == 2 and out == ""
        what = "the poses" if argv[0] == "fk" else "the drawing"
        assert_one_error_line(
            err,
            f"cannot write {what} to {target}: folder {target.parent} is not writable "
            "(read-only file system)",
        )
        assert sorted(tmp_path.iterdir()) == listing  # neither the file nor a temporary one


def test_verify_of_a_missing_urdf_says_so_before_asking_for_yourdfpy(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # as if the extra were not installed
    for argv in (["verify"], ["fk", "--q", "0"], ["screws"]):
        code, _, err = run(capsys, argv[0], str(tmp_path / "x.urdf"), *argv[1:])
        assert code == 2
        assert_one_error_line(err, "x.urdf: no such URDF file; check the path")
    (tmp_path / "x.urdf").write_text('<robot name="r"><link name="a"/></robot>')
    code, _, err = run(capsys, "verify", str(tmp_path / "x.urdf"))
    assert code == 2
    assert_one_error_line(err, "reading x.urdf needs yourdfpy, which is not installed")


def test_no_two_help_examples_write_one_file() -> None:
    """Run one after another in one folder, as a reader trying them would, every --help example
    works: no two write the same file (issue 20: jacobian's two wrote J.npy; poekin --help
    repeated verify's, which wrote fk.png)."""
    import shlex

    from poekin.cli import _build_parser

    parser = _build_parser()
    epilogs = [parser.epilog or ""]
    sub = next(a for a in parser._actions if a.dest == "command")
    epilogs += [p.epilog or "" for p in sub.choices.values()]  # type: ignore[union-attr]
    written: dict[str, str] = {}
    for line in (ln.strip() for e in epilogs for ln in e.splitlines()):
        argv = shlex.split(line) if line.startswith("poekin ") else []
        for flag in ("--output", "--out", "--plot"):
            if flag in argv:
                path = argv[argv.index(flag) + 1]
                assert path not in written, f"{line!r} and {written[path]!r} both write {path}"
                written[path] = line
    assert {"J.npy", "J_FL_calf.npy", "fk.png", "T.csv"} <= set(written)
