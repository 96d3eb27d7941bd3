"""``poekin fk`` and ``poekin jacobian``: poses and Jacobians for joint values.

Both speak one vocabulary for what ``q`` is and which frame is meant:

* by default ``q`` holds the joint values of the chain from the world to ``--frame`` (the model's
  only site if not given); ``--params`` gives that chain as a parameter set instead;
* ``--tree``: ``q`` is the whole model's ``qpos`` (MuJoCo's layout, free and ball joints
  included), and ``--frame`` is any body or site; ``--all-frames`` gives every one of them, and
  ``--relative-to A`` a frame's pose (or Jacobian) in frame ``A`` (both imply ``--tree``).

``fk --form`` says how a pose is written: its 4 x 4 matrix, ``pos_quat`` (x y z, then the
quaternion w x y z) or ``xyz_rpy`` (x y z, then roll pitch yaw in URDF's fixed-axis convention,
``R = Rz(yaw) Ry(pitch) Rx(roll)``: :func:`poekin.lie.rotation_to_rpy`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np
from numpy.typing import NDArray

from poekin.cli._args import (
    JointSpace,
    add_floating_base,
    add_joint_values,
    add_params,
    add_placement,
    add_source,
    model_source,
    place,
    placement,
    read_joint_values,
)
from poekin.cli._describe import params_or_chain
from poekin.cli._text import fixed, matrix_lines, table
from poekin.errors import InputError

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = ["end_chain", "register", "tree_base"]

FloatArray = NDArray[np.float64]
_ROWS = ("wx", "wy", "wz", "vx", "vy", "vz")


@dataclasses.dataclass(frozen=True)
class _Target:
    """What a command evaluates: ``evaluate(q)`` for joint values in ``space``; ``frames`` the
    frames of the result (one, or every frame of a tree along axis -3); ``columns`` the
    Jacobian's columns; ``reference`` the frame the poses are in."""

    evaluate: Callable[[FloatArray], FloatArray]
    space: JointSpace
    frames: tuple[str, ...]
    many: bool = False
    columns: tuple[str, ...] = ()
    reference: str = "world"


def _tree_mode(args: argparse.Namespace) -> bool:
    return bool(
        args.tree or getattr(args, "all_frames", False) or getattr(args, "relative_to", None)
    )


def _load_tree(args: argparse.Namespace) -> Tree:
    from poekin.io.loading import load_tree

    if args.params:
        raise InputError(
            "--tree, --all-frames and --relative-to take the whole model from SOURCE, not --params"
        )
    base = tree_base(args)  # said before the model is read
    return load_tree(model_source(args, None), floating_base=args.floating_base, base=base)


def tree_base(args: argparse.Namespace) -> FloatArray | None:
    """``--base`` for a whole model; ``--tool`` has no place there (it rides on one chain)."""
    base, tool = placement(args)
    if tool is not None:
        raise InputError(
            "--tool mounts a tool on the end frame of a chain; --tree, --all-frames and "
            "--relative-to pose the model's own bodies and sites: drop --tool, or drop those"
        )
    return base


def end_chain(args: argparse.Namespace) -> Any:
    """The chain (or DH table) to the frame, refusing a frame behind a ball or free joint with
    the way to pose it (``--tree``); ``poekin ik`` solves it too."""
    if getattr(args, "floating_base", False):
        raise InputError("--floating-base gives a whole model's qpos: pass --tree too")
    placement(args)  # a bad --base or --tool is said before the model is read
    if args.params:
        return place(params_or_chain(args), args)
    from poekin.io.loading import default_frame, load_tree

    tree = load_tree(model_source(args, None))
    frame = args.frame if args.frame is not None else default_frame(tree)
    for k in tree.path_joints(frame):
        kind = tree.joint_types[k]
        if kind in ("ball", "free"):
            raise InputError(
                f"{frame!r} sits behind the {kind} joint {tree.joint_names[k]!r}, which a chain "
                f"of hinges and slides cannot hold: pass --tree, with which q is the whole qpos "
                f"({tree.nq} values: {tree.qpos_layout()})"
            )
    return place(tree.chain(frame), args)


