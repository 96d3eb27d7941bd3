"""The files poekin reads and writes for its user: arrays of joint values and results, and figures.

The suffix names the format, case-insensitively; a suffix poekin does not know is refused before
any work is done, naming those it knows. A file is written exactly where the user said, never
under another name, and through a temporary file in the same folder that replaces the target in
one step, so a failed write leaves no half-written file. An existing file is replaced only when
the caller says so (``--force``).

Arrays (:data:`ARRAY_FORMATS`):

* ``.npy``: NumPy's array file, read without unpickling (``allow_pickle=False``);
* ``.npz``: NumPy's archive; read: the one array it holds; written: the result under its name
  (``T`` or ``J``) and the frame or column names beside it;
* ``.csv``: one row per configuration, values separated by commas; an optional first line of
  column names is skipped when read and written when saving; ``#`` starts a comment;
* ``.txt``: the same, separated by whitespace (``np.savetxt``'s format), names in a ``#`` line.

Text values are written with 17 significant digits, so they read back to the same float64 bits.
A result of shape ``(N, ...)`` becomes ``N`` rows of its values in C order.

Figures (:data:`FIGURE_FORMATS`): whatever matplotlib writes from these suffixes.
"""

from __future__ import annotations

import contextlib
import csv
import io
import os
import pathlib
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from poekin.errors import InputError

__all__ = [
    "ARRAY_FORMATS",
    "FIGURE_FORMATS",
    "array_format",
    "check_new_file",
    "figure_format",
    "read_array",
    "write_array",
    "write_text",
]

#: Array file suffixes and what they hold.
ARRAY_FORMATS: Mapping[str, str] = {
    ".npy": "NumPy array",
    ".npz": "NumPy archive",
    ".csv": "comma-separated values",
    ".txt": "whitespace-separated values",
}

#: Figure file suffixes and the matplotlib format each one writes.
FIGURE_FORMATS: Mapping[str, str] = {
    ".png": "png",
    ".pdf": "pdf",
    ".svg": "svg",
    ".jpg": "jpeg",
    ".jpeg": "jpeg",
    ".eps": "eps",
    ".ps": "ps",
    ".tif": "tiff",
    ".tiff": "tiff",
    ".webp": "webp",
}

_NPY_MAGIC = b"\x93NUMPY"
_ZIP_MAGIC = b"PK\x03\x04"


def _suffix(path: str | os.PathLike[str], formats: Mapping[str, str], what: str) -> str:
    suffix = pathlib.Path(path).suffix.lower()
    if suffix not in formats:
        known = ", ".join(formats)
        said = f"its suffix {suffix!r}" if suffix else "it has no suffix"
        raise InputError(f"{what} {os.fspath(path)}: {said} names no format poekin knows: {known}")
    return suffix


def array_format(path: str | os.PathLike[str], what: str) -> str:
    """The suffix of an array file (a key of :data:`ARRAY_FORMATS`), else :class:`InputError`
    naming ``what`` (e.g. ``"--output"``) and the known suffixes."""
    return _suffix(path, ARRAY_FORMATS, what)


def figure_format(path: str | os.PathLike[str], what: str = "figure") -> str:
    """The matplotlib format that the suffix of ``path`` names (``"pdf"`` for ``fig.pdf``), else
    :class:`InputError` listing the suffixes known (:data:`FIGURE_FORMATS`)."""
    return FIGURE_FORMATS[_suffix(path, FIGURE_FORMATS, what)]


def check_new_file(path: str | os.PathLike[str], what: str, *, force: bool = False) -> pathlib.Path:
    """``path`` as a :class:`pathlib.Path` if a file can be written there: its folder exists, it
    is not a folder, and it does not exist yet (unless ``force``). Else :class:`InputError`."""
    p = pathlib.Path(path)
    if not p.parent.is_dir():
        raise InputError(f"cannot write the {what} to {p}: folder {p.parent} does not exist")
    if p.is_dir():
        raise InputError(f"cannot write the {what} to {p}: it is a folder")
    if p.exists() and not force:
        raise InputError(f"{p} already exists; pass --force to replace it, or choose another path")
    return p


# --- reading -----------------------------------------------------------------------------------


def _numbers(arr: NDArray[Any], where: str) -> NDArray[np.float64]:
    if arr.dtype.kind == "c":
        raise InputError(f"{where} holds complex numbers; joint values are real numbers")
    if arr.dtype.kind not in "biuf":
        raise InputError(f"{where} holds {arr.dtype} values, not numbers")
    return np.asarray(arr, dtype=np.float64)


def _read_npy(p: pathlib.Path, where: str) -> NDArray[Any]:
    with p.open("rb") as f:
        head = f.read(len(_NPY_MAGIC))
    if head != _NPY_MAGIC:
        raise InputError(
            f"{where} is not a NumPy .npy file (it does not start with NumPy's header); "
            "save it with numpy.save, or give text a .csv or .txt suffix"
        )
    try:
        arr: NDArray[Any] = np.load(p, allow_pickle=False)
    except ValueError as e:
        if "pickle" in str(e):
            raise InputError(f"{where} holds Python objects, not an array of numbers") from None
        raise InputError(f"{where} is not a readable .npy file: {e}") from None
    return arr


