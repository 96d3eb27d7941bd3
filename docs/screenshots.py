"""Make the three screenshots of ``poekin view`` that docs/viewer.md shows (README shows the
first)

    python docs/screenshots.py       # writes docs/view_ur5e.png, view_lynch_park.png, view_ik.png
    python docs/screenshots.py ik    # only those whose name contains "ik"

Each is a 1280 x 720 page, quantised to 256 colours to stay small.
"""

from __future__ import annotations

import pathlib
import sys
import warnings

from PIL import Image
from playwright.sync_api import Page, sync_playwright

import poekin
import poekin.viewer.app
from poekin import lie

HERE = pathlib.Path(__file__).resolve().parent
Q = [0.5, -1.2, 1.5, -1.9, -1.5708, 0.0]
# the IK target: the end frame at Q moved 6 cm and turned 0.3 rad, as a drag would
TARGET_MOVE = [0.04, -0.03, 0.03]
TARGET_TURN = [0.0, 0.3, 0.0]


def _shoot(
    page: Page, viewer: poekin.viewer.app.Viewer, tab: str | None, out: pathlib.Path
) -> None:
    """A screenshot of the page with ``tab`` open (None: the first, Joints)."""
    page.goto(viewer.url)
    page.wait_for_selector("canvas")
    page.get_by_text("geometry: the model's").first.wait_for(timeout=120_000)
    viewer.frame_view()
    if tab is not None:
        page.get_by_role("tab", name=tab).click()
    page.wait_for_timeout(45_000)  # software WebGL on a busy machine draws the labels last
    page.evaluate(  # the "software WebGL" notice
        "() => document.querySelectorAll('[class*=Notification]').forEach(e => e.remove())"
    )
    page.screenshot(path=str(out))
    Image.open(out).convert("RGB").quantize(256).save(out, optimize=True)
    print(f"{out}: {out.stat().st_size // 1024} KB")


def _ur5e(page: Page) -> None:
    with poekin.view("universal_robots_ur5e", port=0, open_browser=False) as v:
        v.q = Q
        v.wait_geometry()
        _shoot(page, v, "Screws & PoE", HERE / "view_ur5e.png")


def _lynch_park(page: Page) -> None:
    with poekin.view(
        "universal_robots_ur5e", params="lynch-park-ur5", port=0, open_browser=False
    ) as v:
        v.q = Q
        v.set_option("robot opacity", 0.35)
        v.wait_geometry()
        _shoot(page, v, "Compare", HERE / "view_lynch_park.png")


def _ik(page: Page) -> None:
    """The IK mode: the target handle moved from the end frame, the arm solved to it, the
    other closed-form solutions as numbered ghosts."""
    with poekin.view("universal_robots_ur5e", port=0, open_browser=False) as v:
        v.q = Q
        v.set_option("screw axes", False)
        v.set_option("home pose M", False)
        T = v.subject.chain.fk(Q)
        T[:3, 3] += TARGET_MOVE
        T[:3, :3] = T[:3, :3] @ lie.exp_so3(TARGET_TURN)
        v.set_target(T)
        v.wait_geometry()
        _shoot(page, v, None, HERE / "view_ik.png")


SHOTS = {"view_ur5e": _ur5e, "view_lynch_park": _lynch_park, "view_ik": _ik}


def main() -> None:
    warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
    wanted = [name for name in SHOTS if not sys.argv[1:] or any(a in name for a in sys.argv[1:])]
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=poekin.viewer.app.HEADLESS_CHROMIUM,
            args=list(poekin.viewer.app.HEADLESS_CHROMIUM_ARGS),
        )
        page = browser.new_page(viewport={"width": 1280, "height": 720})
        for name in wanted:
            SHOTS[name](page)
        browser.close()


if __name__ == "__main__":
    main()
