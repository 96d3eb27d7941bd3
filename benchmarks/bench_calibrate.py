"""The calibration benchmark (issue #22): time per calibration and accuracy on a known truth.

The truth is a robot made by MuJoCo from a perturbed model (:func:`poekin.calibration.simulate.
simulate_robot`: bodies moved ~1 mm and turned ~2 mrad, joint axes tilted ~2 mrad, anchors
moved ~1 mm, the tool moved and turned, encoder offsets of ~10 mrad, measured from a frame
2 m away turned at random), measured with Gaussian noise per axis. Each calibration is judged
on 300 held-out configurations against the noise-free truth (RMS and max of the position error
norm and of the orientation angle). One run reports:

* the time of ``poekin.calibrate`` on the UR5e, 50 poses, as a user calls it (the report, the
  workspace prediction and the 5-fold held-out residual included; also without the folds):
  median and interquartile range of wall and CPU time (a shared machine's wall time waits for
  a core; the CPU's name and vector width are printed first, as ``bench_fk.py`` does);
* accuracy against the number of poses (10, 20, 50, 100; noise 0.1 mm / 0.1 mrad) and the noise
  level (0 to 0.5 mm / mrad; 50 poses), each the mean over draws, beside the error predicted
  from the standard errors (``Calibration.predicted``, over the workspace)
  and a plain maximum-likelihood fit of a complete model (``tests/calibration_helpers.
  plain_fit``, SciPy) where that one is run: the ratio is ours over it;
* positions only (a target 5 cm off the flange) and a 7R arm (the FR3);
* the identifiable counts, and Monte-Carlo z-scores of the fitted corrections (their RMS is 1
  when the standard errors are honest; 200 runs).

No figure is asserted here; ``tests/calibration/test_calibration_fit.py`` asserts the issue's goals.

examples:
  python benchmarks/bench_calibrate.py --quick         # seconds; what CI runs
  python benchmarks/bench_calibrate.py --json calibrate.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from bench_fk import machine_info, to_json  # noqa: E402  (the FK benchmark's machine report)
from calibration_helpers import plain_fit  # noqa: E402  (the independent reference fit)

import poekin  # noqa: E402
from poekin import lie  # noqa: E402
from poekin.calibration import calibrate  # noqa: E402
from poekin.calibration.simulate import simulate_robot  # noqa: E402
from poekin.verification.verify import pose_errors  # noqa: E402

ROBOT = "universal_robots_ur5e"
SIGMA = 1e-4


@dataclasses.dataclass(frozen=True)
class Sizes:
    """How much to run; ``--quick`` shrinks everything so CI runs it in seconds."""

    repeats: int = 40  # timing repeats
    poses: tuple[int, ...] = (10, 20, 50, 100)
    noise: tuple[float, ...] = (0.0, 0.05e-3, 0.1e-3, 0.2e-3, 0.5e-3)
    draws: int = 8  # robots and noise draws per accuracy cell
    plain_draws: int = 4  # of which also fitted by the plain reference (slow: SciPy, numeric)
    test_poses: int = 300
    monte_carlo: int = 200


QUICK = Sizes(
    repeats=5,
    poses=(10, 50),
    noise=(0.0, 0.1e-3),
    draws=1,
    plain_draws=1,
    test_poses=50,
    monte_carlo=8,
)


def _configurations(chain: poekin.Chain, n: int, rng: np.random.Generator) -> np.ndarray:
    assert chain.limits is not None
    lim = np.clip(chain.limits, -np.pi, np.pi)
    return rng.uniform(lim[:, 0], lim[:, 1], (n, chain.n_joints))


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


def _load(robot: str) -> poekin.Chain:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load(robot)


def _simulate(robot: str, seed: int, target: np.ndarray | None = None) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return simulate_robot(robot, seed=seed, target=target)


# --- timing ---------------------------------------------------------------------------------


def timing(sizes: Sizes) -> dict[str, Any]:
    """``calibrate`` on the UR5e with 50 poses: wall and CPU time, median and IQR."""
    chain = _load(ROBOT)
    sim = _simulate(ROBOT, 1)
    q = _configurations(chain, 50, np.random.default_rng(1))
    measured = sim.measure(q, noise_m=SIGMA, noise_rad=SIGMA, seed=1)
    out = {}
    for folds in (0, 5):
        calibrate(chain, q, measured, folds=folds)  # warm up (the structure is analysed once)
        wall, cpu = [], []
        for _ in range(sizes.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            calibrate(chain, q, measured, folds=folds)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        out[f"folds={folds}"] = {
            "wall_ms": [float(t) * 1e3 for t in np.percentile(wall, [25, 50, 75])],
            "cpu_ms": [float(t) * 1e3 for t in np.percentile(cpu, [25, 50, 75])],
        }
    return out


# --- accuracy -------------------------------------------------------------------------------


def trial(
    robot: str, n: int, noise: float, seed: int, test: int, *, plain: bool, positions: bool = False
) -> dict[str, float]:
    """One draw: simulate, calibrate (and the plain fit), judge on held-out configurations."""
    chain = _load(robot)
    target = None
    if positions:
        target = np.eye(4)
        target[:3, 3] = [0.03, 0.05, 0.04]
    sim = _simulate(robot, seed, target)
    rng = np.random.default_rng(1000 + seed)
    q, q_test = _configurations(chain, n, rng), _configurations(chain, test, rng)
    measured = sim.measure(q, noise_m=noise, noise_rad=noise, positions=positions, seed=seed)
    truth = sim.poses(q_test)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.errors.CalibrationWarning)
        result = calibrate(chain, q, measured, folds=0)
    pos, ori = pose_errors(truth, result.chain.fk(q_test))
    row = {
        "pos_rms_m": _rms(pos),
        "pos_max_m": float(pos.max()),
        "ori_rms_rad": _rms(ori),
        "predicted_pos_rms_m": result.predicted.workspace_m,
        "identifiable": result.identifiable,
    }
    if plain and noise > 0:
        fk = plain_fit(chain.screws, chain.home, chain.joint_types, q, measured, noise, noise)
        pos_p, ori_p = pose_errors(truth, fk(q_test))
        row |= {"plain_pos_rms_m": _rms(pos_p), "plain_ori_rms_rad": _rms(ori_p)}
    return row


def cell(
    robot: str, n: int, noise: float, sizes: Sizes, *, positions: bool = False
) -> dict[str, float]:
    """Mean over draws of :func:`trial`; the plain fit's ratio over the draws that ran it."""
    rows = [
        trial(
            robot, n, noise, s, sizes.test_poses, plain=s < sizes.plain_draws, positions=positions
        )
        for s in range(sizes.draws)
    ]
    means = ("pos_rms_m", "ori_rms_rad", "predicted_pos_rms_m")
    out = {k: float(np.mean([r[k] for r in rows])) for k in means}
    out["pos_max_m"] = max(r["pos_max_m"] for r in rows)
    out["identifiable"] = min(r["identifiable"] for r in rows)
    plain = [r for r in rows if "plain_pos_rms_m" in r]
    if plain:
        out["ratio_pos"] = float(np.mean([r["pos_rms_m"] / r["plain_pos_rms_m"] for r in plain]))
        out["ratio_ori"] = float(
            np.mean([r["ori_rms_rad"] / r["plain_ori_rms_rad"] for r in plain])
        )
    return out


