"""The ``poekin`` command line: ``verify``, ``screws`` and ``fk``.

Exit codes: 0 success (verify: within tolerance), 1 verify out of tolerance, 2 bad input.
Every expected failure prints one ``poekin: error: ...`` line and no traceback.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any, NoReturn, TextIO

import numpy as np

from poekin.errors import InputError, PoekinError

__all__ = ["main"]

DEFAULT_ROBOT = "universal_robots_ur5e"
_EXIT_FAIL = 1
_EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage errors in one line, pointing to ``--help``."""

    def error(self, message: str) -> NoReturn:
        self.exit(_EXIT_USAGE, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def _check_new_file(path: str, what: str, *, force: bool = False) -> pathlib.Path:
    p = pathlib.Path(path)
    if not p.parent.is_dir():
        raise InputError(f"cannot write the {what} to {path}: directory {p.parent} does not exist")
    if p.is_dir():
        raise InputError(f"cannot write the {what} to {path}: it is a directory")
    if p.exists() and not force:
        raise InputError(
            f"{path} already exists; pass --force to replace it, or choose another path"
        )
    return p


# --- verify -----------------------------------------------------------------------------------


def _cmd_verify(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.metrics import append_metrics, check_metrics_file, metric_rows, sha256_files
    from poekin.sources import load_model
    from poekin.verify import verify

    if args.samples < 1:
        raise InputError(f"--samples must be at least 1, got {args.samples}")
    if args.plot:
        _check_new_file(args.plot, "plot", force=args.force)
    if args.metrics:
        check_metrics_file(args.metrics)
    loaded = load_model(args.source)
    report = verify(
        loaded,
        args.frame,
        samples=args.samples,
        seed=args.seed,
        within_limits=args.within_limits,
        pos_tol=args.pos_tol,
        ori_tol=args.ori_tol,
        progress=True,
    )
    if args.json:
        print(json.dumps(report.summary()), file=out)
    else:
        rng = "within joint limits" if args.within_limits else "in [-2 pi, 2 pi]"
        print(
            f"{report.robot}  frame {report.frame!r}  {report.samples} samples {rng}, "
            f"seed {report.seed}, vs mj_forward",
            file=out,
        )
        print(
            f"{'':12}{'max pos [m]':>14}{'median pos [m]':>16}"
            f"{'max ori [rad]':>15}{'median ori [rad]':>18}",
            file=out,
        )
        for method, s in report.per_method().items():
            print(
                f"{method:12}{_fmt(s['max_pos_err_m']):>14}{_fmt(s['median_pos_err_m']):>16}"
                f"{_fmt(s['max_ori_err_rad']):>15}{_fmt(s['median_ori_err_rad']):>18}",
                file=out,
            )
        verdict = "PASS" if report.passed else "FAIL"
        print(f"{verdict}: tolerances {report.pos_tol:g} m, {report.ori_tol:g} rad", file=out)
    if args.plot:
        from poekin.plotting import plot_errors

        plot_errors(
            report.pos_err,
            report.ori_err,
            title=f"{report.robot} / {report.frame}: PoE vs mj_forward, {report.samples} samples",
            path=args.plot,
            pos_tol=report.pos_tol,
            ori_tol=report.ori_tol,
        )
        if not args.json:
            print(f"plot written to {args.plot}", file=out)
    if args.metrics:
        notes = f"frame={report.frame}; range={'limits' if args.within_limits else '[-2pi,2pi]'}"
        rows = metric_rows(
            report,
            experiment=f"fk_verify_{loaded.short_name}",
            model_sha=sha256_files(loaded.files, loaded.xml_path.parent),
            notes=notes,
        )
        append_metrics(args.metrics, rows)
        if not args.json:
            print(f"{len(rows)} metric rows appended to {args.metrics}", file=out)
    return 0 if report.passed else _EXIT_FAIL


# --- screws -----------------------------------------------------------------------------------


def _row(values: np.ndarray[Any, Any]) -> str:
    return " ".join(f"{x + 0.0: .15f}" for x in values)  # + 0.0 prints -0.0 as 0.0


def _matrix_lines(M: np.ndarray[Any, Any]) -> list[str]:
    return ["  " + _row(row) for row in M]


def _cmd_screws(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.import_mujoco import load

    chain = load(args.source, args.frame)
    if args.json:
        print(json.dumps(_finite_json(chain.describe())), file=out)
        return 0
    form, screws = ("body B_i", chain.body_screws) if args.body else ("space S_i", chain.screws)
    print(
        f"{chain.robot}  frame {chain.frame!r}  {chain.n_joints} joints, {form} = [w; v]", file=out
    )
    width = max(len(n) for n in chain.joint_names) if chain.joint_names else 5
    for name, kind, S in zip(chain.joint_names, chain.joint_types, screws, strict=True):
        print(f"  {name:{width}} {kind[0].upper()} " + _row(S), file=out)
    print("M = T_world_frame(q = 0):", file=out)
    print("\n".join(_matrix_lines(chain.home)), file=out)
    return 0


def _finite_json(obj: Any) -> Any:
    """Replace non-finite floats (unlimited joints) with None so the output is strict JSON."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite_json(v) for v in obj]
    return obj


# --- fk ---------------------------------------------------------------------------------------


def _load_q_file(path: str) -> np.ndarray[Any, Any]:
    p = pathlib.Path(path)
    if not p.is_file():
        raise InputError(f"--input {path}: no such file")
    try:
        arr: np.ndarray[Any, Any] = np.load(p, allow_pickle=False)
    except (ValueError, OSError) as e:
        raise InputError(f"--input {path}: not a .npy array file ({e})") from None
    return arr


def _cmd_fk(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.import_mujoco import load

    if (args.q is None) == (args.input is None):
        raise InputError("give joint values with --q Q1 ... Qn, or a batch with --input q.npy")
    if args.input is not None and args.output is None:
        raise InputError("--input needs --output T.npy for the (N, 4, 4) poses")
    if args.output is not None:
        if args.input is None:
            raise InputError("--output goes with --input q.npy")
        _check_new_file(args.output, "poses", force=args.force)
    chain = load(args.source, args.frame)
    if args.input is not None:
        T = chain.fk(_load_q_file(args.input))
        np.save(args.output, T)
        print(
            f"{T.shape[0] if T.ndim > 2 else 1} poses {T.shape} written to {args.output}", file=out
        )
        return 0
    T = chain.fk(args.q)
    if args.json:
        print(json.dumps({"frame": chain.frame, "q": list(args.q), "T": T.tolist()}), file=out)
    else:
        print(f"T_world_{chain.frame} =", file=out)
        print("\n".join(_matrix_lines(T)), file=out)
    return 0


# --- parser -----------------------------------------------------------------------------------


def _build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = _Parser(
        prog="poekin",
        description="Product-of-Exponentials forward kinematics derived from MuJoCo models.",
        epilog="example:\n  poekin verify --plot fk.png --metrics metrics.csv",
        formatter_class=fmt,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def source(p: argparse.ArgumentParser, default: str | None = None) -> None:
        p.add_argument(
            "source",
            metavar="SOURCE",
            nargs="?" if default else None,
            default=default,
            help="Menagerie robot name or path to an MJCF file"
            + (f" (default: {default})" if default else ""),
        )
        p.add_argument(
            "--frame", metavar="F", help="end frame: site or body name (default: the only site)"
        )

    v = sub.add_parser(
        "verify",
        help="check PoE FK against mj_forward on random joint values",
        description="Compare space- and body-form PoE with MuJoCo's mj_forward on random q. "
        "Exit 0 if both maxima are within tolerance, 1 if not, 2 on bad input.",
        epilog="examples:\n  poekin verify\n  poekin verify --plot fk.png --metrics metrics.csv\n"
        "  poekin verify franka_fr3 --frame attachment_site --within-limits --json",
        formatter_class=fmt,
    )
    source(v, DEFAULT_ROBOT)
    v.add_argument("--samples", type=int, default=1000, help="random configurations (1000)")
    v.add_argument("--seed", type=int, default=0, help="random seed (0)")
    v.add_argument(
        "--within-limits",
        action="store_true",
        help="sample within joint limits instead of [-2 pi, 2 pi]",
    )
    v.add_argument("--pos-tol", type=float, default=1e-5, help="max position error, m (1e-5)")
    v.add_argument("--ori-tol", type=float, default=1e-4, help="max orientation error, rad (1e-4)")
    v.add_argument("--plot", metavar="PATH", help="write an error-distribution PNG")
    v.add_argument("--metrics", metavar="PATH", help="append metric rows to this CSV")
    v.add_argument("--json", action="store_true", help="print one JSON object")
    v.add_argument("--force", action="store_true", help="replace an existing --plot file")
    v.set_defaults(run=_cmd_verify)

    s = sub.add_parser(
        "screws",
        help="print the screw axes and home pose M",
        description="Print the screw axes S_i = [w; v] (space frame, or body frame with --body) "
        "and the home pose M, all derived from the model.",
        epilog="examples:\n  poekin screws universal_robots_ur5e\n"
        "  poekin screws franka_emika_panda --frame hand --body --json",
        formatter_class=fmt,
    )
    source(s)
    s.add_argument("--body", action="store_true", help="body-frame screws B_i = Ad(M^-1) S_i")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(run=_cmd_screws)

    f = sub.add_parser(
        "fk",
        help="forward kinematics for joint values",
        description="Print T_world_frame(q) for one configuration, or map a batch of q "
        "(an (N, n) .npy file) to an (N, 4, 4) .npy file.",
        epilog="examples:\n  poekin fk universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin fk universal_robots_ur5e --input q.npy --output T.npy",
        formatter_class=fmt,
    )
    source(f)
    f.add_argument("--q", type=float, nargs="+", metavar="Q", help="joint values (rad, m)")
    f.add_argument("--input", metavar="Q.npy", help="(N, n) array of joint values")
    f.add_argument("--output", metavar="T.npy", help="where to save the (N, 4, 4) poses")
    f.add_argument("--force", action="store_true", help="replace an existing --output file")
    f.add_argument("--json", action="store_true", help="print one JSON object")
    f.set_defaults(run=_cmd_fk)
    return parser


def _one_line_warnings() -> Callable[..., None]:
    def show(message: Warning | str, category: type[Warning], *_: Any, **__: Any) -> None:
        print(f"poekin: note: {message}", file=sys.stderr)

    return show


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``poekin`` console script; returns the exit code."""
    parser = _build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return _EXIT_USAGE
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warnings()
        try:
            return int(args.run(args, sys.stdout))
        except PoekinError as e:
            print(f"poekin: error: {e}", file=sys.stderr)
            return _EXIT_USAGE
        except KeyboardInterrupt:
            print("poekin: interrupted", file=sys.stderr)
            return 130


if __name__ == "__main__":
    sys.exit(main())
