"""``poekin path``: a straight line of the end frame, followed and timed; the trajectory it
writes checked by MuJoCo's FK (the end pose, the line between samples) and against its limits;
the bad-input matrix, one line each."""

from __future__ import annotations

import json
import pathlib

import mujoco
import numpy as np
import pytest
from helpers import assert_one_error_line, load_quiet, mj_frame_pose, run

import poekin
from poekin.io.trajectory import load_trajectory

START = ["0.3", "-1.2", "1.4", "-0.5", "1.1", "0.2"]
END = ["0.6", "-1.0", "1.2", "-0.7", "1.3", "0.4"]


def _mujoco_poses(q: np.ndarray) -> np.ndarray:
    loaded = load_quiet("universal_robots_ur5e")
    model, data = loaded.model, mujoco.MjData(loaded.model)
    site = model.site("attachment_site").id
    out = []
    for row in q:
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        out.append(mj_frame_pose(model, data, "site", site))
    return np.array(out)


def test_a_line_is_followed_timed_and_written(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    out_file = tmp_path / "traj.npz"
    vel, acc = 1.0, 2.0
    code, out, err = run(
        capsys,
        "path",
        "universal_robots_ur5e",
        "--from",
        *START,
        "--to",
        *END,
        "--vel-limits",
        str(vel),
        "--acc-limits",
        str(acc),
        "--output",
        str(out_file),
        "--json",
    )
    assert code == 0, err
    report = json.loads(out)
    assert report["fraction"] == 1.0 and report["reason"] == "done"
    assert report["path"] == "line" and report["max_deviation_m"] <= 1e-4
    traj = load_trajectory(out_file)
    assert traj.t[0] == 0.0 and np.all(np.diff(traj.t) > 0)
    assert traj.duration == pytest.approx(report["duration_s"])
    # the limits at every sample, by the file's own derivatives and by differences of q
    assert np.all(np.abs(traj.qd) <= vel * (1 + 1e-9))
    assert np.all(np.abs(traj.qdd) <= acc * (1 + 1e-9))
    assert np.all(np.abs(np.diff(traj.q, axis=0)) / np.diff(traj.t)[:, None] <= vel * (1 + 1e-6))
    # by MuJoCo: it starts at --from, ends at --to's pose, and every sample is on the line
    poses = _mujoco_poses(traj.q)
    goal = _mujoco_poses(np.array([[float(v) for v in END]]))[0]
    np.testing.assert_allclose(traj.q[0], [float(v) for v in START], atol=0)
    assert np.linalg.norm(poses[-1, :3, 3] - goal[:3, 3]) < 1e-9
    p0, p1 = poses[0, :3, 3], goal[:3, 3]
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    off = poses[:, :3, 3] - p0
    off_line = off - (off @ u)[:, None] * u
    assert np.max(np.linalg.norm(off_line, axis=1)) < 2e-4  # samples between follow's: the spline


def test_text_output_names_every_joint(
    capsys: pytest.CaptureFixture[str], ur5e: poekin.Chain
) -> None:
    code, out, err = run(capsys, "path", "universal_robots_ur5e", "--from", *START, "--to", *END)
    assert code == 0, err
    assert "line of " in out and "followed to its end" in out
    assert all(name in out for name in ur5e.joint_names)
    assert "poekin: note: limits: 1.05 rad/s and 1.4 rad/s^2" in err


def test_a_line_out_of_reach_stops_and_says_where(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path, ur5e: poekin.Chain
) -> None:
    """A line to a point 3 m away leaves the workspace: exit 1, the part followed is written,
    and the file says where and why it stopped."""
    out_file = tmp_path / "stop.npz"
    q0 = np.array([float(v) for v in START])
    p = ur5e.fk(q0)[:3, 3] + [3.0, 0.0, 0.0]
    pose = [*map(str, p), "0", "1", "0", "0"]
    code, out, err = run(
        capsys,
        "path",
        "universal_robots_ur5e",
        "--from",
        *START,
        "--to-pose",
        *pose,
        "--output",
        str(out_file),
        "--json",
    )
    assert code == 1, err
    report = json.loads(out)
    assert report["reason"] != "done" and 0.0 < report["fraction"] < 1.0
    traj = load_trajectory(out_file)
    assert traj.fraction == pytest.approx(report["fraction"]) and traj.reason
    assert traj.stop_index == len(traj.t) - 1


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "give the path's end: --to-pose"),
        (["--to", *END, "--to-pose", "0.4", "0", "0.3", "1", "0", "0", "0"], "give the path's end"),
        (["--to-pose", "0.4", "0", "0.3"], "--to-pose takes 7 numbers"),
        (["--to-pose", "0.4", "0", "0.3", "2", "0", "0", "0"], "quaternion"),
        (["--to-pose", "nan", "0", "0.3", "1", "0", "0", "0"], "NaN"),
        (["--to", *END, "--rate", "0"], "--rate must be a number > 0"),
        (["--to", *END, "--vel-limits", "-1"], "--vel-limits takes one number > 0 or 6"),
        (["--to", *END, "--acc-limits", "1", "2"], "--acc-limits takes one number > 0 or 6"),
        (["--to", *END, "--tol", "0"], "--tol must be a number > 0"),
        (["--to", *END, "--output", "traj.csv"], "a trajectory file is a .npz archive"),
        (["--to", "0", "0"], "expected 6 --to values"),
    ],
)
def test_bad_input_is_one_line(
    capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    code, out, err = run(capsys, "path", "universal_robots_ur5e", "--from", *START, *extra)
    assert code == 2 and out == ""
    assert_one_error_line(err, message)


def test_an_existing_output_is_kept_without_force(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    out_file = tmp_path / "traj.npz"
    out_file.write_bytes(b"mine")
    argv = ["path", "universal_robots_ur5e", "--from", *START, "--to", *END]
    code, _, err = run(capsys, *argv, "--output", str(out_file))
    assert code == 2 and out_file.read_bytes() == b"mine"
    assert_one_error_line(err, "already exists")
    code, _, err = run(capsys, *argv, "--output", str(out_file), "--force")
    assert code == 0, err
    assert load_trajectory(out_file).q.shape[1] == 6
