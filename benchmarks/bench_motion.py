"""The motion benchmark (issue #28): each part of ``poekin.motion`` against its reference
library, in the same run.

Parts (one function each, ``bench_<part>(sizes) -> list[Row]``; ``main`` runs them all):

* ``bench_retime``: :func:`poekin.motion.retime` against toppra 0.6 (``TOPPRA`` with
  ``JointVelocityConstraint`` and ``JointAccelerationConstraint``, its default grid and
  ``ParametrizeConstAccel``) on the same paths and limits: random waypoints (5 to 10, uniform
  within the joint limits) of the UR5e (pi rad/s, 8 rad/s^2 on the big joints and 12 on the
  wrist) and the FR3 (Franka's data sheet: 2.62 to 5.26 rad/s, 10 rad/s^2), the spline at
  ``linspace(0, 1, N)`` for both. Per path, the median time of one call (poekin's includes
  the samples at 500 Hz; toppra's is ``compute_trajectory`` at its defaults, its own grid and
  ``ParametrizeSpline``, and then its samples at 500 Hz, ``q, qd, qdd``), and how far the
  durations are apart: poekin's optimum on its grid (``optimal_duration``) and its sampled
  motion (``duration``, slowed within the limits between grid points and to a whole tick) over
  toppra's; and the largest ``|qd|`` and ``|qdd|`` of toppra's samples over the limits (its
  output is a spline in time through its grid points, which the limits do not bound between
  them). Then ``retime`` with jerk limits (Ruckig,
  1000 rad/s^3 on the FR3's joints), its median time and duration over the unlimited one.
* ``bench_via``: :func:`poekin.motion.via_trajectory` against Robotics Toolbox's ``mstraj``
  (the bench extra) on the same via points, ``qdmax`` and ``tacc``: 20 random paths of 6 via
  points of a 6-joint arm; the median time per path, and, per path, the durations and how fast
  each moves over ``qdmax`` at its fastest sample (by differences of ``q``), and how near each
  passes its via points (its blends cut the corners).
* ``bench_follow``: ``chain.follow`` of a UR5e straight line given as 1,000 samples
  (``line_path`` at uniform ``s``, a 0.5 m move with a 0.6 rad turn, the elbow up): median per
  call, single-threaded NumPy with the compiled kernel. Goal: <= 5 ms on one core. Beside it,
  1,000 warm-started single solves (``chain.ik`` from the previous sample, one at a time) and
  one batched ``chain.ik_all`` of the 1,000 poses, the two things it is "close to". Then the
  same line as a callable (11 first samples: the adaptive re-sampling alone decides how many
  samples the 0.1 mm bound needs), and the FR3 (seven joints, no closed form) on a 0.3 m line as
  a callable, each sample ``chain.ik`` from the one before. Every answer is checked before it
  is timed: the line followed to its end, the largest midpoint deviation under 0.1 mm.
* ``bench_track``: :func:`poekin.motion.track` on a G1 clip of 300 frames at 30 Hz against
  ``tree.ik`` frame by frame (each frame from the last answer, one attempt), on the same
  targets: the hands (the elbow roll links), feet and pelvis as poses, the head by position,
  from a smooth motion (every hinge outside the fingers its centre plus three sines of 0.1 to
  0.6 Hz inside its limits, the base swaying and turning), with 5 mm of noise on every position
  and 5 mrad on every orientation; the fingers frozen. Medians of repeated whole solves (NumPy
  on one BLAS thread, as both solvers run), the mean joint acceleration ``|qdd|`` of each answer
  (hinges, rad/s^2) and its RMS target position error against the noisy targets. The goal:
  ``track`` within 2 s, and no slower than frame by frame.

Timings are medians of repeated single calls (wall time on a possibly shared machine: read
medians and ratios); the CPU, its vector width and the load average are printed with the
table.

examples:
  python benchmarks/bench_motion.py --quick      # seconds: a check that it runs
  python benchmarks/bench_motion.py              # the full run, about a minute
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import logging
import math
import pathlib
import sys
import time
import warnings
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info, package_version  # the FK benchmark's machine description

import poekin
import poekin.motion
from poekin.motion import line_path, retime
from poekin.wholebody.space import space

FloatArray = NDArray[np.float64]

RATE = 500.0  # Hz: the samples both sides return
GOAL_AGREE = 0.01  # the issue: durations within 1% of toppra's
ARMS = {  # robot: (label, velocity limits, acceleration limits)
    "universal_robots_ur5e": (
        "UR5e",
        np.full(6, math.pi),
        np.array([8.0, 8.0, 8.0, 12.0, 12.0, 12.0]),
    ),
    "franka_fr3": (
        "FR3",
        np.array([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26]),
        np.full(7, 10.0),
    ),
}
JERK = 1000.0  # rad/s^3, the jerk row's limit on every joint


@dataclasses.dataclass(frozen=True)
class Sizes:
    """How much to run; ``--quick`` shrinks everything to seconds (its figures are not the
    table's)."""

    paths: int = 20  # per arm
    repeats: int = 7  # timed calls per path
    follow_repeats: int = 50  # follow: timed calls per case
    frames: int = 300  # track: the clip's frames
    track_repeats: int = 3  # track: whole solves of the clip


QUICK = Sizes(paths=2, repeats=2, follow_repeats=3, frames=20, track_repeats=1)


@dataclasses.dataclass
class Row:
    name: str
    poekin: str
    reference: str
    ratio: float | None  # the reference's time over poekin's
    note: str


def median_s(call: Callable[[], object], repeats: int) -> float:
    """The median wall time of ``repeats`` calls after one warm-up call (s)."""
    call()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def fmt_s(seconds: float) -> str:
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds / 1e-9:.3g} ns"


