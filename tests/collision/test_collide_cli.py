"""``poekin collide``: the closest pairs, exit codes 0 / 1 / 2, --json, --deg, --top. The
figures printed are checked against Tree.distances, itself checked against MuJoCo
(test_query.py); the colliding configuration against mj_collision here."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest
from helpers import assert_one_error_line, load_quiet, run

FOLDED = ["0", "-90", "160", "0", "0", "0"]  # the elbow folded: the wrist in the upper arm


def test_collision_free_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(
        capsys, "collide", "universal_robots_ur5e", "--q", "0", "-1.57", "1.57", "0", "0", "0"
    )
    lines = out.splitlines()
    assert code == 0
    assert lines[0] == "universal_robots_ur5e: 21 pairs checked, collision-free"
    assert len(lines) == 2 + 5 and "COLLIDES" not in out
    distances = [float(line.split()[2]) for line in lines[2:]]
    assert distances == sorted(distances) and distances[0] > 0


def test_colliding_exits_1_and_marks_the_pairs(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(
        capsys, "collide", "universal_robots_ur5e", "--q", *FOLDED, "--deg", "--top", "3"
    )
    assert code == 1
    lines = out.splitlines()
    assert lines[0].endswith("5 colliding") and len(lines) == 2 + 3
    assert all(line.endswith("COLLIDES") for line in lines[2:])
    model = load_quiet("universal_robots_ur5e").model  # MuJoCo agrees that it collides
    data = mujoco.MjData(model)
    data.qpos[:] = np.radians([float(x) for x in FOLDED])
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    assert len({frozenset(map(int, c.geom)) for c in data.contact if c.dist < 0}) == 5


def test_json(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(
        capsys, "collide", "universal_robots_ur5e", "--q", *FOLDED, "--deg", "--json", "--top", "2"
    )
    doc = json.loads(out)
    assert code == 1
    assert doc["in_collision"] is True and doc["pairs_checked"] == 21
    assert doc["colliding_pairs"] == 5 and len(doc["closest"]) == 2
    first = doc["closest"][0]
    gap = np.linalg.norm(np.subtract(*first["points"][::-1]))
    assert abs(gap - abs(first["distance"])) < 1e-12 and first["colliding"] is True


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["universal_robots_ur5e", "--q", "0", "0"], "expected 6 qpos values"),
        (["universal_robots_ur5e"], "give the configuration with --q"),
        (["unitree_g1", "--q", "0"], "its collision geometry needs 32 mesh file(s)"),
        (["ur5e", "--q", "0"], "unknown robot 'ur5e'"),
    ],
)
def test_bad_input_exits_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    code, _, err = run(capsys, "collide", *argv)
    assert code == 2
    assert_one_error_line(err.replace("poekin: note: g1.xml", "poekin: note: "), message)


def test_top_must_be_positive(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        run(capsys, "collide", "universal_robots_ur5e", "--q", *FOLDED, "--top", "0")
    assert info.value.code == 2
    assert "--top: must be a whole number >= 1" in capsys.readouterr().err
