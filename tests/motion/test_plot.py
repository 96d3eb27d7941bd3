"""The trajectory figure (poekin.motion.plot): three stacked axes of q, qd and qdd, a line per
joint with the joint names in the legend, the limits as bands, the stop marked and labelled.
Finite differences are checked against the quintic's exact derivatives, never against the
module's own."""

from __future__ import annotations

import dataclasses
import math
import pathlib
import subprocess
import sys

import numpy as np
from helpers import assert_labels_apart
from trajectory_helpers import quintic

from poekin.io.fileio import save_figure
from poekin.io.trajectory import Trajectory
from poekin.motion.plot import BAND_GID, STOP_GID, derivatives, trajectory_figure

NAMES = ("pan", "lift", "elbow", "wrist 1", "wrist 2", "wrist 3")
VEL = np.array([3.14, 3.14, 3.14, 6.28, 6.28, np.inf])  # two values shared, one joint unlimited
ACC = np.full(6, 8.0)
POS = np.array([[-2 * math.pi, 2 * math.pi]] * 5 + [[-1.0, 0.6]])  # wrist 3 reaches 0.5


def _trajectory(**changes: object) -> Trajectory:
    t, q, qd, qdd = quintic()
    full = Trajectory(
        t,
        q,
        qd,
        qdd,
        robot="universal_robots_ur5e",
        joint_names=NAMES,
        vel_limits=VEL,
        acc_limits=ACC,
        pos_limits=POS,
        fraction=0.625,
        reason="joint limit: elbow",
        stop_index=125,
    )
    return dataclasses.replace(full, **changes)  # type: ignore[arg-type]


def _joint_lines(ax: object) -> list[object]:
    return [ln for ln in ax.lines if ln.get_gid() != STOP_GID]  # type: ignore[attr-defined]


def _bands(ax: object) -> list[object]:
    return [c for c in ax.collections if c.get_gid() == BAND_GID]  # type: ignore[attr-defined]


def test_three_axes_a_line_per_joint_and_the_names() -> None:
    fig = trajectory_figure(_trajectory())
    assert len(fig.axes) == 3
    q_ax, _, qdd_ax = fig.axes
    assert [ax.get_ylabel() for ax in fig.axes] == ["q [rad]", "qd [rad/s]", "qdd [rad/s²]"]
    assert qdd_ax.get_xlabel() == "t [s]"
    t, q, qd, qdd = quintic()
    for ax, values in zip(fig.axes, (q, qd, qdd), strict=True):
        lines = _joint_lines(ax)
        assert [ln.get_label() for ln in lines] == list(NAMES)
        for j, ln in enumerate(lines):
            assert np.array_equal(ln.get_xdata(), t) and np.array_equal(
                ln.get_ydata(), values[:, j]
            )
    legend = q_ax.get_legend()
    assert [x.get_text() for x in legend.get_texts()] == list(NAMES)
    assert "universal_robots_ur5e: 201 samples over 2 s" in fig.get_suptitle()
    assert_labels_apart(fig)


def test_the_limits_are_bands_beyond_them() -> None:
    """One band per distinct finite limit and side: q 2 + 2 (wrist 3's own), qd 2 + 2 (3.14 and
    6.28; wrist 3 unlimited), qdd 1 + 1; each from its limit outwards."""
    fig = trajectory_figure(_trajectory())
    counts = [len(_bands(ax)) for ax in fig.axes]
    assert counts == [4, 4, 2]
    for ax, lower, upper in (
        (fig.axes[0], POS[:, 0], POS[:, 1]),
        (fig.axes[1], -VEL, VEL),
        (fig.axes[2], -ACC, ACC),
    ):
        edges = set()
        bottom, top = ax.get_ylim()
        for band in _bands(ax):
            y = band.get_paths()[0].vertices[:, 1]
            inner = y[np.argmin(np.abs(y))]  # the limit (the other edge is beyond the view)
            edges.add(round(float(inner), 9))
            assert y.min() <= bottom or y.max() >= top  # reaches the edge of the view
        want = {round(float(v), 9) for v in (*lower, *upper) if math.isfinite(v)}
        assert edges == want
    # wrist 3's upper position limit (0.6) is within reach of its motion (0.5): in view
    assert fig.axes[0].get_ylim()[1] > 0.6
    without = trajectory_figure(_trajectory(vel_limits=None, acc_limits=None, pos_limits=None))
    assert [len(_bands(ax)) for ax in without.axes] == [0, 0, 0]


