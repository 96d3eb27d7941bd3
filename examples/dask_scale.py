"""FK, an IK dataset and motion retargeting beyond one process: chain.fk and chain.ik mapped over
dask arrays, poekin.motion.track mapped over clips.

    pip install "dask[distributed]"
    python examples/dask_scale.py [--samples 1000000] [--ik-samples 1000000] [--chunk 100000]
        [--workers 2] [--out dataset.npz] [--clips 0] [--clip-frames 60]

Starts a local distributed cluster (worker processes on 127.0.0.1, no dashboard), splits a
batch of UR5e configurations into chunks, and poses each chunk on a worker with ``chain.fk``
(``map_blocks``; the chain is pickled to the workers, and the compiled kernel releases the GIL,
so each worker also uses its threads). Then it builds an IK dataset the same way: targets that
are the poses of random configurations within the joint limits, each chunk solved on a worker
by ``chain.ik`` (from seeded random starts, not from the configurations that made them), and
``--out`` saves the targets with their answers. Both results equal a single-process call on the
whole batch bit for bit: the kernel gives a configuration the same pose, and a target the same
answer, alone or in any batch (an IK answer depends only on the target's own numbers and the
seed). For many machines, point ``Client`` at a real scheduler
(``Client("tcp://scheduler:8786")``, ``dask-jobqueue``, ``dask-kubernetes``): the code that maps
the chunks is the same.

``--clips K`` then retargets K clips of the G1 humanoid, one task per clip: each clip is a smooth
motion (every hinge but the fingers' its centre plus slow sines within its limits, the base
swaying) whose hands, feet and pelvis poses, with 5 mm of noise, are the targets of
:func:`poekin.motion.track` (the whole clip as one problem); the answers equal a single
process's bit for bit (the solve is deterministic and runs on one BLAS thread).
"""

from __future__ import annotations

import argparse
import logging
import pathlib
import sys
import time
import warnings
from typing import TYPE_CHECKING

import numpy as np

import poekin

if TYPE_CHECKING:
    import dask.array as da
    from dask.distributed import Client


def solve_block(T: np.ndarray, chain: poekin.Chain) -> np.ndarray:
    """``chain.ik`` of one chunk of ``(m, 4, 4)`` targets, as ``(m, n + 3)`` rows: the joint
    values, then success (1 or 0), the position error (m) and the orientation error (rad)."""
    found = chain.ik(T)
    return np.column_stack([found.q, found.success, found.pos_err, found.ori_err])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="FK configurations")
    parser.add_argument("--ik-samples", type=int, default=1_000_000, help="IK targets (0: none)")
    parser.add_argument("--chunk", type=int, default=100_000, help="configurations per task")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    parser.add_argument("--out", type=pathlib.Path, help="save the IK dataset here (.npz)")
    parser.add_argument("--clips", type=int, default=0, help="G1 clips to retarget (0: none)")
    parser.add_argument("--clip-frames", type=int, default=60, help="frames per clip (30 Hz)")
    args = parser.parse_args()
    if args.out is not None and args.out.exists():
        print(f"dask_scale: {args.out} already exists; choose another path", file=sys.stderr)
        return 1
    try:
        import dask.array as da
        from dask.distributed import Client, LocalCluster
    except ImportError:
        print('dask_scale: needs Dask: pip install "dask[distributed]"', file=sys.stderr)
        return 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
            chain = poekin.load("universal_robots_ur5e")
    except poekin.PoekinError as e:
        print(f"dask_scale: {e}", file=sys.stderr)
        return 1
    with (
        LocalCluster(
            n_workers=args.workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            # a busy machine makes Dask log warnings ("event loop was unresponsive") that say
            # nothing about the result; errors still show
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster, timeout=60) as client,
    ):
        workers = len(client.scheduler_info()["workers"])
        # drawn on the workers, chunk by chunk: no batch travels through the task graph
        q = da.random.default_rng(0).uniform(
            -2 * np.pi, 2 * np.pi, size=(args.samples, 6), chunks=(args.chunk, 6)
        )
        t0 = time.perf_counter()
        q_all, T_world_ee = da.compute(q, poses_of(chain, q))
        elapsed = time.perf_counter() - t0
        print(
            f"{args.samples} configurations in {q.numblocks[0]} chunks on {workers} "
            f"workers: {elapsed:.2f} s"
        )
        same = bool(np.array_equal(T_world_ee, chain.fk(q_all)))
        print(f"equal to the single-process result bit for bit: {same}")
        if args.ik_samples > 0:
            lo, hi = chain.limits[:, 0], chain.limits[:, 1]
            # scaled from [0, 1): Dask would broadcast array bounds to the whole batch in
            # its task graph (96 MB for a million targets)
            unit = da.random.default_rng(1).uniform(
                size=(args.ik_samples, 6), chunks=(args.chunk, 6)
            )
            q_made = lo + (hi - lo) * unit
            same &= ik_dataset(chain, poses_of(chain, q_made), workers, args.out)
        if args.clips > 0:
            same &= retarget(client, args.clips, args.clip_frames, workers)
    return 0 if same else 1


