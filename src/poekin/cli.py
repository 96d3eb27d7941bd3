"""The ``poekin`` command line: ``verify``, ``screws``, ``fk``, ``dh`` and ``diagnose``.

Exit codes: 0 success (verify: within tolerance; diagnose: parameters match), 1 verify out of
tolerance or diagnose found differences, 2 bad input.
Every expected failure prints one ``poekin: error: ...`` line and no traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

import numpy as np

from poekin.errors import InputError, PoekinError

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.dh import DHTable

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


# --- parameter sets ----------------------------------------------------------------------------


def _params(spec: str) -> Chain | DHTable:
    from poekin.paramfile import load_params

    return load_params(spec)


def _params_or_chain(args: argparse.Namespace) -> Chain | DHTable:
    """``--params`` if given, else the chain of the positional model SOURCE (not both)."""
    from poekin.loading import load

    if args.params and args.source:
        raise InputError("give a model SOURCE or --params FILE|NAME, not both")
    return _params(args.params) if args.params else load(_model_source(args, None), args.frame)


def _import_mujoco_without_gl() -> None:
    """Import MuJoCo with its OpenGL backends off, unless the user chose one with ``MUJOCO_GL``.

    The command line never renders with MuJoCo (plots use matplotlib), but MuJoCo's default
    backend, GLFW, looks for its library when MuJoCo is imported, and starts a Python subprocess
    to read the library's version: about 0.1 s of every command. The variable is set only for
    that import, so nothing else in the process, or started from it, sees it.
    """
    if "mujoco" in sys.modules or "MUJOCO_GL" in os.environ:
        return
    os.environ["MUJOCO_GL"] = "disable"
    try:
        import mujoco  # noqa: F401
    finally:
        del os.environ["MUJOCO_GL"]


def _model_source(args: argparse.Namespace, default: str | None = DEFAULT_ROBOT) -> str:
    """The model to compare with: ``--against`` or the positional SOURCE (not both).

    A model is loaded next, so MuJoCo is imported here (:func:`_import_mujoco_without_gl`).
    """
    against = getattr(args, "against", None)
    if against and args.source and against != args.source:
        raise InputError(f"two models given ({args.source!r} and --against {against!r}); give one")
    source = against or args.source or default
    if source is None:
        raise InputError(
            "give a model: a Menagerie robot name or an MJCF path (or --params FILE|NAME)"
        )
    _import_mujoco_without_gl()
    return str(source)


# --- verify -----------------------------------------------------------------------------------


def _check_run_options(args: argparse.Namespace) -> None:
    """--samples, --pos-tol and --ori-tol of verify and diagnose."""
    if args.samples < 1:
        raise InputError(f"--samples must be at least 1, got {args.samples}")
    for flag, value in (("--pos-tol", args.pos_tol), ("--ori-tol", args.ori_tol)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{flag} must be a positive number, got {value}")
    if args.plot:
        _check_new_file(args.plot, "plot", force=args.force)


def _cmd_verify(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.sources import load_model
    from poekin.verify import verify

    _check_run_options(args)
    if args.metrics:
        from poekin.metrics import check_metrics_file

        check_metrics_file(args.metrics)
    if args.against and not args.params:
        raise InputError("--against SOURCE goes with --params FILE|NAME (what to check)")
    params = _params(args.params) if args.params else None
    loaded = load_model(_model_source(args))
    report = verify(
        loaded,
        args.frame,
        all_frames=args.all_frames,
        params=params,
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
        checked = f"{args.params} against " if args.params else ""
        frame = "every body and site" if args.all_frames else f"frame {report.frame!r}"
        print(
            f"{checked}{report.robot}  {frame}  {report.samples} samples {rng}, "
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
        if len(report.frame_errors) > 1:
            worst = max(report.frame_errors, key=lambda f: report.frame_errors[f])
            pos, ori = report.frame_errors[worst]
            print(
                f"{len(report.frame_errors)} frames; worst {worst!r}: {_fmt(pos)} m, "
                f"{_fmt(ori)} rad",
                file=out,
            )
        verdict = "PASS" if report.passed else "FAIL"
        print(f"{verdict}: tolerances {report.pos_tol:g} m, {report.ori_tol:g} rad", file=out)
    if args.plot:
        from poekin.plotting import plot_errors

        plot_errors(
            report.pos_err,
            report.ori_err,
            title=f"{args.params + ' vs ' if args.params else ''}{report.robot} / "
            f"{report.frame}: FK vs mj_forward, {report.samples} samples",
            path=args.plot,
            pos_tol=report.pos_tol,
            ori_tol=report.ori_tol,
        )
        if not args.json:
            print(f"plot written to {args.plot}", file=out)
    if args.metrics:
        from poekin.metrics import append_metrics, metric_rows, sha256_files

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
    return 0 if report.passed else _EXIT_FAIL


# --- screws -----------------------------------------------------------------------------------


def _row(values: np.ndarray[Any, Any]) -> str:
    return " ".join(f"{x + 0.0: .15f}" for x in values)  # + 0.0 prints -0.0 as 0.0


def _matrix_lines(M: np.ndarray[Any, Any]) -> list[str]:
    return ["  " + _row(row) for row in M]


def _cmd_screws(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.loading import load

    chain = load(_model_source(args, None), args.frame)
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


def _fk_function(args: argparse.Namespace) -> tuple[Callable[[Any], Any], tuple[str, ...]]:
    """``(fk, frame names)``: the whole tree with ``--all-frames``, else one frame's chain."""
    if not args.all_frames:
        chain = _params_or_chain(args)
        return chain.fk, (chain.frame,)
    from poekin.loading import load_tree

    if args.params or args.frame:
        raise InputError(
            "--all-frames poses every frame of a model: give SOURCE, not --frame/--params"
        )
    tree = load_tree(_model_source(args, None))
    return tree.fk, tree.frame_names


