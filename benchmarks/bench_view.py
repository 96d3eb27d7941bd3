"""How fast ``poekin view`` answers: a slider move server-side, and the start to a usable page.

1. **Slider update**: the time from setting ``viewer.q`` to every scene update sent (poses of
   every body, screw axis, PoE step and frame, the panel's readouts, then a flush to the
   websocket), for the UR5e (meshes) and the go2 (floating base, stand-in), with a Chromium page
   connected (Playwright, if installed) or none. Median and spread over distinct q.
2. **IK drag update**: the time from a new pose of the IK target handle to every scene update
   sent (``viewer.set_target``: the solve from the configuration shown, the closed-form
   solutions and their ghosts, every node posed, the readouts, the flush), along a drag path of
   small steps; and the solve alone (:func:`poekin.viewer.ik.reach`: ``Chain.ik`` or
   ``Tree.ik`` from the configuration shown, then ``ik_all``), and ``chain.ik`` alone; then a
   target out of reach (the restarts before the best fit). The UR5e (meshes, 8 ghosts) and the
   go2's leg (position only, no closed form).
3. **Start to usable page**: from launching ``poekin view --no-browser`` to (a) its URL line and
   (b) a Chromium page (already running) showing the joint sliders, median over runs.

Goal (issue 17): a slider update within 20 ms, a usable page within 2 s; issue 21: IK at an
interactive rate while dragging.

    python benchmarks/bench_view.py            # 300 updates, 5 starts
    python benchmarks/bench_view.py --quick    # CI: a few of each, so it cannot rot
"""

from __future__ import annotations

import argparse
import contextlib
import os
import pathlib
import platform
import socket
import subprocess
import sys
import time
import warnings
from collections.abc import Iterator
from typing import Any

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info  # the CPU, its vector width, the cores

import poekin
from poekin.viewer.app import HEADLESS_CHROMIUM as CHROMIUM
from poekin.viewer.app import HEADLESS_CHROMIUM_ARGS as ARGS
from poekin.viewer.app import view
from poekin.viewer.ik import reach


def _browser() -> Any:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return None
    if not os.path.exists(CHROMIUM):
        return None
    return sync_playwright().start()


def _ms(values: list[float]) -> str:
    q = np.percentile(values, [10, 50, 90]) * 1e3
    return f"median {q[1]:6.2f} ms  (10%-90%: {q[0]:.2f}-{q[2]:.2f})"


