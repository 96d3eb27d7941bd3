"""``poekin ik ROBOT --targets FILE.json``: many frames at once from the command line, checked
by MuJoCo; bad input is one error line and exit 2."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from helpers import MJ_TOL, assert_one_error_line, load_quiet, mj_pose, run

import poekin


def _g1_file(folder: pathlib.Path, **extra: object) -> tuple[pathlib.Path, dict[str, np.ndarray]]:
    """Both feet where they stand, the pelvis 5 cm lower and turned, the head a point."""
    g1 = poekin.load_tree(load_quiet("unitree_g1"))
    T = g1.fk(g1.qpos0)
    poses = {f: T[g1.frame_index(f)] for f in ("left_foot", "right_foot", "pelvis")}
    pelvis = poses["pelvis"] @ poekin.lie.exp_se3([0.0, 0.0, 0.1, 0.0, 0.0, -0.05])
    poses["pelvis"] = pelvis
    document: dict[str, object] = {f: T_f.tolist() for f, T_f in poses.items()}
    xyz, quat = pelvis[:3, 3], poekin.lie.rotation_to_quat(pelvis[:3, :3])
    document["pelvis"] = [*xyz.tolist(), *quat.tolist()]  # the seven-number form
    document.update(extra)
    document = {f: v for f, v in document.items() if v is not None}  # None: left out
    path = folder / "targets.json"
    path.write_text(json.dumps(document))
    return path, poses


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
def test_g1_crouch_with_held_feet_is_checked_by_mujoco(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    path, poses = _g1_file(tmp_path)
    code, out, err = run(
        capsys, "ik", "unitree_g1", "--targets", str(path), "--hold", "left_foot,right_foot"
    )
    assert code == 0, err
    answer = json.loads(out)
    assert answer["success"] is True and answer["held"] == ["left_foot", "right_foot"]
    qpos = np.array(answer["qpos"])[None]
    model = load_quiet("unitree_g1").model
    for frame, T in poses.items():
        pos, ori = poekin.pose_errors(T, mj_pose(model, qpos, frame)[0])
        assert pos <= 1e-10 + MJ_TOL and ori <= 1e-10 + MJ_TOL, frame
        assert answer["frame_errors"][frame]["pos_err"] <= 1e-10
    assert len(answer["qpos_names"]) == len(answer["qpos"]) == 44


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
def test_an_unreachable_soft_frame_exits_1_with_the_feet_held(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    path, _ = _g1_file(tmp_path, left_elbow_roll_link=[3.0, 0.0, 1.0])  # a point 3 m ahead
    code, out, _ = run(
        capsys, "ik", "unitree_g1", "--targets", str(path), "--hold", "left_foot,right_foot"
    )
    assert code == 1
    answer = json.loads(out)
    assert answer["success"] is False
    assert answer["frame_errors"]["left_foot"]["pos_err"] <= 1e-10
    assert answer["frame_errors"]["left_elbow_roll_link"]["pos_err"] > 1.0


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
@pytest.mark.parametrize(
    ("extra", "argv", "message"),
    [
        (
            {},
            ["--hold", "left_fot"],
            "hold names 'left_fot', which has no target: did you mean 'left_foot'?",
        ),
        (
            {"left_fot": [0, 0, 0]},
            [],
            "no site or body named 'left_fot' to place: did you mean 'left_foot'?",
        ),
        (  # the misspelt target is named, not the held frame it was meant to be
            {"left_fot": [0, 0, 0], "left_foot": None},
            ["--hold", "left_foot"],
            "no site or body named 'left_fot' to place: did you mean 'left_foot'?",
        ),
        ({"pelvis": [1, 2]}, [], "the target of 'pelvis' must be 7 numbers"),
        (  # rows of different lengths
            {"pelvis": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1]]},
            [],
            "the target of 'pelvis' must be 7 numbers",
        ),
        ({"pelvis": [0, 0, 0, 2, 0, 0, 0]}, [], "the quaternion of 'pelvis' has norm 2"),
        (
            {},
            ["--pose", "1", "2", "3"],
            "--targets places every frame the file names: it takes no --pose",
        ),
        ({}, ["--posture", "-1"], "--posture must be a weight >= 0"),
    ],
)
def test_bad_targets_are_one_line(
    capsys: pytest.CaptureFixture[str],
    tmp_path: pathlib.Path,
    extra: dict[str, object],
    argv: list[str],
    message: str,
) -> None:
    path, _ = _g1_file(tmp_path, **extra)
    code, out, err = run(capsys, "ik", "unitree_g1", "--targets", str(path), *argv)
    assert code == 2 and out == ""
    assert_one_error_line(err, message)


def test_unreadable_files_and_misplaced_options(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path
) -> None:
    (tmp_path / "cut.json").write_text('{"pelvis": [1, 2')
    for argv, message in (
        (["--targets", str(tmp_path / "none.json")], "none.json: no such file"),
        (["--targets", str(tmp_path / "cut.json")], "not JSON"),
        (
            ["--pose", "0.4", "0.2", "0.3", "0", "1", "0", "0", "--hold", "a"],
            "--hold goes with --targets",
        ),
    ):
        code, _, err = run(capsys, "ik", "universal_robots_ur5e", *argv)
        assert code == 2
        assert_one_error_line(err, message)
