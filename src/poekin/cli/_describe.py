"""``poekin screws`` and ``poekin dh``: a model's parameters as screws and M, or as a DH table."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from poekin.cli._args import (
    add_params,
    add_placement,
    add_precision,
    add_source,
    model_source,
    params,
    place,
    placement,
)
from poekin.cli._text import fixed, matrix_lines, table
from poekin.errors import InputError
from poekin.io.fileio import finite_json

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.dh import DHTable

__all__ = ["params_or_chain", "register"]


def params_or_chain(args: argparse.Namespace) -> Chain | DHTable:
    """``--params`` if given, else the chain of the positional model SOURCE (not both)."""
    from poekin.io.loading import load

    if args.params and args.source:
        raise InputError("give a model SOURCE or --params FILE|NAME, not both")
    if args.params and args.frame:
        raise InputError("--frame names a model's frame; a parameter set has its own end frame")
    if args.params:
        return params(args.params, args)
    return load(model_source(args, None), args.frame)


# --- screws -----------------------------------------------------------------------------------


def _cmd_screws(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.io.loading import load

    base, tool = placement(args)  # checked before the model is read
    chain = load(model_source(args, None), args.frame, base=base, tool=tool)
    if args.json:
        print(json.dumps(finite_json(chain.describe())), file=out)
        return 0
    form, screws, name = (
        ("body", chain.body_screws, "B_i") if args.body else ("space", chain.screws, "S_i")
    )
    print(
        f"{chain.robot}  frame {chain.frame!r}  {chain.n_joints} joints, {form} screws "
        f"{name} = [w; v]",
        file=out,
    )
    p = args.precision
    header = ["joint", "type", "wx", "wy", "wz", "vx", "vy", "vz"]
    rows = [
        [name, kind, *(fixed(x, p) for x in S)]
        for name, kind, S in zip(chain.joint_names, chain.joint_types, screws, strict=True)
    ]
    print("\n".join(table([header, *rows], left=(0, 1))), file=out)
    print(f"M = T_world_{chain.frame}(q = 0):", file=out)
    print("\n".join(matrix_lines(chain.home, p)), file=out)
    return 0


# --- dh ----------------------------------------------------------------------------------------


def _dh_table(args: argparse.Namespace) -> tuple[DHTable, Chain | None]:
    """The table to print, and the chain it was extracted from (None: a table given as is)."""
    from poekin.chain import Chain
    from poekin.dh import DHTable, dh_from_chain, nearest_dh

    if args.parallel_tol <= 0:
        raise InputError(f"--parallel-tol must be positive, got {args.parallel_tol}")
    placed = any(x is not None for x in placement(args))  # checked before the model is read
    obj = params_or_chain(args)
    if isinstance(obj, DHTable):
        if obj.convention == args.convention and not args.nearest and not placed:
            return obj, None
        obj = obj.to_chain()
    chain = place(obj, args)
    assert isinstance(chain, Chain)  # a table became its chain above
    if args.nearest:
        return nearest_dh(chain, args.convention), chain
    return dh_from_chain(chain, args.convention, parallel_tol=args.parallel_tol), chain


# The residual of an approximate table: its FK against the chain's on this many random q.
_RESIDUAL_SAMPLES = 1000


def _residual(table_: DHTable, chain: Chain) -> tuple[float, float]:
    """Max position (m) and orientation (rad) error of the table's FK against the chain's, over
    random q (seeded) within the chain's limits, or [-pi, pi] where it has none."""
    from poekin.verification.verify import pose_errors, random_generator

    low = np.where(np.isfinite(chain.limits[:, 0]), chain.limits[:, 0], -np.pi)  # type: ignore[index]
    high = np.where(np.isfinite(chain.limits[:, 1]), chain.limits[:, 1], np.pi)  # type: ignore[index]
    q = random_generator(0).uniform(low, high, size=(_RESIDUAL_SAMPLES, chain.n_joints))
    pos, ori = pose_errors(chain.fk(q), table_.fk(q))
    return float(np.max(pos)), float(np.max(ori))


def _size(pos: float, ori: float) -> str:
    """A residual in mm and mrad, two significant digits (geometry decides them, not rounding)."""
    return f"{pos * 1e3:.2g} mm and {ori * 1e3:.2g} mrad"


