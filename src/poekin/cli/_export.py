"""``poekin export``: write a parameter set or a model's chain as UR's kinematics YAML or a
URDF."""

from __future__ import annotations

import argparse
from typing import Any, TextIO

import numpy as np

from poekin.cli._args import add_ur_yaml_order, params
from poekin.cli._text import fixed

__all__ = ["register"]


def _cmd_export(args: argparse.Namespace, out: TextIO) -> int:
    from poekin import lie
    from poekin.errors import InputError
    from poekin.io.exporters import check_export, export
    from poekin.io.loading import load
    from poekin.verification.diagnose import _is_param_set

    check_export(args.to, args.output, force=args.force)  # before anything is read
    if _is_param_set(args.params):
        if args.frame:
            raise InputError("--frame names a model's frame; a parameter set has its own end frame")
        chain = params(args.params, args)
    else:
        chain = load(args.params, args.frame)
    done = export(chain, args.to, args.output, force=args.force, ur_yaml_order=args.ur_yaml_order)
    what = f"{args.to} file ({done.model})" if done.model else f"{args.to} file"
    print(f"{what} written to {done.path}", file=out)
    if args.to == "ur-yaml":
        offset = float(np.linalg.norm(done.tcp[:3, 3]))
        turn = float(lie.rotation_angle(done.tcp[:3, :3]))
        frame = chain.frame
        if offset > 1e-9 or turn > 1e-9:
            x, y, z = (fixed(v, 4) for v in done.tcp[:3, 3] * 1e3)
            rx, ry, rz = (fixed(v, 6) for v in np.asarray(lie.log_so3(done.tcp[:3, :3])))
            print(
                f"the end frame {frame!r} is not tool0 (on joint 6's axis, which the file ends "
                f"at): set the controller's TCP to x {x} y {y} z {z} mm, rx {rx} ry {ry} rz {rz} "
                "rad (a rotation vector) to reach it",
                file=out,
            )
        else:
            print(f"the end frame {frame!r} is tool0: the controller's TCP stays zero", file=out)
    return 0


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    e = sub.add_parser(
        "export",
        help="write parameters as UR's kinematics YAML or a URDF",
        description="Write a parameter set (a calibration poekin calibrate wrote, a DH table, "
        "UR's calibration .yaml, a named set) or a model's chain for other tools: --to ur-yaml, "
        "UR's kinematics: file (x y z roll pitch yaw per joint, as ur_description's "
        "default_kinematics.yaml; UR arms in UR's base frame only), or --to urdf (one link per "
        "joint, the joint limits, the end frame a fixed link). Both read back to the same FK. "
        "Exit 0 on success, 2 on bad input (nothing written).",
        epilog="examples:\n"
        "  poekin export my_robot.json --to ur-yaml --output my_robot_kinematics.yaml\n"
        "  poekin export my_robot.json --to urdf --output my_robot.urdf\n"
        "  poekin export universal_robots_ur5e --to urdf --output ur5e.urdf",
        formatter_class=fmt,
    )
    e.add_argument(
        "params",
        metavar="PARAMS",
        help="a parameter file (.json/.yaml), a named set, or a model (a Menagerie robot name, "
        "an MJCF or URDF path)",
    )
    e.add_argument(
        "--frame", metavar="F", help="a model's end frame: site or body (default: its only site)"
    )
    e.add_argument("--to", required=True, choices=("ur-yaml", "urdf"), help="the file's format")
    e.add_argument(
        "--output", required=True, metavar="FILE", help="the file to write (.yaml, .urdf)"
    )
    e.add_argument("--force", action="store_true", help="replace an existing --output file")
    add_ur_yaml_order(e, "written with --to ur-yaml")
    e.set_defaults(run=_cmd_export)
