"""``poekin path``: a straight line (or screw motion) of the end frame, followed by IK and timed
within the joints' limits.

From ``--from Q...`` to ``--to-pose X Y Z QW QX QY QZ`` (or to the end frame's pose at ``--to
Q...``): the path ``--line`` (the default: the origin on a straight line, the rotation by
slerp, as a UR's ``movel``) or ``--screw`` (:mod:`poekin.motion.paths`), followed by
:meth:`poekin.Chain.follow` (the branch of ``--from`` kept, the tool within ``--tol`` of the
path between samples), then timed by :func:`poekin.motion.retime` within ``--vel-limits`` and
``--acc-limits`` at ``--rate``. A path that cannot be followed to its end is timed as far as it
got, and the output says where it stopped and why.

Exit codes: 0 when the path is followed to its end, 1 when it stops early (the part followed is
written all the same), 2 on bad input (nothing written).
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any, TextIO

import numpy as np
from numpy.typing import NDArray

from poekin.chain import pos_quat_poses
from poekin.cli._args import (
    EXIT_FAIL,
    JointSpace,
    add_params,
    add_placement,
    add_source,
    note,
    read_values,
)
from poekin.cli._fk import end_chain
from poekin.cli._text import sig
from poekin.errors import InputError

__all__ = ["DEFAULT_ACC", "DEFAULT_VEL", "register"]

FloatArray = NDArray[np.float64]

#: The limits without --vel-limits and --acc-limits (rad/s, rad/s^2; m/s, m/s^2 for a slide):
#: URScript's ``movej`` defaults, gentle for most arms. Give your arm's own.
DEFAULT_VEL = 1.05
DEFAULT_ACC = 1.4


def _limits(values: list[float] | None, n: int, default: float, flag: str, unit: str) -> FloatArray:
    if values is None:
        return np.full(n, default)
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape not in ((1,), (n,)) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InputError(
            f"{flag} takes one number > 0 or {n} of them ({unit}, one per joint), got "
            + " ".join(f"{v:g}" for v in values)
        )
    out: FloatArray = np.broadcast_to(arr, (n,)).copy()
    return out


def _number(value: float, flag: str, unit: str) -> float:
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{flag} must be a number > 0 ({unit}), got {value:g}")
    return float(value)


def _goal(args: argparse.Namespace, chain: Any, space: JointSpace) -> FloatArray:
    """The path's end pose: --to-pose, or the end frame at --to."""
    if (args.to_pose is None) == (args.to is None):
        raise InputError("give the path's end: --to-pose X Y Z QW QX QY QZ, or --to Q... (joints)")
    if args.to is not None:
        q1 = read_values(args.to, space, args.deg, "--to")
        goal: FloatArray = np.asarray(chain.fk(q1), dtype=np.float64)
        return goal
    if len(args.to_pose) != 7:
        raise InputError(
            f"--to-pose takes 7 numbers, X Y Z (m) QW QX QY QZ (a unit quaternion), got "
            f"{len(args.to_pose)}"
        )
    row = np.asarray(args.to_pose, dtype=np.float64)
    if not np.all(np.isfinite(row)):
        raise InputError("--to-pose has NaN or inf; give 7 finite numbers")
    goal = pos_quat_poses(row[None], lambda _: "--to-pose")[0]
    return goal


