"""Shared test helpers: tolerances with their reasons, and an assert that names the field."""

from __future__ import annotations

import importlib
import os
import pathlib
import warnings
from typing import Any

import mujoco
import numpy as np
import pytest
from numpy.typing import ArrayLike

import poekin
from poekin import lie
from poekin.io.sources import LoadedModel
from poekin.tree import Tree

# PoE vs mj_forward. Both codes round to ~3e-15 m on the UR5e at |q| <= 2 pi (measured against
# a 40-digit mpmath product), and error grows with the number of joints and the robot's size;
# 1e-13 is a bound that is a property of both codes rather than of one sample: issue #2's bar.
MJ_TOL = 1e-13


# `poekin verify --json` keys, in order: issue #2's, then issue #15's.
SUMMARY_KEYS = [
    "robot",
    "frame",
    "samples",
    "seed",
    "max_pos_err_m",
    "median_pos_err_m",
    "max_ori_err_rad",
    "median_ori_err_rad",
    "passed",
    # issue #15: every figure the table prints, what was checked, and how
    "params",
    "pos_tol",
    "ori_tol",
    "sample_range",
    "methods",
    "model_file",
    "model_origin",
]


def assert_close(field: str, actual: ArrayLike, expected: ArrayLike, atol: float) -> None:
    """Assert equal shapes and ``max |actual - expected| <= atol``; the message names ``field``
    and the worst index. NaN anywhere fails."""
    a, e = np.asarray(actual), np.asarray(expected)
    assert a.shape == e.shape, f"{field}: shape {a.shape} != expected {e.shape}"
    err = np.abs(a.astype(np.float64) - e.astype(np.float64))
    worst = float(np.max(err)) if err.size else 0.0
    if not worst <= atol:  # also fails on NaN
        where = np.unravel_index(int(np.nanargmax(err)), err.shape) if err.size else ()
        raise AssertionError(f"{field}: max abs error {worst:.3e} > atol {atol:.1e} at {where}")


def ur5e_obstacles() -> list[Any]:
    """A table under the UR5e's reach, a post beside it and a ball held by its tool: every
    kind of obstacle placement (world, world, a frame) the collision tests measure."""
    from poekin.collision import Box, Capsule, Sphere

    return [
        Box([0.3, 0.4, 0.02], pose=[-0.55, 0.0, -0.02, 1.0, 0.0, 0.0, 0.0], name="table"),
        Capsule(0.05, 0.3, pose=[0.4, 0.3, 0.3, 1.0, 0.0, 0.0, 0.0], name="post"),
        Sphere(0.03, pose=[0.0, 0.0, 0.06, 1.0, 0.0, 0.0, 0.0], frame="attachment_site"),
    ]


