"""The array-library benchmark: poekin on JAX and PyTorch against MJX and pytorch_kinematics.

One run, the same configurations for everyone (UR5e q uniform in [-2 pi, 2 pi]^6, fixed seed;
go2 and aloha qpos from ``poekin.sample_qpos``):

* UR5e (Menagerie ``universal_robots_ur5e``, ``attachment_site``), float64, per configuration:
  JAX ``jit(vmap(chain.fk))`` (target <= 300 ns at 1e5), its forward plus backward pass (the
  gradient of the sum of all poses with respect to q; target <= 3x the forward), its first call
  (trace and compile; target <= 1 s); PyTorch ``chain.fk`` on a ``(N, 6)`` CPU tensor and its
  forward plus backward; ``torch.compile`` (Inductor) of ``chain.fk``, first call and per
  configuration; float32 of both; poekin's NumPy kernel for scale; and the anchors, if installed:
  MJX ``jit(vmap(kinematics))`` (target: JAX poekin >= 100x faster) and pytorch_kinematics on the
  same tensor (target: PyTorch poekin >= 10x faster), each checked against MuJoCo.
* go2 and aloha, every body and site: ``tree.fk`` in both libraries, forward and forward plus
  backward (target: the forward never slower than forward plus backward), JAX's forward per
  configuration against the NumPy kernel's (target for the go2: <= 5x), and ``torch.compile``
  (Inductor) of ``tree.fk``: first call (target <= 60 s; compile caches off) and per
  configuration.
* every Menagerie model here (``first-calls``): JAX's first call of ``jit(vmap(tree.fk))``
  (trace and compile; target <= 3 s each).

Medians and interquartile ranges over repeats; ratios as ``x`` (time / poekin's). Accuracy: the
largest position and orientation difference from MuJoCo's ``mj_kinematics`` on a subset. The
machine is shared and noisy: read medians and ratios from one run, never one sample. No timing
is asserted anywhere. At the end, the trees' figures in one table (CPU named) and issue #20's
four goals for trees, each met or missed (also under ``goals`` in ``--json``).

examples:
  python benchmarks/bench_arrays.py --quick                  # seconds; what CI runs
  python benchmarks/bench_arrays.py --json arrays.json --plot arrays.png
  python benchmarks/bench_arrays.py --skip mjx pytorch_kinematics torch_compile first_calls
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import time
import warnings
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import (  # the FK benchmark's timing helpers and model loading
    ROBOT,
    SITE,
    Model,
    Timing,
    _mj_frame_poses,
    _quiet,
    fmt_count,
    fmt_ns,
    machine_info,
    package_version,
    pytorch_kinematics_library,
    to_json,
)

import poekin

TREES = ("unitree_go2", "aloha")
MENAGERIE = (  # the models shared with the tests (../shared/menagerie)
    "universal_robots_ur5e",
    "universal_robots_ur10e",
    "franka_emika_panda",
    "franka_fr3",
    "ufactory_lite6",
    "rethink_robotics_sawyer",
    "trs_so_arm100",
    "unitree_go2",
    "aloha",
)
ANCHORS = ("mjx", "pytorch_kinematics", "torch_compile", "first_calls")


@dataclasses.dataclass(frozen=True)
class Sizes:
    batch: int = 100_000  # UR5e and trees
    anchor_batch: int = 10_000  # MJX (~40 us a configuration here)
    repeats: int = 7
    check: int = 200  # configurations checked against MuJoCo


QUICK = Sizes(batch=500, anchor_batch=100, repeats=3, check=20)


@dataclasses.dataclass
class Row:
    """One measurement: ns per configuration, or seconds for a first call."""

    group: str  # "ur5e", "unitree_go2", "aloha"
    name: str
    timing: Timing | None = None
    first_call_s: float | None = None
    max_pos_m: float | None = None  # against MuJoCo
    max_ori_rad: float | None = None
    note: str = ""


def _block(x: Any) -> Any:
    """``x`` once computed: JAX dispatches asynchronously (a tuple of results included)."""
    jax = sys.modules.get("jax")
    return jax.block_until_ready(x) if jax is not None else x


def time_per_config(call: Callable[[], Any], size: int, repeats: int) -> Timing:
    """Median ns per configuration of ``call()`` (one call on ``size`` configurations), JAX's
    asynchronous results waited for, after one warm-up call."""
    _block(call())
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        _block(call())
        samples.append((time.perf_counter_ns() - t0) / size)
    return Timing.of(samples, size)


def time_interleaved(calls: list[Callable[[], Any]], size: int, repeats: int) -> list[Timing]:
    """:func:`time_per_config` of several calls, one repeat of each in turn, so that a noisy
    spell of the shared machine falls on all of them alike and their ratios hold."""
    for call in calls:
        _block(call())
    samples: list[list[float]] = [[] for _ in calls]
    for _ in range(repeats):
        for call, out in zip(calls, samples, strict=True):
            t0 = time.perf_counter_ns()
            _block(call())
            out.append((time.perf_counter_ns() - t0) / size)
    return [Timing.of(out, size) for out in samples]


def first_call(call: Callable[[], Any]) -> float:
    t0 = time.perf_counter()
    _block(call())
    return time.perf_counter() - t0


def agreement(row: Row, T: np.ndarray, T_ref: np.ndarray) -> Row:
    pos, ori = poekin.pose_errors(T_ref, np.asarray(T, dtype=np.float64))
    row.max_pos_m, row.max_ori_rad = float(pos.max()), float(ori.max())
    return row


def mujoco_site_poses(loaded: poekin.LoadedModel, chain: poekin.Chain, q: np.ndarray) -> Any:
    m, data = loaded.model, mujoco.MjData(loaded.model)
    idx = list(chain.qpos_indices or range(chain.n_joints))
    out = []
    for row in q:
        data.qpos[idx] = row
        mujoco.mj_kinematics(m, data)
        out.append(_mj_frame_poses(m, data, [SITE])[0])
    return np.array(out)


# --- JAX ----------------------------------------------------------------------------------------


def jax_rows(
    group: str, fk: Callable[..., Any], q: np.ndarray, sizes: Sizes, ref: Any
) -> list[Row]:
    """poekin's NumPy kernel (for scale, timed first and alone: a small batch's kernel call
    after a JAX call runs up to 2x slower); jit(vmap(fk)): first call, forward and forward plus
    backward (timed interleaved, whose ratio is a goal), float32."""
    import jax
    import jax.numpy as jnp

    rows = [Row(group, "poekin numpy kernel (for scale)")]
    rows[0].timing = time_per_config(lambda: fk(q), len(q), sizes.repeats)
    x = jnp.asarray(q)
    forward = jax.jit(jax.vmap(fk))
    rows.append(Row(group, "jax jit(vmap(fk))", first_call_s=first_call(lambda: forward(x))))
    agreement(rows[1], forward(x[: len(ref)]), ref)
    both = jax.jit(jax.grad(lambda y: jnp.sum(jax.vmap(fk)(y))))
    rows.append(Row(group, "jax forward + backward", first_call_s=first_call(lambda: both(x))))
    rows[1].timing, rows[2].timing = time_interleaved(
        [lambda: forward(x), lambda: both(x)], len(q), sizes.repeats
    )
    x32 = x.astype(jnp.float32)
    rows.append(Row(group, "jax jit(vmap(fk)) float32"))
    rows[-1].timing = time_per_config(lambda: forward(x32), len(q), sizes.repeats)
    agreement(rows[-1], forward(x32[: len(ref)]), ref)
    return rows


def mjx_row(loaded: poekin.LoadedModel, q: np.ndarray, sizes: Sizes, ref: Any) -> Row:
    """MJX's jit(vmap(kinematics)) of the whole model, float64, the site's pose read back."""
    import jax
    import jax.numpy as jnp
    from mujoco import mjx

    m = loaded.model
    mx, dx = mjx.put_model(m), mjx.make_data(m)
    site = m.site(SITE).id

    def kinematics(qpos: Any) -> Any:
        d = mjx.kinematics(mx, dx.replace(qpos=qpos))
        return d.site_xpos[site], d.site_xmat[site]

    f = jax.jit(jax.vmap(kinematics))
    n = sizes.anchor_batch
    x = jnp.asarray(q[:n])
    row = Row("ur5e", "mjx jit(vmap(kinematics))", first_call_s=first_call(lambda: f(x)))
    row.timing = time_per_config(lambda: f(x), n, sizes.repeats)
    pos, mat = f(x[: len(ref)])
    T = np.tile(np.eye(4), (len(ref), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = np.asarray(mat).reshape(-1, 3, 3), np.asarray(pos)
    row.note = f"whole model, batch {fmt_count(n)}, mujoco-mjx {package_version('mujoco-mjx')}"
    return agreement(row, T, ref)


# --- PyTorch --------------------------------------------------------------------------------------


def torch_rows(
    group: str, fk: Callable[..., Any], q: np.ndarray, sizes: Sizes, ref: Any
) -> list[Row]:
    """Eager fk on a CPU tensor, forward plus backward, float32."""
    import torch

    x = torch.from_numpy(q)
    rows = [Row(group, "torch fk(tensor)", note=f"{torch.get_num_threads()} torch threads")]
    with torch.no_grad():
        rows[0].timing = time_per_config(lambda: fk(x), len(q), sizes.repeats)
    agreement(rows[0], fk(x[: len(ref)]).numpy(), ref)

    def both() -> Any:
        y = x.detach().requires_grad_()
        fk(y).sum().backward()
        return y.grad

    rows.append(Row(group, "torch forward + backward"))
    rows[-1].timing = time_per_config(both, len(q), sizes.repeats)
    x32 = x.float()
    rows.append(Row(group, "torch fk(tensor) float32"))
    with torch.no_grad():
        rows[-1].timing = time_per_config(lambda: fk(x32), len(q), sizes.repeats)
    agreement(rows[-1], fk(x32[: len(ref)]).numpy(), ref)
    return rows


def torch_compile_row(chain: poekin.Chain, q: np.ndarray, sizes: Sizes, ref: Any) -> Row:
    """torch.compile (Inductor, fullgraph) of chain.fk: first call (compile), then per config."""
    import torch

    x = torch.from_numpy(q)
    compiled = torch.compile(chain.fk, fullgraph=True)
    row = Row("ur5e", "torch.compile(fk) inductor", first_call_s=first_call(lambda: compiled(x)))
    row.timing = time_per_config(lambda: compiled(x), len(q), sizes.repeats)
    return agreement(row, compiled(x[: len(ref)]).numpy(), ref)


def tree_compile_row(
    group: str, tree: poekin.Tree, qpos: np.ndarray, sizes: Sizes, ref: Any
) -> Row:
    """torch.compile (Inductor, fullgraph) of tree.fk with Inductor's caches off, so that the
    first call is a whole compile however often the benchmark runs. An eager call has come
    first (torch_rows): torch.compile as a process's first torch call fails (issue #20, 3)."""
    import torch
    import torch._inductor.config as inductor

    x = torch.from_numpy(qpos)
    compiled = torch.compile(tree.fk, fullgraph=True)
    before = inductor.force_disable_caches
    inductor.force_disable_caches = True
    try:
        first = first_call(lambda: compiled(x[:8]))
    finally:
        inductor.force_disable_caches = before
    row = Row(group, "torch.compile(tree.fk) inductor", first_call_s=first)
    with torch.no_grad():
        row.timing = time_per_config(lambda: compiled(x), len(qpos), sizes.repeats)
    return agreement(row, compiled(x[: len(ref)]).numpy(), ref)


