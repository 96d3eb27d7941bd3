"""Random MJCF kinematic trees against MuJoCo: every body and site, by tree FK and by the PoE
chain of every frame that has one.

A hypothesis strategy writes models nobody planned for: 1-4 branches of 1-12 bodies, each
branch hung off the world or off a body already made; hinge, slide, ball and free joints with
random (non-unit) axes, anchors and refs; body frames as pos with quat, euler (any sequence),
axisangle, xyaxes or zaxis, in radians or degrees; default classes with childclass; sites.
Each model is also evaluated with a randomly drawn array library (NumPy, JAX or PyTorch, those
installed; all three where ``POEKIN_REQUIRE_EXTRAS=1``), whose float64 results must equal the
NumPy path's to 1e-15 per metre of reach. ``POEKIN_FUZZ_EXAMPLES`` sets how many (200 by
default; issue #6's slow run used 5,000). A model that fails is written to
``POEKIN_FUZZ_FAILURES`` (default: a ``poekin-fuzz-failures`` folder in the system's temporary
directory) and the assertion names the file.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import pathlib
import tempfile
from collections.abc import Callable, Iterator
from typing import Any

import mujoco
import numpy as np
import pytest
from array_libs import load
from helpers import assert_close
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_tree import mj_frames

from poekin import ModelError
from poekin.io.import_mujoco import tree_from_model
from poekin.verification.verify import sample_qpos

# Issue #6's bar. Frames sit at most ~50 bodies and ~50 m from the world here, and both codes
# round at ~1e-16 relative per operation, so real agreement is ~1e-14; a wrong axis, anchor,
# sign or order is off by ~1e-3 or more.
FUZZ_TOL = 1e-12
EXAMPLES = int(os.environ.get("POEKIN_FUZZ_EXAMPLES", "200"))
QPOS_PER_MODEL = 16
# JAX / PyTorch vs the NumPy path: as tests/test_arrays.py, per metre the frames reach.
LIB_TOL = 1e-15
LIBRARIES = ["numpy"] + [
    name
    for name in ("jax", "torch")
    if os.environ.get("POEKIN_REQUIRE_EXTRAS") == "1" or importlib.util.find_spec(name) is not None
]
FAILURES = pathlib.Path(
    os.environ.get(
        "POEKIN_FUZZ_FAILURES", pathlib.Path(tempfile.gettempdir()) / "poekin-fuzz-failures"
    )
)

_coord = st.floats(-1.0, 1.0, allow_nan=False, width=64)
_vec3 = st.tuples(_coord, _coord, _coord)
_axis = _vec3.filter(lambda v: float(np.linalg.norm(v)) > 0.1)  # MuJoCo refuses ~0 axes
EULER_SEQS = ["xyz", "XYZ", "zyx", "ZYX", "xzx", "ZXZ", "yxz"]


def _nums(values: tuple[float, ...] | list[float]) -> str:
    return " ".join(repr(float(v)) for v in values)


@st.composite
def _orientation(draw: st.DrawFn, degrees: bool) -> str:
    """A body or site frame's orientation attribute, or none."""
    kind = draw(st.sampled_from(["", "quat", "euler", "axisangle", "xyaxes", "zaxis"]))
    turn = st.floats(-180.0, 180.0) if degrees else st.floats(-np.pi, np.pi)
    if kind == "quat":  # unnormalised: MuJoCo normalises it
        q = draw(
            st.tuples(_coord, _coord, _coord, _coord).filter(lambda v: np.linalg.norm(v) > 0.1)
        )
        return f'quat="{_nums(q)}"'
    if kind == "euler":
        return f'euler="{_nums(draw(st.tuples(turn, turn, turn)))}"'
    if kind == "axisangle":
        return f'axisangle="{_nums([*draw(_axis), draw(turn)])}"'
    if kind == "xyaxes":
        x = draw(_axis)
        y = draw(_axis.filter(lambda v: np.linalg.norm(np.cross(x, v)) > 0.1 * np.linalg.norm(v)))
        return f'xyaxes="{_nums([*x, *y])}"'
    if kind == "zaxis":
        return f'zaxis="{_nums(draw(_axis))}"'
    return ""


@st.composite
def _joint_kinds(draw: st.DrawFn, free_ok: bool) -> list[str]:
    """0-2 joint types for one body, in an order MuJoCo takes: a free joint alone, and no
    rotation after a ball joint."""
    n = draw(st.sampled_from([0, 1, 1, 1, 1, 2]))
    kinds = ["hinge", "hinge", "hinge", "slide", "ball"] + (["free"] if free_ok and n == 1 else [])
    drawn = [draw(st.sampled_from(kinds)) for _ in range(n)]
    if n == 2 and "ball" in drawn:  # a hinge beside a ball would repeat one of its rotations
        drawn = ["slide", "ball"]
    return drawn


@st.composite
def _joint(draw: st.DrawFn, name: str, kind: str, degrees: bool, own_axis: bool) -> str:
    """One joint; ``own_axis``: never the class default's axis (a body's second joint, which
    would otherwise repeat its first one's freedom)."""
    if kind == "free":
        return f'<joint name="{name}" type="free"/>'
    attrs = [f'name="{name}"', f'type="{kind}"', f'pos="{_nums(draw(_vec3))}"']
    if kind in ("hinge", "slide"):
        if own_axis or draw(st.booleans()):  # else the class default's axis
            attrs.append(f'axis="{_nums(draw(_axis))}"')
        ref = draw(st.floats(-90.0, 90.0) if degrees and kind == "hinge" else st.floats(-1.5, 1.5))
        attrs.append(f'ref="{ref!r}"')
    return f"<joint {' '.join(attrs)}/>"


