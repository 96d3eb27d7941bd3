"""The verification figure: a real PNG, robust to zeros, and no change to matplotlib's state."""

from __future__ import annotations

import dataclasses
import os
import pathlib
import subprocess
import sys
import textwrap
import warnings

import matplotlib
import matplotlib.colors
import matplotlib.image as mimage
import numpy as np
import pytest
from helpers import assert_labels_apart
from matplotlib.figure import Figure

import poekin
from poekin import lie
from poekin.errors import InputError
from poekin.verification import plotting
from poekin.verification.diagnose import Diagnosis, Finding, diagnose
from poekin.verification.plotting import plot_diagnosis, plot_errors

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _realistic(n: int = 200, seed: int = 0) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    pos, ori = {}, {}
    for name in ("space PoE", "body PoE"):
        p = np.abs(rng.normal(0.0, 1.5e-16, n))
        o = np.abs(rng.normal(0.0, 4e-16, n))
        p[rng.random(n) < 0.1] = 0.0
        o[rng.random(n) < 0.2] = 0.0
        pos[name], ori[name] = p, o
    return pos, ori


def _assert_png(path: pathlib.Path) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC
    assert len(data) > 10_000  # a drawn 13 x 4.5 in figure, not an empty file


def _capture_figure(monkeypatch: pytest.MonkeyPatch) -> list[Figure]:
    """Record the Figure that plot_errors saves, to inspect what was drawn."""
    figs: list[Figure] = []
    real = Figure.savefig

    def spy(self: Figure, *args: object, **kwargs: object) -> None:
        figs.append(self)
        real(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Figure, "savefig", spy)
    return figs


def _texts(fig: Figure) -> str:
    out = [fig.get_suptitle()] if hasattr(fig, "get_suptitle") else []
    for ax in fig.axes:
        out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
        out += [t.get_text() for t in ax.texts]
        leg = ax.get_legend()
        if leg is not None:
            out += [t.get_text() for t in leg.get_texts()]
            out.append(leg.get_title().get_text())
    return "\n".join(out)


