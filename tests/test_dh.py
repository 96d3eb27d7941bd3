"""Tests of poekin.dh: the row closed forms, DH table -> PoE chain, PoE chain -> DH table, and the
tables of Menagerie robots against mj_forward."""

from __future__ import annotations

import functools
import pathlib
from dataclasses import dataclass

import numpy as np
import pytest
from helpers import assert_close, load_quiet
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin import Chain, InputError, exp_se3
from poekin.dh import CONVENTIONS, NEAR_PARALLEL_SIN, DHTable, dh_from_chain, nearest_dh
from poekin.io.paramfile import load_params
from poekin.io.params import named_params
from poekin.verification.verify import mujoco_poses, pose_errors

# Frame axes and origins that dh builds from unit vectors and O(1) m points (base z, base
# origin, R^T R of the base): a few float64 operations, each ~1e-16, so 1e-14.
FRAME_TOL = 1e-14
# Closed forms: dh's row matrix and the test's product of four elementary matrices evaluate
# the same float64 products of O(1) numbers (measured: bit-identical), and fk multiplies the
# rows in the same order, so any difference is rounding of a few eps per row. 1e-14 still
# catches any wrong sign, swapped factor or misplaced q (errors of O(0.1) or more).
ROW_TOL = 1e-14
# table.fk vs table.to_chain().fk: <= 8 rows with |a|, |d| <= 1 m put the joint frames up to
# ~12 m from the origin, so the PoE exponentials carry intermediate terms q v of up to
# 2 pi * 12 m = 75 m that cancel to the chord; each joint then rounds at ~75 eps ~ 2e-14 m.
# Measured over 20000 tables: 5e-14 m worst for uniform a, d; 1.1e-13 m when every |a| = |d|
# = 1 with 8 rows (the corner hypothesis likes to try). 3e-13 m, about three times that
# corner, is the bar for such metre-scale tables.
TABLE_TO_CHAIN_TOL = 3e-13
# dh_from_chain(chain).fk vs chain.fk: extraction adds common normals and atan2 angles, each a
# few eps; common normals of axes >= 0.2 rad apart are <= ~50 m long, so rounding stays
# ~1e-14 m (measured: 1.5e-14 m worst over 3000 chains). 1e-12 m is the exactness bar of the
# DH extraction (and of the Menagerie check below).
CHAIN_TO_DH_TOL = 1e-12
# chain -> DH -> chain -> DH: both tables are computed from the same lines up to the rounding of
# to_chain (~1e-15 m, amplified by at most 1 / sin 0.2 in a common normal), so 1e-12.
ROUND_TRIP_TOL = 1e-12
# Menagerie DH tables vs mj_forward: the tables of models whose axes are exactly parallel or
# skew agree with MuJoCo to ~3e-15 (measured), so 1e-12 m and 1e-12 rad is a bar they meet with
# three orders of magnitude to spare.
MENAGERIE_POS_TOL = 1e-12
MENAGERIE_ORI_TOL = 1e-12
# ufactory_lite6 alone: its XML rounds quaternions to 6 digits (link3 quat="-2.59734e-06
# -0.707105 -0.707108 -2.59735e-06"), which tilts joint 3 by 7.3e-6 rad from (anti)parallel to
# joint 2. The exact common normal of joints 2 and 3 then lies 2.7e4 m out along the axes
# (d2 = 2.73e4 m), and d3 = 2.73e4 m walks frame 3 back along joint 3 to the joint 3-4 normal.
# Float64 FK through a frame that far out rounds at ~|d| * eps = 6e-12 m per operation:
# measured 1.26e-11 m (standard) and 1.36e-11 m (modified). 1e-10 m is ~16 |d| eps.
# Orientation is unaffected (rotations do not see d) and keeps MENAGERIE_ORI_TOL.
LITE6_POS_TOL = 1e-10
# The explicit near-parallel example below: FK through a frame |d| metres out rounds at
# ~|d| * eps; measured 4.3e-11 m = 0.65 |d| eps (standard) and 8e-16 m (modified) for
# |d| = 3e5 m. 1e-15 |d| (~4.5 |d| eps) is "agrees to about |d| * 1e-15".
NEAR_PARALLEL_REL_TOL = 1e-15

PI = np.pi
SPECIAL_ANGLES = [0.0, PI / 2, PI, -PI / 2]
BATCH_SHAPES = [(), (1,), (3, 1, 2, 1)]
FAST = settings(max_examples=25, deadline=None)

