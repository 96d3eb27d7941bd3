"""The FK benchmark: poekin against MuJoCo and, when installed, other kinematics libraries.

One run times, on the same random configurations (uniform in [-2 pi, 2 pi]^6, fixed seed):

* the UR5e (Menagerie ``universal_robots_ur5e``, end frame ``attachment_site``): poekin
  ``chain.fk`` (single call, batches of 1e5 and 1e6), a MuJoCo ``mj_kinematics`` loop and, if
  installed (``pip install -e '.[bench]'``), Pinocchio, Robotics Toolbox, pytorch_kinematics
  and the Modern Robotics library, each built from the same model and first checked to give
  the same pose as poekin on a few hundred configurations;
* whole trees (``unitree_go2``: free base + 12 hinges; ``aloha``: two arms), poekin
  ``tree.fk`` (every body and site) against an ``mj_kinematics`` loop;
* the wall time of ``poekin verify --samples 1000`` and of ``python -c "import poekin"``, as
  fresh processes.

Single call: a Python loop calling the library on distinct configurations, per call. Batch:
one vectorised call per configuration (libraries without one: a Python loop over a subset).
Every figure is the median over repeats with its spread (interquartile range, and min-max in
the JSON); ratios are against poekin (x3.0: three times poekin's time). The machines here are
shared and noisy: read medians and ratios, never one sample. No timing is asserted anywhere.

examples:
  python benchmarks/bench_fk.py --quick                      # seconds; what CI runs
  python benchmarks/bench_fk.py --json fk.json --plot fk.png
  python benchmarks/bench_fk.py --save                       # to benchmarks/results/
  python benchmarks/bench_fk.py --repeats 15 --skip pytorch_kinematics
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import gc
import importlib.metadata
import inspect
import json
import os
import pathlib
import platform
import shutil
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

import poekin

FloatArray = NDArray[np.float64]
Call = Callable[[Any], object]

ROBOT = "universal_robots_ur5e"
SITE = "attachment_site"
TREES = ("unitree_go2", "aloha")
RESULTS = pathlib.Path(__file__).resolve().parent / "results"
BENCH_PACKAGES = ("pin", "roboticstoolbox-python", "pytorch-kinematics", "torch", "modern-robotics")
AGREE_TOL = 1e-6  # m and rad: a competitor within this computes the same FK as poekin


@dataclasses.dataclass(frozen=True)
class Sizes:
    """How much to time; ``--quick`` shrinks everything so CI runs it in seconds."""

    n: int = 1_000_000  # configurations drawn (every other size is a prefix of them)
    batches: tuple[int, ...] = (100_000, 1_000_000)  # poekin chain.fk batches
    vector_batch: int = 100_000  # competitors' vectorised batch APIs
    loop: int = 10_000  # libraries without one: a Python loop over this many
    single: int = 2_000  # distinct configurations per single-call repeat
    tree_batches: tuple[int, ...] = (10_000, 100_000)  # tree.fk (1e5: ~0.2 GB of poses)
    repeats: int = 7
    budget_s: float = 1.0  # a loop is cut to about this many seconds per repeat
    check: int = 300  # configurations for the agreement check
    verify_samples: int = 1000
    cmd_repeats: int = 5


QUICK = Sizes(
    n=2_000,
    batches=(200, 2_000),
    vector_batch=2_000,
    loop=200,
    single=200,
    tree_batches=(100, 1_000),
    repeats=3,
    budget_s=0.1,
    check=50,
    cmd_repeats=2,
)


# --- timing ---------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Timing:
    """Nanoseconds per configuration over repeats, each repeat covering ``size`` of them."""

    median_ns: float
    q1_ns: float
    q3_ns: float
    min_ns: float
    max_ns: float
    repeats: int
    size: int

    @classmethod
    def of(cls, samples_ns: Sequence[float], size: int) -> Timing:
        q1, q2, q3 = np.percentile(samples_ns, [25, 50, 75])
        lo, hi = min(samples_ns), max(samples_ns)
        return cls(float(q2), float(q1), float(q3), float(lo), float(hi), len(samples_ns), size)

    @property
    def iqr_ns(self) -> float:
        return self.q3_ns - self.q1_ns


def _wall_ns(fn: Callable[[], object]) -> int:
    """One call's wall time with the garbage collector off, as ``timeit`` does."""
    gc.disable()
    try:
        t0 = time.perf_counter_ns()
        fn()
        return time.perf_counter_ns() - t0
    finally:
        gc.enable()


def time_batch(call: Call, batch: Any, size: int, repeats: int) -> Timing:
    """``call(batch)`` (one call on ``size`` configurations), after one warm-up call."""
    call(batch)
    return Timing.of([_wall_ns(lambda: call(batch)) / size for _ in range(repeats)], size)


