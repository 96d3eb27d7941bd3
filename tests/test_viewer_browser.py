"""``poekin view`` in a real browser: the system Chromium (Debian's ``chromium``, WebGL in
software) driven by Playwright, against the command itself on a free loopback port.

Skipped without Playwright or /usr/bin/chromium, unless POEKIN_REQUIRE_BROWSER=1 (CI), which
turns the skip into a failure, as POEKIN_REQUIRE_COMPILED does for the kernel.
"""

from __future__ import annotations

import io
import os
import re
import socket
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import matplotlib.image as mimage
import numpy as np
import pytest
from helpers import assert_close, mesh_menagerie

import poekin
from poekin.viewer.app import HEADLESS_CHROMIUM as CHROMIUM
from poekin.viewer.app import HEADLESS_CHROMIUM_ARGS as CHROMIUM_ARGS

pytestmark = pytest.mark.slow  # a browser per module, WebGL in software: seconds a page

TIMEOUT_MS = 60_000  # WebGL in software on a shared machine is slow


def _need_browser() -> Any:
    required = os.environ.get("POEKIN_REQUIRE_BROWSER") == "1"
    why = ""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        why = "playwright is not installed (pip install playwright)"
    if not why and not os.path.exists(CHROMIUM):
        why = f"{CHROMIUM} is missing (apt-get install chromium)"
    if why and required:
        pytest.fail(f"POEKIN_REQUIRE_BROWSER=1 but {why}")
    if why:
        pytest.skip(why)
    pytest.importorskip("viser")
    return sync_playwright


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    sync_playwright = _need_browser()
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def serve() -> Iterator[Any]:
    """Start ``poekin view --no-browser --port N ...``; stop it with Ctrl-C afterwards."""
    procs: list[subprocess.Popen[str]] = []

    def start(*argv: str) -> str:
        port = _free_port()
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "poekin.cli",
                "view",
                "--no-browser",
                "--port",
                str(port),
                *argv,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        procs.append(proc)
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith(f"poekin view: http://127.0.0.1:{port}"), proc.stderr.read()  # type: ignore[union-attr]
        return f"http://127.0.0.1:{port}"

    yield start
    for proc in procs:
        proc.send_signal(2)
        proc.communicate(timeout=60)
        assert proc.returncode == 130


class Page:
    """A page of the viewer, with what it logged and fetched."""

    def __init__(self, browser: Any, url: str) -> None:
        self.page = browser.new_page(viewport={"width": 1280, "height": 800})
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.on("request", lambda r: self.requests.append(r.url))
        self.page.set_default_timeout(TIMEOUT_MS)
        self.page.goto(url)
        self.page.wait_for_selector("canvas")

    def tab(self, name: str) -> None:
        self.page.get_by_role("tab", name=name).click()

    def number_box(self, label: str) -> Any:
        """The number box beside the slider labelled ``label``."""
        target = self.page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$"))
        uuid = target.first.get_attribute("for")
        return self.page.locator(f"[id='{uuid}']").locator("xpath=..").locator("input[type=text]")

    def choose(self, label: str, option: str) -> None:
        self.page.get_by_label(label, exact=True).click()
        self.page.get_by_role("option", name=option, exact=True).click()

    def text_with(self, pattern: str) -> str:
        """The visible text of the panel once it matches ``pattern``."""
        locator = self.page.get_by_text(re.compile(pattern)).first
        locator.wait_for()
        return str(self.page.inner_text("body"))


def _printed_T(text: str, frame: str) -> np.ndarray:
    after = text.split(f"T(q) = T_world_{frame}")[1]
    rows = [ln for ln in after.splitlines() if re.fullmatch(r"\s*(-?\d+\.\d{6}\s*){4}", ln)]
    return np.array([[float(x) for x in ln.split()] for ln in rows[:4]])


def test_ur5e_page_slider_readout_forms_and_poe_steps(
    browser: Any, serve: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The complete UR5e, meshes drawn (the tests' copy has none)."""
    monkeypatch.setenv("MENAGERIE_ROOT", str(mesh_menagerie()))
    page = Page(browser, serve("universal_robots_ur5e"))
    chain = poekin.load("universal_robots_ur5e")
    page.text_with("geometry: the model's 20 meshes")
    # move a joint through the page's own control: the number box of its slider
    box = page.number_box("shoulder_lift_joint")
    box.fill("-1.2")
    box.press("Enter")
    page.tab("T(q) & J")
    q = np.array([0.0, -1.2, 0.0, 0.0, 0.0, 0.0])
    expected = chain.fk(q)
    printed = None
    for _ in range(60):  # the page updates when the server's reply arrives
        text = page.text_with(r"T\(q\) = T_world_attachment_site")
        printed = _printed_T(text, "attachment_site")
        if printed.shape == (4, 4) and np.max(np.abs(printed - expected)) <= 5e-7:
            break
        page.page.wait_for_timeout(500)
    assert printed is not None
    assert_close("T(q) on the page", printed, expected, 5e-7)  # printed with 6 decimals
    # the body form and the PoE step, through their controls
    page.tab("Screws & PoE")
    page.choose("form", "body (B_i)")
    page.page.get_by_role("cell", name="B1", exact=True).wait_for()  # the screw table
    step = page.number_box("PoE step k")
    step.fill("2")
    step.press("Enter")
    text = page.text_with(r"PoE step k = 2 of 6")
    assert "T2 = M · e^[B1]q1 · e^[B2]q2" in text
    # a picture: the canvas is drawn, not blank
    png = page.page.locator("canvas").first.screenshot()
    img = mimage.imread(io.BytesIO(png))[..., :3]
    assert img.std() > 0.05
    dark = np.mean(img.mean(axis=-1) < 0.45)  # the robot and its axes on a light scene
    assert dark > 0.002, dark
    assert page.errors == []
    assert all(
        u.startswith(("http://127.0.0.1", "ws://127.0.0.1", "data:", "blob:"))
        for u in page.requests
    ), page.requests
    page.page.close()


def test_params_page_lists_the_base_rotation(browser: Any, serve: Any) -> None:
    page = Page(browser, serve("--params", "lynch-park-ur5"))
    page.tab("Compare")
    text = page.text_with(r"base frame: yours is turned 180\.0 deg")
    assert "lynch-park-ur5 vs universal_robots_ur5e / attachment_site: MISMATCH" in text
    assert page.errors == []
    page.page.close()
