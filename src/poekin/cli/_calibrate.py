"""``poekin calibrate``: fit a model to measurements, or plan the poses to measure."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import pathlib
import sys
import warnings
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from poekin.cli._args import add_params, add_source, model_source, note

if TYPE_CHECKING:
    from poekin.calibration.model import Measure
from poekin.errors import InputError

__all__ = ["register"]


def _check_options(args: argparse.Namespace) -> None:
    """Every option, and the files to write, before any model is loaded or anything written."""
    from poekin.io.fileio import check_new_file, figure_format

    if args.plan is not None:
        for flag in ("measurements", "plot"):
            if getattr(args, flag):
                raise InputError(f"--plan proposes poses to measure: drop --{flag}")
        if args.plan < 1:
            raise InputError(f"--plan must be a whole number of poses, 1 or more, got {args.plan}")
        if args.candidates is not None and args.candidates < args.plan:
            raise InputError(f"--candidates must be at least --plan ({args.plan})")
        _check_constraints(args)
        if args.output:
            from poekin.io.fileio import array_format

            array_format(args.output, "--output")
            check_new_file(args.output, "planned poses", force=args.force)
        return
    if args.params:
        raise InputError(
            "--params goes with --plan N (to plan the poses for a parameter set); a fit starts "
            "from the model SOURCE the measurements were taken on"
        )
    for flag, given in (
        ("--range", args.range),
        ("--above-z", args.above_z is not None),
        ("--box", args.box),
    ):
        if given:
            raise InputError(f"{flag} goes with --plan N: it constrains the poses proposed")
    if not args.measurements:
        raise InputError(
            "give --measurements FILE (a .csv or .npz of joint readings and measured poses), or "
            "--plan N to propose the poses to measure"
        )
    for flag, value in (("--sigma-pos", args.sigma_pos), ("--sigma-ori", args.sigma_ori)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{flag} must be a positive number, got {value}")
    for flag, value in (("--prior-m", args.prior_m), ("--prior-rad", args.prior_rad)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"{flag} must be a positive number, got {value}")
    if args.folds < 0 or args.folds == 1:
        raise InputError(f"--folds must be 0 (none) or 2 or more, got {args.folds}")
    if args.output:
        if pathlib.Path(args.output).suffix.lower() != ".json":
            raise InputError(
                f"--output {args.output}: the calibrated parameters are a .json parameter file"
            )
        check_new_file(args.output, "parameters", force=args.force)
    if args.plot:
        figure_format(args.plot, "--plot")
        check_new_file(args.plot, "plot", force=args.force)
    if args.output and args.plot and pathlib.Path(args.output) == pathlib.Path(args.plot):
        raise InputError("--output and --plot name the same file")


def _number(text: str) -> float:
    """A finite number, or NaN for anything else (said by the caller, naming the option)."""
    try:
        value = float(text)
    except ValueError:
        return math.nan
    return value if math.isfinite(value) else math.nan


def _check_constraints(args: argparse.Namespace) -> None:
    """--range, --above-z and --box, as far as they can be checked without the model."""
    seen: set[str] = set()
    for joint, lo_text, hi_text in args.range or []:
        lo, hi = _number(lo_text), _number(hi_text)
        given = f"--range {joint} {lo_text} {hi_text}"
        if math.isnan(lo) or math.isnan(hi):
            raise InputError(
                f"{given}: LO and HI must be finite numbers (rad or m; degrees with --deg)"
            )
        if not lo < hi:
            raise InputError(f"{given}: LO must be below HI")
        if joint in seen:
            raise InputError(f"--range {joint} is given twice; give each joint one range")
        seen.add(joint)
    if args.above_z is not None and not math.isfinite(args.above_z):
        raise InputError(f"--above-z must be a finite height in m, got {args.above_z}")
    if args.box:
        if not all(math.isfinite(v) for v in args.box):
            raise InputError("--box takes six finite numbers: XMIN YMIN ZMIN XMAX YMAX ZMAX (m)")
        for k, axis in enumerate("XYZ"):
            lo, hi = args.box[k], args.box[k + 3]
            if not lo < hi:
                raise InputError(
                    f"--box: {axis}MIN {lo:g} is not below {axis}MAX {hi:g}; give the lower "
                    "corner, then the upper: XMIN YMIN ZMIN XMAX YMAX ZMAX (m)"
                )


def _ranges(args: argparse.Namespace, chain: Any) -> dict[str, tuple[float, float]]:
    """--range as joint name -> (low, high) in rad and m, checked against the chain: a name it
    has (or the nearest named), within the joint's limits (said in the units given)."""
    from poekin.errors import did_you_mean

    names = list(chain.joint_names)
    ranges: dict[str, tuple[float, float]] = {}
    for joint, lo_text, hi_text in args.range or []:
        given = f"--range {joint} {lo_text} {hi_text}"
        if joint not in names:
            raise InputError(
                f"{given}: {chain.robot or 'the chain'} has no joint {joint!r}; "
                f"{did_you_mean(joint, names)}"
            )
        k = names.index(joint)
        degrees = args.deg and chain.joint_types[k] == "revolute"
        scale = math.pi / 180 if degrees else 1.0
        lo, hi = float(lo_text) * scale, float(hi_text) * scale
        low, high = (float(v) for v in chain.limits[k])
        if lo < low or hi > high:
            unit = "deg" if degrees else "rad" if chain.joint_types[k] == "revolute" else "m"
            shown = [_inward(low / scale, math.ceil), _inward(high / scale, math.floor)]
            raise InputError(
                f"{given}: {joint}'s limits are [{shown[0]}, {shown[1]}] {unit}; give LO and HI "
                f"within them{'' if args.deg else ' (radians; degrees with --deg)'}"
            )
        ranges[joint] = (lo, hi)
    return ranges