def _cmd_path(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.chain import Chain
    from poekin.motion import line_path, retime, screw_path

    rate = _number(args.rate, "--rate", "Hz")
    tol = _number(args.tol, "--tol", "m")
    max_step = _number(args.max_step, "--max-step", "rad")
    if args.output is not None:  # said before anything is computed
        from poekin.io.fileio import check_new_file

        if not str(args.output).lower().endswith(".npz"):
            raise InputError(f"--output {args.output}: a trajectory file is a .npz archive")
        check_new_file(args.output, "trajectory", force=args.force)
    chain = end_chain(args)
    if not isinstance(chain, Chain):
        chain = chain.to_chain()
    space = JointSpace.of(chain)
    n = chain.n_joints
    vel = _limits(args.vel_limits, n, DEFAULT_VEL, "--vel-limits", "rad/s or m/s")
    acc = _limits(args.acc_limits, n, DEFAULT_ACC, "--acc-limits", "rad/s^2 or m/s^2")
    if args.vel_limits is None or args.acc_limits is None:
        note(
            f"limits: {DEFAULT_VEL:g} rad/s and {DEFAULT_ACC:g} rad/s^2 per joint where not "
            "given (URScript's movej defaults); give your arm's with --vel-limits, --acc-limits"
        )
    q0 = read_values(args.from_q, space, args.deg, "--from")
    T0, T1 = np.asarray(chain.fk(q0), dtype=np.float64), _goal(args, chain, space)
    shape = screw_path if args.screw else line_path

    def path(s: FloatArray) -> FloatArray:
        return np.asarray(shape(T0, T1, s), dtype=np.float64)

    found = chain.follow(path, q0, max_step=max_step, tol=tol)
    if len(found.q) < 2:
        raise InputError(
            f"the path stops at its start ({found.reason}: {found.detail}); there is no motion "
            "to time"
        )
    timed = retime(found.q, vel, acc, rate=rate)
    peak_v = np.max(np.abs(timed.qd), axis=0)
    peak_a = np.max(np.abs(timed.qdd), axis=0)
    done = found.reason == "done"
    if args.output is not None:
        from poekin.io.trajectory import Trajectory

        Trajectory(
            t=timed.t,
            q=timed.q,
            qd=timed.qd,
            qdd=timed.qdd,
            robot=chain.robot or "",
            joint_names=tuple(chain.joint_names),
            vel_limits=vel,
            acc_limits=acc,
            pos_limits=np.asarray(chain.limits, dtype=np.float64),
            fraction=float(found.fraction),
            reason="" if done else f"{found.reason}: {found.detail}",
            stop_index=None if done else len(timed.t) - 1,
        ).save(args.output, force=args.force)
    kind = "screw" if args.screw else "line"
    length = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
    if args.json:
        report = {
            "robot": chain.robot,
            "frame": chain.frame,
            "path": kind,
            "length_m": length,
            "fraction": float(found.fraction),
            "reason": found.reason,
            "detail": found.detail,
            "samples": len(found.s),
            "max_deviation_m": float(found.max_deviation),
            "duration_s": float(timed.duration),
            "rate_hz": rate,
            "peak_velocity": dict(zip(chain.joint_names, peak_v.tolist(), strict=True)),
            "peak_acceleration": dict(zip(chain.joint_names, peak_a.tolist(), strict=True)),
            "output": None if args.output is None else str(args.output),
        }
        print(json.dumps(report, indent=2), file=out)
        return 0 if done else EXIT_FAIL
    print(f"{kind} of {sig(length)} m for {chain.frame} ({chain.robot or 'chain'})", file=out)
    where = "to its end" if done else f"to {100 * found.fraction:.1f}%: {found.detail}"
    print(
        f"followed {where}; {len(found.s)} samples, the tool within "
        f"{sig(tol * 1e3)} mm of the path between them",
        file=out,
    )
    print(f"duration {sig(timed.duration)} s at {rate:g} Hz ({len(timed.t)} samples)", file=out)
    unit = {True: "rad/s", False: "m/s"}
    for j, name in enumerate(chain.joint_names):
        angle = bool(space.angles[j])
        print(
            f"  {name:<22} peak {sig(peak_v[j])} of {sig(vel[j])} {unit[angle]}, "
            f"{sig(peak_a[j])} of {sig(acc[j])} {unit[angle]}^2",
            file=out,
        )
    if args.output is not None:
        print(f"trajectory (t, q, qd, qdd) written to {args.output}", file=out)
    return 0 if done else EXIT_FAIL


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser(
        "path",
        help="a straight line of the end frame, followed by IK and timed within limits",
        description="Move the end frame from its pose at --from to --to-pose X Y Z QW QX QY QZ "
        "(metres, a unit quaternion w first, in the world frame), or to its pose at --to: on a "
        "straight line (--line, the default: the origin on a line, the rotation by slerp, as a "
        "UR's movel) or a screw motion (--screw). The path is followed by IK (Chain.follow: "
        "the branch of --from kept, never switched; the tool within --tol of the path between "
        "samples, which are added where needed; no joint moving more than --max-step between "
        "two), then timed as fast as --vel-limits and --acc-limits allow at every sample "
        "(poekin.motion.retime; without them, URScript's movej defaults, 1.05 rad/s and 1.4 "
        "rad/s^2). --output FILE.npz saves t, q, qd and qdd (poekin view --play and poekin "
        "plot-trajectory read it). Exit 0 when the path is followed to its end, 1 when it "
        "stops early (where and why are said, and the part followed is timed and written), 2 "
        "on bad input.",
        epilog="examples:\n"
        "  poekin path universal_robots_ur5e --from 0.3 -1.2 1.4 -0.5 1.1 0.2 --to 0.6 -1.0 "
        "1.2 -0.7 1.3 0.4\n"
        "  poekin path universal_robots_ur5e --from 0 -90 90 -90 -90 0 --deg --to-pose -0.4 "
        "-0.2 0.3 0 0.707106781 0.707106781 0 --rate 500 --output traj.npz\n"
        "  poekin path universal_robots_ur5e --from 0.3 -1.2 1.4 -0.5 1.1 0.2 --to 0.6 -1.0 "
        "1.2 -0.7 1.3 0.4 --screw --json",
        formatter_class=fmt,
    )
    add_source(p)
    add_params(p, "move with these parameters instead of a model's")
    add_placement(p)
    p.add_argument(
        "--from",
        dest="from_q",
        type=float,
        nargs="+",
        required=True,
        metavar="Q",
        help="the start: joint values (rad and m; see --deg)",
    )
    p.add_argument(
        "--to-pose",
        type=float,
        nargs="+",
        metavar="V",
        help="the end: X Y Z (m) QW QX QY QZ (unit quaternion), in the world frame",
    )
    p.add_argument(
        "--to",
        type=float,
        nargs="+",
        metavar="Q",
        help="or the end frame's pose at these joint values (the path is still a line of the "
        "end frame, not a joint-space move)",
    )
    kind = p.add_mutually_exclusive_group()
    kind.add_argument("--line", action="store_true", help="a straight line (the default)")
    kind.add_argument("--screw", action="store_true", help="a screw motion (one twist)")
    p.add_argument("--rate", type=float, default=500.0, help="samples per second (500)")
    p.add_argument(
        "--vel-limits",
        type=float,
        nargs="+",
        metavar="V",
        help=f"each joint's speed limit, one number or one per joint (rad/s; {DEFAULT_VEL:g})",
    )
    p.add_argument(
        "--acc-limits",
        type=float,
        nargs="+",
        metavar="A",
        help=f"each joint's acceleration limit, one or one per joint (rad/s^2; {DEFAULT_ACC:g})",
    )
    p.add_argument(
        "--tol",
        type=float,
        default=1e-4,
        help="the tool's largest deviation from the path between samples, m (1e-4)",
    )
    p.add_argument(
        "--max-step",
        type=float,
        default=0.1,
        help="the largest move of a joint between two samples, rad (0.1); more is a jump",
    )
    p.add_argument("--deg", action="store_true", help="revolute joint values in degrees")
    p.add_argument("--output", metavar="FILE", help="save the trajectory here (.npz)")
    p.add_argument("--force", action="store_true", help="replace an existing --output file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=_cmd_path)
