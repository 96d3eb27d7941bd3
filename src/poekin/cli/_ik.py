"""``poekin ik``: the joint values that put a frame at target poses (inverse kinematics).

Targets, in the world frame: ``--pose X Y Z QW QX QY QZ`` (metres and a unit quaternion, w
first) for one, or ``--input FILE`` for a batch, whose answers go to ``--output FILE``. A batch
file holds ``(N, 4, 4)`` matrices, ``(N, 16)`` rows of them (as ``poekin fk --output T.csv``
writes them) or ``(N, 7)`` rows ``x y z qw qx qy qz`` (``poekin fk --form pos_quat``); with
``--position-only`` also ``(N, 3)`` points, and ``--pose X Y Z``. A quaternion's norm must be
within :data:`~poekin.chain.QUAT_TOL` of 1 (it is then scaled to unit length, which does not
change the rotation it stands for); any other, zero included, is refused, never normalised: it
is most likely a typo. A matrix must be a rigid transform
(:func:`poekin.ik.numerical.check_targets`).

Solvers: :meth:`poekin.Chain.ik` (numerical, from seeded random starts or ``--q0``);
:meth:`poekin.Chain.ik_all` with ``--all`` (every closed-form solution, for the six-joint arms
it supports); :meth:`poekin.Tree.ik` with ``--tree`` (any body or site, the joints off its path
held at ``qpos0`` or ``--qpos``).

Exit codes: 0 when every target is solved (``--all``: has a valid solution), 1 when some are
not (the answers are written all the same, with ``success`` false, and a summary line says how
many and the worst residual), 2 on bad input (nothing written).
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import json
import math
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np
from numpy.typing import NDArray

from poekin.chain import QUAT_TOL, pos_quat_poses
from poekin.cli._args import (
    EXIT_FAIL,
    JointSpace,
    add_params,
    add_placement,
    add_precision,
    add_source,
    input_row,
    model_source,
    note,
    read_values,
)
from poekin.cli._fk import end_chain, tree_base
from poekin.cli._text import fixed, sig, table
from poekin.errors import AnalyticIKError, InputError, JointLimitsWarning

if TYPE_CHECKING:
    from poekin.io.fileio import Table

__all__ = ["QUAT_TOL", "register"]

_QUAT_TOL_TEXT = f"{QUAT_TOL:.0e}".replace("e-0", "e-")  # 1e-6

FloatArray = NDArray[np.float64]
Fields = dict[str, NDArray[Any]]

#: Targets per call when a progress bar shows (the answers do not depend on the split).
CHUNK = 10_000
_SHOWN_ROWS = 10  # unsolved rows named in the summary
_FIELDS = ("q", "success", "pos_err", "ori_err", "iterations", "attempts")
_ALL_FIELDS = ("q", "valid", "pos_err", "ori_err")


# --- checks before any model is loaded -------------------------------------------------------


def _check_args(args: argparse.Namespace) -> None:
    """Which target, which files, which options go together; the numbers' ranges."""
    from poekin.cli._ik_targets import check_targets_args
    from poekin.io.fileio import array_format, check_new_file

    check_targets_args(args)
    if args.targets is not None:
        if args.input is not None or args.output is not None or args.json:
            raise InputError(
                "--targets prints one JSON object: it takes no --input/--output/--json"
            )
        return
    if args.pose is not None and args.input is not None:
        raise InputError(
            "both --pose and --input were given; give one: --pose X Y Z QW QX QY QZ for one "
            "target, or --input FILE for a batch"
        )
    if args.pose is None and args.input is None:
        raise InputError(
            "give a target with --pose X Y Z QW QX QY QZ (m, unit quaternion w first), or a "
            "batch with --input FILE"
        )
    if args.pose is not None and len(args.pose) not in (3, 7):
        raise InputError(
            f"--pose takes 7 numbers, X Y Z QW QX QY QZ (or X Y Z with --position-only), got "
            f"{len(args.pose)}"
        )
    if args.pose is not None and len(args.pose) == 3 and not args.position_only:
        raise InputError(
            "--pose X Y Z gives a position only: add QW QX QY QZ, or pass --position-only"
        )
    if args.input is not None:
        array_format(args.input, "--input")
        if args.output is None:
            raise InputError(
                "--input needs --output FILE (.npy, .npz, .csv, .txt) for the joint values"
            )
        if args.json:
            raise InputError(
                "--json prints the answer for one --pose; a batch from --input goes to --output "
                "FILE (a .npz keeps success and the residuals of every target)"
            )
    if args.output is not None:
        if args.input is None:
            raise InputError("--output goes with --input FILE")
        array_format(args.output, "--output")
    if args.seed is not None and not 0 <= args.seed < 2**64:
        raise InputError(f"--seed must be a whole number from 0 to 2**64 - 1, got {args.seed}")
    for flag, value in (("--pos-tol", args.pos_tol), ("--ori-tol", args.ori_tol)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{flag} must be a positive number, got {value}")
    if args.qpos is not None and not args.tree and args.targets is None:
        raise InputError("--qpos gives a whole model's joint values: pass --tree too")
    if args.all:
        given = [
            flag
            for flag, value in (
                ("--q0", args.q0),
                ("--seed", args.seed),
                ("--pos-tol", args.pos_tol),
                ("--ori-tol", args.ori_tol),
                ("--position-only", args.position_only or None),
                ("--tree", args.tree or None),
            )
            if value is not None
        ]
        if given:
            raise InputError(
                f"--all gives every closed-form solution of a chain, exact to 1e-12: it takes "
                f"no {', '.join(given)}; drop {'them' if len(given) > 1 else 'it'}, or drop --all"
            )
    if args.output is not None:
        check_new_file(args.output, "joint values", force=args.force)


# --- targets ---------------------------------------------------------------------------------


def _pose_rows(rows: FloatArray, where: Callable[[int], str]) -> FloatArray:
    """``(N, 7)`` rows ``x y z qw qx qy qz`` or ``(N, 3)`` points as ``(N, 4, 4)`` targets; a
    point's rotation is the identity (``--position-only`` ignores it). ``where(k)`` names row
    ``k`` in a message."""
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=-1))
    if bad.size:
        raise InputError(f"{where(int(bad[0]))} holds NaN or inf; every value must be finite")
    if rows.shape[-1] == 7:
        return pos_quat_poses(rows, where)
    T = np.tile(np.eye(4), (len(rows), 1, 1))
    T[:, :3, 3] = rows[:, :3]
    return T


