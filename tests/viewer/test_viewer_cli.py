"""``poekin view`` as a process: the URL line, Ctrl-C, the --host warning, a port in use, and
the missing extra; ``poekin draw`` writes its file."""

from __future__ import annotations

import pathlib
import signal
import socket
import subprocess
import sys

import pytest

from poekin.cli import main

pytest.importorskip("viser")

# `poekin view` as a user on a fresh machine runs it: the built-in UR5e, which loads silently
pytestmark = pytest.mark.usefixtures("fresh_machine")


def _start(*argv: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "poekin.cli", "view", "--no-browser", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.parametrize("attempt", range(3))
def test_view_prints_the_url_and_ctrl_c_exits_130(attempt: int) -> None:
    # Ctrl-C right after the URL line, as a user may: a signal landing just before a long sleep
    # began was lost until the sleep ended (an hour); several attempts catch that race
    proc = _start("--port", "0")
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line.startswith("poekin view: http://127.0.0.1:")
    assert "(universal_robots_ur5e, end frame 'attachment_site'); Ctrl-C to stop" in line
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130
    assert err == "poekin: interrupted\n" and out == ""


def test_a_host_beyond_loopback_is_warned_about() -> None:
    proc = _start("--port", "0", "--host", "0.0.0.0")
    assert proc.stdout is not None and proc.stderr is not None
    assert proc.stdout.readline().startswith("poekin view: http://localhost:")
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert err.splitlines() == [
        "poekin: warning: --host 0.0.0.0: the page is reachable from other machines",
        "poekin: interrupted",
    ]


def test_a_port_in_use_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["view", "--no-browser", "--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"poekin: error: port {port} on 127.0.0.1 is in use; choose another with --port, "
        "or --port 0 for any free port\n"
    )


def test_view_without_the_extra_names_it() -> None:
    code = (
        "import sys; sys.modules['viser'] = None\n"
        "from poekin.cli import main; sys.exit(main(['view']))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.startswith(
        "poekin: error: 'poekin view' needs viser, which is not installed: pip install "
    )
    assert "[view]" in proc.stderr
    assert proc.stderr.count("\n") == 1


def test_draw_writes_and_keeps_files(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "arm.svg"
    assert main(["draw", "--q", "0", "-1.57", "1.57", "0", "0", "0", "--out", str(out)]) == 0
    assert capsys.readouterr().out == f"drawing written to {out}\n"
    before = out.read_bytes()
    assert b"<svg" in before
    assert main(["draw", "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err and out.read_bytes() == before
    assert main(["draw", "--out", str(out), "--force", "--params", "lynch-park-ur5"]) == 0


def test_view_in_process_serves_until_ctrl_c(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    opened: list[str] = []

    def interrupt(_: float) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("time.sleep", interrupt)
    monkeypatch.setattr("webbrowser.open", opened.append)
    assert main(["view", "--port", "0", "--params", "ur5e-poe"]) == 130
    out, err = capsys.readouterr()
    assert out.startswith("poekin view: http://127.0.0.1:") and err == "poekin: interrupted\n"
    assert len(opened) <= 1  # the browser is opened from a thread, maybe after the stop


G1_FRAMES = "left_elbow_roll_link,right_elbow_roll_link,left_foot,right_foot"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["unitree_g1", "--frames", "left_foot"],
            "--frames puts whole-body IK handles on frames: give --ik too, e.g. poekin view "
            "unitree_g1 --ik --frames left_foot,right_foot",
        ),
        (
            ["unitree_g1", "--ik", "--hold", "left_foot"],
            "--hold names some of the frames of --frames: give --frames too",
        ),
        (
            ["unitree_g1", "--ik", "--frames", G1_FRAMES, "--hold", "left_foot,right_fot"],
            "--hold 'right_fot' is not among --frames (a held frame needs a handle): did you mean "
            "'right_foot'? Valid names: 'left_elbow_roll_link', 'right_elbow_roll_link', "
            "'left_foot', 'right_foot'",
        ),
        (
            ["unitree_g1", "--ik", "--frames", "left_foot,left_foot"],
            "--frames names 'left_foot' twice: give each frame once",
        ),
        (
            ["unitree_g1", "--ik", "--frames", ","],
            "--frames names no frame: give names, e.g. --frames left_foot,right_foot",
        ),
        (
            ["unitree_g1", "--ik", "--frames", "left_fot,right_foot", "--hold", "right_foot"],
            "whole-body IK: no site or body named 'left_fot': did you mean 'left_foot'? Valid "
            "names: 'pelvis', ",
        ),
        (
            ["unitree_go2", "--ik", "--frame", "base"],
            "no IK mode for the end frame 'base': no hinge or slide joint moves 'base': nothing "
            "to solve",
        ),
    ],
    ids=[
        "frames-without-ik",
        "hold-without-frames",
        "hold-not-a-frame",
        "twice",
        "none",
        "unknown-frame",
        "ik-on-a-frame-it-refuses",
    ],
)
def test_whole_body_options_refused_in_one_line(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["view", "--no-browser", "--port", "0", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"poekin: error: {message}"), err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_view_with_whole_body_handles_says_so(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def interrupt(_: float) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("time.sleep", interrupt)
    argv = ["view", "unitree_g1", "--no-browser", "--port", "0", "--ik", "--frames", G1_FRAMES]
    assert main([*argv, "--hold", "left_foot, right_foot"]) == 130
    out, err = capsys.readouterr()
    assert out.startswith("poekin view: http://127.0.0.1:") and err == "poekin: interrupted\n"
    assert out.endswith(
        "(unitree_g1, whole-body IK: 4 handles, held: left_foot, right_foot); Ctrl-C to stop\n"
    )
