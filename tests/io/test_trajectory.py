"""The trajectory file (poekin.io.trajectory): written and read back to the bit, read by plain
NumPy (no pickle, texts as unicode), hand-made archives accepted, and every bad file refused
with one line that names the file and the problem."""

from __future__ import annotations

import pathlib
from typing import Any

import hypothesis.extra.numpy as hnp
import numpy as np
import pytest
from helpers import load_quiet
from hypothesis import given, settings
from hypothesis import strategies as st
from trajectory_helpers import quintic

from poekin.errors import InputError
from poekin.io.import_mujoco import tree_from_model
from poekin.io.trajectory import FORMAT, Trajectory, load_trajectory, qpos_column_names

UR5E_NAMES = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)


def _full() -> Trajectory:
    t, q, qd, qdd = quintic()
    return Trajectory(
        t,
        q,
        qd,
        qdd,
        robot="universal_robots_ur5e",
        joint_names=UR5E_NAMES,
        vel_limits=np.array([3.14, 3.14, 3.14, 6.28, 6.28, np.inf]),
        acc_limits=np.full(6, 8.0),
        pos_limits=np.tile([-2 * np.pi, 2 * np.pi], (6, 1)),
        fraction=0.625,
        reason="joint limit: elbow_joint",
        stop_index=125,
    )


