"""The command line's parser, the arguments its commands share, and reading joint values.

Joint values come from ``--q`` or an ``--input`` file; with ``--deg`` the revolute ones are in
degrees (prismatic ones stay metres, quaternions and positions of ball and free joints stay as
they are). Values that look like degrees without ``--deg``, and values outside the model's joint
limits, get a one-line note on stderr: the result is computed all the same.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np
from numpy.typing import NDArray

from poekin.cli._text import DEFAULT_PRECISION
from poekin.errors import InputError

if TYPE_CHECKING:
    from poekin.chain import Chain
    from poekin.dh import DHTable
    from poekin.tree import Tree

__all__ = [
    "DEFAULT_ROBOT",
    "EXIT_FAIL",
    "EXIT_USAGE",
    "JointSpace",
    "Parser",
    "add_floating_base",
    "add_joint_values",
    "add_params",
    "add_placement",
    "add_precision",
    "add_q",
    "add_sampling",
    "add_source",
    "add_ur_yaml_order",
    "import_mujoco_without_gl",
    "model_source",
    "note",
    "params",
    "params_spec",
    "place",
    "placement",
    "read_joint_values",
    "read_values",
]

DEFAULT_ROBOT = "universal_robots_ur5e"
EXIT_FAIL = 1
EXIT_USAGE = 2
PARAM_NAMES = "lynch-park-ur5, ur5-dh, ur5e-dh, ur5e-poe"

# A negative number in any form float() reads: -1, -1.5, -.5, -1e-3, -1.E+2, -inf, -nan.
# argparse's own pattern knows only -1 and -1.5, and takes the rest for option names.
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^-(inf|infinity|nan)$", re.I)
# Revolute values beyond this (rad) are more likely degrees than turns of more than a circle.
_DEGREES_LIKELY = 2 * np.pi + 1e-9


class Parser(argparse.ArgumentParser):
    """argparse that takes every negative number as a value, and reports usage errors in one
    line pointing to ``--help``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def note(text: str) -> None:
    """One ``poekin: note:`` line on stderr."""
    print(f"poekin: note: {text}", file=sys.stderr)


# --- arguments ---------------------------------------------------------------------------------


def add_source(p: argparse.ArgumentParser, default: str | None = None) -> None:
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


def add_floating_base(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--floating-base",
        action="store_true",
        help="URDF: give the root link a free joint (qpos then starts with x y z qw qx qy qz)",
    )


_POSE7 = ("X", "Y", "Z", "QW", "QX", "QY", "QZ")


def add_placement(p: argparse.ArgumentParser) -> None:
    """``--base`` (where the robot stands in the world) and ``--tool`` (what the end frame
    carries), each ``x y z qw qx qy qz``: :func:`placement` reads them."""
    p.add_argument(
        "--base",
        type=float,
        nargs=7,
        metavar=_POSE7,
        help="the robot's base in your world, T_world_base: x y z (m) and a unit quaternion "
        "w x y z; poses, Jacobians and targets are then in your world",
    )
    p.add_argument(
        "--tool",
        type=float,
        nargs=7,
        metavar=_POSE7,
        help="a tool on the end frame, T_flange_tool: x y z (m) and a unit quaternion "
        "w x y z in the end frame; poses, Jacobians and targets are then the tool's",
    )


def placement(args: argparse.Namespace) -> tuple[NDArray[np.float64] | None, ...]:
    """``--base`` and ``--tool`` as ``(4, 4)`` rigid transforms, None where not given (or
    where the command has no such options).

    Raises:
        InputError: a quaternion whose norm is not 1, NaN or inf (one line naming the option).
    """
    from poekin.chain import rigid_transform

    given = [getattr(args, name, None) for name in ("base", "tool")]
    return tuple(
        None if value is None else rigid_transform(np.asarray(value), f"--{name}")
        for name, value in zip(("base", "tool"), given, strict=True)
    )


def place(chain: Chain | DHTable, args: argparse.Namespace) -> Chain | DHTable:
    """``chain`` on ``--base`` with ``--tool`` (a DH table becomes its chain first), or as it
    is without them."""
    base, tool = placement(args)
    if base is None and tool is None:
        return chain
    from poekin.chain import Chain

    placed = chain if isinstance(chain, Chain) else chain.to_chain()
    placed = placed if base is None else placed.with_base(base)
    return placed if tool is None else placed.with_tool(tool)


