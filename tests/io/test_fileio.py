"""Array and figure files: the suffix names the format, files go exactly where the user said."""

from __future__ import annotations

import errno
import os
import pathlib
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from poekin.errors import InputError
from poekin.io import fileio
from poekin.io.fileio import (
    check_new_file,
    check_writable,
    figure_format,
    read_array,
    save_figure,
    write_array,
)

Q = np.array([[0.1, -1e-3, 2.5, 0.0, -0.25, 3.0], [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]])


@pytest.mark.parametrize("suffix", [".npy", ".npz", ".csv", ".txt", ".CSV", ".Npy"])
def test_round_trip_to_the_bit(suffix: str, tmp_path: pathlib.Path) -> None:
    """Written where asked (no suffix added) and read back to the same float64 bits."""
    x = np.random.default_rng(0).normal(size=(5, 6)) * 10.0 ** np.arange(-8, 4, 2)
    path = tmp_path / f"q{suffix}"
    write_array(path, x, name="q", columns=[f"q{i}" for i in range(6)])
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
    back = read_array(path)
    assert back.dtype == np.float64 and back.shape == x.shape
    assert np.array_equal(back, x)


def test_text_formats_carry_column_names(tmp_path: pathlib.Path) -> None:
    T = np.arange(2 * 4 * 4, dtype=float).reshape(2, 4, 4)
    cells = [f"T{r}{c}" for r in range(4) for c in range(4)]
    write_array(tmp_path / "T.csv", T, name="T", columns=cells)
    write_array(tmp_path / "T.txt", T, name="T", columns=cells)
    csv_lines = (tmp_path / "T.csv").read_text().splitlines()
    assert csv_lines[0] == ",".join(cells) and len(csv_lines) == 3
    assert csv_lines[1].split(",")[:3] == ["0", "1", "2"]
    txt_lines = (tmp_path / "T.txt").read_text().splitlines()
    assert txt_lines[0] == "# " + " ".join(cells) and len(txt_lines) == 3
    assert np.array_equal(read_array(tmp_path / "T.csv"), T.reshape(2, 16))


def test_npz_holds_the_names_beside_the_result(tmp_path: pathlib.Path) -> None:
    T = np.zeros((3, 2, 4, 4))
    write_array(tmp_path / "T.npz", T, name="T", columns=[], extras={"frames": ("a", "b")})
    with np.load(tmp_path / "T.npz") as archive:
        assert sorted(archive) == ["T", "frames"]
        assert archive["T"].shape == (3, 2, 4, 4)
        assert archive["frames"].tolist() == ["a", "b"]


def test_read_csv_with_a_header_comments_and_one_row(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "q.csv"
    path.write_text("# my joints\nq1,q2,q3,q4,q5,q6\n0.1,-1e-3,2.5,0,-.25,3  # first\n")
    assert np.array_equal(read_array(path), Q[:1])


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("q.npy", b"0,0,0,0,0,0\n", "is not a NumPy .npy file"),
        ("q.npz", b"0 0 0\n", "is not a NumPy .npz archive"),
        ("q.csv", b"0,zero,0\n0,1,2\n", "line 1, column 2: 'zero' is not a number"),
        (  # the file's own line numbers, the header's column names (not NumPy's row 0)
            "q.csv",
            b"a,b,c\n# a comment\n0,1,2\n\n0,1,zz\n",
            "q.csv line 5, column 'c': 'zz' is not a number (values separated by commas)",
        ),
        ("q.csv", b"# nothing\n\n", "holds no numbers"),
        ("q.txt", b"0 1 2\n3 4\n", "line 2 holds 2 values, line 1 3: every row needs as many"),
        ("q.txt", b"\xff\xfe\x00garbage", "not UTF-8"),
        ("q.dat", b"0 0 0\n", "its suffix '.dat' names no format poekin knows"),
        ("q", b"0 0 0\n", "it has no suffix"),
    ],
)
def test_unreadable_files_say_why_in_one_line(
    name: str, content: bytes, message: str, tmp_path: pathlib.Path
) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        read_array(path)
    text = str(info.value)
    assert message in text and "\n" not in text
    assert "pickle" not in text  # never the advice to unpickle a file


