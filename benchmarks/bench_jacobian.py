"""The Jacobian benchmark: poekin against MuJoCo and, when installed, Pinocchio (issue #7).

One run, the same q for everyone: the UR5e's ``attachment_site`` Jacobian from poekin's
``chain.jacobian_world`` (single calls and batches; also ``jacobian_space`` and
``jacobian_body``), a loop of MuJoCo's ``mj_kinematics`` + ``mj_comPos`` + ``mj_jacSite`` (what
``mj_jacSite`` needs), and a loop of Pinocchio's ``computeFrameJacobian`` in
``LOCAL_WORLD_ALIGNED`` (forward kinematics included). Each competitor's Jacobian is checked to
agree with poekin's world Jacobian (Pinocchio's rows ``[v; w]`` reordered). Then the go2's
``FL_calf`` (free base, 18 qvel columns) from ``tree.jacobian`` against ``mj_jacBody``. Medians
and IQR over repeats, ratios against poekin, and ``--json``; ``--quick`` is CI's tiny size.

    python benchmarks/bench_jacobian.py [--quick] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import (  # the FK benchmark's timing and table helpers
    ROBOT,
    SITE,
    Row,
    _pinocchio_root_fix,
    add_ratios,
    machine_info,
    print_table,
    time_batch,
    time_loop,
    to_json,
)

import poekin

FloatArray = np.ndarray[Any, np.dtype[np.float64]]
AGREE_TOL = 1e-9  # a competitor's Jacobian within this of poekin's is the same Jacobian

FULL = {"n": 100_000, "batches": (10_000, 100_000), "loop": 10_000, "single": 2_000}
QUICK = {"n": 500, "batches": (100, 500), "loop": 100, "single": 100}


def mujoco_jacobian(
    loaded: poekin.LoadedModel, chain: poekin.Chain
) -> tuple[Callable[[Any], Any], Callable[[Any], Any]]:
    """MuJoCo's Jacobian of one configuration: ``(timed, full)``. ``timed`` does MuJoCo's work
    only (qpos, mj_kinematics, mj_comPos, mj_jacSite into preallocated jacp, jacr); ``full``
    also assembles ``[jacr; jacp]`` (6 x n) of the chain's columns, for the agreement check."""
    m = loaded.model
    data, site = mujoco.MjData(m), m.site(SITE).id
    idx = list(chain.qpos_indices or range(chain.n_joints))
    target = slice(None) if idx == list(range(m.nq)) else idx  # a slice copies fastest
    dofs = [int(m.jnt_dofadr[np.flatnonzero(m.jnt_qposadr == i)[0]]) for i in idx]
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))

    def timed(q: FloatArray) -> None:
        data.qpos[target] = q
        mujoco.mj_kinematics(m, data)
        mujoco.mj_comPos(m, data)
        mujoco.mj_jacSite(m, data, jacp, jacr, site)

    def full(q: FloatArray) -> FloatArray:
        timed(q)
        return np.vstack([jacr[:, dofs], jacp[:, dofs]])

    return timed, full


def pinocchio_jacobian(
    loaded: poekin.LoadedModel,
) -> tuple[Callable[[Any], Any], Callable[[Any], Any], str]:
    """One configuration's ``LOCAL_WORLD_ALIGNED`` frame Jacobian, rows ``[v; w]`` (its own
    result, so the timed and the full call are one)."""
    import pinocchio as pin

    pm = pin.buildModelFromMJCF(str(loaded.xml_path))
    note = _pinocchio_root_fix(pin, pm, loaded.model)
    data, frame = pm.createData(), pm.getFrameId(SITE)
    aligned = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

    def jacobian(q: FloatArray) -> Any:
        return pin.computeFrameJacobian(pm, data, q, frame, aligned)

    return jacobian, jacobian, note


def agreement(
    row: Row, jacobian: Callable[[Any], Any], q: FloatArray, expected: FloatArray
) -> None:
    got = np.stack([jacobian(row_q) for row_q in q])
    if row.name.startswith("pinocchio"):
        got = np.concatenate([got[:, 3:], got[:, :3]], axis=1)  # [v; w] -> [w; v]
    diff = float(np.abs(got - expected).max())
    verdict = "agrees" if diff <= AGREE_TOL else f"DISAGREES (tolerance {AGREE_TOL:g})"
    row.note = f"{verdict}: max |dJ| {diff:.0e} vs poekin; {row.note}".strip("; ")


TREE, TREE_FRAME = "unitree_go2", "FL_calf"


