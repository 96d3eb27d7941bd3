"""Parameter files: DH tables and PoE sets read back from JSON/YAML give the same kinematics, and
every malformed file gets a one-line InputError that says where and what."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import assert_close
from test_params import BOOK_BODY_SCREWS, BOOK_HOME

from poekin import Chain, InputError, adjoint, dh_from_chain, exp_se3
from poekin._extras import install_command
from poekin.dh import DHTable
from poekin.errors import MissingExtraError, UnitWarning, UnknownParamsError
from poekin.io.paramfile import load_params, load_registration, params_from_dict
from poekin.io.params import PARAM_SETS, UR5E_DH, lynch_park_ur5_chain, ur5e_chain

# JSON writes floats with repr(), which reads back bit for bit: round trips are exact.
EXACT = 0.0
Q = np.random.default_rng(11).uniform(-np.pi, np.pi, size=(40, 6))


def _write(path: Path, obj: Any) -> Path:
    path.write_text(json.dumps(obj, indent=1))
    return path


# --- round trips --------------------------------------------------------------------------------


def test_dh_table_round_trip(tmp_path: Path) -> None:
    path = _write(tmp_path / "ur5e.json", UR5E_DH.describe())
    table = load_params(path)
    assert isinstance(table, DHTable)
    assert_close("fk", table.fk(Q), UR5E_DH.fk(Q), EXACT)
    assert (table.joint_names, table.frame, table.robot) == (
        UR5E_DH.joint_names,
        "flange",
        "ur5e-dh",
    )


def test_modified_dh_with_prismatic_base_tool_and_notes_round_trip(tmp_path: Path) -> None:
    original = DHTable(
        "modified",
        a=[0.0, 0.3, 0.1],
        alpha=[0.0, -np.pi / 2, 0.7],
        d=[0.2, 0.05, -0.1],
        theta_offset=[0.1, 0.0, -0.4],
        joint_types=("revolute", "prismatic", "revolute"),
        base=exp_se3([0.1, -0.2, 0.3, 1.0, 2.0, 3.0]),
        tool=exp_se3([-0.5, 0.4, 0.2, 0.0, 0.1, 0.2]),
        notes=("a note the file may carry",),
    )
    table = load_params(_write(tmp_path / "rpr.json", original.describe()))
    assert isinstance(table, DHTable) and table.convention == "modified"
    assert table.joint_types == original.joint_types
    q = np.random.default_rng(2).uniform(-1, 1, size=(40, 3))
    assert_close("fk", table.fk(q), original.fk(q), EXACT)


def test_chain_describe_round_trip(tmp_path: Path) -> None:
    for chain in (ur5e_chain(), lynch_park_ur5_chain()):  # finite and infinite limits
        loaded = load_params(_write(tmp_path / "chain.json", chain.describe()))
        assert isinstance(loaded, Chain)
        assert_close("fk", loaded.fk(Q), chain.fk(Q), EXACT)
        assert (loaded.joint_names, loaded.frame) == (chain.joint_names, chain.frame)


def test_chain_describe_with_null_limits(tmp_path: Path) -> None:
    doc = lynch_park_ur5_chain().describe()
    for joint in doc["joints"]:
        joint["limits"] = [None, None]
    loaded = load_params(_write(tmp_path / "chain.json", doc))
    assert_close("fk", loaded.fk(Q), lynch_park_ur5_chain().fk(Q), EXACT)


def test_screws_form_with_prismatic_joint(tmp_path: Path) -> None:
    # A hand-written RP arm: turn about z, then slide along x; M = translation (1, 0, 0.5).
    doc = {
        "screws": [[0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0]],
        "home": [[1, 0, 0, 1], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]],
        "joint_names": ["turn", "slide"],
        "joint_types": ["revolute", "prismatic"],
        "frame": "tip",
        "robot": "rp",
    }
    chain = load_params(_write(tmp_path / "rp.json", doc))
    assert isinstance(chain, Chain) and chain.joint_types == ("revolute", "prismatic")
    t, s = 0.3, 0.2
    tip = [(1 + s) * np.cos(t), (1 + s) * np.sin(t), 0.5]
    assert_close("tip", chain.fk([t, s])[:3, 3], tip, 1e-15)


def test_body_screws_form_reproduces_the_book(tmp_path: Path) -> None:
    # Lynch & Park Example 4.5 in its body form, typed from the book; its printed FK result.
    doc = {"body_screws": BOOK_BODY_SCREWS, "home": BOOK_HOME}
    chain = load_params(_write(tmp_path / "body.json", doc))
    assert isinstance(chain, Chain)
    q = [0, -np.pi / 2, 0, 0, np.pi / 2, 0]
    T_book = [[0, -1, 0, 0.095], [1, 0, 0, 0.109], [0, 0, 1, 0.988], [0, 0, 0, 1]]
    assert_close("fk", chain.fk(q), T_book, 1e-12)
    assert_close("vs the PoE set", chain.fk(Q), lynch_park_ur5_chain().fk(Q), 1e-14)


def test_yaml_hand_written_planar_arm(tmp_path: Path) -> None:
    pytest.importorskip("yaml")
    path = tmp_path / "planar.yaml"
    path.write_text(
        "convention: standard\n"
        "robot: planar\n"
        "rows:\n"
        "  - {a: 0.5, alpha: 0, d: 0}\n"
        "  - {a: 0.3, alpha: 0, d: 0, joint: elbow}\n"
    )
    table = load_params(path)
    assert isinstance(table, DHTable) and table.joint_names == ("joint1", "elbow")
    q1, q2 = 0.4, -1.1
    tip = [0.5 * np.cos(q1) + 0.3 * np.cos(q1 + q2), 0.5 * np.sin(q1) + 0.3 * np.sin(q1 + q2), 0]
    assert_close("tip", table.fk([q1, q2])[:3, 3], tip, 1e-15)


def test_yaml_round_trip(tmp_path: Path) -> None:
    yaml = pytest.importorskip("yaml")
    for suffix, original in ((".yml", UR5E_DH), (".yaml", ur5e_chain())):
        path = tmp_path / f"p{suffix}"
        path.write_text(yaml.safe_dump(original.describe()))
        loaded = load_params(str(path))
        assert type(loaded) is type(original)
        assert_close("fk", loaded.fk(Q), original.fk(Q), EXACT)


def test_named_sets_through_load_params() -> None:
    for name in PARAM_SETS:
        assert isinstance(load_params(name), (Chain, DHTable))


# --- malformed documents ------------------------------------------------------------------------

ROW = {"a": 0.0, "alpha": 0.0, "d": 0.1}
EYE = np.eye(4).tolist()
SCREW = [0, 0, 1, 0, 0, 0]


def _dh(*rows: Any, **extra: Any) -> dict[str, Any]:
    return {"convention": "standard", "rows": list(rows), **extra}


MALFORMED: list[tuple[str, Any, str]] = [
    ("top-level-list", [ROW], "the top level is a list of 1, expected an object"),
    ("top-level-number", 3, "expected an object"),
    ("neither", {"robot": "x"}, "neither a DH table (needs 'rows'), a PoE set"),
    ("missing-alpha", _dh(ROW, ROW, {"a": 0, "d": 0}), "rows[2] has no 'alpha'; each row needs"),
    ("string-number", _dh({**ROW, "d": "0.1"}), "rows[0].d must be a number"),
    ("bool-number", _dh({**ROW, "a": True}), "rows[0].a must be a number, got true"),
    ("null-number", _dh({**ROW, "a": None}), "rows[0].a must be a number, got null"),
    ("nan", _dh({**ROW, "alpha": float("nan")}), "rows[0].alpha is NaN"),
    ("inf", _dh({**ROW, "theta_offset": float("inf")}), "rows[0].theta_offset is infinite"),
    ("row-not-object", _dh([0, 0, 0]), "rows[0] must be an object"),
    ("row-typo", _dh({**ROW, "theta": 1}), "unknown key 'theta' (did you mean 'theta_offset'?)"),
    ("no-convention", {"rows": [ROW]}, "a DH table needs 'convention'"),
    ("bad-convention", _dh(ROW, convention="craig"), "unknown DH convention 'craig'"),
    ("bad-joint-type", _dh({**ROW, "joint_type": "rev"}), "unknown joint type 'rev'"),
    ("empty-rows", _dh(), "'rows' is empty"),
    ("rows-not-list", {"convention": "standard", "rows": {"a": 0}}, "'rows' must be a list"),
    ("duplicate-joint", _dh({**ROW, "joint": "j"}, {**ROW, "joint": "j"}), "'j' appears twice"),
    ("home-3-rows", {"screws": [SCREW], "home": EYE[:3]}, "'home' must be a 4x4 matrix, got 3"),
    ("home-short-row", {"screws": [SCREW], "home": [*EYE[:3], [0, 0, 1]]}, "'home'[3] has 3"),
    ("home-not-list", {"screws": [SCREW], "home": "eye"}, "'home' must be a 4x4 matrix, got a s"),
    ("home-missing", {"screws": [SCREW]}, "a PoE set needs 'home'"),
    ("home-bad-rotation", {"screws": [SCREW], "home": (2 * np.eye(4)).tolist()}, "not orthonorm"),
    ("base-bad-last-row", _dh(ROW, base=[*EYE[:3], [0, 0, 1, 1]]), "base: the last row must be"),
    ("screw-5", {"screws": [SCREW[:5]], "home": EYE}, "screws[0] has 5 numbers, expected 6"),
    ("screw-string", {"screws": [[0, 0, "z", 0, 0, 0]], "home": EYE}, "screws[0][2] must be a n"),
    ("screw-not-unit", {"screws": [[0, 0, 2, 0, 0, 0]], "home": EYE}, "needs a unit axis w"),
    ("both-screws", {"screws": [SCREW], "body_screws": [SCREW], "home": EYE}, "keep one (space"),
    ("both-shapes", {**_dh(ROW), "screws": [SCREW], "home": EYE}, "has both 'rows'"),
    (
        "names-count",
        {"screws": [SCREW], "home": EYE, "joint_names": ["a", "b"]},
        "'joint_names' has 2 entries but 'screws' has 1",
    ),
    ("name-not-string", {"screws": [SCREW], "home": EYE, "joint_names": [7]}, "joint_names[0] mu"),
    ("joints-no-screw", {"joints": [{"name": "a"}], "home": EYE}, "joints[0] has no 'screw'"),
    ("frame-not-string", _dh(ROW, frame=3), "'frame' must be a string"),
]


@pytest.mark.parametrize(
    ("doc", "phrase"), [m[1:] for m in MALFORMED], ids=[m[0] for m in MALFORMED]
)
def test_malformed_document(tmp_path: Path, doc: Any, phrase: str) -> None:
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(doc))  # NaN and Infinity are written as JSON's extensions
    with pytest.raises(InputError) as info:
        load_params(path)
    message = str(info.value)
    assert phrase in message
    assert message.startswith(str(path)), message
    assert "\n" not in message


def test_params_from_dict_names_the_source() -> None:
    with pytest.raises(InputError, match=r"^mine\.json: rows\[0\] has no 'd'"):
        params_from_dict({"convention": "standard", "rows": [{"a": 0, "alpha": 0}]}, "mine.json")


# --- malformed files ----------------------------------------------------------------------------


FILES: list[tuple[str, str, str]] = [
    ("syntax", '{\n  "rows": [\n    {"a": 0,,}\n', "not valid JSON: Expecting"),
    ("syntax-line", '{\n  "rows": [\n    {"a": 0,,}\n', "line 3, column"),
    ("empty", "", "is empty"),
    ("blank", "  \n\t\n", "is empty"),
    ("duplicate-key", '{"rows": [], "rows": []}', "the key 'rows' appears twice"),
]


@pytest.mark.parametrize(("text", "phrase"), [f[1:] for f in FILES], ids=[f[0] for f in FILES])
def test_malformed_json_file(tmp_path: Path, text: str, phrase: str) -> None:
    path = tmp_path / "mine.json"
    path.write_text(text)
    with pytest.raises(InputError, match=r"mine\.json") as info:
        load_params(path)
    assert phrase in str(info.value) and "\n" not in str(info.value)


def test_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "mine.json"
    path.write_bytes(b'{"rows": "\xff"}')
    with pytest.raises(InputError, match="not UTF-8"):
        load_params(path)


def test_yaml_syntax_error_and_empty_document(tmp_path: Path) -> None:
    pytest.importorskip("yaml")
    path = tmp_path / "mine.yaml"
    path.write_text("rows:\n  - a: [1, 2\n  - b: 3\n")
    with pytest.raises(InputError, match=r"mine\.yaml: not valid YAML: .* at line \d+, column"):
        load_params(path)
    path.write_text("# only a comment\n")
    with pytest.raises(InputError, match="is empty"):
        load_params(path)


def test_yaml_exponent_without_dot_is_text(tmp_path: Path) -> None:
    pytest.importorskip("yaml")
    path = tmp_path / "mine.yml"
    path.write_text("convention: standard\nrows:\n  - {a: 0, alpha: 0, d: 1e-3}\n")
    with pytest.raises(InputError, match=r"rows\[0\]\.d must be a number, got a string .*1\.0e-3"):
        load_params(path)


def test_yaml_without_pyyaml(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "mine.yaml"
    path.write_text("convention: standard\nrows:\n  - {a: 0, alpha: 0, d: 0}\n")
    monkeypatch.setitem(sys.modules, "yaml", None)  # makes `import yaml` raise ImportError
    with pytest.raises(MissingExtraError) as info:
        load_params(path)
    assert str(info.value) == (
        f"reading {path} needs PyYAML, which is not installed: {install_command('yaml')} "
        "(or save it as JSON)"
    )


def test_directory(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="is a directory"):
        load_params(tmp_path)


def test_bad_suffix(tmp_path: Path) -> None:
    path = _write(tmp_path / "mine.txt", UR5E_DH.describe())
    with pytest.raises(InputError, match=r"must end in \.json or \.yaml \(\.yml\), got '\.txt'"):
        load_params(path)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file") as info:
        load_params(tmp_path / "nope.json")
    assert not isinstance(info.value, UnknownParamsError)


def test_unreadable_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _write(tmp_path / "mine.json", UR5E_DH.describe())

    def refuse(self: Path) -> bytes:
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_bytes", refuse)  # chmod 0 would not stop root
    with pytest.raises(InputError, match=r"cannot read .*mine\.json: Permission denied"):
        load_params(path)


def test_unknown_name_near_miss() -> None:
    with pytest.raises(UnknownParamsError, match="did you mean 'ur5e-dh'") as info:
        load_params("ur5e_dh")
    message = str(info.value)
    assert "'lynch-park-ur5'" in message and ".json" in message and "\n" not in message


# --- issue #15: degrees typed by mistake, or on purpose -------------------------------------------


def _ur5e_table_in(unit: str) -> dict[str, Any]:
    table = UR5E_DH.describe()
    if unit == "deg":
        for row in table["rows"]:
            row["alpha"] = float(np.degrees(row["alpha"]))
            row["theta_offset"] = float(np.degrees(row["theta_offset"]))
        table["angle_unit"] = "deg"
    return table


def test_angle_unit_deg_reads_alpha_and_theta_in_degrees() -> None:
    in_degrees = params_from_dict(_ur5e_table_in("deg"), "deg.json")
    assert isinstance(in_degrees, DHTable)
    assert in_degrees.alpha[0] == pytest.approx(np.pi / 2, abs=1e-15)
    q = np.random.default_rng(3).uniform(-6, 6, (50, 6))
    assert_close("fk", in_degrees.fk(q), UR5E_DH.fk(q), 1e-15)
    assert np.array_equal(in_degrees.d, UR5E_DH.d)  # lengths stay metres


def test_degree_looking_angles_get_a_note_once() -> None:
    table = _ur5e_table_in("deg")
    del table["angle_unit"]
    with pytest.warns(UnitWarning) as caught:
        params_from_dict(table, "mine.json")
    assert len(caught) == 1
    assert str(caught[0].message) == (
        "mine.json: rows[0].alpha = 90 is read as radians (more than a turn); if the table's "
        "angles are degrees, add angle_unit: deg"
    )


def test_angle_unit_mistakes() -> None:
    table = _ur5e_table_in("rad")
    with pytest.raises(InputError, match=r"'angle_unit' is 'degrees'; use 'rad' .* or 'deg'"):
        params_from_dict({**table, "angle_unit": "degrees"}, "t.json")
    poe = ur5e_chain().describe()
    with pytest.raises(InputError, match="angle_unit applies to a DH table's alpha"):
        params_from_dict({**poe, "angle_unit": "deg"}, "p.json")
    assert isinstance(params_from_dict({**poe, "angle_unit": "rad"}, "p.json"), Chain)


# --- issue #26: joint limits, and lengths no arm has ----------------------------------------------


def test_limits_read_back(tmp_path: Path) -> None:
    """Chain.describe()'s limits, and a screws form's 'limits' (null and JSON's Infinity for
    none), are the chain's limits when read."""
    chain = ur5e_chain()
    loaded = load_params(_write(tmp_path / "chain.json", chain.describe()))
    assert isinstance(loaded, Chain) and loaded.limits is not None
    assert np.array_equal(loaded.limits, chain.limits)
    doc = {
        "screws": [[0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0]],
        "home": EYE,
        "joint_types": ["revolute", "prismatic"],
        "limits": [[-1.5, None], [float("-inf"), 0.25]],
    }
    path = tmp_path / "rp.json"
    path.write_text(json.dumps(doc))  # -inf written as JSON's -Infinity
    rp = load_params(path)
    assert isinstance(rp, Chain) and rp.limits is not None
    assert rp.limits.tolist() == [[-1.5, np.inf], [-np.inf, 0.25]]