def z_scores(sizes: Sizes) -> dict[str, float]:
    """Monte-Carlo z-scores of the fitted corrections (UR5e, 50 poses, 0.1 mm / 0.1 mrad): the
    truth in the model's own gauge is the fit of the noise-free poses."""
    chain = _load(ROBOT)
    sim = _simulate(ROBOT, 5)
    q = _configurations(chain, 50, np.random.default_rng(7))
    exact = calibrate(chain, q, sim.poses(q), folds=0)
    free = list(exact.model.free)
    keys = [exact.model.params[k].key for k in free]
    z = []
    for run in range(sizes.monte_carlo):
        measured = sim.measure(q, noise_m=SIGMA, noise_rad=SIGMA, seed=10_000 + run)
        result = calibrate(chain, q, measured, folds=0)
        std = result.std()
        err = result.state.x[free] - exact.state.x[free]
        err[:3] = lie.log_so3(result.base[:3, :3] @ exact.base[:3, :3].T)
        err[3:6] = result.base[:3, 3] - exact.base[:3, 3]
        z.append(err / np.array([std[k] for k in keys]))
    per = np.sqrt(np.mean(np.array(z) ** 2, axis=0))
    return {
        "runs": sizes.monte_carlo,
        "rms": _rms(np.array(z)),
        "per_parameter_min": float(per.min()),
        "per_parameter_max": float(per.max()),
    }


def counts() -> dict[str, int]:
    from poekin.calibration import model_of

    out = {}
    for robot in (ROBOT, "universal_robots_ur10e", "franka_fr3"):
        chain = _load(robot)
        for measure in ("pose", "position"):
            out[f"{robot} {measure}"] = len(model_of(chain, measure).free)  # type: ignore[arg-type]
    return out