def first_call_rows(sizes: Sizes) -> list[Row]:
    """JAX's first call of jit(vmap(tree.fk)) (trace and compile) for every Menagerie model."""
    import jax
    import jax.numpy as jnp

    rows = []
    for robot in MENAGERIE:
        try:
            tree = poekin.load_tree(_quiet(lambda robot=robot: poekin.load_model(robot)))
        except poekin.PoekinError as e:
            rows.append(skipped("first calls", robot, e))
            continue
        x = jnp.asarray(poekin.sample_qpos(tree, sizes.batch, seed=0))
        forward = jax.jit(jax.vmap(tree.fk))
        note = f"{len(tree.body_names)} bodies, {len(tree.site_names)} sites"
        seconds = first_call(lambda forward=forward, x=x: forward(x))
        rows.append(Row("first calls", robot, first_call_s=seconds, note=note))
    return rows


def pytorch_kinematics_row(model: Model, q: np.ndarray, sizes: Sizes, ref: Any) -> Row:
    import torch

    lib = pytorch_kinematics_library(model)
    x = torch.from_numpy(q)
    row = Row("ur5e", "pytorch_kinematics", note=lib.note)
    assert lib.batch is not None
    batch = lib.batch
    row.timing = time_per_config(lambda: batch(x), len(q), sizes.repeats)
    return agreement(row, lib.poses(q[: len(ref)]), ref)


