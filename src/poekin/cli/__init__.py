"""The ``poekin`` command line: ``verify``, ``diagnose``, ``screws``, ``dh``, ``fk``,
``jacobian``, ``ik``, ``path``, ``collide``, ``view``, ``draw``, ``calibrate``, ``export`` and
``plot-trajectory``.

Exit codes: 0 success (verify: within tolerance; diagnose: parameters match; ik: every target
solved; collide: no pair collides), 1 verify out of tolerance, diagnose found differences, ik
left targets unsolved or collide found a pair colliding, 2
bad input. Every expected failure prints one
``poekin: error: ...`` line and no traceback; notes (``poekin: note: ...``) say what poekin
assumed or noticed, on stderr.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

from poekin.cli import (
    _calibrate,
    _collide,
    _describe,
    _export,
    _fk,
    _ik,
    _path,
    _trajectory,
    _verify,
    _view,
)
from poekin.cli._args import EXIT_USAGE, Parser
from poekin.errors import PoekinError

__all__ = ["main", "version"]


def version() -> str:
    """What ``poekin --version`` prints: poekin's version, its FK kernel, and the versions of
    Python, NumPy and MuJoCo (MuJoCo's read without importing it)."""
    import platform
    from importlib import metadata

    import numpy as np

    from poekin import __version__
    from poekin.kernel._fast import kernel_description

    try:
        mujoco = metadata.version("mujoco")
    except metadata.PackageNotFoundError:
        mujoco = "not installed"
    return (
        f"poekin {__version__} ({kernel_description()}); Python {platform.python_version()}, "
        f"NumPy {np.__version__}, MuJoCo {mujoco}"
    )


class _Version(argparse.Action):
    """``--version``: the text is made only when asked for."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        print(version())
        parser.exit(0)


def _build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = Parser(
        prog="poekin",
        description="Product-of-Exponentials forward kinematics derived from MuJoCo models.",
        epilog="examples:\n  poekin verify universal_robots_ur5e\n"
        "  poekin fk universal_robots_ur5e --q 0 -1.57 1.57 0 0 0",
        formatter_class=fmt,
    )
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    _verify.register(sub, fmt)
    _describe.register(sub, fmt)
    _fk.register(sub, fmt)
    _ik.register(sub, fmt)
    _path.register(sub, fmt)
    _collide.register(sub, fmt)
    _view.register(sub, fmt)
    _calibrate.register(sub, fmt)
    _export.register(sub, fmt)
    _trajectory.register(sub, fmt)
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
        return EXIT_USAGE
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warnings()
        try:
            return int(args.run(args, sys.stdout))
        except PoekinError as e:
            print(f"poekin: error: {e}", file=sys.stderr)
            return EXIT_USAGE
        except KeyboardInterrupt:
            print("poekin: interrupted", file=sys.stderr)
            return 130
        except BrokenPipeError:  # `poekin dh ... | head`: the reader left; say nothing more
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 141
