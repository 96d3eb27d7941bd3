"""The analytic IK benchmark: poekin's ``chain.ik_all`` against ik-geo, every solution (issue #21).

One run, the same targets for both: the UR5e (Menagerie ``universal_robots_ur5e``, end frame
``attachment_site``) at configurations drawn uniformly within its joint limits (fixed seed),
the targets being MuJoCo's poses of them. Timed:

* poekin ``chain.ik_all(T)``: one call on the whole batch (the compiled kernel, on poekin's
  threads and on one), the same call on the NumPy reference path, and single calls (one
  ``(4, 4)`` target each);
* ik-geo (``pip install ik-geo``, Elias and Wen's IK-Geo in Rust), ``Robot.get_ik`` in a loop,
  one pose per call (it has no batch call), built with ``three_parallel_two_intersecting``
  from the same axes.

Then every solution either reports is checked with MuJoCo: poekin's ``valid`` ones and ik-geo's
exact ones (``is_ls`` False) are put through ``mj_kinematics`` and compared with the target
(position in m, geodesic angle in rad). A target counts as solved when the configuration it
came from is among the solutions (modulo 2 pi), each within the limits.

Pitfall: ik-geo's ``get_ik(R, t)`` expects the transpose of the rotation its documentation
describes (with ``R`` as documented every solution misses by ~0.7 m); this script passes
``R.T``. It also wants the axis points where axes 1 and 2, and 5 and 6, meet.

Every figure is the median over repeats with its interquartile range; ratios are ik-geo's time
over poekin's. The machines here are shared and noisy: read medians and ratios. No timing is
asserted anywhere.

examples:
  python benchmarks/bench_ik_all.py --quick          # seconds; what CI runs
  python benchmarks/bench_ik_all.py --json ik_all.json
  python benchmarks/bench_ik_all.py --n 100000 --repeats 15
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import warnings
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import (  # the FK benchmark's machine description and timing helpers
    ROBOT,
    SITE,
    Timing,
    fmt_count,
    fmt_ns,
    machine_info,
    package_version,
    time_batch,
    time_loop,
    to_json,
)

import poekin
from poekin.ik import analytic

FloatArray = np.ndarray[Any, np.dtype[np.float64]]
EXACT = 1e-12  # m and rad: a solution this close to its target, checked by MuJoCo, is exact
SAME_Q = 1e-6  # rad: the drawn configuration is among the solutions


@dataclasses.dataclass(frozen=True)
class Sizes:
    n: int = 10_000  # targets; the batch
    single: int = 2_000  # targets per single-call repeat
    loop: int = 2_000  # ik-geo: targets per repeat (one call each)
    checked: int = 2_000  # targets whose every solution MuJoCo checks
    repeats: int = 7
    budget_s: float = 1.0


QUICK = Sizes(n=500, single=100, loop=100, checked=200, repeats=3, budget_s=0.1)


@dataclasses.dataclass
class Row:
    name: str
    per_target: Timing | None = None
    ratio: float | None = None  # ik-geo's time / this row's
    solutions: float | None = None  # exact solutions per target, mean
    solved: float | None = None  # fraction of targets whose drawn q is among the solutions
    max_pos_m: float | None = None  # MuJoCo residual over every exact solution
    max_ori_rad: float | None = None
    note: str = ""


# --- the arm and its targets ----------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Arm:
    loaded: poekin.LoadedModel
    chain: poekin.Chain

    def mujoco_poses(self, q: FloatArray) -> FloatArray:
        """``(m, 4, 4)`` poses of the end frame from ``mj_kinematics`` for ``(m, 6)`` q."""
        m = self.loaded.model
        data, site = mujoco.MjData(m), m.site(SITE).id
        idx = list(self.chain.qpos_indices or range(6))
        out = np.tile(np.eye(4), (len(q), 1, 1))
        for k, row in enumerate(q):
            data.qpos[idx] = row
            mujoco.mj_kinematics(m, data)
            out[k, :3, :3] = data.site_xmat[site].reshape(3, 3)
            out[k, :3, 3] = data.site_xpos[site]
        return out


def load_arm() -> Arm:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model(ROBOT)
    return Arm(loaded, poekin.load(loaded, SITE))


def check(
    arm: Arm, T: FloatArray, q_drawn: FloatArray, solutions: list[FloatArray], row: Row
) -> None:
    """MuJoCo's residuals of every solution (``solutions[k]``: ``(m_k, 6)`` for target k),
    the mean count, and whether the drawn q is among them within the limits."""
    flat = np.concatenate([s.reshape(-1, 6) for s in solutions])
    which = np.repeat(np.arange(len(solutions)), [len(s) for s in solutions])
    pos, ori = poekin.pose_errors(T[which], arm.mujoco_poses(flat))
    row.max_pos_m, row.max_ori_rad = float(pos.max(initial=0.0)), float(ori.max(initial=0.0))
    row.solutions = float(np.mean([len(s) for s in solutions]))
    limits = arm.chain.limits
    found = []
    for s, q in zip(solutions, q_drawn, strict=True):
        inside = np.all((s >= limits[:, 0]) & (s <= limits[:, 1]), axis=-1)
        gap = np.max(np.abs(np.angle(np.exp(1j * (s - q)))), axis=-1)
        found.append(bool(np.any(inside & (gap <= SAME_Q))))
    row.solved = float(np.mean(found))


# --- poekin -------------------------------------------------------------------------------------


def poekin_rows(arm: Arm, T: FloatArray, q: FloatArray, sizes: Sizes) -> list[Row]:
    chain = arm.chain
    n = sizes.n
    rows = []
    batch = Row("poekin ik_all, batch", time_batch(chain.ik_all, T, n, sizes.repeats))
    sol = chain.ik_all(T[: sizes.checked])
    check(
        arm,
        T[: sizes.checked],
        q[: sizes.checked],
        [s[v] for s, v in zip(sol.q, sol.valid, strict=True)],
        batch,
    )
    rows.append(batch)
    threads = poekin.get_threads()
    if threads > 1:
        poekin.set_threads(1)
        try:
            rows.append(
                Row("poekin ik_all, batch, 1 thread", time_batch(chain.ik_all, T, n, sizes.repeats))
            )
        finally:
            poekin.set_threads(threads)
    small = T[: max(sizes.n // 10, 1)]
    rows.append(
        Row(
            "poekin ik_all, NumPy path (no compiler)",
            time_batch(lambda t: analytic.solve_numpy(chain, t), small, len(small), sizes.repeats),
        )
    )
    rows.append(
        Row(
            "poekin ik_all, single calls",
            time_loop(chain.ik_all, list(T[: sizes.single]), sizes.repeats, sizes.budget_s),
        )
    )
    if not poekin.compiled_kernel():
        for r in rows:
            r.note = "no compiled kernel: NumPy path"
    return rows


# --- ik-geo -------------------------------------------------------------------------------------


def _closest(p1: FloatArray, w1: FloatArray, p2: FloatArray, w2: FloatArray) -> FloatArray:
    """Where two lines meet (the midpoint of their closest points)."""
    n = np.cross(w1, w2)
    d = p2 - p1
    a = p1 + w1 * (np.cross(d, w2) @ n / (n @ n))
    b = p2 + w2 * (np.cross(d, w1) @ n / (n @ n))
    return (a + b) / 2


def ik_geo_robot(chain: poekin.Chain) -> Any:
    """ik-geo's robot from the chain's axes: directions h_i and the offsets p_i between one
    point on each axis, the points where axes 1 and 2 and axes 5 and 6 meet, and the feet of
    the common normal from there on axes 3 and 4 (its kinematic form, all frames aligned with
    the base at q = 0)."""
    import ik_geo

    w = chain.screws[:, :3]
    point = np.cross(w, chain.screws[:, 3:])
    c12 = _closest(point[0], w[0], point[1], w[1])
    c56 = _closest(point[4], w[4], point[5], w[5])
    feet = [point[i] + w[i] * ((c12 - point[i]) @ w[i]) for i in (2, 3)]
    points = [c12, c12, *feet, c56, c56]
    p = np.zeros((7, 3))
    p[0] = points[0]
    for i in range(1, 6):
        p[i] = points[i] - points[i - 1]
    p[6] = chain.home[:3, 3] - points[5]
    return ik_geo.Robot.three_parallel_two_intersecting(w.tolist(), p.tolist())


def ik_geo_row(arm: Arm, T: FloatArray, q: FloatArray, sizes: Sizes) -> Row:
    try:
        robot = ik_geo_robot(arm.chain)
    except ImportError:
        return Row(
            "ik-geo get_ik, loop", note="not installed: pip install ik-geo (the bench extra)"
        )
    R_home = arm.chain.home[:3, :3]
    # the rotation ik-geo wants: the target's turn of the base-aligned frame 6, transposed
    args = [((t[:3, :3] @ R_home.T).T.tolist(), t[:3, 3].tolist()) for t in T]

    def solve(a: tuple[list[list[float]], list[float]]) -> Any:
        return robot.get_ik(*a)

    row = Row(
        "ik-geo get_ik, loop", time_loop(solve, args[: sizes.loop], sizes.repeats, sizes.budget_s)
    )
    solutions = []
    for a in args[: sizes.checked]:
        exact = [s for s, least_squares in robot.get_ik(*a) if not least_squares]
        solutions.append(np.array(exact, dtype=np.float64).reshape(-1, 6))
    check(arm, T[: sizes.checked], q[: sizes.checked], solutions, row)
    version = package_version("ik-geo")
    row.note = f"ik-geo {version}; one pose per call" if version else ""
    return row


# --- report -------------------------------------------------------------------------------------


def _fmt(x: float | None, spec: str) -> str:
    return "" if x is None else format(x, spec)


def print_table(rows: list[Row]) -> None:
    print(
        f"\n{'':42} {'per target':>10} {'IQR':>9} {'ik-geo/':>8} {'solutions':>9} "
        f"{'drawn q':>8} {'max residual (MuJoCo)':>22}  note"
    )
    print(
        f"{'':42} {'':>10} {'':>9} {'this':>8} {'per target':>9} {'found':>8} {'m':>10} {'rad':>11}"
    )
    for r in rows:
        t = r.per_target
        cells = f"{fmt_ns(t.median_ns):>10} {fmt_ns(t.iqr_ns):>9}" if t else f"{'':>10} {'':>9}"
        print(
            f"{r.name:42} {cells} {_fmt(r.ratio, '>7.1f')}{'x' if r.ratio else ' ':1} "
            f"{_fmt(r.solutions, '>9.2f')} {_fmt(r.solved, '>8.2%')} "
            f"{_fmt(r.max_pos_m, '>10.1e')} {_fmt(r.max_ori_rad, '>11.1e')}  {r.note}"
        )


def run(sizes: Sizes, seed: int) -> list[Row]:
    arm = load_arm()
    limits = arm.chain.limits
    q = np.random.default_rng(seed).uniform(limits[:, 0], limits[:, 1], (sizes.n, 6))
    T = arm.mujoco_poses(q)
    rows = [*poekin_rows(arm, T, q, sizes), ik_geo_row(arm, T, q, sizes)]
    geo = rows[-1].per_target
    for r in rows:
        if geo and r.per_target:
            r.ratio = geo.median_ns / r.per_target.median_ns
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    doc = __doc__ or ""
    parser = argparse.ArgumentParser(
        description=doc.splitlines()[0],
        epilog="examples:" + doc.split("examples:")[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--quick", action="store_true", help="tiny sizes, seconds (for CI)")
    parser.add_argument("--n", type=int, help="targets in the batch (10000)")
    parser.add_argument("--repeats", type=int, help="repeats per measurement (7)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (0)")
    parser.add_argument("--json", metavar="PATH", type=pathlib.Path, help="write results here")
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else Sizes()
    if args.n:
        sizes = dataclasses.replace(
            sizes, n=args.n, single=min(sizes.single, args.n), loop=min(sizes.loop, args.n),
            checked=min(sizes.checked, args.n),
        )  # fmt: skip
    if args.repeats:
        sizes = dataclasses.replace(sizes, repeats=args.repeats)
    info = machine_info()
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} cores, "
        f"load {info['load_average']}; poekin threads {info['poekin_threads']}"
    )
    print(
        f"UR5e {SITE}: {fmt_count(sizes.n)} targets from q uniform within the limits "
        f"(seed {args.seed}); medians and IQR over {sizes.repeats} repeats; MuJoCo checks every "
        f"solution of {fmt_count(sizes.checked)} targets"
    )
    rows = run(sizes, args.seed)
    print_table(rows)
    if args.json:
        args.json.write_text(
            json.dumps(to_json({"machine": info, "sizes": sizes, "rows": rows}), indent=1)
        )
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
