"""``poekin calibrate``: fit a model to measurements, or plan the poses to measure."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import pathlib
import sys
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from poekin.cli._args import add_source, model_source, note

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
        if args.output:
            from poekin.io.fileio import array_format

            array_format(args.output, "--output")
            check_new_file(args.output, "planned poses", force=args.force)
        return
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


def _plan(args: argparse.Namespace, chain: Any, out: TextIO) -> int:
    from poekin.calibration import plan_poses
    from poekin.calibration.identify import quality_text
    from poekin.calibration.model import model_of
    from poekin.calibration.plan import quality, sampling_chain
    from poekin.verification.verify import sample_joint_values

    measure: Measure = "position" if args.positions else "pose"
    with _bar(args.plan, "plan", "pose") as step:
        q = plan_poses(
            chain,
            args.plan,
            measure=measure,
            candidates=args.candidates,
            seed=args.seed,
            progress=step,
        )
    cm = model_of(chain, measure)
    o1, cond = quality(cm, q)
    random_q = sample_joint_values(
        sampling_chain(chain), args.plan, seed=args.seed + 1, within_limits=True
    )
    o1_random, cond_random = quality(cm, random_q)
    what = "poses (position and orientation)" if measure == "pose" else "positions"
    summary = (
        f"{args.plan} {what} for {chain.robot or 'the chain'} / {chain.frame!r}: "
        f"{quality_text(cond, o1)} (random poses within the limits: "
        f"{quality_text(cond_random, o1_random)})"
    )
    if args.json:
        print(
            json.dumps(
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
                }
            ),
            file=out,
        )
    elif not args.output:
        print(f"# {summary}", file=out)
        print(",".join(chain.joint_names), file=out)
        for row in q:
            print(",".join(f"{v:.6f}" for v in row), file=out)
    if args.output:
        from poekin.io.fileio import write_array

        write_array(args.output, q, name="q", columns=chain.joint_names)
        if not args.json:
            print(summary, file=out)
            print(f"planned poses written to {args.output}", file=out)
    return 0


@contextlib.contextmanager
def _bar(total: int, desc: str, unit: str) -> Iterator[Callable[[int], None] | None]:
    """A progress callback (the count done so far) for a tqdm bar on stderr when it is a
    terminal and ``total`` is large enough to take seconds, else None (tqdm is imported only
    then)."""
    if total < 200 or not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty()):
        yield None
        return
    from tqdm import tqdm

    with tqdm(total=total, desc=desc, unit=unit, delay=0.5, leave=False) as bar:
        yield lambda done: bar.update(done - bar.n)


def _cmd_calibrate(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.calibration import calibrate
    from poekin.calibration.files import params_document, read_measurements, write_json
    from poekin.io.loading import load

    _check_options(args)
    source = model_source(args, None)
    chain = load(source, args.frame)
    if args.plan is not None:
        return _plan(args, chain, out)
    q, measured = read_measurements(args.measurements, chain, deg=args.deg)
    if not args.deg:
        revolute = np.array([t == "revolute" for t in chain.joint_types])
        if np.any(np.abs(q[:, revolute]) > 2 * np.pi + 1e-9):
            note(
                f"joint readings up to {np.max(np.abs(q[:, revolute])):g} are read as radians "
                "(more than a turn); if they are degrees, pass --deg"
            )
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
_IMPLAUSIBLE_SIGMAS = 100  # or by this many times the noise the user gave (--sigma-pos)


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
        return
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
        "controller or ROS. --plan N proposes N poses to measure. Exit 0 on success, 2 on bad "
        "input.",
        epilog="measurements: a .csv whose header names the joints, then x,y,z (m) and optionally "
        "qw,qx,qy,qz; or a .npz with q and T (N, 4, 4) or p (N, 3).\n"
        "examples:\n"
        "  poekin calibrate universal_robots_ur5e --plan 30\n"
        "  poekin calibrate universal_robots_ur5e --plan 40 --positions --output poses.csv\n"
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
    c.add_argument("--deg", action="store_true", help="revolute joint readings are in degrees")
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
    c.add_argument("--seed", type=int, default=0, help="random seed: folds, --plan (0)")
    c.set_defaults(run=_cmd_calibrate)