def _fk_target(args: argparse.Namespace) -> _Target:
    if not _tree_mode(args):
        chain = end_chain(args)
        return _Target(chain.fk, JointSpace.of(chain), (chain.frame,))
    from poekin import lie
    from poekin.io.loading import default_frame

    tree = _load_tree(args)
    if args.all_frames and args.frame:
        raise InputError("--all-frames poses every frame: drop --frame, or drop --all-frames")
    frames = tree.frame_names if args.all_frames else (args.frame or default_frame(tree),)
    index = [tree.frame_index(f) for f in frames]
    relative = None if args.relative_to is None else tree.frame_index(args.relative_to)

    def fk(qpos: FloatArray) -> FloatArray:
        T_all = tree.fk(qpos)
        T: FloatArray = T_all[..., index, :, :]
        if relative is not None:
            T = np.asarray(lie.inverse(T_all[..., relative, None, :, :]) @ T)
        return T if args.all_frames else T[..., 0, :, :]

    reference = args.relative_to or "world"
    return _Target(fk, JointSpace.of_tree(tree), frames, args.all_frames, reference=reference)


def _jacobian_target(args: argparse.Namespace) -> _Target:
    convention = args.convention
    if not _tree_mode(args):
        from poekin.chain import Chain

        chain = end_chain(args)
        if not isinstance(chain, Chain):
            chain = chain.to_chain()
        method = getattr(chain, f"jacobian_{convention}")
        return _Target(method, JointSpace.of(chain), (chain.frame,), columns=chain.joint_names)
    from poekin.io.loading import default_frame

    tree = _load_tree(args)
    if args.all_frames and args.frame:
        raise InputError("--all-frames gives every frame: drop --frame, or drop --all-frames")
    frames = tree.frame_names if args.all_frames else (args.frame or default_frame(tree),)
    for f in (*frames, *([args.relative_to] if args.relative_to else [])):
        tree.frame_index(f)  # an unknown frame is said now, before q is read

    def jacobian(qpos: FloatArray) -> FloatArray:
        Js = [tree.jacobian(qpos, f, convention, relative_to=args.relative_to) for f in frames]
        return np.stack(Js, axis=-3) if args.all_frames else Js[0]

    return _Target(
        jacobian,
        JointSpace.of_tree(tree),
        frames,
        args.all_frames,
        columns=tree.dof_names(),
        reference=args.relative_to or "world",
    )


def _check_q_args(args: argparse.Namespace, result: str) -> None:
    """``--q`` or ``--input`` (one of them); ``--input`` with ``--output``, a new file of a
    known format; ``--json`` only with ``--q``. Checked before any model is loaded."""
    from poekin.io.fileio import array_format, check_new_file

    if args.q is not None and args.input is not None:
        raise InputError(
            "both --q and --input were given; give one: --q Q1 ... Qn for one configuration, "
            "or --input FILE for a batch"
        )
    if args.q is None and args.input is None:
        raise InputError("give joint values with --q Q1 ... Qn, or a batch with --input FILE")
    if args.input is not None:
        array_format(args.input, "--input")
        if args.output is None:
            raise InputError(
                f"--input needs --output FILE (.npy, .npz, .csv, .txt) for the {result}"
            )
        if args.json:
            raise InputError(
                "--json prints the result of one --q; a batch from --input goes to --output FILE"
            )
    if args.output is not None:
        if args.input is None:
            raise InputError("--output goes with --input FILE")
        array_format(args.output, "--output")
        check_new_file(args.output, result, force=args.force)


def _save(
    args: argparse.Namespace,
    result: FloatArray,
    what: str,
    name: str,
    columns: list[str],
    extras: dict[str, Any],
    out: TextIO,
) -> None:
    from poekin.io.fileio import write_array

    write_array(args.output, result, name=name, columns=columns, extras=extras, what=what)
    print(f"{what} {name} of shape {result.shape} written to {args.output}", file=out)


# --- fk ---------------------------------------------------------------------------------------


_FORM_CELLS = {
    "matrix": tuple(f"T{r}{c}" for r in range(4) for c in range(4)),
    "pos_quat": ("x", "y", "z", "qw", "qx", "qy", "qz"),
    "xyz_rpy": ("x", "y", "z", "roll", "pitch", "yaw"),
}


def _in_form(T: FloatArray, form: str) -> FloatArray:
    """``(..., 4, 4)`` poses as ``form``: themselves, ``(..., 7)`` or ``(..., 6)``."""
    from poekin import lie

    if form == "matrix":
        return T
    R = T[..., :3, :3]
    turn = lie.rotation_to_quat(R) if form == "pos_quat" else lie.rotation_to_rpy(R)
    return np.concatenate([T[..., :3, 3], turn], axis=-1)


def _form_lines(pose: FloatArray, form: str, precision: int) -> list[str]:
    """One pose in ``form`` as aligned, labelled lines."""
    if form == "matrix":
        return matrix_lines(pose, precision)
    label = "quat [wxyz]" if form == "pos_quat" else "rpy [rad]"
    rows = [["xyz [m]", *(fixed(x, precision) for x in pose[:3])]]
    rows.append([label, *(fixed(x, precision) for x in pose[3:])])
    return table(rows)


