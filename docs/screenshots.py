"""Make the screenshots of ``poekin view`` that docs/viewer.md and docs/wholebody.md show
(README shows the first)

    python docs/screenshots.py       # writes docs/view_ur5e.png, view_lynch_park.png,
                                     # view_ik.png, view_wholebody.png, view_play.png,
                                     # view_collision.png
    python docs/screenshots.py ik    # only those whose name contains "ik"

Each is a 1280 x 720 page, quantised to 256 colours to stay small. The UR5e's are drawn with its
meshes: set MENAGERIE_ROOT to a complete Menagerie clone (../shared/menagerie).
"""

from __future__ import annotations

import pathlib
import sys
import warnings

import numpy as np
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
# the G1's whole-body handles: both palms and both feet, the feet held
G1_HANDS = ("left_elbow_roll_link", "right_elbow_roll_link")
G1_FEET = ("left_foot", "right_foot")
# where the palms' handles are dragged: their poses with the arms raised forward (shoulder
# pitch -0.4 rad, roll 0.15 rad outward), reached in five drags of each
ARMS_RAISED = {"shoulder_pitch_joint": -0.4, "shoulder_roll_joint": 0.15}
# the trajectory played: a quintic time scaling over 2 s from Q to PLAY_TO, shown at 1.2 s
PLAY_TO = [1.6, -0.7, 1.0, -1.9, -1.5708, 0.8]
PLAY_AT = 1.2
# the UR5e at the edge of a table (docs/collision.md), leaning on it: the forearm's elbow end
# 10 mm into the table top, the tool pointing down; seen from the side, the panel on the right
TABLE = {"half_sizes": [0.3, 0.4, 0.02], "pose": [-0.55, 0.0, -0.02, 1.0, 0.0, 0.0, 0.0]}
ELBOW_DOWN = [0.3, 0.28, -1.6, -0.25, -1.5708, 0.0]
SIDE_CAMERA = ([-0.05, -0.8, 0.25], [-0.22, -0.14, 0.16])


def _shoot(
    page: Page,
    viewer: poekin.viewer.app.Viewer,
    tab: str | None,
    out: pathlib.Path,
    ready: str = "geometry: the model's",
    camera: tuple[list[float], list[float]] | None = None,
) -> None:
    """A screenshot of the page with ``tab`` open (None: the first, Joints), once the panel
    shows ``ready`` (the geometry's note), the camera at ``(position, look_at)`` (None: the
    viewer's framing of the robot)."""
    page.goto(viewer.url)
    page.wait_for_selector("canvas")
    page.get_by_text(ready).first.wait_for(timeout=120_000)
    viewer.frame_view()
    for client in viewer.server.get_clients().values() if camera is not None else ():
        client.camera.position, client.camera.look_at = camera
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


def _wholebody(page: Page) -> None:
    """Whole-body IK on the G1 (the built-in model has no meshes: the stand-in capsules): a
    handle on each palm and foot, the palms dragged forward and up, the feet held."""
    with poekin.view(
        "unitree_g1", frames=[*G1_HANDS, *G1_FEET], hold=G1_FEET, port=0, open_browser=False
    ) as v:
        v.set_option("screw axes", False)
        v.set_option("home pose M", False)
        v.set_option("robot opacity", 1.0)  # the stand-in's capsules overlap
        assert v.wholebody is not None and v.subject.tree is not None
        tree = v.subject.tree
        raised = np.array(tree.qpos0)
        for side, sign in (("left", 1.0), ("right", -1.0)):
            for joint, value in ARMS_RAISED.items():
                turn = sign * value if "roll" in joint else value
                raised[tree.qpos_adr[tree.joint_names.index(f"{side}_{joint}")]] = turn
        start = {f: v.wholebody.targets[f] for f in G1_HANDS}
        goal = {f: tree.pose(raised, f) for f in G1_HANDS}
        for step in range(1, 6):
            for frame in G1_HANDS:
                A, B, a = start[frame], goal[frame], step / 5
                T = np.eye(4)
                T[:3, 3] = (1 - a) * A[:3, 3] + a * B[:3, 3]
                T[:3, :3] = A[:3, :3] @ lie.exp_so3(a * lie.log_so3(A[:3, :3].T @ B[:3, :3]))
                shown = v.drag_handle(frame, T)
        assert shown.success, shown.frame_errors
        v.wait_geometry()
        _shoot(page, v, None, HERE / "view_wholebody.png", ready="geometry: stand-in")


def _play(page: Page) -> None:
    """A trajectory played on the UR5e: the quintic from Q to PLAY_TO, paused at PLAY_AT, the
    end frame's path over the whole of it as the tool trace."""
    from poekin.io.trajectory import Trajectory

    t = np.linspace(0.0, 2.0, 201)
    tau = t / 2.0
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    q = np.asarray(Q) + np.outer(s, np.subtract(PLAY_TO, Q))
    trajectory = Trajectory(t, q, robot="universal_robots_ur5e")
    with poekin.view("universal_robots_ur5e", play=trajectory, port=0, open_browser=False) as v:
        v.set_option("screw axes", False)
        v.play_time = PLAY_AT
        v.wait_geometry()
        _shoot(page, v, None, HERE / "view_play.png")


def _collision(page: Page) -> None:
    """The collision view: the UR5e's collision capsules over its meshes at the edge of a
    table, the forearm and the table red where they overlap, with their witness points, and
    those of the pairs within 20 mm."""
    from poekin.collision import Box

    table = Box(TABLE["half_sizes"], pose=TABLE["pose"], name="table")
    with poekin.view(
        "universal_robots_ur5e", collision=True, obstacles=[table], port=0, open_browser=False
    ) as v:
        v.q = ELBOW_DOWN
        v.set_option("screw axes", False)
        v.set_option("home pose M", False)
        v.set_option("robot opacity", 0.2)  # the capsules inside the meshes show
        v.wait_geometry()
        _shoot(page, v, None, HERE / "view_collision.png", camera=SIDE_CAMERA)


SHOTS = {
    "view_ur5e": _ur5e,
    "view_lynch_park": _lynch_park,
    "view_ik": _ik,
    "view_wholebody": _wholebody,
    "view_play": _play,
    "view_collision": _collision,
}


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