# --- retime: poekin against toppra --------------------------------------------------------------


def waypoints(robot: str, paths: int, seed: int) -> list[FloatArray]:
    """``paths`` arrays of 5 to 10 waypoints within the joint limits (one turn for none)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        tree = poekin.load_tree(robot)
    lo, hi = np.clip(tree.joint_limits, -math.pi, math.pi).T
    rng = np.random.default_rng(seed)
    return [rng.uniform(lo, hi, (int(rng.integers(5, 11)), len(lo))) for _ in range(paths)]


def toppra_call(
    q: FloatArray, vel: FloatArray, acc: FloatArray
) -> Callable[[], tuple[float, float, float]]:
    """toppra's whole call on the path through ``q`` at its defaults, sampled at :data:`RATE`:
    its duration and its samples' peak ``|qd|`` and ``|qdd|`` over the limits."""
    import toppra
    import toppra.algorithm
    import toppra.constraint

    def call() -> tuple[float, float, float]:
        path = toppra.SplineInterpolator(np.linspace(0.0, 1.0, len(q)), q)
        constraints = [
            toppra.constraint.JointVelocityConstraint(vel),
            toppra.constraint.JointAccelerationConstraint(acc),
        ]
        traj = toppra.algorithm.TOPPRA(constraints, path).compute_trajectory()
        t = np.arange(0.0, traj.duration, 1.0 / RATE)
        _, qd, qdd = traj(t), traj(t, 1), traj(t, 2)
        peak_v = float(np.max(np.abs(qd) / vel))
        return float(traj.duration), peak_v, float(np.max(np.abs(qdd) / acc))

    return call