@pytest.mark.parametrize("form", ["joints", "screws"])
def test_limits_upside_down_are_refused_naming_the_joint(tmp_path: Path, form: str) -> None:
    """[1, -1] once was accepted, and IK then failed after 1,359 iterations without a word."""
    doc = ur5e_chain().describe()
    if form == "joints":
        doc["joints"][1]["limits"] = [1, -1]
        where = "joints[1].limits"
    else:
        doc = {
            "screws": [j["screw"] for j in doc["joints"]],
            "joint_names": [j["name"] for j in doc["joints"]],
            "home": doc["home"],
            "limits": [[-3, 3], [1, -1], None, None, None, None],
        }
        where = "limits[1]"
    path = _write(tmp_path / "limits.json", doc)
    with pytest.raises(InputError) as info:
        load_params(path)
    assert str(info.value) == (
        f"{path}: joint 'shoulder_lift_joint' has limits [1, -1]: the lower limit is above the "
        f"upper ({where}); write [lower, upper] (rad, or m for a prismatic joint), null for no "
        "limit"
    )


@pytest.mark.parametrize(
    ("limits", "phrase"),
    [([1], "must be [lower, upper], got a list of 1"), ("wide", "must be [lower, upper]"),
     ([0, "pi"], "joints[0].limits[1] must be a number")],
)  # fmt: skip
def test_malformed_limits(tmp_path: Path, limits: Any, phrase: str) -> None:
    doc = ur5e_chain().describe()
    doc["joints"][0]["limits"] = limits
    with pytest.raises(InputError, match=re.escape(phrase)):
        load_params(_write(tmp_path / "l.json", doc))


