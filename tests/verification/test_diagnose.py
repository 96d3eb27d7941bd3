"""diagnose: each kind of planted error is named, with its joint and size; exact copies match."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import assert_close

import poekin
from poekin import lie
from poekin.dh import DHTable, dh_from_chain, joint_lines
from poekin.verification.diagnose import align_base, diagnose

# Planted errors are recovered from float64 geometry built from the model's own screws, so the
# sizes come back to rounding (~1e-15 m), far inside this bound.
SIZE_TOL = 1e-9
MODELS = [("universal_robots_ur5e", None), ("franka_fr3", None)]


@pytest.fixture(scope="module", params=MODELS, ids=lambda m: m[0])
def model(request: pytest.FixtureRequest) -> poekin.Chain:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load(*request.param)


def with_screws(chain: poekin.Chain, screws: np.ndarray, home: np.ndarray | None = None):
    return poekin.Chain(
        chain.joint_names,
        chain.joint_types,
        screws,
        chain.home if home is None else home,
        robot="yours",
    )


def kinds(d, joint=None):
    return {f.kind for f in d.findings if joint is None or f.joint == joint}


def test_the_model_itself_matches(model):
    d = diagnose(model, model, samples=200)
    assert d.matches and d.findings == () and d.bisect == () and d.symptoms == ()
    assert_close("base", d.base, np.eye(4), 0.0)


def test_its_own_dh_table_matches(model):
    for convention in ("standard", "modified"):
        d = diagnose(dh_from_chain(model, convention), model, samples=200)
        assert d.matches, [f.message for f in d.findings]
        assert d.findings == ()


@pytest.mark.parametrize("joint", range(6))
def test_a_negated_screw_is_named_flipped(model, joint):
    S = model.screws.copy()
    S[joint] *= -1
    d = diagnose(with_screws(model, S), model, samples=200)
    assert not d.matches
    flipped = [f for f in d.findings if f.kind == "axis_flipped"]
    assert [f.joint for f in flipped] == [joint]
    assert model.joint_names[joint] in flipped[0].message
    assert kinds(d) <= {"axis_flipped", "link_length", "link_twist"}, kinds(d)
    assert d.bisect[0].joint == joint and d.bisect[0].max_pos_err_m < SIZE_TOL


@pytest.mark.parametrize("joint", range(6))
def test_an_axis_point_moved_1cm_is_named_with_its_distance(model, joint):
    dirs, points = joint_lines(model)
    normal = np.cross(dirs[joint], [1.0, 0.0, 0.0])
    if np.linalg.norm(normal) < 0.5:
        normal = np.cross(dirs[joint], [0.0, 1.0, 0.0])
    moved = points[joint] + 0.01 * normal / np.linalg.norm(normal)
    S = model.screws.copy()
    S[joint, 3:] = -np.cross(dirs[joint], moved)
    d = diagnose(with_screws(model, S), model, samples=200)
    offsets = [f for f in d.findings if f.kind == "axis_offset"]
    assert [f.joint for f in offsets] == [joint]
    assert_close("offset", offsets[0].value, 0.01, SIZE_TOL)
    assert "0.01 m" in offsets[0].message
    assert not kinds(d) & {"base_rotation", "base_shift", "axis_flipped", "axis_tilted"}
    assert d.bisect[0].joint == joint


def test_a_tilted_axis_is_named_with_its_angle(ur5e):
    S = ur5e.screws.copy()
    R = lie.exp_so3(np.array([0.05, 0.0, 0.0]))  # joint 5 is vertical: tilt it 0.05 rad about x
    w, p = R @ S[4, :3], joint_lines(ur5e)[1][4]
    S[4] = np.concatenate([w, -np.cross(w, p)])
    d = diagnose(with_screws(ur5e, S), ur5e, samples=200)
    tilted = [f for f in d.findings if f.kind == "axis_tilted"]
    assert [f.joint for f in tilted] == [4]
    assert_close("tilt", tilted[0].value, 0.05, SIZE_TOL)


def test_a_moved_base_is_found_and_nothing_else(model):
    B = np.eye(4)
    B[:3, :3] = lie.exp_so3(np.array([0.3, -0.2, 1.1]))
    axis1 = joint_lines(model)[0][0]
    shift = np.array([0.05, -0.02, 0.03])
    B[:3, 3] = shift - axis1 * (shift @ axis1)  # a shift along joint 1 is d1, not the base
    yours = with_screws(
        model, (lie.adjoint(lie.inverse(B)) @ model.screws.T).T, lie.inverse(B) @ model.home
    )
    d = diagnose(yours, model, samples=200)
    assert not d.matches
    assert kinds(d) <= {"base_rotation", "base_shift"}, [f.message for f in d.findings]
    assert_close("base", d.base, B, SIZE_TOL)
    assert d.aligned_max_pos_err_m < SIZE_TOL


def test_a_wrong_home_pose_is_named_and_blamed_at_q0(ur5e):
    M = ur5e.home.copy()
    M[:3, 3] += [0.0, 0.0, 0.4]
    d = diagnose(with_screws(ur5e, ur5e.screws, M), ur5e, samples=200)
    home = [f for f in d.findings if f.kind == "home_position"]
    assert len(home) == 1 and abs(home[0].value - 0.4) < SIZE_TOL
    assert any("q = 0" in s for s in d.symptoms)
    assert any("tenths of a metre" in s for s in d.symptoms)
    assert d.bisect[0].part == "M"


def test_lynch_park_ur5_against_the_menagerie_ur5e(ur5e):
    d = diagnose(poekin.io.params.named_params("lynch-park-ur5"), ur5e)
    assert not d.matches
    rotation = [f for f in d.findings if f.kind == "base_rotation"]
    assert len(rotation) == 1 and abs(rotation[0].value - np.pi) < SIZE_TOL
    assert "180.0 deg" in rotation[0].message
    lengths = {f.message.split(":")[0]: f for f in d.findings if f.kind == "link_length"}
    # Textbook H1 = 0.089 m is the shoulder height; the Menagerie body offset is 0.163 m.
    assert_close("d1", lengths["d1"].value, 0.163 - 0.089, SIZE_TOL)
    assert "home_position" in kinds(d)
    assert any("pi rad" in s for s in d.symptoms)


def test_official_ur5e_dh_table_names_the_millimetre_differences(ur5e):
    d = diagnose(poekin.io.params.named_params("ur5e-dh"), ur5e)
    assert not d.matches and d.max_pos_err_m < 0.01
    text = "\n".join(f.message for f in d.findings)
    assert "d4: 0.1333 m in yours vs 0.134 m in the model" in text
    assert "d1: 0.1625 m in yours vs 0.163 m in the model" in text
    assert {s.part.split()[0] for s in d.bisect} <= {"row", "tool"}
    assert d.bisect[-1].max_pos_err_m < SIZE_TOL


def test_a_joint_type_mismatch_is_named(ur5e):
    t = dh_from_chain(ur5e)
    types = list(t.joint_types)
    types[5] = "prismatic"
    d = diagnose(dataclasses.replace(t, joint_types=tuple(types)), ur5e, samples=100)
    assert [f.joint for f in d.findings if f.kind == "joint_type"] == [5]


def test_a_different_joint_count_is_refused(ur5e):
    t = dh_from_chain(ur5e)
    five = DHTable("standard", t.a[:5], t.alpha[:5], t.d[:5], t.theta_offset[:5], t.joint_types[:5])
    with pytest.raises(poekin.InputError, match="5 joints but the model's chain"):
        diagnose(five, ur5e)


def test_base_alignment_ignores_one_flipped_joint(ur5e):
    S = ur5e.screws.copy()
    S[1] *= -1
    assert_close("base", align_base(with_screws(ur5e, S), ur5e), np.eye(4), 0.0)


def test_summary_is_json_ready(ur5e):
    import json

    S = ur5e.screws.copy()
    S[2] *= -1
    summary = diagnose(with_screws(ur5e, S), ur5e, samples=50).summary()
    again = json.loads(json.dumps(summary))
    assert again["matches"] is False
    assert again["findings"][0]["kind"] == "axis_flipped"


def test_diagnose_takes_names_and_paths() -> None:
    """issue #15: poekin.diagnose("ur5e-dh", "universal_robots_ur5e") as load takes them."""
    import poekin

    by_name = poekin.diagnose("ur5e-dh", "universal_robots_ur5e", samples=100)
    by_object = poekin.diagnose(
        poekin.named_params("ur5e-dh"), poekin.load("universal_robots_ur5e"), samples=100
    )
    assert by_name.max_pos_err_m == by_object.max_pos_err_m > 1e-3
    assert [f.message for f in by_name.findings] == [f.message for f in by_object.findings]
    by_tree = poekin.diagnose("ur5e-poe", poekin.load_tree("universal_robots_ur5e"), samples=50)
    assert by_tree.matches and by_tree.report()[0].startswith("MATCH")
