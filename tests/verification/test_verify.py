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


# --- issue #15: the API takes what load takes -------------------------------------------------


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
def test_verify_takes_a_name_a_path_a_chain_a_tree_and_a_table() -> None:
    import poekin

    by_name = verify("universal_robots_ur5e", samples=50)
    assert by_name.passed and by_name.frame == "attachment_site" and by_name.params is None
    chain = load("universal_robots_ur5e")
    by_chain = verify(chain, samples=50)
    assert by_chain.passed and by_chain.max_pos_err_m == by_name.max_pos_err_m
    by_path = verify(load_quiet("unitree_go2").xml_path, samples=20)
    assert by_path.passed and by_path.frame == "imu"
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    by_tree = verify(tree, samples=20)
    assert by_tree.passed and by_tree.frame == "all frames" and len(by_tree.frame_errors) == 14
    table = poekin.named_params("ur5e-dh")
    by_table = verify(table, against="universal_robots_ur5e", samples=50)
    assert not by_table.passed and by_table.params == "ur5e-dh"
    assert list(by_table.pos_err) == ["DH table", "space PoE", "body PoE"]
    by_param_name = verify(params="ur5e-dh", samples=50)
    assert by_param_name.max_pos_err_m == by_table.max_pos_err_m


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda p: verify(p.named_params("ur5e-dh")), "say which model to check it against"),
        (lambda p: verify(p.lynch_park_ur5_chain()), "say which model to check it against"),
        (lambda p: verify(42), "cannot check against a int"),
        (lambda p: verify("universal_robots_ur5e", against="x"), "against= goes with a chain"),
        (lambda p: verify(samples=0), "samples must be a whole number, 1 or more"),
        (lambda p: verify(seed=-1), "the seed must be a whole number, 0 or more, got -1"),
        (lambda p: p.diagnose(42), "must be a Chain, a DHTable"),
        (lambda p: p.diagnose("ur5e-dh", 3.5), "the model must be a Chain, a Tree"),
        (lambda p: p.diagnose("ur5e-dh", samples=0), "samples must be a whole number"),
    ],
)
def test_wrong_things_to_check_are_typed_errors(call, message: str) -> None:
    import poekin

    with pytest.raises(poekin.InputError, match=message):
        call(poekin)


def test_sample_counts_and_seeds_are_checked() -> None:
    import poekin

    tree = poekin.load_tree(load_quiet("unitree_go2"))
    chain = load("universal_robots_ur5e")
    for call in (
        lambda: poekin.sample_qpos(tree, -1),
        lambda: poekin.sample_qpos(tree, 3, seed=-1),
        lambda: sample_joint_values(chain, 2.5),  # type: ignore[arg-type]
        lambda: sample_joint_values(chain, 3, seed=True),  # type: ignore[arg-type]
    ):
        with pytest.raises(poekin.InputError, match="must be a whole number"):
            call()
    assert poekin.sample_qpos(tree, 0).shape == (0, 19)
    assert sample_joint_values(chain, 2, seed=np.int64(3)).shape == (2, 6)


def test_samples_that_cannot_fit_are_refused_before_anything_is_allocated(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """issue 20: --samples 100000000000 raised MemoryError. The figure said is a lower bound
    (q and two (4, 4) poses of float64 per sample), against the machine's memory."""
    import importlib

    import poekin

    verify_module = importlib.import_module("poekin.verification.verify")

    def no_sampling(*_: object, **__: object) -> None:
        raise AssertionError("sampled before checking the memory")

    monkeypatch.setattr(verify_module, "sample_joint_values", no_sampling)
    monkeypatch.setattr(verify_module, "sample_qpos", no_sampling)
    monkeypatch.setattr(verify_module, "_physical_memory", lambda: 16 * 2**30)  # 16 GiB
    n = 10**11
    needed = 8 * n * (6 + 2 * 16)  # bytes
    with pytest.raises(poekin.InputError) as info:
        verify("universal_robots_ur5e", samples=n)
    assert str(info.value) == (
        f"{n} samples need at least {needed / 2**40:.3g} TiB of memory for their joint values "
        f"and poses, more than this machine's 16 GiB; use fewer (at most about "
        f"{16 * 2**30 // (8 * 38):,}), or several runs with different seeds"
    )
    with pytest.raises(poekin.InputError, match="samples need at least"):
        verify(load_quiet("unitree_go2"), all_frames=True, samples=10**9)
    with pytest.raises(poekin.InputError, match="samples need at least"):
        poekin.diagnose("ur5e-dh", samples=n)
    monkeypatch.undo()
    assert verify("universal_robots_ur5e", samples=3).samples == 3