def _cmd_fk(args: argparse.Namespace, out: TextIO) -> int:
    _check_q_args(args, "poses")
    target = _fk_target(args)
    q = read_joint_values(args, target.space)
    T = _in_form(target.evaluate(q), args.form)
    frames = target.frames
    ref = target.reference
    name = "T" if args.form == "matrix" else args.form
    if args.input is not None:
        cells = _FORM_CELLS[args.form]
        columns = [f"{f}.{c}" for f in frames for c in cells] if target.many else list(cells)
        _save(args, T, "poses", name, columns, {"frames": frames}, out)
        if target.many:
            print(
                f"frames (axis {-3 if args.form == 'matrix' else -2}): {', '.join(frames)}",
                file=out,
            )
        return 0
    poses = T if target.many else T[None]
    if args.json:
        named = {f: poses[k].tolist() for k, f in enumerate(frames)}
        body = {"frames": named} if target.many else {"frame": frames[0], name: named[frames[0]]}
        extra = {"relative_to": ref} if ref != "world" else {}
        form = {"form": args.form} if args.form != "matrix" else {}
        print(json.dumps({**body, **extra, **form, "q": list(args.q), "deg": args.deg}), file=out)
        return 0
    for k, f in enumerate(frames):
        print(f"T_{ref}_{f} =", file=out)
        print("\n".join(_form_lines(poses[k], args.form, args.precision)), file=out)
    return 0


# --- jacobian ----------------------------------------------------------------------------------


def _jacobian_rows(convention: str, reference: str) -> str:
    """What the rows of a Jacobian are, in words."""
    if convention == "world":
        where = "world" if reference == "world" else repr(reference)
        return f"[w; v_frame] in {where} coordinates"
    return "[w; v]"


def _cmd_jacobian(args: argparse.Namespace, out: TextIO) -> int:
    _check_q_args(args, "Jacobians")
    target = _jacobian_target(args)
    q = read_joint_values(args, target.space)
    J = target.evaluate(q)
    frames, columns, ref = target.frames, target.columns, target.reference
    if args.input is not None:
        cells = [f"{r}:{c}" for r in _ROWS for c in columns]
        if target.many:
            cells = [f"{f}.{cell}" for f in frames for cell in cells]
        extras = {"columns": columns, **({"frames": frames} if target.many else {})}
        _save(args, J, "Jacobians", "J", cells, extras, out)
        if target.many:
            print(f"frames (axis -3): {', '.join(frames)}", file=out)
        return 0
    per_frame = J if target.many else J[None]
    if args.json:
        named = {f: per_frame[k].tolist() for k, f in enumerate(frames)}
        body = {"frames": named} if target.many else {"frame": frames[0]}
        extra = {"relative_to": ref} if ref != "world" else {}
        head = {**body, **extra, "convention": args.convention, "q": list(args.q)}
        tail = {"J": named[frames[0]]} if not target.many else {}
        print(json.dumps({**head, "deg": args.deg, "columns": list(columns), **tail}), file=out)
        return 0
    rows = _jacobian_rows(args.convention, ref)
    relative = f" relative to {ref!r}" if ref != "world" else ""
    for k, f in enumerate(frames):
        size = f"6 x {per_frame.shape[-1]}"
        print(f"J_{args.convention} of {f!r}{relative} ({size}), rows {rows}", file=out)
        if k == 0:
            print(f"columns: {', '.join(columns)}", file=out)
        print("\n".join(matrix_lines(per_frame[k], args.precision)), file=out)
    return 0


def _frame_options(p: argparse.ArgumentParser, what: str) -> None:
    """The frame options of fk and jacobian: ``--tree``, ``--floating-base``, ``--all-frames``
    and ``--relative-to``; ``what`` is what each frame gets (``"pose"``)."""
    _tree_options(p)
    p.add_argument(
        "--all-frames",
        action="store_true",
        help=f"the {what} of every body and site (implies --tree)",
    )
    p.add_argument(
        "--relative-to",
        metavar="A",
        help=f"the {what} in body or site A instead of in the world (implies --tree)",
    )