# --- the run --------------------------------------------------------------------------------------


def skipped(group: str, name: str, error: BaseException) -> Row:
    return Row(group, name, note=f"not run: {type(error).__name__}: {error}"[:160])


def run_ur5e(sizes: Sizes, seed: int, skip: list[str]) -> list[Row]:
    loaded = _quiet(lambda: poekin.load_model(ROBOT))
    chain = poekin.load(loaded, SITE)
    q = np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, (sizes.batch, 6))
    ref = mujoco_site_poses(loaded, chain, q[: sizes.check])
    rows = jax_rows("ur5e", chain.fk, q, sizes, ref)
    agreement(rows[0], chain.fk(q[: sizes.check]), ref)
    rows += torch_rows("ur5e", chain.fk, q, sizes, ref)
    anchors: dict[str, Callable[[], Row]] = {
        "torch_compile": lambda: torch_compile_row(chain, q, sizes, ref),
        "mjx": lambda: mjx_row(loaded, q, sizes, ref),
        "pytorch_kinematics": lambda: pytorch_kinematics_row(Model(loaded, chain), q, sizes, ref),
    }
    for name, build in anchors.items():
        if name in skip:
            continue
        try:
            rows.append(build())
        except Exception as e:  # an anchor that is not installed or fails says so in its row
            rows.append(skipped("ur5e", name, e))
    return rows