def _loop(call: Call, rows: Sequence[Any]) -> None:
    for row in rows:
        call(row)


def fit_rows(call: Call, rows: Sequence[Any], budget_s: float) -> Sequence[Any]:
    """The prefix of ``rows`` that a loop of ``call`` gets through in about ``budget_s``."""
    probe = rows[: min(len(rows), 20)]
    _loop(call, probe)  # warm up
    per_ns = max(_wall_ns(lambda: _loop(call, probe)) / len(probe), 1.0)
    return rows[: int(np.clip(budget_s * 1e9 / per_ns, len(probe), len(rows)))]


def time_loop(call: Call, rows: Sequence[Any], repeats: int, budget_s: float) -> Timing:
    """A Python loop of ``call`` over distinct ``rows`` (cut to the budget), per call."""
    rows = fit_rows(call, rows, budget_s)
    return Timing.of(
        [_wall_ns(lambda: _loop(call, rows)) / len(rows) for _ in range(repeats)], len(rows)
    )


def time_command(argv: Sequence[str], repeats: int) -> Timing:
    """Wall time of a fresh process (``size`` 1: the figures are ns per run).

    Python's bytecode cache is on, as for anyone who has run poekin once (an environment with
    ``PYTHONDONTWRITEBYTECODE`` set would recompile every module at every start); one untimed
    run first writes it.
    """
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    samples = []
    for k in range(repeats + 1):
        t0 = time.perf_counter_ns()
        done = subprocess.run(argv, capture_output=True, text=True, check=False, env=env)
        if k > 0:
            samples.append(time.perf_counter_ns() - t0)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(argv)} exited {done.returncode}: {done.stderr[-300:]}")
    return Timing.of(samples, 1)


# --- the rows of the table ------------------------------------------------------------------


@dataclasses.dataclass
class Row:
    """One line of the table: a library or a way of calling poekin."""

    name: str
    single: Timing | None = None
    batch: Timing | None = None
    method: str = ""  # "vectorised" or "loop"
    max_pos_m: float | None = None  # agreement with poekin
    max_ori_rad: float | None = None
    single_ratio: float | None = None  # median / poekin's
    batch_ratio: float | None = None  # per configuration / poekin's batch nearest in size
    note: str = ""

    def agree(self, T: FloatArray, T_ref: FloatArray) -> None:
        """Record the largest position and orientation difference between two pose stacks."""
        pos, ori = poekin.pose_errors(T_ref, T)
        self.max_pos_m, self.max_ori_rad = float(pos.max()), float(ori.max())
        if max(self.max_pos_m, self.max_ori_rad) > AGREE_TOL:
            self.note = f"DISAGREES with poekin (tolerance {AGREE_TOL:g}); {self.note}".strip()


def add_ratios(rows: list[Row], reference: str) -> None:
    """Each row's medians over those of the row(s) named ``reference`` (poekin's plain call).

    A batch is compared with the reference batch nearest in size (log scale).
    """
    refs = [r for r in rows if r.name == reference]
    single = next((r.single for r in refs if r.single), None)
    batches = [r.batch for r in refs if r.batch]
    for r in rows:
        if r.single and single:
            r.single_ratio = r.single.median_ns / single.median_ns
        if r.batch and batches:
            size = r.batch.size
            ref = min(batches, key=lambda t: abs(np.log(t.size / size)))
            r.batch_ratio = r.batch.median_ns / ref.median_ns


@dataclasses.dataclass(frozen=True)
class Case:
    """One way of calling poekin's FK (plain, ``out=``, ``form=``, threads): one row."""

    label: str
    make: Callable[[tuple[int, ...]], Call]  # batch shape -> the function to time
    single: bool = True  # also timed as single calls
    setting: Callable[[], contextlib.AbstractContextManager[None]] = contextlib.nullcontext
    first_batch_only: bool = False  # a slow case: the smallest batch is enough


def _optional(name: str) -> Any:
    """``poekin.<name>`` if this poekin has it (the script runs before and after it came)."""
    return getattr(poekin, name, None)


@contextlib.contextmanager
def _poekin_threads(n: int) -> Iterator[None]:
    old = _optional("get_threads")()
    _optional("set_threads")(n)
    try:
        yield
    finally:
        _optional("set_threads")(old)


def _same(fn: Callable[..., object], **kwargs: Any) -> Callable[[tuple[int, ...]], Call]:
    """A case's ``make`` that needs no batch shape: ``fn`` with ``kwargs`` (``fn`` itself
    without, so the plain call is timed as a user makes it, not through a wrapper)."""
    return lambda shape: partial(fn, **kwargs) if kwargs else fn


