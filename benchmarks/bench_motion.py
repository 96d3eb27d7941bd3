"""The motion benchmark (issue #28): ``chain.follow`` along straight lines, beside its goal.

Rows:

1. ``chain.follow`` of a UR5e straight line given as 1,000 samples (``line_path`` at uniform
   ``s``, a 0.5 m move with a 0.6 rad turn, the elbow up): median per call, single-threaded
   NumPy with the compiled kernel. Goal: <= 5 ms on one core. Beside it, 1,000 warm-started
   single solves (``chain.ik`` from the previous sample, one at a time) and one batched
   ``chain.ik_all`` of the 1,000 poses, the two things it is "close to".
2. The same line given as a callable (11 first samples): the adaptive re-sampling alone decides
   how many samples the 0.1 mm bound needs.
3. The FR3 (seven joints, no closed form): a 0.3 m line as a callable; each sample is
   ``chain.ik`` from the one before.

Every answer is checked before it is timed: the line followed to its end, the largest midpoint
deviation under 0.1 mm. Timings are medians of repeated calls (wall time on a possibly shared
machine: read medians, not one sample); the CPU and its vector width are printed with them.

examples:
  python benchmarks/bench_motion.py --quick      # seconds: a check that it runs
  python benchmarks/bench_motion.py              # the full run, under a minute
"""

from __future__ import annotations

import argparse
import pathlib
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info, package_version  # the FK benchmark's machine description

import poekin
from poekin.motion import line_path

UR_START = np.array([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
FR3_START = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.7])
GOAL_MS = 5.0


def median_s(call: Callable[[], Any], repeats: int, budget_s: float = 5.0) -> float:
    """Median wall time of ``call`` (s) over up to ``repeats`` calls, fewer past ``budget_s``."""
    call()  # warm: caches, the kernel's first use
    times: list[float] = []
    start = time.perf_counter()
    while len(times) < repeats and (not times or time.perf_counter() - start < budget_s):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _ur_line(chain: poekin.Chain) -> tuple[np.ndarray, np.ndarray]:
    T0 = chain.fk(UR_START)
    T1 = T0.copy()
    T1[:3, 3] += [0.3, -0.3, -0.25]
    turn = poekin.lie.exp_so3(np.array([0.0, 0.0, 0.6]))
    T1[:3, :3] = turn @ T0[:3, :3]
    return T0, T1


def bench_follow(quick: bool = False) -> list[dict[str, Any]]:
    """Time ``chain.follow`` (rows 1 to 3 of the module's docstring); returns the rows printed."""
    repeats = 3 if quick else 50
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        ur = poekin.load("universal_robots_ur5e")
        fr3 = poekin.load("franka_fr3")
    rows: list[dict[str, Any]] = []
    T0, T1 = _ur_line(ur)
    samples = line_path(T0, T1, np.linspace(0.0, 1.0, 1000))
    result = ur.follow(samples, UR_START)
    assert result.done and len(result.s) == 1000 and result.max_deviation <= 1e-4, result.detail

    def one_by_one() -> None:
        q = UR_START
        for T in samples:
            q = ur.ik(T, q, max_attempts=1).q

    rows.append(
        {
            "case": "UR5e, 1,000-sample line: chain.follow",
            "ms": 1e3 * median_s(lambda: ur.follow(samples, UR_START), repeats),
            "samples": len(result.s),
            "goal": f"<= {GOAL_MS:g} ms",
        }
    )
    rows.append(
        {
            "case": "  1,000 warm-started chain.ik, one by one",
            "ms": 1e3 * median_s(one_by_one, max(1, repeats // 5)),
            "samples": 1000,
            "goal": "",
        }
    )
    rows.append(
        {
            "case": "  one chain.ik_all of the 1,000 poses",
            "ms": 1e3 * median_s(lambda: ur.ik_all(samples), repeats),
            "samples": 1000,
            "goal": "",
        }
    )

    def ur_path(s: np.ndarray) -> np.ndarray:
        return line_path(T0, T1, s)

    adaptive = ur.follow(ur_path, UR_START)
    assert adaptive.done and adaptive.max_deviation <= 1e-4, adaptive.detail
    rows.append(
        {
            "case": "UR5e, the line as a callable (re-sampled)",
            "ms": 1e3 * median_s(lambda: ur.follow(ur_path, UR_START), repeats),
            "samples": len(adaptive.s),
            "goal": "",
        }
    )
    F0 = fr3.fk(FR3_START)
    F1 = F0.copy()
    F1[:3, 3] += [0.1, 0.25, -0.1]

    def fr3_path(s: np.ndarray) -> np.ndarray:
        return line_path(F0, F1, s)

    seven = fr3.follow(fr3_path, FR3_START)
    assert seven.done and seven.max_deviation <= 1e-4, seven.detail
    rows.append(
        {
            "case": "FR3, 0.3 m line as a callable (chain.ik)",
            "ms": 1e3 * median_s(lambda: fr3.follow(fr3_path, FR3_START), max(1, repeats // 5)),
            "samples": len(seven.s),
            "goal": "",
        }
    )
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
        f"average {loadavg}); poekin {package_version('poekin')}, numpy {np.__version__}; "
        f"git {info['git']}",
        flush=True,
    )
    rows = bench_follow(quick=args.quick)
    print(f"{'case':<46} {'ms':>9} {'samples':>8}  goal")
    for row in rows:
        print(f"{row['case']:<46} {row['ms']:>9.3f} {row['samples']:>8}  {row['goal']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
