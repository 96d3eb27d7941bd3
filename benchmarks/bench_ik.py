"""The IK benchmark: poekin's numerical ``Chain.ik`` and analytic ``Chain.ik_all`` against
Robotics Toolbox, pytorch_kinematics, Pinocchio and ik-geo, on the same targets, every answer
checked by MuJoCo (issue #21's protocol).

Protocol, per arm of the shared Menagerie (UR5e, UR10e, FR3, Panda ``hand``, Sawyer, Lite6):
configurations uniform within the joint limits (seed 0); the targets are their poses by MuJoCo's
``mj_forward``. Every numerical solver starts from random configurations, never the generating
ones. An answer succeeds at a tolerance when MuJoCo's pose of it (the answer written into
``qpos``) is that close to the target, in metres and radians, and it lies within the joint
limits. Rates are given at 1e-9, at 1e-5 and at 5 mm / 0.05 rad, so the anchors' published
figures compare. A solver of every solution succeeds on a target when one of its solutions does.

Rows (each a prefix of the same targets):

* poekin ``chain.ik(T)``: one batch, all threads and one thread (solves per second, time per
  solve including failures); a loop of single calls (median, p99 and mean per call), and
  one from ``q0`` near the answer (the generating q plus 0.01 rad of noise: a control loop's
  call); targets out of reach (2.5 m from the base: every one must fail; time per failed target);
* poekin ``chain.ik_all(T)``, every closed-form solution, on the arms that have one (the UR
  arms: three parallel axes; the Lite6: a spherical wrist): one batch on all threads and on one,
  the NumPy reference path (an installation without a compiler), a loop of single calls, and
  the targets out of reach (no solution may be valid). MuJoCo checks every valid solution of
  every target: the largest residual (goal 1e-12), solutions per target, and whether the
  configuration a target came from is among them;
* ik-geo (``pip install ik-geo``: Elias and Wen's IK-Geo in Rust), ``Robot.get_ik`` in a loop,
  one pose per call (it has no batch call), on the UR arms, built with
  ``three_parallel_two_intersecting`` from the same axes; its exact solutions checked as
  poekin's;
* Robotics Toolbox ``ETS.ik_LM`` (C++; 100 searches x 30 iterations, limits on), its ETS built
  from poekin's screws (``S_1 .. S_n``, ``M``: the same model, never its built-in robots, whose
  UR5 clones a repository): a loop of single calls;
* pytorch_kinematics ``PseudoInverseIK`` (float64 CPU, 10 retries, 50 iterations), its chain
  from the Menagerie file: one batch;
* Pinocchio's CLIK loop (its documentation's example: damped least squares, ``DT = 0.1``,
  1,000 iterations, 10 restarts; limits by clamping), its model from the Menagerie file: a loop;
* poekin on JAX arrays, ``jax.jit(jax.vmap(chain.ik))`` in float64 (the fixed-shape solve of
  ``poekin.ik.fixed``: lanes that restart attempts within 256 iterations per target), batches
  of 1,000 and 10,000 targets: the first call (trace, compile, run; the first of the process
  also starts JAX's CPU backend) and the median of later calls, with XLA's default options,
  without its fusion emitters (``compiler_options``: less compile time, programs as fast) and
  with its quick compile (no fusion emitters, backend optimisation level 0: less compile time
  still, slower programs); poekin on PyTorch tensors, ``chain.ik(tensor)`` eagerly (float64;
  torch.compile runs the solve eagerly too): one batch of 1,000. On the UR5e and the Panda
  unless ``--arrays-arms`` says otherwise.

The numerical anchors run on the UR5e and the Panda (the issue's table) unless
``--anchor-arms`` says otherwise; solvers that are not installed are skipped
(``pip install -e '.[bench]'``). Ratios: each anchor's mean time per target (the protocol's
figure: restarts and failures included) over poekin's batch time per target (``chain.ik`` for
the numerical anchors, ``chain.ik_all`` for ik-geo), and, for a loop of single calls, its
median call over poekin's median single call. Timings are wall times of one run on a shared machine:
read medians and ratios, never one sample. The CPU and its vector width are printed with every
table.

Pitfalls met on the way: ik-geo's ``get_ik(R, t)`` expects the transpose of the rotation its
documentation describes (as documented, every solution misses by ~0.7 m; this script passes
``R.T``), and wants the points where axes 1 and 2, and 5 and 6, meet as its axis points.

examples:
  python benchmarks/bench_ik.py --quick                      # seconds; what CI runs
  python benchmarks/bench_ik.py --json ik.json
  python benchmarks/bench_ik.py --arms ur5e panda --skip pinocchio
  python benchmarks/bench_ik.py --arms ur5e --skip roboticstoolbox pytorch_kinematics pinocchio
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import pathlib
import sys
import time
import types
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info, package_version  # the FK benchmark's machine description

import poekin
from poekin.ik import analytic
from poekin.ik._angles import within_limits

FloatArray = NDArray[np.float64]

ARMS = {
    "ur5e": ("universal_robots_ur5e", None),
    "ur10e": ("universal_robots_ur10e", None),
    "fr3": ("franka_fr3", None),
    "panda": ("franka_emika_panda", "hand"),
    "sawyer": ("rethink_robotics_sawyer", None),
    "lite6": ("ufactory_lite6", None),
    # a calibrated UR5e (issue 26): the synthetic UR calibration file of tests/data/ur, its
    # axes 0.07 and 0.12 deg from parallel as a real arm's are; MuJoCo checks it through the
    # URDF poekin writes of it, and it gets the nominal UR5e's joint limits
    "ur5e_cal": ("tests/data/ur/ur5e_calibration.yaml", None),
}
CALIBRATED = {"ur5e_cal": "universal_robots_ur5e"}  # each calibrated arm's nominal model
ANCHOR_ARMS = ("ur5e", "panda")
ARRAYS_ARMS = ("ur5e", "panda")  # JAX and PyTorch rows
# XLA's compile options on the CPU (docs/ik.md): without the fusion emitters, less compile time
# and programs as fast; the quick compile, less compile time still and slower programs
NO_FUSION_EMITTERS = {"xla_cpu_use_fusion_emitters": False}
QUICK_COMPILE = {**NO_FUSION_EMITTERS, "xla_backend_optimization_level": 0}
TOLERANCES = {"1e-9": (1e-9, 1e-9), "1e-5": (1e-5, 1e-5), "5mm/0.05rad": (5e-3, 0.05)}
UNREACHABLE_M = 2.5  # every arm here reaches less than 1.5 m


@dataclasses.dataclass(frozen=True)
class Sizes:
    """How much to run; ``--quick`` shrinks everything so that CI runs it in seconds."""

    targets: int = 10_000  # per arm; poekin's batch
    repeats: int = 5  # poekin's batch, timed this many times
    single: int = 1_000  # poekin's loop of single calls
    unreachable: int = 1_000
    rtb: int = 2_000  # Robotics Toolbox's loop
    pytorch_kinematics: int = 1_000  # its batch
    pinocchio: int = 100  # its loop (milliseconds per target)
    analytic_single: int = 2_000  # poekin ik_all's loop of single calls
    analytic_numpy: int = 1_000  # ik_all's NumPy reference path
    ik_geo: int = 2_000  # ik-geo's loop
    arrays: tuple[int, ...] = (1_000, 10_000)  # poekin's JAX batches (PyTorch: the first)


QUICK = Sizes(
    targets=200,
    repeats=2,
    single=50,
    unreachable=20,
    rtb=20,
    pytorch_kinematics=20,
    pinocchio=5,
    analytic_single=50,
    analytic_numpy=50,
    ik_geo=50,
    arrays=(16,),
)
EXACT = 1e-12  # m and rad: ik_all's goal for the MuJoCo residual of every valid solution
SAME_Q = 1e-6  # rad: the configuration a target came from is among its solutions


@dataclasses.dataclass(frozen=True)
class Case:
    """One arm: MuJoCo's model, poekin's chain, the targets and their generating q."""

    arm: str
    loaded: poekin.LoadedModel
    chain: poekin.Chain
    q_true: FloatArray
    T: FloatArray


@dataclasses.dataclass
class Row:
    solver: str
    arm: str
    mode: str  # "batch" or "single calls"
    n: int
    per_solve_us: float  # wall time per target, failures included
    median_us: float | None = None  # single calls only
    p99_us: float | None = None
    success: dict[str, float] = dataclasses.field(default_factory=dict)
    note: str = ""
    # solvers of every solution: solutions per target, the fraction of targets whose
    # generating q is among them, MuJoCo's largest residual over every solution (m, rad)
    checks: dict[str, float] = dataclasses.field(default_factory=dict)

    @property
    def solves_per_s(self) -> float:
        return 1e6 / self.per_solve_us


# --- targets and the MuJoCo check ---------------------------------------------------------------


def _frame(model: mujoco.MjModel, name: str) -> tuple[str, int]:
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if site >= 0:
        return "site", site
    return "body", mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)


def mujoco_poses(loaded: poekin.LoadedModel, chain: poekin.Chain, q: FloatArray) -> FloatArray:
    """``(N, 4, 4)`` poses of the chain's frame by ``mj_forward``, ``q`` written into qpos."""
    model = loaded.model
    data = mujoco.MjData(model)
    kind, fid = _frame(model, chain.frame)
    idx = list(chain.qpos_indices or range(chain.n_joints))
    out = np.tile(np.eye(4), (len(q), 1, 1))
    for k, row in enumerate(q):
        data.qpos[:] = model.qpos0
        data.qpos[idx] = row
        mujoco.mj_forward(model, data)
        xmat, xpos = (data.site_xmat, data.site_xpos) if kind == "site" else (data.xmat, data.xpos)
        out[k, :3, :3] = xmat[fid].reshape(3, 3)
        out[k, :3, 3] = xpos[fid]
    return out