def _inward(limit: float, rounding: Callable[[float], int]) -> str:
    """A joint limit to 4 decimals, rounded inwards (``math.ceil`` for a lower limit,
    ``math.floor`` for an upper) so that the number shown is within it."""
    if not math.isfinite(limit):
        return f"{limit}"
    text = f"{rounding(limit * 1e4) / 1e4:.4f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def _constraints_text(args: argparse.Namespace, chain: Any, plan: Any) -> str:
    """How the candidates were constrained, in the units given, and how many were kept; empty
    without constraints."""
    parts = []
    for joint, lo_text, hi_text in args.range or []:
        revolute = chain.joint_types[list(chain.joint_names).index(joint)] == "revolute"
        unit = ("deg" if args.deg else "rad") if revolute else "m"
        parts.append(f"{joint} in [{float(lo_text):g}, {float(hi_text):g}] {unit}")
    if plan.constraints.filters:
        parts.append(f"end frame {plan.constraints.region_text()}")
    if not parts:
        return ""
    counted = (
        f"{plan.kept:,} of {plan.drawn:,} candidates kept"
        if plan.constraints.filters
        else f"{plan.drawn:,} candidates drawn within {'it' if len(parts) == 1 else 'them'}"
    )
    return f"{'; '.join(parts)} ({counted})"


def _plan_chain(args: argparse.Namespace) -> Any:
    """The chain to plan for: --params as a chain (a DH table's), else the model's."""
    from poekin.chain import Chain
    from poekin.cli._describe import params_or_chain

    if not args.params:
        from poekin.io.loading import load

        return load(model_source(args, None), args.frame)
    read = params_or_chain(args)
    return read if isinstance(read, Chain) else read.to_chain()


