"""A trajectory played in the viewer (poekin view --play): the match with the robot shown, the
configuration at any time, the tool trace (checked against MuJoCo's mj_forward), the real-time
clock; then a headless Viewer with its slider, play button and trace, and the command line."""

from __future__ import annotations

import dataclasses
import functools
import pathlib
import signal
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pytest
from helpers import MJ_TOL, assert_one_error_line, load_quiet, mj_pose, run
from trajectory_helpers import quintic

import poekin
from poekin import lie
from poekin.errors import InputError
from poekin.io.trajectory import Trajectory, qpos_column_names
from poekin.viewer.loading import load_shown
from poekin.viewer.play import Clock, playback_of, tool_trace
from poekin.viewer.scene import Subject

pytestmark = pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")

UR5E = "universal_robots_ur5e"
G1_HAND = "left_elbow_roll_link"


@functools.cache
def _subject(robot: str, frame: str | None = None) -> Subject:
    return load_shown(load_quiet(robot), frame).subject


def _ur5e_trajectory(**changes: Any) -> Trajectory:
    t, q, qd, qdd = quintic()
    names = _subject(UR5E).chain.joint_names
    return dataclasses.replace(Trajectory(t, q, qd, qdd, robot=UR5E, joint_names=names), **changes)


# --- the match --------------------------------------------------------------------------------


def test_a_chain_trajectory_plays_as_the_robots_qpos() -> None:
    subject = _subject(UR5E)
    shown = playback_of(subject, _ur5e_trajectory())
    assert shown.what == "qpos" and shown.quats == ()
    assert np.array_equal(shown.qpos, quintic()[1])
    # without names too
    assert playback_of(subject, _ur5e_trajectory(joint_names=())).what == "qpos"


def test_the_tool_trace_is_mujocos_end_frame() -> None:
    subject = _subject(UR5E)
    shown = playback_of(subject, _ur5e_trajectory())
    trace = tool_trace(subject, shown.qpos)
    want = mj_pose(load_quiet(UR5E).model, shown.qpos, "attachment_site")[:, :3, 3]
    assert trace.shape == (201, 3)
    assert np.max(np.abs(trace - want)) < MJ_TOL
    # a tool on the end frame: the tool's point
    tool = np.eye(4)
    tool[:3, 3] = [0.0, 0.0, 0.15]
    with_tool = load_shown(load_quiet(UR5E), tool=tool).subject
    T = mj_pose(load_quiet(UR5E).model, shown.qpos, "attachment_site") @ tool
    assert np.max(np.abs(tool_trace(with_tool, shown.qpos) - T[:, :3, 3])) < MJ_TOL


def test_a_chain_of_a_floating_robot_plays_with_the_rest_at_qpos0() -> None:
    """The G1's left arm (from the pelvis): its joint values into qpos, the trace MuJoCo's."""
    subject = _subject("unitree_g1", G1_HAND)
    tree = subject.tree
    assert tree is not None
    names = subject.chain.joint_names
    n = len(names)
    t = np.linspace(0.0, 1.0, 21)
    q = 0.3 * np.sin(np.outer(t, np.arange(1, n + 1)))
    shown = playback_of(subject, Trajectory(t, q, joint_names=names))
    assert shown.what == "chain" and shown.quats == (3,)
    for j, name in enumerate(names):
        column = tree.qpos_adr[tree.joint_names.index(name)]
        assert np.array_equal(shown.qpos[:, column], q[:, j])
    others = [
        c
        for c in range(tree.nq)
        if c not in tree.qpos_adr[[tree.joint_names.index(m) for m in names]]
    ]
    assert np.array_equal(shown.qpos[:, others], np.repeat(tree.qpos0[None, others], 21, axis=0))
    want = mj_pose(load_quiet("unitree_g1").model, shown.qpos, G1_HAND)[:, :3, 3]
    assert np.max(np.abs(tool_trace(subject, shown.qpos) - want)) < MJ_TOL


