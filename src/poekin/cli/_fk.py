"""``poekin fk`` and ``poekin jacobian``: poses and Jacobians for joint values.

Both speak one vocabulary for what ``q`` is and which frame is meant:

* by default ``q`` holds the joint values of the chain from the world to ``--frame`` (the model's
  only site if not given); ``--params`` gives that chain as a parameter set instead;
* ``--tree``: ``q`` is the whole model's ``qpos`` (MuJoCo's layout, free and ball joints
  included), and ``--frame`` is any body or site; ``fk --all-frames`` poses every one of them,
  and ``fk --relative-to A`` gives a frame's pose in frame ``A`` (both imply ``--tree``).
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
    add_source,
    model_source,
    read_joint_values,
)
from poekin.cli._describe import params_or_chain
from poekin.cli._text import matrix_lines
from poekin.errors import InputError

if TYPE_CHECKING:
    from poekin.tree import Tree

__all__ = ["register"]

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
    from poekin.loading import load_tree

    if args.params:
        raise InputError(
            "--tree, --all-frames and --relative-to take the whole model from SOURCE, not --params"
        )
    return load_tree(model_source(args, None), floating_base=args.floating_base)


def _chain(args: argparse.Namespace) -> Any:
    """The chain (or DH table) to the frame, refusing a frame behind a ball or free joint with
    the way to pose it (``--tree``)."""
    if args.floating_base:
        raise InputError("--floating-base gives a whole model's qpos: pass --tree too")
    if args.params:
        return params_or_chain(args)
    from poekin.loading import default_frame, load_tree

    tree = load_tree(model_source(args, None))
    frame = args.frame if args.frame is not None else default_frame(tree)
    for k in tree.path_joints(frame):
        kind = tree.joint_types[k]
        if kind in ("ball", "free"):
            raise InputError(
                f"{frame!r} sits behind the {kind} joint {tree.joint_names[k]!r}, which a chain "
                f"of hinges and slides cannot hold: pass --tree and give the whole qpos "
                f"({tree.nq} values: {tree.qpos_layout()})"
            )
    return tree.chain(frame)


def _fk_target(args: argparse.Namespace) -> _Target:
    if not _tree_mode(args):
        chain = _chain(args)
        return _Target(chain.fk, JointSpace.of(chain), (chain.frame,))
    from poekin import lie
    from poekin.loading import default_frame

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
    if not args.tree:
        from poekin.chain import Chain

        chain = _chain(args)
        if not isinstance(chain, Chain):
            chain = chain.to_chain()
        method = getattr(chain, f"jacobian_{convention}")
        return _Target(method, JointSpace.of(chain), (chain.frame,), columns=chain.joint_names)
    from poekin.loading import default_frame

    tree = _load_tree(args)
    frame = args.frame or default_frame(tree)
    tree.frame_index(frame)  # an unknown frame is said now, before q is read

    def jacobian(qpos: FloatArray) -> FloatArray:
        J: FloatArray = tree.jacobian(qpos, frame, convention)
        return J

    return _Target(jacobian, JointSpace.of_tree(tree), (frame,), columns=tree.dof_names())


def _check_q_args(args: argparse.Namespace, result: str) -> None:
    """``--q`` or ``--input`` (one of them); ``--input`` with ``--output``, a new file of a
    known format; ``--json`` only with ``--q``. Checked before any model is loaded."""
    from poekin.fileio import array_format, check_new_file

    if (args.q is None) == (args.input is None):
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
    from poekin.fileio import write_array

    write_array(args.output, result, name=name, columns=columns, extras=extras)
    print(f"{what} {name} of shape {result.shape} written to {args.output}", file=out)


# --- fk ---------------------------------------------------------------------------------------


def _cmd_fk(args: argparse.Namespace, out: TextIO) -> int:
    _check_q_args(args, "poses")
    target = _fk_target(args)
    q = read_joint_values(args, target.space)
    T = target.evaluate(q)
    frames = target.frames
    ref = target.reference
    if args.input is not None:
        cells = [f"T{r}{c}" for r in range(4) for c in range(4)]
        columns = [f"{f}.{c}" for f in frames for c in cells] if target.many else cells
        _save(args, T, "poses", "T", columns, {"frames": frames}, out)
        if target.many:
            print(f"frames (axis -3): {', '.join(frames)}", file=out)
        return 0
    poses = T if target.many else T[None]
    if args.json:
        named = {f: poses[k].tolist() for k, f in enumerate(frames)}
        body = {"frames": named} if target.many else {"frame": frames[0], "T": named[frames[0]]}
        extra = {"relative_to": ref} if ref != "world" else {}
        print(json.dumps({**body, **extra, "q": list(args.q), "deg": args.deg}), file=out)
        return 0
    for k, f in enumerate(frames):
        print(f"T_{ref}_{f} =", file=out)
        print("\n".join(matrix_lines(poses[k], args.precision)), file=out)
    return 0


# --- jacobian ----------------------------------------------------------------------------------


def _cmd_jacobian(args: argparse.Namespace, out: TextIO) -> int:
    _check_q_args(args, "Jacobians")
    target = _jacobian_target(args)
    q = read_joint_values(args, target.space)
    J = target.evaluate(q)
    frame, columns = target.frames[0], target.columns
    if args.input is not None:
        cells = [f"{r}:{c}" for r in _ROWS for c in columns]
        _save(args, J, "Jacobians", "J", cells, {"columns": columns}, out)
        return 0
    if args.json:
        body = {"frame": frame, "convention": args.convention, "q": list(args.q), "deg": args.deg}
        print(json.dumps({**body, "columns": list(columns), "J": J.tolist()}), file=out)
        return 0
    rows = "[w; v_frame] in world coordinates" if args.convention == "world" else "[w; v]"
    print(f"J_{args.convention} of {frame!r} (6 x {J.shape[-1]}), rows {rows}", file=out)
    print(f"columns: {', '.join(columns)}", file=out)
    print("\n".join(matrix_lines(J, args.precision)), file=out)
    return 0


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
        "T_A_frame; both imply --tree.",
        epilog="examples:\n  poekin fk universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin fk universal_robots_ur5e --q 0 -90 90 0 0 0 --deg\n"
        "  poekin fk universal_robots_ur5e --input q.npy --output T.csv\n"
        "  poekin fk --params lynch-park-ur5 --q 0 -1.5708 0 0 1.5708 0\n"
        "  poekin fk unitree_go2 --all-frames --input qpos.npy --output T_all.npy\n"
        "  poekin fk unitree_go2 --frame FL_calf --relative-to base --q 0 0 0.3 1 0 0 0 "
        "0 0.9 -1.8 0 0.9 -1.8 0 0.9 -1.8 0 0.9 -1.8",
        formatter_class=fmt,
    )
    add_source(f)
    add_params(f, "use these parameters instead of a model")
    add_joint_values(f, "FILE", "(N, 4, 4) poses")
    _tree_options(f)
    f.add_argument(
        "--all-frames", action="store_true", help="pose every body and site (implies --tree)"
    )
    f.add_argument(
        "--relative-to",
        metavar="A",
        help="the pose in body or site A, T_A_frame, instead of in the world (implies --tree)",
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
        "and the columns are MuJoCo's qvel (6 x nv): frames behind ball and free joints too.",
        epilog="examples:\n  poekin jacobian universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin jacobian universal_robots_ur5e --q 0 0 0 0 0 0 --convention body --json\n"
        "  poekin jacobian universal_robots_ur5e --input q.npy --output J.npy\n"
        "  poekin jacobian unitree_go2 --tree --frame FL_calf --convention world --input "
        "qpos.npy --output J.npy",
        formatter_class=fmt,
    )
    add_source(j)
    add_params(j, "use these parameters instead of a model")
    add_joint_values(j, "FILE", "(N, 6, n) Jacobians")
    j.add_argument(
        "--convention",
        choices=["space", "body", "world"],
        default="space",
        help="space (J_s, default), body (J_b) or world (as mj_jacSite)",
    )
    _tree_options(j)
    j.set_defaults(run=_cmd_jacobian)
