"""The motion benchmark (issue #28): each goal of ``poekin.motion`` measured, its reference in
the same run.

``bench_track``: ``poekin.motion.track`` on a G1 clip of 300 frames at 30 Hz against
``tree.ik`` frame by frame (each frame from the last answer, one attempt), on the same targets:
the hands (the elbow roll links), feet and pelvis as poses, the head by position, from a smooth
motion (every hinge outside the fingers its centre plus three sines of 0.1 to 0.6 Hz inside its
limits, the base swaying and turning), with 5 mm of noise on every position and 5 mrad on every
orientation; the fingers frozen. Medians of repeated whole solves (wall time on a possibly
shared machine, NumPy on one BLAS thread, as both solvers run), the mean joint acceleration
``|qdd|`` of each answer (hinges, rad/s^2) and its RMS target position error against the
noisy targets. The goal: ``track`` within 2 s, and no slower than frame by frame.

examples:
  python benchmarks/bench_motion.py --quick      # seconds: a check that it runs
  python benchmarks/bench_motion.py              # the full run, about a minute
"""

from __future__ import annotations

import argparse
import pathlib
import statistics
import sys
import time
import warnings
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info  # the FK benchmark's machine description

import poekin
import poekin.motion
from poekin.wholebody.space import space

FloatArray = NDArray[np.float64]

DT = 1.0 / 30.0
NOISE = 0.005  # m on every position, rad on every orientation
POSES = ("left_elbow_roll_link", "right_elbow_roll_link", "left_foot", "right_foot", "pelvis")
FINGER_WORDS = {"zero", "one", "two", "three", "four", "five", "six"}
GOAL_TRACK_S = 2.0


def g1_clip(tree: poekin.Tree, fingers: Sequence[str], T: int, seed: int) -> FloatArray:
    """``(T, nq)`` the smooth G1 motion of the module's docstring."""
    rng = np.random.default_rng(seed)
    sp = space(tree, fingers)
    t = np.arange(T) * DT
    lo, hi = sp.lower, sp.upper
    centre = np.clip(tree.qpos0[sp.scalar_q], lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))
    amplitude = 0.25 * np.minimum(hi - lo, 1.0) / 3
    wave = np.zeros((T, len(centre)))
    for _ in range(3):
        f = rng.uniform(0.1, 0.6, len(centre))
        phase = rng.uniform(0, 2 * np.pi, len(centre))
        wave += (
            rng.uniform(0, 1, len(centre)) * amplitude * np.sin(2 * np.pi * f * t[:, None] + phase)
        )
    q = np.repeat(tree.qpos0[None], T, axis=0)
    q[:, sp.scalar_q] = np.clip(centre + wave, lo, hi)
    q[:, 0] += 0.1 * np.sin(2 * np.pi * 0.2 * t)
    q[:, 1] += 0.05 * np.sin(2 * np.pi * 0.3 * t)
    yaw = 0.2 * np.sin(2 * np.pi * 0.15 * t)
    q[:, 3:7] = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=1)
    return q


def noisy_targets(tree: poekin.Tree, q: FloatArray, seed: int) -> dict[str, FloatArray]:
    rng = np.random.default_rng(seed)
    P = tree.fk(q)
    out: dict[str, FloatArray] = {}
    for f in POSES:
        v = np.array(P[:, tree.frame_index(f)])
        v[:, :3, 3] += rng.normal(0, NOISE, (len(q), 3))
        v[:, :3, :3] = poekin.exp_so3(rng.normal(0, NOISE, (len(q), 3))) @ v[:, :3, :3]
        out[f] = v
    out["head"] = P[:, tree.frame_index("head"), :3, 3] + rng.normal(0, NOISE, (len(q), 3))
    return out


def mean_acceleration(qpos: FloatArray) -> float:
    """Mean ``|qdd|`` over the hinges (``qpos[:, 7:]``) and the frames (rad/s^2)."""
    return float(np.mean(np.abs(np.diff(qpos[:, 7:], 2, axis=0)))) / DT**2


def rms_error(tree: poekin.Tree, qpos: FloatArray, targets: dict[str, FloatArray]) -> float:
    P = tree.fk(qpos)
    errors = [
        P[:, tree.frame_index(f), :3, 3] - (v if v.ndim == 2 else v[:, :3, 3])
        for f, v in targets.items()
    ]
    return float(np.sqrt(np.mean(np.sum(np.square(errors), axis=-1))))


def by_frame(
    tree: poekin.Tree, targets: dict[str, FloatArray], fingers: Sequence[str]
) -> FloatArray:
    """``tree.ik`` frame by frame, each frame from the last answer, one attempt."""
    T = len(next(iter(targets.values())))
    out, q = [], tree.qpos0
    for t in range(T):
        one = {f: v[t] for f, v in targets.items()}
        q = tree.ik(one, q, position_only={"head"}, freeze=fingers, max_attempts=1).qpos
        out.append(q)
    return np.array(out)


def bench_track(frames: int = 300, repeats: int = 3) -> list[str]:
    """The rows of ``track`` against ``tree.ik`` frame by frame on the G1 clip."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        tree = poekin.load_tree("unitree_g1")
    fingers = tuple(n for n in tree.joint_names if n.split("_")[1] in FINGER_WORDS)
    targets = noisy_targets(tree, g1_clip(tree, fingers, frames, seed=4), seed=5)
    times: dict[str, list[float]] = {"track": [], "frames": []}
    answers: dict[str, FloatArray] = {}
    iterations = 0
    for _ in range(repeats):
        start = time.perf_counter()
        found = poekin.motion.track(tree, targets, tree.qpos0, freeze=fingers, dt=DT)
        times["track"].append(time.perf_counter() - start)
        answers["track"], iterations = found.qpos, found.iterations
        start = time.perf_counter()
        answers["frames"] = by_frame(tree, targets, fingers)
        times["frames"].append(time.perf_counter() - start)
    t_track, t_frames = (statistics.median(times[k]) for k in ("track", "frames"))
    rows = [
        f"G1 clip, {frames} frames at 30 Hz, 5 mm / 5 mrad noise (median of {repeats})",
        f"  track            {t_track:7.3f} s  ({iterations} iterations)  mean |qdd| "
        f"{mean_acceleration(answers['track']):6.2f} rad/s^2  RMS error "
        f"{rms_error(tree, answers['track'], targets) * 1e3:5.2f} mm",
        f"  tree.ik by frame {t_frames:7.3f} s  mean |qdd| "
        f"{mean_acceleration(answers['frames']):6.2f} rad/s^2  RMS error "
        f"{rms_error(tree, answers['frames'], targets) * 1e3:5.2f} mm",
        f"  goal: track <= {GOAL_TRACK_S:g} s: {'met' if t_track <= GOAL_TRACK_S else 'MISSED'}; "
        f"no slower than by frame: {'met' if t_track <= t_frames else 'MISSED'} "
        f"({t_frames / t_track:.2f}x)",
    ]
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0] if __doc__ else None,
        epilog=__doc__[__doc__.index("examples:") :] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--quick", action="store_true", help="small sizes, seconds: a check that it runs"
    )
    args = parser.parse_args(argv)
    info = machine_info()
    loadavg = ", ".join(f"{x:.2f}" for x in info["load_average"] or ())
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} usable cores (load "
        f"average {loadavg}); numpy {np.__version__}; git {info['git']}",
        flush=True,
    )
    rows = bench_track(20, 1) if args.quick else bench_track()
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