def _conditioning(table_: DHTable, chain: Chain, args: argparse.Namespace) -> list[str]:
    """What the output says when the chain's DH form is ill-conditioned (nearly parallel axes)
    or the table is not exact (axes made parallel), with the residual of the table offered."""
    from poekin.dh import NEAR_PARALLEL_SIN, PARALLEL_SIN, joint_lines, nearest_dh

    dirs, _ = joint_lines(chain)
    tilts = np.linalg.norm(np.cross(dirs[:-1], dirs[1:]), axis=1)
    near = (tilts > PARALLEL_SIN) & (tilts < NEAR_PARALLEL_SIN)
    pairs = ", ".join(f"{i + 1}-{i + 2} ({tilts[i] * 1e3:.2g} mrad)" for i in np.flatnonzero(near))
    if not pairs:
        return []
    over = f"max over {_RESIDUAL_SAMPLES} random q within the limits"
    if args.nearest:
        return [
            f"not exact: the nearest DH table with axes {pairs} made parallel; its FK is "
            f"within {_size(*_residual(table_, chain))} of the chain's ({over})"
        ]
    if np.any(near & (tilts < args.parallel_tol)):  # taken as parallel
        return [
            f"not exact: axes {pairs} are taken as parallel, so this table's FK is within "
            f"{_size(*_residual(table_, chain))} of the chain's ({over}); --nearest fits the "
            "rest to do better"
        ]
    nearest = nearest_dh(chain, table_.convention)
    where = f"--params {args.params}" if args.params else args.source or ""
    d = float(np.max(np.abs(table_.d)))
    return [
        f"this arm has no well-conditioned DH form: axes {pairs} are nearly but not exactly "
        "parallel, as a calibrated arm's always are, and DH puts the common normal of nearly "
        f"parallel axes far away (|d| up to {d:.3g} m): the table above is exact, but its "
        "lengths are not the arm's",
        f"nearest DH table, with those axes parallel: poekin dh {where} --nearest; its FK is "
        f"within {_size(*_residual(nearest, chain))} of the chain's ({over})",
    ]


def _cmd_dh(args: argparse.Namespace, out: TextIO) -> int:
    table_, chain = _dh_table(args)
    extra = _conditioning(table_, chain, args) if chain is not None else []
    if args.json:
        print(json.dumps({**table_.describe(), "notes": [*table_.notes, *extra]}), file=out)
        return 0
    std = table_.convention == "standard"
    form = (
        "standard (Denavit-Hartenberg): Rz(theta) Tz(d) Tx(a) Rx(alpha)"
        if std
        else "modified (Craig): Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta) Tz(d)"
    )
    source = table_.robot or args.params or args.source
    print(f"{source}  frame {table_.frame!r}  {form}", file=out)
    a, al = ("a", "alpha") if std else ("a(i-1)", "alpha(i-1)")
    header = ["joint", "type", f"{a} [m]", f"{al} [rad]", "d [m]", "theta_off [rad]"]
    p = args.precision
    rows = [
        [
            row["joint"],
            row["joint_type"],
            *(fixed(row[k], p) for k in ("a", "alpha", "d", "theta_offset")),
        ]
        for row in table_.rows()
    ]
    print("\n".join(table([header, *rows], left=(0, 1))), file=out)
    print("base = T_world_frame0:", file=out)
    print("\n".join(matrix_lines(table_.base, p)), file=out)
    print(f"tool = T_frame{table_.n_joints}_{table_.frame}:", file=out)
    print("\n".join(matrix_lines(table_.tool, p)), file=out)
    for text in [*table_.notes, *extra]:
        print(f"note: {text}", file=out)
    return 0


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    s = sub.add_parser(
        "screws",
        help="print the screw axes and home pose M",
        description="Print the screw axes S_i = [w; v] (space frame, or body frame with --body) "
        "and the home pose M, all derived from the model: with --base, in your world; with "
        "--tool, M is the tool's.",
        epilog="examples:\n  poekin screws universal_robots_ur5e\n"
        "  poekin screws franka_emika_panda --frame hand --body --json",
        formatter_class=fmt,
    )
    add_source(s)
    add_placement(s)
    s.add_argument("--body", action="store_true", help="body-frame screws B_i = Ad(M^-1) S_i")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    add_precision(s)
    s.set_defaults(run=_cmd_screws)

    d = sub.add_parser(
        "dh",
        help="print a Denavit-Hartenberg table of a model or parameter set",
        description="Extract a DH table (standard or modified convention) from a model's chain, "
        "or convert a parameter set. Its FK equals the chain's to float precision; the free "
        "choices (parallel axes, prismatic joints) are printed as notes. With --base and "
        "--tool the rows stay the robot's own: the base goes before the table's base, the tool "
        "after its tool.",
        epilog="examples:\n  poekin dh universal_robots_ur5e\n"
        "  poekin dh franka_fr3 --convention modified --json > fr3_dh.json\n"
        "  poekin dh --params lynch-park-ur5\n"
        "  poekin dh --params my_calibrated_ur5e.json --nearest",
        formatter_class=fmt,
    )
    add_source(d)
    add_params(d, "convert these parameters instead of a model")
    add_placement(d)
    d.add_argument(
        "--convention",
        choices=["standard", "modified"],
        default="standard",
        help="standard (Denavit-Hartenberg) or modified (Craig); default standard",
    )
    d.add_argument(
        "--parallel-tol",
        type=float,
        default=1e-8,
        metavar="SIN",
        help="treat axes within this sine of parallel as parallel (1e-8: float rounding only)",
    )
    d.add_argument(
        "--nearest",
        action="store_true",
        help="the nearest table with nearly parallel axes (within 0.05 sine) made parallel: "
        "fitted to the chain's FK, for a calibrated arm (its exact table has d of metres)",
    )
    d.add_argument("--json", action="store_true", help="print one JSON object")
    add_precision(d)
    d.set_defaults(run=_cmd_dh)