def _check_q_args(args: argparse.Namespace, result: str, file_example: str) -> None:
    """``--q`` or ``--input`` (one of them); ``--input`` with ``--output``, a new file."""
    if (args.q is None) == (args.input is None):
        raise InputError("give joint values with --q Q1 ... Qn, or a batch with --input q.npy")
    if args.input is not None and args.output is None:
        raise InputError(f"--input needs --output {file_example} for the {result}")
    if args.output is not None:
        if args.input is None:
            raise InputError("--output goes with --input q.npy")
        _check_new_file(args.output, result, force=args.force)


def _cmd_fk(args: argparse.Namespace, out: TextIO) -> int:
    _check_q_args(args, "poses", "T.npy")
    fk, frames = _fk_function(args)
    if args.input is not None:
        T = fk(_load_q_file(args.input))
        np.save(args.output, T)
        print(f"poses of shape {T.shape} written to {args.output}", file=out)
        if args.all_frames:
            print(f"frames (axis -3): {', '.join(frames)}", file=out)
        return 0
    T = fk(args.q)
    if not args.all_frames:
        T = T[None]
    if args.json:
        poses = {f: T[k].tolist() for k, f in enumerate(frames)}
        body = {"frames": poses} if args.all_frames else {"frame": frames[0], "T": poses[frames[0]]}
        print(json.dumps({**body, "q": list(args.q)}), file=out)
        return 0
    for k, f in enumerate(frames):
        print(f"T_world_{f} =", file=out)
        print("\n".join(_matrix_lines(T[k])), file=out)
    return 0


# --- jacobian ----------------------------------------------------------------------------------


def _jacobian_function(
    args: argparse.Namespace,
) -> tuple[Callable[[Any], Any], str, tuple[str, ...]]:
    """``(q -> J, frame, column names)``: the chain to the frame, or with ``--tree`` the whole
    model (q is qpos, columns are qvel)."""
    from poekin.chain import Chain

    if not args.tree:
        chain = _params_or_chain(args)
        if not isinstance(chain, Chain):
            chain = chain.to_chain()
        method = getattr(chain, f"jacobian_{args.convention}")
        return method, chain.frame, chain.joint_names
    from poekin.loading import load_tree

    if args.params:
        raise InputError("--tree takes the whole model from SOURCE, not --params")
    tree = load_tree(_model_source(args, None))
    frame = args.frame
    if frame is None:
        sites = tree.frame_names[len(tree.body_names) :]
        if len(sites) != 1:
            raise InputError(
                f"the model has {len(sites)} sites: name the frame with --frame "
                f"({', '.join(tree.frame_names[:8])}{', ...' if tree.n_frames > 8 else ''})"
            )
        frame = sites[0]
    tree.frame_index(frame)  # an unknown frame is said now, before q is read

    def jacobian(qpos: Any) -> Any:
        return tree.jacobian(qpos, frame, args.convention)

    return jacobian, frame, tree.dof_names()