# --- report ---------------------------------------------------------------------------------


def _mm(x: float) -> str:
    """Millimetres (milliradians) with 4 decimals, or 3 significant digits below 1e-4."""
    return f"{x * 1e3:.4f}" if x >= 1e-7 else f"{x * 1e3:.3g}"


def _table(
    title: str, rows: list[tuple[str, dict[str, float]]], *, orientation: bool = True
) -> None:
    print(f"\n{title}")
    head = ("pos RMS mm", "predicted", "pos max mm", "ori RMS mrad", "ident.", "vs plain")
    print(
        f"  {'':>22}  {head[0]:>10}  {head[1]:>10}  {head[2]:>10}  {head[3]:>12}  {head[4]:>6}  "
        f"{head[5] + ' (pos, ori)':>20}"
    )
    for label, r in rows:
        ratio = f"{r['ratio_pos']:.3f}, {r['ratio_ori']:.3f}" if "ratio_pos" in r else "-"
        ori = _mm(r["ori_rms_rad"]) if orientation else "-"
        if not orientation and "ratio_pos" in r:
            ratio = f"{r['ratio_pos']:.3f}, -"
        print(
            f"  {label:>22}  {_mm(r['pos_rms_m']):>10}  {_mm(r['predicted_pos_rms_m']):>10}  "
            f"{_mm(r['pos_max_m']):>10}  {ori:>12}  {r['identifiable']:>6}  {ratio:>20}"
        )


def parse_args(argv: Sequence[str] | None) -> tuple[argparse.Namespace, Sizes]:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--quick", action="store_true", help="a tiny run (CI)")
    p.add_argument("--json", type=pathlib.Path, help="write the results as JSON")
    args = p.parse_args(argv)
    return args, QUICK if args.quick else Sizes()


def main(argv: Sequence[str] | None = None) -> int:
    args, sizes = parse_args(argv)
    t0 = time.perf_counter()
    machine = machine_info()
    print(
        f"{machine['cpu']}, {machine['vector_width']}, {machine['usable_cores']} cores, "
        f"load {machine['load_average']}"
    )
    times = timing(sizes)
    print(f"\npoekin.calibrate, UR5e, 50 poses (medians of {sizes.repeats}; IQR):")
    for label, t in times.items():
        w, c = t["wall_ms"], t["cpu_ms"]
        print(
            f"  {label}: {w[1]:.1f} ms wall ({w[0]:.1f}-{w[2]:.1f}), {c[1]:.1f} ms CPU "
            f"({c[0]:.1f}-{c[2]:.1f})"
        )
    run: Callable[..., dict[str, float]] = cell
    by_poses = [(f"{n} poses", run(ROBOT, n, SIGMA, sizes)) for n in sizes.poses]
    _table("UR5e, noise 0.1 mm / 0.1 mrad, by number of poses (held-out vs truth)", by_poses)
    by_noise = [(f"noise {s * 1e3:g} mm, mrad", run(ROBOT, 50, s, sizes)) for s in sizes.noise]
    _table("UR5e, 50 poses, by noise", by_noise)
    others = [
        ("UR5e positions", run(ROBOT, 50, SIGMA, sizes, positions=True)),
        ("FR3 (7R) poses", run("franka_fr3", 50, SIGMA, sizes)),
    ]
    _table("positions only (a target off the flange), 50 poses", others[:1], orientation=False)
    _table("a 7R arm, 50 poses", others[1:])
    identifiable = counts()
    print("\nidentifiable parameters (4R + 2P + 6; 3 fewer for positions):")
    for k, v in identifiable.items():
        print(f"  {k}: {v}")
    z = z_scores(sizes)
    print(
        f"\nz-scores of the fitted corrections, {z['runs']} Monte-Carlo runs: RMS {z['rms']:.3f} "
        f"(per parameter {z['per_parameter_min']:.2f} to {z['per_parameter_max']:.2f})"
    )
    elapsed = time.perf_counter() - t0
    print(f"\nbenchmark wall time {elapsed:.1f} s")
    if args.json:
        result = {
            "machine": machine,
            "sizes": sizes,
            "timing": times,
            "by_poses": dict(by_poses),
            "by_noise": dict(by_noise),
            "others": dict(others),
            "identifiable": identifiable,
            "z_scores": z,
            "wall_s": elapsed,
        }
        args.json.write_text(json.dumps(to_json(result), indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