def _plan(args: argparse.Namespace, chain: Any, out: TextIO) -> int:
    from poekin.calibration.identify import quality_text
    from poekin.calibration.model import model_of
    from poekin.calibration.plan import draw_candidates, make_plan, quality

    measure: Measure = "position" if args.positions else "pose"
    ranges = _ranges(args, chain)
    box = None if not args.box else (tuple(args.box[:3]), tuple(args.box[3:]))
    with _bar(args.plan, "plan", "pose") as step:
        plan = make_plan(
            chain,
            args.plan,
            measure=measure,
            candidates=args.candidates,
            seed=args.seed,
            ranges=ranges or None,
            above_z=args.above_z,
            box=box,
            progress=step,
        )
    q = plan.q
    cm = model_of(chain, measure)
    o1, cond = quality(cm, q)
    # as many random poses, drawn as the candidates were: within the limits, the same draw as
    # sample_joint_values of the sampling chain; with a height or box, 1,000 at a time until
    # enough meet them
    batch = max(args.plan, 1000) if plan.constraints.filters else args.plan
    drawn_q, _ = draw_candidates(chain, plan.constraints, batch, seed=args.seed + 1, want=args.plan)
    random_q = drawn_q[: args.plan]
    constrained = _constraints_text(args, chain, plan)
    what = "poses (position and orientation)" if measure == "pose" else "positions"
    where = "meeting the constraints" if constrained else "within the limits"
    if len(random_q) == args.plan:
        o1_random, cond_random = quality(cm, random_q)
        compared = f" (random poses {where}: {quality_text(cond_random, o1_random)})"
    else:  # too few drawn meet the constraints (the plan's candidates were more)
        o1_random = cond_random = math.nan
        compared = ""
    name = chain.robot or "the chain"
    if args.params:  # as poekin verify names them
        name = args.params if chain.robot in ("", args.params) else f"{args.params} ({chain.robot})"
    summary = f"{args.plan} {what} for {name} / {chain.frame!r}: {quality_text(cond, o1)}{compared}"
    lines = [summary] + ([f"constrained: {constrained}"] if constrained else [])
    if args.json:
        from poekin.io.fileio import finite_json

        print(
            json.dumps(
                finite_json(
                    {
                        "robot": chain.robot,
                        "frame": chain.frame,
                        "measure": measure,
                        "joint_names": list(chain.joint_names),
                        "q": q.tolist(),
                        "observability_o1": o1,
                        "condition_number": cond,
                        "random_observability_o1": o1_random,
                        "random_condition_number": cond_random,
                        "ranges": {k: list(v) for k, v in ranges.items()},
                        "above_z": plan.constraints.above_z,
                        "box": None if box is None else [list(c) for c in box],
                        "candidates_drawn": plan.drawn,
                        "candidates_kept": plan.kept,
                    }
                )
            ),
            file=out,
        )
    elif not args.output:
        for line in lines:
            print(f"# {line}", file=out)
        print(",".join(chain.joint_names), file=out)
        for row in q:
            print(",".join(f"{v:.6f}" for v in row), file=out)
    if args.output:
        from poekin.io.fileio import write_array

        write_array(args.output, q, name="q", columns=chain.joint_names)
        if not args.json:
            for line in lines:
                print(line, file=out)
            print(f"planned poses written to {args.output}", file=out)
    return 0


_BAR_DELAY = 1.0  # s: a step that takes longer shows its bar (issue 26: any over 2 s)


@contextlib.contextmanager
def _bar(total: int, desc: str, unit: str) -> Iterator[Callable[[int], None] | None]:
    """A progress callback (the count done so far) for a tqdm bar on stderr when it is a
    terminal, else None (tqdm is imported only then). The bar shows once the step has taken
    :data:`_BAR_DELAY` seconds: a short one leaves the terminal as it was."""
    if not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty()):
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=total, desc=desc, unit=unit, delay=_BAR_DELAY, leave=False) as bar:
        yield lambda done: bar.update(done - bar.n)