def _rigid(T: FloatArray, where: str) -> FloatArray:
    """``T`` checked as rigid transforms (the solver's own check, its message prefixed)."""
    from poekin.ik.numerical import check_targets

    try:
        return check_targets(T)
    except InputError as e:
        raise InputError(f"{where}: {e}") from None


def _targets(args: argparse.Namespace) -> tuple[FloatArray, str]:
    """The targets, ``(4, 4)`` for ``--pose`` or ``(N, 4, 4)`` from ``--input`` (a single
    pose in a file: ``(4, 4)``), and their description."""
    if args.pose is not None:
        pose = np.asarray(args.pose, dtype=np.float64)
        T = _pose_rows(pose[None], lambda _: "--pose")[0]
        xyz = " ".join(fixed(x, args.precision) for x in pose[:3])
        if len(pose) == 3 or args.position_only:
            return T, f"target xyz {xyz} m (position only)"
        quat = " ".join(f"{x:g}" for x in pose[3:])
        return T, f"target xyz {xyz} m, quat wxyz {quat}"
    from poekin.io.fileio import array_format, read_array, read_table

    def where(k: int) -> str:  # a row of an array file, by its index
        return input_row(args.input, k)

    if array_format(args.input, "--input") in (".csv", ".txt"):
        text = read_table(args.input)
        arr, where = _by_name(text, args.position_only), text.at  # type: ignore[assignment]
    else:
        arr = read_array(args.input, name="T")
    shape = arr.shape
    one = arr.ndim == 1 or shape == (4, 4)
    rows = arr.reshape(1, *shape) if one else arr
    if rows.ndim == 3 and rows.shape[1:] == (4, 4):
        T = _rigid(rows, f"--input {args.input}")
    elif rows.ndim == 2 and rows.shape[1] == 16:
        T = _rigid(rows.reshape(-1, 4, 4), f"--input {args.input}")
    elif rows.ndim == 2 and (rows.shape[1] == 7 or (rows.shape[1] == 3 and args.position_only)):
        T = _pose_rows(rows, (lambda _: f"--input {args.input} the pose") if one else where)
    else:
        points = "(N, 3) points" + ("" if args.position_only else " with --position-only")
        raise InputError(
            f"--input {args.input} holds an array of shape {shape}; give targets as (N, 4, 4) "
            f"matrices, (N, 16) rows of them, (N, 7) rows x y z qw qx qy qz, or {points}"
        )
    count = "1 target" if one else f"{len(T)} targets"
    return (T[0] if one else T), f"{count} from {args.input}"


