"""Batched distances between convex shapes (issue #29, sections 1 and 3):
:mod:`poekin.collision.primitives` and :mod:`poekin.collision.gjk` against a Python loop of
MuJoCo's ``mj_geomDistance`` on the same pairs, in the same run.

Rows: capsule-capsule (the closed form) and cylinder-cylinder (the batched GJK; the
overlapping pairs' EPA pair by pair, so that row takes a tenth of the pairs; then GJK alone,
``depth=False``), on ``N`` random pairs (uniform rotations, centres in a 0.6 m cube, sizes in
[0.02, 0.2] m, about a fifth overlapping). MuJoCo's loop sets both mocap poses, runs
``mj_kinematics`` and ``mj_geomDistance`` per pair (timed on a sample of the pairs, scaled to
the row's). Also the largest difference between the two, apart and overlapping. Timings
are medians over repeats of the whole batch (wall time on a possibly shared machine); the
CPU, its vector width and the load average are printed first.

examples:
  python benchmarks/bench_distance.py --quick    # seconds: a check that it runs
  python benchmarks/bench_distance.py            # 100,000 pairs a row, about a minute
"""

from __future__ import annotations

import argparse
import pathlib
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests" / "collision"))
from bench_fk import machine_info, package_version  # the FK benchmark's machine description
from mj_geoms import GeomPair, random_poses, random_sizes  # the tests' MuJoCo pair

from poekin.collision import gjk, primitives


def _median_time(f: Callable[[], Any], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _mujoco_loop(
    kind: str, T1: np.ndarray, S1: np.ndarray, T2: np.ndarray, S2: np.ndarray
) -> Callable[[], np.ndarray]:
    pair = GeomPair(kind, kind)
    m, d = pair.model, pair.data
    quats = np.zeros((2, len(T1), 4))
    for k in range(len(T1)):
        for g, T in enumerate((T1[k], T2[k])):
            mujoco.mju_mat2Quat(quats[g, k], np.ascontiguousarray(T[:3, :3]).ravel())
    fromto = np.zeros(6)

    def run() -> np.ndarray:
        out = np.zeros(len(T1))
        for k in range(len(T1)):
            d.mocap_pos[0], d.mocap_pos[1] = T1[k, :3, 3], T2[k, :3, 3]
            d.mocap_quat[0], d.mocap_quat[1] = quats[0, k], quats[1, k]
            m.geom_size[0], m.geom_size[1] = S1[k], S2[k]
            mujoco.mj_kinematics(m, d)
            out[k] = mujoco.mj_geomDistance(m, d, 0, 1, 100.0, fromto)
        return out

    return run


def _capsules(T1: np.ndarray, S1: np.ndarray, T2: np.ndarray, S2: np.ndarray) -> Any:
    return primitives.capsule_capsule(T1, S1, T2, S2)


def _cylinders(T1: np.ndarray, S1: np.ndarray, T2: np.ndarray, S2: np.ndarray) -> Any:
    return gjk.gjk("cylinder", T1, S1, "cylinder", T2, S2)


def _cylinders_gjk(T1: np.ndarray, S1: np.ndarray, T2: np.ndarray, S2: np.ndarray) -> Any:
    return gjk.gjk("cylinder", T1, S1, "cylinder", T2, S2, depth=False)


# (name, kind, function, share of N): EPA runs pair by pair, so its row takes a tenth
ROWS = [
    ("capsule-capsule", "capsule", _capsules, 1.0),
    ("cylinder-cylinder", "cylinder", _cylinders, 0.1),
    ("  GJK, no depth", "cylinder", _cylinders_gjk, 1.0),  # overlap found, its depth not computed
]


def bench(n: int, sample: int, repeats: int) -> None:
    """Print one row per pair kind: ``n`` pairs, MuJoCo's loop timed on ``sample`` of them."""
    print(
        f"{'pair':18s} {'pairs':>8s} {'poekin':>10s} {'mujoco loop':>12s} {'speed-up':>9s} "
        f"{'max |diff| apart':>17s} {'overlapping':>12s}"
    )
    for name, kind, f, share in ROWS:
        n_row = int(n * share)
        rng = np.random.default_rng(0)  # the same pairs for both cylinder rows
        T1, T2 = random_poses(rng, (n_row,)), random_poses(rng, (n_row,))
        S1, S2 = random_sizes(rng, (n_row,)), random_sizes(rng, (n_row,))
        args = (T1, S1, T2, S2)
        ours_t = _median_time(lambda f=f, args=args: f(*args), repeats)
        ours = f(*args).distance
        loop = _mujoco_loop(kind, T1[:sample], S1[:sample], T2[:sample], S2[:sample])
        mj_t = _median_time(loop, repeats) * n_row / sample
        ref = loop()
        diff = np.abs(ours[:sample] - ref)
        apart = ref > 0
        overlap = f"{diff[~apart].max():12.1e}" if f is not _cylinders_gjk else f"{'-':>12s}"
        print(
            f"{name:18s} {n_row:8d} {ours_t * 1e3:8.1f}ms {mj_t * 1e3:10.1f}ms "
            f"{mj_t / ours_t:8.1f}x {diff[apart].max():17.1e} {overlap}",
            flush=True,
        )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog=__doc__[__doc__.index("examples:") :],
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
        f"average {loadavg}); poekin {package_version('poekin')}, mujoco {mujoco.__version__}, "
        f"numpy {np.__version__}; git {info['git']}",
        flush=True,
    )
    if args.quick:
        bench(n=2_000, sample=200, repeats=1)
    else:
        bench(n=100_000, sample=10_000, repeats=3)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