def test_writes_png_realistic(tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figs = _capture_figure(monkeypatch)
    pos, ori = _realistic()
    out = tmp_path / "fk.png"
    backend, rc_before = matplotlib.get_backend(), dict(matplotlib.rcParams)
    assert plot_errors(pos, ori, title="ur5e / site", path=str(out)) == out
    assert matplotlib.get_backend() == backend
    assert dict(matplotlib.rcParams) == rc_before
    _assert_png(out)
    (fig,) = figs
    assert len(fig.axes) == 3
    assert [ax.get_xscale() for ax in fig.axes] == ["log", "log", "log"]
    assert fig.axes[2].get_yscale() == "log"
    w, h = fig.get_size_inches()
    assert (round(w), round(h, 1)) == (13, 4.5)
    assert fig.dpi == 150
    text = _texts(fig)
    assert "ur5e / site" in text
    assert "position error [m]" in text
    assert "orientation error [rad]" in text
    assert "count" in text
    n_pos_zeros = sum(int(np.count_nonzero(a == 0)) for a in pos.values())
    assert f"{n_pos_zeros} exact zeros shown at" in text
    for name, a in pos.items():
        assert f"{name}  max {float(a.max()):.2g}  med {float(np.median(a)):.2g}" in text


VERDICTS = [(True, "PASS: within", "#1a7f37"), (False, "FAIL: outside", "#c62828")]


@pytest.mark.parametrize(("passed", "verdict", "color"), VERDICTS)
def test_the_verdict_is_in_the_title(
    passed: bool, verdict: str, color: str, tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """issue #15: a failing run must not look as calm as a passing one."""
    figs = _capture_figure(monkeypatch)
    pos, ori = _realistic()
    plot_errors(
        pos, ori, title="t", path=tmp_path / "fk.png", pos_tol=1e-5, ori_tol=1e-4, passed=passed
    )
    (fig,) = figs
    (text,) = [t for t in fig.texts if t.get_text().startswith(verdict)]
    assert text.get_text() == f"{verdict} tolerances 1e-05 m, 0.0001 rad"
    assert matplotlib.colors.to_hex(text.get_color()) == color


MAGIC = [(".pdf", b"%PDF"), (".svg", b"<?xml"), (".jpeg", b"\xff\xd8")]


@pytest.mark.parametrize(("suffix", "magic"), MAGIC)
def test_the_suffix_names_the_format(suffix: str, magic: bytes, tmp_path: pathlib.Path) -> None:
    pos, ori = _realistic(20)
    assert (
        plot_errors(pos, ori, title="t", path=tmp_path / f"fk{suffix}")
        .read_bytes()
        .startswith(magic)
    )
    with pytest.raises(InputError, match="names no format poekin knows"):
        plot_errors(pos, ori, title="t", path=tmp_path / "fk.xyz")


def test_exact_zeros_are_drawn_at_a_floor(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    figs = _capture_figure(monkeypatch)
    zeros = {"space PoE": np.zeros(50), "body PoE": np.zeros(50)}
    plot_errors(zeros, zeros, title="all exact", path=tmp_path / "z.png")
    _assert_png(tmp_path / "z.png")
    text = _texts(figs[0])
    assert "100 exact zeros shown at 1e-18" in text
    assert "max 0  med 0" in text
    for ax in figs[0].axes:
        lo, hi = ax.get_xlim()
        assert 0 < lo < 1e-18 < hi


def test_floor_is_a_decade_below_the_smallest_positive(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    figs = _capture_figure(monkeypatch)
    p = np.array([0.0, 0.0, 0.05, 0.4, 0.8])
    o = np.array([0.0, 3.0, 2.5, 0.7, 1.1])
    out = plot_errors(
        {"m": p}, {"m": o}, title="fail", path=tmp_path / "f.png", pos_tol=1e-9, ori_tol=1e-9
    )
    _assert_png(out)
    text = _texts(figs[0])
    assert "m  max 0.8  med 0.05" in text
    assert "m  max 3  med 1.1" in text
    assert "2 exact zeros shown at 1e-3" in text  # smallest positive 0.05 -> 1e-2 -> 1e-3
    assert "1 exact zero shown at 1e-2" in text  # smallest positive 0.7 -> 1e-1 -> 1e-2


def test_single_method_with_tolerances(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    figs = _capture_figure(monkeypatch)
    pos, ori = _realistic()
    out = tmp_path / "one.png"
    plot_errors(
        {"space PoE": pos["space PoE"]},
        {"space PoE": ori["space PoE"]},
        title="one method",
        path=out,
        pos_tol=1e-9,
        ori_tol=2e-9,
    )
    _assert_png(out)
    fig = figs[0]
    text = _texts(fig)
    assert "body PoE" not in text
    assert "tol 1e-09 m" in text
    assert "tol 2e-09 rad" in text
    # Dashed tolerance lines: one per histogram, a vertical and a horizontal in the scatter.
    xs = [ln.get_xdata() for ln in fig.axes[0].lines]
    assert any(list(x) == [1e-9, 1e-9] for x in xs)
    sc = fig.axes[2]
    assert any(list(ln.get_xdata()) == [1e-9, 1e-9] for ln in sc.lines)
    assert any(list(ln.get_ydata()) == [2e-9, 2e-9] for ln in sc.lines)
    assert all(ln.get_linestyle() in ("--", "-.") or ln.get_dashes() for ln in sc.lines)
    # The tolerance is within the view even though the data are 7 decades below it.
    assert sc.get_xlim()[1] >= 1e-9
    assert sc.get_ylim()[1] >= 2e-9


def test_nan_is_left_out_and_counted(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    figs = _capture_figure(monkeypatch)
    p = np.array([1e-16, np.nan, 2e-16])
    plot_errors(
        {"m": p}, {"m": np.array([1e-16, 1e-16, np.inf])}, title="t", path=tmp_path / "n.png"
    )
    _assert_png(tmp_path / "n.png")
    assert "1 NaN/inf not shown" in _texts(figs[0])


def test_empty_arrays_do_not_crash(tmp_path: pathlib.Path) -> None:
    out = plot_errors({"m": np.zeros(0)}, {"m": np.zeros(0)}, title="t", path=tmp_path / "e.png")
    _assert_png(out)


def test_mismatched_inputs_raise(tmp_path: pathlib.Path) -> None:
    out = tmp_path / "x.png"
    with pytest.raises(InputError, match="same methods"):
        plot_errors({"a": np.zeros(3)}, {"b": np.zeros(3)}, title="t", path=out)
    with pytest.raises(InputError, match="3 position errors but 2"):
        plot_errors({"a": np.zeros(3)}, {"a": np.zeros(2)}, title="t", path=out)
    with pytest.raises(InputError, match=">= 0"):
        plot_errors({"a": np.array([1e-16, -1e-16])}, {"a": np.zeros(2)}, title="t", path=out)
    with pytest.raises(InputError, match=r"shape \(N,\)"):
        plot_errors({"a": np.zeros((3, 2))}, {"a": np.zeros((3, 2))}, title="t", path=out)
    assert not out.exists()


def test_missing_parent_directory_raises(tmp_path: pathlib.Path) -> None:
    missing = tmp_path / "nope"
    pos, ori = _realistic(10)
    with pytest.raises(InputError, match="does not exist") as info:
        plot_errors(pos, ori, title="t", path=missing / "fk.png")
    assert str(missing) in str(info.value)
    assert not missing.exists()


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs /proc")
def test_a_folder_that_takes_no_files_is_refused_before_drawing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """issue 20: /proc exists but takes no new files (as root too): one InputError line, not
    matplotlib's FileNotFoundError after the figure was drawn."""
    pos, ori = _realistic(10)

    def no_drawing(*_: object, **__: object) -> None:
        raise AssertionError("drew before checking the path")

    monkeypatch.setattr(plotting, "_histogram", no_drawing)
    monkeypatch.setattr(plotting, "_diagnosis_figure", no_drawing)
    with pytest.raises(InputError, match=r"to /proc/fk\.png: folder /proc is not"):
        plot_errors(pos, ori, title="t", path="/proc/fk.png")
    with pytest.raises(InputError, match=r"to /proc/w\.png: folder /proc is not"):
        plot_diagnosis(None, "/proc/w.png")  # type: ignore[arg-type]


def test_fresh_process_keeps_its_backend_and_has_no_pyplot(tmp_path: pathlib.Path) -> None:
    # In a fresh interpreter with a non-Agg backend chosen, so that neither an earlier test's
    # import of pyplot nor Agg being the default can hide a change.
    code = textwrap.dedent(
        """
        import sys, matplotlib
        import numpy as np
        from poekin.verification.plotting import plot_errors
        before = matplotlib.get_backend()
        e = {"m": np.array([0.0, 1e-16, 2e-16])}
        plot_errors(e, e, title="t", path=sys.argv[1], pos_tol=1e-9, ori_tol=1e-9)
        assert matplotlib.get_backend() == before == "svg", (before, matplotlib.get_backend())
        assert "matplotlib.pyplot" not in sys.modules, "pyplot was imported"
        """
    )
    env = {**os.environ, "MPLBACKEND": "svg"}
    src = str(pathlib.Path(plotting.__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
    out = tmp_path / "fresh.png"
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    _assert_png(out)


# --- the diagnosis figure -----------------------------------------------------------------------

DIAG_PIXELS = (840, 1680)  # 14 x 7 in at 120 dpi: (rows, columns)


@pytest.fixture(scope="module")
def panda_finger() -> poekin.Chain:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        return poekin.load("franka_emika_panda", "left_finger")


def _with_screws(chain: poekin.Chain, screws: np.ndarray, **changes: object) -> poekin.Chain:
    return dataclasses.replace(chain, screws=screws, robot="", qpos_indices=None, **changes)


def _flipped(chain: poekin.Chain, joint: int) -> poekin.Chain:
    S = chain.screws.copy()
    S[joint] *= -1
    return _with_screws(chain, S)


def _axis_moved(chain: poekin.Chain, joint: int, shift: np.ndarray) -> poekin.Chain:
    """``chain`` with revolute ``joint``'s axis line moved by ``shift`` (m)."""
    S = chain.screws.copy()
    S[joint, 3:] -= np.cross(S[joint, :3], shift)  # v = -w x q
    return _with_screws(chain, S)


def _diag_texts(fig: Figure) -> list[str]:
    """Every string drawn: suptitle, panel titles, axis labels, texts, the figure legend."""
    out = [fig.get_suptitle()]
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()]  # type: ignore[attr-defined]
        out += [t.get_text() for t in ax.texts]
    for leg in fig.legends:
        out += [t.get_text() for t in leg.get_texts()] + [leg.get_title().get_text()]
    return out


def _quiet_figure(d: Diagnosis, title: str | None = None) -> Figure:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = plotting._diagnosis_figure(d, title)
        fig.canvas.draw()  # warnings from drawing (layout, text) count too
    return fig


def _assert_equal_limits(fig: Figure) -> None:
    for ax in fig.axes:
        lims = [ax.get_xlim(), ax.get_ylim(), ax.get_zlim()]  # type: ignore[attr-defined]
        widths = [hi - lo for lo, hi in lims]
        assert min(widths) > 0
        assert np.allclose(widths, widths[0], rtol=1e-9), widths
        aspect = np.asarray(ax.get_box_aspect())  # type: ignore[attr-defined]
        assert np.allclose(aspect, aspect[0]), aspect  # a cube: 1 m is as long on every axis
        assert (ax.elev, ax.azim) == (25.0, -60.0)  # type: ignore[attr-defined]


def _arrow_colors(ax: object) -> list[tuple[float, ...]]:
    """The colour of each quiver (one per chain) in a 3-D axes."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    return [
        tuple(np.round(c.get_color()[0], 3))
        for c in ax.collections  # type: ignore[attr-defined]
        if isinstance(c, Line3DCollection)
    ]


def test_diagnosis_png_flipped_joint(ur5e: poekin.Chain, tmp_path: pathlib.Path) -> None:
    d = diagnose(_flipped(ur5e, 3), ur5e)
    assert d.joint_labels() == {3: "flipped"}
    out = tmp_path / "diag.png"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert plot_diagnosis(d, out) is None  # type: ignore[func-returns-value]
    assert out.read_bytes()[:8] == PNG_MAGIC
    img = mimage.imread(out)
    assert img.shape[:2] == DIAG_PIXELS
    assert float(img[..., :3].std()) > 0.05  # something is drawn, not a blank canvas

    fig = _quiet_figure(d)
    assert len(fig.axes) == 2
    left, right = fig.axes
    assert left.get_title() == "as given (each in its own base frame)"
    # a flipped axis is no base turn: the right panel shows your base as given, as report()
    assert not d.base_aligned
    assert right.get_title().startswith("as given: aligning your base does not reduce the error")
    right_texts = [t.get_text() for t in right.texts]
    assert "J4 flipped" in right_texts
    assert "J4 flipped" not in [t.get_text() for t in left.texts]
    # Every joint is tagged in both panels; J4's tag on the right is its finding label.
    for ax in (left, right):
        tags = " ".join(t.get_text() for t in ax.texts)
        for i in range(1, 7):
            assert f"J{i}" in tags
    assert fig.get_suptitle() == (
        "your parameters vs universal_robots_ur5e: mismatch\n"
        f"max error {d.max_pos_err_m:.3g} m, {d.max_ori_err_rad:.3g} rad (180 deg) "
        "over 1000 random q"
    )
    text = "\n".join(_diag_texts(fig))
    assert "model: universal_robots_ur5e / attachment_site" in text
    assert "yours: your parameters" in text
    for label in ("x [m]", "y [m]", "z [m]"):
        assert label in text
    _assert_equal_limits(fig)
    # One quiver per chain in each panel, in the two colours.
    model_rgb = tuple(np.round(matplotlib.colors.to_rgba(plotting._MODEL_COLOR), 3))
    yours_rgb = tuple(np.round(matplotlib.colors.to_rgba(plotting._YOURS_COLOR), 3))
    for ax in (left, right):
        assert _arrow_colors(ax) == [model_rgb, yours_rgb]


def test_diagnosis_of_a_match_has_no_findings(ur5e: poekin.Chain, tmp_path: pathlib.Path) -> None:
    d = diagnose(dataclasses.replace(ur5e), ur5e)
    assert d.matches
    out = tmp_path / "self.png"
    plot_diagnosis(d, str(out))  # a str path works as well as a Path
    assert mimage.imread(out).shape[:2] == DIAG_PIXELS
    fig = _quiet_figure(d)
    texts = _diag_texts(fig)
    joined = "\n".join(texts)
    assert "flipped" not in joined
    assert "offset" not in joined
    assert "base turned" not in joined
    assert "M:" not in joined
    assert "universal_robots_ur5e vs universal_robots_ur5e: match\n" in fig.get_suptitle()
    assert "your base" not in texts  # the alignment is the identity: one base triad


def test_diagnosis_title_overrides_the_first_line(ur5e: poekin.Chain) -> None:
    d = diagnose(_flipped(ur5e, 0), ur5e)
    fig = _quiet_figure(d, "my table vs ur5e / attachment_site")
    first, second = fig.get_suptitle().split("\n")
    assert first == "my table vs ur5e / attachment_site"
    assert second.startswith("max error ")


def test_diagnosis_prismatic_joint_and_moved_axis(
    panda_finger: poekin.Chain, tmp_path: pathlib.Path
) -> None:
    assert panda_finger.joint_types[-1] == "prismatic"
    n = panda_finger.n_joints
    d = diagnose(_axis_moved(panda_finger, 2, np.array([0.01, 0.0, 0.0])), panda_finger)
    assert d.joint_labels() == {2: "offset 0.01 m"}
    out = tmp_path / "panda.png"
    plot_diagnosis(d, out)
    assert mimage.imread(out).shape[:2] == DIAG_PIXELS
    fig = _quiet_figure(d)
    left, right = fig.axes
    assert "J3 offset 0.01 m" in [t.get_text() for t in right.texts]
    assert not any("offset" in t.get_text() for t in left.texts)
    # The slide joint gets its arrow: each quiver has n arrows of 3 strokes (shaft, 2 heads).
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    for ax in (left, right):
        quivers = [c for c in ax.collections if isinstance(c, Line3DCollection)]
        assert [len(q._segments3d) for q in quivers] == [3 * n, 3 * n]
        tags = " ".join(t.get_text() for t in ax.texts)
        assert f"J{n}" in tags
    _assert_equal_limits(fig)


def test_diagnosis_prismatic_flipped(panda_finger: poekin.Chain) -> None:
    n = panda_finger.n_joints
    d = diagnose(_flipped(panda_finger, n - 1), panda_finger)
    fig = _quiet_figure(d)
    assert f"J{n} flipped" in [t.get_text() for t in fig.axes[1].texts]


def test_diagnosis_base_and_home_notes(ur5e: poekin.Chain) -> None:
    B = np.eye(4)
    B[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # 90 deg about z
    B[:3, 3] = [0.05, 0.0, 0.0]
    B_inv = lie.inverse(B)
    screws = (np.asarray(lie.adjoint(B_inv)) @ ur5e.screws.T).T
    home = B_inv @ ur5e.home
    home[:3, 3] += B_inv[:3, :3] @ [0.0, 0.0, 0.03]
    d = diagnose(_with_screws(ur5e, screws, home=home), ur5e)
    assert {f.kind for f in d.findings} >= {"base_rotation", "base_shift", "home_position"}
    fig = _quiet_figure(d)
    left, right = (sorted(t.get_text() for t in ax.texts) for ax in fig.axes)
    assert "base turned 90 deg, shifted 0.05 m" in left
    assert "M: off by 0.03 m" in right
    assert "your base" in right
    assert not any(t.startswith("M:") for t in left)
    assert not any(t.startswith("base ") for t in right)
    assert "J1" in right  # the right panel's base has a triad for each base, J1 still tagged
    _assert_equal_limits(fig)


def test_diagnosis_degenerate_chains(tmp_path: pathlib.Path) -> None:
    # One joint, every point at the origin: the extent has no size of its own.
    one = poekin.Chain(("j",), ("revolute",), [[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]], np.eye(4))
    slide = poekin.Chain(("s",), ("prismatic",), [[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]], np.eye(4))
    for yours, model in ((one, one), (slide, slide), (one, slide)):
        d = diagnose(yours, model)
        fig = _quiet_figure(d)
        _assert_equal_limits(fig)
        for ax in fig.axes:
            assert all(np.isfinite(ax.get_xlim()))
        out = tmp_path / "one.png"
        plot_diagnosis(d, out)
        assert mimage.imread(out).shape[:2] == DIAG_PIXELS
    texts = _diag_texts(_quiet_figure(diagnose(one, slide)))
    assert "J1 type" in texts
    assert "model: the model / ee" in texts  # a hand-made chain has no robot name


def test_diagnosis_long_labels_are_wrapped(ur5e: poekin.Chain) -> None:
    d = diagnose(_flipped(ur5e, 1), ur5e)
    extra = tuple(
        Finding(kind, "x", joint=1, value=0.0123456)
        for kind in ("axis_tilted", "axis_offset", "joint_type")
    )
    d = dataclasses.replace(d, findings=d.findings + extra)
    label = d.joint_labels()[1]
    assert len(label) > 40
    fig = _quiet_figure(d, "a title " * 20)
    (text,) = [t.get_text() for t in fig.axes[1].texts if t.get_text().startswith("J2 ")]
    assert "\n" in text
    assert text.replace("\n  ", " ") == f"J2 {label}"


def test_diagnosis_fresh_process_has_no_pyplot(tmp_path: pathlib.Path) -> None:
    code = textwrap.dedent(
        """
        import sys, matplotlib
        import poekin
        from poekin.verification.diagnose import diagnose
        from poekin.verification.plotting import plot_diagnosis
        before = matplotlib.get_backend()
        m = poekin.Chain(("j",), ("revolute",), [[0, 0, 1, 0, 0, 0]], [[1, 0, 0, 0.3],
            [0, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0, 1]])
        plot_diagnosis(diagnose(m, m), sys.argv[1])
        assert matplotlib.get_backend() == before == "svg", (before, matplotlib.get_backend())
        assert "matplotlib.pyplot" not in sys.modules, "pyplot was imported"
        """
    )
    env = {**os.environ, "MPLBACKEND": "svg"}
    src = str(pathlib.Path(plotting.__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
    out = tmp_path / "fresh_diag.png"
    proc = subprocess.run(
        [sys.executable, "-W", "error", "-c", code, str(out)],
        env=env,
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert mimage.imread(out).shape[:2] == DIAG_PIXELS


def test_diagnosis_figure_lists_the_link_lengths_that_differ(ur5e: poekin.Chain) -> None:
    d = diagnose(poekin.named_params("lynch-park-ur5"), ur5e, samples=100)
    text = "\n".join(_diag_texts(_quiet_figure(d)))
    assert "DH link lengths and twists that differ" in text
    assert "d1: 0.089 m in yours vs 0.163 m in the model" in text
    exact = _diag_texts(_quiet_figure(diagnose(ur5e, ur5e, samples=20)))
    assert not any("link lengths" in t for t in exact)


@pytest.mark.parametrize("params", ["ur5e-dh", "lynch-park-ur5", "flipped J4", "base and M"])
def test_diagnosis_labels_overlap_nothing(params: str, ur5e: poekin.Chain) -> None:
    """issue 20: no finding label, tag or the DH box overlaps another, a tick label (the DH box
    covered the x ticks), a title or the legend."""
    if params == "flipped J4":
        yours: poekin.Chain | str = _flipped(ur5e, 3)
    elif params == "base and M":
        B = lie.exp_se3(np.array([0.0, 0.0, np.pi / 2, 0.05, 0.0, 0.0]))
        B_inv = lie.inverse(B)
        home = B_inv @ ur5e.home
        home[:3, 3] += [0.0, 0.0, 0.03]
        screws = (np.asarray(lie.adjoint(B_inv)) @ ur5e.screws.T).T
        yours = _with_screws(ur5e, screws, home=home)
    else:
        yours = params
    fig = _quiet_figure(diagnose(yours, ur5e, samples=100))
    assert_labels_apart(fig)


def test_the_aligned_panel_says_what_the_report_says(ur5e: poekin.Chain) -> None:
    """issue 20: for ur5e-dh aligning the base does not help, so the report compares the base
    as it is; the right panel said "after aligning your base" all the same."""
    d = diagnose("ur5e-dh", ur5e, samples=100)
    assert not d.base_aligned
    assert "aligning the base does not reduce it" in d.report()[0]
    title = _quiet_figure(d).axes[1].get_title()
    assert title.startswith("as given: aligning your base does not reduce the error\n")
    assert "after" not in title
    lynch = diagnose("lynch-park-ur5", ur5e, samples=100)
    assert lynch.base_aligned and "after aligning the base" in lynch.report()[0]
    title = _quiet_figure(lynch).axes[1].get_title()
    assert title.startswith("after aligning your base to the model's\n")
    assert title.endswith(" after alignment")