#: The columns a target file's header may name, each layout in the order it is read (what
#: ``poekin fk --output`` writes: ``--form pos_quat``, the 4x4 matrices, and points).
TARGET_COLUMNS: dict[str, tuple[str, ...]] = {
    "poses": ("x", "y", "z", "qw", "qx", "qy", "qz"),
    "4x4 matrices": tuple(f"T{i}{j}" for i in range(4) for j in range(4)),
    "points (with --position-only)": ("x", "y", "z"),
}


def _by_name(text: Table, position_only: bool) -> FloatArray:
    """A text file's targets, its columns read by the names its header gives (in any order),
    else by position. Raises InputError for a header that names none of the layouts of
    :data:`TARGET_COLUMNS` (an unknown name, one missing or given twice)."""
    values: FloatArray = text.values
    if text.header is None:
        return values
    header = list(text.header)
    known = sorted({c for cols in TARGET_COLUMNS.values() for c in cols})
    shown = {
        k: ",".join(c if len(c) < 16 else (*c[:2], "...", c[-1])) for k, c in TARGET_COLUMNS.items()
    }
    layouts = "; ".join(f"{name} {cols}" for name, cols in shown.items())
    for name in header:
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InputError(
                f"{text.where}: unknown column {name!r} in the header{hint}; name the columns "
                f"of one layout, in any order: {layouts}"
            )
    for cols in TARGET_COLUMNS.values():
        if sorted(header) == sorted(cols) and (len(cols) != 3 or position_only):
            return values[:, [header.index(c) for c in cols]]
    raise InputError(
        f"{text.where}: the header {','.join(header)} names no layout of targets; name the "
        f"columns of one, in any order: {layouts}"
    )


# --- the problem: a chain, its --all, or a tree's frame ---------------------------------------


@dataclasses.dataclass(frozen=True)
class _Problem:
    """What is solved: ``solve(T)`` maps ``(N, 4, 4)`` targets to the result's arrays;
    ``space`` describes ``q`` (the chain's joints, or the tree's whole qpos), of which the
    entries ``solved`` are solved for (the others are held)."""

    robot: str
    frame: str
    space: JointSpace
    solved: tuple[int, ...]
    solve: Callable[[FloatArray], Fields]
    geometry: str = ""  # --all: the closed-form split


def _options(args: argparse.Namespace) -> dict[str, Any]:
    given = {"pos_tol": args.pos_tol, "ori_tol": args.ori_tol}
    return {
        "seed": args.seed or 0,
        "position_only": args.position_only,
        **{k: v for k, v in given.items() if v is not None},
    }


def _fields(found: Any, names: Sequence[str]) -> Fields:
    return {k: np.asarray(getattr(found, k)) for k in names}


def _chain_problem(args: argparse.Namespace) -> _Problem:
    from poekin.chain import Chain

    chain = end_chain(args)
    if not isinstance(chain, Chain):
        chain = chain.to_chain()
    space = JointSpace.of(chain)
    solved = tuple(range(chain.n_joints))
    robot = chain.robot or "chain"
    if args.all:
        from poekin.ik.analytic import geometry, nearest_geometry

        refine = not args.no_refine
        try:
            split = nearest_geometry(chain) if refine else geometry(chain)
        except AnalyticIKError as e:
            raise AnalyticIKError(f"{e}; without --all, poekin ik solves it numerically") from None
        description = split.description
        if split.nearest:
            note(
                f"{robot} is near, not on, the closed form's geometry ({split.nearest}): each "
                "branch of the nearest ideal geometry is refined numerically on the arm itself "
                "(--no-refine refuses instead)"
            )
            description = f"nearest {description}, refined"
        return _Problem(
            robot,
            chain.frame,
            space,
            solved,
            lambda T: _fields(chain.ik_all(T, refine=refine), _ALL_FIELDS),
            description,
        )
    q0 = None if args.q0 is None else read_values(args.q0, space, args.deg, "--q0")
    options = _options(args)
    return _Problem(
        robot,
        chain.frame,
        space,
        solved,
        lambda T: _fields(chain.ik(T, q0, **options), _FIELDS),
    )


