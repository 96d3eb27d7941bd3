"""The UR5e forward-kinematics lab, end to end, with poekin.

1. Derive the space-frame screw axes S_i and home pose M from the Menagerie UR5e.
2. Verify space-form PoE against MuJoCo's mj_forward on 1000 random q in [-2 pi, 2 pi]^6:
   max and median position (m) and orientation (rad) errors.
3. Draw the error distribution and log a metrics row per metric.
4. Side quest: the body form T = M e^[B1]q1 ... e^[Bn]qn, with B_i = Ad(M^-1) S_i, gives the
   same poses.

Run:  MENAGERIE_ROOT=../shared/menagerie python examples/ur5e_lab.py --out lab_output
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

import poekin
from poekin.verification.metrics import append_metrics, metric_rows, new_run_id, sha256_files
from poekin.verification.plotting import plot_errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="lab_output", help="folder for the figure and metrics")
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    # 1. Parameters from the model, never typed by hand.
    loaded = poekin.load_model("universal_robots_ur5e")
    chain = poekin.load(loaded)  # frame: the model's only site, attachment_site
    np.set_printoptions(precision=4, suppress=True)
    print("S (space frame, rows [w; v]):\n", chain.screws)
    print("M = T_world_attachment_site(q = 0):\n", chain.home)

    # 2. Verification against mj_forward (space and body PoE).
    report = poekin.verify(loaded, samples=args.samples, seed=0)
    for method, stats in report.per_method().items():
        print(method, {k: f"{v:.2e}" for k, v in stats.items()})
    print("passed:", report.passed)

    # 3. The figure and the metrics rows.
    run_id = new_run_id()
    figure = plot_errors(
        report.pos_err,
        report.ori_err,
        title=f"UR5e attachment_site: PoE vs mj_forward, {report.samples} samples",
        path=out / f"fk_errors_{run_id}.png",
        pos_tol=report.pos_tol,
        ori_tol=report.ori_tol,
    )
    rows = metric_rows(
        report,
        experiment="fk_verify_ur5e",
        model_sha=sha256_files(loaded.files, loaded.xml_path.parent),
        notes="examples/ur5e_lab.py",
        run_id=run_id,
    )
    metrics = append_metrics(out / "metrics.csv", rows)
    print(f"figure: {figure}\nmetrics: {metrics} (+{len(rows)} rows)")

    # 4. Side quest: body-frame PoE. Same poses; the screws are expressed in the end frame.
    print("B (body frame, rows [w; v]):\n", chain.body_screws)
    q = poekin.sample_joint_values(chain, 5, seed=1)
    gap = np.abs(chain.fk(q) - chain.fk_body(q)).max()
    print(f"max |T_space - T_body| over 5 random q: {gap:.1e}")
    print("the named constants agree too:", np.allclose(poekin.fk_ur5e_poe(q), chain.fk(q)))


if __name__ == "__main__":
    try:
        main()
    except poekin.PoekinError as e:
        sys.exit(f"ur5e_lab: {e}")