def _scaled(chain: Chain, factor: float) -> dict[str, Any]:
    """The chain's describe() with every length times ``factor``."""
    doc = chain.describe()
    for joint in doc["joints"]:
        joint["screw"] = [*joint["screw"][:3], *(factor * v for v in joint["screw"][3:])]
    home = np.array(doc["home"])
    home[:3, 3] *= factor
    doc["home"] = home.tolist()
    return doc


def test_lengths_in_millimetres_are_refused(tmp_path: Path) -> None:
    """The UR5e in millimetres reaches 850 m from its wrist axes; a DH table so too."""
    path = _write(tmp_path / "mm.json", _scaled(ur5e_chain(), 1000.0))
    with pytest.raises(InputError) as info:
        load_params(path)
    text = str(info.value)
    assert text.startswith(f"{path}: the end frame is ")
    assert " m from joint '" in text and "look like millimetres" in text
    table = UR5E_DH.describe()
    for row in table["rows"]:
        row["a"], row["d"] = 1000 * row["a"], 1000 * row["d"]
    with pytest.raises(InputError, match="look like millimetres"):
        load_params(_write(tmp_path / "dh_mm.json", table))


def test_the_reach_bound_is_the_arm_not_its_numbers(tmp_path: Path) -> None:
    """15 m of reach is an arm (the ISS's reaches 17.6 m), 25 m no arm; a DH table's d of
    tens of metres (nearly parallel axes) is not a reach, and an arm far from the origin of
    its world is no longer for it."""
    big = load_params(_write(tmp_path / "big.json", _scaled(ur5e_chain(), 15.0)))
    assert isinstance(big, Chain)
    with pytest.raises(InputError, match="farther than any arm reaches"):
        load_params(_write(tmp_path / "huge.json", _scaled(ur5e_chain(), 25.0)))
    calibrated = load_params(Path(__file__).parents[1] / "data" / "ur" / "ur5e_calibration.yaml")
    table = dh_from_chain(calibrated)  # type: ignore[arg-type]
    assert np.max(np.abs(table.d)) > 50.0
    assert isinstance(load_params(_write(tmp_path / "dh.json", table.describe())), DHTable)
    moved = exp_se3([0.3, -0.2, 0.1, 1000.0, 0.0, 0.0])  # placed 1 km away, turned
    doc = ur5e_chain().describe()
    for joint in doc["joints"]:
        joint["screw"] = (adjoint(moved) @ np.array(joint["screw"])).tolist()
    doc["home"] = (moved @ ur5e_chain().home).tolist()
    assert isinstance(load_params(_write(tmp_path / "far.json", doc)), Chain)