def success_rates(case: Case, q: FloatArray, n: int) -> dict[str, float]:
    """The fraction of the first ``n`` targets that ``q`` reaches by MuJoCo, within the limits,
    at each of :data:`TOLERANCES`."""
    q = np.asarray(q, dtype=np.float64)[:n]
    pos, ori = poekin.pose_errors(case.T[:n], mujoco_poses(case.loaded, case.chain, q))
    inside = within_limits(q, case.chain.limits)
    return {
        name: float(np.mean((pos <= p) & (ori <= o) & inside))
        for name, (p, o) in TOLERANCES.items()
    }


def solution_checks(
    case: Case, solutions: Sequence[FloatArray]
) -> tuple[dict[str, float], dict[str, float]]:
    """For ``solutions[k]``, the ``(m_k, n)`` solutions a solver gives for target ``k``: the
    fraction of targets with a solution that MuJoCo puts within each of :data:`TOLERANCES`
    (within the limits), and :attr:`Row.checks`."""
    n = len(solutions)
    flat = np.concatenate([np.reshape(s, (-1, case.chain.n_joints)) for s in solutions])
    which = np.repeat(np.arange(n), [len(s) for s in solutions])
    pos, ori = poekin.pose_errors(case.T[which], mujoco_poses(case.loaded, case.chain, flat))
    inside = within_limits(flat, case.chain.limits)
    rates = {}
    for name, (p, o) in TOLERANCES.items():
        reached = np.zeros(n, dtype=bool)
        np.logical_or.at(reached, which, (pos <= p) & (ori <= o) & inside)
        rates[name] = float(reached.mean())
    gap = np.abs(np.angle(np.exp(1j * (flat - case.q_true[which])))).max(axis=-1)
    drawn = np.zeros(n, dtype=bool)
    np.logical_or.at(drawn, which, inside & (gap <= SAME_Q))
    checks = {
        "solutions per target": len(flat) / n,
        "generating q found": float(drawn.mean()),
        "max residual m": float(pos.max(initial=0.0)),
        "max residual rad": float(ori.max(initial=0.0)),
    }
    return rates, checks