def _cmd_calibrate(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.calibration import calibrate
    from poekin.calibration.files import params_document, read_measurements, write_json
    from poekin.io.loading import load

    _check_options(args)
    if args.plan is not None:
        return _plan(args, _plan_chain(args), out)
    source = model_source(args, None)
    chain = load(source, args.frame)
    q, measured = read_measurements(args.measurements, chain, deg=args.deg)
    # the fit's notes wait for the check of its residual: a refusal is its one error line,
    # which names the likely cause itself
    with warnings.catch_warnings(record=True) as notes:
        result = calibrate(
            chain,
            q,
            measured,
            sigma_pos=args.sigma_pos,
            sigma_ori=args.sigma_ori,
            loss=args.loss,
            prior_m=args.prior_m,
            prior_rad=args.prior_rad,
            folds=args.folds,
            seed=args.seed,
        )
    result = _named(result, source)
    if args.output:
        _check_plausible(result, chain, q, measured, args)
    if not args.deg:
        revolute = np.array([t == "revolute" for t in chain.joint_types])
        if np.any(np.abs(q[:, revolute]) > 2 * np.pi + 1e-9):
            note(
                f"joint readings up to {np.max(np.abs(q[:, revolute])):g} are read as radians "
                "(more than a turn); if they are degrees, pass --deg"
            )
    for w in notes:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if args.output:
        write_json(pathlib.Path(args.output), params_document(result))
    if args.plot:
        from poekin.calibration.plot import plot_calibration

        plot_calibration(
            result,
            args.plot,
            title=f"{chain.robot} / {chain.frame}: calibrated on {result.poses} "
            f"{'poses' if result.measure == 'pose' else 'positions'}",
        )
    if args.json:
        from poekin.io.fileio import finite_json

        print(json.dumps(finite_json(result.summary())), file=out)
        return 0
    print(f"{chain.robot}  frame {chain.frame!r}  measurements {args.measurements}", file=out)
    for line in result.report():
        print(line, file=out)
    if args.output:
        print(f"calibrated parameters written to {args.output}", file=out)
    if args.plot:
        print(f"plot written to {args.plot}", file=out)
    return 0


# A calibrated chain that misses its measurements by more than this (m RMS) was fitted to wrong
# data: a robot differs from its model by millimetres, and the fit takes those out
_IMPLAUSIBLE_M = 0.01
# ... or whose orientations it misses by this much (rad): a robot's axes are off by mrad
_IMPLAUSIBLE_RAD = 0.05
_IMPLAUSIBLE_SIGMAS = 100  # or by this many times the noise the user gave (--sigma-pos/-ori)


def _check_plausible(
    result: Any, chain: Any, q: Any, measured: Any, args: argparse.Namespace
) -> None:
    """Refuse to write a calibration whose residual no difference between a robot and its model
    explains (issue 26: degrees read as radians, millimetres, swapped joint columns), naming the
    likely cause. Raises InputError: nothing is written."""
    limit = _IMPLAUSIBLE_M
    if args.sigma_pos is not None:
        limit = min(limit, _IMPLAUSIBLE_SIGMAS * args.sigma_pos)
    miss = result.residual_rms_m
    if miss <= limit:
        _check_orientations(result, args)
        return
    if miss <= _IMPLAUSIBLE_M:  # only the noise given rules it out
        raise _noise_below(
            f"the measurements by {miss * 1e3:.3g} mm",
            miss,
            "--sigma-pos",
            args.sigma_pos,
            "m",
            args,
        )
    revolute = np.array([t == "revolute" for t in chain.joint_types])
    p_meas = measured[:, :3, 3] if measured.ndim == 3 else measured
    p_model = chain.fk(q)[:, :3, 3]

    def spread(p: Any) -> float:
        return float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))

    ratio = spread(p_meas) / max(spread(p_model), 1e-12)
    if not args.deg and np.any(np.abs(q[:, revolute]) > 2 * np.pi + 1e-9):
        cause = (
            f"the joint readings (up to {np.max(np.abs(q[:, revolute])):.4g}) look like degrees: "
            "pass --deg"
        )
    elif ratio > 10:
        cause = (
            f"the measured positions spread {ratio:.3g} times as far as the model's: are they "
            "in millimetres? give metres"
        )
    else:
        cause = (
            "check that the joint columns hold the joints their header names (in radians and "
            "metres), and the frame that was measured (--frame)"
        )
    bound = "1 cm" if limit == _IMPLAUSIBLE_M else f"{_IMPLAUSIBLE_SIGMAS} x --sigma-pos"
    raise InputError(
        f"the calibrated chain still misses the measurements by {miss * 1e3:.3g} mm RMS, more "
        f"than any robot differs from its model ({bound}): {cause}; {args.output} not written"
    )


def _check_orientations(result: Any, args: argparse.Namespace) -> None:
    """:func:`_check_plausible` for the orientations of measured poses."""
    miss = result.residual_rms_rad
    if miss is None:
        return
    sigma = args.sigma_ori
    if miss > _IMPLAUSIBLE_RAD:
        raise InputError(
            f"the calibrated chain still misses the measured orientations by {miss * 1e3:.3g} "
            f"mrad RMS ({math.degrees(miss):.3g} deg), more than any robot differs from its "
            f"model ({_IMPLAUSIBLE_RAD * 1e3:g} mrad): check that the quaternion columns are "
            "qw,qx,qy,qz (w first; x,y,z,w order turns them) and the frame that was measured "
            f"(--frame); {args.output} not written"
        )
    if sigma is not None and miss > _IMPLAUSIBLE_SIGMAS * sigma:
        raise _noise_below(
            f"the measured orientations by {miss * 1e3:.3g} mrad",
            miss,
            "--sigma-ori",
            sigma,
            "rad",
            args,
        )


def _noise_below(
    missed: str, miss: float, flag: str, sigma: float, unit: str, args: argparse.Namespace
) -> InputError:
    """The refusal of a fit that only the noise given (``flag``, ``sigma`` in ``unit``) rules
    out: ``missed`` says what it misses by how much (RMS)."""
    return InputError(
        f"the calibrated chain misses {missed} RMS, {miss / sigma:.3g} times the {flag} given "
        f"({sigma:g} {unit}): that is below the measurements' real noise; give the tracker's "
        f"noise, or leave {flag} out (estimated from the residuals); {args.output} not written"
    )


