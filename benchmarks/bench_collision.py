"""The collision benchmark (issue #29): self-collision checks, batched, against a MuJoCo loop.

For a batch of random configurations (uniform within the joint ranges), the time per
configuration of

* poekin: ``tree.in_collision(qpos)`` (one batched call on the kernel's threads, and on one
  thread; the kernel skips pairs whose bounds lie clear and stops at a configuration's first
  hit; mesh pairs go to MuJoCo's ``mj_geomDistance``), and ``tree.distances(qpos)`` (every
  pair's distance and witness points);
* MuJoCo: a Python loop of ``mj_kinematics`` + ``mj_collision`` per configuration on the same
  model (the issue's reference), which finds the contacts only.

Robots: the UR5e (capsules and a cylinder; poekin's built-in copy serves, no mesh files), and
the G1 (example-robot-data's ``g1_29dof_rev_1_0`` URDF with its STL collision meshes, as
MuJoCo compiles it: Menagerie's G1 here has no mesh files). The issue's goal: the UR5e >= 10x
MuJoCo's loop. Each row also gives the share of configurations that collide with themselves,
by poekin and by MuJoCo (they must agree).

Timings are medians of repeats (wall time on a possibly shared machine: read medians and
ratios); the CPU, its vector width and the load average are printed with the table.

Collision-free IK (``bench_ik_avoid``): the UR5e above a table (its top 1 cm under the base),
targets from configurations that keep 5 mm from the table and from the robot itself; the share
``chain.ik(T, avoid=True, obstacles=[table])`` solves, the successful answers MuJoCo's
``mj_collision`` finds within the margin (the issue: 0), and the median time per solve against
the plain ``chain.ik(T)`` (the issue: within 3x; the two solves taken in turn, ``IK_REPEATS``
times), on the issue's 1,000 targets and on 10,000 (where the Python around each call weighs
less per target).

examples:
  python benchmarks/bench_collision.py --quick      # seconds: a check that it runs
  python benchmarks/bench_collision.py              # the full run, 10,000 configurations
"""

from __future__ import annotations

import argparse
import pathlib
import statistics
import sys
import sysconfig
import time
import warnings
from collections.abc import Callable, Sequence

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info, package_version  # the FK benchmark's machine description

import poekin

GOAL = 10.0  # the issue: UR5e self-collision >= 10x MuJoCo's loop
IK_REPEATS = 15  # plain and collision-free solves of the targets, taken in turn


def _median_s(run: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _ur5e() -> tuple[str, poekin.Tree, mujoco.MjModel]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model("universal_robots_ur5e")
    return "UR5e (capsules)", poekin.load_tree(loaded), loaded.model


def _g1() -> tuple[str, poekin.Tree, mujoco.MjModel] | None:
    share = pathlib.Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share"
    path = (
        share
        / "example-robot-data"
        / "robots"
        / "g1_description"
        / "urdf"
        / "g1_29dof_rev_1_0.urdf"
    )
    if not path.is_file():
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tree = poekin.load_tree(path, floating_base=True)
    spec = mujoco.MjSpec.from_file(str(path))
    for mesh in spec.meshes:
        mesh.file = mesh.file.replace(
            "package://example-robot-data", str(share / "example-robot-data")
        )
    spec.compiler.fusestatic = False
    spec.worldbody.bodies[0].add_freejoint()
    for compiler in {id(b.compiler): b.compiler for b in spec.bodies}.values():
        compiler.boundmass, compiler.boundinertia = 1e-6, 1e-12
    return "G1 URDF (STL meshes)", tree, spec.compile()


def _mujoco_loop(model: mujoco.MjModel, full: np.ndarray) -> np.ndarray:
    """Whether each configuration collides, by mj_kinematics + mj_collision in a loop."""
    data = mujoco.MjData(model)
    out = np.zeros(len(full), dtype=bool)
    for c, row in enumerate(full):
        data.qpos[:] = row
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        out[c] = bool(np.any(data.contact.dist < 0))  # the contacts' distances as one array
    return out


def _row(label: str, tree: poekin.Tree, model: mujoco.MjModel, n: int, repeats: int) -> str:
    qpos = poekin.sample_qpos(tree, n, seed=0, within_limits=True)
    full = tree.full_qpos(qpos)
    tree.in_collision(qpos[:2])  # the collision model is built once, outside the timing
    ours = tree.in_collision(qpos)
    theirs = _mujoco_loop(model, full)
    t_ours = _median_s(lambda: tree.in_collision(qpos), repeats) / n
    threads = poekin.get_threads()
    poekin.set_threads(1)
    try:
        t_one = _median_s(lambda: tree.in_collision(qpos), repeats) / n
    finally:
        poekin.set_threads(threads)
    t_dist = _median_s(lambda: tree.distances(qpos), repeats) / n
    t_mj = _median_s(lambda: _mujoco_loop(model, full), repeats) / n
    agree = "agree" if np.array_equal(ours, theirs) else f"DIFFER ({np.sum(ours != theirs)})"
    note = f"{100 * ours.mean():.1f}% collide (MuJoCo {100 * theirs.mean():.1f}%: {agree})"
    return (
        f"| {label}, {n} configurations | {1e6 * t_ours:.3g} us ({1e6 * t_one:.3g} us) | "
        f"{1e6 * t_dist:.3g} us | {1e6 * t_mj:.3g} us | {t_mj / t_ours:.3g}x "
        f"({t_mj / t_one:.3g}x) | {note} |"
    )


def bench(n: int, repeats: int) -> list[str]:
    rows = [_row(*_ur5e(), n, repeats)]
    g1 = _g1()
    if g1 is None:
        rows.append("| G1 | — | — | — | — | example-robot-data is not installed |")
    else:
        rows.append(_row(*g1, n, repeats))
    return rows


AVOID_SHARE = 0.995  # the issue: >= 99.5% of the targets solved collision-free
AVOID_SLOWDOWN = 3.0  # ... within 3x the plain solve


def _mj_table(margin: float) -> tuple[mujoco.MjModel, mujoco.MjData, object]:
    """The UR5e's kinematics compile with the table as a geom of the world, every geom's
    margin ``margin``: ``mj_collision`` then reports each pair closer than it."""
    from poekin.collision import Box

    table = Box([0.8, 0.8, 0.02], pose=[0.0, 0.0, -0.03, 1.0, 0.0, 0.0, 0.0], name="table")
    spec = poekin.io.sources.kinematics_spec("universal_robots_ur5e")
    body = spec.worldbody.add_body(pos=table.pose[:3, 3])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=table.half_sizes, contype=1, conaffinity=1)
    model = spec.compile()
    model.geom_margin[:] = margin
    return model, mujoco.MjData(model), table