def poekin_cases(
    fk: Callable[..., FloatArray],
    frames: tuple[int, ...],
    reference: Callable[[FloatArray], FloatArray] | None = None,
) -> list[Case]:
    """The plain call, plus ``out=``, ``form=`` and one-thread rows where this poekin has them,
    and the pure-NumPy ``reference`` path (what an install without a C compiler runs).

    ``frames`` is the result's shape between the batch and the pose: ``()`` for a chain,
    ``(n_frames,)`` for a tree. A new variant is one more ``Case`` here.
    """
    cases = [Case("", _same(fk))]
    params = inspect.signature(fk).parameters
    if "out" in params:  # a preallocated result, reused by every call
        cases.append(Case("out=", lambda s: partial(fk, out=np.empty((*s, *frames, 4, 4)))))
    if "form" in params:
        cases += [Case(f"form={form}", _same(fk, form=form)) for form in ("3x4", "pos_quat")]
    if _optional("set_threads") and _optional("get_threads"):
        threads = partial(_poekin_threads, 1)
        cases.append(Case("1 thread", _same(fk), single=False, setting=threads))
    if reference is not None:
        cases.append(Case("NumPy path (no compiler)", _same(reference), first_batch_only=True))
    return cases


def time_cases(
    name: str, cases: list[Case], q: FloatArray, batches: Sequence[int], sizes: Sizes
) -> list[Row]:
    """One row per case and batch size; the single-call figure on each case's first row."""
    rows = []
    for case in cases:
        label = f"{name}, {case.label}" if case.label else name
        with case.setting():
            single = (
                time_loop(case.make(()), list(q[: sizes.single]), sizes.repeats, sizes.budget_s)
                if case.single
                else None
            )
            for k, n in enumerate(batches[:1] if case.first_batch_only else batches):
                batch = time_batch(case.make((n,)), q[:n], n, sizes.repeats)
                rows.append(Row(label, single if k == 0 else None, batch, "vectorised"))
    return rows


# --- the libraries --------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Model:
    """The UR5e, loaded once: MuJoCo's compile of it and poekin's chain from that compile."""

    loaded: poekin.LoadedModel
    chain: poekin.Chain


@dataclasses.dataclass
class Library:
    """A competitor, built from the same model as poekin's chain.

    ``single`` takes one configuration as made by ``rows`` and returns the pose in the
    library's own form; ``batch`` (vectorised libraries only) takes ``batch_input(q)``;
    ``poses`` gives ``(n, 4, 4)`` world poses of the end frame, for the agreement check.
    """

    name: str
    package: str
    single: Call
    poses: Callable[[FloatArray], FloatArray]
    rows: Callable[[FloatArray], Sequence[Any]] = list
    batch: Call | None = None
    batch_input: Callable[[FloatArray], Any] = lambda q: q
    note: str = ""


def _pose(pos: FloatArray, quat: FloatArray) -> FloatArray:
    """``4x4`` pose from MuJoCo's ``pos`` and ``quat`` (wxyz)."""
    T = np.eye(4)
    T[:3, :3] = poekin.quat_to_rotation(quat)
    T[:3, 3] = pos
    return T


def _path_to_site(m: mujoco.MjModel, site: str) -> list[int]:
    """Body ids from the world's child down to ``site``'s body."""
    body, path = int(m.site(site).bodyid[0]), []
    while body != 0:
        path.append(body)
        body = int(m.body_parentid[body])
    return path[::-1]


def mujoco_library(model: Model) -> Library:
    m, chain = model.loaded.model, model.chain
    data, site = mujoco.MjData(m), m.site(SITE).id
    idx = list(chain.qpos_indices or range(chain.n_joints))
    target = slice(None) if idx == list(range(m.nq)) else idx  # a slice copies fastest

    def single(q: FloatArray) -> None:
        data.qpos[target] = q
        mujoco.mj_kinematics(m, data)

    def poses(q: FloatArray) -> FloatArray:
        T = np.tile(np.eye(4), (len(q), 1, 1))
        for k, row in enumerate(q):
            single(row)
            T[k, :3, :3] = data.site_xmat[site].reshape(3, 3)
            T[k, :3, 3] = data.site_xpos[site]
        return T

    return Library("mujoco mj_kinematics", "mujoco", single, poses)