def add_params(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--params",
        metavar="FILE|NAME",
        help=f"{what}: a DH table or PoE set as a .json/.yaml file, UR's calibration .yaml "
        f"(ur_calibration's kinematics:), or a named set ({PARAM_NAMES})",
    )
    add_ur_yaml_order(p)


def add_ur_yaml_order(p: argparse.ArgumentParser, written: str = "") -> None:
    p.add_argument(
        "--ur-yaml-order",
        choices=("description", "controller"),  # poekin.io.ur_kinematics.UR_YAML_ORDERS
        default="description",
        help="how a UR calibration .yaml's roll, pitch, yaw compose"
        + (f" (read, and {written})" if written else "")
        + ": description, Rz Ry Rx, as ur_description reads them (default); controller, "
        "Rx Ry Rz, as ur_calibration computed them (3-7 um apart on real files)",
    )


def add_precision(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--precision",
        type=_precision,
        default=DEFAULT_PRECISION,
        metavar="N",
        help=f"decimals printed ({DEFAULT_PRECISION}); --json keeps full precision",
    )


def _precision(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = -1
    if not 0 <= n <= 17:
        raise argparse.ArgumentTypeError(f"must be a whole number from 0 to 17, got {text!r}")
    return n


def add_q(p: argparse.ArgumentParser, q_help: str) -> None:
    """``--q`` for one configuration and ``--deg`` for its angles (:func:`read_joint_values`)."""
    p.add_argument("--q", type=float, nargs="+", metavar="Q", help=q_help)
    p.add_argument("--deg", action="store_true", help="revolute joint values are in degrees")


def add_joint_values(p: argparse.ArgumentParser, output: str, saved: str) -> None:
    """``--q`` for one configuration, or ``--input``/``--output`` files for a batch."""
    add_q(p, "joint values (rad and m; see --deg)")
    p.add_argument(
        "--input", metavar="FILE", help="(N, n) joint values: a .npy, .npz, .csv or .txt file"
    )
    p.add_argument(
        "--output", metavar=output, help=f"where to save the {saved} (.npy, .npz, .csv or .txt)"
    )
    p.add_argument("--force", action="store_true", help="replace an existing --output file")
    p.add_argument("--json", action="store_true", help="print one JSON object (with --q)")
    add_precision(p)


def add_sampling(p: argparse.ArgumentParser) -> None:
    p.add_argument("--samples", type=int, default=1000, help="random configurations (1000)")
    p.add_argument("--seed", type=int, default=0, help="random seed, 0 or more (0)")


# --- models and parameter sets -----------------------------------------------------------------


def import_mujoco_without_gl() -> None:
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


def model_source(args: argparse.Namespace, default: str | None = DEFAULT_ROBOT) -> str:
    """The model: ``--against`` or the positional SOURCE (not both), else ``default``.

    A model is loaded next, so MuJoCo is imported here (:func:`import_mujoco_without_gl`).
    """
    against = getattr(args, "against", None)
    if against and args.source and against != args.source:
        raise InputError(f"two models given ({args.source!r} and --against {against!r}); give one")
    source = against or args.source or default
    if source is None:
        raise InputError(
            "give a model: a Menagerie robot name, an MJCF or URDF path (or --params FILE|NAME)"
        )
    import_mujoco_without_gl()
    return str(source)


def params(spec: str, args: argparse.Namespace | None = None) -> Chain | DHTable:
    """The parameter set ``spec``, a UR calibration read in ``args.ur_yaml_order``."""
    from poekin.io.paramfile import load_params

    order = getattr(args, "ur_yaml_order", "description")
    return load_params(spec, ur_yaml_order="controller" if order == "controller" else "description")


def params_spec(args: argparse.Namespace) -> str | Chain | DHTable | None:
    """``--params`` for a function that reads it itself: the name as given, or, for a UR
    calibration read in the controller's order, the parameters read so."""
    if args.params is None or args.ur_yaml_order == "description":
        return str(args.params) if args.params is not None else None
    return params(args.params, args)


# --- joint values ------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class JointSpace:
    """What each entry of ``q`` is: a name, whether it is an angle, its limits (or +-inf)."""

    names: tuple[str, ...]
    angles: NDArray[np.bool_]
    limits: NDArray[np.float64]

    @classmethod
    def of_joints(
        cls, names: Sequence[str], types: Sequence[str], limits: Any = None
    ) -> JointSpace:
        lim = np.tile([-np.inf, np.inf], (len(names), 1)) if limits is None else np.asarray(limits)
        return cls(tuple(names), np.array([t == "revolute" for t in types], bool), lim)

    @classmethod
    def of(cls, model: Chain | DHTable) -> JointSpace:
        """A chain's joints, or a DH table's rows (no limits)."""
        from poekin.chain import Chain

        if isinstance(model, Chain):
            return cls.of_joints(model.joint_names, model.joint_types, model.limits)
        return cls.of_joints(model.joint_names, model.joint_types)

    @classmethod
    def of_tree(cls, tree: Tree) -> JointSpace:
        """A whole model's ``qpos``: hinge entries are angles; quaternions are not."""
        angles = np.zeros(tree.nq, bool)
        limits = np.tile([-np.inf, np.inf], (tree.nq, 1))
        for k, (kind, mimic) in enumerate(zip(tree.joint_types, tree.mimics, strict=True)):
            if mimic is None and kind in ("revolute", "prismatic"):
                a = int(tree.qpos_adr[k])
                angles[a], limits[a] = kind == "revolute", tree.joint_limits[k]
        names = tree.qpos_names()
        return cls(tuple(names), angles, limits)


def read_joint_values(args: argparse.Namespace, space: JointSpace) -> NDArray[np.float64]:
    """``--q`` or the ``--input`` file as float64, in radians (``--deg`` converts the angles).

    A wrong last axis is left for the model to refuse, with its own message. Notes go to stderr
    for values that look like degrees and for values outside the joint limits.
    """
    from poekin.io.fileio import read_array

    path = getattr(args, "input", None)  # commands without --input (draw) read --q only
    q = read_array(path, name="q") if path is not None else np.asarray(args.q, dtype=np.float64)
    if path is not None and not np.all(np.isfinite(q)):
        _refuse_not_finite(path, q)
    n = len(space.names)
    if q.ndim == 0 or q.shape[-1] != n or not np.all(np.isfinite(q)):
        return q
    if args.deg:
        q = np.where(space.angles, np.radians(q), q)
    elif np.any(np.abs(q[..., space.angles]) > _DEGREES_LIKELY):
        biggest = float(np.max(np.abs(q[..., space.angles])))
        note(
            f"revolute joint values up to {biggest:g} are read as radians (more than a turn); "
            "if they are degrees, pass --deg"
        )
        return q  # out of their limits too, most likely: one note says why
    _note_limits(q, space)
    return q


def input_row(path: str, k: int) -> str:
    """Row ``k`` of the ``--input`` array file ``path``, named for a message: by its index
    from 0 (a text file's rows are named by their own lines, ``read_table(path).at``)."""
    return f"--input {path} row {k} (from 0)"


def _refuse_not_finite(path: str, q: NDArray[np.float64]) -> None:
    """An InputError naming the first row of the ``--input`` file ``path`` that holds NaN or
    inf: by the file's own line (a text file), or by its index from 0 (an array file)."""
    from poekin.io.fileio import array_format, read_table

    rows = q.reshape(-1, q.shape[-1]) if q.ndim > 1 else q.reshape(1, -1)
    k = int(np.flatnonzero(~np.all(np.isfinite(rows), axis=-1))[0])
    text = array_format(path, "--input") in (".csv", ".txt")
    where = read_table(path).at(k) if text and q.ndim <= 2 else input_row(path, k)
    raise InputError(f"{where} holds NaN or inf; every value must be finite")


def _note_limits(q: NDArray[np.float64], space: JointSpace) -> None:
    """One note naming every joint with a value outside its limits (in a batch: in how many
    rows, and the first such value)."""
    from poekin.ik._angles import outside_limits

    said = outside_limits(q, space.limits, space.names, list(space.angles))
    if said:
        note(f"{said} (computed all the same)")


def read_values(values: list[float], space: JointSpace, deg: bool, what: str) -> Any:
    """``--q0`` or ``--qpos`` in radians (``--deg``: degrees for revolute joints), with the
    command line's notes (values that look like degrees, values outside the limits)."""
    from poekin.chain import as_joint_values

    q = read_joint_values(argparse.Namespace(q=values, deg=deg), space)
    return as_joint_values(q, len(space.names), what=f"{what} values")