def test_registration_is_read_beside_the_chain(tmp_path: Path) -> None:
    T = exp_se3([0.1, 0.2, -0.3, 1.0, 0.5, 2.0])
    registration = {"T_meas_base": T.tolist(), "std_m": [1e-5, 2e-5, 3e-5], "std_rad": None}
    doc = {**ur5e_chain().describe(), "registration": registration}
    path = _write(tmp_path / "cal.json", doc)
    chain = load_params(path)
    assert_close("fk", chain.fk(Q), ur5e_chain().fk(Q), EXACT)  # not applied to the chain
    reg = load_registration(path)
    assert np.array_equal(reg.T_meas_base, T) and reg.std_rad is None
    assert reg.std_m is not None and reg.std_m.tolist() == [1e-5, 2e-5, 3e-5]
    with pytest.raises(InputError, match="has no 'registration'"):
        load_registration(_write(tmp_path / "plain.json", ur5e_chain().describe()))
    bad = {**doc, "registration": {"T_meas_base": (2 * np.eye(4)).tolist()}}
    with pytest.raises(InputError, match=r"registration\.T_meas_base"):
        load_params(_write(tmp_path / "bad.json", bad))
    bad = {**doc, "registration": {"T_meas_base": T.tolist(), "std_m": [-1, 0, 0]}}
    with pytest.raises(InputError, match="negative standard error"):
        load_registration(_write(tmp_path / "bad2.json", bad))