def tree_rows(sizes: dict[str, Any], repeats: int, seed: int) -> list[Row]:
    """go2 (free base + 12 hinges): ``tree.jacobian`` of a calf, world convention, against a
    loop of ``mj_kinematics`` + ``mj_comPos`` + ``mj_jacBody``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model(TREE)
    tree, m = poekin.load_tree(loaded), loaded.model
    qpos = poekin.sample_qpos(tree, sizes["n"], seed=seed)
    rows_q = list(qpos[: sizes["single"]])
    budget = 1.0 if sizes is FULL else 0.1

    def jacobian(x: Any) -> Any:
        return tree.jacobian(x, TREE_FRAME)

    rows = [
        Row(
            "poekin tree.jacobian",
            time_loop(jacobian, rows_q, repeats, budget) if k == 0 else None,
            time_batch(jacobian, qpos[:size], size, repeats),
            "vectorised",
        )
        for k, size in enumerate(sizes["batches"])
    ]
    data, body = mujoco.MjData(m), m.body(TREE_FRAME).id
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))

    def timed(x: FloatArray) -> None:
        data.qpos[:] = x
        mujoco.mj_kinematics(m, data)
        mujoco.mj_comPos(m, data)
        mujoco.mj_jacBody(m, data, jacp, jacr, body)

    def full(x: FloatArray) -> FloatArray:
        timed(x)
        return np.vstack([jacr, jacp])

    row = Row("mujoco mj_jacBody", time_loop(timed, rows_q, repeats, budget), None, "loop")
    row.batch = time_loop(timed, list(qpos[: sizes["loop"]]), repeats, budget)
    agreement(row, full, qpos[:50], tree.jacobian(qpos[:50], TREE_FRAME))
    rows.append(row)
    add_ratios(rows, "poekin tree.jacobian")
    return rows


def run(sizes: dict[str, Any], repeats: int, seed: int) -> list[Row]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        loaded = poekin.load_model(ROBOT)
    chain = poekin.load(loaded, SITE)
    q = np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, (sizes["n"], chain.n_joints))
    rows_q = list(q[: sizes["single"]])
    budget = 1.0 if sizes is FULL else 0.1
    rows: list[Row] = []
    for name in ("world", "space", "body"):
        method = getattr(chain, f"jacobian_{name}")
        for k, size in enumerate(sizes["batches"]):
            single = (
                time_loop(method, rows_q, repeats, budget) if name == "world" and k == 0 else None
            )
            batch = time_batch(method, q[:size], size, repeats)
            rows.append(Row(f"poekin chain.jacobian_{name}", single, batch, "vectorised"))
    expected = chain.jacobian_world(q[:50])
    Make = Callable[[], tuple[Callable[[Any], Any], Callable[[Any], Any], str]]
    competitors: list[tuple[str, Make]] = [
        ("mujoco mj_jacSite", lambda: (*mujoco_jacobian(loaded, chain), "")),
        ("pinocchio computeFrameJacobian", lambda: pinocchio_jacobian(loaded)),
    ]
    for name, make in competitors:
        try:
            timed, full, note = make()
        except ImportError as e:
            rows.append(Row(name, note=f"not installed ({e.name}): pip install -e '.[bench]'"))
            continue
        loop = list(q[: sizes["loop"]])
        row = Row(name, time_loop(timed, rows_q, repeats, budget), None, "loop", note=note)
        row.batch = time_loop(timed, loop, repeats, budget)
        agreement(row, full, q[:50], expected)
        rows.append(row)
    add_ratios(rows, "poekin chain.jacobian_world")
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny sizes, seconds (for CI)")
    parser.add_argument("--repeats", type=int, default=7, help="repeats per measurement (7)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (0)")
    parser.add_argument("--json", metavar="PATH", type=pathlib.Path, help="write results here")
    args = parser.parse_args(argv)
    sizes = QUICK if args.quick else FULL
    repeats = min(args.repeats, 3) if args.quick else args.repeats
    info = machine_info()
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} cores; "
        f"medians and IQR over {repeats} repeats"
    )
    rows = run(sizes, repeats, args.seed)
    print_table(f"UR5e Jacobian of {SITE} (ratio = time / poekin jacobian_world's)", rows)
    trees = tree_rows(sizes, repeats, args.seed)
    print_table(f"{TREE} Jacobian of {TREE_FRAME}, 18 qvel columns (ratio = / poekin's)", trees)
    if args.json:
        results = {"machine": info, "rows": rows, "tree_rows": trees}
        args.json.write_text(json.dumps(to_json(results), indent=1))
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
