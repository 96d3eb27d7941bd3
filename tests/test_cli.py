"""The poekin command line: outputs, exit codes, and one-line errors without tracebacks."""

from __future__ import annotations

import csv
import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from helpers import MJ_TOL, SUMMARY_KEYS, assert_close, load_quiet

import poekin
from poekin import load
from poekin.cli import main
from poekin.metrics import METRICS_HEADER

UR5E_XML = pathlib.Path(os.environ["MENAGERIE_ROOT"]) / "universal_robots_ur5e" / "ur5e.xml"


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


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
    assert code == 0 and "body B_i" in out and "wrist_3_joint" in out


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


BAD_INPUTS = [
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
        "not a .npy",
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
    (["diagnose", "--params", "ur5e-dh", "--plot", "{other_csv}"], "already exists"),
    (["fk", "unitree_go2", "--all-frames", "--q", "0", "1"], "expected 19 qpos values"),
    (["fk", "unitree_go2", "--frame", "FL_calf", "--q", "0"], "--all-frames"),
    (["fk", "aloha", "--all-frames", "--frame", "left/gripper", "--q", "0"], "not --frame"),
    (["verify", "aloha", "--all-frames", "--frame", "left/gripper"], "give no frame"),
    (["screws", "unitree_go2", "--frame", "imu"], "'joint0' on the path to 'imu' is a free"),
    (["verify", "{mj_rejects}"], "MuJoCo rejected"),
    (["fk", "--params", "{zero_axis}", "--q", *"000000"], "needs a unit axis w, got |w| = 0;"),
    (["fk", "--params", "{half_axis}", "--q", *"000000"], "needs a unit axis w, got |w| = 0.5"),
    (["verify", "--params", "{skewed_home}", "--against", "universal_robots_ur5e"], "orthonormal"),
    (["jacobian", "universal_robots_ur5e", "--q", "1", "2"], "expected 6 joint values"),
    (["jacobian", "universal_robots_ur5e"], "give joint values with --q"),
    (["jacobian", "unitree_go2", "--frame", "FL_calf", "--q", "0"], "is a free joint"),
    (["jacobian", "unitree_go2", "--tree", "--frame", "FL_clf", "--q", "0"], "'FL_calf'"),
    (["jacobian", "aloha", "--tree", "--q", "0"], "name the frame with --frame"),
    (["jacobian", "--tree", "--params", "ur5e-dh", "--q", "0"], "not --params"),
    (["jacobian", "universal_robots_ur5e", "--output", "{tmp}/J.npy", "--q", "0"], "goes with"),
    (
        ["draw", "universal_robots_ur5", "--out", "{tmp}/a.png"],
        "did you mean 'universal_robots_ur5e'",
    ),
    (["draw", "--q", "1", "2", "--out", "{tmp}/a.png"], "expected 6 qpos values"),
    (["draw", "--out", "{tmp}/a.gif"], "the suffix decides the format"),
    (["draw", "--out", "{tmp}/missing/a.png"], "does not exist"),
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
    pytest.param(
        ["verify", "--metrics", "/dev/full"],
        "No space left on device",
        marks=pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full"),
    ),
]


def _param_file(tmp_path: pathlib.Path, name: str, joint: int, screw: list[float]) -> str:
    """The UR5e's screws as ``poekin screws --json`` writes them, one joint's screw replaced
    (an empty ``screw`` instead skews the home pose M)."""
    described = load("universal_robots_ur5e").describe()
    if screw:
        described["joints"][joint]["screw"] = screw
    else:
        described["home"][0][0] = 2.0
    return _write(tmp_path, name, json.dumps(described))


def assert_one_error_line(err: str, message: str) -> None:
    """stderr holds exactly one error line (plus, at most, notes) and no traceback."""
    lines = err.splitlines()
    errors = [ln for ln in lines if ln.startswith("poekin: error: ")]
    assert len(errors) == 1 and message in errors[0], err
    assert all(ln.startswith("poekin: note: ") for ln in lines if ln not in errors), err
    assert "Traceback" not in err


@pytest.mark.parametrize(("argv", "message"), BAD_INPUTS)
def test_bad_input_gives_one_line_and_exit_2(
    argv: list[str], message: str, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = _write(tmp_path, "other.csv", "a,b,c\n1,2,3\n")
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
        "other_csv": other,
    }
    before = pathlib.Path(other).read_bytes()
    code, _, err = run(capsys, *[a.format(**fills) for a in argv])
    assert code == 2
    assert_one_error_line(err, message)
    assert pathlib.Path(other).read_bytes() == before


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


def test_no_network_menagerie(
    capsys: pytest.CaptureFixture[str], tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("MENAGERIE_ROOT")
    monkeypatch.setenv("MENAGERIE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("MENAGERIE_BASE_URL", (tmp_path / "offline").as_uri())
    code, _, err = run(capsys, "verify")
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


def test_console_script_runs_without_traceback() -> None:
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
    "poekin.metrics",
    "poekin.plotting",
]


def test_verify_imports_only_what_it_needs() -> None:
    """``import poekin`` imports no MuJoCo, and ``poekin verify`` none of the modules it does not
    use; MUJOCO_GL is left as the user had it."""
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