seeds = st.integers(min_value=0, max_value=2**32 - 1)
conventions = st.sampled_from(CONVENTIONS)


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles mapped to [-pi, pi)."""
    return (np.asarray(angle) + PI) % (2 * PI) - PI


def random_pose(rng: np.random.Generator) -> np.ndarray:
    """A pose with a random rotation and a translation of O(1) m."""
    return exp_se3(np.r_[rng.normal(size=3), rng.uniform(-1.0, 1.0, size=3)])


# --------------------------------------------------------------------------------------------
# 1. closed forms: rows against a product of elementary transforms written here


def rot(axis: int, angle: np.ndarray) -> np.ndarray:
    """``(..., 4, 4)`` rotation about x (axis 0) or z (axis 2)."""
    j, k = {0: (1, 2), 2: (0, 1)}[axis]
    c, s = np.cos(angle), np.sin(angle)
    T = np.zeros((*np.shape(angle), 4, 4))
    T[..., 0, 0] = T[..., 1, 1] = T[..., 2, 2] = T[..., 3, 3] = 1.0
    T[..., j, j], T[..., j, k], T[..., k, j], T[..., k, k] = c, -s, s, c
    return T


def trans(axis: int, dist: np.ndarray) -> np.ndarray:
    """``(..., 4, 4)`` translation along x (axis 0) or z (axis 2)."""
    T = np.zeros((*np.shape(dist), 4, 4))
    T[..., 0, 0] = T[..., 1, 1] = T[..., 2, 2] = T[..., 3, 3] = 1.0
    T[..., axis, 3] = dist
    return T


def elementary_row(
    convention: str, theta: np.ndarray, d: np.ndarray, a: float, alpha: float
) -> np.ndarray:
    a_, alpha_ = np.full(np.shape(theta), a), np.full(np.shape(theta), alpha)
    if convention == "standard":
        return rot(2, theta) @ trans(2, d) @ trans(0, a_) @ rot(0, alpha_)
    return rot(0, alpha_) @ trans(0, a_) @ rot(2, theta) @ trans(2, d)


def random_table(rng: np.random.Generator, convention: str, n: int) -> DHTable:
    """Rows with random a, d in [-1, 1], angles in [-pi, pi] (half of them special), random
    joint types and base/tool poses."""

    def angles() -> np.ndarray:
        return np.where(rng.random(n) < 0.5, rng.choice(SPECIAL_ANGLES, n), rng.uniform(-PI, PI, n))

    types = tuple("prismatic" if rng.random() < 0.3 else "revolute" for _ in range(n))
    a, d = rng.uniform(-1.0, 1.0, (2, n))
    return DHTable(
        convention,  # type: ignore[arg-type]
        a,
        angles(),
        d,
        angles(),
        types,
        base=random_pose(rng),
        tool=random_pose(rng),
    )


@pytest.mark.parametrize("shape", BATCH_SHAPES)
@pytest.mark.parametrize("convention", CONVENTIONS)
@FAST
@given(seed=seeds, n=st.integers(1, 8))
def test_rows_and_fk_match_elementary_products(
    shape: tuple[int, ...], convention: str, seed: int, n: int
) -> None:
    rng = np.random.default_rng(seed)
    table = random_table(rng, convention, n)
    q = rng.uniform(-2 * PI, 2 * PI, size=(*shape, n))
    links = table.link_transforms(q)
    assert links.shape == (*shape, n, 4, 4)
    expected_fk = np.broadcast_to(table.base, (*shape, 4, 4))
    for i, kind in enumerate(table.joint_types):
        revolute = kind == "revolute"
        theta = table.theta_offset[i] + (q[..., i] if revolute else 0.0 * q[..., i])
        d = table.d[i] + (0.0 * q[..., i] if revolute else q[..., i])
        row = elementary_row(convention, theta, d, table.a[i], table.alpha[i])
        assert_close(f"{convention} row {i} ({kind})", links[..., i, :, :], row, ROW_TOL)
        expected_fk = expected_fk @ row
    assert_close("fk = base @ rows @ tool", table.fk(q), expected_fk @ table.tool, ROW_TOL)


def test_prismatic_q_moves_d_and_revolute_q_turns_theta() -> None:
    """One revolute and one prismatic row, checked by hand: q = 0 gives the offsets."""
    for convention in CONVENTIONS:
        table = DHTable(
            convention, [0.5, 0.2], [PI / 2, 0.0], [0.1, 0.3], [0.0, 0.4], ("revolute", "prismatic")
        )
        zero, moved = table.link_transforms([[0.0, 0.0], [0.7, 0.25]])
        assert_close(
            "theta moved", moved[0], elementary_row(convention, 0.7, 0.1, 0.5, PI / 2), ROW_TOL
        )
        assert_close("d moved", moved[1], elementary_row(convention, 0.4, 0.55, 0.2, 0.0), ROW_TOL)
        assert_close("q = 0", zero[1], elementary_row(convention, 0.4, 0.3, 0.2, 0.0), ROW_TOL)


# --------------------------------------------------------------------------------------------
# 2. DH table -> PoE chain is exact

dh_angles = st.one_of(st.sampled_from(SPECIAL_ANGLES), st.floats(-PI, PI))
dh_lengths = st.one_of(st.just(0.0), st.floats(-1.0, 1.0))
dh_rows = st.tuples(
    st.sampled_from(["revolute", "revolute", "prismatic"]),
    dh_lengths,
    dh_angles,
    dh_lengths,
    dh_angles,
)


@settings(max_examples=60, deadline=None)
@given(convention=conventions, table_rows=st.lists(dh_rows, min_size=1, max_size=8), seed=seeds)
def test_table_to_chain_is_exact(
    convention: str, table_rows: list[tuple[str, float, float, float, float]], seed: int
) -> None:
    rng = np.random.default_rng(seed)
    types, a, alpha, d, theta = zip(*table_rows, strict=True)
    base, tool = (random_pose(rng) if rng.random() < 0.8 else np.eye(4) for _ in range(2))
    table = DHTable(convention, a, alpha, d, theta, types, base=base, tool=tool)  # type: ignore[arg-type]
    chain = table.to_chain()
    assert chain.joint_types == table.joint_types
    assert chain.joint_names == table.joint_names
    q = rng.uniform(-2 * PI, 2 * PI, size=(16, table.n_joints))
    assert_close("to_chain().fk", chain.fk(q), table.fk(q), TABLE_TO_CHAIN_TOL)
    assert_close("home", chain.home, table.fk(np.zeros(table.n_joints)), 0.0)
    # The screws are the z axes of joint_frames, which are unit and point along each joint.
    frames = table.joint_frames()
    for i, kind in enumerate(table.joint_types):
        part = chain.screws[i, :3] if kind == "revolute" else chain.screws[i, 3:]
        assert_close(f"screw {i} direction", part, frames[i, :3, 2], 0.0)


# --------------------------------------------------------------------------------------------
# 3. PoE chain -> DH table is exact


RELATIONS = (
    "skew",  # random direction >= 0.2 rad from the previous axis, random point
    "perpendicular",  # perpendicular direction, random point (skew)
    "intersecting",  # direction >= 0.2 rad off, through a point of the previous axis
    "parallel",  # same direction, 0.1 - 1 m beside the previous axis
    "antiparallel",  # opposite direction, beside
    "coincident",  # the previous axis line, same direction
    "coincident_flipped",  # the previous axis line, opposite direction
)
FIRST_AXES = ("random", "+z", "-z", "+x")
END_FRAMES = ("off_axis", "on_axis", "on_axis_aligned")
AXIS_DIRECTIONS = np.vstack([np.eye(3), -np.eye(3)])
MIN_SIN = 0.2  # general axes stay this far from parallel: DH is well conditioned


@dataclass
class LineChain:
    """A random chain and how it was built: the relation of joint i + 1 to joint i."""

    chain: Chain
    dirs: np.ndarray
    points: np.ndarray  # each axis' point as dh places it (see joint_lines' docstring)
    pair: list[str]  # per consecutive pair: "parallel", "coincident", "intersecting" or ""
    twist: list[float | None]  # per pair: |alpha| by construction (0, pi/2, pi), None if random
    end: str  # one of END_FRAMES


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def direction_off(rng: np.random.Generator, prev: np.ndarray) -> np.ndarray:
    """A direction at least asin(MIN_SIN) from +-prev: axis-aligned half of the time."""
    while True:
        u = AXIS_DIRECTIONS[rng.integers(6)] if rng.random() < 0.5 else unit(rng.normal(size=3))
        if np.linalg.norm(np.cross(prev, u)) >= MIN_SIN:
            return u


def line_chain(
    rng: np.random.Generator, joints: list[tuple[str, str]], first: str, end: str
) -> LineChain:
    """Axes built line by line: ``joints`` holds (type, relation to the previous axis).

    A prismatic joint only has a direction; dh_from_chain places its line through the previous
    axis point (the world origin for joint 1), and a revolute axis' point is the foot on it of
    the previous point. The same rule is followed here, so the relations below hold for the
    lines dh sees: a prismatic axis not parallel to the previous one intersects it, a parallel
    one coincides with it.
    """
    n = len(joints)
    dirs, points, screws = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 6))
    pair: list[str] = []
    twist: list[float | None] = []
    prev_point = np.zeros(3)
    for i, (kind, relation) in enumerate(joints):
        if i == 0:
            table = {"+z": [0.0, 0.0, 1.0], "-z": [0.0, 0.0, -1.0], "+x": [1.0, 0.0, 0.0]}
            u = np.array(table[first]) if first in table else unit(rng.normal(size=3))
            p = rng.uniform(-1.0, 1.0, 3)
        else:
            w, o = dirs[i - 1], points[i - 1]
            if relation in ("skew", "intersecting"):
                u = direction_off(rng, w)
            elif relation == "perpendicular":
                u = unit(np.cross(w, direction_off(rng, w)))
            else:
                u = -w if relation in ("antiparallel", "coincident_flipped") else w
            if relation in ("skew", "perpendicular"):
                p = rng.uniform(-1.0, 1.0, 3)
            elif relation in ("parallel", "antiparallel"):
                side = unit(np.cross(w, direction_off(rng, w)))
                p = o + side * rng.uniform(0.1, 1.0)
            else:  # intersecting, coincident: through a point of the previous line
                p = o + w * rng.uniform(-1.0, 1.0)
        if kind == "revolute":
            prev_point = p + u * ((prev_point - p) @ u)
            screws[i] = np.r_[u, -np.cross(u, p)]
        else:
            screws[i, 3:] = u
        dirs[i], points[i] = u, prev_point
        if i > 0:
            parallel = relation in ("parallel", "antiparallel", "coincident", "coincident_flipped")
            if kind == "prismatic":
                pair.append("coincident" if parallel else "intersecting")
            elif relation in ("parallel", "antiparallel"):
                pair.append("parallel")
            elif relation.startswith("coincident"):
                pair.append("coincident")
            else:
                pair.append("intersecting" if relation == "intersecting" else "")
            flipped = relation in ("antiparallel", "coincident_flipped")
            twist.append(PI if flipped else 0.0 if parallel else None)
            if relation == "perpendicular":
                twist[-1] = PI / 2
    u, o = dirs[-1], points[-1]
    home = random_pose(rng)
    if end != "off_axis":
        home[:3, 3] = o + u * rng.uniform(-1.0, 1.0)
    if end == "on_axis_aligned":
        x = unit(np.cross(u, direction_off(rng, u)))
        home[:3, :3] = np.column_stack([x, np.cross(u, x), u])
    names = tuple(f"j{i + 1}" for i in range(n))
    types = tuple(kind for kind, _ in joints)
    chain = Chain(names, types, screws, home)  # type: ignore[arg-type]
    return LineChain(chain, dirs, points, pair, twist, end)


def check_table(table: DHTable, built: LineChain) -> None:
    """What dh_from_chain's docstring promises about frames, a, d and notes."""
    chain = built.chain
    # Frame 0 sits on joint 1's axis, at the foot of the world origin, z along the axis.
    assert_close("base z", table.base[:3, 2], built.dirs[0], FRAME_TOL)
    assert_close("base origin", table.base[:3, 3], built.points[0], FRAME_TOL)
    if np.array_equal(built.dirs[0], [0.0, 0.0, 1.0]):
        assert_close("base rotation (joint 1 along +z)", table.base[:3, :3], np.eye(3), 0.0)
    if np.array_equal(built.dirs[0], [0.0, 0.0, -1.0]):  # pi about x
        assert_close("base rotation (along -z)", table.base[:3, :3], np.diag([1.0, -1, -1]), 0.0)
    # The extraction picks x so that every a is >= 0 (flipping the common normal if needed).
    assert np.all(table.a >= 0.0), table.a
    # a of pair i is row i's a (standard) or row i + 1's a_{i} (modified); d is row i's d.
    shift = 0 if table.convention == "standard" else 1
    for i, kind in enumerate(built.pair):
        names = f"'j{i + 1}' and 'j{i + 2}'"
        if kind in ("intersecting", "coincident"):
            assert table.a[i + shift] == 0.0, (i, kind, table.a)
        if kind in ("parallel", "coincident"):
            assert table.d[i] == 0.0, (i, kind, table.d)
        parallel_note = f"joints {names} have parallel axes: chose d{i + 1} = 0"
        coincident_note = f"joints {names} share one axis line"
        assert (parallel_note in table.notes) == (kind == "parallel"), table.notes
        assert any(coincident_note in s for s in table.notes) == (kind == "coincident")
    for i, angle in enumerate(built.twist):  # perpendicular, parallel and opposite axes
        if angle is not None:
            assert_close(f"|alpha| of pair {i}", abs(table.alpha[i + shift]), angle, FRAME_TOL)
    # The last frame sits at the end frame's origin where the row allows it: always in the
    # standard convention (d and a), on the last axis in the modified one (d only). With the
    # end frame's z along the axis as well, the tool is the identity.
    if table.convention == "standard" or built.end != "off_axis":
        assert_close("tool origin", table.tool[:3, 3], np.zeros(3), CHAIN_TO_DH_TOL)
    if built.end == "on_axis_aligned":
        assert_close("tool rotation", table.tool[:3, :3], np.eye(3), FRAME_TOL)
    for name, kind in zip(chain.joint_names, chain.joint_types, strict=True):
        note = f"joint {name!r} is prismatic: its axis placed through the previous axis point"
        assert (note in table.notes) == (kind == "prismatic"), table.notes


