"""A batch of FK beyond one process: chain.fk mapped over a dask array on a Dask cluster.

    pip install "dask[distributed]"
    python examples/dask_scale.py [--samples 1000000] [--chunk 100000] [--workers 2]

Starts a local distributed cluster (worker processes on 127.0.0.1, no dashboard), splits a
batch of UR5e configurations into chunks, and poses each chunk on a worker with ``chain.fk``
(``map_blocks``; the chain is pickled to the workers once, and the compiled kernel releases the
GIL, so each worker also uses its threads). The poses equal a single-process ``chain.fk`` of the
whole batch bit for bit: the kernel gives one configuration the same bits alone or in any batch.
For many machines, point ``Client`` at a real scheduler (``Client("tcp://scheduler:8786")``,
``dask-jobqueue``, ``dask-kubernetes``): the code that maps the chunks is the same.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
import warnings

import numpy as np

import poekin


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--chunk", type=int, default=100_000, help="configurations per task")
    parser.add_argument("--workers", type=int, default=2, help="worker processes")
    args = parser.parse_args()
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
    q = np.random.default_rng(0).uniform(-2 * np.pi, 2 * np.pi, (args.samples, 6))
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
        chunks = da.from_array(q, chunks=(args.chunk, 6))
        poses = chunks.map_blocks(
            chain.fk,
            dtype=np.float64,
            drop_axis=1,
            new_axis=[1, 2],
            chunks=(chunks.chunks[0], (4,), (4,)),
        )
        t0 = time.perf_counter()
        T_world_ee = poses.compute()
        elapsed = time.perf_counter() - t0
        workers = len(client.scheduler_info()["workers"])
    print(
        f"{args.samples} configurations in {chunks.numblocks[0]} chunks on {workers} workers: "
        f"{elapsed:.2f} s"
    )
    same = bool(np.array_equal(T_world_ee, chain.fk(q)))
    print(f"equal to the single-process result bit for bit: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
