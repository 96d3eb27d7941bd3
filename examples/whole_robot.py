"""Whole robots: every body and site of a quadruped and of a dual-arm robot, in one pass.

    python examples/whole_robot.py [--samples 1000]

Loads the Menagerie go2 (free base + 12 hinges) and aloha (two arms with slide fingers, built
from included XML files), poses every frame with ``tree.fk`` on random qpos (random unit
quaternions for the free base), and compares each frame with ``mj_forward``.
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

import poekin
from poekin.io.import_mujoco import find_frame
from poekin.verification.verify import mujoco_frame_poses, pose_errors


def check(robot: str, samples: int) -> float:
    """Worst position or orientation error of ``tree.fk`` against mj_forward, over all frames."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)  # XML-only folders
        loaded = poekin.load_model(robot)
    tree = poekin.load_tree(loaded)
    qpos = poekin.sample_qpos(tree, samples, seed=0)
    T_world_frames = tree.fk(qpos)  # (samples, n_frames, 4, 4)
    ids = [find_frame(loaded.model, name)[:2] for name in tree.frame_names]
    pos, ori = pose_errors(mujoco_frame_poses(loaded.model, qpos, ids), T_world_frames)
    print(f"{robot}: {tree}")
    print(f"  qpos layout: {tree.qpos_layout()}")
    worst = f"max error {pos.max():.2g} m, {ori.max():.2g} rad"
    print(f"  {tree.n_frames} frames x {samples} qpos: {worst}")
    return float(max(pos.max(), ori.max()))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args()
    try:
        worst = max(check(robot, args.samples) for robot in ("unitree_go2", "aloha"))
    except poekin.PoekinError as e:
        print(f"whole_robot: {e}", file=sys.stderr)
        return 1
    print(f"passed: {bool(np.isfinite(worst) and worst < 1e-13)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