def run_tree(robot: str, sizes: Sizes, seed: int, skip: list[str]) -> list[Row]:
    loaded = _quiet(lambda: poekin.load_model(robot))
    tree = poekin.load_tree(loaded)
    qpos = poekin.sample_qpos(tree, sizes.batch, seed=seed)
    ref = tree.fk(qpos[: sizes.check])  # equal to mj_kinematics to 1e-15 (tests/test_tree.py)
    rows = jax_rows(robot, tree.fk, qpos, sizes, ref)
    rows += torch_rows(robot, tree.fk, qpos, sizes, ref)
    if "torch_compile" not in skip:
        try:
            rows.append(tree_compile_row(robot, tree, qpos, sizes, ref))
        except Exception as e:  # a failed compile says so in its row
            rows.append(skipped(robot, "torch.compile(tree.fk) inductor", e))
    for r in rows:
        if r.max_pos_m is not None:
            r.note = f"{r.note}; accuracy vs poekin's NumPy path".lstrip("; ")
    return rows


def ratios(rows: list[Row]) -> dict[str, float]:
    """The issue's targets as ratios, from one run."""
    by = {(r.group, r.name): r.timing.median_ns for r in rows if r.timing}
    out: dict[str, float] = {}

    def ratio(key: str, a: tuple[str, str], b: tuple[str, str]) -> None:
        if a in by and b in by:
            out[key] = by[a] / by[b]

    for group in TREES:
        ratio(
            f"{group}: jax forward / numpy kernel",
            (group, "jax jit(vmap(fk))"),
            (group, "poekin numpy kernel (for scale)"),
        )
    for group in ("ur5e", *TREES):
        ratio(
            f"{group}: jax forward+backward / forward",
            (group, "jax forward + backward"),
            (group, "jax jit(vmap(fk))"),
        )
        ratio(
            f"{group}: torch forward+backward / forward",
            (group, "torch forward + backward"),
            (group, "torch fk(tensor)"),
        )
    ratio("mjx / poekin jax", ("ur5e", "mjx jit(vmap(kinematics))"), ("ur5e", "jax jit(vmap(fk))"))
    ratio(
        "pytorch_kinematics / poekin torch",
        ("ur5e", "pytorch_kinematics"),
        ("ur5e", "torch fk(tensor)"),
    )
    return out