def _tree_problem(args: argparse.Namespace) -> _Problem:
    from poekin.ik.trees import plan
    from poekin.io.loading import default_frame, load_tree

    if args.params:
        raise InputError("--tree takes the whole model from SOURCE, not --params")
    base = tree_base(args)  # said before the model is read
    tree = load_tree(model_source(args, None), base=base)
    frame = args.frame if args.frame is not None else default_frame(tree)
    how = plan(tree, frame)
    space = JointSpace.of_tree(tree)
    qpos = tree.qpos0 if args.qpos is None else read_values(args.qpos, space, args.deg, "--qpos")
    if args.q0 is not None:
        qpos = qpos.copy()
        qpos[list(how.indices)] = read_values(args.q0, JointSpace.of(how.chain), args.deg, "--q0")
    options = _options(args)
    warm = args.q0 is not None

    def solve(T: FloatArray) -> Fields:
        return _fields(tree.ik(T, frame, qpos, warm_start=warm, **options), _FIELDS)

    return _Problem(tree.robot or "tree", frame, space, how.indices, solve)


def _solve(problem: _Problem, T: FloatArray) -> Fields:
    """``problem.solve`` on ``(..., 4, 4)`` targets: a batch in chunks with a progress bar when
    stderr is a terminal (tqdm, imported only then), else in one call. Each target's answer
    depends only on its own numbers, so the split changes no bit."""
    if T.ndim == 2:
        return {k: v[0] for k, v in problem.solve(T[None]).items()}
    n = len(T)
    if n <= CHUNK or not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty()):
        return problem.solve(T)
    from tqdm import tqdm

    parts = []
    with tqdm(total=n, desc="ik", unit="target", delay=0.5, leave=False) as bar:
        for start in range(0, n, CHUNK):
            parts.append(problem.solve(T[start : start + CHUNK]))
            bar.update(min(CHUNK, n - start))
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


# --- output ----------------------------------------------------------------------------------


def _in_units(q: FloatArray, space: JointSpace, deg: bool) -> FloatArray:
    """``q`` (rad, m) as printed and written: revolute values in degrees with ``--deg``."""
    return np.where(space.angles, np.degrees(q), q) if deg else q


def _unit(space: JointSpace, j: int, deg: bool) -> str:
    return ("deg" if deg else "rad") if space.angles[j] else "m"


def _units(space: JointSpace, joints: Sequence[int], deg: bool) -> str:
    """The units of ``joints``' values: ``"rad"``, ``"m"``, ``"rad and m"`` (``"deg"``)."""
    angles = space.angles[list(joints)]
    units = (("deg" if deg else "rad", angles.any()), ("m", not angles.all()))
    return " and ".join(unit for unit, present in units if present)


def _tolerances(args: argparse.Namespace) -> str:
    """The tolerances a success was judged by: the options, else the solver's defaults."""
    from poekin.ik.numerical import settings

    used = settings()
    pos = args.pos_tol or used.pos_tol
    if args.position_only:
        return f"tolerance {pos:g} m"
    return f"tolerances {pos:g} m, {args.ori_tol or used.ori_tol:g} rad"


def _plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def _residual(args: argparse.Namespace, pos: float, ori: float) -> str:
    return f"{sig(pos)} m" if args.position_only else f"{sig(pos)} m, {sig(ori)} rad"


def _print_one(
    args: argparse.Namespace, problem: _Problem, got: Fields, target: str, out: TextIO
) -> int:
    """One target's answer: text, or ``--json``."""
    space, deg = problem.space, args.deg
    q = _in_units(got["q"], space, deg)
    solved = bool(got["success"])
    if args.json:
        body = {
            "robot": problem.robot,
            "frame": problem.frame,
            "target": list(args.pose),
            "position_only": args.position_only,
            "joints": list(space.names),
            "deg": deg,
            "q": q.tolist(),
            "success": solved,
            "pos_err": float(got["pos_err"]),
            "ori_err": float(got["ori_err"]),
            "iterations": int(got["iterations"]),
            "attempts": int(got["attempts"]),
            "seed": args.seed or 0,
        }
        if len(problem.solved) != len(space.names):
            body["solved"] = [space.names[j] for j in problem.solved]
        print(json.dumps(body), file=out)
        return 0 if solved else EXIT_FAIL
    print(f"{problem.robot}  frame {problem.frame!r}  {target}", file=out)
    residual = _residual(args, float(got["pos_err"]), float(got["ori_err"]))
    effort = (
        f"{_plural(int(got['iterations']), 'iteration')}, "
        f"{_plural(int(got['attempts']), 'attempt')}"
    )
    if solved:
        print(f"SOLVED: residual {residual} ({_tolerances(args)}); {effort}", file=out)
    else:
        print(
            f"NOT SOLVED: residual {residual} ({_tolerances(args)}); {effort}; q is the "
            "best fit found",
            file=out,
        )
    rows = [
        [space.names[j], fixed(q[j], args.precision), _unit(space, j, deg)] for j in problem.solved
    ]
    print("\n".join(table(rows, left=(0, 2))), file=out)
    held = len(space.names) - len(problem.solved)
    if held:
        where = "--qpos" if args.qpos is not None else "qpos0"
        print(
            f"the other {held} qpos values held at {where} (--json gives the whole qpos)",
            file=out,
        )
    return 0 if solved else EXIT_FAIL


