"""``poekin draw``: the figure's content (its artists and texts) and a pixel check that the arm
is drawn, not a golden image."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import textwrap

import matplotlib.colors
import matplotlib.image as mimage
import numpy as np
import pytest
from helpers import assert_labels_apart, load_quiet
from mpl_toolkits.mplot3d.art3d import Line3DCollection

import poekin
from poekin.errors import InputError
from poekin.verification.plotting import _MODEL_COLOR, _YOURS_COLOR
from poekin.viewer import draw as drawing
from poekin.viewer.scene import make_subject


def _quivers(fig: object, color: str) -> int:
    rgba = tuple(np.round(matplotlib.colors.to_rgba(color), 3))
    ax = fig.axes[0]  # type: ignore[attr-defined]
    return sum(
        1
        for c in ax.collections
        if isinstance(c, Line3DCollection) and tuple(np.round(c.get_color()[0], 3)) == rgba
    )


def _texts(fig: object) -> list[str]:
    return [t.get_text() for t in fig.axes[0].texts]  # type: ignore[attr-defined]


def test_arm_with_its_screws(tmp_path: pathlib.Path) -> None:
    q = [0.0, -1.57, 1.57, 0.0, 0.0, 0.0]
    out = tmp_path / "arm.png"
    fig = drawing.draw("universal_robots_ur5e", q, path=out)
    assert _quivers(fig, _MODEL_COLOR) == 6  # one arrow per screw axis
    texts = _texts(fig)
    assert [f"S{i}" for i in range(1, 7)] == [t for t in texts if t.startswith("S")]
    assert "T(q): attachment_site" in texts and "M" in texts and "world" in texts
    assert "at q = [0, -1.57, 1.57, 0, 0, 0]" in fig.get_suptitle()
    # the pixels: PNG, not blank, and the screw axes' blue is on it
    img = mimage.imread(out)
    assert img.shape[:2] == (900, 1080)
    blue = np.array(matplotlib.colors.to_rgb(_MODEL_COLOR))
    assert np.sum(np.all(np.abs(img[..., :3] - blue) < 0.05, axis=-1)) > 500
    body = drawing.draw("universal_robots_ur5e", q, form="body")
    assert [f"B{i}" for i in range(1, 7)] == [t for t in _texts(body) if t.startswith("B")]


def test_parameters_and_all_frames() -> None:
    q = [0.3, -1.2, 1.3, -1.0, -1.5708, 0.0]
    fig = drawing.draw("universal_robots_ur5e", q, params="lynch-park-ur5")
    assert _quivers(fig, _MODEL_COLOR) == 6 and _quivers(fig, _YOURS_COLOR) == 6
    lynch, model = poekin.lynch_park_ur5_chain(), poekin.load("universal_robots_ur5e")
    pos = float(poekin.pose_errors(model.fk(q), lynch.fk(q))[0])
    assert f"end frame off by {pos:.3g} m" in fig.get_suptitle()
    assert "yours: lynch-park-ur5" in _texts(fig)
    go2 = drawing.draw(load_quiet("unitree_go2"), all_frames=True)
    tree = poekin.load_tree(load_quiet("unitree_go2"))
    assert set(tree.frame_names) <= set(_texts(go2))


@pytest.mark.parametrize(
    ("suffix", "magic"), [(".pdf", b"%PDF"), (".svg", b"<?xml"), (".jpg", b"\xff\xd8")]
)
def test_the_suffix_decides_the_format(tmp_path: pathlib.Path, suffix: str, magic: bytes) -> None:
    out = tmp_path / f"arm{suffix}"
    drawing.draw(poekin.lynch_park_ur5_chain(), np.zeros(6), path=out)
    assert out.read_bytes().startswith(magic)


def test_bad_suffix_and_q_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_work(*_: object, **__: object) -> None:
        raise AssertionError("loaded a model before checking the suffix")

    monkeypatch.setattr("poekin.viewer.loading.load_shown", no_work)
    with pytest.raises(InputError, match=r"names no format poekin knows: \.png, \.pdf, \.svg"):
        drawing.draw("universal_robots_ur5e", path="arm.gif")
    monkeypatch.undo()
    with pytest.raises(InputError, match="expected 6 qpos values"):
        drawing.draw("universal_robots_ur5e", [1.0, 2.0])
    with pytest.raises(InputError, match="form must be"):
        subject = make_subject(poekin.lynch_park_ur5_chain())
        drawing.figure(subject, np.zeros(6), form="x")  # type: ignore[arg-type]


def test_a_fresh_process_keeps_its_backend_and_has_no_pyplot(tmp_path: pathlib.Path) -> None:
    code = textwrap.dedent(
        """
        import sys, matplotlib
        import poekin
        before = matplotlib.get_backend()
        poekin.draw(poekin.lynch_park_ur5_chain(), path=sys.argv[1])
        assert matplotlib.get_backend() == before == "svg", (before, matplotlib.get_backend())
        assert "matplotlib.pyplot" not in sys.modules, "pyplot was imported"
        """
    )
    out = tmp_path / "fresh.png"
    env = {**os.environ, "MPLBACKEND": "svg"}
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_aligned_needs_parameters(monkeypatch: pytest.MonkeyPatch) -> None:
    """issue 20: aligned=True without params was ignored; it is refused before any work."""

    def no_work(*_: object, **__: object) -> None:
        raise AssertionError("loaded a model before checking aligned")

    monkeypatch.setattr("poekin.viewer.loading.load_shown", no_work)
    with pytest.raises(InputError, match=r"aligned=True draws your parameters .*: give params"):
        drawing.draw("universal_robots_ur5e", aligned=True)


def test_a_path_that_cannot_be_written_is_refused_before_any_work(
    monkeypatch: pytest.MonkeyPatch, tmp_path: pathlib.Path
) -> None:
    def no_work(*_: object, **__: object) -> None:
        raise AssertionError("loaded a model before checking the path")

    monkeypatch.setattr("poekin.viewer.loading.load_shown", no_work)
    (tmp_path / "file").write_text("")
    with pytest.raises(InputError, match=r"cannot write the drawing to .*: .*file is a file, not"):
        drawing.draw("universal_robots_ur5e", path=tmp_path / "file" / "arm.png")
    with pytest.raises(InputError, match=r"folder .* does not exist"):
        drawing.draw("universal_robots_ur5e", path=tmp_path / "no" / "arm.png")


LABEL_CASES = {
    "ur5e at qpos0": dict(model="universal_robots_ur5e"),
    "ur5e bent": dict(model="universal_robots_ur5e", qpos=[0.0, -1.57, 1.57, 0.0, 0.0, 0.0]),
    "ur5e body form": dict(
        model="universal_robots_ur5e", qpos=[0.3, -1.2, 1.3, -1, -1.57, 0], form="body"
    ),
    "lynch-park ghost": dict(
        model="universal_robots_ur5e",
        qpos=np.radians([0, -90, 90, 0, 0, 0]),
        params="lynch-park-ur5",
    ),
    "lynch-park aligned": dict(
        model="universal_robots_ur5e",
        qpos=[0.3, -1.2, 1.3, -1.0, -1.5708, 0.0],
        params="lynch-park-ur5",
        aligned=True,
    ),
    "ur5e-dh ghost": dict(model="universal_robots_ur5e", params="ur5e-dh", aligned=True),
    "go2 every frame": dict(model="unitree_go2", all_frames=True),
}


@pytest.mark.parametrize("case", list(LABEL_CASES))
def test_no_label_overlaps_another_or_a_tick_label(case: str, tmp_path: pathlib.Path) -> None:
    """issue 20: the ghost's J4/J5/J6 offsets, T(q), "yours: ..." and S2/world, T(q)/S4/S6 were
    drawn over each other. Checked on the figure as saved (PNG and PDF, whose dpi differs)."""
    kwargs = dict(LABEL_CASES[case])
    model = kwargs.pop("model")
    source = load_quiet(model) if model == "unitree_go2" else model
    fig = drawing.draw(source, **kwargs)  # type: ignore[arg-type]
    assert_labels_apart(fig)
    texts = _texts(fig)
    assert "T(q): " + ("FL_calf" if model == "unitree_go2" else "attachment_site") in texts
    if "params" in kwargs:
        assert any(t.startswith("yours: ") for t in texts)
        assert sum(t.startswith("J") and "offset" in t for t in texts) == 5
    fig.savefig(tmp_path / "d.pdf", format="pdf", dpi=drawing._DPI)
    assert_labels_apart(fig)  # the placement is in axes coordinates: any dpi
