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

    def text_box(self, label: str) -> Any:
        """The text box of the row labelled ``label``."""
        target = self.page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$"))
        row = target.first.locator("xpath=ancestor::div[contains(@class, 'mantine-Flex-root')][1]")
        return row.locator("input")

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


def _slider_values(page: Page, joints: tuple[str, ...]) -> np.ndarray:
    return np.array([float(page.number_box(j).input_value()) for j in joints])


def _wait_sliders(page: Page, joints: tuple[str, ...], q: np.ndarray) -> np.ndarray:
    """The joint sliders' number boxes once they show ``q`` (to their 4 decimals)."""
    shown = _slider_values(page, joints)
    for _ in range(60):  # the page updates when the server's messages arrive
        if np.max(np.abs(shown - q)) <= 1e-4:
            break
        page.page.wait_for_timeout(250)
        shown = _slider_values(page, joints)
    return shown


def _gizmo_square(page: Page) -> tuple[float, float]:
    """Where the target handle's red plane square is drawn (the densest patch of its red,
    left of the panel), once two screenshots agree on it."""
    last = None
    for _ in range(40):
        png = page.page.locator("canvas").first.screenshot()
        img = mimage.imread(io.BytesIO(png))[..., :3] * 255
        red = (img[..., 0] > 200) & (img[..., 1] < 80) & (img[..., 2] > 60) & (img[..., 2] < 140)
        red[:, 860:] = False  # the panel
        ys, xs = np.nonzero(red)
        if len(xs) > 50:
            bins = [np.arange(0, 871, 10), np.arange(0, img.shape[0] + 10, 10)]
            H, xe, ye = np.histogram2d(xs, ys, bins=bins)
            i, j = np.unravel_index(np.argmax(H), H.shape)
            at = (float(xe[i] + 5), float(ye[j] + 5))
            if at == last:
                return at
            last = at
        page.page.wait_for_timeout(500)
    raise AssertionError("the target handle was not drawn")


def test_ik_target_drag_moves_the_sliders_and_an_unreachable_one_shows_its_residual(
    browser: Any,
) -> None:
    """The IK mode in the page: the target handle dragged with the mouse (the arm, its
    sliders and the panel follow); its pose set through the viewer's handle, the solved q read
    back from the page's sliders; an unreachable pose typed into the page's target box, the
    residual read from the panel."""
    from poekin.viewer.app import view

    with view("universal_robots_ur5e", port=0, open_browser=False) as v:
        chain = v.subject.chain
        joints = chain.joint_names
        q_start = np.array([0.5, -1.2, 1.5, -1.9, -1.5708, 0.0])
        v.q = q_start
        v.set_option("screw axes", False)
        v.set_option("ghost solutions", False)
        v.set_option("IK target", True)
        page = Page(browser, v.url)
        page.text_with(r"the target is at the end frame: drag it")
        # a drag of the handle's plane square: the handle moves, the solve follows it (each
        # move redraws the page in software: a few, long ones)
        x, y = _gizmo_square(page)
        mouse = page.page.mouse
        mouse.move(x, y)
        mouse.down()
        for k in range(1, 4):
            mouse.move(x - 20 * k, y - 12 * k)
        mouse.up()
        page.text_with(r"solved from the configuration shown")
        dragged = v.reach
        assert dragged is not None and dragged.success and dragged.how == "current"
        moved = np.linalg.norm(dragged.target[:3, 3] - chain.fk(q_start)[:3, 3])
        assert moved > 0.02, moved
        assert_close("dragged", chain.fk(dragged.qpos), dragged.target, 1e-10)
        assert_close("sliders", _wait_sliders(page, joints, v.q), v.q, 1e-4)
        # the handle's pose set through the viewer's handle
        q_goal = np.array([0.45, -1.05, 1.3, -0.7, 1.2, 0.5])
        shown = v.set_target(chain.fk(q_goal))
        assert shown.success
        assert_close("sliders", _wait_sliders(page, joints, shown.qpos), shown.qpos, 1e-4)
        assert_close("the solution", chain.fk(shown.qpos), chain.fk(q_goal), 1e-10)
        # an unreachable pose, through the page's own controls
        page.text_box("target").fill("0.9 -0.4 0.6 0 1 0 0")
        page.page.get_by_role("button", name="set target").click()
        text = page.text_with(r"UNREACHABLE")
        far = v.reach
        assert far is not None and not far.success
        words = f"{far.pos_err * 1e3:.4g} mm, {far.ori_err * 1e3:.4g} mrad"
        assert f"residual: {words}" in text, text
        pos, ori = poekin.pose_errors(far.target, chain.fk(far.qpos))
        assert abs(pos - far.pos_err) < 1e-12 and abs(ori - far.ori_err) < 1e-12
        assert far.pos_err > 0.1 and np.allclose(far.target[:3, 3], [0.9, -0.4, 0.6])
        assert_close("best fit", _wait_sliders(page, joints, far.qpos), far.qpos, 1e-4)
        assert page.errors == []
        page.page.close()
