"""``poekin view`` and ``poekin draw``: the robot, its screw axes and its PoE, in the browser or
in an image file."""

from __future__ import annotations

import argparse
import sys
from typing import Any, TextIO

from poekin.cli._args import (
    DEFAULT_ROBOT,
    JointSpace,
    add_params,
    add_placement,
    add_q,
    add_source,
    model_source,
    params_spec,
    placement,
    read_joint_values,
)
from poekin.errors import InputError, did_you_mean

__all__ = ["register"]


def _names(text: str | None) -> list[str]:
    """``a,b,c`` as names (spaces around them and empty pieces dropped)."""
    return [] if text is None else [n.strip() for n in text.split(",") if n.strip()]


def _check_wholebody(args: argparse.Namespace) -> None:
    """``--frames`` and ``--hold`` make sense together (said before the model is read)."""
    if args.frames is not None and not args.ik:
        raise InputError(
            "--frames puts whole-body IK handles on frames: give --ik too, e.g. poekin view "
            "unitree_g1 --ik --frames left_foot,right_foot"
        )
    if args.hold is not None and args.frames is None:
        raise InputError("--hold names some of the frames of --frames: give --frames too")
    frames = _names(args.frames)
    if args.frames is not None and not frames:
        raise InputError("--frames names no frame: give names, e.g. --frames left_foot,right_foot")
    for option, names in (("--frames", frames), ("--hold", _names(args.hold))):
        twice = [n for k, n in enumerate(names) if n in names[:k]]
        if twice:
            raise InputError(f"{option} names {twice[0]!r} twice: give each frame once")
    for name in _names(args.hold):
        if name not in frames:
            raise InputError(
                f"--hold {name!r} is not among --frames (a held frame needs a handle): "
                f"{did_you_mean(name, frames)}"
            )


def _cmd_view(args: argparse.Namespace, out: TextIO) -> int:
    """Serve the viewer until Ctrl-C (which :func:`poekin.cli.main` reports as exit 130)."""
    import time

    from poekin._extras import require_view

    _check_wholebody(args)

    require_view("'poekin view'")
    from poekin.io.trajectory import load_trajectory
    from poekin.viewer.app import is_loopback, view
    from poekin.viewer.collision import read_obstacles

    base, tool = placement(args)  # checked before the model is read
    obstacles = () if args.obstacles is None else read_obstacles(args.obstacles)
    trajectory = None
    if args.play is not None:
        trajectory = load_trajectory(args.play, "--play")
        if args.source is None and not args.params and trajectory.robot:
            args.source = trajectory.robot  # the robot it was made for
    source = model_source(args)
    if not is_loopback(args.host):
        print(
            f"poekin: warning: --host {args.host}: the page is reachable from other machines",
            file=sys.stderr,
        )
    viewer = view(
        source,
        frame=args.frame,
        params=params_spec(args),
        port=args.port,
        host=args.host,
        open_browser=not args.no_browser,
        base=base,
        tool=tool,
        ik=args.ik,
        frames=None if args.frames is None else _names(args.frames),
        hold=None if args.hold is None else _names(args.hold),
        play=trajectory,
        play_name=None if args.play is None else f"--play {args.play}",
        collision=args.collision,
        obstacles=obstacles,
    )
    try:
        what = f"end frame {viewer.frame!r}"
        shown = viewer.wholebody
        if shown is not None:
            held = ", ".join(shown.handles.hold) or "none"
            what = f"whole-body IK: {len(shown.handles.frames)} handles, held: {held}"
        if trajectory is not None:
            what += (
                f"; playing {args.play}: {len(trajectory.t)} samples over "
                f"{trajectory.duration:.6g} s"
            )
        scene = viewer.collision_scene
        if scene is not None:
            n = len(scene.obstacles)
            drawn = f"{n} obstacle{'s' if n != 1 else ''}"
            what += (
                f"; collision: {scene.n_robot} geoms, {drawn}, {len(scene.pairs)} pairs"
                if args.collision
                else f"; {drawn} (checked with --collision)"
            )
        print(
            f"poekin view: {viewer.url}  ({viewer.subject.name}, {what}); Ctrl-C to stop",
            file=out,
            flush=True,
        )
        # short sleeps, not one long one: a Ctrl-C that lands between the interpreter's last
        # check for signals and the start of the sleep is acted on only when the sleep ends
        while True:
            time.sleep(0.2)
    finally:
        viewer.close()