@dataclasses.dataclass(frozen=True)
class TreeFigures:
    """One tree's figures for issue #20's goals (section 4), per configuration."""

    robot: str
    jax_forward_ns: float | None
    jax_both_ns: float | None  # forward plus backward
    numpy_ns: float | None  # poekin's NumPy kernel
    jax_first_call_s: float | None
    torch_compile_s: float | None  # first call of torch.compile(tree.fk): the compile


def tree_figures(rows: list[Row]) -> list[TreeFigures]:
    def get(group: str, name: str) -> Row | None:
        return next((r for r in rows if r.group == group and r.name == name), None)

    out = []
    for robot in dict.fromkeys(r.group for r in rows if r.group in TREES):
        fwd, both = get(robot, "jax jit(vmap(fk))"), get(robot, "jax forward + backward")
        kernel = get(robot, "poekin numpy kernel (for scale)")
        compiled = get(robot, "torch.compile(tree.fk) inductor")
        out.append(
            TreeFigures(
                robot,
                fwd.timing.median_ns if fwd and fwd.timing else None,
                both.timing.median_ns if both and both.timing else None,
                kernel.timing.median_ns if kernel and kernel.timing else None,
                fwd.first_call_s if fwd else None,
                compiled.first_call_s if compiled else None,
            )
        )
    return out


def goals(rows: list[Row]) -> dict[str, dict[str, Any]]:
    """Issue #20's goals for trees (section 4), each with its figure and whether it is met,
    from one run: (a) JAX's forward never slower than forward plus backward (go2, aloha);
    (b) the go2's JAX forward <= 5x the NumPy kernel; (c) the first JAX call of every shared
    Menagerie model <= 3 s; (d) torch.compile of a tree <= 60 s."""
    out: dict[str, dict[str, Any]] = {}
    for t in tree_figures(rows):
        if t.jax_forward_ns is not None and t.jax_both_ns is not None:
            ratio = t.jax_forward_ns / t.jax_both_ns
            out[f"(a) {t.robot}: jax forward / forward+backward <= 1"] = {
                "value": ratio,
                "met": ratio <= 1.0,
            }
        if t.robot == "unitree_go2" and t.jax_forward_ns and t.numpy_ns:
            ratio = t.jax_forward_ns / t.numpy_ns
            out[f"(b) {t.robot}: jax forward / numpy kernel <= 5"] = {
                "value": ratio,
                "met": ratio <= 5.0,
            }
        if t.torch_compile_s is not None:
            out[f"(d) {t.robot}: torch.compile s <= 60"] = {
                "value": t.torch_compile_s,
                "met": t.torch_compile_s <= 60.0,
            }
    firsts = [r for r in rows if r.group == "first calls" and r.first_call_s is not None]
    if firsts:
        slowest = max(firsts, key=lambda r: r.first_call_s or 0.0)
        seconds = slowest.first_call_s or 0.0
        out[f"(c) every model: first jax call s <= 3 (slowest: {slowest.name})"] = {
            "value": seconds,
            "met": seconds <= 3.0 and len(firsts) == len(MENAGERIE),
        }
    return out


