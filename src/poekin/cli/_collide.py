"""``poekin collide``: the closest collision pairs of a robot at one configuration.

``q`` is the model's whole ``qpos`` (MuJoCo's layout); the pairs are the model's own collision
geoms as MuJoCo pairs them (:mod:`poekin.collision.model`). Exit 0 when no pair penetrates, 1
when one does, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
from typing import Any, TextIO

import numpy as np

from poekin.cli._args import (
    JointSpace,
    add_floating_base,
    add_q,
    model_source,
    read_joint_values,
)
from poekin.cli._text import fixed, table
from poekin.errors import InputError

__all__ = ["register"]

_COLLIDING = 1


def _top(text: str) -> int:
    try:
        k = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text!r}") from None
    if k < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, got {text!r}")
    return k


def register(sub: Any, fmt: type[argparse.HelpFormatter]) -> None:
    c = sub.add_parser(
        "collide",
        help="the closest collision pairs of a robot at a configuration",
        description="Print the closest pairs of the model's collision geoms at one "
        "configuration (q is the whole qpos, MuJoCo's layout) with their signed distances in "
        "mm (negative: how deep they penetrate), colliding pairs marked. The geoms and pairs "
        "are MuJoCo's (contype/conaffinity, no body with its parent, <exclude>, <pair>; for a "
        "URDF, no link with an adjacent one), measured by poekin's closed forms, GJK and EPA "
        "(a pair with a mesh by MuJoCo's mj_geomDistance). Exit 0 "
        "when collision-free, 1 when a pair collides, 2 on bad input.",
        epilog="examples:\n  poekin collide universal_robots_ur5e --q 0 -1.57 1.57 0 0 0\n"
        "  poekin collide universal_robots_ur5e --q 0 -90 150 0 0 0 --deg --top 3\n"
        "  poekin collide universal_robots_ur5e --q 0 -1.57 1.57 0 0 0 --json",
        formatter_class=fmt,
    )
    c.add_argument(
        "source",
        metavar="ROBOT",
        help="Menagerie robot name, or path to an MJCF or URDF file (with its collision meshes)",
    )
    add_q(c, "the whole qpos (rad and m; see --deg)")
    add_floating_base(c)
    c.add_argument(
        "--top",
        type=_top,
        default=5,
        metavar="K",
        help="how many of the closest pairs to print (default 5)",
    )
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.set_defaults(run=_cmd_collide)


def _cmd_collide(args: argparse.Namespace, out: TextIO) -> int:
    from poekin.io.loading import load_tree

    if args.q is None:
        raise InputError("give the configuration with --q (the whole qpos, MuJoCo's layout)")
    tree = load_tree(model_source(args, None), floating_base=args.floating_base)
    q = read_joint_values(args, JointSpace.of_tree(tree))
    found = tree.distances(q)
    order = np.argsort(found.distance, kind="stable")[: args.top]
    colliding = bool((found.distance < 0).any())
    n_colliding = int((found.distance < 0).sum())
    if args.json:
        rows = [
            {
                "pair": list(found.pairs[p]),
                "distance": float(found.distance[p]),
                "points": found.points[p].tolist(),
                "colliding": bool(found.distance[p] < 0),
            }
            for p in order
        ]
        doc = {
            "robot": tree.robot,
            "pairs_checked": len(found.pairs),
            "colliding_pairs": n_colliding,
            "in_collision": colliding,
            "closest": rows,
        }
        print(json.dumps(doc, indent=2), file=out)
        return _COLLIDING if colliding else 0
    state = f"{n_colliding} colliding" if colliding else "collision-free"
    print(f"{tree.robot}: {len(found.pairs)} pairs checked, {state}", file=out)
    cells = [["pair", "", "distance (mm)", ""]]
    for p in order:
        a, b = found.pairs[p]
        d = float(found.distance[p])
        cells.append([a, b, fixed(1000.0 * d, 1), "COLLIDES" if d < 0 else ""])
    for line in table(cells, left=(0, 1, 3)):
        print(line, file=out)
    return _COLLIDING if colliding else 0
