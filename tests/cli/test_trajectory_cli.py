"""``poekin plot-trajectory``: the figure written where asked, the line that says what it
shows, and the bad-input matrix (one error line, exit 2, nothing written)."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from helpers import assert_one_error_line, run
from trajectory_helpers import quintic

from poekin.io.trajectory import Trajectory


@pytest.fixture
def traj(tmp_path: pathlib.Path) -> pathlib.Path:
    t, q, qd, _ = quintic()
    return Trajectory(
        t,
        q,
        qd,
        robot="universal_robots_ur5e",
        vel_limits=np.full(6, 3.14),
        fraction=0.5,
        reason="singular: smallest singular value 2.1e-05",
    ).save(tmp_path / "traj.npz")


def test_writes_the_figure(
    traj: pathlib.Path, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "traj.svg"
    code, stdout, err = run(capsys, "plot-trajectory", str(traj), "--out", str(out))
    assert code == 0 and err == ""
    assert stdout == (
        f"plot written to {out}: 6 joints, 201 samples over 2 s; the path stopped at 50.0%: "
        "singular: smallest singular value 2.1e-05\n"
    )
    svg = out.read_text()
    assert svg.startswith("<?xml") and 'id="limit-band' in svg and 'id="stop' in svg
    # --force replaces it; --deg in degrees
    code, stdout, _ = run(capsys, "plot-trajectory", str(traj), "--out", str(out), "--force")
    assert code == 0
    png = tmp_path / "deg.png"
    assert run(capsys, "plot-trajectory", str(traj), "--deg", "--out", str(png))[0] == 0
    assert png.read_bytes().startswith(b"\x89PNG")


def test_a_trajectory_that_did_not_stop(
    tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    t, q, _, _ = quintic(11)
    np.savez(tmp_path / "mine.npz", t=t, q=q)
    out = tmp_path / "mine.png"
    code, stdout, _ = run(capsys, "plot-trajectory", str(tmp_path / "mine.npz"), "--out", str(out))
    assert code == 0 and stdout == f"plot written to {out}: 6 joints, 11 samples over 2 s\n"


def _write(tmp_path: pathlib.Path, case: str) -> pathlib.Path:
    t, q, _, _ = quintic(5)
    p = tmp_path / "in.npz"
    if case == "not npz":
        p.write_bytes(b"\x93NUMPY not an archive")
    elif case == "npy named npz":
        with p.open("wb") as f:
            np.save(f, q)
    elif case == "wrong contents":
        np.savez(p, T=np.zeros((5, 4, 4)))
    elif case == "lengths differ":
        np.savez(p, t=t, q=q[:3])
    elif case == "nan":
        np.savez(p, t=t, q=np.full_like(q, np.nan))
    elif case == "not increasing":
        np.savez(p, t=t[::-1], q=q)
    elif case == "zero limit":
        np.savez(p, t=t, q=q, vel_limits=np.zeros(6))
    return p


BAD = {
    "missing": "trajectory {p}: no such file",
    "not npz": "trajectory {p} is not a NumPy .npz archive; save a trajectory with Trajectory.save",
    "npy named npz": "trajectory {p} is not a NumPy .npz archive",
    "wrong contents": "trajectory {p} is not a trajectory: it has no t or q (it holds 'T')",
    "lengths differ": "trajectory {p}: q must be (K, n) = (5, n) joint values, one row per time",
    "nan": "trajectory {p}: q[0, 0] is nan; every value must be finite",
    "not increasing": "trajectory {p}: t must increase strictly, but t[1] = 1.5 s follows "
    "t[0] = 2 s",
    "zero limit": "trajectory {p}: vel_limits must be > 0 (inf: no limit), got 0 for joint 0",
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_one_line_and_exit_2(
    case: str, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    p = tmp_path / "missing.npz" if case == "missing" else _write(tmp_path, case)
    out = tmp_path / "fig.png"
    code, stdout, err = run(capsys, "plot-trajectory", str(p), "--out", str(out))
    assert code == 2 and stdout == ""
    assert_one_error_line(err, BAD[case].format(p=p))
    assert not out.exists()


def test_the_output_is_checked_before_the_file_is_read(
    traj: pathlib.Path, tmp_path: pathlib.Path, capsys: pytest.CaptureFixture[str]
) -> None:
    existing = tmp_path / "fig.png"
    existing.write_bytes(b"mine")
    code, _, err = run(
        capsys, "plot-trajectory", str(tmp_path / "nope.npz"), "--out", str(existing)
    )
    assert code == 2 and existing.read_bytes() == b"mine"
    assert_one_error_line(err, f"{existing} already exists; pass --force to replace it")
    code, _, err = run(capsys, "plot-trajectory", str(traj), "--out", str(tmp_path / "fig.xyz"))
    assert code == 2
    assert_one_error_line(err, "--out " + str(tmp_path / "fig.xyz") + ": its suffix '.xyz' names")
    code, _, err = run(
        capsys, "plot-trajectory", str(traj), "--out", str(tmp_path / "no" / "f.png")
    )
    assert code == 2
    assert_one_error_line(err, "does not exist; create it or choose another path")
    with pytest.raises(SystemExit) as info:  # argparse's own usage error
        run(capsys, "plot-trajectory", str(traj))
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "the following arguments are required: --out" in err and "Traceback" not in err
