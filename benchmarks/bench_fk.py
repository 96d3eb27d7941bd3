"""Forward kinematics: poekin (single call, batch) vs a MuJoCo ``mj_kinematics`` loop, for the
UR5e chain and for whole trees (go2: free base + 12 hinges; aloha: two arms with slide fingers).

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


def _quiet_load(robot: str) -> poekin.LoadedModel:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load_model(robot)


def mj_loop(model: mujoco.MjModel, qpos: np.ndarray) -> Callable[[], None]:
    """``mj_kinematics`` on each row of ``qpos`` (``(N, nq)``) in a Python loop."""
    data = mujoco.MjData(model)

    def run() -> None:
        for q in qpos:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)

    return run


def tree_results(robot: str, batch: int, loop: int, repeats: int) -> dict[str, dict[str, float]]:
    """``tree.fk`` (every body and site) on a batch vs an ``mj_kinematics`` loop."""
    loaded = _quiet_load(robot)
    tree = poekin.load_tree(loaded)
    qpos = poekin.sample_qpos(tree, batch, seed=0)
    return {
        f"{robot}: poekin tree.fk, batch {batch}": timings(lambda: tree.fk(qpos), repeats, batch),
        f"{robot}: mujoco mj_kinematics loop": timings(
            mj_loop(loaded.model, qpos[:loop]), repeats, loop
        ),
    }


def report(title: str, results: dict[str, dict[str, float]], base_name: str) -> None:
    base = results[base_name]["median_ns"]
    print(title)
    for name, r in results.items():
        print(
            f"  {name:44} median {r['median_ns']:10.1f}  IQR {r['iqr_ns']:8.1f}  "
            f"x{r['median_ns'] / base:6.2f} vs poekin batch"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny sizes (for CI)")
    parser.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    args = parser.parse_args()
    batch, loop, repeats = (1_000, 200, 3) if args.quick else (100_000, 5_000, 15)

    loaded = _quiet_load("universal_robots_ur5e")
    chain = poekin.load(loaded)
    q = poekin.sample_joint_values(chain, batch, seed=0)
    q1 = q[0].copy()
    results = {
        "poekin fk, single call": timings(lambda: chain.fk(q1), repeats * 100, 1),
        f"poekin fk, batch {batch}": timings(lambda: chain.fk(q), repeats, batch),
        f"poekin fk_body, batch {batch}": timings(lambda: chain.fk_body(q), repeats, batch),
        "mujoco mj_kinematics loop": timings(mj_loop(loaded.model, q[:loop]), repeats, loop),
    }
    cpu = platform.processor() or "cpu"
    report(
        f"UR5e FK to attachment_site, ns per configuration ({cpu})",
        results,
        f"poekin fk, batch {batch}",
    )
    for robot in ("unitree_go2", "aloha"):
        trees = tree_results(robot, batch // 10, loop, repeats)
        report(
            f"{robot}: every body and site, ns per configuration",
            trees,
            f"{robot}: poekin tree.fk, batch {batch // 10}",
        )
        results.update(trees)
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
