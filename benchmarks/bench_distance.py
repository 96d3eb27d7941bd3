"""Batched distances between convex shapes (issue #29, sections 1 and 3):
:mod:`poekin.collision.primitives` and :mod:`poekin.collision.gjk` against a Python loop of
MuJoCo's ``mj_geomDistance`` on the same pairs, in the same run.

Rows: capsule-capsule (the closed form) and cylinder-cylinder (GJK, EPA for the overlapping
pairs; then GJK alone, ``depth=False``), on ``N`` random pairs (uniform rotations, centres in a
0.6 m cube, sizes in [0.02, 0.2] m, about a fifth overlapping), each on the compiled kernel
(poekin/kernel/_distance.h, one thread and the default threads) and on the NumPy reference
(whose EPA runs pair by pair in Python, so its cylinder row takes a tenth of the pairs), with
whether the two give the same bits. MuJoCo's loop sets both mocap poses, runs
``mj_kinematics`` and ``mj_geomDistance`` per pair (timed on a sample of the pairs, scaled to
the row's). Also the largest difference between the kernel and MuJoCo, apart and overlapping.

Then the UR5e's self-collision (issue #29's speed goal): its 9 collision geoms (8 capsules, a
cylinder) and the 21 pairs MuJoCo's rules check (other bodies, not parent and child), at random
configurations: ``gjk.pair_distances`` on the geoms' world poses (computed beforehand; FK is
not in the figure) against a Python loop of ``mj_kinematics`` + ``mj_collision`` per
configuration, and whether both find the same configurations in collision.

Timings are medians over repeats of the whole batch (wall time on a possibly shared machine);
the CPU, its vector width and the load average are printed first.

examples:
  python benchmarks/bench_distance.py --quick    # seconds: a check that it runs
  python benchmarks/bench_distance.py            # 100,000 pairs a row, a few minutes
"""

from __future__ import annotations

import argparse
import itertools
import pathlib
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests" / "collision"))
from bench_fk import machine_info, package_version  # the FK benchmark's machine description
from mj_geoms import GeomPair, random_poses, random_sizes  # the tests' MuJoCo pair

import poekin
from poekin.collision import gjk
from poekin.io.sources import load_model


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
    return gjk.distance("capsule", T1, S1, "capsule", T2, S2)  # the closed form


def _cylinders(T1: np.ndarray, S1: np.ndarray, T2: np.ndarray, S2: np.ndarray) -> Any:
    return gjk.gjk("cylinder", T1, S1, "cylinder", T2, S2)


def _cylinders_gjk(T1: np.ndarray, S1: np.ndarray, T2: np.ndarray, S2: np.ndarray) -> Any:
    return gjk.gjk("cylinder", T1, S1, "cylinder", T2, S2, depth=False)


# (name, kind, function, share of N for the NumPy reference): its EPA runs pair by pair
ROWS = [
    ("capsule-capsule", "capsule", _capsules, 1.0),
    ("cylinder-cylinder", "cylinder", _cylinders, 0.1),
    ("  GJK, no depth", "cylinder", _cylinders_gjk, 1.0),  # overlap found, its depth not computed
]


def _numpy(f: Callable[..., Any], *args: Any) -> Any:
    """``f(*args)`` on the NumPy reference (gjk without its compiled twin)."""
    kernel, gjk._kernel = gjk._kernel, None
    try:
        return f(*args)
    finally:
        gjk._kernel = kernel


def _threads(n: int | None, f: Callable[[], Any]) -> Callable[[], Any]:
    def run() -> Any:
        before = poekin.get_threads()
        poekin.set_threads(n)
        try:
            return f()
        finally:
            poekin.set_threads(before)

    return run