def print_goals(rows: list[Row], cpu: str, sizes: Sizes) -> None:
    """The trees' figures in one table, and issue #20's goals met or missed."""
    figures = tree_figures(rows)
    if not figures:
        return

    def ns(v: float | None) -> str:
        return fmt_ns(v) if v is not None else "-"

    def ratio(a: float | None, b: float | None) -> str:
        return f"{a / b:.2f}x" if a is not None and b else "-"

    def sec(v: float | None) -> str:
        return f"{v:.2f} s" if v is not None else "-"

    print(f"\ntrees, per configuration, float64, batch {fmt_count(sizes.batch)}, {cpu}:")
    head = ("model", "jax fwd", "fwd+bwd", "fwd/both", "numpy", "jax/numpy", "1st jax", "compile")
    print(f"  {head[0]:12}" + "".join(f" {h:>10}" for h in head[1:]))
    for t in figures:
        cells = (
            ns(t.jax_forward_ns),
            ns(t.jax_both_ns),
            ratio(t.jax_forward_ns, t.jax_both_ns),
            ns(t.numpy_ns),
            ratio(t.jax_forward_ns, t.numpy_ns),
            sec(t.jax_first_call_s),
            sec(t.torch_compile_s),
        )
        print(f"  {t.robot:12}" + "".join(f" {c:>10}" for c in cells))
    print("issue #20 goals (one run, provisional on a shared machine):")
    for key, goal in goals(rows).items():
        print(f"  {'met   ' if goal['met'] else 'MISSED'} {key}: {goal['value']:.3g}")


def print_rows(rows: list[Row]) -> None:
    group = None
    for r in rows:
        if r.group != group:
            group = r.group
            print(f"\n{group}: {'':42} {'per conf':>9} {'IQR':>8} {'first call':>10}  max diff")
        t = (
            f"{fmt_ns(r.timing.median_ns):>9} {fmt_ns(r.timing.iqr_ns):>8}"
            if r.timing
            else " " * 18
        )
        first = f"{r.first_call_s:8.2f} s" if r.first_call_s is not None else " " * 10
        acc = ""
        if r.max_pos_m is not None and r.max_ori_rad is not None:
            acc = f"{r.max_pos_m:.1e} m {r.max_ori_rad:.1e} rad"
        print(f"  {r.name:48} {t} {first:>10}  {acc:22} {r.note}")


