"""``poekin verify`` and ``poekin diagnose``: check FK against MuJoCo, and explain a mismatch."""

from __future__ import annotations

import argparse
import json
from typing import Any, TextIO

from poekin.cli._args import (
    DEFAULT_ROBOT,
    EXIT_FAIL,
    PARAM_NAMES,
    add_floating_base,
    add_params,
    add_sampling,
    add_source,
    add_ur_yaml_order,
    model_source,
    params,
    params_spec,
)
from poekin.cli._text import sig, table
from poekin.errors import InputError

__all__ = ["register"]


def _check_run_options(args: argparse.Namespace) -> None:
    """--samples, --seed, --pos-tol, --ori-tol and --plot of verify and diagnose, before any
    model is loaded."""
    import math

    from poekin.io.fileio import check_new_file, figure_format

    if args.samples < 1:
        raise InputError(f"--samples must be at least 1, got {args.samples}")
    if args.seed < 0:
        raise InputError(f"--seed must be a whole number, 0 or more, got {args.seed}")
    for flag, value in (("--pos-tol", args.pos_tol), ("--ori-tol", args.ori_tol)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{flag} must be a positive number, got {value}")
    if args.plot:
        figure_format(args.plot, "--plot")
        check_new_file(args.plot, "plot", force=args.force)


def _verdict(passed: bool, pos_tol: float, ori_tol: float) -> str:
    return f"{'PASS' if passed else 'FAIL'}: tolerances {pos_tol:g} m, {ori_tol:g} rad"


# --- verify -----------------------------------------------------------------------------------


def _cmd_verify(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.io.loading import is_urdf, load_tree
    from poekin.io.sources import load_model
    from poekin.verification.verify import verify

    _check_run_options(args)
    if args.metrics:
        from poekin.verification.metrics import check_metrics_file

        check_metrics_file(args.metrics)
    if args.against and not args.params:
        raise InputError("--against SOURCE goes with --params FILE|NAME (what to check)")
    source = model_source(args)
    # a URDF is read by poekin first: a malformed file gets poekin's message, naming the joint
    tree = load_tree(source, floating_base=args.floating_base) if is_urdf(source) else None
    if args.floating_base and tree is None:
        load_tree(source, floating_base=True)  # refuses a model that is not a URDF
    free_root = tree.joint_names[0] if args.floating_base and tree is not None else None
    loaded = load_model(source, free_root=free_root)
    common = {
        "samples": args.samples,
        "seed": args.seed,
        "within_limits": args.within_limits,
        "pos_tol": args.pos_tol,
        "ori_tol": args.ori_tol,
        "progress": True,
    }
    if args.floating_base and tree is not None:
        if args.params:
            raise InputError("--floating-base checks a URDF model's own tree, not --params")
        report = verify(tree, args.frame, against=loaded, **common)  # type: ignore[arg-type]
    else:
        report = verify(
            loaded,
            args.frame,
            all_frames=args.all_frames,
            params=params_spec(args),
            **common,  # type: ignore[arg-type]
        )
    if args.json:
        print(json.dumps(report.summary()), file=out)
    else:
        _print_report(report, args, out)
    if args.plot:
        from poekin.verification.plotting import plot_errors

        plot_errors(
            report.pos_err,
            report.ori_err,
            title=f"{args.params + ' vs ' if args.params else ''}{report.robot} / "
            f"{report.frame}: FK vs mj_forward, {report.samples} samples",
            path=args.plot,
            pos_tol=report.pos_tol,
            ori_tol=report.ori_tol,
            passed=report.passed,
        )
        if not args.json:
            print(f"plot written to {args.plot}", file=out)
    if args.metrics:
        from poekin.verification.metrics import append_metrics, metric_rows, sha256_files

        notes = f"frame={report.frame}; range={'limits' if args.within_limits else '[-2pi,2pi]'}"
        if args.params:
            notes += f"; params={args.params}"
        rows = metric_rows(
            report,
            experiment=f"fk_verify_{loaded.short_name}",
            model_sha=sha256_files(loaded.files, loaded.xml_path.parent),
            notes=notes,
        )
        append_metrics(args.metrics, rows)
        if not args.json:
            print(f"{len(rows)} metric rows appended to {args.metrics}", file=out)
    return 0 if report.passed else EXIT_FAIL


def _print_report(report: Any, args: argparse.Namespace, out: TextIO) -> None:
    checked = f"{report.params} against " if report.params else ""
    frame = "every body and site" if report.frame == "all frames" else f"frame {report.frame!r}"
    print(
        f"{checked}{report.robot}  {frame}  {report.samples} samples {report.sample_range}, "
        f"seed {report.seed}, vs mj_forward",
        file=out,
    )
    builtin = report.model_origin.startswith("poekin's built-in")
    where = f" ({report.model_origin})" if report.model_origin else ""
    print(f"model: {report.model_origin if builtin else report.model_file + where}", file=out)
    header = ["", "max pos [m]", "median pos [m]", "max ori [rad]", "median ori [rad]"]
    keys = ("max_pos_err_m", "median_pos_err_m", "max_ori_err_rad", "median_ori_err_rad")
    rows = [[m, *(sig(s[k]) for k in keys)] for m, s in report.per_method().items()]
    print("\n".join(table([header, *rows], indent=0)), file=out)
    if len(report.frame_errors) > 1:
        worst = max(report.frame_errors, key=lambda f: report.frame_errors[f])
        pos, ori = report.frame_errors[worst]
        print(
            f"{len(report.frame_errors)} frames; worst {worst!r}: {sig(pos)} m, {sig(ori)} rad",
            file=out,
        )
    print(_verdict(report.passed, report.pos_tol, report.ori_tol), file=out)


# --- diagnose ----------------------------------------------------------------------------------


def _cmd_diagnose(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.chain import Chain
    from poekin.dh import DHTable
    from poekin.verification.diagnose import _is_param_set, diagnose

    _check_run_options(args)
    source = model_source(args)
    against: str | Chain = source
    if args.ur_yaml_order != "description" and _is_param_set(source):
        read = params(source, args)  # a UR calibration read in the controller's order
        against = read.to_chain() if isinstance(read, DHTable) else read
    d = diagnose(
        params(args.params, args),
        against,
        frame=args.frame,
        samples=args.samples,
        seed=args.seed,
        pos_tol=args.pos_tol,
        ori_tol=args.ori_tol,
    )
    model = d.model
    if args.plot:
        from poekin.verification.plotting import plot_diagnosis

        verdict = "match" if d.matches else "mismatch"
        plot_diagnosis(
            d, args.plot, title=f"{args.params} vs {model.robot} / {model.frame}: {verdict}"
        )
    if args.json:
        print(json.dumps(d.summary()), file=out)
        return 0 if d.matches else EXIT_FAIL
    # what the file is, where it says more than its name (a UR calibration's model and hash)
    robot = d.yours.robot
    yours = args.params if robot in ("", args.params) else f"{args.params} ({robot})"
    print(
        f"{yours} vs {model.robot}  frame {model.frame!r}  {d.samples} random q in "
        f"[-2 pi, 2 pi], seed {d.seed}",
        file=out,
    )
    for line in d.report():
        print(line, file=out)
    if args.plot:
        print(f"plot written to {args.plot}", file=out)
    return 0 if d.matches else EXIT_FAIL


# --- parsers -----------------------------------------------------------------------------------


def _outputs(p: argparse.ArgumentParser, *, pos_tol: float, ori_tol: float, plot: str) -> None:
    p.add_argument(
        "--pos-tol", type=float, default=pos_tol, help=f"position tolerance, m ({pos_tol:g})"
    )
    p.add_argument(
        "--ori-tol", type=float, default=ori_tol, help=f"orientation tolerance, rad ({ori_tol:g})"
    )
    p.add_argument(
        "--plot",
        metavar="PATH",
        help=f"{plot} (.png, .pdf, .svg, .jpg, ...: the suffix says which)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--force", action="store_true", help="replace an existing --plot file")


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    v = sub.add_parser(
        "verify",
        help="check PoE FK against mj_forward on random joint values",
        description="Compare space- and body-form PoE with MuJoCo's mj_forward on random q. "
        "Exit 0 if both maxima are within tolerance, 1 if not, 2 on bad input.",
        epilog="examples:\n  poekin verify\n  poekin verify --plot fk.png --metrics metrics.csv\n"
        "  poekin verify franka_fr3 --frame attachment_site --within-limits --json\n"
        "  poekin verify unitree_go2 --all-frames\n"
        "  poekin verify --params ur5e-dh --against universal_robots_ur5e",
        formatter_class=fmt,
    )
    add_source(v, DEFAULT_ROBOT)
    add_params(v, "check these parameters instead of the model's own PoE")
    v.add_argument(
        "--against",
        metavar="SOURCE",
        help=f"the model to check --params against (default: {DEFAULT_ROBOT})",
    )
    add_sampling(v)
    v.add_argument(
        "--all-frames",
        action="store_true",
        help="check every body and site in one run (the whole tree on random qpos)",
    )
    add_floating_base(v)
    v.add_argument(
        "--within-limits",
        action="store_true",
        help="sample within joint limits instead of [-2 pi, 2 pi]",
    )
    _outputs(v, pos_tol=1e-5, ori_tol=1e-4, plot="write an error-distribution figure")
    v.add_argument("--metrics", metavar="PATH", help="append metric rows to this CSV")
    v.set_defaults(run=_cmd_verify)

    g = sub.add_parser(
        "diagnose",
        help="explain why a parameter set disagrees with a model",
        description="Compare your PoE set or DH table with the model's chain, joint by joint, "
        "after finding the best base alignment: base, flipped/tilted/offset axes, link lengths, "
        "M, and a bisection that replaces one part at a time. Exit 0 if the parameters match, "
        "1 if not, 2 on bad input.",
        epilog="examples:\n  poekin diagnose --params lynch-park-ur5\n"
        "  poekin diagnose --params my_ur5e.json --against universal_robots_ur5e "
        "--plot why.png\n"
        "  poekin diagnose --params my_robot_calibration.yaml --against ur5e-dh",
        formatter_class=fmt,
    )
    g.add_argument(
        "--params",
        metavar="FILE|NAME",
        required=True,
        help="your parameters: a DH table or PoE set as a .json/.yaml file, UR's calibration "
        f".yaml (ur_calibration's kinematics:), or a named set ({PARAM_NAMES})",
    )
    g.add_argument(
        "--against",
        metavar="SOURCE",
        help=f"Menagerie robot name, MJCF or URDF path (default: {DEFAULT_ROBOT}), or another "
        "parameter set (a named set or .json/.yaml file), e.g. ur5e-dh, UR's nominal UR5e",
    )
    add_ur_yaml_order(g)
    g.add_argument(
        "--frame", metavar="F", help="end frame: site or body name (default: the only site)"
    )
    add_sampling(g)
    _outputs(g, pos_tol=1e-6, ori_tol=1e-6, plot="draw both arms at q = 0")
    g.set_defaults(run=_cmd_diagnose, source=None)
