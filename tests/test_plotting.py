"""The verification figure: a real PNG, robust to zeros, and no change to matplotlib's state."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import textwrap

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure

from poekin import plotting
from poekin.errors import InputError
from poekin.plotting import plot_errors

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
    with pytest.raises(FileNotFoundError, match="does not exist") as info:
        plot_errors(pos, ori, title="t", path=missing / "fk.png")
    assert str(missing) in str(info.value)
    assert not missing.exists()


def test_fresh_process_keeps_its_backend_and_has_no_pyplot(tmp_path: pathlib.Path) -> None:
    # In a fresh interpreter with a non-Agg backend chosen, so that neither an earlier test's
    # import of pyplot nor Agg being the default can hide a change.
    code = textwrap.dedent(
        """
        import sys, matplotlib
        import numpy as np
        from poekin.plotting import plot_errors
        before = matplotlib.get_backend()
        e = {"m": np.array([0.0, 1e-16, 2e-16])}
        plot_errors(e, e, title="t", path=sys.argv[1], pos_tol=1e-9, ori_tol=1e-9)
        assert matplotlib.get_backend() == before == "svg", (before, matplotlib.get_backend())
        assert "matplotlib.pyplot" not in sys.modules, "pyplot was imported"
        """
    )
    env = {**os.environ, "MPLBACKEND": "svg"}
    src = str(pathlib.Path(plotting.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([src, env.get("PYTHONPATH", "")])
    out = tmp_path / "fresh.png"
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr
    _assert_png(out)