joint_specs = st.lists(
    st.tuples(st.sampled_from(["revolute", "revolute", "prismatic"]), st.sampled_from(RELATIONS)),
    min_size=1,
    max_size=8,
)


@settings(max_examples=80, deadline=None)
@given(
    joints=joint_specs,
    first=st.sampled_from(FIRST_AXES),
    end=st.sampled_from(END_FRAMES),
    seed=seeds,
)
def test_chain_to_table_is_exact(
    joints: list[tuple[str, str]], first: str, end: str, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    built = line_chain(rng, joints, first, end)
    chain = built.chain
    q = rng.uniform(-2 * PI, 2 * PI, size=(16, chain.n_joints))
    for convention in CONVENTIONS:
        table = dh_from_chain(chain, convention)
        assert table.convention == convention
        assert table.joint_types == chain.joint_types
        assert table.joint_names == chain.joint_names
        assert_close(f"{convention}: fk", table.fk(q), chain.fk(q), CHAIN_TO_DH_TOL)
        assert_close(
            f"{convention}: fk(0)", table.fk(np.zeros(chain.n_joints)), chain.home, CHAIN_TO_DH_TOL
        )
        check_table(table, built)
        if convention == "modified":  # Craig's a_0, alpha_0 are free: the base takes them
            assert table.a[0] == 0.0 and table.alpha[0] == 0.0
        # The frames depend only on the axis lines and the end frame, so the round trip
        # reproduces the table: a, d, base and tool to rounding; alpha and theta up to 2 pi
        # (atan2 may answer -pi for pi).
        again = dh_from_chain(table.to_chain(), convention)
        for field in ("a", "d", "base", "tool"):
            assert_close(
                f"round trip {field}", getattr(again, field), getattr(table, field), ROUND_TRIP_TOL
            )
        for field in ("alpha", "theta_offset"):
            diff = wrap(getattr(again, field) - getattr(table, field))
            assert_close(
                f"round trip {field} (mod 2 pi)", diff, np.zeros_like(diff), ROUND_TRIP_TOL
            )
        assert again.notes == table.notes
        assert again.joint_types == table.joint_types


@pytest.mark.parametrize("tilt", [0.0, 1e-12, 1e-9, 1e-6, 1.5e-6, 3e-6, 1e-5, 1e-3, 0.5])
def test_first_axis_near_minus_z(tilt: float) -> None:
    """Regression: an axis within ~1e-5 rad of -z once gave a base rotation that missed the
    axis by up to 1e-6 rad (or was not orthonormal, raising InputError)."""
    z = unit(np.array([0.6 * np.sin(tilt), 0.8 * np.sin(tilt), -np.cos(tilt)]))
    screws = [np.r_[z, -np.cross(z, [0.1, 0.2, 0.3])], [1.0, 0.0, 0.0, 0.0, 0.0, 0.5]]
    chain = Chain(
        ("j1", "j2"), ("revolute", "revolute"), screws, random_pose(np.random.default_rng(0))
    )
    q = np.random.default_rng(1).uniform(-2 * PI, 2 * PI, size=(16, 2))
    for convention in CONVENTIONS:
        table = dh_from_chain(chain, convention)
        assert_close("base z", table.base[:3, 2], z, FRAME_TOL)
        R = table.base[:3, :3]
        assert_close("base R^T R", R.T @ R, np.eye(3), FRAME_TOL)
        assert_close(f"{convention}: fk", table.fk(q), chain.fk(q), CHAIN_TO_DH_TOL)


def test_nearly_parallel_axes_are_ill_conditioned() -> None:
    """Two axes 1e-6 rad from parallel: the exact common normal is ~0.3 / 1e-6 m away."""
    tilt = 1e-6
    u = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    p = np.array([0.3, 0.1, 0.0])  # the second axis: 0.1 m beside the z axis, 0.3 m out
    screws = [[0.0, 0.0, 1.0, 0.0, 0.0, 0.0], np.r_[u, -np.cross(u, p)]]
    chain = Chain(
        ("j1", "j2"), ("revolute", "revolute"), screws, exp_se3([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    )
    q = np.random.default_rng(2).uniform(-2 * PI, 2 * PI, size=(64, 2))
    for convention in CONVENTIONS:
        table = dh_from_chain(chain, convention)
        d1 = table.d[0]
        # Lines z and p + s u meet (in projection) where 0.3 + s sin(tilt) = 0.
        assert_close("d1", d1, -0.3 / np.tan(tilt), 1e-6 * abs(d1))
        assert_close("a1", table.a[0 if convention == "standard" else 1], 0.1, 1e-9)
        note = (
            "joints 'j1' and 'j2' are nearly parallel (1e-06 rad): DH is ill-conditioned here "
            "(d1 = -3e+05 m)"
        )
        assert note in table.notes, table.notes
        assert_close(f"{convention}: fk", table.fk(q), chain.fk(q), NEAR_PARALLEL_REL_TOL * abs(d1))
        # A parallel_tol above the tilt gives a clean table (d1 = 0), and says what it costs.
        clean = dh_from_chain(chain, convention, parallel_tol=1e-5)
        assert clean.d[0] == 0.0
        assert any(
            "1e-06 rad from parallel, treated as parallel (d1 = 0)" in s for s in clean.notes
        )
        err = np.abs(clean.fk(q) - chain.fk(q)).max()
        assert 1e-9 < err < 1e-5, err  # ~tilt times the reach, not float rounding


def test_chain_without_joints() -> None:
    home = random_pose(np.random.default_rng(3))
    chain = Chain((), (), np.zeros((0, 6)), home)
    for convention in CONVENTIONS:
        table = dh_from_chain(chain, convention)
        assert table.n_joints == 0
        assert_close("fk", table.fk(np.zeros(0)), home, 0.0)


# --------------------------------------------------------------------------------------------
# 4. Menagerie: DH tables extracted from the models against mj_forward

MENAGERIE_CHAINS = [
    ("universal_robots_ur5e", None),
    ("universal_robots_ur10e", None),
    ("franka_fr3", None),
    ("ufactory_lite6", None),
    ("rethink_robotics_sawyer", None),
    ("franka_emika_panda", "hand"),
]
N_SAMPLES = 1000


@functools.cache
def menagerie_case(source: str, frame: str | None) -> tuple[Chain, np.ndarray, np.ndarray]:
    """The chain, 1000 q in [-2 pi, 2 pi] (seed 0) and mj_forward's poses of the frame."""
    loaded = load_quiet(source)
    reference = poekin.chain_from_model(loaded.model, frame, robot=loaded.robot)
    q = np.random.default_rng(0).uniform(-2 * PI, 2 * PI, size=(N_SAMPLES, reference.n_joints))
    return poekin.load(loaded, frame), q, mujoco_poses(loaded.model, reference, q)


@pytest.mark.parametrize("convention", CONVENTIONS)
@pytest.mark.parametrize(("source", "frame"), MENAGERIE_CHAINS)
def test_menagerie_dh_matches_mj_forward(source: str, frame: str | None, convention: str) -> None:
    chain, q, T_ref = menagerie_case(source, frame)
    table = dh_from_chain(chain, convention)  # type: ignore[arg-type]
    pos, ori = pose_errors(T_ref, table.fk(q))
    pos_tol = LITE6_POS_TOL if source == "ufactory_lite6" else MENAGERIE_POS_TOL
    assert pos.max() <= pos_tol, f"{source} {convention}: position error {pos.max():.3e} m"
    assert ori.max() <= MENAGERIE_ORI_TOL, f"{source} {convention}: angle {ori.max():.3e} rad"
    if source == "ufactory_lite6":
        note = (
            "joints 'joint2' and 'joint3' are nearly parallel (7.3e-06 rad): "
            "DH is ill-conditioned here (d2 = 2.73e+04 m)"
        )
        assert note in table.notes, table.notes
        # d3 = 2.73e4 m too, but joints 3 and 4 are perpendicular: d3 is large only because
        # frame 2 starts 2.7e4 m out, so there is no note about them.
        assert not any(s.startswith("joints 'joint3' and 'joint4'") for s in table.notes)


def test_ur5e_standard_table_matches_the_xml() -> None:
    """The UR5e's textbook numbers, read off universal_robots_ur5e/ur5e.xml:

    * the base body sits at the world origin (quat="0 0 0 -1", a half turn about z) and
      shoulder_link at pos="0 0 0.163" with the pan axis along z: d1 = 0.163;
    * the lift, elbow and wrist-1 joints use the class default axis="0 1 0", and the bodies
      between them only turn about y (quat="1 0 1 0"), so these three axes are parallel;
    * forearm_link sits 0.425 along the upper arm (pos="0 -0.131 0.425"): |a2| = 0.425;
    * wrist_1_link sits 0.392 along the forearm (pos="0 0 0.392"): |a3| = 0.392;
    * along those parallel axes (local y) upper_arm_link is offset by +0.138, forearm_link by
      -0.131 and wrist_2_link (whose joint turns about its z) by +0.127:
      d4 = 0.138 - 0.131 + 0.127 = 0.134.
    """
    chain, _, _ = menagerie_case("universal_robots_ur5e", None)
    table = dh_from_chain(chain, "standard")
    assert_close("|a2|", abs(table.a[1]), 0.425, 1e-12)
    assert_close("|a3|", abs(table.a[2]), 0.392, 1e-12)
    assert_close("d1", table.d[0], 0.163, 1e-12)
    assert_close("d4", table.d[3], 0.134, 1e-12)
    assert table.param_names()[1] == ("a2", "alpha2", "d2", "theta2")


# --------------------------------------------------------------------------------------------
# the rest of the table API


def test_param_names_rows_and_describe() -> None:
    table = random_table(np.random.default_rng(4), "modified", 3)
    assert table.param_names() == [
        ("a0", "alpha0", "d1", "theta1"),
        ("a1", "alpha1", "d2", "theta2"),
        ("a2", "alpha2", "d3", "theta3"),
    ]
    info = table.describe()
    assert info["convention"] == "modified"
    assert [r["joint"] for r in info["rows"]] == ["joint1", "joint2", "joint3"]
    rebuilt = DHTable(
        info["convention"],
        [r["a"] for r in info["rows"]],
        [r["alpha"] for r in info["rows"]],
        [r["d"] for r in info["rows"]],
        [r["theta_offset"] for r in info["rows"]],
        tuple(r["joint_type"] for r in info["rows"]),
        base=info["base"],
        tool=info["tool"],
    )
    q = np.random.default_rng(5).uniform(-PI, PI, size=(4, 3))
    assert_close("fk of the described table", rebuilt.fk(q), table.fk(q), 0.0)
    assert "modified, 3 rows" in repr(table)
    with pytest.raises(ValueError, match="read-only"):
        table.a[0] = 1.0


# --------------------------------------------------------------------------------------------
# 5. bad input


GOOD = {
    "convention": "standard",
    "a": [0.0, 0.1, 0.2],
    "alpha": [PI / 2, 0.0, 0.0],
    "d": [0.1, 0.0, 0.0],
    "theta_offset": [0.0, 0.0, 0.0],
    "joint_types": ("revolute", "revolute", "prismatic"),
}


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"convention": "craig"}, r"unknown DH convention 'craig'; use 'standard'"),
        ({"a": [0.0, 0.1]}, r"a must have shape \(3,\), got \(2,\)"),
        ({"theta_offset": [[0.0, 0.0, 0.0]]}, r"theta_offset must have shape \(3,\)"),
        ({"joint_names": ("a", "b")}, "3 joint types but 2 joint names"),
        ({"joint_types": ("revolute", "ball", "revolute")}, "unknown joint type 'ball'"),
        ({"d": [0.1, np.nan, 0.0]}, "d contains NaN or inf"),
        ({"alpha": [0.0, np.inf, 0.0]}, "alpha contains NaN or inf"),
        ({"base": np.diag([2.0, 1.0, 1.0, 1.0])}, "base: the rotation block is not orthonormal"),
        ({"tool": np.diag([1.0, -1.0, 1.0, 1.0])}, "tool: the rotation block is not orthonormal"),
        ({"base": np.eye(4) + np.eye(4, k=-3)}, "base: the last row must be"),
        ({"tool": np.eye(3)}, r"tool must have shape \(4, 4\)"),
    ],
)
def test_bad_table(change: dict[str, object], match: str) -> None:
    with pytest.raises(InputError, match=match):
        DHTable(**{**GOOD, **change})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("q", "match"),
    [
        ([0.0, 1.0], r"expected 3 joint values"),
        (np.zeros((2, 4)), r"expected 3 joint values .* shape \(2, 4\)"),
        ([0.0, np.nan, 0.0], "NaN or inf"),
    ],
)
def test_bad_joint_values(q: object, match: str) -> None:
    table = DHTable(**GOOD)  # type: ignore[arg-type]
    for method in (table.fk, table.link_transforms):
        with pytest.raises(InputError, match=match):
            method(q)  # type: ignore[operator]