def _cmd_draw(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.io.fileio import check_new_file, figure_format
    from poekin.io.loading import load_tree
    from poekin.viewer.draw import draw

    if args.aligned and not args.params:
        raise InputError(
            "--aligned draws the arm of --params after aligning its base to the model's: "
            "give --params FILE|NAME too, or drop --aligned"
        )
    figure_format(args.out, "--out")
    check_new_file(args.out, "drawing", force=args.force)
    base, tool = placement(args)
    source = model_source(args)
    qpos = None
    if args.q is not None:
        qpos = read_joint_values(args, JointSpace.of_tree(load_tree(source)))
    draw(
        source,
        qpos,
        path=args.out,
        frame=args.frame,
        params=params_spec(args),
        aligned=args.aligned,
        all_frames=args.all_frames,
        form=args.form,
        base=base,
        tool=tool,
    )
    print(f"drawing written to {args.out}", file=out)
    return 0


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    w = sub.add_parser(
        "view",
        help="see the robot, its screw axes and its PoE in the browser",
        description="Serve an interactive page (viser) with a slider per joint, the screw axes "
        "S_i / B_i at the current q, T(q) and the Jacobian, the PoE step by step and DH frames, "
        "an IK mode (drag a target handle, the arm follows; every closed-form solution a ghost); "
        "with --frames, whole-body IK (a handle per frame, the whole robot solved at each drag, "
        "the --hold frames met exactly); with --play, a trajectory file played with a time "
        "slider and a play button, the end frame's path drawn as a trace; with --collision, the "
        "model's collision geoms, colliding pairs red with their witness points, and the "
        "obstacles of --obstacles; with --params, your parameters as a ghost arm with "
        "diagnose's findings. Needs the extra poekin[view]. Ctrl-C stops it.",
        epilog="examples:\n  poekin view\n  poekin view unitree_go2 --no-browser --port 8081\n"
        "  poekin view --params lynch-park-ur5\n"
        "  poekin view --base 0 0 0.8 1 0 0 0 --tool 0 0 0.15 1 0 0 0\n"
        "  poekin view --ik\n"
        "  poekin view universal_robots_ur5e --play traj.npz\n"
        "  poekin view universal_robots_ur5e --collision\n"
        "  poekin view unitree_g1 --ik --frames left_elbow_roll_link,right_elbow_roll_link,"
        "left_foot,right_foot --hold left_foot,right_foot",
        formatter_class=fmt,
    )
    add_source(w, DEFAULT_ROBOT)
    add_params(w, "draw these parameters as a ghost beside the model")
    add_placement(w)
    w.add_argument(
        "--port", type=int, default=None, help="port (default: 8080, or the next free one)"
    )
    w.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to serve on (default 127.0.0.1: this machine only)",
    )
    w.add_argument("--no-browser", action="store_true", help="do not open a browser")
    w.add_argument(
        "--ik",
        action="store_true",
        help="start in the IK mode: a target handle on the end frame (with --frames: on each "
        "of those frames, the whole robot solved by tree.ik)",
    )
    w.add_argument(
        "--frames",
        metavar="F,F,...",
        help="with --ik: whole-body IK, a handle on each of these frames (bodies or sites); "
        "dragging one solves every joint, the others keep their targets",
    )
    w.add_argument(
        "--hold",
        metavar="F,F,...",
        help="some of --frames met exactly whatever the drag (contacts: the feet)",
    )
    w.add_argument(
        "--play",
        metavar="TRAJ",
        help="play this trajectory file (.npz, as poekin path writes it): a time slider, a "
        "play/pause button, the tool's path as a trace; without SOURCE, on the robot it was "
        "made for",
    )
    w.add_argument(
        "--collision",
        action="store_true",
        help="show the model's collision geoms (see-through; meshes as their convex hulls), "
        "the two geoms of a penetrating pair red, and the witness points of the pairs closer "
        "than the panel's margin (20 mm)",
    )
    w.add_argument(
        "--obstacles",
        metavar="FILE.json",
        help='world obstacles, a JSON list: [{"type": "box", "half_sizes": [0.3, 0.4, 0.02], '
        '"pose": [x, y, z, qw, qx, qy, qz], "name": "table"}, ...] (types box, sphere, '
        "capsule, plane, mesh); drawn, and checked with --collision",
    )
    w.set_defaults(run=_cmd_view)

    a = sub.add_parser(
        "draw",
        help="draw the robot with its screw axes at q to an image",
        description="Draw the robot at q (its qpos, MuJoCo's layout; default qpos0) with each "
        "joint's screw axis, the world, end and home frames; with --params, your parameters as "
        "a second arm and the end-frame error. The suffix of --out decides the format.",
        epilog="examples:\n"
        "  poekin draw universal_robots_ur5e --q 0 -1.57 1.57 0 0 0 --out arm.png\n"
        "  poekin draw --params lynch-park-ur5 --q 0 -90 90 0 0 0 --deg --out ghost.pdf\n"
        "  poekin draw unitree_go2 --all-frames --out go2.svg\n"
        "  poekin draw --q 0 -90 90 0 0 0 --deg --tool 0 0 0.15 1 0 0 0 --out tool.png",
        formatter_class=fmt,
    )
    add_source(a, DEFAULT_ROBOT)
    add_params(a, "draw these parameters beside the model")
    add_placement(a)
    add_q(a, "qpos (rad, m; see --deg); default qpos0")
    a.add_argument("--out", metavar="PATH", required=True, help="image file: .png .pdf .svg .jpg")
    a.add_argument("--force", action="store_true", help="replace an existing --out file")
    a.add_argument("--form", choices=["space", "body"], default="space", help="label S_i or B_i")
    a.add_argument(
        "--aligned", action="store_true", help="with --params: your arm after base alignment"
    )
    a.add_argument("--all-frames", action="store_true", help="every body and site as a triad")
    a.set_defaults(run=_cmd_draw)