def _print_all(
    args: argparse.Namespace, problem: _Problem, got: Fields, target: str, out: TextIO
) -> int:
    """One target's closed-form branches (``--all``): text, or ``--json``."""
    space, deg = problem.space, args.deg
    q = _in_units(got["q"], space, deg)
    valid = got["valid"]
    if args.json:
        body = {
            "robot": problem.robot,
            "frame": problem.frame,
            "target": list(args.pose),
            "geometry": problem.geometry,
            "joints": list(space.names),
            "deg": deg,
            "q": q[valid].tolist(),
            "success": bool(valid.any()),
            "solutions": q.tolist(),
            "valid": valid.tolist(),
            "pos_err": got["pos_err"].tolist(),
            "ori_err": got["ori_err"].tolist(),
        }
        print(json.dumps(body), file=out)
        return 0 if valid.any() else EXIT_FAIL
    print(f"{problem.robot}  frame {problem.frame!r}  {target}", file=out)
    k = len(valid)
    found = int(valid.sum())
    summary = f"{problem.geometry}: {found} of {k} branches valid (exact, within the limits)"
    if found:
        worst = _residual(
            args, float(got["pos_err"][valid].max()), float(got["ori_err"][valid].max())
        )
        summary += f"; worst residual {worst}"
    print(("SOLVED: " if found else "NOT SOLVED: ") + summary, file=out)
    n = len(space.names)
    print(
        f"q1..q{n} [{_units(space, problem.solved, deg)}]: {', '.join(space.names)}",
        file=out,
    )
    rows = [["branch", "valid", *(f"q{j + 1}" for j in range(n))]]
    rows += [
        [str(b + 1), "yes" if valid[b] else "no", *(fixed(x, args.precision) for x in q[b])]
        for b in range(k)
    ]
    print("\n".join(table(rows, left=(1,))), file=out)
    return 0 if found else EXIT_FAIL


def _rows_named(rows: NDArray[np.intp]) -> str:
    shown = ", ".join(str(int(r)) for r in rows[:_SHOWN_ROWS])
    more = f", ... ({len(rows) - _SHOWN_ROWS} more)" if len(rows) > _SHOWN_ROWS else ""
    return f"row{'s' if len(rows) > 1 else ''} {shown}{more}"


