"""UR5e forward kinematics: poekin (single call, batch) vs a MuJoCo ``mj_kinematics`` loop.

Prints the median and the spread (interquartile range) over repeats, per configuration, and the
ratio against poekin's batch. Machines here are shared and noisy: read medians and ratios.

    python benchmarks/bench_fk.py              # full sizes
    python benchmarks/bench_fk.py --quick      # tiny sizes, as CI runs it so it cannot rot
    python benchmarks/bench_fk.py --json out.json
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import time
import warnings
from collections.abc import Callable

import mujoco
import numpy as np

import poekin


def timings(fn: Callable[[], object], repeats: int, per: int) -> dict[str, float]:
    """Median and interquartile range of ``fn``'s wall time, in ns per configuration."""
    fn()  # warm up
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        fn()
        samples.append((time.perf_counter_ns() - t0) / per)
    q25, q50, q75 = np.percentile(samples, [25, 50, 75])
    return {"median_ns": float(q50), "iqr_ns": float(q75 - q25), "repeats": repeats}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny sizes (for CI)")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    batch, loop, repeats = (1_000, 200, 3) if args.quick else (100_000, 5_000, 15)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model("universal_robots_ur5e")
    chain = poekin.load(loaded)
    model, data = loaded.model, mujoco.MjData(loaded.model)
    q = poekin.sample_joint_values(chain, batch, seed=0)
    q1 = q[0].copy()

    def mj_loop() -> None:
        for k in range(loop):
            data.qpos[:] = q[k]
            mujoco.mj_kinematics(model, data)

    results = {
        "poekin fk, single call": timings(lambda: chain.fk(q1), repeats * 100, 1),
        f"poekin fk, batch {batch}": timings(lambda: chain.fk(q), repeats, batch),
        f"poekin fk_body, batch {batch}": timings(lambda: chain.fk_body(q), repeats, batch),
        "mujoco mj_kinematics loop": timings(mj_loop, repeats, loop),
    }
    base = results[f"poekin fk, batch {batch}"]["median_ns"]
    print(f"UR5e FK to attachment_site, ns per configuration ({platform.processor() or 'cpu'})")
    for name, r in results.items():
        print(
            f"  {name:32} median {r['median_ns']:10.1f}  IQR {r['iqr_ns']:8.1f}  "
            f"x{r['median_ns'] / base:6.2f} vs poekin batch"
        )
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