@contextlib.contextmanager
def _viewer(robot: str, pw: Any) -> Iterator[tuple[Any, bool]]:
    """``poekin view``'s viewer of ``robot`` with its geometry sent, and whether a Chromium
    page (Playwright ``pw``, if given) is connected to it and showing the scene."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        viewer = view(robot, port=0, open_browser=False)
    viewer.wait_geometry()
    browser = None
    try:
        if pw is not None:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page()
            page.goto(viewer.url)
            page.wait_for_selector("canvas", timeout=120_000)
            page.get_by_text("geometry: ").first.wait_for(timeout=120_000)
        yield viewer, browser is not None
    finally:
        if browser is not None:
            browser.close()
        viewer.close()


def updates(robot: str, n: int, pw: Any) -> None:
    with _viewer(robot, pw) as (viewer, connected):
        _updates(viewer, robot, n, connected)


def _updates(viewer: Any, robot: str, n: int, connected: bool) -> None:
    tree = viewer.subject.tree
    assert tree is not None
    qs = poekin.sample_qpos(tree, n + 10, seed=0, within_limits=True)
    times = []
    for k, q in enumerate(qs):
        t = time.perf_counter()
        viewer.q = q  # computes, poses every node, writes the readouts, flushes
        if k >= 10:  # the first few warm caches
            times.append(time.perf_counter() - t)
    nodes = len(viewer.node_names()) - len(viewer.node_names("part"))
    client = "a Chromium page connected" if connected else "no page connected"
    print(f"  {robot:22} {_ms(times)}  ({n} updates, {nodes} nodes, {client})")


def _us(values: list[float]) -> str:
    q = np.percentile(values, [10, 50, 90]) * 1e6
    return f"median {q[1]:6.0f} us  (10%-90%: {q[0]:.0f}-{q[2]:.0f})"


def ik_updates(robot: str, n: int, pw: Any) -> None:
    with _viewer(robot, pw) as (viewer, connected):
        _ik_updates(viewer, robot, n, connected)


def _ik_updates(viewer: Any, robot: str, n: int, connected: bool) -> None:
    subject = viewer.subject
    tree = subject.tree
    assert tree is not None
    # a drag: the end frame's poses along a path of small joint steps, from qpos0 with the
    # chain's joints in the middle of their limits
    lo, hi = np.clip(subject.chain.limits.T, -np.pi, np.pi)
    slots = list(subject.chain.qpos_indices or ())
    path = np.tile(subject.qpos0, (n + 11, 1))
    steps = np.linspace(0.0, 1.0, n + 11)[:, None]
    path[:, slots] = lo + (hi - lo) * (0.35 + 0.3 * steps)
    targets = [tree.pose(x, subject.frame) for x in path]
    viewer.q = path[0]
    viewer.set_option("IK target", True)
    updates, solves, alone = [], [], []
    position_only = bool(viewer.options()["position only"])
    for k, T in enumerate(targets[1:]):
        x = viewer.q
        t = time.perf_counter()
        reach(subject, x, T, position_only=position_only)
        t1 = time.perf_counter()
        tree.ik(T, subject.frame, x, warm_start=True, position_only=position_only, max_attempts=1)
        t2 = time.perf_counter()
        viewer.set_target(T)  # solves again, poses every node, flushes
        t3 = time.perf_counter()
        if k >= 10:  # the first few warm caches
            solves.append(t1 - t)
            alone.append(t2 - t1)
            updates.append(t3 - t2)
    shown = viewer.reach
    assert shown is not None and shown.success, "the drag path left the arm's reach"
    ghosts = len(shown.ghosts)
    far = []
    for T in targets[-min(n, 10) :]:
        out = T.copy()
        out[:3, 3] = 3.0 * T[:3, 3] + [1.0, 1.0, 1.0]  # well out of reach
        t = time.perf_counter()
        viewer.set_target(out)
        far.append(time.perf_counter() - t)
    client = "a Chromium page connected" if connected else "no page connected"
    print(f"  {robot:22} update {_ms(updates)}  ({n} drag steps, {ghosts} ghosts, {client})")
    print(f"  {'':22} the solve {_us(solves)}; Tree.ik alone (first attempt) {_us(alone)}")
    print(f"  {'':22} out of reach: update {_ms(far)}")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def starts(robot: str, n: int, pw: Any) -> None:
    url_times, page_times = [], []
    browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS) if pw is not None else None
    for _ in range(n):
        port = _free_port()
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "poekin.cli",
                "view",
                robot,
                "--no-browser",
                "--port",
                str(port),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        assert proc.stdout is not None
        proc.stdout.readline()
        url_times.append(time.perf_counter() - t0)
        if browser is not None:
            page = browser.new_page()
            page.goto(f"http://127.0.0.1:{port}")
            page.get_by_role("slider").first.wait_for(timeout=120_000)
            page_times.append(time.perf_counter() - t0)
            page.close()
        proc.send_signal(2)
        proc.communicate(timeout=60)
    print(f"  {robot:22} URL printed: {_ms(url_times)}")
    if page_times:
        print(f"  {robot:22} sliders on the page: {_ms(page_times)} (Chromium, WebGL in software)")
    if browser is not None:
        browser.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a few runs (CI)")
    parser.add_argument("--no-browser", action="store_true", help="no Chromium page")
    args = parser.parse_args()
    n_updates, n_starts = (20, 1) if args.quick else (300, 5)
    pw = None if args.no_browser else _browser()
    info = machine_info()
    print(
        f"{info['cpu']}, {info['vector_width']}, {info['usable_cores']} cores, "
        f"Python {platform.python_version()}"
    )
    print("slider update, server-side (set q -> every update sent):")
    for robot in ("universal_robots_ur5e", "unitree_go2"):
        updates(robot, n_updates, pw)
        if pw is not None and not args.quick:
            updates(robot, n_updates, None)
    print("IK drag update, server-side (new target pose -> every update sent):")
    for robot in ("universal_robots_ur5e", "unitree_go2"):
        ik_updates(robot, n_updates, pw)
    print("start to usable page:")
    starts("universal_robots_ur5e", n_starts, pw)
    if pw is not None:
        pw.stop()


if __name__ == "__main__":
    main()