def _cmd_jacobian(args: argparse.Namespace, out: TextIO) -> int:
    _check_q_args(args, "Jacobians", "J.npy")
    jacobian, frame, columns = _jacobian_function(args)
    if args.input is not None:
        J = jacobian(_load_q_file(args.input))
        np.save(args.output, J)
        print(f"{args.convention} Jacobians of shape {J.shape} written to {args.output}", file=out)
        return 0
    J = jacobian(args.q)
    if args.json:
        body = {"frame": frame, "convention": args.convention, "q": list(args.q)}
        print(json.dumps({**body, "columns": list(columns), "J": J.tolist()}), file=out)
        return 0
    rows = "[w; v_frame] in world coordinates" if args.convention == "world" else "[w; v]"
    print(f"J_{args.convention} of {frame!r} (6 x {J.shape[-1]}), rows {rows}", file=out)
    print(f"columns: {', '.join(columns)}", file=out)
    print("\n".join(_matrix_lines(J)), file=out)
    return 0


# --- dh ----------------------------------------------------------------------------------------


def _dh_table(args: argparse.Namespace) -> DHTable:
    from poekin.dh import DHTable, dh_from_chain

    if args.parallel_tol <= 0:
        raise InputError(f"--parallel-tol must be positive, got {args.parallel_tol}")
    obj = _params_or_chain(args)
    if isinstance(obj, DHTable):
        if obj.convention == args.convention:
            return obj
        obj = obj.to_chain()
    return dh_from_chain(obj, args.convention, parallel_tol=args.parallel_tol)


def _shown(x: float) -> float:
    """``x`` for a 6-decimal column: rounding residue such as -1e-17 prints as 0.000000."""
    return 0.0 if abs(x) < 5e-7 else x


def _cmd_dh(args: argparse.Namespace, out: TextIO) -> int:
    table = _dh_table(args)
    if args.json:
        print(json.dumps(table.describe()), file=out)
        return 0
    std = table.convention == "standard"
    form = (
        "standard (Denavit-Hartenberg): Rz(theta) Tz(d) Tx(a) Rx(alpha)"
        if std
        else "modified (Craig): Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta) Tz(d)"
    )
    source = table.robot or args.params or args.source
    print(f"{source}  frame {table.frame!r}  {form}", file=out)
    width = max([len(n) for n in table.joint_names] + [5])
    a, al = ("a", "alpha") if std else ("a(i-1)", "alpha(i-1)")
    print(
        f"  {'joint':{width}}    {a + ' [m]':>12}{al + ' [rad]':>18}{'d [m]':>12}"
        f"{'theta_off [rad]':>17}",
        file=out,
    )
    for row in table.rows():
        values = [_shown(row[k]) for k in ("a", "alpha", "d", "theta_offset")]
        print(
            f"  {row['joint']:{width}}  {row['joint_type'][0].upper()} "
            f"{values[0]:12.6f}{values[1]:18.6f}{values[2]:12.6f}{values[3]:17.6f}",
            file=out,
        )
    print("base = T_world_frame0:", file=out)
    print("\n".join(_matrix_lines(table.base)), file=out)
    print(f"tool = T_frame{table.n_joints}_{table.frame}:", file=out)
    print("\n".join(_matrix_lines(table.tool)), file=out)
    for note in table.notes:
        print(f"note: {note}", file=out)
    return 0


# --- diagnose ----------------------------------------------------------------------------------