def _pinocchio_root_fix(pin: Any, pm: Any, m: mujoco.MjModel) -> str:
    """Re-apply a jointless root body's pose if this Pinocchio's MJCF reader dropped it.

    Pinocchio up to 4.1 ignores ``pos``/``quat`` of the first body in ``<worldbody>`` when it
    has no joint (stack-of-tasks/pinocchio#2782; the UR5e's ``base`` is turned 180 degrees).
    The pose is MuJoCo's compile of the same file, not a typed number.
    """
    root = 1
    if m.nbody < 2 or m.body_jntnum[root] > 0:
        return ""
    X = pin.SE3(_pose(m.body_pos[root], m.body_quat[root]))
    frame = pm.frames[pm.getFrameId(m.body(root).name, pin.FrameType.BODY)]
    if frame.placement.isApprox(X):
        return ""
    for j in range(1, pm.njoints):
        if pm.parents[j] == 0:
            pm.jointPlacements[j] = X * pm.jointPlacements[j]
    for f in pm.frames:
        if f.parentJoint == 0 and f.name != "universe":
            f.placement = X * f.placement
    return "root body pose re-applied (pinocchio#2782)"


def pinocchio_library(model: Model) -> Library:
    import pinocchio as pin

    pm = pin.buildModelFromMJCF(str(model.loaded.xml_path))
    note = _pinocchio_root_fix(pin, pm, model.loaded.model)
    data, frame = pm.createData(), pm.getFrameId(SITE)

    def single(q: FloatArray) -> Any:
        pin.forwardKinematics(pm, data, q)
        return pin.updateFramePlacement(pm, data, frame)

    def poses(q: FloatArray) -> FloatArray:
        return np.stack([single(row).homogeneous for row in q])

    return Library("pinocchio", "pin", single, poses, note=note)


def _rtb_joint(et: Any, pos: FloatArray, axis: FloatArray, jindex: int) -> Any:
    """MuJoCo's hinge (``axis`` through ``pos``, in the body frame) as RTB elementary terms."""
    k = int(np.argmax(np.abs(axis)))
    if not np.allclose(np.abs(axis), np.eye(3)[k]):
        raise ValueError("only axis-aligned hinges are converted")
    rot = (et.Rx, et.Ry, et.Rz)[k](jindex=jindex, flip=bool(axis[k] < 0))
    if not np.any(pos):
        return rot
    unit = np.array([1.0, 0.0, 0.0, 0.0])
    return et.SE3(_pose(pos, unit)) * rot * et.SE3(_pose(-pos, unit))


def rtb_library(model: Model) -> Library:
    """An ETS from MuJoCo's compiled body offsets (body pos/quat, joint pos/axis, site)."""
    import roboticstoolbox as rtb

    m, ET = model.loaded.model, rtb.ET
    ets = rtb.ETS()  # type: ignore[operator]  # a class; mypy sees the module of that name
    for b in _path_to_site(m, SITE):
        ets *= ET.SE3(_pose(m.body_pos[b], m.body_quat[b]))
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
                raise ValueError("only hinges are converted")
            ets *= _rtb_joint(ET, m.jnt_pos[j], m.jnt_axis[j], int(m.jnt_qposadr[j]))
    site = m.site(SITE).id
    ets = (ets * ET.SE3(_pose(m.site_pos[site], m.site_quat[site]))).compile()
    return Library(
        "robotics toolbox ETS.eval", "roboticstoolbox-python", ets.eval, ets.eval, batch=ets.eval
    )


def pytorch_kinematics_library(model: Model) -> Library:
    """``build_chain_from_mjcf`` on the Menagerie file (its meshes as assets), float64 CPU."""
    import pytorch_kinematics as pk
    import pytorch_kinematics.mjcf as pk_mjcf
    import torch

    # 0.10 keys its joint-type table by MuJoCo enums; MuJoCo 3.3+/4 hands it numpy ints.
    pk_mjcf.JOINT_TYPE_MAP = {int(k): v for k, v in pk_mjcf.JOINT_TYPE_MAP.items()}
    xml = model.loaded.xml_path
    assets = {
        str(p.relative_to(xml.parent)): p.read_bytes()
        for p in model.loaded.files
        if p != xml.resolve() and p.is_relative_to(xml.parent)
    }
    tree = pk.build_chain_from_mjcf(xml.read_text(), assets=assets)
    chain = pk.SerialChain(tree, SITE).to(dtype=torch.float64)

    def single(q: Any) -> Any:
        return chain.forward_kinematics(q)

    def poses(q: FloatArray) -> FloatArray:
        return np.asarray(chain.forward_kinematics(torch.from_numpy(q)).get_matrix().numpy())

    return Library(
        "pytorch_kinematics",
        "pytorch-kinematics",
        single,
        poses,
        rows=lambda q: list(torch.from_numpy(q)),
        batch=single,
        batch_input=torch.from_numpy,
        note=f"float64 CPU, {torch.get_num_threads()} torch threads; offsets parsed as float32",
    )


