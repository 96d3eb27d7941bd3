"""Make the two screenshots of ``poekin view`` that docs/viewer.md shows (README shows the first)

    python docs/screenshots.py       # writes docs/view_ur5e.png and docs/view_lynch_park.png

Each is a 1280 x 720 page, quantised to 256 colours to stay small.
"""

from __future__ import annotations

import pathlib
import warnings

from PIL import Image
from playwright.sync_api import Page, sync_playwright

import poekin
import poekin.viewer.app

HERE = pathlib.Path(__file__).resolve().parent
Q = [0.5, -1.2, 1.5, -1.9, -1.5708, 0.0]


def _shoot(page: Page, viewer: poekin.viewer.app.Viewer, tab: str, out: pathlib.Path) -> None:
    page.goto(viewer.url)
    page.wait_for_selector("canvas")
    page.get_by_text("geometry: the model's").first.wait_for(timeout=120_000)
    viewer.frame_view()
    page.get_by_role("tab", name=tab).click()
    page.wait_for_timeout(45_000)  # software WebGL on a busy machine draws the labels last
    page.evaluate(  # the "software WebGL" notice
        "() => document.querySelectorAll('[class*=Notification]').forEach(e => e.remove())"
    )
    page.screenshot(path=str(out))
    Image.open(out).convert("RGB").quantize(256).save(out, optimize=True)
    print(f"{out}: {out.stat().st_size // 1024} KB")


def main() -> None:
    warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=poekin.viewer.app.HEADLESS_CHROMIUM,
            args=list(poekin.viewer.app.HEADLESS_CHROMIUM_ARGS),
        )
        page = browser.new_page(viewport={"width": 1280, "height": 720})
        with poekin.view("universal_robots_ur5e", port=0, open_browser=False) as v:
            v.q = Q
            v.wait_geometry()
            _shoot(page, v, "Screws & PoE", HERE / "view_ur5e.png")
        with poekin.view(
            "universal_robots_ur5e", params="lynch-park-ur5", port=0, open_browser=False
        ) as v:
            v.q = Q
            v.set_option("robot opacity", 0.35)
            v.wait_geometry()
            _shoot(page, v, "Compare", HERE / "view_lynch_park.png")
        browser.close()


if __name__ == "__main__":
    main()