def _read_npz(p: pathlib.Path, where: str) -> NDArray[Any]:
    with p.open("rb") as f:
        head = f.read(len(_ZIP_MAGIC))
    if head != _ZIP_MAGIC:
        raise InputError(f"{where} is not a NumPy .npz archive; save it with numpy.savez")
    try:
        with np.load(p, allow_pickle=False) as archive:
            names = list(archive.keys())
            if len(names) != 1:
                listed = ", ".join(repr(n) for n in names) or "none"
                raise InputError(
                    f"{where} holds {len(names)} arrays ({listed}); give a file with one"
                )
            arr: NDArray[Any] = archive[names[0]]
    except ValueError as e:
        raise InputError(f"{where} is not a readable .npz archive: {e}") from None
    return arr


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_text(p: pathlib.Path, where: str, delimiter: str | None) -> NDArray[Any]:
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{where} is not a text file (it is not UTF-8)") from None
    lines = [ln for ln in text.splitlines() if ln.split("#", 1)[0].strip()]
    if lines and not any(map(_is_number, lines[0].split("#", 1)[0].replace(",", " ").split())):
        lines = lines[1:]  # a first line of column names only
    if not lines:
        raise InputError(f"{where} holds no numbers")
    try:
        arr: NDArray[Any] = np.loadtxt(
            io.StringIO("\n".join(lines)), delimiter=delimiter, comments="#", ndmin=2
        )
    except ValueError as e:
        sep = "commas" if delimiter else "whitespace"
        raise InputError(f"{where}: {e} (values separated by {sep}, one row each)") from None
    return arr


def read_array(path: str | os.PathLike[str], what: str = "--input") -> NDArray[np.float64]:
    """The float64 array in the file at ``path``, read in the format its suffix names.

    Raises:
        InputError: unknown suffix, no such file, not that format, or values that are not real
            numbers (a complex array is refused, not truncated). Never a pickle.
    """
    suffix = array_format(path, what)
    p = pathlib.Path(path)
    where = f"{what} {os.fspath(path)}"
    if not p.is_file():
        raise InputError(f"{where}: no such file")
    if suffix == ".npy":
        arr = _read_npy(p, where)
    elif suffix == ".npz":
        arr = _read_npz(p, where)
    else:
        arr = _read_text(p, where, "," if suffix == ".csv" else None)
    return _numbers(arr, where)


# --- writing -----------------------------------------------------------------------------------


@contextlib.contextmanager
def _replacing(p: pathlib.Path) -> Iterator[IO[bytes]]:
    """A binary file in ``p``'s folder that replaces ``p`` when the block ends without error."""
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _rows(array: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(N, ...)`` as ``N`` rows of values (a single result as one row)."""
    a = np.asarray(array, dtype=np.float64)
    return a.reshape(1, -1) if a.ndim < 2 else a.reshape(a.shape[0], -1)


def write_array(
    path: str | os.PathLike[str],
    array: NDArray[np.float64],
    *,
    name: str,
    columns: Sequence[str],
    extras: Mapping[str, Sequence[str]] | None = None,
) -> pathlib.Path:
    """Write ``array`` to ``path`` in the format its suffix names, replacing any file there.

    Args:
        path: the file; its suffix must be one of :data:`ARRAY_FORMATS` (checked first).
        array: ``(N, ...)`` results, one configuration per leading index.
        name: the array's name in a ``.npz`` archive (``"T"``).
        columns: one name per value of a configuration, for the text formats' header.
        extras: string arrays stored beside it in a ``.npz`` archive (e.g. ``{"frames": ...}``).

    Returns:
        The path written.
    """
    suffix = array_format(path, "output")
    p = pathlib.Path(path)
    with _replacing(p) as f:
        if suffix == ".npy":
            np.save(f, array)
        elif suffix == ".npz":
            arrays: dict[str, Any] = {name: array}
            arrays.update({k: np.array(list(v)) for k, v in (extras or {}).items()})
            np.savez(f, allow_pickle=False, **arrays)
        else:
            rows = _rows(array)
            if rows.shape[1] != len(columns):
                raise ValueError(f"{len(columns)} column names for {rows.shape[1]} values")
            text = io.StringIO(newline="")
            if suffix == ".csv":
                writer = csv.writer(text, lineterminator="\n")
                writer.writerow(columns)
                writer.writerows([[f"{x:.17g}" for x in row] for row in rows])
            else:
                np.savetxt(text, rows, fmt="%.17g", header=" ".join(columns))
            f.write(text.getvalue().encode())
    return p


def write_text(path: str | os.PathLike[str], text: str) -> pathlib.Path:
    """Write ``text`` (UTF-8) to ``path``, replacing any file there in one step (see the module
    docstring). Returns the path written."""
    p = pathlib.Path(path)
    with _replacing(p) as f:
        f.write(text.encode())
    return p