def _tree_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--tree",
        action="store_true",
        help="the whole model: q is its qpos (MuJoCo's layout), --frame any body or site",
    )
    add_floating_base(p)


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    f = sub.add_parser(
        "fk",
        help="forward kinematics for joint values",
        description="Print T_world_frame(q) for one configuration, or map a batch of q "
        "(N rows in a .npy, .npz, .csv or .txt file) to (N, 4, 4) poses in a file of the "
        "format its suffix names. By default q holds the joints of the chain to --frame. "
        "With --tree, q is the model's whole qpos (MuJoCo's layout: a free joint is "
        "x y z qw qx qy qz, a ball joint a quaternion wxyz) and --frame any body or site; "
        "--all-frames poses every body and site, (N, frames, 4, 4), and --relative-to A gives "
        "T_A_frame; both imply --tree. --form pos_quat writes each pose as x y z (m) and its "
        "quaternion w x y z, (N, 7); --form xyz_rpy as x y z (m) and roll pitch yaw (rad) in "
        "URDF's fixed-axis convention, R = Rz(yaw) Ry(pitch) Rx(roll) (roll about the fixed x "
        "axis first, then pitch about y, then yaw about z; pitch in [-pi/2, pi/2]), (N, 6). "
        "--tool gives the pose of a tool on the end frame, T_world_tool = T_world_frame "
        "T_frame_tool; --base places the robot's base in your world, T_world_base.",
        epilog="examples:\n  poekin fk universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin fk universal_robots_ur5e --q 0 -90 90 0 0 0 --deg\n"
        "  poekin fk universal_robots_ur5e --q 0 -90 90 0 0 0 --deg --form xyz_rpy\n"
        "  poekin fk universal_robots_ur5e --input q.npy --output T.csv\n"
        "  poekin fk universal_robots_ur5e --q 0 -90 90 0 0 0 --deg --base 0 0 0.8 1 0 0 0 "
        "--tool 0 0 0.15 1 0 0 0\n"
        "  poekin fk --params lynch-park-ur5 --q 0 -1.5708 0 0 1.5708 0\n"
        "  poekin fk unitree_go2 --all-frames --input qpos.npy --output T_all.npy\n"
        "  poekin fk unitree_go2 --frame FL_calf --relative-to base --form pos_quat --q 0 0 0.3 "
        "1 0 0 0 0 0.9 -1.8 0 0.9 -1.8 0 0.9 -1.8 0 0.9 -1.8",
        formatter_class=fmt,
    )
    add_source(f)
    add_params(f, "use these parameters instead of a model")
    add_joint_values(f, "FILE", "poses ((N, 4, 4), or as --form says)")
    add_placement(f)
    _frame_options(f, "pose")
    f.add_argument(
        "--form",
        choices=list(_FORM_CELLS),
        default="matrix",
        help="each pose as its 4 x 4 matrix (default), pos_quat (x y z qw qx qy qz) or "
        "xyz_rpy (x y z roll pitch yaw, R = Rz(yaw) Ry(pitch) Rx(roll))",
    )
    f.set_defaults(run=_cmd_fk)

    j = sub.add_parser(
        "jacobian",
        help="the Jacobian of a frame for joint values",
        description="Print the 6 x n Jacobian of the end frame at joint values q, or map a "
        "batch of q (N rows in a .npy, .npz, .csv or .txt file) to (N, 6, n) Jacobians in a "
        "file. Rows are [w; v]. --convention space: the twist in the world frame (Modern "
        "Robotics' J_s); body: in the end frame (J_b); world: v is the velocity of the frame's "
        "origin in world coordinates, as MuJoCo's mj_jacSite. With --tree, q is the whole qpos "
        "and the columns are MuJoCo's qvel (6 x nv): frames behind ball and free joints too. "
        "--all-frames gives the Jacobian of every body and site, (N, frames, 6, nv); "
        "--relative-to A the Jacobian of T_A_frame, A in the world's role (space: the twist in "
        "A; world: rows in A's coordinates); both imply --tree. --tool gives the Jacobian of "
        "a tool on the end frame; --base puts the twists in your world.",
        epilog="examples:\n  poekin jacobian universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin jacobian universal_robots_ur5e --q 0 0 0 0 0 0 --convention body --json\n"
        "  poekin jacobian universal_robots_ur5e --input q.npy --output J.npy\n"
        "  poekin jacobian unitree_go2 --tree --frame FL_calf --convention world --input "
        "qpos.npy --output J_FL_calf.npy\n"
        "  poekin jacobian unitree_go2 --frame FL_calf --relative-to base --q 0 0 0.3 1 0 0 0 "
        "0 0.9 -1.8 0 0.9 -1.8 0 0.9 -1.8 0 0.9 -1.8",
        formatter_class=fmt,
    )
    add_source(j)
    add_params(j, "use these parameters instead of a model")
    add_joint_values(j, "FILE", "(N, 6, n) Jacobians")
    add_placement(j)
    j.add_argument(
        "--convention",
        choices=["space", "body", "world"],
        default="space",
        help="space (J_s, default), body (J_b) or world (as mj_jacSite)",
    )
    _frame_options(j, "Jacobian")
    j.set_defaults(run=_cmd_jacobian)