def _write_batch(
    args: argparse.Namespace, problem: _Problem, got: Fields, target: str, out: TextIO
) -> int:
    """A batch's answers to ``--output``, and a summary."""
    from poekin.io.fileio import write_array

    space, deg = problem.space, args.deg
    names = list(space.names)
    units = _units(space, range(len(names)), deg)  # of every entry the file holds
    print(f"{problem.robot}  frame {problem.frame!r}  {target}", file=out)
    if args.all:
        valid = got["valid"]
        q = np.where(valid[..., None], _in_units(got["q"], space, deg), np.nan)
        k = valid.shape[-1]
        columns = [f"{b + 1}.{name}" for b in range(k) for name in names]
        extras: dict[str, Any] = {
            "joints": names,
            "valid": valid,
            "pos_err": got["pos_err"],
            "ori_err": got["ori_err"],
        }
        write_array(args.output, q, name="q", columns=columns, extras=extras, what="joint values")
        print(
            f"all {k} branches q of shape {q.shape} written to {args.output} ({units}; NaN where "
            "a branch is not a valid solution)",
            file=out,
        )
        success = valid.any(axis=-1).reshape(-1)
        if success.all():
            per = valid.sum(axis=-1).mean()
            print(
                f"SOLVED: every target has a valid solution ({per:.2f} of {k} on average)", file=out
            )
            return 0
        bad = np.flatnonzero(~success)
        print(
            f"NOT SOLVED: {len(bad)} of {success.size} targets have no valid solution "
            f"({_rows_named(bad)})",
            file=out,
        )
        return EXIT_FAIL
    q = _in_units(got["q"], space, deg)
    extras = {"joints": names, **{f: got[f] for f in _FIELDS[1:]}}
    write_array(args.output, q, name="q", columns=names, extras=extras, what="joint values")
    print(f"joint values q of shape {q.shape} written to {args.output} ({units})", file=out)
    success = got["success"].reshape(-1)
    effort = (
        f"{got['iterations'].mean():.1f} iterations, {got['attempts'].mean():.2f} attempts per "
        "target"
    )
    if success.all():
        print(f"SOLVED: all {success.size} targets ({_tolerances(args)}); {effort}", file=out)
        return 0
    bad = np.flatnonzero(~success)
    worst = _residual(
        args,
        float(got["pos_err"].reshape(-1)[bad].max()),
        float(got["ori_err"].reshape(-1)[bad].max()),
    )
    print(
        f"NOT SOLVED: {len(bad)} of {success.size} targets ({_rows_named(bad)}), worst residual "
        f"{worst} ({_tolerances(args)}); their q is the best fit found",
        file=out,
    )
    if not args.output.lower().endswith(".npz"):
        note(
            f"{args.output} holds q only: write a .npz to keep success, pos_err, ori_err, "
            "iterations and attempts for every target"
        )
    return EXIT_FAIL