def test_a_qpos_trajectory_turns_the_shorter_way() -> None:
    """Between samples: the hinges linear (np.interp), the floating base's quaternion
    normalised; one sample's quaternion negated (the same rotation) changes nothing."""
    subject = _subject("unitree_g1", G1_HAND)
    tree = subject.tree
    assert tree is not None
    rng = np.random.default_rng(3)
    t = np.array([0.0, 0.4, 1.0])
    qpos = np.repeat(tree.qpos0[None], 3, axis=0)
    qpos[:, 7:] += rng.normal(0.0, 0.2, (3, tree.nq - 7))
    quats = lie.quat_normalize(rng.normal(size=(3, 4)))
    qpos[:, 3:7] = quats
    flipped = qpos.copy()
    flipped[1, 3:7] *= -1.0
    names = qpos_column_names(tree)
    shown = playback_of(subject, Trajectory(t, qpos, joint_names=names))
    other = playback_of(subject, Trajectory(t, flipped))
    assert shown.what == "qpos" and shown.quats == (3,)
    for time_ in (0.0, 0.1, 0.4, 0.77, 1.0):
        x = shown.qpos_at(time_)
        for c in [0, 1, 2, *range(7, tree.nq)]:
            assert abs(x[c] - np.interp(time_, t, qpos[:, c])) < 1e-15
        assert abs(np.linalg.norm(x[3:7]) - 1.0) < 1e-15
        R, R_other = lie.quat_to_rotation(x[3:7]), lie.quat_to_rotation(other.qpos_at(time_)[3:7])
        assert np.max(np.abs(R - R_other)) < 1e-15
    assert np.array_equal(shown.qpos_at(0.4), qpos[1]) and np.array_equal(
        shown.qpos_at(5.0), qpos[2]
    )
    assert np.array_equal(shown.qpos_at(-1.0), qpos[0])
    # the rotation at the middle of a sample pair lies between its ends
    a, b = lie.quat_to_rotation(qpos[1, 3:7]), lie.quat_to_rotation(qpos[2, 3:7])
    mid = lie.quat_to_rotation(shown.qpos_at(0.7)[3:7])
    angle = lambda R1, R2: float(np.linalg.norm(lie.log_so3(R1.T @ R2)))  # noqa: E731
    assert abs(angle(a, mid) + angle(mid, b) - angle(a, b)) < 1e-9


def test_bare_parameters_play_their_joint_values() -> None:
    chain = poekin.named_params("ur5e-dh")
    subject = load_shown(chain).subject
    shown = playback_of(subject, _ur5e_trajectory(joint_names=()))
    assert shown.what == "chain"
    fk = np.asarray(subject.chain.fk(shown.qpos))[:, :3, 3]
    assert np.array_equal(tool_trace(subject, shown.qpos), fk)


def test_a_trajectory_of_another_robot_is_refused() -> None:
    subject = _subject(UR5E)
    t = np.linspace(0.0, 1.0, 5)
    fr3 = Trajectory(t, np.zeros((5, 7)), robot="franka_fr3")
    with pytest.raises(InputError) as info:
        playback_of(subject, fr3, "--play fr3.npz")
    assert str(info.value) == (
        "--play fr3.npz (made for 'franka_fr3') holds 7 columns; universal_robots_ur5e takes "
        "its qpos: 6 (shoulder_pan_joint, shoulder_lift_joint, elbow_joint, wrist_1_joint, "
        "... (6 in all)): play it on its robot, poekin view franka_fr3 --play FILE"
    )
    renamed = _ur5e_trajectory(joint_names=("a", "b", "c", "d", "e", "f"), robot="")
    with pytest.raises(InputError, match=r"^the trajectory holds 6 columns \(a, b, c, d, \.\.\. "):
        playback_of(subject, renamed)
    g1 = _subject("unitree_g1", G1_HAND)
    with pytest.raises(InputError) as info:
        playback_of(g1, _ur5e_trajectory())
    message = str(info.value)
    assert "unitree_g1 takes its qpos: 44 (floating_base_joint[x], " in message
    assert f" or its chain to '{G1_HAND}': 6 (torso_joint, " in message
    assert "\n" not in message


# --- the clock ----------------------------------------------------------------------------------


def test_the_clock_plays_pauses_seeks_and_stops_at_the_end() -> None:
    clock = Clock(0.5, 2.5, 0.0)
    assert clock.time == 0.5 and not clock.playing and clock.at(100.0) == 0.5
    clock.play(now=10.0)
    assert clock.at(10.25) == 0.75 and clock.tick(11.0) == 1.5 and clock.playing
    clock.pause(now=11.5)
    assert clock.time == 2.0 and clock.at(50.0) == 2.0 and not clock.playing
    clock.seek(1.0, now=60.0)
    clock.play(now=61.0)
    assert clock.tick(61.5) == 1.5
    clock.seek(0.75, now=62.0)  # a seek while playing plays on from there
    assert clock.tick(62.5) == 1.25 and clock.playing
    assert clock.tick(70.0) == 2.5 and not clock.playing  # the end: stopped there
    clock.play(now=80.0)  # again: from the start
    assert clock.tick(80.5) == 1.0
    clock.seek(-3.0, now=81.0)
    assert clock.time == 0.5
    clock.seek(9.0, now=81.0)
    assert clock.tick(81.0) == 2.5 and not clock.playing


# --- the viewer -------------------------------------------------------------------------------

viser = pytest.importorskip("viser")


def _bodies_at(v: Any, qpos: np.ndarray) -> None:
    tree = v.subject.tree
    T = tree.fk(qpos)
    poses = v.node_poses("body")
    for b in range(len(tree.body_names)):
        assert np.max(np.abs(poses[f"/robot/b{b}"] - T[b])) < 1e-12


