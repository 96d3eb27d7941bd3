"""The examples run as documented, so they cannot rot (``examples/dask_scale.py`` runs as
docs/performance.md shows it, in tests/test_docs.py)."""

from __future__ import annotations

import csv
import os
import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[1]


def test_ur5e_lab_example(tmp_path: pathlib.Path) -> None:
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "examples" / "ur5e_lab.py"),
            "--out",
            str(tmp_path),
            "--samples",
            "200",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "passed: True" in proc.stdout
    assert len(list(tmp_path.glob("fk_errors_*.png"))) == 1
    with (tmp_path / "metrics.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert {r["method"] for r in rows} == {"space_poe", "body_poe"}
    assert all(float(r["value"]) < 1e-13 for r in rows)


def test_ur5e_lab_example_without_menagerie_is_one_line(tmp_path: pathlib.Path) -> None:
    env = {**os.environ, "MENAGERIE_ROOT": str(tmp_path)}  # a clone without the robot
    proc = subprocess.run(
        [sys.executable, str(REPO / "examples" / "ur5e_lab.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        check=False,
        env=env,
    )
    assert proc.returncode == 1
    assert proc.stderr.startswith("ur5e_lab: Menagerie robot 'universal_robots_ur5e'")
    assert "Traceback" not in proc.stderr


def test_whole_robot_example() -> None:
    proc = subprocess.run(
        [sys.executable, str(REPO / "examples" / "whole_robot.py"), "--samples", "100"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "unitree_go2: Tree('unitree_go2', 13 bodies, 13 joints, 1 sites, nq=19, nv=18)" in (
        proc.stdout
    )
    assert "aloha: " in proc.stdout and "passed: True" in proc.stdout


def test_teleop_step_example_follows_its_targets() -> None:
    proc = subprocess.run(
        [sys.executable, str(REPO / "examples" / "teleop_step.py"), "--seconds", "0.2"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert [line.split(":")[0] for line in lines] == ["universal_robots_ur5e", "aloha"]
    for line in lines:  # MuJoCo's frames trail their moving targets by under a micrometre
        assert float(line.split("within ")[1].split(" mm")[0]) < 1e-3, line