def _cmd_diagnose(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.diagnose import diagnose
    from poekin.loading import load

    _check_run_options(args)
    yours = _params(args.params)
    model = load(_model_source(args), args.frame)
    d = diagnose(
        yours,
        model,
        samples=args.samples,
        seed=args.seed,
        pos_tol=args.pos_tol,
        ori_tol=args.ori_tol,
    )
    if args.plot:
        from poekin.plotting import plot_diagnosis

        verdict = "match" if d.matches else "mismatch"
        plot_diagnosis(
            d, args.plot, title=f"{args.params} vs {model.robot} / {model.frame}: {verdict}"
        )
    if args.json:
        print(json.dumps(d.summary()), file=out)
        return 0 if d.matches else _EXIT_FAIL
    print(
        f"{args.params} vs {model.robot}  frame {model.frame!r}  {d.samples} random q in "
        f"[-2 pi, 2 pi], seed {d.seed}",
        file=out,
    )
    errs = f"max error {_fmt(d.max_pos_err_m)} m, {_fmt(d.max_ori_err_rad)} rad"
    if d.matches:
        print(
            f"MATCH: {errs}, within {d.pos_tol:g} m, {d.ori_tol:g} rad",
            file=out,
        )
        return 0
    print(
        f"MISMATCH: {errs} (at q = 0: {_fmt(d.home_pos_err_m)} m, "
        f"{_fmt(d.home_ori_err_rad)} rad); after aligning the base: "
        f"{_fmt(d.aligned_max_pos_err_m)} m, {_fmt(d.aligned_max_ori_err_rad)} rad",
        file=out,
    )
    print(f"differences (above {d.pos_tol:g} m, {d.ori_tol:g} rad):", file=out)
    for f in d.findings:
        print(f"  - {f.message}", file=out)
    if d.symptoms:
        print("what the errors point to:", file=out)
        for text in d.symptoms:
            print(f"  - {text}", file=out)
    if d.bisect:
        print(
            "bisection: replace one part at a time by the model's (largest gain first):", file=out
        )
        for k, step in enumerate(d.bisect, 1):
            print(
                f"  {k}. {step.part:32} -> max error {_fmt(step.max_pos_err_m)} m, "
                f"{_fmt(step.max_ori_err_rad)} rad",
                file=out,
            )
    if args.plot:
        print(f"plot written to {args.plot}", file=out)
    return _EXIT_FAIL


# --- view, draw ---------------------------------------------------------------------------------


def _cmd_view(args: argparse.Namespace, out: TextIO) -> int:
    """Serve the viewer until Ctrl-C (which :func:`main` reports as exit 130)."""
    import time

    try:
        from poekin.viewer.app import is_loopback, view
    except ImportError as exc:
        raise InputError(
            f"'poekin view' needs the viewer extra: pip install \"poekin[view]\" ({exc})"
        ) from None

    source = _model_source(args)
    if not is_loopback(args.host):
        print(
            f"poekin: warning: --host {args.host}: the page is reachable from other machines",
            file=sys.stderr,
        )
    viewer = view(
        source,
        frame=args.frame,
        params=args.params,
        port=args.port,
        host=args.host,
        open_browser=not args.no_browser,
    )
    try:
        print(
            f"poekin view: {viewer.url}  ({viewer.subject.name}, end frame {viewer.frame!r}); "
            "Ctrl-C to stop",
            file=out,
            flush=True,
        )
        while True:
            time.sleep(3600)
    finally:
        viewer.close()


def _cmd_draw(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.viewer.draw import check_format, draw

    check_format(args.out)
    _check_new_file(args.out, "drawing", force=args.force)
    draw(
        _model_source(args),
        args.q,
        path=args.out,
        frame=args.frame,
        params=args.params,
        aligned=args.aligned,
        all_frames=args.all_frames,
        form=args.form,
    )
    print(f"drawing written to {args.out}", file=out)
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
            nargs="?",
            default=None,
            help="Menagerie robot name, or path to an MJCF or URDF file"
            + (f" (default: {default})" if default else ""),
        )
        p.add_argument(
            "--frame", metavar="F", help="end frame: site or body name (default: the only site)"
        )

    def params(p: argparse.ArgumentParser, what: str) -> None:
        p.add_argument(
            "--params",
            metavar="FILE|NAME",
            help=f"{what}: a DH table or PoE set as a .json/.yaml file, or a named set "
            "(lynch-park-ur5, ur5-dh, ur5e-dh, ur5e-poe)",
        )

    def joint_values(p: argparse.ArgumentParser, output: str, saved: str) -> None:
        """``--q`` for one configuration, or ``--input``/``--output`` files for a batch."""
        p.add_argument("--q", type=float, nargs="+", metavar="Q", help="joint values (rad, m)")
        p.add_argument("--input", metavar="Q.npy", help="(N, n) array of joint values")
        p.add_argument("--output", metavar=output, help=f"where to save the {saved}")
        p.add_argument("--force", action="store_true", help="replace an existing --output file")
        p.add_argument("--json", action="store_true", help="print one JSON object")

    def sampling(p: argparse.ArgumentParser) -> None:
        p.add_argument("--samples", type=int, default=1000, help="random configurations (1000)")
        p.add_argument("--seed", type=int, default=0, help="random seed (0)")

    def outputs(p: argparse.ArgumentParser, *, pos_tol: float, ori_tol: float, plot: str) -> None:
        p.add_argument(
            "--pos-tol", type=float, default=pos_tol, help=f"position tolerance, m ({pos_tol:g})"
        )
        p.add_argument(
            "--ori-tol",
            type=float,
            default=ori_tol,
            help=f"orientation tolerance, rad ({ori_tol:g})",
        )
        p.add_argument("--plot", metavar="PATH", help=plot)
        p.add_argument("--json", action="store_true", help="print one JSON object")
        p.add_argument("--force", action="store_true", help="replace an existing --plot file")

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
    source(v, DEFAULT_ROBOT)
    params(v, "check these parameters instead of the model's own PoE")
    v.add_argument(
        "--against",
        metavar="SOURCE",
        help=f"the model to check --params against (default: {DEFAULT_ROBOT})",
    )
    sampling(v)
    v.add_argument(
        "--all-frames",
        action="store_true",
        help="check every body and site in one run (the whole tree on random qpos)",
    )
    v.add_argument(
        "--within-limits",
        action="store_true",
        help="sample within joint limits instead of [-2 pi, 2 pi]",
    )
    outputs(v, pos_tol=1e-5, ori_tol=1e-4, plot="write an error-distribution PNG")
    v.add_argument("--metrics", metavar="PATH", help="append metric rows to this CSV")
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
        "(an (N, n) .npy file) to an (N, 4, 4) .npy file. With --all-frames, q is the model's "
        "whole qpos (MuJoCo's layout: a free joint is x y z qw qx qy qz, a ball joint a "
        "quaternion wxyz) and every body and site is posed: (N, frames, 4, 4).",
        epilog="examples:\n  poekin fk universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin fk universal_robots_ur5e --input q.npy --output T.npy\n"
        "  poekin fk --params lynch-park-ur5 --q 0 -1.5708 0 0 1.5708 0\n"
        "  poekin fk unitree_go2 --all-frames --input qpos.npy --output T_all.npy",
        formatter_class=fmt,
    )
    source(f)
    params(f, "use these parameters instead of a model")
    joint_values(f, "T.npy", "(N, 4, 4) poses")
    f.add_argument(
        "--all-frames", action="store_true", help="pose every body and site from the whole qpos"
    )
    f.set_defaults(run=_cmd_fk)

    j = sub.add_parser(
        "jacobian",
        help="the Jacobian of a frame for joint values",
        description="Print the 6 x n Jacobian of the end frame at joint values q, or map a "
        "batch of q (an (N, n) .npy file) to an (N, 6, n) .npy file. Rows are [w; v]. "
        "--convention space: the twist in the world frame (Modern Robotics' J_s); body: in the "
        "end frame (J_b); world: v is the velocity of the frame's origin in world coordinates, "
        "as MuJoCo's mj_jacSite. With --tree, q is the whole qpos and the columns are MuJoCo's "
        "qvel (6 x nv): frames behind ball and free joints too.",
        epilog="examples:\n  poekin jacobian universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin jacobian universal_robots_ur5e --q 0 0 0 0 0 0 --convention body --json\n"
        "  poekin jacobian universal_robots_ur5e --input q.npy --output J.npy\n"
        "  poekin jacobian unitree_go2 --tree --frame FL_calf --convention world --input qpos.npy "
        "--output J.npy",
        formatter_class=fmt,
    )
    source(j)
    params(j, "use these parameters instead of a model")
    joint_values(j, "J.npy", "(N, 6, n) Jacobians")
    j.add_argument(
        "--convention",
        choices=["space", "body", "world"],
        default="space",
        help="space (J_s, default), body (J_b) or world (as mj_jacSite)",
    )
    j.add_argument(
        "--tree",
        action="store_true",
        help="the whole model: q is qpos (MuJoCo's layout), columns are qvel",
    )
    j.set_defaults(run=_cmd_jacobian)

    d = sub.add_parser(
        "dh",
        help="print a Denavit-Hartenberg table of a model or parameter set",
        description="Extract a DH table (standard or modified convention) from a model's chain, "
        "or convert a parameter set. Its FK equals the chain's to float precision; the free "
        "choices (parallel axes, prismatic joints) are printed as notes.",
        epilog="examples:\n  poekin dh universal_robots_ur5e\n"
        "  poekin dh franka_fr3 --convention modified --json > fr3_dh.json\n"
        "  poekin dh --params lynch-park-ur5",
        formatter_class=fmt,
    )
    source(d)
    params(d, "convert these parameters instead of a model")
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
    d.add_argument("--json", action="store_true", help="print one JSON object")
    d.set_defaults(run=_cmd_dh)

    g = sub.add_parser(
        "diagnose",
        help="explain why a parameter set disagrees with a model",
        description="Compare your PoE set or DH table with the model's chain, joint by joint, "
        "after finding the best base alignment: base, flipped/tilted/offset axes, link lengths, "
        "M, and a bisection that replaces one part at a time. Exit 0 if the parameters match, "
        "1 if not, 2 on bad input.",
        epilog="examples:\n  poekin diagnose --params lynch-park-ur5\n"
        "  poekin diagnose --params my_ur5e.json --against universal_robots_ur5e "
        "--plot why.png",
        formatter_class=fmt,
    )
    g.add_argument(
        "--params",
        metavar="FILE|NAME",
        required=True,
        help="your parameters: a DH table or PoE set as a .json/.yaml file, or a named set "
        "(lynch-park-ur5, ur5-dh, ur5e-dh, ur5e-poe)",
    )
    g.add_argument(
        "--against",
        metavar="SOURCE",
        help=f"Menagerie robot name, MJCF or URDF path (default: {DEFAULT_ROBOT})",
    )
    g.add_argument(
        "--frame", metavar="F", help="end frame: site or body name (default: the only site)"
    )
    sampling(g)
    outputs(g, pos_tol=1e-6, ori_tol=1e-6, plot="draw both arms at q = 0 to this PNG")
    g.set_defaults(run=_cmd_diagnose, source=None)

    w = sub.add_parser(
        "view",
        help="see the robot, its screw axes and its PoE in the browser",
        description="Serve an interactive page (viser) with a slider per joint, the screw axes "
        "S_i / B_i at the current q, T(q) and the Jacobian, the PoE step by step and DH frames; "
        "with --params, your parameters as a ghost arm with diagnose's findings. Needs "
        'pip install "poekin[view]". Ctrl-C stops it.',
        epilog="examples:\n  poekin view\n  poekin view unitree_go2 --no-browser --port 8081\n"
        "  poekin view --params lynch-park-ur5",
        formatter_class=fmt,
    )
    source(w, DEFAULT_ROBOT)
    params(w, "draw these parameters as a ghost beside the model")
    w.add_argument(
        "--port", type=int, default=None, help="port (default: 8080, or the next free one)"
    )
    w.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to serve on (default 127.0.0.1: this machine only)",
    )
    w.add_argument("--no-browser", action="store_true", help="do not open a browser")
    w.set_defaults(run=_cmd_view)

    a = sub.add_parser(
        "draw",
        help="draw the robot with its screw axes at q to an image",
        description="Draw the robot at q (its qpos, MuJoCo's layout; default qpos0) with each "
        "joint's screw axis, the world, end and home frames; with --params, your parameters as "
        "a second arm and the end-frame error. The suffix of --out decides the format.",
        epilog="examples:\n"
        "  poekin draw universal_robots_ur5e --q 0 -1.57 1.57 0 0 0 --out arm.png\n"
        "  poekin draw --params lynch-park-ur5 --q 0 -1.57 1.57 0 0 0 --out ghost.pdf\n"
        "  poekin draw unitree_go2 --all-frames --out go2.svg",
        formatter_class=fmt,
    )
    source(a, DEFAULT_ROBOT)
    params(a, "draw these parameters beside the model")
    a.add_argument("--q", type=float, nargs="+", metavar="Q", help="qpos (rad, m); default qpos0")
    a.add_argument("--out", metavar="PATH", required=True, help="image file: .png .pdf .svg .jpg")
    a.add_argument("--force", action="store_true", help="replace an existing --out file")
    a.add_argument("--form", choices=["space", "body"], default="space", help="label S_i or B_i")
    a.add_argument(
        "--aligned", action="store_true", help="with --params: your arm after base alignment"
    )
    a.add_argument("--all-frames", action="store_true", help="every body and site as a triad")
    a.set_defaults(run=_cmd_draw)
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
        except BrokenPipeError:  # `poekin dh ... | head`: the reader left; say nothing more
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 141


if __name__ == "__main__":
    sys.exit(main())