def load_quiet(source: str) -> LoadedModel:
    """Load a model, silencing the kinematics-only note for XML-only Menagerie folders."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load_model(source)


def mj_frame_pose(model: mujoco.MjModel, data: mujoco.MjData, kind: str, fid: int) -> np.ndarray:
    """``(4, 4)`` pose of a site or body from ``data`` (after mj_forward)."""
    T = np.eye(4)
    if kind == "site":
        T[:3, :3] = data.site_xmat[fid].reshape(3, 3)
        T[:3, 3] = data.site_xpos[fid]
    else:
        T[:3, :3] = data.xmat[fid].reshape(3, 3)
        T[:3, 3] = data.xpos[fid]
    return T


def mj_pose(model: mujoco.MjModel, qpos: np.ndarray, frame: str) -> np.ndarray:
    """``(N, 4, 4)`` poses of a site or body from mj_forward, for ``(N, nq)`` qpos."""
    data = mujoco.MjData(model)
    fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
    kind = "site" if fid >= 0 else "body"
    if fid < 0:
        fid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
    out = np.empty((len(qpos), 4, 4))
    for k, row in enumerate(qpos):
        data.qpos[:] = row
        mujoco.mj_forward(model, data)
        out[k] = mj_frame_pose(model, data, kind, fid)
    return out


def pinocchio_q(model: Any, tree: Tree, qpos: np.ndarray) -> np.ndarray:
    """``(n, model.nq)``: Pinocchio's configuration for the tree's ``qpos``, joint by joint
    (by name; ``root_joint`` is the floating base). Mimic followers are joints of their own
    (Pinocchio's default), set from their leaders. A continuous joint is ``cos, sin``; a free
    joint ``x y z qx qy qz qw`` relative to its ``<origin>`` (which poekin and MuJoCo fold into
    qpos: their qpos is the world pose)."""
    full = tree.full_qpos(qpos)
    q = np.zeros((len(qpos), model.nq))
    for j in range(1, model.njoints):
        name, joint = model.names[j], model.joints[j]
        k = 0 if name == "root_joint" else tree.joint_names.index(name)
        a, i = tree.full_qpos_adr[k], joint.idx_q
        if joint.nq == 7:
            T = np.tile(np.eye(4), (len(qpos), 1, 1))
            T[:, :3, 3] = full[:, a : a + 3]
            T[:, :3, :3] = lie.quat_to_rotation(lie.quat_normalize(full[:, a + 3 : a + 7]))
            local = np.linalg.inv(model.jointPlacements[j].homogeneous) @ T
            wxyz = lie.rotation_to_quat(local[:, :3, :3])
            q[:, i : i + 3], q[:, i + 3 : i + 6], q[:, i + 6] = (
                local[:, :3, 3],
                wxyz[:, 1:],
                wxyz[:, 0],
            )
        elif joint.nq == 2:
            q[:, i], q[:, i + 1] = np.cos(full[:, a]), np.sin(full[:, a])
        else:
            q[:, i] = full[:, a]
    return q


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """``poekin ARGV...`` in this process: the exit code, stdout and stderr."""
    from poekin.cli import main

    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_error_line(err: str, message: str) -> None:
    """stderr holds exactly one error line (plus, at most, notes) and no traceback."""
    lines = err.splitlines()
    errors = [ln for ln in lines if ln.startswith("poekin: error: ")]
    assert len(errors) == 1 and message in errors[0], err
    assert all(ln.startswith("poekin: note: ") for ln in lines if ln not in errors), err
    assert "Traceback" not in err


def import_extra(module: str) -> Any:
    """``module`` (JAX, PyTorch, array-api-compat), or skip the test without it; with
    ``POEKIN_REQUIRE_EXTRAS=1`` (CI) a missing one fails instead, so the array-library tests
    cannot silently not run."""
    if os.environ.get("POEKIN_REQUIRE_EXTRAS") == "1":
        return importlib.import_module(module)
    return pytest.importorskip(module)


def drawn_text_boxes(fig: Any) -> list[tuple[Any, Any]]:
    """``(text, display box)`` of every text a draw of ``fig`` renders (its box included),
    recorded as it is drawn: a tick label out of view, which exists but is not drawn, is not
    counted, and a 3-D text has its extent where it was drawn (it moves back to its 3-D
    coordinates after)."""
    from matplotlib.text import Text
    from matplotlib.transforms import Bbox

    renderer = fig.canvas.get_renderer()
    drawn: dict[int, tuple[Any, Any]] = {}
    original = Text.draw

    def record(self: Any, renderer: Any) -> Any:
        if self.get_visible() and self.get_text().strip() and id(self) not in drawn:
            box = self.get_window_extent(renderer)
            patch = self.get_bbox_patch()
            if patch is not None:
                self.update_bbox_position_size(renderer)
                box = Bbox.union([box, patch.get_window_extent(renderer)])
            drawn[id(self)] = (self, box)
        return original(self, renderer)

    Text.draw = record  # type: ignore[method-assign]
    try:
        fig.draw(renderer)
    finally:
        Text.draw = original  # type: ignore[method-assign]
    return list(drawn.values())


def assert_labels_apart(fig: Any) -> None:
    """No two labels (the texts of the axes: joint tags, screw labels, findings, boxes) overlap,
    and none overlaps another drawn text (a tick or axis label, a title, the legend), with
    matplotlib's own extents (``Text.get_window_extent``); every label is inside the figure."""
    boxes = drawn_text_boxes(fig)
    labels = {id(t) for ax in fig.axes for t in ax.texts}
    whole = fig.bbox
    for i, (a, box_a) in enumerate(boxes):
        if id(a) not in labels:
            continue
        assert whole.x0 <= box_a.x0 and box_a.x1 <= whole.x1, f"{a.get_text()!r} leaves the figure"
        assert whole.y0 <= box_a.y0 and box_a.y1 <= whole.y1, f"{a.get_text()!r} leaves the figure"
        for j, (b, box_b) in enumerate(boxes):
            if j != i and (id(b) not in labels or j > i):
                assert not box_a.overlaps(box_b), f"{a.get_text()!r} overlaps {b.get_text()!r}"


def mesh_menagerie() -> pathlib.Path:
    """A Menagerie clone with the UR5e's meshes, for the few tests that draw or hash them
    (poekin's built-in copies in src/poekin/data are XML only): ``POEKIN_MESH_MENAGERIE`` if
    set, else ``../shared/menagerie`` beside the checkout. Without one the test skips, saying
    how to enable it; with ``POEKIN_REQUIRE_MESHES=1`` (CI) it fails instead."""
    root = pathlib.Path(__file__).resolve().parents[1]
    folder = pathlib.Path(
        os.environ.get("POEKIN_MESH_MENAGERIE") or root.parent / "shared" / "menagerie"
    )
    if (folder / "universal_robots_ur5e" / "assets" / "base_0.obj").is_file():
        return folder
    why = (
        f"needs the UR5e's meshes, not found under {folder}: set POEKIN_MESH_MENAGERIE to a "
        "mujoco_menagerie clone with them"
    )
    if os.environ.get("POEKIN_REQUIRE_MESHES") == "1":
        pytest.fail(f"{why} (POEKIN_REQUIRE_MESHES=1)")
    pytest.skip(why)