def test_every_field_reads_back_to_the_bit(tmp_path: pathlib.Path) -> None:
    full = _full()
    path = full.save(tmp_path / "traj.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["traj.npz"]
    back = load_trajectory(path)
    for name in ("t", "q", "qd", "qdd", "vel_limits", "acc_limits", "pos_limits"):
        got, want = getattr(back, name), getattr(full, name)
        assert got.dtype == np.float64 and np.array_equal(got, want), name
    for name in ("robot", "joint_names", "fraction", "reason", "stop_index"):
        assert getattr(back, name) == getattr(full, name), name
    assert back.stopped and back.stop_time == full.t[125]
    assert back.duration == 2.0 and back.n == 6


def test_the_file_is_plain_arrays(tmp_path: pathlib.Path) -> None:
    """Read by NumPy itself with pickles refused: numbers as float64, texts as unicode."""
    path = _full().save(tmp_path / "traj.npz")
    with np.load(path, allow_pickle=False) as archive:
        files = {name: archive[name] for name in archive.files}
    assert set(files) == {
        *("t", "q", "qd", "qdd", "vel_limits", "acc_limits", "pos_limits"),
        *("robot", "joint_names", "fraction", "reason", "stop_index", "format", "version"),
    }
    assert files["format"].dtype.kind == "U" and str(files["format"]) == FORMAT
    assert files["joint_names"].dtype.kind == "U" and files["joint_names"].shape == (6,)
    assert str(files["robot"]) == "universal_robots_ur5e"
    assert files["stop_index"].dtype.kind == "i" and int(files["stop_index"]) == 125
    t, q, _, _ = quintic()
    assert np.array_equal(files["t"], t) and np.array_equal(files["q"], q)


def test_a_hand_made_archive_reads(tmp_path: pathlib.Path) -> None:
    """``numpy.savez(path, t=t, q=q)``: the optional entries are absent, so None or empty."""
    t, q, _, _ = quintic(11)
    np.savez(tmp_path / "mine.npz", t=t, q=q.astype(np.float32))
    back = load_trajectory(tmp_path / "mine.npz")
    assert back.q.dtype == np.float64 and np.array_equal(back.q, q.astype(np.float32))
    assert back.qd is None and back.qdd is None and back.vel_limits is None
    assert back.robot == "" and back.joint_names == () and back.fraction is None
    assert not back.stopped and back.stop_time is None
    assert back.column_names() == tuple(f"q[{j}]" for j in range(6))
    # what it holds is written again under its own names
    back.save(tmp_path / "again.npz")
    with np.load(tmp_path / "again.npz") as archive:
        assert set(archive.files) == {"t", "q", "format", "version"}


def test_a_fraction_below_one_stops_at_the_last_sample() -> None:
    t, q, _, _ = quintic(11)
    stopped = Trajectory(t, q, fraction=0.4, reason="singular: sigma_min 1e-4")
    assert stopped.stopped and stopped.stop_time == t[-1]
    assert not Trajectory(t, q, fraction=1.0).stopped


@settings(max_examples=40, deadline=None)
@given(
    tq=st.integers(2, 30).flatmap(
        lambda K: st.tuples(
            st.lists(
                st.floats(-1e6, 1e6, allow_nan=False), min_size=K, max_size=K, unique=True
            ).map(sorted),
            hnp.arrays(np.float64, (K, 3), elements=st.floats(-1e300, 1e300)),
        )
    ),
    names=st.lists(
        st.text(st.characters(exclude_characters="\x00"), min_size=1, max_size=12),
        min_size=3,
        max_size=3,
        unique=True,
    ),
)
def test_round_trip_property(
    tq: tuple[list[float], np.ndarray], names: list[str], tmp_path_factory: Any
) -> None:
    t, q = tq
    path = tmp_path_factory.mktemp("h") / "x.npz"
    original = Trajectory(np.array(t), q, joint_names=tuple(names), robot=names[0] * 3)
    back = load_trajectory(original.save(path))
    assert np.array_equal(back.t, np.array(t)) and np.array_equal(back.q, q)
    assert back.joint_names == tuple(names) and back.robot == names[0] * 3


def test_qpos_column_names_follow_mujocos_layout() -> None:
    """One name per qpos column, each at its joint's jnt_qposadr in MuJoCo's compiled model."""
    loaded = load_quiet("unitree_g1")
    tree = tree_from_model(loaded.model, robot=loaded.robot)
    names = qpos_column_names(tree)
    model = loaded.model
    assert len(names) == model.nq
    words = {0: ("x", "y", "z", "qw", "qx", "qy", "qz"), 1: ("qw", "qx", "qy", "qz")}
    for j in range(model.njnt):
        name, adr, kind = model.joint(j).name, model.jnt_qposadr[j], model.jnt_type[j]
        if kind in words:  # mjJNT_FREE, mjJNT_BALL
            assert names[adr : adr + len(words[kind])] == tuple(f"{name}[{w}]" for w in words[kind])
        else:
            assert names[adr] == name
    ur5e = load_quiet("universal_robots_ur5e")
    assert qpos_column_names(tree_from_model(ur5e.model)) == UR5E_NAMES


# --- bad files ----------------------------------------------------------------------------------


def _savez(path: pathlib.Path, **arrays: Any) -> pathlib.Path:
    np.savez(path, **arrays)
    return path


def _bad(tmp_path: pathlib.Path, case: str) -> pathlib.Path:
    """A file that is no valid trajectory, for each case."""
    t, q, qd, _ = quintic(5)
    p = tmp_path / "bad.npz"
    fixes: dict[str, dict[str, Any]] = {
        "no t": {"q": q},
        "no q": {"t": t},
        "neither": {"T": np.zeros((2, 4, 4))},
        "other format": {"t": t, "q": q, "format": np.array("poekin-params")},
        "unknown entry": {"t": t, "q": q, "qdot": qd},
        "not increasing": {"t": t[[0, 1, 3, 2, 4]], "q": q},
        "lengths differ": {"t": t, "q": q[:4]},
        "nan": {"t": t, "q": np.where(np.arange(6) == 2, np.nan, q)},
        "qd shape": {"t": t, "q": q, "qd": qd[:, :5]},
        "zero limit": {"t": t, "q": q, "vel_limits": np.array([1, 1, 0.0, 1, 1, 1])},
        "negative limit": {"t": t, "q": q, "acc_limits": -np.ones(6)},
        "upside down": {"t": t, "q": q, "pos_limits": np.tile([1.0, -1.0], (6, 1))},
        "names count": {"t": t, "q": q, "joint_names": np.array(["a", "b"])},
        "names twice": {"t": t, "q": q, "joint_names": np.array(["a", "b", "c", "a", "e", "f"])},
        "names numbers": {"t": t, "q": q, "joint_names": np.arange(6)},
        "fraction": {"t": t, "q": q, "fraction": np.array(1.5)},
        "stop index": {"t": t, "q": q, "stop_index": np.array(5)},
        "stop index float": {"t": t, "q": q, "stop_index": np.array(2.0)},
        "version": {"t": t, "q": q, "version": np.array(2)},
        "one sample": {"t": t[:1], "q": q[:1]},
        "t 2-d": {"t": t[:, None], "q": q},
        "text numbers": {"t": t, "q": q.astype(str)},
    }
    if case == "missing":
        return tmp_path / "missing.npz"
    if case == "not npz":
        p.write_text("t,q\n0,1\n")
        return p
    if case == "pickle":
        np.savez(p, t=t, q=np.array([object()] * 5, dtype=object))
        return p
    return _savez(p, **fixes[case])


BAD = {
    "missing": "trajectory {p}: no such file",
    "not npz": "trajectory {p} is not a NumPy .npz archive; save a trajectory with Trajectory.save",
    "pickle": "trajectory {p} holds Python objects, not arrays of numbers",
    "no t": "trajectory {p} is not a trajectory: it has no t (it holds 'q'); a trajectory holds "
    "t (K,) and q (K, n)",
    "no q": "trajectory {p} is not a trajectory: it has no q (it holds 't')",
    "neither": "trajectory {p} is not a trajectory: it has no t or q (it holds 'T')",
    "other format": "trajectory {p} is a 'poekin-params' file, not a trajectory",
    "unknown entry": "trajectory {p}: unknown entry 'qdot': did you mean 'qd'?",
    "not increasing": "trajectory {p}: t must increase strictly, but t[3] = 1 s follows "
    "t[2] = 1.5 s",
    "lengths differ": "trajectory {p}: q must be (K, n) = (5, n) joint values, one row per time "
    "of t, got shape (4, 6)",
    "nan": "trajectory {p}: q[0, 2] is nan; every value must be finite",
    "qd shape": "trajectory {p}: qd has shape (5, 5), expected (5, 6)",
    "zero limit": "trajectory {p}: vel_limits must be > 0 (inf: no limit), got 0 for joint 2",
    "negative limit": "trajectory {p}: acc_limits must be > 0 (inf: no limit), got -1 for joint 0",
    "upside down": "trajectory {p}: pos_limits of joint 0 are upside down (1 > -1); give "
    "[lower, upper]",
    "names count": "trajectory {p}: joint_names names 2 columns, q has 6: give one name per column",
    "names twice": "trajectory {p}: joint_names names 'a' twice",
    "names numbers": "trajectory {p}: joint_names must be a (n,) array of text, got int64 (6,)",
    "fraction": "trajectory {p}: fraction must be in [0, 1], got 1.5",
    "stop index": "trajectory {p}: stop_index must be in 0..4, got 5",
    "stop index float": "trajectory {p}: stop_index must be an integer, got 2.0",
    "version": "trajectory {p} is a trajectory of version 2; this poekin reads version 1",
    "one sample": "trajectory {p}: t must be (K,) sample times with K >= 2, got shape (1,)",
    "t 2-d": "trajectory {p}: t must be (K,) sample times with K >= 2, got shape (5, 1)",
    "text numbers": "trajectory {p}: q holds <U",
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_file_is_one_line_naming_it(case: str, tmp_path: pathlib.Path) -> None:
    p = _bad(tmp_path, case)
    with pytest.raises(InputError) as info:
        load_trajectory(p)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(BAD[case].format(p=p)), message


def test_save_refuses_another_suffix_and_an_existing_file(tmp_path: pathlib.Path) -> None:
    full = _full()
    with pytest.raises(InputError, match=r"traj.csv: a trajectory file is a .npz archive"):
        full.save(tmp_path / "traj.csv")
    path = full.save(tmp_path / "traj.npz")
    with pytest.raises(InputError, match="already exists; pass --force to replace it"):
        full.save(path)
    t, q, _, _ = quintic(3)
    Trajectory(t, q).save(path, force=True)
    assert load_trajectory(path).q.shape == (3, 6)


def test_fields_given_in_python_are_checked_and_named() -> None:
    t, q, _, _ = quintic(4)
    with pytest.raises(InputError, match=r"^trajectory: q\[1, 0\] is inf; every value"):
        Trajectory(t, np.where(np.arange(4)[:, None] == 1, np.inf, q))
    with pytest.raises(InputError, match=r"^trajectory: robot must be text, got int"):
        Trajectory(t, q, robot=3)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"^trajectory: joint_names 'a\\x00' holds a NUL"):
        Trajectory(t, q[:, :1], joint_names=("a\x00",))
    with pytest.raises(InputError, match=r"^trajectory: stop_index must be a sample index"):
        Trajectory(t, q, stop_index=True)
    with pytest.raises(InputError, match=r"^trajectory: vel_limits\[4\] is nan"):
        Trajectory(t, q, vel_limits=np.array([1, 1, 1, 1, np.nan, 1]))
    ints = Trajectory(np.arange(4), np.ones((4, 2), dtype=int))
    assert ints.t.dtype == ints.q.dtype == np.float64
