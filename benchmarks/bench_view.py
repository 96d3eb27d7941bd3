"""How fast ``poekin view`` answers: a slider move server-side, and the start to a usable page.

1. **Slider update**: the time from setting ``viewer.q`` to every scene update sent (poses of
   every body, screw axis, PoE step and frame, the panel's readouts, then a flush to the
   websocket), for the UR5e (meshes) and the go2 (floating base, stand-in), with a Chromium page
   connected (Playwright, if installed) or none. Median and spread over distinct q.
2. **Start to usable page**: from launching ``poekin view --no-browser`` to (a) its URL line and
   (b) a Chromium page (already running) showing the joint sliders, median over runs.

Goal (issue 17): a slider update within 20 ms, a usable page within 2 s.

    python benchmarks/bench_view.py            # 300 updates, 5 starts
    python benchmarks/bench_view.py --quick    # CI: a few of each, so it cannot rot
"""

from __future__ import annotations

import argparse
import os
import pathlib
import platform
import socket
import subprocess
import sys
import time
import warnings
from typing import Any

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from bench_fk import machine_info  # the CPU, its vector width, the cores

import poekin
from poekin.viewer.app import HEADLESS_CHROMIUM as CHROMIUM
from poekin.viewer.app import HEADLESS_CHROMIUM_ARGS as ARGS
from poekin.viewer.app import view


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


def updates(robot: str, n: int, pw: Any) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        viewer = view(robot, port=0, open_browser=False)
    viewer.wait_geometry()
    tree = viewer.subject.tree
    assert tree is not None
    qs = poekin.sample_qpos(tree, n + 10, seed=0, within_limits=True)
    browser = page = None
    if pw is not None:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page()
        page.goto(viewer.url)
        page.wait_for_selector("canvas", timeout=120_000)
        page.get_by_text("geometry: ").first.wait_for(timeout=120_000)
    times = []
    for k, q in enumerate(qs):
        t = time.perf_counter()
        viewer.q = q  # computes, poses every node, writes the readouts, flushes
        if k >= 10:  # the first few warm caches
            times.append(time.perf_counter() - t)
    nodes = len(viewer.node_names()) - len(viewer.node_names("part"))
    client = "a Chromium page connected" if page is not None else "no page connected"
    print(f"  {robot:22} {_ms(times)}  ({n} updates, {nodes} nodes, {client})")
    if browser is not None:
        browser.close()
    viewer.close()


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
    print("start to usable page:")
    starts("universal_robots_ur5e", n_starts, pw)
    if pw is not None:
        pw.stop()


if __name__ == "__main__":
    main()
