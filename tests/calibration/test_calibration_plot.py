"""The calibration figure (issue #22, item 4): residuals per pose before and after, and each
joint's change; every text apart from every other, the values it must show on it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from helpers import assert_labels_apart, drawn_text_boxes

import poekin
from poekin.calibration import calibrate
from poekin.calibration.plot import calibration_figure
from poekin.calibration.simulate import simulate_robot

pytestmark = pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")

OFF_FLANGE = np.eye(4)
OFF_FLANGE[:3, 3] = [0.03, 0.05, 0.04]  # a target 7 cm off the flange: its tool bar is cut


def _result(robot: str, case: str) -> poekin.calibration.Calibration:
    chain = poekin.load(robot)
    sim = simulate_robot(robot, seed=4, target=OFF_FLANGE if case == "positions" else None)
    q = poekin.sample_joint_values(chain, 40, seed=5)
    if case == "still":
        q[:, 3] = 0.4
    measured = sim.measure(q, seed=6, positions=case == "positions")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.errors.CalibrationWarning)
        return calibrate(chain, q, measured)


@pytest.mark.parametrize(
    ("robot", "case"),
    [
        ("universal_robots_ur5e", "poses"),
        ("universal_robots_ur5e", "still"),
        ("universal_robots_ur5e", "positions"),
        ("franka_fr3", "poses"),
    ],
)
def test_no_text_overlaps_another(robot: str, case: str) -> None:
    result = _result(robot, case)
    fig = calibration_figure(result, title=f"{robot}: {case}")
    assert_labels_apart(fig)
    boxes = drawn_text_boxes(fig)
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1 :]:
            assert not box_a.overlaps(box_b), f"{a.get_text()!r} overlaps {b.get_text()!r}"
    axes = fig.axes
    assert len(axes) == (2 if case == "positions" else 3)
    bars = axes[-1]
    names = [t.get_text() for t in bars.get_xticklabels()]
    assert names[-1] == "tool" and names[1] == f"J2\n{result.nominal.joint_names[1]}"
    hatched = {round(p.get_x() + p.get_width() / 2) for p in bars.patches if p.get_hatch()}
    partial = {result.model.params[k].joint for k in result.undetermined}
    joints = {len(names) - 1 if j is None else j for j in partial}
    assert hatched == joints  # the joints not all identified, and only they, are hatched
    if case == "still":
        assert 3 in joints
    if case == "positions":  # the target's 7 cm offset is cut, and written on its bar
        (cut,) = [t.get_text() for t in bars.texts]
        assert cut.endswith(" mm") and 65 < float(cut.split()[0]) < 75
    else:
        assert len(bars.texts) == 0