def modern_robotics_library(model: Model) -> Library:
    """``FKinSpace(M, Slist, q)`` with poekin's home pose and screws (same [w; v] order)."""
    import modern_robotics as mr

    M, S = model.chain.home, np.ascontiguousarray(model.chain.screws.T)

    def single(q: FloatArray) -> Any:
        return mr.FKinSpace(M, S, q)

    return Library(
        "modern_robotics FKinSpace",
        "modern-robotics",
        single,
        lambda q: np.stack([single(row) for row in q]),
        note="screws and M from poekin's chain",
    )


COMPETITORS: dict[str, Callable[[Model], Library]] = {
    "pinocchio": pinocchio_library,
    "roboticstoolbox": rtb_library,
    "pytorch_kinematics": pytorch_kinematics_library,
    "modern_robotics": modern_robotics_library,
}


def time_library(lib: Library, model: Model, q: FloatArray, sizes: Sizes) -> Row:
    """Agreement with poekin first, then the single-call loop and the batch (or loop)."""
    row = Row(lib.name, note=lib.note)
    check = q[: sizes.check]
    row.agree(lib.poses(check), model.chain.fk(check))
    rows = lib.rows(q[: max(sizes.single, sizes.loop)])
    row.single = time_loop(lib.single, rows[: sizes.single], sizes.repeats, sizes.budget_s)
    if lib.batch is not None:
        n = sizes.vector_batch
        row.batch = time_batch(lib.batch, lib.batch_input(q[:n]), n, sizes.repeats)
        row.method = "vectorised"
    else:
        row.batch = time_loop(lib.single, rows[: sizes.loop], sizes.repeats, sizes.budget_s)
        row.method = "loop"
    return row


def competitor_row(
    name: str, build: Callable[[Model], Library], model: Model, q: FloatArray, sizes: Sizes
) -> Row:
    """The competitor's row, or a row that says why it has no timings."""
    try:
        lib = build(model)
    except ImportError as e:
        return Row(name, note=f"not installed ({e.name}): pip install -e '.[bench]'")
    except Exception as e:  # a library that cannot load the model says so in its row
        return Row(name, note=f"could not build from the model: {type(e).__name__}: {e}")
    return time_library(lib, model, q, sizes)


# --- the trees ------------------------------------------------------------------------------


def _quiet(load: Callable[[], Any]) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return load()


def _mj_frame_poses(m: mujoco.MjModel, data: mujoco.MjData, names: Sequence[str]) -> FloatArray:
    """World poses of the named bodies and sites in ``data`` (after ``mj_kinematics``)."""
    T = np.tile(np.eye(4), (len(names), 1, 1))
    for k, name in enumerate(names):
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        xmat, xpos = (data.xmat, data.xpos) if body >= 0 else (data.site_xmat, data.site_xpos)
        i = body if body >= 0 else mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, name)
        T[k, :3, :3], T[k, :3, 3] = xmat[i].reshape(3, 3), xpos[i]
    return T


def mujoco_tree_row(
    loaded: poekin.LoadedModel, tree: poekin.Tree, qpos: FloatArray, sizes: Sizes
) -> Row:
    """An ``mj_kinematics`` loop over ``qpos``, checked against ``tree.fk`` on every frame."""
    m, data = loaded.model, mujoco.MjData(loaded.model)
    if tree.nq != m.nq:
        raise ValueError(f"{loaded.robot}: tree qpos ({tree.nq}) is not MuJoCo's ({m.nq})")

    def mj(q: FloatArray) -> None:
        data.qpos[:] = q
        mujoco.mj_kinematics(m, data)

    row = Row("mujoco mj_kinematics", method="loop", note=f"{tree.n_frames} frames, nq {tree.nq}")
    check = qpos[: sizes.check]
    poses = []
    for q in check:
        mj(q)
        poses.append(_mj_frame_poses(m, data, tree.frame_names))
    row.agree(np.stack(poses), tree.fk(check))
    row.single = time_loop(mj, list(qpos[: sizes.single]), sizes.repeats, sizes.budget_s)
    row.batch = time_loop(mj, list(qpos[: sizes.loop]), sizes.repeats, sizes.budget_s)
    return row


def tree_rows(robot: str, sizes: Sizes, seed: int) -> list[Row]:
    """poekin ``tree.fk`` (every body and site) on a batch, then an ``mj_kinematics`` loop."""
    loaded = _quiet(lambda: poekin.load_model(robot))
    tree = poekin.load_tree(loaded)
    n = max(*sizes.tree_batches, sizes.loop, sizes.single, sizes.check)
    qpos = poekin.sample_qpos(tree, n, seed=seed)
    cases = poekin_cases(tree.fk, (tree.n_frames,), getattr(tree, "_fk_numpy", None))
    rows = time_cases("poekin tree.fk", cases, qpos, sizes.tree_batches, sizes)
    rows.append(mujoco_tree_row(loaded, tree, qpos, sizes))
    add_ratios(rows, "poekin tree.fk")
    return rows