@st.composite
def mjcf_trees(draw: st.DrawFn) -> str:
    """An MJCF model: a random kinematic tree with every compile-time feature MuJoCo resolves."""
    degrees = draw(st.booleans())
    parents: list[int] = []  # parent body of each body (-1: the world)
    for _ in range(draw(st.integers(1, 4))):
        parent = draw(st.integers(-1, len(parents) - 1))
        for _ in range(draw(st.integers(1, 12))):
            parents.append(parent)
            parent = len(parents) - 1
    n = len(parents)
    heads, tails = [], []
    for b, parent in enumerate(parents):
        kinds = draw(_joint_kinds(free_ok=parent < 0))
        joints = [
            draw(_joint(f"j{b}_{k}", kind, degrees, own_axis=len(kinds) > 1))
            for k, kind in enumerate(kinds)
        ]
        child_class = ' childclass="arm"' if draw(st.integers(0, 3)) == 0 else ""
        frame = draw(_orientation(degrees))
        heads.append(
            f'<body name="b{b}" pos="{_nums(draw(_vec3))}" {frame}{child_class}>'
            '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>' + "".join(joints)
        )
        tails.append("</body>")
    sites = [[] for _ in range(n + 1)]  # index 0: the world
    for s in range(draw(st.integers(0, 4))):
        on = draw(st.integers(0, n))
        sites[on].append(
            f'<site name="s{s}" pos="{_nums(draw(_vec3))}" {draw(_orientation(degrees))}/>'
        )

    def body_xml(b: int) -> str:
        children = "".join(body_xml(c) for c in range(n) if parents[c] == b)
        return heads[b] + "".join(sites[b + 1]) + children + tails[b]

    world = "".join(sites[0]) + "".join(body_xml(b) for b in range(n) if parents[b] < 0)
    default_axis = _nums(draw(_axis))
    arm_anchor = _nums(draw(_vec3))
    return (
        f'<mujoco><compiler angle="{"degree" if degrees else "radian"}" '
        f'eulerseq="{draw(st.sampled_from(EULER_SEQS))}"/>'
        f'<default><joint axis="{default_axis}"/>'
        f'<default class="arm"><joint pos="{arm_anchor}"/></default></default>'
        f"<worldbody>{world}</worldbody></mujoco>"
    )


@pytest.fixture(autouse=True, scope="module")
def _mujoco_warnings_kept_in_memory() -> Iterator[list[str]]:
    """MuJoCo appends warnings (a random model's mass matrix may be near singular, which is
    no matter for kinematics) to MUJOCO_LOG.TXT in the working directory: keep them here."""
    kept: list[str] = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(kept.append)
    yield kept
    mujoco.set_mju_user_warning(previous)


def _save(xml: str, folder: pathlib.Path = FAILURES) -> pathlib.Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"model-{hashlib.sha256(xml.encode()).hexdigest()[:12]}.xml"
    path.write_text(xml)
    return path


def _in(library: str) -> tuple[Callable[[np.ndarray], Any], Callable[[Any], np.ndarray]]:
    """To and from ``library``'s float64 arrays (identity for NumPy)."""
    if library == "numpy":
        return (lambda x: x), np.asarray
    lib = load(library)
    return lib.asarray, lib.numpy


def _check(xml: str, seed: int, library: str = "numpy") -> None:
    model = mujoco.MjModel.from_xml_string(xml)
    tree = tree_from_model(model)
    qpos = sample_qpos(tree, QPOS_PER_MODEL, seed=seed)
    expected = mj_frames(model, qpos)
    got = tree.fk(qpos)
    to, back = _in(library)
    tol = LIB_TOL * max(1.0, float(np.abs(got[..., :3, 3]).max()))
    if library != "numpy":
        assert_close(f"{library} tree.fk", back(tree.fk(to(qpos))), got, tol)
    for f, name in enumerate(tree.frame_names):
        assert_close(f"tree.fk {name}", got[:, f], expected[:, f], FUZZ_TOL)
        try:
            chain = tree.chain(name)
        except ModelError:  # a ball or free joint on the path: no PoE chain
            continue
        q = qpos[:, list(chain.qpos_indices or ())]
        for method in ("fk", "fk_body"):
            T = getattr(chain, method)(q)
            assert_close(f"chain.{method} {name}", T, expected[:, f], FUZZ_TOL)
            if library != "numpy":
                got_lib = back(getattr(chain, method)(to(q)))
                assert_close(f"{library} chain.{method} {name}", got_lib, T, 2 * tol)


@pytest.mark.slow
@settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(xml=mjcf_trees(), seed=st.integers(0, 2**32 - 1), library=st.sampled_from(LIBRARIES))
def test_random_models_match_mj_kinematics(xml: str, seed: int, library: str) -> None:
    try:
        _check(xml, seed, library)
    except AssertionError as e:
        where = f"{_save(xml)} (qpos seed {seed}, {library})"
        raise AssertionError(f"{e}\nthe model is saved in {where}") from e


def test_a_failing_model_is_saved(tmp_path: pathlib.Path) -> None:
    """The file the fuzz test names on failure holds the model."""
    path = _save("<mujoco/>", tmp_path / "failures")
    assert path.parent == tmp_path / "failures" and path.read_text() == "<mujoco/>"
