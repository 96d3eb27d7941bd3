"""``poekin calibrate`` (issue #22, items 3-4): outputs, files, and one-line errors (exit 2,
nothing written) in the style of ``tests/cli/test_cli.py``'s ``BAD_INPUTS``."""

from __future__ import annotations

import functools
import json
import pathlib
import re
from typing import Any

import numpy as np
import pytest
from calibration_helpers import JSON_KEYS
from helpers import assert_one_error_line, load_quiet, mj_pose, run

import poekin
from poekin.calibration.files import read_measurements, write_measurements
from poekin.calibration.simulate import simulate_robot
from poekin.errors import InputError
from poekin.io.fileio import read_array
from poekin.verification.verify import pose_errors

ROBOT = "universal_robots_ur5e"


@functools.cache
def _data() -> tuple[poekin.Chain, np.ndarray, np.ndarray, np.ndarray]:
    """The UR5e, 30 configurations, their measured poses (0.1 mm, 0.1 mrad noise) and the true
    poses of a simulated robot (MuJoCo on a perturbed model)."""
    chain = poekin.load(ROBOT)
    sim = simulate_robot(ROBOT, seed=2)
    q = poekin.sample_joint_values(chain, 30, seed=3)
    return chain, q, sim.measure(q, seed=4), sim.poses(q)


