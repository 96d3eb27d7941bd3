"""``poekin ik ROBOT --targets FILE.json``: many frames at once (:mod:`poekin.wholebody`).

The file is one JSON object, frame name to target, in the world frame: seven numbers ``[x,
y, z, qw, qx, qy, qz]`` (m, a unit quaternion w first) for a pose, three ``[x, y, z]`` for a
point (that frame is then placed by position only), or a 4x4 matrix as a list of rows.
``"com"`` names the centre of mass (three numbers). ``--hold A,B`` names the frames met
exactly; ``--qpos`` the start (default ``qpos0``). The answer is one JSON object on stdout:
``qpos`` (MuJoCo's layout, named by ``qpos_names``), ``success``, per-frame errors, iterations
and attempts. Exit 0 when every frame is within tolerance, 1 when not, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from poekin.chain import QUAT_TOL
from poekin.cli._args import EXIT_FAIL, JointSpace, model_source, read_values
from poekin.cli._fk import tree_base
from poekin.errors import InputError

__all__ = ["check_targets_args", "run_targets"]

FloatArray = NDArray[np.float64]

_NOT_WITH = (
    ("--pose", "pose"),
    ("--input", "input"),
    ("--all", "all"),
    ("--q0", "q0"),
    ("--frame", "frame"),
    ("--params", "params"),
    ("--tool", "tool"),
    ("--position-only", "position_only"),
)


def _names(text: str | None) -> set[str]:
    return set() if not text else {n.strip() for n in text.split(",") if n.strip()}


def check_targets_args(args: argparse.Namespace) -> None:
    """The options ``--targets`` takes and those it does not, before anything is read."""
    if args.targets is None:
        for flag, value in (("--hold", args.hold), ("--posture", args.posture)):
            if value is not None:
                raise InputError(f"{flag} goes with --targets FILE.json (many frames at once)")
        return
    given = [flag for flag, name in _NOT_WITH if getattr(args, name) not in (None, False, [])]
    if given:
        raise InputError(
            f"--targets places every frame the file names: it takes no {', '.join(given)} "
            "(a frame is placed by position only when its target is three numbers)"
        )
    if args.posture is not None and not (math.isfinite(args.posture) and args.posture >= 0):
        raise InputError(f"--posture must be a weight >= 0, got {args.posture}")


def _target(name: str, value: Any, where: str) -> FloatArray:
    arr = None
    if _numbers(value):
        try:
            arr = np.asarray(value, dtype=np.float64)
        except ValueError:  # rows of different lengths
            arr = None
    if arr is None or arr.shape not in ((3,), (7,), (4, 4)) or not np.all(np.isfinite(arr)):
        raise InputError(
            f"{where}: the target of {name!r} must be 7 numbers [x, y, z, qw, qx, qy, qz], "
            "3 numbers [x, y, z] (position only) or a 4x4 matrix (a list of 4 rows), all finite"
        )
    if arr.shape == (7,):
        norm = float(np.linalg.norm(arr[3:]))
        if abs(norm - 1.0) > QUAT_TOL:
            raise InputError(
                f"{where}: the quaternion of {name!r} has norm {norm:.6g}; a unit quaternion "
                "(w first) is needed"
            )
        from poekin import lie

        T = np.eye(4)
        T[:3, :3] = lie.quat_to_rotation(arr[3:] / norm)
        T[:3, 3] = arr[:3]
        return T
    return arr


def _numbers(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, int | float):
        return True
    return isinstance(value, list) and all(_numbers(v) for v in value)


def _read(path: str) -> dict[str, FloatArray]:
    file = pathlib.Path(path)
    if not file.is_file():
        raise InputError(f"--targets {path}: no such file")
    try:
        data = json.loads(file.read_text())
    except json.JSONDecodeError as e:
        raise InputError(
            f"--targets {path}: not JSON ({e.msg} at line {e.lineno}, column {e.colno})"
        ) from None
    except UnicodeDecodeError:
        raise InputError(f"--targets {path}: not a text file") from None
    if not isinstance(data, dict) or not data:
        raise InputError(
            f"--targets {path}: the file must hold one JSON object, frame name to target, e.g. "
            '{"left_foot": [0, 0.1, 0, 1, 0, 0, 0]}'
        )
    return {name: _target(name, value, f"--targets {path}") for name, value in data.items()}


def run_targets(args: argparse.Namespace, out: TextIO) -> int:
    """``poekin ik --targets``: solve, print the JSON answer, the exit code."""
    from poekin.io.loading import load_tree

    targets = _read(args.targets)
    base = tree_base(args)
    tree = load_tree(model_source(args, None), base=base)
    space = JointSpace.of_tree(tree)
    qpos = tree.qpos0
    if args.qpos is not None:
        qpos = read_values(args.qpos, space, args.deg, "--qpos")
    points = {n for n, T in targets.items() if T.shape == (3,)}
    options: dict[str, Any] = {
        name: value
        for name, value in (
            ("seed", args.seed),
            ("pos_tol", args.pos_tol),
            ("ori_tol", args.ori_tol),
            ("posture", args.posture),
        )
        if value is not None
    }
    found = tree.ik(
        targets, qpos, hold=_names(args.hold), position_only=points - {"com"}, **options
    )
    q = np.array(found.qpos)
    revolute = [
        int(tree.qpos_adr[k])
        for k, (t, m) in enumerate(zip(tree.joint_types, tree.mimics, strict=True))
        if t == "revolute" and m is None
    ]
    if args.deg:
        q[revolute] = np.degrees(q[revolute])
    answer = {
        "robot": tree.robot,
        "success": bool(found.success),
        "qpos": [float(v) for v in q],
        "qpos_names": list(tree.qpos_names()),
        "units": "deg" if args.deg else "rad",
        "held": sorted(_names(args.hold)),
        "frame_errors": {
            name: {"pos_err": float(pos), "ori_err": float(ori)}
            for name, (pos, ori) in found.frame_errors.items()
        },
        "iterations": int(found.iterations),
        "attempts": int(found.attempts),
    }
    out.write(json.dumps(answer, indent=2) + "\n")
    return 0 if found.success else EXIT_FAIL