def bench(n: int, sample: int, repeats: int) -> None:
    """Print one row per pair kind: ``n`` pairs, MuJoCo's loop timed on ``sample`` of them."""
    print(
        f"{'pair':18s} {'pairs':>8s} {'kernel 1 thr':>12s} {f'{poekin.get_threads()} thr':>9s} "
        f"{'numpy':>9s} {'mujoco loop':>12s} {'speed-up':>9s} {'same bits':>9s} "
        f"{'max |diff| apart':>17s} {'overlapping':>12s}"
    )
    for name, kind, f, share in ROWS:
        rng = np.random.default_rng(0)  # the same pairs for both cylinder rows
        T1, T2 = random_poses(rng, (n,)), random_poses(rng, (n,))
        S1, S2 = random_sizes(rng, (n,)), random_sizes(rng, (n,))
        args = (T1, S1, T2, S2)
        one_t = _median_time(_threads(1, lambda f=f, args=args: f(*args)), repeats)
        all_t = _median_time(lambda f=f, args=args: f(*args), repeats)
        ours = f(*args).distance
        m = max(int(n * share), 1)
        part = (T1[:m], S1[:m], T2[:m], S2[:m])
        np_t = _median_time(lambda f=f, part=part: _numpy(f, *part), 1) * n / m
        same = np.array_equal(_numpy(f, *part).distance, ours[:m])
        loop = _mujoco_loop(kind, T1[:sample], S1[:sample], T2[:sample], S2[:sample])
        mj_t = _median_time(loop, repeats) * n / sample
        ref = loop()
        diff = np.abs(ours[:sample] - ref)
        apart = ref > 0
        overlap = f"{diff[~apart].max():12.1e}" if f is not _cylinders_gjk else f"{'-':>12s}"
        print(
            f"{name:18s} {n:8d} {one_t * 1e3:10.1f}ms {all_t * 1e3:7.1f}ms {np_t * 1e3:7.0f}ms "
            f"{mj_t * 1e3:10.1f}ms {mj_t / all_t:8.1f}x {same!s:>9s} "
            f"{diff[apart].max():17.1e} {overlap}",
            flush=True,
        )


_MJ_KINDS = {0: "plane", 2: "sphere", 3: "capsule", 4: "ellipsoid", 5: "cylinder", 6: "box"}


def bench_ur5e(n: int, sample: int, repeats: int) -> None:
    """The UR5e's self-collision: ``n`` configurations, MuJoCo's loop on ``sample``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the visual meshes' files are absent: tiny spheres
        m = load_model("universal_robots_ur5e").model
    d = mujoco.MjData(m)
    geoms = [g for g in range(m.ngeom) if m.geom_contype[g] or m.geom_conaffinity[g]]
    body, parent = m.geom_bodyid, m.body_parentid
    pairs = np.array(
        [
            (i, j)
            for i, j in itertools.combinations(range(len(geoms)), 2)
            if body[geoms[i]] != body[geoms[j]]
            and parent[body[geoms[i]]] != body[geoms[j]]
            and parent[body[geoms[j]]] != body[geoms[i]]
        ]
    )
    kinds = [_MJ_KINDS[int(m.geom_type[g])] for g in geoms]
    sizes = m.geom_size[geoms]
    rng = np.random.default_rng(1)
    lo, hi = m.jnt_range[:, 0], m.jnt_range[:, 1]
    Q = rng.uniform(np.where(hi > lo, lo, -np.pi), np.where(hi > lo, hi, np.pi), (n, m.nq))
    poses = np.tile(np.eye(4), (n, len(geoms), 1, 1))
    for k in range(n):
        d.qpos[:] = Q[k]
        mujoco.mj_kinematics(m, d)
        poses[k, :, :3, :3] = d.geom_xmat[geoms].reshape(-1, 3, 3)
        poses[k, :, :3, 3] = d.geom_xpos[geoms]

    def ours() -> Any:
        return gjk.pair_distances(kinds, sizes, pairs, poses)

    def loop() -> np.ndarray:
        hits = np.zeros(sample, dtype=bool)
        for k in range(sample):
            d.qpos[:] = Q[k]
            mujoco.mj_kinematics(m, d)
            mujoco.mj_collision(m, d)
            hits[k] = d.ncon > 0
        return hits

    one_t = _median_time(_threads(1, ours), repeats) / n
    all_t = _median_time(ours, repeats) / n
    mj_t = _median_time(loop, repeats) / sample
    found = ours().distance
    hits = loop()
    agree = np.mean((found[:sample] < 0).any(axis=-1) == hits)
    print(
        f"\nUR5e self-collision, {len(geoms)} geoms ({', '.join(sorted(set(kinds)))}), "
        f"{len(pairs)} pairs ({sum('cylinder' in (kinds[i], kinds[j]) for i, j in pairs)} "
        f"with the cylinder), {n} configurations:\n"
        f"  poekin pair_distances {one_t * 1e6:.2f} us/config on 1 thread, {all_t * 1e6:.2f} on "
        f"{poekin.get_threads()}; MuJoCo loop mj_kinematics + mj_collision {mj_t * 1e6:.2f} "
        f"us/config: {mj_t / all_t:.1f}x ({mj_t / one_t:.1f}x on 1 thread); "
        f"{hits.mean():.1%} in collision, the same configurations in {agree:.2%}",
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
        bench_ur5e(n=2_000, sample=500, repeats=1)
    else:
        bench(n=100_000, sample=10_000, repeats=3)
        bench_ur5e(n=100_000, sample=10_000, repeats=3)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