def _cmd_ik(args: argparse.Namespace, out: TextIO) -> int:
    _check_args(args)
    if args.targets is not None:
        from poekin.cli._ik_targets import run_targets

        return run_targets(args, out)
    T, target = _targets(args)
    problem = _tree_problem(args) if args.tree else _chain_problem(args)
    with warnings.catch_warnings():  # --q0 outside the limits: noted once, as it was read
        warnings.simplefilter("ignore", JointLimitsWarning)
        got = _solve(problem, T)
    if args.input is not None:
        return _write_batch(args, problem, got, target, out)
    if args.all:
        return _print_all(args, problem, got, target, out)
    return _print_one(args, problem, got, target, out)


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser(
        "ik",
        help="inverse kinematics: joint values for target poses",
        description="Find the joint values that put the end frame at a target pose in the world "
        "frame: --pose X Y Z QW QX QY QZ (metres, and a unit quaternion w first: |q| within "
        f"{_QUAT_TOL_TEXT} of 1; another one is refused, not normalised), or a batch from --input "
        "FILE ((N, 4, 4) matrices, (N, 16) rows of them, or (N, 7) rows x y z qw qx qy qz, in a "
        ".npy, .npz, .csv or .txt file) with --output FILE. The numerical solver (Chain.ik) "
        "answers within the joint limits, from seeded random starts (the same bits for the same "
        "seed) or from --q0; success needs the pose to 1e-10 m and 1e-10 rad (--pos-tol, "
        "--ori-tol). --all gives every closed-form solution instead (Chain.ik_all), for "
        "six-joint arms whose axes allow one: three parallel axes with axes 5 and 6 meeting "
        "(every Universal Robots arm), or a spherical wrist (axes 4, 5, 6 meeting: PUMA, most "
        "ABB, KUKA, Fanuc arms, the Lite6); any other arm gets an error that names the "
        "condition that fails. --tree solves for any body or site of a model, the joints off "
        "its path held at qpos0 or --qpos; --targets FILE.json places many frames at once, "
        "every joint of the model solved for (a floating base too), --hold frames met exactly. "
        "With --tool the targets are the tool's poses; "
        "with --base they are in your world, where the robot's base stands. Exit 0 when every "
        "target is solved, 1 when some "
        "are not (the answers are written all the same: a .npz output keeps success, pos_err, "
        "ori_err, iterations and attempts per target), 2 on bad input.",
        epilog="examples:\n"
        "  poekin ik universal_robots_ur5e --pose 0.4 0.2 0.3 0 1 0 0\n"
        "  poekin ik universal_robots_ur5e --pose 0.4 0.2 0.3 0 1 0 0 --deg --json\n"
        "  poekin ik universal_robots_ur5e --pose 0.4 0.2 0.3 0 1 0 0 --all\n"
        "  poekin ik universal_robots_ur5e --pose -0.492 -0.134 0.438 0 0.707106781 0.707106781 "
        "0 --q0 0 -90 90 -90 -90 0 --deg\n"
        "  poekin ik universal_robots_ur5e --input T.npy --output q_ik.npz\n"
        "  poekin ik universal_robots_ur5e --pose 0.6 0.1 0.9 0 1 0 0 --all --base 0 0 0.8 1 0 0 "
        "0 --tool 0 0 0.15 1 0 0 0\n"
        "  poekin ik franka_emika_panda --frame hand --pose 0.5 0 0.4 0 1 0 0\n"
        "  poekin ik trs_so_arm100 --frame Fixed_Jaw --pose 0.2 0 0.15 --position-only --deg\n"
        "  poekin ik aloha --tree --frame left/gripper --pose -0.1 0.05 0.25 1 0 0 0 --json\n"
        "  poekin ik unitree_g1 --targets g1_targets.json --hold left_foot,right_foot",
        formatter_class=fmt,
    )
    add_source(p)
    add_params(p, "solve these parameters instead of a model")
    add_placement(p)
    p.add_argument(
        "--pose",
        type=float,
        nargs="+",
        metavar="V",
        help="one target: X Y Z (m) QW QX QY QZ (unit quaternion), in the world frame",
    )
    p.add_argument(
        "--input",
        metavar="FILE",
        help="a batch of targets: (N, 4, 4), (N, 16) or (N, 7) (.npy, .npz, .csv or .txt; a "
        "text file's header is read by name: x,y,z,qw,qx,qy,qz or T00..T33)",
    )
    p.add_argument(
        "--output",
        metavar="FILE",
        help="where to save q, (N, n) (--all: (N, 8, n)); a .npz also keeps success, pos_err, "
        "ori_err, iterations and attempts (--all: valid, pos_err, ori_err)",
    )
    p.add_argument("--force", action="store_true", help="replace an existing --output file")
    p.add_argument(
        "--all",
        action="store_true",
        help="every closed-form solution (analytic; six-joint arms with three parallel axes "
        "or a spherical wrist, or near one: a calibrated arm's branches are refined)",
    )
    p.add_argument(
        "--no-refine",
        action="store_true",
        help="--all: refuse an arm only near a closed-form geometry instead of refining",
    )
    p.add_argument(
        "--q0",
        type=float,
        nargs="+",
        metavar="Q",
        help="start the first attempt here (rad and m; see --deg): a path solved target by "
        "target stays on its branch",
    )
    p.add_argument(
        "--seed",
        type=int,
        help="seed of the random starts, 0 to 2**64 - 1 (0): the same seed, the same bits",
    )
    p.add_argument(
        "--deg",
        action="store_true",
        help="revolute joint values in degrees: --q0, --qpos and the answers",
    )
    p.add_argument("--pos-tol", type=float, help="success: position within this, m (1e-10)")
    p.add_argument("--ori-tol", type=float, help="and orientation within this, rad (1e-10)")
    p.add_argument(
        "--position-only",
        action="store_true",
        help="reach the position only, whatever the orientation (5-joint arms, point targets); "
        "--pose X Y Z is then enough",
    )
    p.add_argument(
        "--tree",
        action="store_true",
        help="the whole model: --frame any body or site; q is its qpos, the joints off the "
        "frame's path held at qpos0 or --qpos",
    )
    p.add_argument(
        "--qpos",
        type=float,
        nargs="+",
        metavar="Q",
        help="with --tree: every joint's value (MuJoCo's qpos layout), the others held there",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object (with --pose)")
    p.add_argument(
        "--targets",
        metavar="FILE",
        help="many frames at once (whole-body IK, every joint of the model): a JSON object of "
        "frame name to [x, y, z, qw, qx, qy, qz], [x, y, z] (position only) or a 4x4 matrix; "
        '"com" is the centre of mass. Prints one JSON object with per-frame errors',
    )
    p.add_argument(
        "--hold",
        metavar="NAMES",
        help="with --targets: frames met exactly, comma-separated (contacts: the feet)",
    )
    p.add_argument(
        "--posture",
        type=float,
        metavar="WEIGHT",
        help="with --targets: pull toward the start (--qpos or qpos0) in the redundancy "
        "left, weight > 0 (0: none)",
    )
    add_precision(p)
    p.set_defaults(run=_cmd_ik)