def test_the_stop_is_marked_and_labelled() -> None:
    fig = trajectory_figure(_trajectory())
    t_stop = quintic()[0][125]
    for ax in fig.axes:
        stops = [ln for ln in ax.lines if ln.get_gid() == STOP_GID]
        assert len(stops) == 1 and np.all(np.asarray(stops[0].get_xdata()) == t_stop)
    labels = [x for x in fig.axes[0].texts if x.get_gid() == STOP_GID]
    assert [x.get_text() for x in labels] == ["stopped at 62.5%: joint limit: elbow"]
    # a fraction below 1 without an index: at the last sample; no stop: nothing marked
    at_end = trajectory_figure(_trajectory(stop_index=None, reason=""))
    stops = [ln for ln in at_end.axes[1].lines if ln.get_gid() == STOP_GID]
    assert np.all(np.asarray(stops[0].get_xdata()) == 2.0)
    assert [x.get_text() for x in at_end.axes[0].texts] == ["stopped at 62.5%"]
    done = trajectory_figure(_trajectory(stop_index=None, fraction=1.0, reason=""))
    assert all(ln.get_gid() != STOP_GID for ax in done.axes for ln in ax.lines)
    assert len(done.axes[0].texts) == 0


def test_missing_derivatives_are_finite_differences_and_say_so() -> None:
    """Second order on a uniform 10 ms grid: qd within 1e-3 rad/s of the quintic's exact
    derivative (edges included), qdd within 2e-3 rad/s² inside (the differences of differences
    are first order in their two end samples: within 0.1 rad/s² there)."""
    t, q, qd, qdd = quintic()
    bare = Trajectory(t, q)
    fd_qd, fd_qdd, qd_fd, qdd_fd = derivatives(bare)
    assert qd_fd and qdd_fd
    assert np.max(np.abs(fd_qd - qd)) < 1e-3
    assert np.max(np.abs(fd_qdd - qdd)[2:-2]) < 2e-3 and np.max(np.abs(fd_qdd - qdd)) < 0.1
    fig = trajectory_figure(bare)
    assert fig.axes[1].get_ylabel() == "qd [rad/s] (finite differences)"
    assert fig.axes[2].get_ylabel() == "qdd [rad/s²] (finite differences)"
    assert [ln.get_label() for ln in _joint_lines(fig.axes[0])] == [f"q[{j}]" for j in range(6)]
    # qd given, qdd not: qdd from the given qd
    half = derivatives(Trajectory(t, q, qd))
    assert not half[2] and half[3] and np.array_equal(half[0], qd)
    assert np.max(np.abs(half[1] - qdd)) < 2e-3
    # on an uneven grid too
    uneven = np.sort(np.concatenate([[0.0, 2.0], np.random.default_rng(0).uniform(0, 2, 400)]))
    tau = uneven / 2.0
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    sd = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / 2.0
    got = derivatives(Trajectory(uneven, s[:, None]))[0][:, 0]
    assert np.max(np.abs(got - sd)) < 5e-3


def test_degrees() -> None:
    fig = trajectory_figure(_trajectory(), deg=True)
    assert [ax.get_ylabel() for ax in fig.axes] == ["q [deg]", "qd [deg/s]", "qdd [deg/s²]"]
    _, q, _, _ = quintic()
    got = _joint_lines(fig.axes[0])[2].get_ydata()
    assert np.allclose(got, np.degrees(q[:, 2]), rtol=1e-15, atol=0)
    y = [b.get_paths()[0].vertices[:, 1] for b in _bands(fig.axes[1])]
    assert any(np.any(np.isclose(v, math.degrees(3.14), rtol=1e-14)) for v in y)


def test_many_joints_and_a_title() -> None:
    t = np.linspace(0.0, 1.0, 30)
    q = np.sin(np.outer(t, np.arange(1, 13)))
    fig = trajectory_figure(Trajectory(t, q), title="twelve")
    assert fig.get_suptitle() == "twelve"
    colors = {tuple(ln.get_color()) for ln in _joint_lines(fig.axes[0])}
    assert len(colors) == 12  # no two joints share a colour


def test_rendered_to_png(tmp_path: pathlib.Path) -> None:
    path = save_figure(trajectory_figure(_trajectory(qd=None)), tmp_path / "traj.png", dpi=80)
    data = path.read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n")
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert (width, height) == (880, 680)  # 11 x 8.5 in at 80 dpi


def test_no_pyplot_and_no_matplotlib_before_it_is_called() -> None:
    """matplotlib is imported when a figure is drawn, and never pyplot (the user's backend)."""
    code = (
        "import sys, numpy as np; import poekin.motion.plot as p; "
        "from poekin.io.trajectory import Trajectory; "
        "assert 'matplotlib' not in sys.modules; "
        "p.trajectory_figure(Trajectory(np.arange(3.0), np.zeros((3, 1)))); "
        "assert 'matplotlib.pyplot' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