def _checks_note(checks: dict[str, float]) -> str:
    return (
        f"{checks['solutions per target']:.2f} solutions per target, the generating q among "
        f"them for {100 * checks['generating q found']:.2f}%; MuJoCo's largest residual "
        f"{checks['max residual m']:.1e} m, {checks['max residual rad']:.1e} rad"
    )


def make_case(arm: str, n: int) -> Case:
    if arm in CALIBRATED:
        return _calibrated_case(arm, n)
    robot, frame = ARMS[arm]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model(robot)
    chain = poekin.load(loaded, frame)
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    q = np.random.default_rng(0).uniform(lo, hi, (n, chain.n_joints))
    return Case(arm, loaded, chain, q, mujoco_poses(loaded, chain, q))


def _calibrated_case(arm: str, n: int) -> Case:
    """A calibrated arm from its parameter file, with its nominal model's joint limits, and
    MuJoCo's compile of the URDF poekin writes of it (the independent FK that checks it)."""
    import tempfile

    repo = pathlib.Path(__file__).resolve().parents[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        nominal = poekin.load(CALIBRATED[arm])
    chain = dataclasses.replace(poekin.load_params(repo / ARMS[arm][0]), limits=nominal.limits)
    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / f"{arm}.urdf"
        poekin.export(chain, "urdf", path)
        model = mujoco.MjModel.from_xml_path(str(path))
    loaded: Any = types.SimpleNamespace(model=model)  # what mujoco_poses reads of a model
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    q = np.random.default_rng(0).uniform(lo, hi, (n, chain.n_joints))
    return Case(arm, loaded, chain, q, mujoco_poses(loaded, chain, q))


# --- poekin -----------------------------------------------------------------------------------


@contextlib.contextmanager
def threads(n: int | None) -> Iterator[None]:
    before = poekin.get_threads()
    poekin.set_threads(n)
    try:
        yield
    finally:
        poekin.set_threads(before)


def _loop_times(call: Callable[[Any], object], rows: Sequence[Any]) -> FloatArray:
    """Wall time of each call, in microseconds."""
    out = np.empty(len(rows))
    for k, row in enumerate(rows):
        t0 = time.perf_counter_ns()
        call(row)
        out[k] = (time.perf_counter_ns() - t0) / 1e3
    return out


def _single_row(solver: str, case: Case, times: FloatArray, q: FloatArray, note: str) -> Row:
    return Row(
        solver,
        case.arm,
        "single calls",
        len(times),
        float(times.mean()),
        float(np.median(times)),
        float(np.percentile(times, 99)),
        success_rates(case, q, len(times)),
        note,
    )


def poekin_rows(case: Case, sizes: Sizes) -> list[Row]:
    chain, T = case.chain, case.T
    chain.ik(T[:50])  # builds the solver
    rows = []
    for n_threads, label in ((None, "all threads"), (1, "1 thread")):
        with threads(n_threads):
            samples = []
            for _ in range(sizes.repeats):
                t0 = time.perf_counter()
                found = chain.ik(T)
                samples.append(time.perf_counter() - t0)
        rows.append(
            Row(
                "poekin chain.ik",
                case.arm,
                "batch",
                len(T),
                float(np.median(samples)) / len(T) * 1e6,
                success=success_rates(case, found.q, len(T)),
                note=f"{label} ({poekin.get_threads() if n_threads is None else 1}); "
                f"{found.iterations.mean():.1f} iterations, {found.attempts.mean():.2f} "
                "attempts per target",
            )
        )
    singles: list[FloatArray] = []
    times = _loop_times(lambda t: singles.append(chain.ik(t).q), T[: sizes.single])
    rows.append(_single_row("poekin chain.ik", case, times, np.array(singles), ""))
    # a control loop's call: q0 near the answer (the generating q, 0.01 rad of noise on each
    # joint, brought into the limits)
    n = min(sizes.single, len(T))
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    noise = np.random.default_rng(2).normal(0.0, 0.01, (n, chain.n_joints))
    near = np.clip(case.q_true[:n] + noise, lo, hi)
    singles = []
    times = _loop_times(lambda k: singles.append(chain.ik(T[k], near[k]).q), range(n))
    note = "q0 near the answer: the generating q plus 0.01 rad of noise"
    rows.append(_single_row("poekin chain.ik, q0 near", case, times, np.array(singles), note))
    rows.append(unreachable_row(case, sizes))
    return rows


def out_of_reach(case: Case, sizes: Sizes) -> FloatArray:
    """The first targets moved to :data:`UNREACHABLE_M` from the base, turned as they were."""
    T = case.T[: sizes.unreachable].copy()
    T[:, :3, 3] *= UNREACHABLE_M / np.linalg.norm(T[:, :3, 3], axis=-1, keepdims=True)
    return T


def unreachable_row(case: Case, sizes: Sizes) -> Row:
    """Targets out of reach: every one must fail (success would be false), and the cost of a
    failure is the time to spend every attempt."""
    T = out_of_reach(case, sizes)
    t0 = time.perf_counter()
    found = case.chain.ik(T)
    batch_us = (time.perf_counter() - t0) / len(T) * 1e6
    single = _loop_times(case.chain.ik, T[: max(1, sizes.unreachable // 20)])
    false = int(found.success.sum())
    return Row(
        "poekin chain.ik, out of reach",
        case.arm,
        "batch",
        len(T),
        batch_us,
        float(np.median(single)),
        float(np.percentile(single, 99)),
        {"reported success (must be 0)": float(false)},
        f"{found.attempts.mean():.0f} attempts each; single calls: the median and p99 columns",
    )


def arrays_rows(case: Case, sizes: Sizes) -> list[Row]:
    """poekin's fixed-shape solve on JAX arrays (``jit(vmap(chain.ik))``, each batch size of
    ``sizes.arrays``) and PyTorch tensors (eager, the first size), float64, on the first
    targets. In ``--quick`` runs (CI) JAX compiles with :data:`QUICK_COMPILE` only."""
    chain = case.chain
    rows = []
    if package_version("jax") is not None:
        import jax

        jax.config.update("jax_enable_x64", True)
        quick = sizes.arrays == QUICK.arrays
        for size in sizes.arrays:
            n = min(size, len(case.T))
            settings = [
                ({}, "XLA defaults"),
                (NO_FUSION_EMITTERS, "XLA without fusion emitters"),
                (QUICK_COMPILE, "XLA quick compile"),
            ]
            for options, label in settings:
                if quick and options is not QUICK_COMPILE:
                    continue
                solve = jax.jit(jax.vmap(chain.ik), compiler_options=options)
                targets = jax.device_put(case.T[:n])
                t0 = time.perf_counter()
                found = jax.block_until_ready(solve(targets))
                first = time.perf_counter() - t0
                samples = []
                for _ in range(sizes.repeats):
                    t0 = time.perf_counter()
                    jax.block_until_ready(solve(targets))
                    samples.append(time.perf_counter() - t0)
                rows.append(
                    Row(
                        "poekin jit(vmap(chain.ik)), JAX",
                        case.arm,
                        "batch",
                        n,
                        float(np.median(samples)) / n * 1e6,
                        success=success_rates(case, np.asarray(found.q), n),
                        note=f"{label}; first call (trace, compile, run) {first:.2f} s; "
                        f"jax {jax.__version__} on {jax.devices()[0].platform}, float64",
                    )
                )
    if package_version("torch") is not None:
        import torch

        n = min(sizes.arrays[0], len(case.T))
        tensor = torch.from_numpy(case.T[:n])
        chain.ik(tensor[:2])  # the first call's imports
        samples = []
        for _ in range(max(1, sizes.repeats // 2)):
            t0 = time.perf_counter()
            found_t = chain.ik(tensor)
            samples.append(time.perf_counter() - t0)
        rows.append(
            Row(
                "poekin chain.ik, PyTorch eager",
                case.arm,
                "batch",
                n,
                float(np.median(samples)) / n * 1e6,
                success=success_rates(case, found_t.q.numpy(), n),
                note=f"torch {torch.__version__}, {torch.get_num_threads()} threads, float64",
            )
        )
    return rows


# --- poekin: every solution ---------------------------------------------------------------------


def ik_all_rows(case: Case, sizes: Sizes) -> list[Row]:
    """``chain.ik_all`` on the arms that have a closed form (none for the 7-joint arms)."""
    chain, T = case.chain, case.T
    try:
        split = analytic.nearest_geometry(chain)  # a calibrated arm's: refined
    except poekin.AnalyticIKError:
        return []
    refined = f"nearest {split.description}, refined ({split.nearest})" if split.nearest else ""
    chain.ik_all(T[:50])  # warm
    rows = []
    for n_threads, label in ((None, "all threads"), (1, "1 thread")):
        with threads(n_threads):
            samples = []
            for _ in range(sizes.repeats):
                t0 = time.perf_counter()
                chain.ik_all(T)
                samples.append(time.perf_counter() - t0)
        count = poekin.get_threads() if n_threads is None else 1
        rows.append(
            Row(
                "poekin chain.ik_all",
                case.arm,
                "batch",
                len(T),
                float(np.median(samples)) / len(T) * 1e6,
                note=f"{label} ({count}); {refined or split.description}",
            )
        )
    found = chain.ik_all(T)
    rates, checks = solution_checks(case, [q[v] for q, v in zip(found.q, found.valid, strict=True)])
    rows[0].success, rows[0].checks = rates, checks
    rows[0].note += f"; {_checks_note(checks)}"
    small = T[: sizes.analytic_numpy]
    samples = []
    for _ in range(sizes.repeats if not refined else 0):  # the exact closed form's reference
        t0 = time.perf_counter()
        analytic.solve_numpy(chain, small)
        samples.append(time.perf_counter() - t0)
    if samples:
        rows.append(
            Row(
                "poekin chain.ik_all, NumPy path",
                case.arm,
                "batch",
                len(small),
                float(np.median(samples)) / len(small) * 1e6,
                note="the reference path, as an installation without a C compiler runs it",
            )
        )
    singles: list[FloatArray] = []
    times = _loop_times(lambda t: singles.append(chain.ik_all(t).q), T[: sizes.analytic_single])
    rows.append(
        Row(
            "poekin chain.ik_all",
            case.arm,
            "single calls",
            len(times),
            float(times.mean()),
            float(np.median(times)),
            float(np.percentile(times, 99)),
            note="one (4, 4) target per call",
        )
    )
    far = out_of_reach(case, sizes)
    t0 = time.perf_counter()
    missed = chain.ik_all(far)
    far_us = (time.perf_counter() - t0) / len(far) * 1e6
    false = int(missed.valid.any(axis=-1).sum())
    rows.append(
        Row(
            "poekin chain.ik_all, out of reach",
            case.arm,
            "batch",
            len(far),
            far_us,
            success={"reported success (must be 0)": float(false)},
            note="a target counts as reported reached if any branch is valid",
        )
    )
    return rows


# --- ik-geo -----------------------------------------------------------------------------------


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


def ik_geo_rows(case: Case, sizes: Sizes) -> list[Row]:
    """ik-geo's ``get_ik`` in a loop, on the arms of the UR geometry."""
    try:
        split = analytic.geometry(case.chain)
    except poekin.AnalyticIKError:
        return []
    if split.kind != "three parallel axes":
        return []  # ik-geo has other constructors; only this one is built here
    robot = ik_geo_robot(case.chain)
    R_home = case.chain.home[:3, :3]
    # the rotation ik-geo wants: the target's turn of the base-aligned frame 6, transposed
    n = min(sizes.ik_geo, len(case.T))
    args = [((t[:3, :3] @ R_home.T).T.tolist(), t[:3, 3].tolist()) for t in case.T[:n]]
    answers: list[Any] = []
    times = _loop_times(lambda a: answers.append(robot.get_ik(*a)), args)
    exact = [
        np.array([q for q, least_squares in found if not least_squares], dtype=np.float64)
        for found in answers
    ]
    rates, checks = solution_checks(_prefix(case, n), exact)
    return [
        Row(
            "ik-geo get_ik",
            case.arm,
            "single calls",
            n,
            float(times.mean()),
            float(np.median(times)),
            float(np.percentile(times, 99)),
            rates,
            f"ik-geo {package_version('ik-geo')}, one pose per call; {_checks_note(checks)}",
            checks,
        )
    ]


def _prefix(case: Case, n: int) -> Case:
    return dataclasses.replace(case, q_true=case.q_true[:n], T=case.T[:n])


# --- anchors ----------------------------------------------------------------------------------


def rtb_rows(case: Case, sizes: Sizes) -> list[Row]:
    """Robotics Toolbox ``ik_LM`` on an ETS of poekin's screws: ``G_1 Rz(q_1) G_1^-1 ... M``,
    ``G_i`` turning z onto the axis ``w_i`` through its point ``w_i x v_i``."""
    import roboticstoolbox as rtb

    chain, ET = case.chain, rtb.ET
    ets = rtb.ETS()
    for i, (S, (lo, hi)) in enumerate(zip(chain.screws, chain.limits, strict=True)):
        G = np.eye(4)
        G[:3, :3] = _turn_z_onto(S[:3])
        G[:3, 3] = np.cross(S[:3], S[3:])
        ets *= ET.SE3(G) * ET.Rz(jindex=i, qlim=[lo, hi]) * ET.SE3(poekin.inverse(G))
    ets = (ets * ET.SE3(chain.home)).compile()
    q_check = case.q_true[:20]
    if not np.allclose(np.stack([ets.eval(q) for q in q_check]), chain.fk(q_check), atol=1e-12):
        raise RuntimeError("the Robotics Toolbox ETS does not match poekin's chain")
    n = min(sizes.rtb, len(case.T))
    answers: list[FloatArray] = []

    def solve(T: FloatArray) -> None:
        answers.append(np.asarray(ets.ik_LM(T, ilimit=30, slimit=100, tol=1e-20).q))

    times = _loop_times(solve, case.T[:n])
    note = "C++, 100 searches x 30 iterations, tol 1e-20 (on 0.5 e^T e), limits on"
    return [_single_row("Robotics Toolbox ik_LM", case, times, np.array(answers), note)]


def _turn_z_onto(w: FloatArray) -> FloatArray:
    """A rotation taking the z axis onto unit ``w``."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, w)
    s, c = np.linalg.norm(axis), float(np.dot(z, w))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return poekin.exp_so3(axis / s * np.arctan2(s, c))


def pytorch_kinematics_rows(case: Case, sizes: Sizes) -> list[Row]:
    """``PseudoInverseIK`` on ``build_chain_from_mjcf`` of the Menagerie file, float64."""
    import pytorch_kinematics as pk
    import pytorch_kinematics.mjcf as pk_mjcf
    import torch

    # 0.10 keys its joint-type table by MuJoCo enums; MuJoCo 3.3+ hands it numpy ints.
    pk_mjcf.JOINT_TYPE_MAP = {int(k): v for k, v in pk_mjcf.JOINT_TYPE_MAP.items()}
    tree = pk.build_chain_from_mjcf(kinematic_xml(case.loaded.xml_path))
    serial = pk.SerialChain(tree, case.chain.frame).to(dtype=torch.float64)
    names = serial.get_joint_parameter_names()
    if list(names) != list(case.chain.joint_names):
        raise RuntimeError(f"pytorch_kinematics joints {names} are not poekin's")
    q_check = torch.from_numpy(case.q_true[:50])
    model_err = float(
        np.abs(
            serial.forward_kinematics(q_check).get_matrix().numpy() - case.chain.fk(q_check.numpy())
        ).max()
    )
    limits = torch.tensor(case.chain.limits, dtype=torch.float64)
    solver = pk.PseudoInverseIK(
        serial,
        pos_tolerance=1e-9,
        rot_tolerance=1e-9,
        num_retries=10,
        max_iterations=50,
        joint_limits=limits,
        early_stopping_any_converged=True,
    )
    n = min(sizes.pytorch_kinematics, len(case.T))
    target = pk.Transform3d(matrix=torch.from_numpy(case.T[:n]))
    t0 = time.perf_counter()
    found = solver.solve(target)
    per_us = (time.perf_counter() - t0) / n * 1e6
    err = (found.err_pos + found.err_rot).reshape(n, -1)
    best = torch.argmin(torch.where(found.converged.reshape(n, -1), -1.0, err), dim=1)
    q = found.solutions.reshape(n, -1, case.chain.n_joints)[torch.arange(n), best].numpy()
    return [
        Row(
            "pytorch_kinematics PseudoInverseIK",
            case.arm,
            "batch",
            n,
            per_us,
            success=success_rates(case, q, n),
            note=f"float64 CPU, {torch.get_num_threads()} torch threads, 10 retries x 50 "
            f"iterations, tolerance 1e-9; its model {model_err:.0e} off poekin's (offsets "
            "parsed as float32)",
        )
    ]


def kinematic_xml(path: pathlib.Path) -> str:
    """The MJCF file with its mesh geoms made small spheres and its mesh and texture files
    dropped (MuJoCo's ``MjSpec`` writes it): the same kinematics, without the files that the
    shared Menagerie leaves out, for libraries that compile the XML themselves."""
    spec = mujoco.MjSpec.from_file(str(path))
    for geom in spec.geoms:
        if geom.meshname:
            geom.type, geom.size, geom.meshname = mujoco.mjtGeom.mjGEOM_SPHERE, [0.01, 0, 0], ""
    for asset in [*spec.meshes, *spec.textures]:
        spec.delete(asset)
    spec.compile()
    return str(spec.to_xml())


def pinocchio_rows(case: Case, sizes: Sizes) -> list[Row]:
    """Pinocchio's documented CLIK loop, restarted from random configurations."""
    import pinocchio as pin
    from bench_fk import _pinocchio_root_fix

    pm = pin.buildModelFromMJCF(str(case.loaded.xml_path))
    note = _pinocchio_root_fix(pin, pm, case.loaded.model)
    data, frame = pm.createData(), pm.getFrameId(case.chain.frame)
    idx_q = [pm.idx_qs[pm.getJointId(name)] for name in case.chain.joint_names]
    lo, hi = case.chain.limits[:, 0], case.chain.limits[:, 1]
    rng = np.random.default_rng(1)
    eps, it_max, dt, damp, restarts = 1e-10, 1_000, 1e-1, 1e-12, 10

    def solve(T: FloatArray) -> FloatArray:
        target = pin.SE3(T)
        best, best_err = pin.neutral(pm), np.inf
        for _ in range(restarts):
            q = pin.neutral(pm)
            q[idx_q] = rng.uniform(lo, hi)
            for _ in range(it_max):
                pin.forwardKinematics(pm, data, q)
                pin.updateFramePlacement(pm, data, frame)
                err = pin.log(target.actInv(data.oMf[frame])).vector
                norm = float(np.linalg.norm(err))
                if norm < best_err:
                    best, best_err = q.copy(), norm
                if norm < eps:
                    return q[idx_q]
                J = pin.computeFrameJacobian(pm, data, q, frame)
                v = -J.T.dot(np.linalg.solve(J.dot(J.T) + damp * np.eye(6), err))
                q = pin.integrate(pm, q, v * dt)
                q[idx_q] = np.clip(q[idx_q], lo, hi)
        return best[idx_q]

    n = min(sizes.pinocchio, len(case.T))
    answers: list[FloatArray] = []
    times = _loop_times(lambda T: answers.append(solve(T)), case.T[:n])
    note = f"DT 0.1, <= 1000 iterations x 10 restarts, eps 1e-10, clamped to the limits {note}"
    return [_single_row("Pinocchio CLIK loop", case, times, np.array(answers), note.strip())]


Solver = tuple[str, Callable[[Case, Sizes], list[Row]]]  # (distribution, rows)
# the numerical anchors, on --anchor-arms
ANCHORS: dict[str, Solver] = {
    "roboticstoolbox": ("roboticstoolbox-python", rtb_rows),
    "pytorch_kinematics": ("pytorch-kinematics", pytorch_kinematics_rows),
    "pinocchio": ("pin", pinocchio_rows),
}
# every solver, by name; the analytic ones run on every arm with a closed form
SOLVERS: dict[str, Solver] = {
    "poekin": ("numpy", poekin_rows),
    "ik_all": ("numpy", ik_all_rows),
    "ik-geo": ("ik-geo", ik_geo_rows),
    "poekin_arrays": ("array-api-compat", arrays_rows),
    **ANCHORS,
}


# --- output -----------------------------------------------------------------------------------


def table(rows: Sequence[Row]) -> str:
    head = f"{'solver':38} {'arm':7} {'mode':13} {'n':>6} {'us/solve':>9} {'solves/s':>10} "
    head += f"{'median':>8} {'p99':>8}  success 1e-9 / 1e-5 / 5mm"
    lines = [head, "-" * len(head)]
    for r in rows:
        med = f"{r.median_us:8.1f}" if r.median_us is not None else f"{'':8}"
        p99 = f"{r.p99_us:8.1f}" if r.p99_us is not None else f"{'':8}"
        rates = " / ".join(f"{100 * v:.2f}%" for v in r.success.values())
        if "reported success (must be 0)" in r.success:
            rates = f"{int(r.success['reported success (must be 0)'])} false successes"
        lines.append(
            f"{r.solver:38} {r.arm:7} {r.mode:13} {r.n:6d} {r.per_solve_us:9.2f} "
            f"{r.solves_per_s:10.0f} {med} {p99}  {rates}"
        )
        if r.note:
            lines.append(f"{'':38}   {r.note}")
    return "\n".join(lines)


# each anchor's poekin counterpart: the numerical solver's, or ik_all's for ik-geo
COUNTERPART = {"ik-geo get_ik": "poekin chain.ik_all"}


def ratios(rows: Sequence[Row]) -> dict[str, float]:
    """Each anchor's time per target over poekin's on the same arm: its mean (restarts and
    failures included) over poekin's batch on all threads, and, for an anchor's single calls,
    its median call over poekin's median single call (a median shrugs off a shared machine's
    stray slow call; a mean keeps the restarts' cost)."""
    out = {}
    for r in rows:
        if r.solver.startswith("poekin"):
            continue
        ours = COUNTERPART.get(r.solver, "poekin chain.ik")
        same = [x for x in rows if x.solver == ours and x.arm == r.arm]
        batch = next((x for x in same if x.mode == "batch"), None)
        if batch is not None:
            out[f"{r.solver} ({r.arm}) / {ours} batch"] = r.per_solve_us / batch.per_solve_us
        single = next((x for x in same if x.mode == "single calls"), None)
        if r.mode == "single calls" and single is not None:
            assert r.median_us is not None and single.median_us is not None
            out[f"{r.solver} ({r.arm}) / {ours} single calls, medians"] = (
                r.median_us / single.median_us
            )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0] if __doc__ else None,
        epilog=__doc__[__doc__.index("examples:") :] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--quick", action="store_true", help="tiny sizes (CI)")
    parser.add_argument("--arms", nargs="+", choices=list(ARMS), default=list(ARMS))
    parser.add_argument("--anchor-arms", nargs="+", choices=list(ARMS), default=list(ANCHOR_ARMS))
    parser.add_argument("--arrays-arms", nargs="+", choices=list(ARMS), default=list(ARRAYS_ARMS))
    parser.add_argument("--skip", nargs="+", choices=list(SOLVERS)[1:], default=[])
    parser.add_argument("--json", type=pathlib.Path, help="write the rows and machine here")
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else Sizes()
    info = machine_info()
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} usable cores; "
        f"{poekin.kernel._fast.kernel_description()}",
        flush=True,
    )
    rows: list[Row] = []
    skipped: list[str] = []
    for arm in args.arms:
        case = make_case(arm, sizes.targets)
        for name, (dist, solver) in SOLVERS.items():
            if name in args.skip or (name in ANCHORS and arm not in args.anchor_arms):
                continue
            if name == "poekin_arrays" and arm not in args.arrays_arms:
                continue
            if package_version(dist) is None:
                skipped.append(f"{name} (not installed)")
                continue
            added = solver(case, sizes)
            rows.extend(added)
            print("\n".join(table(added).splitlines()[2:]), flush=True)
    print()
    print(table(rows))
    rel = ratios(rows)
    for name, x in rel.items():
        print(f"{name}: {x:.1f}x the time per target")
    if skipped:
        print("skipped:", ", ".join(sorted(set(skipped))))
    if args.json:
        out = {
            "machine": info,
            "sizes": dataclasses.asdict(sizes),
            "tolerances": TOLERANCES,
            "rows": [dataclasses.asdict(r) | {"solves_per_s": r.solves_per_s} for r in rows],
            "ratios": rel,
            "skipped": sorted(set(skipped)),
        }
        args.json.write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