def test_bad_convention_for_extraction() -> None:
    chain = Chain(("j",), ("revolute",), [[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]], np.eye(4))
    with pytest.raises(InputError, match=r"unknown DH convention 'dh'.*'modified' \(Craig\)"):
        dh_from_chain(chain, "dh")  # type: ignore[arg-type]


# --- issue #26: the nearest table of a calibrated arm --------------------------------------------


def test_nearest_dh_of_a_calibrated_arm() -> None:
    """UR's calibration file (axes 1 to 2 mrad from parallel): the exact table has d of hundreds
    of metres; the nearest one keeps those axes parallel (d = 0) and, fitted, is nearer the
    chain on configurations it was not fitted on than the table that only drops the tilt."""
    chain = load_params(pathlib.Path(__file__).parent / "data" / "ur" / "ur5e_calibration.yaml")
    assert isinstance(chain, Chain)
    assert np.max(np.abs(dh_from_chain(chain).d)) > 100.0
    nearest = nearest_dh(chain)
    dropped = dh_from_chain(chain, parallel_tol=NEAR_PARALLEL_SIN)
    assert nearest.d[1] == nearest.d[2] == 0.0 and np.max(np.abs(nearest.d)) < 0.2
    q = np.random.default_rng(99).uniform(-np.pi, np.pi, (2000, 6))
    pos_n, ori_n = pose_errors(chain.fk(q), nearest.fk(q))
    pos_d, ori_d = pose_errors(chain.fk(q), dropped.fk(q))

    def rms(e: np.ndarray) -> float:
        return float(np.sqrt(np.mean(e**2)))

    # the fit minimises the squares: nearer in RMS (positions most: the orientation error is the
    # in-plane tilt itself, which nothing else in the table can turn back), in the maxima too
    assert rms(pos_n) < 0.8 * rms(pos_d) and rms(ori_n) < 0.95 * rms(ori_d)
    assert np.max(pos_n) < np.max(pos_d) and np.max(ori_n) < np.max(ori_d)
    assert np.max(pos_n) < 2e-3  # millimetres: the in-plane tilt DH cannot hold


def test_nearest_dh_of_exactly_parallel_axes_is_exact() -> None:
    chain = named_params("ur5e-dh").to_chain()  # type: ignore[union-attr]
    q = np.random.default_rng(3).uniform(-np.pi, np.pi, (500, 6))
    pos, ori = pose_errors(chain.fk(q), nearest_dh(chain, "modified").fk(q))
    assert np.max(pos) < 1e-12 and np.max(ori) < 1e-12