def poses_of(chain: poekin.Chain, q: da.Array) -> da.Array:
    """``chain.fk`` of each chunk of ``(N, 6)`` joint values: ``(N, 4, 4)`` poses."""
    return q.map_blocks(
        chain.fk,  # the bound method: the chain and its compiled method travel to the workers
        dtype=np.float64,
        drop_axis=1,
        new_axis=[1, 2],
        chunks=(q.chunks[0], (4,), (4,)),
    )


def ik_dataset(
    chain: poekin.Chain, targets: da.Array, workers: int, out: pathlib.Path | None
) -> bool:
    """Solve the targets chunk by chunk on the cluster; True if the answers equal one
    process's bit for bit."""
    import dask.array as da

    rows = targets.map_blocks(
        solve_block,
        chain=chain,
        dtype=np.float64,
        drop_axis=2,
        chunks=(targets.chunks[0], (chain.n_joints + 3,)),
    )
    t0 = time.perf_counter()
    T, answers = da.compute(targets, rows)  # the targets are computed once, for both
    elapsed = time.perf_counter() - t0
    n = len(T)
    print(
        f"IK dataset: {n} targets in {targets.numblocks[0]} chunks on {workers} workers: "
        f"{elapsed:.2f} s ({n / elapsed:,.0f} solves/s)"
    )
    q, success = answers[:, : chain.n_joints], answers[:, chain.n_joints] == 1.0
    one = chain.ik(T)
    same = bool(
        np.array_equal(q, one.q)
        and np.array_equal(success, one.success)
        and np.array_equal(answers[:, -2], one.pos_err)
        and np.array_equal(answers[:, -1], one.ori_err)
    )
    print(f"solved: {int(success.sum())} of {n}")
    print(f"equal to the single-process result bit for bit: {same}")
    if out is not None:
        np.savez(out, T=T, q=q, success=success, pos_err=answers[:, -2], ori_err=answers[:, -1])
        print(f"dataset (T, q, success, pos_err, ori_err) written to {out}")
    return same


CLIP_DT = 1.0 / 30.0  # s
CLIP_FRAMES = ("left_elbow_roll_link", "right_elbow_roll_link", "left_foot", "right_foot", "pelvis")


def g1() -> tuple[poekin.Tree, tuple[str, ...]]:
    """The built-in G1 and its finger joints (frozen in the clips)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        tree = poekin.load_tree("unitree_g1")
    digits = {"zero", "one", "two", "three", "four", "five", "six"}
    return tree, tuple(n for n in tree.joint_names if n.split("_")[1] in digits)


def clip_targets(seed: int, frames: int) -> dict[str, np.ndarray]:
    """Clip ``seed``'s targets: each frame's ``(frames, 4, 4)`` poses, with noise."""
    tree, fingers = g1()
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] * CLIP_DT
    q = np.repeat(tree.qpos0[None], frames, axis=0)
    for k, kind in enumerate(tree.joint_types):
        if kind == "revolute" and tree.joint_names[k] not in fingers:
            lo, hi = tree.joint_limits[k]
            a = tree.qpos_adr[k]
            centre, swing = (lo + hi) / 2, 0.1 * min(hi - lo, 1.0)
            wave = swing * np.sin(2 * np.pi * rng.uniform(0.1, 0.5) * t + rng.uniform(0, 6.3))
            q[:, a] = np.clip(centre + wave[:, 0], lo, hi)
    q[:, 0] += 0.05 * np.sin(2 * np.pi * 0.2 * t[:, 0])
    poses = tree.fk(q)
    out = {}
    for name in CLIP_FRAMES:
        T = np.array(poses[:, tree.frame_index(name)])
        T[:, :3, 3] += rng.normal(0.0, 0.005, (frames, 3))
        out[name] = T
    return out


def track_clip(seed: int, frames: int) -> np.ndarray:
    """Clip ``seed`` retargeted by :func:`poekin.motion.track`: ``(frames, nq)``."""
    import poekin.motion

    tree, fingers = g1()
    found = poekin.motion.track(
        tree, clip_targets(seed, frames), tree.qpos0, freeze=fingers, dt=CLIP_DT
    )
    return np.asarray(found.qpos)


def retarget(client: Client, clips: int, frames: int, workers: int) -> bool:
    """The clips on the cluster, one task per clip; True if the answers equal one process's
    bit for bit."""
    t0 = time.perf_counter()
    futures = client.map(track_clip, range(clips), frames=frames, pure=False)
    answers = client.gather(futures)
    elapsed = time.perf_counter() - t0
    print(
        f"G1 clips: {clips} of {frames} frames in {clips} tasks on {workers} workers: "
        f"{elapsed:.2f} s"
    )
    same = all(np.array_equal(a, track_clip(k, frames)) for k, a in enumerate(answers))
    print(f"equal to the single-process result bit for bit: {same}")
    return same


if __name__ == "__main__":
    sys.exit(main())