def bench_ik_avoid(n: int) -> list[str]:
    """The collision-free IK rows (the module's docstring)."""
    margin = 0.005
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        chain = poekin.load("universal_robots_ur5e")
    tree = chain._tree
    model, data, table = _mj_table(margin * (1 - 1e-6))
    rng = np.random.default_rng(0)
    q: list[np.ndarray] = []
    while len(q) < n:
        draw = rng.uniform(chain.limits[:, 0], chain.limits[:, 1], (500, 6))
        q.extend(draw[~tree.in_collision(draw, [table], margin=margin)])
    T = chain.fk(np.array(q[:n]))
    chain.ik(T[:2], avoid=True, obstacles=[table])  # the collision model built, untimed
    plain = chain.ik(T)
    found = chain.ik(T, avoid=True, obstacles=[table], margin=margin)
    plain_times, avoid_times = [], []
    for _ in range(IK_REPEATS):  # interleaved: a slow moment of the machine slows both alike
        start = time.perf_counter()
        chain.ik(T)
        plain_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        chain.ik(T, avoid=True, obstacles=[table], margin=margin)
        avoid_times.append(time.perf_counter() - start)
    t_plain = statistics.median(plain_times) / n
    t_avoid = statistics.median(avoid_times) / n
    hits = 0
    for row in found.q[found.success]:
        data.qpos[:6] = row
        mujoco.mj_kinematics(model, data)
        mujoco.mj_collision(model, data)
        # the contacts mj_collision reports (every geom's margin is the IK's) that are
        # closer than it (its cylinder's may come a little farther out)
        hits += int(any(c.dist < margin * (1 - 1e-6) for c in data.contact))
    plain_hits = int(tree.in_collision(plain.q, [table], margin=margin).sum())
    return [
        f"| UR5e above a table, {n} targets | {100 * found.success.mean():.1f}% "
        f"(goal {100 * AVOID_SHARE:g}%) | {hits} (goal 0) | {1e6 * t_plain:.3g} us | "
        f"{1e6 * t_avoid:.3g} us | {t_avoid / t_plain:.3g}x (goal {AVOID_SLOWDOWN:g}x) | "
        f"{plain_hits} plain answers collide |"
    ]


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
    n, repeats = (200, 1) if args.quick else (10_000, 3)
    info = machine_info()
    loadavg = ", ".join(f"{x:.2f}" for x in info["load_average"] or ())
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} usable cores (load "
        f"average {loadavg}); poekin {package_version('poekin')}, mujoco "
        f"{package_version('mujoco')}, numpy {np.__version__}; git {info['git']}",
        flush=True,
    )
    print()
    print(
        "| robot | poekin in_collision / config (1 thread) | poekin distances / config | "
        "MuJoCo mj_kinematics + mj_collision / config | MuJoCo / poekin in_collision "
        "(1 thread) | self-collision |"
    )
    print("|---|---|---|---|---|---|")
    for row in bench(n, repeats):
        print(row)
    print(f"\nthe issue's goal: UR5e >= {GOAL:g}x MuJoCo's loop")
    print()
    print(
        "| collision-free IK | solved clear | successes MuJoCo finds within 5 mm | plain ik / "
        "solve | avoid=True / solve | slowdown | note |"
    )
    print("|---|---|---|---|---|---|---|")
    for n in (50,) if args.quick else (1000, 10_000):  # 10,000: Python's cost per call spread
        for row in bench_ik_avoid(n):
            print(row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