def _tracker(folder: pathlib.Path, name: str = "tracker.csv", **edits: str) -> str:
    """The measurements as a CSV, with ``edits``: ``header`` replaces the first line, ``row``
    the second (the first pose), ``rows`` keeps only that many poses."""
    chain, q, measured, _ = _data()
    path = folder / name
    write_measurements(path, chain, q, measured, force=True)  # a test may write it again
    lines = path.read_text().splitlines()
    if "header" in edits:
        lines[0] = edits["header"]
    if "row" in edits:
        lines[1] = edits["row"]
    if "rows" in edits:
        lines = lines[: 1 + int(edits["rows"])]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_calibrate_writes_a_parameter_file_that_reads_back(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, plot = tmp_path / "my_robot.json", tmp_path / "calibration.png"
    code, text, err = run(
        capsys,
        "calibrate",
        ROBOT,
        "--measurements",
        _tracker(tmp_path),
        "--output",
        str(out),
        "--plot",
        str(plot),
    )
    assert code == 0, err
    assert "identifiable: 30 of 30 parameters" in text
    assert "joint 2 (shoulder_lift_joint): axis tilted by" in text
    assert f"calibrated parameters written to {out}" in text
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    chain = poekin.load_params(out)  # what --params reads: the robot in its base frame
    assert isinstance(chain, poekin.Chain)
    _, q, _, truth = _data()
    T_meas_base = poekin.load_registration(out).T_meas_base  # beside it: the tracker's view
    pos, ori = pose_errors(truth, T_meas_base @ chain.fk(q))  # the measured frame, measured
    assert np.sqrt(np.mean(pos**2)) < 0.1e-3 and np.sqrt(np.mean(ori**2)) < 0.1e-3
    doc = json.loads(out.read_text())
    assert doc["calibration"]["identifiable"] == 30
    # nothing the user owns is replaced without --force
    before = out.read_bytes()
    code, _, err = run(
        capsys, "calibrate", ROBOT, "--measurements", _tracker(tmp_path), "--output", str(out)
    )
    assert code == 2 and "already exists" in err and out.read_bytes() == before
    code, _, _ = run(
        capsys,
        "calibrate",
        ROBOT,
        "--measurements",
        _tracker(tmp_path),
        "--output",
        str(out),
        "--force",
    )
    assert code == 0


def test_calibrate_json(tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, text, _ = run(capsys, "calibrate", ROBOT, "--measurements", _tracker(tmp_path), "--json")
    assert code == 0
    result = json.loads(text)
    for key in JSON_KEYS:
        assert key in result, key
    assert result["identifiable"] == result["expected_identifiable"] == 30
    assert result["heldout_rms_m"] > result["residual_rms_m"] > 0
    assert {c["part"] for c in result["changes"]} >= {"joint 1 (shoulder_pan_joint)", "tool"}
    assert all(
        set(c) >= {"tilt_mrad", "offset_mm", "encoder", "message"} for c in result["changes"]
    )
    for unit in ("m", "rad"):  # the error predicted from the standard errors, below the noise
        predicted, residual = result[f"predicted_rms_{unit}"], result[f"residual_rms_{unit}"]
        assert 0 < predicted["measured"] < residual and 0 < predicted["workspace"] < residual


def test_calibrate_reads_degrees_and_npz(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chain, q, measured, _ = _data()
    write_measurements(tmp_path / "deg.csv", chain, np.degrees(q), measured)
    q_deg, T_deg = read_measurements(tmp_path / "deg.csv", chain, deg=True)
    assert np.allclose(q_deg, q, atol=1e-14) and np.allclose(T_deg, measured, atol=1e-15)
    np.savez(tmp_path / "m.npz", q=q, p=measured[:, :3, 3])
    q_npz, p_npz = read_measurements(tmp_path / "m.npz", chain)
    assert np.array_equal(q_npz, q) and np.array_equal(p_npz, measured[:, :3, 3])
    code, text, err = run(
        capsys, "calibrate", ROBOT, "--measurements", str(tmp_path / "deg.csv"), "--deg"
    )
    assert code == 0 and "identifiable: 30 of 30" in text, err
    code, text, err = run(
        capsys, "calibrate", ROBOT, "--measurements", str(tmp_path / "deg.csv"), "--folds", "0"
    )
    assert code == 0 and "pass --deg" in err  # degrees read as radians get a note
    code, text, _ = run(capsys, "calibrate", ROBOT, "--measurements", str(tmp_path / "m.npz"))
    assert code == 0 and "30 positions; identifiable" in text


def test_plan(tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, text, _ = run(capsys, "calibrate", ROBOT, "--plan", "12", "--candidates", "400")
    assert code == 0
    lines = text.splitlines()
    assert lines[0].startswith("# 12 poses (position and orientation) for universal_robots_ur5e")
    assert lines[1] == ",".join(poekin.load(ROBOT).joint_names)
    (tmp_path / "plan.csv").write_text(text)
    q = read_array(tmp_path / "plan.csv")  # a comment, a header, 12 rows
    assert q.shape == (12, 6)
    code, text, _ = run(capsys, "calibrate", ROBOT, "--plan", "12", "--candidates", "400", "--json")
    assert np.allclose(json.loads(text)["q"], q, atol=1e-6)
    out = tmp_path / "poses.npy"
    code, text, _ = run(
        capsys, "calibrate", ROBOT, "--plan", "12", "--positions", "--output", str(out)
    )
    assert code == 0 and f"planned poses written to {out}" in text and "12 positions" in text
    assert np.load(out).shape == (12, 6)


def _mj_z(q: np.ndarray) -> np.ndarray:
    """The UR5e's end frame heights from MuJoCo's mj_forward (its qpos is the chain's q)."""
    loaded = load_quiet(ROBOT)
    return mj_pose(loaded.model, np.asarray(q), "attachment_site")[:, 2, 3]


def test_plan_with_constraints(tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 26: --above-z, --box and --range (degrees with --deg) constrain the plan as
    plan_poses' above_z, box and ranges do, and the summary says how."""
    from poekin.calibration import plan_poses

    args = ["calibrate", ROBOT, "--plan", "12", "--candidates", "400", "--above-z", "0.05"]
    args += ["--range", "shoulder_lift_joint", "-180", "0", "--deg"]
    code, text, err = run(capsys, *args)
    assert code == 0, err
    lines = text.splitlines()
    assert "(random poses meeting the constraints: condition number" in lines[0]
    counted = re.fullmatch(
        r"# constrained: shoulder_lift_joint in \[-180, 0\] deg; end frame z >= 0.05 m "
        r"\(([\d,]+) of ([\d,]+) candidates kept\)",
        lines[1],
    )
    assert counted, lines[1]
    kept, drawn = (int(g.replace(",", "")) for g in counted.groups())
    assert 400 <= kept < drawn and drawn % 400 == 0  # more were drawn: 400 were not enough
    (tmp_path / "plan.csv").write_text(text)
    q = read_array(tmp_path / "plan.csv")  # two comments, a header, 12 rows
    expected = plan_poses(
        ROBOT, 12, candidates=400, above_z=0.05, ranges={"shoulder_lift_joint": (-np.pi, 0)}
    )
    assert np.allclose(q, expected, atol=1e-6, rtol=0)
    code, text, _ = run(capsys, *args, "--json")
    doc = json.loads(text)
    assert np.array_equal(doc["q"], expected)
    assert np.all(_mj_z(doc["q"]) >= 0.05 - 1e-12)
    assert (doc["candidates_kept"], doc["candidates_drawn"], doc["above_z"]) == (kept, drawn, 0.05)
    assert doc["ranges"] == {"shoulder_lift_joint": [-np.pi, 0.0]} and doc["box"] is None
    out = tmp_path / "box.npy"
    box = ["-0.6", "-0.7", "0.1", "0.2", "0.7", "0.8"]
    code, text, err = run(
        capsys, "calibrate", ROBOT, "--plan", "12", "--box", *box, "--output", str(out)
    )
    assert code == 0, err
    assert text.splitlines()[1].startswith(
        "constrained: end frame x in [-0.6, 0.2], y in [-0.7, 0.7], z in [0.1, 0.8] m ("
    )
    loaded = load_quiet(ROBOT)
    p = mj_pose(loaded.model, np.load(out), "attachment_site")[:, :3, 3]
    assert np.all((p >= [-0.6, -0.7, 0.1]) & (p <= [0.2, 0.7, 0.8]))
    # a range alone narrows the draw and drops nothing
    code, text, _ = run(
        capsys, "calibrate", ROBOT, "--plan", "12", "--range", "elbow_joint", "0", "2.5"
    )
    assert text.splitlines()[1] == (
        "# constrained: elbow_joint in [0, 2.5] rad (2,000 candidates drawn within it)"
    )
    # without constraints: no such line, and the plan of before
    code, text, _ = run(capsys, "calibrate", ROBOT, "--plan", "12", "--candidates", "400")
    assert text.splitlines()[1] == ",".join(poekin.load(ROBOT).joint_names)
    assert "random poses within the limits" in text


def test_plan_for_a_parameter_set(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue 26: --plan with --params plans for that chain (a named set, a DH table, a PoE file)
    instead of a model's; before, calibrate took no --params at all."""
    from poekin.calibration import plan_poses

    code, text, err = run(
        capsys, "calibrate", "--params", "ur5e-dh", "--plan", "12", "--candidates", "400", "--json"
    )
    assert code == 0, err
    doc = json.loads(text)
    table = poekin.load_params("ur5e-dh")
    assert isinstance(table, poekin.DHTable)
    assert doc["frame"] == "flange" and doc["robot"] == "ur5e-dh"
    assert np.array_equal(doc["q"], plan_poses(table.to_chain(), 12, candidates=400))
    # a robot on a 0.5 m pedestal, as a PoE file: --above-z is in its own base frame
    lifted = poekin.load(ROBOT).with_base(
        np.array([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]])
    )
    path = tmp_path / "on_a_pedestal.json"
    path.write_text(json.dumps(lifted.describe()))
    args = ["calibrate", "--params", str(path), "--plan", "12", "--above-z", "0.55"]
    code, text, err = run(capsys, *args, "--output", str(tmp_path / "q.csv"))
    assert code == 0, err
    assert text.startswith(
        f"12 poses (position and orientation) for {path} (universal_robots_ur5e)"
    )
    q = read_array(tmp_path / "q.csv")
    assert np.allclose(q, plan_poses(lifted, 12, above_z=0.55), atol=1e-12)
    assert np.all(_mj_z(q) + 0.5 >= 0.55 - 1e-12)  # MuJoCo's robot stands at 0
    assert not np.all(_mj_z(plan_poses(ROBOT, 12)) >= 0.05)


HEADER_LINE = (
    "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint,"
    "x,y,z,qw,qx,qy,qz"
)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("dup.csv", HEADER_LINE.replace(",x,", ",x,x,") + "\n", "column 'x' appears twice"),
        ("short.csv", HEADER_LINE + "\n1,2,3\n", "line 2 has 3 values, the header 13"),
        # issue 26: the file's own line, comments and blank lines counted
        ("note.csv", HEADER_LINE + "\n# pose 1\n\n1,2,3\n", "line 4 has 3 values, the header 13"),
        ("empty.csv", "# nothing\n", "is empty"),
        ("header.csv", HEADER_LINE + "\n", "has a header but no rows"),
        ("latin.csv", b"\xff\xfe\x00", "not a text file"),
        ("text.npz", "not an archive", "not a readable .npz"),
        ("strings.npz", {"q": np.array([["a"] * 6] * 8), "p": np.zeros((8, 3))}, "not real"),
        ("shape.npz", {"q": np.zeros((8, 5)), "p": np.zeros((8, 3))}, "'q' must be (N, 6)"),
        (
            "nan.npz",
            {"q": np.zeros((8, 6)), "T": np.full((8, 4, 4), np.nan)},
            "'T' of row 0 (from 0)",
        ),
        (
            "both.npz",
            {"q": np.zeros((8, 6)), "T": np.zeros((8, 4, 4)), "p": np.zeros((8, 3))},
            "either",
        ),
    ],
)
def test_bad_measurement_files(
    name: str, content: object, message: str, tmp_path: pathlib.Path
) -> None:
    path = tmp_path / name
    if isinstance(content, dict):
        np.savez(path, **content)
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(str(content))
    with pytest.raises(poekin.InputError, match=re.escape(message)):
        read_measurements(path, poekin.load(ROBOT))


def test_bad_measured_arrays() -> None:
    from poekin.calibration import check_measurements

    with pytest.raises(poekin.InputError, match="must be numbers"):
        check_measurements([["a", "b", "c"]], 1)
    T = np.tile(np.eye(4), (3, 1, 1))
    T[1, 3, 0] = 1.0
    with pytest.raises(poekin.InputError, match="measured pose 1: the last row"):
        check_measurements(T, 3)


def _npz_without_poses(folder: pathlib.Path) -> str:
    np.savez(folder / "bad.npz", q=np.zeros((10, 6)))
    return str(folder / "bad.npz")


HEADER = (
    "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint"
)

# what a bad data file must not leave behind
WRITES = ["--output", "{tmp}/calibrated.json", "--plot", "{tmp}/calibration.png"]

# the upper arm level or lower: the flange reaches no higher than about 0.7 m
SHOULDER_DOWN = ["--range", "shoulder_lift_joint", "0", "0.1"]

# (argv, message); {tracker} is a good measurement file, {bad:...} one with an edit
BAD_INPUTS_CALIBRATE = [
    (["calibrate", ROBOT], "give --measurements FILE"),
    (["calibrate", "universal_robots_ur5", "--plan", "10"], "did you mean 'universal_robots_ur5e'"),
    (["calibrate", ROBOT, "--measurements", "{nan}", *WRITES], "is NaN or inf"),
    (["calibrate", ROBOT, "--measurements", "{typo}"], "did you mean 'wrist_3_joint'"),
    (
        ["calibrate", ROBOT, "--measurements", "{missing_joint}", *WRITES],
        "no column 'wrist_3_joint'",
    ),
    (["calibrate", ROBOT, "--measurements", "{few}", *WRITES], "measure at least 6"),
    (
        ["calibrate", ROBOT, "--measurements", "{not_unit}", *WRITES],
        "not 1; give a unit quaternion",
    ),
    (["calibrate", ROBOT, "--measurements", "{text}"], "'abc' is not a number"),
    (["calibrate", ROBOT, "--measurements", "{half_quaternion}"], "missing qy, qz"),
    (["calibrate", ROBOT, "--measurements", "{no_header}"], "must be a header"),
    (["calibrate", ROBOT, "--measurements", "{tmp}/none.csv"], "no such file"),
    (["calibrate", ROBOT, "--measurements", "{tmp}/m.txt"], "a .csv or .npz file"),
    (["calibrate", ROBOT, "--measurements", "{npz}"], "it needs 'q'"),
    (["calibrate", ROBOT, "--measurements", "{tracker}", "--output", "{tmp}/p.yaml"], ".json"),
    (
        ["calibrate", ROBOT, "--measurements", "{tracker}", "--output", "{existing}"],
        "already exists",
    ),
    (["calibrate", ROBOT, "--measurements", "{tracker}", "--plot", "{tmp}/c.xyz"], "'.xyz'"),
    (
        ["calibrate", ROBOT, "--measurements", "{tracker}", "--output", "{tmp}/no/p.json"],
        "does not",
    ),
    (["calibrate", ROBOT, "--measurements", "{tracker}", "--sigma-pos", "-1"], "--sigma-pos must"),
    (["calibrate", ROBOT, "--measurements", "{tracker}", "--prior-rad", "0"], "--prior-rad must"),
    (["calibrate", ROBOT, "--measurements", "{tracker}", "--folds", "1"], "--folds must be"),
    (["calibrate", ROBOT, "--plan", "3"], "plan at least 6"),
    (["calibrate", ROBOT, "--plan", "0"], "--plan must be a whole number"),
    (["calibrate", ROBOT, "--plan", "10", "--measurements", "{tracker}"], "drop --measurements"),
    (["calibrate", ROBOT, "--plan", "10", "--candidates", "5"], "--candidates must be at least"),
    (  # issue 26: a million candidates took 10 GB and minutes, silently
        ["calibrate", ROBOT, "--plan", "10", "--candidates", "1000000"],
        "1,000,000 candidates: plan from at most 50,000",
    ),
    (["calibrate", ROBOT, "--plan", "10", "--output", "{tmp}/p.xyz"], "'.xyz'"),
    # issue 26: the constraints (and the parameter set) of a plan
    (
        ["calibrate", ROBOT, "--plan", "10", "--range", "elbo_joint", "0", "1"],
        "--range elbo_joint 0 1: universal_robots_ur5e has no joint 'elbo_joint'; did you mean "
        "'elbow_joint'?",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--range", "elbow_joint", "1", "-1"],
        "--range elbow_joint 1 -1: LO must be below HI",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--range", "elbow_joint", "0", "4"],
        "elbow_joint's limits are [-3.1415, 3.1415] rad; give LO and HI within them (radians; "
        "degrees with --deg)",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--range", "elbow_joint", "0", "180", "--deg"],
        "--range elbow_joint 0 180: elbow_joint's limits are [-179.9946, 179.9946] deg;",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--range", "elbow_joint", "0", "pi"],
        "--range elbow_joint 0 pi: LO and HI must be finite numbers",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", *["--range", "elbow_joint", "0", "1"] * 2],
        "--range elbow_joint is given twice",
    ),
    (["calibrate", ROBOT, "--plan", "10", "--above-z", "nan"], "--above-z must be a finite"),
    (
        ["calibrate", ROBOT, "--plan", "10", "--box", "-1", "-1", "1", "1", "1", "0"],
        "--box: ZMIN 1 is not below ZMAX 0; give the lower corner, then the upper",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--box", "-1", "-1", "0", "1", "1", "inf"],
        "--box takes six finite numbers",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--above-z", "1.2", "--output", "{tmp}/p.csv"],
        "only 0 of 200,000 random configurations within the joint limits put the end frame at "
        "z >= 1.2 m, too few for 10 poses: ask for a lower height",
    ),
    (
        ["calibrate", ROBOT, "--plan", "10", "--above-z", "0.8", *SHOULDER_DOWN],
        "within the joint limits and ranges put the end frame at z >= 0.8 m",
    ),
    (["calibrate", ROBOT, "--range", "elbow_joint", "0", "1"], "--range goes with --plan N"),
    (
        ["calibrate", ROBOT, "--measurements", "{tracker}", "--above-z", "0.05", *WRITES],
        "--above-z goes with --plan N",
    ),
    (
        ["calibrate", "--params", "ur5e-dh", "--measurements", "{tracker}", *WRITES],
        "--params goes with --plan N",
    ),
    (["calibrate", ROBOT, "--params", "ur5e-dh", "--plan", "10"], "not both"),
    (
        ["calibrate", "--params", "ur5e-dh", "--frame", "tool0", "--plan", "10"],
        "a parameter set has its own end frame",
    ),
    (["calibrate", "--params", "ur5e_dh", "--plan", "10"], "did you mean 'ur5e-dh'?"),
]


@pytest.mark.parametrize(("argv", "message"), BAD_INPUTS_CALIBRATE)
def test_bad_input_gives_one_line_and_exit_2(
    argv: list[str], message: str, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "m.txt").write_text("1 2 3\n")
    existing = tmp_path / "existing.json"
    existing.write_text("{}")
    fills = {
        "tmp": str(tmp_path),
        "tracker": _tracker(tmp_path),
        "existing": str(existing),
        "nan": _tracker(tmp_path, "nan.csv", row="0,0,0,0,0,nan,1,2,3,1,0,0,0"),
        "typo": _tracker(
            tmp_path,
            "typo.csv",
            header=HEADER.replace("wrist_3_joint", "wrist3_joint") + ",x,y,z,qw,qx,qy,qz",
        ),
        "missing_joint": _tracker(
            tmp_path,
            "missing.csv",
            header=HEADER.replace(",wrist_3_joint", "") + ",x,y,z,qw,qx,qy,qz",
        ),
        "few": _tracker(tmp_path, "few.csv", rows="4"),
        "not_unit": _tracker(tmp_path, "unit.csv", row="0,0,0,0,0,0,1,2,3,0.9,0,0,0"),
        "text": _tracker(tmp_path, "text.csv", row="0,0,abc,0,0,0,1,2,3,1,0,0,0"),
        "half_quaternion": _tracker(tmp_path, "half.csv", header=HEADER + ",x,y,z,qw,qx"),
        "no_header": _tracker(tmp_path, "noheader.csv", header="0,0,0,0,0,0,1,2,3,1,0,0,0"),
        "npz": _npz_without_poses(tmp_path),
    }
    files = {p: p.read_bytes() for p in tmp_path.iterdir()}
    code, _, err = run(capsys, *[a.format(**fills) for a in argv])
    assert code == 2
    assert_one_error_line(err, message)
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == files  # nothing written


def test_every_loss_is_a_choice() -> None:
    """--loss offers what poekin.calibrate takes (the parser does not import the fit)."""
    from poekin.calibration import LOSSES
    from poekin.cli import _build_parser

    parser = _build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    calibrate = sub.choices["calibrate"]  # type: ignore[index]
    (loss,) = [a for a in calibrate._actions if a.dest == "loss"]
    assert tuple(loss.choices) == LOSSES


@pytest.mark.parametrize(
    ("edit", "cause"),
    [
        ("degrees", r"the joint readings \(up to 3\d\d\.?\d*\) look like degrees: pass --deg"),
        ("millimetres", r"the measured positions spread \S+ times as far as the model's: are they"),
        ("swapped", r"check that the joint columns hold the joints their header names"),
        ("sigma", r"\S+ times the --sigma-pos given \(1e-07 m\): that is below the measurements'"),
        ("sigma-ori", r"\S+ times the --sigma-ori given \(1e-07 rad\): that is below the"),
        ("quaternion", r"check that the quaternion columns are qw,qx,qy,qz \(w first; x,y,z,w"),
    ],
)
def test_a_fit_no_robot_explains_is_not_written(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str], edit: str, cause: str
) -> None:
    """Degrees read as radians, positions in millimetres, two joint columns swapped,
    quaternions written x,y,z,w under a qw,qx,qy,qz header, or a residual 100 times the noise
    the user gave (of positions or orientations): one error line naming the likely cause and
    nothing else, exit 2, and no parameter file (issue 26; each ran with exit 0 and wrote
    one)."""
    chain, q, measured, _ = _data()
    measured = measured.copy()
    sigma: list[str] = []
    if edit == "degrees":
        q = np.degrees(q)
    elif edit == "millimetres":
        measured[:, :3, 3] *= 1000.0
    elif edit == "swapped":
        q = q[:, [0, 2, 1, 3, 4, 5]]
    elif edit == "sigma":
        sigma = ["--sigma-pos", "1e-7"]  # 0.1 um, where the data carry 0.1 mm
    elif edit == "sigma-ori":
        sigma = ["--sigma-ori", "1e-7"]  # where the data carry 0.1 mrad
    path = tmp_path / "data.csv"
    write_measurements(path, chain, q, measured)
    if edit == "quaternion":  # each row's qw,qx,qy,qz as qx,qy,qz,qw
        head, *rows = path.read_text().splitlines()
        rows = [",".join([*r.split(",")[:-4], *r.split(",")[-3:], r.split(",")[-4]]) for r in rows]
        path.write_text("\n".join([head, *rows]) + "\n")
    out = tmp_path / "my_robot.json"
    args = ["calibrate", ROBOT, "--measurements", str(path), "--output", str(out), *sigma]
    code, _, err = run(capsys, *args)
    # no note before it (the error names the cause) but the model's own, where it has no meshes
    line = [x for x in err.splitlines() if "loaded for kinematics only" not in x]
    assert code == 2 and len(line) == 1 and line[0].startswith("poekin: error: "), err
    assert re.search(cause, line[0]) and line[0].endswith(f"{out} not written"), line[0]
    assert not out.exists()


def test_folds_beyond_the_poses_are_refused(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(
        capsys, "calibrate", ROBOT, "--measurements", _tracker(tmp_path), "--folds", "100"
    )
    assert code == 2
    assert_one_error_line(
        err,
        "folds=100 with 30 poses: each fold holds out at least one pose, so folds is at most 30 "
        "(5 is usual; 0 for none)",
    )


def test_write_measurements_refuses_what_it_cannot_write_right(tmp_path: pathlib.Path) -> None:
    """Issue 26: a 5-column q for a 6-joint chain wrote a 13-column header over 12-value rows,
    NaN was written, q and T of different lengths were a traceback, and a file was replaced
    without a word. Each is one InputError now, and nothing is written."""
    chain, q, measured, _ = _data()
    path = tmp_path / "m.csv"
    nan = q.copy()
    nan[3, 1] = np.nan
    cases = [
        ((q[:, :5], measured), r"expected 6 joint readings \(shape \(\.\.\., 6\)\)"),
        ((nan, measured), "NaN or inf"),
        ((q[:5], measured), "expected 5 measured poses"),
        ((q, measured[:, :2, :2]), "expected 30 measured poses"),
    ]
    for (qq, mm), message in cases:
        with pytest.raises(InputError, match=message):
            write_measurements(path, chain, qq, mm)
        assert not path.exists()
    write_measurements(path, chain, q, measured)
    before = path.read_text()
    with pytest.raises(InputError, match="already exists; pass force=True to replace it"):
        write_measurements(path, chain, q[:10], measured[:10])
    assert path.read_text() == before
    write_measurements(path, chain, q[:10], measured[:10], force=True)
    assert np.array_equal(read_measurements(path, chain)[0], q[:10])


@pytest.mark.parametrize("noise", [-1.0, float("nan"), "0.1", True])
def test_simulated_noise_must_be_a_standard_deviation(noise: Any) -> None:
    sim = simulate_robot(ROBOT, seed=2)
    for name in ("noise_m", "noise_rad"):
        with pytest.raises(InputError, match=f"{name} must be a number >= 0"):
            sim.measure(np.zeros((3, 6)), **{name: noise})
