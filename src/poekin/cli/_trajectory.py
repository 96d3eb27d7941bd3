"""``poekin plot-trajectory``: a trajectory file's ``q``, ``qd`` and ``qdd`` against time, with
its limits as bands and the place where its path stopped."""

from __future__ import annotations

import argparse
from typing import Any, TextIO

__all__ = ["register"]

_DPI = 130


def _cmd_plot(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.io.fileio import check_new_file, figure_format, save_figure
    from poekin.io.trajectory import load_trajectory
    from poekin.motion.plot import trajectory_figure

    figure_format(args.out, "--out")  # the output is checked before the file is read
    check_new_file(args.out, "plot", force=args.force)
    trajectory = load_trajectory(args.trajectory)
    save_figure(trajectory_figure(trajectory, deg=args.deg), args.out, dpi=_DPI, what="plot")
    stop = f"; the path {trajectory.stop_words()}" if trajectory.stopped else ""
    print(
        f"plot written to {args.out}: {trajectory.n} joints, {len(trajectory.t)} samples over "
        f"{trajectory.duration:.6g} s{stop}",
        file=out,
    )
    return 0


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    p = sub.add_parser(
        "plot-trajectory",
        help="plot a trajectory file's q, qd and qdd against time, with its limits",
        description="Draw the trajectory in TRAJ (a .npz file, as poekin path writes it and "
        "poekin view --play plays it): q, qd and qdd against time in three stacked axes, one "
        "line per joint, the limits it holds as shaded bands beyond them, and where its path "
        "stopped early a vertical line labelled with the fraction reached and the reason. "
        "Velocities and accelerations the file lacks are differentiated from q (the axis says "
        "so). The suffix of --out decides the format.",
        epilog="examples:\n  poekin plot-trajectory traj.npz --out traj.png\n"
        "  poekin plot-trajectory traj.npz --deg --out traj_deg.svg",
        formatter_class=fmt,
    )
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory file (.npz)")
    p.add_argument("--out", metavar="PATH", required=True, help="image file: .png .pdf .svg .jpg")
    p.add_argument("--force", action="store_true", help="replace an existing --out file")
    p.add_argument(
        "--deg", action="store_true", help="angles in degrees (every column read as an angle)"
    )
    p.set_defaults(run=_cmd_plot)