def bench_retime(sizes: Sizes) -> list[Row]:
    if package_version("toppra") is None:
        print("toppra is not installed: pip install 'poekin[motion]'", file=sys.stderr)
        return []
    logging.getLogger("toppra").setLevel(logging.ERROR)
    rows = []
    for seed, (robot, (label, vel, acc)) in enumerate(ARMS.items()):
        ours, theirs, optimal, sampled, peaks_v, peaks_a = [], [], [], [], [], []
        for q in waypoints(robot, sizes.paths, seed):
            reference = toppra_call(q, vel, acc)
            duration, peak_v, peak_a = reference()
            peaks_v.append(peak_v)
            peaks_a.append(peak_a)
            r = retime(q, vel, acc, rate=RATE)
            optimal.append(r.optimal_duration / duration - 1.0)
            sampled.append(r.duration / duration - 1.0)
            ours.append(median_s(functools.partial(retime, q, vel, acc, rate=RATE), sizes.repeats))
            theirs.append(median_s(reference, sizes.repeats))
        worst = max(np.abs(optimal).max(), np.abs(sampled).max())
        rows.append(
            Row(
                f"retime {label}, {sizes.paths} paths of 5-10 waypoints, {RATE:g} Hz",
                fmt_s(float(np.median(ours))),
                fmt_s(float(np.median(theirs))),
                float(np.median(theirs)) / float(np.median(ours)),
                f"durations / toppra's - 1: optimum {min(optimal):+.2%} to {max(optimal):+.2%}, "
                f"sampled {min(sampled):+.2%} to {max(sampled):+.2%} (goal within "
                f"{GOAL_AGREE:.0%}: {'met' if worst < GOAL_AGREE else 'missed'}); toppra's "
                f"samples peak at {max(peaks_v):.4f} of the velocity limit and "
                f"{max(peaks_a):.4f} of the acceleration limit (poekin's: at most 1)",
            )
        )
    if package_version("ruckig") is not None:
        label, vel, acc = ARMS["franka_fr3"]
        paths = waypoints("franka_fr3", sizes.paths, seed=7)
        times, slower = [], []
        for q in paths:
            plain = retime(q, vel, acc, rate=RATE)
            jerked = retime(q, vel, acc, jerk_limits=JERK, rate=RATE)
            slower.append(jerked.duration / plain.duration)
            call = functools.partial(retime, q, vel, acc, jerk_limits=JERK, rate=RATE)
            times.append(median_s(call, sizes.repeats))
        rows.append(
            Row(
                f"retime {label}, jerk {JERK:g} rad/s^3 (Ruckig)",
                fmt_s(float(np.median(times))),
                "—",
                None,
                f"duration / without jerk limits: median {np.median(slower):.3g} "
                f"({min(slower):.3g} to {max(slower):.3g}); leaves the spline between waypoints",
            )
        )
    return rows


# --- via points: poekin against Robotics Toolbox's mstraj ------------------------------------


def bench_via(sizes: Sizes) -> list[Row]:
    """``via_trajectory`` against RTB's ``mstraj`` (the module's docstring); no row without
    roboticstoolbox."""
    if package_version("roboticstoolbox-python") is None:
        print("  via: roboticstoolbox-python is not installed (the bench extra): no row")
        return []
    import roboticstoolbox as rtb

    from poekin.motion import via_trajectory

    rng = np.random.default_rng(7)
    qdmax, tacc, dt = np.full(6, 1.0), 0.2, 1.0 / RATE
    paths = [rng.uniform(-1.5, 1.5, (6, 6)) for _ in range(sizes.paths)]
    ours_t = median_s(
        lambda: [via_trajectory(v, tacc=tacc, qdmax=qdmax, rate=RATE) for v in paths], sizes.repeats
    ) / len(paths)
    theirs_t = median_s(
        lambda: [rtb.mstraj(v, dt=dt, tacc=tacc, qdmax=qdmax) for v in paths], sizes.repeats
    ) / len(paths)
    ratio_t, over_ours, over_theirs, near_ours, near_theirs = [], [], [], [], []
    for v in paths:
        a = via_trajectory(v, tacc=tacc, qdmax=qdmax, rate=RATE)
        b = rtb.mstraj(v, dt=dt, tacc=tacc, qdmax=qdmax)
        ratio_t.append(a.duration / b.t[-1])
        over_ours.append(float(np.max(np.abs(np.diff(a.q, axis=0)) / np.diff(a.t)[:, None])))
        over_theirs.append(float(np.max(np.abs(np.diff(b.q, axis=0))) / dt))
        near_ours.append(max(float(np.min(np.linalg.norm(a.q - w, axis=1))) for w in v[1:-1]))
        near_theirs.append(max(float(np.min(np.linalg.norm(b.q - w, axis=1))) for w in v[1:-1]))
    return [
        Row(
            f"via_trajectory, {sizes.paths} paths of 6 via points, 6 joints",
            fmt_s(ours_t),
            f"mstraj {fmt_s(theirs_t)}",
            theirs_t / ours_t,
            f"duration / mstraj's: median {np.median(ratio_t):.3g}; fastest joint over qdmax: "
            f"poekin {max(over_ours):.3g}, mstraj {max(over_theirs):.3g}; farthest via point "
            f"passed at {max(near_ours):.2g} rad (poekin), {max(near_theirs):.2g} (mstraj)",
        )
    ]