def _named(result: Any, source: str) -> Any:
    """The result with the model named as the user wrote it (for the advice it gives)."""
    import dataclasses

    return dataclasses.replace(result, source=source)


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    c = sub.add_parser(
        "calibrate",
        help="fit a model to the robot you measured, or plan the poses to measure",
        description="Fit the model's chain to measured poses (or positions) of its end frame, "
        "taken in any fixed frame (a laser tracker's, a camera's): the measuring frame, the "
        "tool, the joint axes and the encoder offsets, as a complete, minimal set of PoE "
        "corrections, only the combinations the data can tell apart. Prints what the data "
        "identify (rank, condition number, observability O1, standard errors, a k-fold held-out "
        "residual) and each joint's change in mm and mrad; --output writes the calibrated robot "
        "as a PoE parameter file (--params, poekin.load_params): its FK for the encoder readings "
        "is the measured frame in the robot's own base frame, and its registration the base in "
        "the measuring frame (poekin.load_registration); poekin export writes it for the "
        "controller or ROS. --plan N proposes N poses to measure, for the model or a parameter "
        "set (--params), with joints kept to sub-ranges (--range) and the end frame above a "
        "height (--above-z) or in a box (--box). Exit 0 on success, 2 on bad input.",
        epilog="measurements: a .csv whose header names the joints, then x,y,z (m) and optionally "
        "qw,qx,qy,qz; or a .npz with q and T (N, 4, 4) or p (N, 3).\n"
        "examples:\n"
        "  poekin calibrate universal_robots_ur5e --plan 30\n"
        "  poekin calibrate universal_robots_ur5e --plan 40 --positions --output poses.csv\n"
        "  poekin calibrate universal_robots_ur5e --plan 40 --above-z 0.05 "
        "--range shoulder_lift_joint -180 0 --deg\n"
        "  poekin calibrate --params my_robot.json --plan 30 --box -0.8 -0.8 0.1 0.8 0.8 0.9\n"
        "  poekin calibrate universal_robots_ur5e --measurements tracker.csv "
        "--output my_robot.json --plot calibration.png\n"
        "  poekin calibrate universal_robots_ur5e --measurements tracker.csv --json",
        formatter_class=fmt,
    )
    add_source(c)
    c.add_argument(
        "--measurements",
        metavar="FILE",
        help="joint readings and measured poses: a .csv or .npz file (see below)",
    )
    c.add_argument(
        "--deg", action="store_true", help="revolute joint readings (and --range) are in degrees"
    )
    c.add_argument(
        "--output",
        metavar="FILE",
        help="write the calibrated parameters (.json); with --plan, the poses (.csv, .npy, ...)",
    )
    c.add_argument("--plot", metavar="PATH", help="residuals before/after and per-joint changes")
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.add_argument("--force", action="store_true", help="replace existing --output/--plot files")
    c.add_argument(
        "--sigma-pos", type=float, metavar="M", help="position noise per axis, m (estimated)"
    )
    c.add_argument(
        "--sigma-ori", type=float, metavar="RAD", help="orientation noise per axis, rad (estimated)"
    )
    c.add_argument(
        "--loss",
        choices=("linear", "huber", "soft_l1", "cauchy"),  # poekin.calibration.LOSSES
        default="linear",
        help="robust loss for outliers (linear: plain least squares; cauchy lets gross ones fade)",
    )
    c.add_argument(
        "--prior-m",
        type=float,
        default=1e-3,
        metavar="M",
        help="a length the data must determine better than to fit it (0.001)",
    )
    c.add_argument(
        "--prior-rad",
        type=float,
        default=1e-2,
        metavar="RAD",
        help="an angle the data must determine better than to fit it (0.01)",
    )
    c.add_argument("--folds", type=int, default=5, help="k of the k-fold held-out residual (5)")
    c.add_argument("--plan", type=int, metavar="N", help="propose N poses to measure instead")
    c.add_argument(
        "--positions", action="store_true", help="--plan for a tracker that measures points only"
    )
    c.add_argument("--candidates", type=int, metavar="C", help="--plan: random candidates")
    c.add_argument(
        "--range",
        nargs=3,
        action="append",
        metavar=("JOINT", "LO", "HI"),
        help="--plan: keep JOINT within [LO, HI] (rad or m; degrees with --deg), inside its "
        "limits; repeat for more joints",
    )
    c.add_argument(
        "--above-z",
        type=float,
        metavar="Z",
        help="--plan: only poses whose end frame is at z >= Z (m, the base frame), e.g. 0.05 "
        "above the table the robot stands on",
    )
    c.add_argument(
        "--box",
        type=float,
        nargs=6,
        metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
        help="--plan: only poses whose end frame lies in this box (m, the base frame)",
    )
    add_params(c, "--plan: plan for these parameters instead of a model")
    c.add_argument("--seed", type=int, default=0, help="random seed: folds, --plan (0)")
    c.set_defaults(run=_cmd_calibrate)