# --- commands -------------------------------------------------------------------------------


def poekin_command() -> list[str]:
    """The ``poekin`` console script of this interpreter, or the same through ``-c``."""
    script = pathlib.Path(sys.executable).with_name("poekin")
    if script.exists():
        return [str(script)]
    found = shutil.which("poekin")
    if found:
        return [found]
    return [sys.executable, "-c", "import sys; from poekin.cli import main; sys.exit(main())"]


def command_timings(sizes: Sizes) -> dict[str, Timing]:
    """Fresh-process wall times: import poekin, the bare interpreter, and verify."""
    verify = [*poekin_command(), "verify", ROBOT, "--samples", str(sizes.verify_samples)]
    return {
        "python -c 'import poekin'": time_command(
            [sys.executable, "-c", "import poekin"], sizes.cmd_repeats
        ),
        "python -c 'pass' (interpreter alone)": time_command(
            [sys.executable, "-c", "pass"], sizes.cmd_repeats
        ),
        f"poekin verify --samples {sizes.verify_samples}": time_command(verify, sizes.cmd_repeats),
    }


# --- machine and versions -------------------------------------------------------------------


def package_version(dist: str) -> str | None:
    """The installed version of the distribution ``dist`` (None if it is not installed)."""
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def _cpu_model() -> str:
    with contextlib.suppress(OSError):
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def vector_width() -> str:
    """The widest vector unit this CPU has (the kernel's lanes), for the figures' context."""
    flags = ""
    with contextlib.suppress(OSError):
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                flags = line
                break
    if " avx512f" in flags:
        return "AVX-512 (8 float64 lanes)"
    if " avx2" in flags:
        return "AVX2 (4 float64 lanes)"
    return "SSE2/NEON (2 float64 lanes)"


def _git_revision() -> str | None:
    """The checkout's commit, ``+dirty`` if it has changes (None outside git)."""
    try:
        done = subprocess.run(
            ["git", "describe", "--always", "--dirty=+dirty"],
            cwd=pathlib.Path(__file__).parent,
            capture_output=True,
            text=True,
            check=True,
        )
    except (OSError, subprocess.CalledProcessError):
        return None
    return done.stdout.strip() or None


def machine_info() -> dict[str, Any]:
    """What the timings were taken on: CPU, cores, load, versions, threads, date."""
    compiled, threads = _optional("compiled_kernel"), _optional("get_threads")
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "cpu": _cpu_model(),
        "vector_width": vector_width(),
        "cores": os.cpu_count(),
        "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "git": _git_revision(),
        "versions": {
            d: package_version(d)
            for d in ("poekin", "numpy", "mujoco", "matplotlib", *BENCH_PACKAGES)
        },
        "poekin_threads": threads() if threads else None,
        "poekin_compiled_kernel": compiled() if compiled else None,
    }


# --- report ---------------------------------------------------------------------------------


def fmt_ns(ns: float) -> str:
    for unit, scale in (("s", 1e9), ("ms", 1e6), ("us", 1e3)):
        if ns >= scale:
            return f"{ns / scale:.3g} {unit}"
    return f"{ns:.3g} ns"


