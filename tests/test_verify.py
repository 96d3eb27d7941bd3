"""The verify workflow: sampling, error measures, and reports."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import MJ_TOL, SUMMARY_KEYS, assert_close, load_quiet

from poekin import Chain, exp_so3, load, pose_errors, sample_joint_values, verify


@pytest.fixture(scope="module")
def ur5e_report():
    return verify(load_quiet("universal_robots_ur5e"), samples=1000, seed=0)


def test_ur5e_lab_acceptance(ur5e_report) -> None:
    r = ur5e_report
    assert (r.robot, r.frame, r.samples, r.seed) == (
        "universal_robots_ur5e",
        "attachment_site",
        1000,
        0,
    )
    assert set(r.pos_err) == {"space PoE", "body PoE"}
    for method in r.pos_err:
        assert r.pos_err[method].shape == (1000,)
        assert r.pos_err[method].max() <= MJ_TOL, method
        assert r.ori_err[method].max() <= MJ_TOL, method
    assert r.passed
    assert r.median_pos_err_m <= r.max_pos_err_m


def test_summary_keys_and_worst_case(ur5e_report) -> None:
    s = ur5e_report.summary()
    assert list(s) == SUMMARY_KEYS
    assert s["max_pos_err_m"] == max(e.max() for e in ur5e_report.pos_err.values())
    per = ur5e_report.per_method()
    assert s["max_ori_err_rad"] == max(m["max_ori_err_rad"] for m in per.values())


def test_wrong_parameters_fail() -> None:
    """A chain whose home pose is 1 cm off fails verification with a ~1 cm error."""
    loaded = load_quiet("universal_robots_ur5e")
    good = load(loaded)
    home = good.home.copy()
    home[0, 3] += 0.01
    bad = dataclasses.replace(good, home=home)
    r = verify(loaded, chain=bad, samples=50)
    assert not r.passed
    assert 0.0099 < r.max_pos_err_m < 0.0101
    assert r.max_ori_err_rad < 1e-12


def test_pose_errors_measure_small_angles_accurately() -> None:
    T = np.eye(4)
    T2 = np.eye(4)
    T2[:3, :3] = exp_so3(np.array([0.0, 0.0, 1e-10]))
    T2[:3, 3] = [3e-9, 4e-9, 0.0]
    pos, ori = pose_errors(T, T2)
    assert_close("pos", pos, 5e-9, 1e-24)
    assert abs(ori - 1e-10) < 1e-20  # arccos would give 0 or ~1.5e-8 here


def test_sampling_ranges() -> None:
    chain = Chain(
        ("r", "p", "r_lim"),
        ("revolute", "prismatic", "revolute"),
        [[0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [1, 0, 0, 0, 0, 0]],
        np.eye(4),
        limits=[[-np.inf, np.inf], [-np.inf, np.inf], [-0.5, 0.25]],
    )
    q = sample_joint_values(chain, 5000, seed=1)
    assert np.all(np.abs(q[:, [0, 2]]) <= 2 * np.pi) and np.abs(q[:, 0]).max() > 6.0
    assert np.all(np.abs(q[:, 1]) <= 1.0)
    q_lim = sample_joint_values(chain, 5000, seed=1, within_limits=True)
    assert q_lim[:, 2].min() >= -0.5 and q_lim[:, 2].max() <= 0.25
    assert np.abs(q_lim[:, 0]).max() > 6.0  # unlimited: still [-2 pi, 2 pi]
    assert_close(
        "seeded", sample_joint_values(chain, 3, seed=7), sample_joint_values(chain, 3, seed=7), 0.0
    )


def test_within_limits_report() -> None:
    r = verify(load_quiet("universal_robots_ur5e"), samples=200, within_limits=True)
    assert r.within_limits and r.passed


@pytest.mark.parametrize("n", [1, 2, 7, 1000])
def test_report_medians_are_numpys(ur5e_report, n: int) -> None:
    """The medians equal ``np.median``'s to the bit (poekin sorts itself, so that verifying does
    not import numpy.ma), NaN included."""
    rng = np.random.default_rng(n)
    pos = {"a": rng.random(n) * 1e-14, "b": np.where(rng.random(n) < 0.5, np.nan, 1.0)}
    r = dataclasses.replace(ur5e_report, samples=n, pos_err=pos, ori_err=pos)
    per = r.per_method()
    for m, errors in pos.items():
        assert per[m]["median_pos_err_m"] == float(np.median(errors)) or (
            np.isnan(per[m]["median_pos_err_m"]) and np.isnan(np.median(errors))
        )