def test_arrays_of_objects_complex_numbers_or_strings_are_refused(tmp_path: pathlib.Path) -> None:
    np.save(tmp_path / "objects.npy", np.array([{"q": 1}], dtype=object), allow_pickle=True)
    np.save(tmp_path / "complex.npy", Q + 1j)
    np.save(tmp_path / "strings.npy", np.array(["a", "b"]))
    np.savez(tmp_path / "two.npz", a=Q, b=Q)
    cases = {
        "objects.npy": "holds Python objects",
        "complex.npy": "holds complex numbers",
        "strings.npy": "holds <U1 values, not numbers",
        "two.npz": "holds 2 arrays ('a', 'b'); give a file with one",
    }
    for name, message in cases.items():
        with pytest.raises(InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
            read_array(tmp_path / name)


def test_a_missing_file(tmp_path: pathlib.Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        read_array(tmp_path / "none.npy")


def test_a_failed_write_leaves_nothing_and_keeps_the_old_file(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "T.csv"
    path.write_text("the user's data\n")
    with pytest.raises(ValueError, match="3 column names for 16 values"):
        write_array(path, np.zeros((2, 4, 4)), name="T", columns=["a", "b", "c"])
    assert path.read_text() == "the user's data\n"
    assert [p.name for p in tmp_path.iterdir()] == ["T.csv"]


def test_check_new_file(tmp_path: pathlib.Path) -> None:
    existing = tmp_path / "T.npy"
    existing.write_bytes(b"")
    assert check_new_file(tmp_path / "new.npy", "poses") == tmp_path / "new.npy"
    assert check_new_file(existing, "poses", force=True) == existing
    with pytest.raises(InputError, match="already exists; pass --force"):
        check_new_file(existing, "poses")
    with pytest.raises(InputError, match=r"folder .* does not exist"):
        check_new_file(tmp_path / "missing" / "T.npy", "poses")
    with pytest.raises(InputError, match="it is a folder"):
        check_new_file(tmp_path, "poses")


@pytest.mark.parametrize(
    ("name", "expected"),
    [("fk.png", "png"), ("fk.PDF", "pdf"), ("a.b.svg", "svg"), ("fk.jpg", "jpeg")],
)
def test_figure_format(name: str, expected: str) -> None:
    assert figure_format(name) == expected


@pytest.mark.parametrize("name", ["fk", "fk.txt", "fk.png.bak"])
def test_figure_format_refuses_what_matplotlib_would_not_write(name: str) -> None:
    with pytest.raises(InputError, match=r"names no format poekin knows: \.png, \.pdf, \.svg"):
        figure_format(name, "--plot")


# --- paths poekin cannot write (issue 20) -----------------------------------------------------


def _oserror(code: int) -> Callable[..., Any]:
    def refuse(*_: object, **__: object) -> Any:
        raise OSError(code, os.strerror(code))

    return refuse


@pytest.mark.parametrize(
    ("code", "reason"),
    [
        (errno.EACCES, "folder {folder} is not writable (permission denied)"),
        (errno.EPERM, "folder {folder} is not writable (permission denied)"),
        (errno.EROFS, "folder {folder} is not writable (read-only file system)"),
        (errno.ENOENT, "folder {folder} is not writable (it takes no new files)"),
        (errno.ENOSPC, "No space left on device"),
    ],
)
def test_check_writable_says_why_in_one_line(
    code: int, reason: str, tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(fileio.tempfile, "mkstemp", _oserror(code))
    path = tmp_path / "T.npy"
    with pytest.raises(InputError) as info:
        check_new_file(path, "poses")
    assert str(info.value) == f"cannot write the poses to {path}: " + reason.format(folder=tmp_path)
    with pytest.raises(InputError):  # the write itself says the same
        write_array(path, np.zeros((1, 6)), name="q", columns=[], what="poses")
    assert list(tmp_path.iterdir()) == []


def test_check_writable_of_real_paths(tmp_path: pathlib.Path) -> None:
    (tmp_path / "file").write_text("x")
    (tmp_path / "folder.npy").mkdir()
    cases = {
        tmp_path / "file" / "T.npy": f"{tmp_path / 'file'} is a file, not a folder",
        tmp_path / "no" / "T.npy": f"folder {tmp_path / 'no'} does not exist",
        tmp_path / "folder.npy": "it is a folder; give a file path",
    }
    for path, reason in cases.items():
        with pytest.raises(InputError, match=re.escape(reason)):
            check_new_file(path, "poses", force=True)
    with pytest.raises(InputError, match=r"--output .*folder.npy is a folder; give a file path"):
        read_array(tmp_path / "folder.npy", "--output")
    assert check_writable(tmp_path / "file", "metrics", append=True) == tmp_path / "file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "folder.npy"]  # no probe left
    if os.path.isdir("/proc/self"):  # exists, takes no new files (as root too)
        with pytest.raises(InputError, match="folder /proc is not writable"):
            check_new_file("/proc/T.npy", "poses")


def test_a_write_refused_midway_keeps_the_old_file(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "T.csv"
    path.write_text("the user's data\n")
    monkeypatch.setattr(fileio.os, "replace", _oserror(errno.EROFS))
    with pytest.raises(InputError, match=r"is not writable \(read-only file system\)"):
        write_array(path, np.zeros((2, 6)), name="q", columns=list("abcdef"), what="poses")
    assert path.read_text() == "the user's data\n"
    assert [p.name for p in tmp_path.iterdir()] == ["T.csv"]


def test_save_figure_writes_what_the_suffix_names_with_the_usual_permissions(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure()
    FigureCanvasAgg(fig)
    fig.add_subplot().plot([0, 1], [1, 0])
    for name, magic in (("f.png", b"\x89PNG"), ("f.svg", b"<?xml"), ("f.pdf", b"%PDF")):
        assert save_figure(fig, tmp_path / name, dpi=50).read_bytes().startswith(magic)
    umask = os.umask(0o022)
    os.umask(umask)
    assert (tmp_path / "f.png").stat().st_mode & 0o777 == 0o666 & ~umask  # not mkstemp's 0o600
    monkeypatch.setattr(fig, "savefig", _oserror(errno.ENOSPC))
    with pytest.raises(InputError, match=r"cannot write the figure to .*g\.png: No space left"):
        save_figure(fig, tmp_path / "g.png", dpi=50)
    assert not (tmp_path / "g.png").exists()