def test_the_viewer_plays_a_trajectory() -> None:
    from poekin.viewer.app import view

    t, q, _, _ = quintic(31, duration=0.3)
    trajectory = _ur5e_trajectory(t=t, q=q, qd=None, qdd=None, fraction=0.8, reason="singular")
    with view(UR5E, port=0, open_browser=False, play=trajectory) as v:
        assert v.playback is not None and v.playback.trajectory is trajectory
        assert np.array_equal(v.q, q[0]) and v.play_time == 0.0 and not v.playing
        # the trace: MuJoCo's end frame at every sample, as float32 segments
        segments = v.node("/play/trace").points
        want = mj_pose(load_quiet(UR5E).model, q, "attachment_site")[:, :3, 3]
        assert segments.shape == (30, 2, 3)
        assert np.max(np.abs(segments[:, 0] - want[:-1])) < 1e-6
        assert np.max(np.abs(segments[:, 1] - want[1:])) < 1e-6
        assert np.max(np.abs(v.node("/play/stop").position - want[-1])) < 1e-12
        assert v.node("/play/stop/label").text == "stopped at 80.0%: singular"
        assert v.texts()["trajectory"].startswith("**31** samples over **0.3 s** for `")
        # a time: the robot there, the slider there
        v.play_time = 0.105
        x = np.array([np.interp(0.105, t, q[:, j]) for j in range(6)])
        assert np.max(np.abs(v.q - x)) < 1e-15 and v.options()["time [s]"] == 0.105
        _bodies_at(v, v.q)
        v.set_option("time [s]", 0.2)  # as the page's slider
        assert np.max(np.abs(v.q - q[20])) < 1e-15
        v.set_option("tool trace", False)
        assert not v.node("/play/trace").visible
        with pytest.raises(InputError, match=r"time runs from 0 to 0.3 s, got 0.5"):
            v.play_time = 0.5
        # real time: to the end, then stopped there
        v.play_time = 0.0
        v.play()
        assert v.playing
        deadline = time.monotonic() + 5.0
        while v.playing and time.monotonic() < deadline:
            time.sleep(0.02)
        assert not v.playing and v.play_time == 0.3 and np.array_equal(v.q, q[-1])
        # pause holds the time reached
        v.play()
        time.sleep(0.05)
        v.pause()
        held = v.play_time
        assert 0.0 < held < 0.3 and not v.playing
        time.sleep(0.05)
        assert v.play_time == held
        # another end frame: the trace follows it
        v.set_option("end frame", "wrist_2_link")
        points = v.node("/play/trace").points
        want = mj_pose(load_quiet(UR5E).model, q, "wrist_2_link")[:, :3, 3]
        assert np.max(np.abs(points[:, 0] - want[:-1])) < 1e-6


def test_a_viewer_without_a_trajectory_has_none(tmp_path: pathlib.Path) -> None:
    from poekin.viewer.app import view

    path = _ur5e_trajectory().save(tmp_path / "traj.npz")
    with view(UR5E, port=0, open_browser=False) as v:
        assert v.playback is None and not v.playing and v.node_names("trace") == []
        with pytest.raises(InputError, match="no trajectory to play: start the viewer with"):
            v.play()
    with view(UR5E, port=0, open_browser=False, play=path) as v:  # from its file
        assert v.playback is not None and v.node_names("trace") == ["/play/trace"]
        assert v.node_names("trace_stop") == []  # it did not stop early
    with pytest.raises(InputError, match=r"^play .*fr3.npz \(made for 'franka_fr3'\) holds 7"):
        view(
            UR5E,
            port=0,
            open_browser=False,
            play=Trajectory(np.arange(2.0), np.zeros((2, 7)), robot="franka_fr3").save(
                tmp_path / "fr3.npz"
            ),
        )


# --- the command line ------------------------------------------------------------------------


@pytest.mark.usefixtures("fresh_machine")
def test_view_play_without_a_robot_plays_on_the_files(tmp_path: pathlib.Path) -> None:
    path = _ur5e_trajectory().save(tmp_path / "traj.npz")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "poekin.cli",
            "view",
            "--no-browser",
            "--port",
            "0",
            "--play",
            str(path),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert line.startswith("poekin view: http://127.0.0.1:"), err
    assert (
        f"(universal_robots_ur5e, end frame 'attachment_site'; playing {path}: 201 samples over "
        "2 s); Ctrl-C to stop" in line
    )
    assert proc.returncode == 130


@pytest.mark.usefixtures("fresh_machine")
def test_view_play_bad_input_is_one_line(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "nope.npz"
    code, _, err = run(capsys, "view", "--no-browser", "--play", str(missing))
    assert code == 2
    assert_one_error_line(err, f"--play {missing}: no such file")
    fr3 = Trajectory(np.arange(2.0), np.zeros((2, 7)), robot="franka_fr3").save(tmp_path / "f.npz")
    code, _, err = run(capsys, "view", UR5E, "--no-browser", "--play", str(fr3))
    assert code == 2
    assert_one_error_line(
        err,
        f"--play {fr3} (made for 'franka_fr3') holds 7 columns; universal_robots_ur5e takes its "
        "qpos: 6",
    )