def fmt_count(n: int) -> str:
    for unit, scale in (("M", 1_000_000), ("k", 1_000)):
        if n >= scale and n % (scale // 10) == 0:
            return f"{n / scale:g}{unit}"
    return str(n)


def _cells(t: Timing | None, ratio: float | None) -> str:
    if t is None:
        return f"{'':>9} {'':>8} {'':>6}"
    x = "" if ratio is None else f"x{ratio:.3g}" if ratio < 100 else f"x{ratio:.0f}"
    return f"{fmt_ns(t.median_ns):>9} {fmt_ns(t.iqr_ns):>8} {x:>6}"


def _agreement(row: Row) -> str:
    if row.max_pos_m is None or row.max_ori_rad is None:
        return ""
    return f"{row.max_pos_m:.0e} m {row.max_ori_rad:.0e} rad"


def print_table(title: str, rows: list[Row]) -> None:
    """Median, IQR and ratio against poekin, for single calls and per configuration."""
    print(f"\n{title}")
    print(
        f"{'':36} {'single':>9} {'IQR':>8} {'ratio':>6}  {'batch':>10} {'per conf':>9} "
        f"{'IQR':>8} {'ratio':>6}  {'max diff vs poekin':19} note"
    )
    for r in rows:
        size = f"{r.method[:4]} {fmt_count(r.batch.size)}" if r.batch else ""
        print(
            f"{r.name:36} {_cells(r.single, r.single_ratio)}  {size:>10} "
            f"{_cells(r.batch, r.batch_ratio)}  {_agreement(r):19} {r.note}"
        )


def tree_summary(rows: list[Row]) -> list[dict[str, Any]]:
    """tree.fk per configuration, each batch size, against the mj_kinematics loop (last row)."""
    mj = rows[-1].batch
    if mj is None:
        return []
    return [
        {
            "batch": r.batch.size,
            "poekin_ns_per_config": r.batch.median_ns,
            "mujoco_loop_ns_per_config": mj.median_ns,
            "speedup": mj.median_ns / r.batch.median_ns,
        }
        for r in rows
        if r.name == "poekin tree.fk" and r.batch
    ]


def print_trees(tree_results: dict[str, list[Row]]) -> None:
    for robot, rows in tree_results.items():
        print_table(f"{robot}: every body and site (ratio = time / poekin tree.fk's)", rows)
        for s in tree_summary(rows):
            print(
                f"  tree.fk batch {fmt_count(s['batch'])}: {fmt_ns(s['poekin_ns_per_config'])}"
                f"/config, {s['speedup']:.1f}x faster than the mj_kinematics loop "
                f"({fmt_ns(s['mujoco_loop_ns_per_config'])}/config)"
            )


def print_commands(commands: dict[str, Timing]) -> None:
    print("\nfresh processes, wall time (bytecode cache on)")
    for name, t in commands.items():
        print(
            f"  {name:38} median {t.median_ns / 1e9:6.3f} s  min-max {t.min_ns / 1e9:.3f}-"
            f"{t.max_ns / 1e9:.3f} s  ({t.repeats} runs)"
        )


def plot(path: pathlib.Path, chain_rows: list[Row], tree_results: dict[str, list[Row]]) -> None:
    """Log-scale bars: single call and per-configuration batch time of every timed row."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(f"UR5e to {SITE}", chain_rows)]
    panels += [(f"{robot}, every frame", rows) for robot, rows in tree_results.items()]
    panels = [(title, [r for r in rows if r.single or r.batch]) for title, rows in panels]
    heights = [max(len(rows), 2) for _, rows in panels]
    fig, axes = plt.subplots(
        len(panels),
        1,
        figsize=(10, 0.42 * sum(heights) + 1.5 * len(panels)),
        height_ratios=heights,
        sharex=True,
        squeeze=False,
    )
    for ax, (title, rows) in zip(axes[:, 0], panels, strict=True):
        _bar_panel(ax, title, rows)
    axes[-1, 0].set_xlabel("ns, median over repeats (bars: interquartile range); log scale")
    axes[0, 0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.08), ncols=2, fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _bar_panel(ax: Any, title: str, rows: list[Row]) -> None:
    y = np.arange(len(rows))
    for offset, kind, color in ((-0.2, "single", "tab:blue"), (0.2, "batch", "tab:orange")):
        ts: list[Timing | None] = [getattr(r, kind) for r in rows]
        med = [t.median_ns if t else np.nan for t in ts]
        err = np.array(
            [[t.median_ns - t.q1_ns, t.q3_ns - t.median_ns] if t else [0, 0] for t in ts]
        )
        label = "single call" if kind == "single" else "batch or loop, per configuration"
        ax.barh(y + offset, med, height=0.4, xerr=err.T, color=color, label=label)
    labels = [
        f"{r.name} ({r.method} {fmt_count(r.batch.size)})" if r.batch else r.name for r in rows
    ]
    ax.set_yticks(y, labels, fontsize="small")
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlim(left=10)
    ax.set_title(title, loc="left", fontsize="medium")
    ax.grid(axis="x", which="both", alpha=0.3)


def to_json(value: Any) -> Any:
    """Rows and timings as plain dictionaries."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_json(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_json(v) for v in value]
    return value


# --- main -----------------------------------------------------------------------------------


def parse_args(argv: Sequence[str] | None) -> tuple[argparse.Namespace, Sizes]:
    doc = __doc__ or ""
    parser = argparse.ArgumentParser(
        description=doc.split("\n\n")[0],
        epilog=doc[doc.index("examples:") :],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--quick", action="store_true", help="tiny sizes, seconds (for CI)")
    parser.add_argument("--n", type=int, help="configurations drawn (1e6)")
    parser.add_argument("--batches", type=int, nargs="+", help="poekin batch sizes (1e5 1e6)")
    parser.add_argument("--vector-batch", type=int, help="competitors' vectorised batch (1e5)")
    parser.add_argument("--loop", type=int, help="loop-only libraries: loop size (1e4)")
    parser.add_argument("--single", type=int, help="distinct q per single-call repeat (2000)")
    parser.add_argument("--tree-batches", type=int, nargs="+", help="tree.fk batches (1e4 1e5)")
    parser.add_argument("--repeats", type=int, help="repeats per measurement (7)")
    parser.add_argument("--budget", type=float, dest="budget_s", help="s per loop repeat (1)")
    parser.add_argument("--cmd-repeats", type=int, help="runs per fresh-process timing (5)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (0)")
    parser.add_argument(
        "--skip",
        nargs="+",
        default=[],
        choices=sorted(COMPETITORS),
        metavar="NAME",
        help=f"competitors to leave out: {', '.join(COMPETITORS)}",
    )
    parser.add_argument("--no-trees", action="store_true", help="leave out go2 and aloha")
    parser.add_argument("--no-commands", action="store_true", help="leave out verify and import")
    parser.add_argument("--json", type=pathlib.Path, metavar="PATH", help="write every result")
    parser.add_argument("--plot", type=pathlib.Path, metavar="PATH", help="write a bar chart PNG")
    parser.add_argument(
        "--save",
        action="store_true",
        help=f"--json and --plot into {RESULTS.parent.name}/{RESULTS.name}/",
    )
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else Sizes()
    given = {
        f.name: getattr(args, f.name)
        for f in dataclasses.fields(Sizes)
        if getattr(args, f.name, None) is not None
    }
    for key in ("batches", "tree_batches"):
        if key in given:
            given[key] = tuple(given[key])
    sizes = dataclasses.replace(sizes, **given)
    needed = max(*sizes.batches, sizes.vector_batch, sizes.loop, sizes.single, sizes.check)
    if sizes.n < needed:
        parser.error(f"--n {sizes.n} is smaller than the largest size asked for ({needed})")
    return args, sizes


def run_chain(sizes: Sizes, seed: int, skip: Sequence[str]) -> list[Row]:
    loaded = _quiet(lambda: poekin.load_model(ROBOT))
    model = Model(loaded, poekin.load(loaded, SITE))
    q = np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, size=(sizes.n, 6))
    # the reference path as fk runs it without the kernel (fk validates q, then this)
    numpy_path = getattr(model.chain, "_fk_numpy", None)
    cases = poekin_cases(model.chain.fk, (), numpy_path)
    rows = time_cases("poekin chain.fk", cases, q, sizes.batches, sizes)
    rows.append(time_library(mujoco_library(model), model, q, sizes))
    for name, build in COMPETITORS.items():
        if name not in skip:
            rows.append(competitor_row(name, build, model, q, sizes))
    add_ratios(rows, "poekin chain.fk")
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    args, sizes = parse_args(argv)
    t0 = time.perf_counter()
    machine = machine_info()
    print(
        f"{machine['cpu']}, {machine['vector_width']}, {machine['usable_cores']} cores, "
        f"load {machine['load_average']}"
    )
    print(
        f"{fmt_count(sizes.n)} q in [-2 pi, 2 pi]^6 (seed {args.seed}); medians and IQR over "
        f"{sizes.repeats} repeats; single calls: a loop over up to {fmt_count(sizes.single)} q"
    )
    chain_rows = run_chain(sizes, args.seed, args.skip)
    print_table(f"UR5e FK to {SITE} (ratio = time / poekin chain.fk's)", chain_rows)
    trees = {} if args.no_trees else {r: tree_rows(r, sizes, args.seed) for r in TREES}
    print_trees(trees)
    commands = {} if args.no_commands else command_timings(sizes)
    print_commands(commands)
    elapsed = time.perf_counter() - t0
    print(f"\nbenchmark wall time {elapsed:.1f} s")
    if args.save:
        stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
        RESULTS.mkdir(exist_ok=True)
        args.json = args.json or RESULTS / f"bench_fk-{stamp}.json"
        args.plot = args.plot or RESULTS / f"bench_fk-{stamp}.png"
    if args.json:
        machine["load_average_after"] = os.getloadavg() if hasattr(os, "getloadavg") else None
        result = {
            "machine": machine,
            "sizes": sizes,
            "seed": args.seed,
            "wall_s": elapsed,
            "ur5e": chain_rows,
            "trees": {
                r: {"rows": rows, "vs_mujoco": tree_summary(rows)} for r, rows in trees.items()
            },
            "commands": commands,
        }
        args.json.write_text(json.dumps(to_json(result), indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.plot:
        plot(args.plot, chain_rows, trees)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