def plot(path: pathlib.Path, rows: list[Row]) -> None:
    """Log-scale bars: ns per configuration of every timed row, one panel per robot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = list(dict.fromkeys(r.group for r in rows))
    panels = [[r for r in rows if r.group == g and r.timing] for g in groups]
    heights = [max(len(p), 2) for p in panels]
    fig, axes = plt.subplots(
        len(panels),
        1,
        figsize=(10, 0.4 * sum(heights) + 1.4 * len(panels)),
        height_ratios=heights,
        sharex=True,
        squeeze=False,
    )
    for ax, group, panel in zip(axes[:, 0], groups, panels, strict=True):
        y = np.arange(len(panel))
        med = [r.timing.median_ns for r in panel if r.timing]
        err = np.array(
            [
                [r.timing.median_ns - r.timing.q1_ns, r.timing.q3_ns - r.timing.median_ns]
                for r in panel
                if r.timing
            ]
        )
        colors = [
            "tab:gray"
            if "numpy" in r.name
            else "tab:red"
            if r.name.startswith(("mjx", "pytorch_k"))
            else "tab:blue"
            if r.name.startswith("jax")
            else "tab:orange"
            for r in panel
        ]
        ax.barh(y, med, xerr=err.T, color=colors, height=0.6)
        for k, r in enumerate(panel):
            if r.timing:
                label_at = max(r.timing.q3_ns, r.timing.median_ns) * 1.12
                ax.text(label_at, k, fmt_ns(r.timing.median_ns), va="center", fontsize="x-small")
        ax.set_yticks(y, [r.name for r in panel], fontsize="small")
        ax.invert_yaxis()
        ax.set_xscale("log")
        size = fmt_count(panel[0].timing.size) if panel and panel[0].timing else ""
        ax.set_title(f"{group}: ns per configuration (batch {size})", loc="left", fontsize="medium")
        ax.grid(axis="x", which="both", alpha=0.3)
    slowest = max(r.timing.q3_ns for r in rows if r.timing)
    axes[-1, 0].set_xlim(right=slowest * 4)
    axes[-1, 0].set_xlabel(
        "ns per configuration, median (bars: IQR), log scale\nblue: poekin on JAX, orange: "
        "poekin on PyTorch, grey: poekin's NumPy kernel, red: other libraries"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    doc = __doc__ or ""
    parser = argparse.ArgumentParser(
        description=doc.split("\n\n")[0],
        epilog=doc[doc.index("examples:") :],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--quick", action="store_true", help="tiny sizes, seconds (for CI)")
    parser.add_argument("--batch", type=int, help="configurations per call (1e5)")
    parser.add_argument("--repeats", type=int, help="repeats per measurement (7)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--skip",
        nargs="+",
        default=[],
        choices=ANCHORS,
        metavar="NAME",
        help=f"leave out: {', '.join(ANCHORS)}",
    )
    parser.add_argument("--no-trees", action="store_true", help="leave out go2 and aloha")
    parser.add_argument("--json", type=pathlib.Path, metavar="PATH", help="write every result")
    parser.add_argument("--plot", type=pathlib.Path, metavar="PATH", help="write a bar chart PNG")
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else Sizes()
    if args.batch:
        sizes = dataclasses.replace(
            sizes, batch=args.batch, anchor_batch=min(sizes.anchor_batch, args.batch)
        )
    if args.repeats:
        sizes = dataclasses.replace(sizes, repeats=args.repeats)
    skip = list(args.skip) + (["torch_compile", "mjx", "first_calls"] if args.quick else [])
    try:
        import jax
        import torch
    except ImportError as e:
        print(
            f"bench_arrays: needs JAX and PyTorch: pip install -e '.[jax,torch]' ({e.name})",
            file=sys.stderr,
        )
        return 2
    jax.config.update("jax_enable_x64", True)
    warnings.simplefilter("ignore", UserWarning)  # torch's read-only NumPy array notice
    machine = machine_info()
    machine["torch_threads"] = torch.get_num_threads()
    machine["jax_devices"] = [str(d) for d in jax.devices()]
    for dist in ("jax", "torch", "array-api-compat", "mujoco-mjx", "pytorch-kinematics"):
        machine["versions"][dist] = package_version(dist)
    cores, load = machine["usable_cores"], machine["load_average"]
    print(f"{machine['cpu']}, {machine['vector_width']}, {cores} cores, load {load}")
    print(f"batch {fmt_count(sizes.batch)}, medians and IQR over {sizes.repeats} repeats, float64")
    t0 = time.perf_counter()
    rows = run_ur5e(sizes, args.seed, skip)
    if not args.no_trees:
        for robot in TREES[:1] if args.quick else TREES:  # --quick: the go2 only
            rows += run_tree(robot, sizes, args.seed, skip)
    if "first_calls" not in skip:
        rows += first_call_rows(sizes)
    print_rows(rows)
    summary = ratios(rows)
    print()
    for key, value in summary.items():
        print(f"  {key}: {value:.3g}x")
    print_goals(rows, f"{machine['cpu']}, {machine['vector_width']}", sizes)
    elapsed = time.perf_counter() - t0
    print(f"\nbenchmark wall time {elapsed:.1f} s")
    if args.json:
        machine["load_average_after"] = __import__("os").getloadavg()
        result = {
            "machine": machine,
            "sizes": sizes,
            "seed": args.seed,
            "wall_s": elapsed,
            "rows": rows,
            "ratios": summary,
            "goals": goals(rows),
        }
        args.json.write_text(json.dumps(to_json(result), indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.plot:
        plot(args.plot, rows)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