# --- follow: IK along straight lines ----------------------------------------------------------

UR_START = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
FR3_START = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
GOAL_FOLLOW_MS = 5.0  # ms: the 1,000-sample UR5e line


def _ur_line(chain: poekin.Chain) -> tuple[np.ndarray, np.ndarray]:
    T0 = chain.fk(UR_START)
    T1 = T0.copy()
    T1[:3, 3] += [0.3, -0.3, -0.25]
    turn = poekin.lie.exp_so3(np.array([0.0, 0.0, 0.6]))
    T1[:3, :3] = turn @ T0[:3, :3]
    return T0, T1


def bench_follow(sizes: Sizes) -> list[Row]:
    """``chain.follow`` along straight lines (the module's docstring)."""
    repeats = sizes.follow_repeats
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        ur = poekin.load("universal_robots_ur5e")
        fr3 = poekin.load("franka_fr3")
    T0, T1 = _ur_line(ur)
    samples = line_path(T0, T1, np.linspace(0.0, 1.0, 1000))
    result = ur.follow(samples, UR_START)
    assert result.done and len(result.s) == 1000 and result.max_deviation <= 1e-4, result.detail

    def one_by_one() -> None:
        q = UR_START
        for T in samples:
            q = ur.ik(T, q, max_attempts=1).q

    ours = median_s(lambda: ur.follow(samples, UR_START), repeats)
    single = median_s(one_by_one, max(1, repeats // 5))
    every = median_s(lambda: ur.ik_all(samples), repeats)

    def ur_path(s: FloatArray) -> FloatArray:
        return line_path(T0, T1, s)

    adaptive = ur.follow(ur_path, UR_START)
    assert adaptive.done and adaptive.max_deviation <= 1e-4, adaptive.detail
    F0 = fr3.fk(FR3_START)
    F1 = F0.copy()
    F1[:3, 3] += [0.1, 0.25, -0.1]

    def fr3_path(s: FloatArray) -> FloatArray:
        return line_path(F0, F1, s)

    seven = fr3.follow(fr3_path, FR3_START)
    assert seven.done and seven.max_deviation <= 1e-4, seven.detail
    return [
        Row(
            "follow UR5e, a 1,000-sample line",
            fmt_s(ours),
            f"1,000 warm-started chain.ik {fmt_s(single)}; one ik_all of them {fmt_s(every)}",
            single / ours,
            f"goal <= {GOAL_FOLLOW_MS:g} ms: {'met' if ours * 1e3 <= GOAL_FOLLOW_MS else 'missed'}",
        ),
        Row(
            "follow UR5e, the line as a callable",
            fmt_s(median_s(lambda: ur.follow(ur_path, UR_START), repeats)),
            "—",
            None,
            f"{len(adaptive.s)} samples for the 0.1 mm bound",
        ),
        Row(
            "follow FR3, a 0.3 m line as a callable",
            fmt_s(median_s(lambda: fr3.follow(fr3_path, FR3_START), max(1, repeats // 5))),
            "—",
            None,
            f"{len(seven.s)} samples, chain.ik from each to the next",
        ),
    ]


# --- track: a whole clip against tree.ik frame by frame ------------------------------------------


CLIP_DT = 1.0 / 30.0  # s: the clip's frames
NOISE = 0.005  # m on every position, rad on every orientation
POSES = ("left_elbow_roll_link", "right_elbow_roll_link", "left_foot", "right_foot", "pelvis")
FINGER_WORDS = {"zero", "one", "two", "three", "four", "five", "six"}
GOAL_TRACK_S = 2.0


def g1_clip(tree: poekin.Tree, fingers: Sequence[str], T: int, seed: int) -> FloatArray:
    """``(T, nq)`` the smooth G1 motion of the module's docstring."""
    rng = np.random.default_rng(seed)
    sp = space(tree, fingers)
    t = np.arange(T) * CLIP_DT
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
    return float(np.mean(np.abs(np.diff(qpos[:, 7:], 2, axis=0)))) / CLIP_DT**2


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


def bench_track(sizes: Sizes) -> list[Row]:
    """``track`` against ``tree.ik`` frame by frame on the G1 clip."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        tree = poekin.load_tree("unitree_g1")
    fingers = tuple(n for n in tree.joint_names if n.split("_")[1] in FINGER_WORDS)
    targets = noisy_targets(tree, g1_clip(tree, fingers, sizes.frames, seed=4), seed=5)
    times: dict[str, list[float]] = {"track": [], "frames": []}
    answers: dict[str, FloatArray] = {}
    iterations = 0
    for _ in range(sizes.track_repeats):
        start = time.perf_counter()
        found = poekin.motion.track(tree, targets, tree.qpos0, freeze=fingers, dt=CLIP_DT)
        times["track"].append(time.perf_counter() - start)
        answers["track"], iterations = found.qpos, found.iterations
        start = time.perf_counter()
        answers["frames"] = by_frame(tree, targets, fingers)
        times["frames"].append(time.perf_counter() - start)
    t_track, t_frames = (float(np.median(times[k])) for k in ("track", "frames"))
    qdd = {k: mean_acceleration(v) for k, v in answers.items()}
    err = {k: rms_error(tree, v, targets) * 1e3 for k, v in answers.items()}
    met = t_track <= GOAL_TRACK_S and t_track <= t_frames
    return [
        Row(
            f"track G1, {sizes.frames} frames at 30 Hz, 5 mm / 5 mrad noise",
            f"{fmt_s(t_track)} ({iterations} iterations), mean qdd {qdd['track']:.3g} rad/s^2, "
            f"RMS error {err['track']:.3g} mm",
            f"tree.ik frame by frame {fmt_s(t_frames)}, mean qdd {qdd['frames']:.3g} rad/s^2, "
            f"RMS error {err['frames']:.3g} mm",
            t_frames / t_track,
            f"goal within {GOAL_TRACK_S:g} s and no slower than by frame: "
            f"{'met' if met else 'missed'}",
        )
    ]


PARTS: dict[str, Callable[[Sizes], list[Row]]] = {
    "retime": bench_retime,
    "via": bench_via,
    "follow": bench_follow,
    "track": bench_track,
}


def table(rows: Sequence[Row]) -> str:
    out = ["| row | poekin | reference | reference / poekin | |", "|---|---|---|---|---|"]
    for r in rows:
        ratio = "—" if r.ratio is None else f"{r.ratio:.3g}x"
        out.append(f"| {r.name} | {r.poekin} | {r.reference} | {ratio} | {r.note} |")
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0] if __doc__ else None,
        epilog=__doc__[__doc__.index("examples:") :] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--quick", action="store_true", help="small sizes, seconds: a check that it runs"
    )
    parser.add_argument(
        "--only", choices=sorted(PARTS), action="append", help="run only this part (repeatable)"
    )
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else Sizes()
    info = machine_info()
    loadavg = ", ".join(f"{x:.2f}" for x in info["load_average"] or ())
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} usable cores (load "
        f"average {loadavg}); poekin {package_version('poekin')}, toppra "
        f"{package_version('toppra')}, ruckig {package_version('ruckig')}, numpy "
        f"{np.__version__}; git {info['git']}",
        flush=True,
    )
    rows: list[Row] = []
    for name in args.only or PARTS:
        rows.extend(PARTS[name](sizes))
    print()
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
