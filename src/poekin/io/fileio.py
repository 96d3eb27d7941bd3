"""The files poekin reads and writes for its user: arrays of joint values and results, and figures.

The suffix names the format, case-insensitively; a suffix poekin does not know is refused before
any work is done, naming those it knows. So is a path poekin cannot write to: a folder that does
not exist or takes no new files (permission denied, a read-only file system, ``/proc``), or a
folder given where a file is expected (:func:`check_new_file`, :func:`check_writable`). A file is
written exactly where the user said, never under another name, and through a temporary file in
the same folder that replaces the target in one step, so a failed write leaves no half-written
file; what the OS refuses at write time becomes one :class:`~poekin.errors.InputError` line that
names the path and the reason (:func:`cannot_write`). An existing file is replaced only when the
caller says so (``--force``).

Arrays (:data:`ARRAY_FORMATS`):

* ``.npy``: NumPy's array file, read without unpickling (``allow_pickle=False``);
* ``.npz``: NumPy's archive; read: the one array it holds (or the one the reader names, among
  several); written: the result under its name
  (``T``, ``J`` or ``q``) and what describes it beside it (frame or column names; ``poekin ik``'s
  success flags and residuals);
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
import dataclasses
import errno
import functools
import io
import os
import pathlib
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from typing import IO, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin.errors import InputError, PoekinError

__all__ = [
    "ARRAY_FORMATS",
    "FIGURE_FORMATS",
    "Table",
    "array_format",
    "cannot_write",
    "check_new_file",
    "check_writable",
    "figure_format",
    "finite_json",
    "is_number",
    "read_array",
    "read_table",
    "save_figure",
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
    p = pathlib.Path(path)
    known = ", ".join(formats)
    if p.is_dir():
        raise InputError(
            f"{what} {os.fspath(path)} is a folder; give a file path ending in one of {known}"
        )
    suffix = p.suffix.lower()
    if suffix not in formats:
        said = f"its suffix {suffix!r} names" if suffix else "it has no suffix, so it names"
        raise InputError(f"{what} {os.fspath(path)}: {said} no format poekin knows: {known}")
    return suffix


def array_format(path: str | os.PathLike[str], what: str) -> str:
    """The suffix of an array file (a key of :data:`ARRAY_FORMATS`), else :class:`InputError`
    naming ``what`` (e.g. ``"--output"``) and the known suffixes."""
    return _suffix(path, ARRAY_FORMATS, what)


def figure_format(path: str | os.PathLike[str], what: str = "figure") -> str:
    """The matplotlib format that the suffix of ``path`` names (``"pdf"`` for ``fig.pdf``), else
    :class:`InputError` listing the suffixes known (:data:`FIGURE_FORMATS`)."""
    return FIGURE_FORMATS[_suffix(path, FIGURE_FORMATS, what)]


def _not_a_folder(p: pathlib.Path) -> pathlib.Path | None:
    """The first of ``p``'s folders, from the root down, that exists but is not a folder."""
    for parent in reversed(p.parents):
        if parent.exists() and not parent.is_dir():
            return parent
    return None


def _reason(e: OSError, p: pathlib.Path) -> str:
    """Why the OS refused to write the file ``p`` (``e``), in words, naming what it refused."""
    folder = p.parent
    # an existing file refused itself; a new one (or a probe beside it), its folder
    named = e.filename is None or pathlib.Path(os.fsdecode(e.filename)) == p
    subject = f"{p}" if named and p.exists() else f"folder {folder}"
    code = e.errno
    if code in (errno.EACCES, errno.EPERM):
        return f"{subject} is not writable (permission denied)"
    if code == errno.EROFS:
        return f"{subject} is not writable (read-only file system)"
    if code == errno.EISDIR or p.is_dir():
        return "it is a folder; give a file path"
    if code == errno.ENOTDIR:
        blocker = _not_a_folder(p)
        return f"{blocker or folder} is a file, not a folder"
    if code == errno.ENOENT:
        if folder.is_dir():  # /proc: the folder is there but takes no new files
            return f"folder {folder} is not writable (it takes no new files)"
        return f"folder {folder} does not exist; create it or choose another path"
    return e.strerror or str(e) or type(e).__name__


def cannot_write(path: str | os.PathLike[str], what: str, e: OSError) -> str:
    """One line for an :class:`OSError` ``e`` met writing ``what`` (``"the plot"``) to ``path``:
    ``"cannot write the plot to /proc/fk.png: folder /proc is not writable (permission
    denied)"``. The reason names what was refused: permission, a read-only file system, a folder
    that takes no new files or does not exist, a file where a folder should be, a folder where a
    file should be; else the OS's own words (``No space left on device``)."""
    p = pathlib.Path(path)
    return f"cannot write {what} to {p}: {_reason(e, p)}"


def check_writable(
    path: str | os.PathLike[str],
    what: str,
    *,
    append: bool = False,
    error: type[PoekinError] = InputError,
) -> pathlib.Path:
    """``path`` as a :class:`pathlib.Path` if ``what`` (``"the plot"``) can be written there
    now, else ``error`` with :func:`cannot_write`'s line. Nothing is written: a file is made in
    its folder and removed again (a file is written through one, see the module docstring); with
    ``append``, an existing file is opened for appending instead, and closed.

    The only reliable test: permission bits do not tell what root may do, nor that ``/proc``
    takes no new files, nor that a file system is mounted read-only."""
    p = pathlib.Path(path)
    try:
        if p.is_dir():
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), os.fspath(p))
        if append and p.exists():
            os.close(os.open(p, os.O_WRONLY | os.O_APPEND))
        else:
            fd, probe = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".part")
            os.close(fd)
            os.unlink(probe)
    except OSError as e:
        raise error(cannot_write(p, what, e)) from None
    return p


def check_new_file(path: str | os.PathLike[str], what: str, *, force: bool = False) -> pathlib.Path:
    """``path`` as a :class:`pathlib.Path` if the ``what`` (``"plot"``) can be written there: it
    does not exist yet (unless ``force``) and :func:`check_writable` says its folder takes it.
    Else :class:`InputError`."""
    p = pathlib.Path(path)
    if p.exists() and not p.is_dir() and not force:
        raise InputError(f"{p} already exists; pass --force to replace it, or choose another path")
    return check_writable(p, f"the {what}")


# --- reading -----------------------------------------------------------------------------------


def _numbers(arr: NDArray[Any], where: str) -> NDArray[np.float64]:
    if arr.dtype.kind == "c":
        raise InputError(f"{where} holds complex numbers; give real numbers")
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


def _read_npz(p: pathlib.Path, where: str, name: str | None) -> NDArray[Any]:
    with p.open("rb") as f:
        head = f.read(len(_ZIP_MAGIC))
    if head != _ZIP_MAGIC:
        raise InputError(f"{where} is not a NumPy .npz archive; save it with numpy.savez")
    try:
        with np.load(p, allow_pickle=False) as archive:
            names = list(archive.keys())
            if len(names) != 1 and name not in names:
                listed = ", ".join(repr(n) for n in names) or "none"
                named = f", or one with an array named {name!r}" if name else ""
                raise InputError(
                    f"{where} holds {len(names)} arrays ({listed}); give a file with one{named}"
                )
            arr: NDArray[Any] = archive[names[0] if len(names) == 1 else name]
    except ValueError as e:
        raise InputError(f"{where} is not a readable .npz archive: {e}") from None
    return arr


def is_number(text: str) -> bool:
    """Whether ``text`` reads as a number (``float`` takes it)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclasses.dataclass(frozen=True)
class Table:
    """A text file's numbers: ``values`` ``(rows, columns)``, the ``header`` naming the columns
    if its first line names them (None if it holds numbers), and ``lines``, each row's line in
    the file (from 1, blank lines and ``#`` comments counted), by which messages name a row."""

    header: tuple[str, ...] | None
    values: NDArray[np.float64]
    lines: tuple[int, ...]
    where: str

    def at(self, row: int) -> str:
        """``where`` and the file line of ``row``: ``--input poses.csv line 7``."""
        return f"{self.where} line {self.lines[row]}"


def read_table(path: str | os.PathLike[str], what: str = "--input") -> Table:
    """The ``.csv`` or ``.txt`` file at ``path`` as a :class:`Table`; see :func:`read_array`
    for what is refused."""
    suffix, p, where = _existing(path, what)
    if suffix not in (".csv", ".txt"):
        raise InputError(f"{where}: a table is a .csv or .txt file")
    return _read_text(p, where, "," if suffix == ".csv" else None)


def _existing(path: str | os.PathLike[str], what: str) -> tuple[str, pathlib.Path, str]:
    """An array file's suffix (:func:`array_format`), its path, and how messages name it
    (``--input q.csv``); :class:`InputError` if no file is there."""
    suffix = array_format(path, what)
    p = pathlib.Path(path)
    where = f"{what} {os.fspath(path)}"
    if not p.is_file():
        raise InputError(f"{where}: no such file")
    return suffix, p, where


def _read_text(p: pathlib.Path, where: str, delimiter: str | None) -> Table:
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{where} is not a text file (it is not UTF-8)") from None
    numbered = [
        (k + 1, ln.split("#", 1)[0])
        for k, ln in enumerate(text.splitlines())
        if ln.split("#", 1)[0].strip()
    ]
    header = None
    if numbered and not any(map(is_number, numbered[0][1].replace(",", " ").split())):
        cells = numbered[0][1].split(delimiter) if delimiter else numbered[0][1].split()
        header = tuple(c.strip() for c in cells)
        numbered = numbered[1:]  # a first line of column names only
    if not numbered:
        raise InputError(f"{where} holds no numbers")
    try:  # every row at once; only a file it refuses is read again, line by line, to say where
        values = np.loadtxt(
            io.StringIO("\n".join(content for _, content in numbered)),
            delimiter=delimiter,
            ndmin=2,
        )
    except ValueError as e:
        _refused_line(numbered, where, delimiter, header)
        sep = "commas" if delimiter else "whitespace"
        raise InputError(f"{where}: {e} (values separated by {sep}, one row each)") from None
    if header is not None and len(header) != values.shape[1]:
        raise InputError(
            f"{where}: the header names {len(header)} columns, line {numbered[0][0]} holds "
            f"{values.shape[1]} values"
        )
    return Table(header, values, tuple(line for line, _ in numbered), where)


def _refused_line(
    numbered: list[tuple[int, str]],
    where: str,
    delimiter: str | None,
    header: tuple[str, ...] | None = None,
) -> None:
    """Raise :class:`InputError` naming the first of the file's ``(line, content)`` rows that
    is not numbers (the line as the file counts it, and the column by its header name or its
    place from 1), or whose count of values differs from the first row's."""
    sep = "commas" if delimiter else "whitespace"
    width = None
    for line, content in numbered:
        try:
            row = np.loadtxt(io.StringIO(content), delimiter=delimiter, ndmin=1)
        except ValueError as e:
            cells = content.split(delimiter) if delimiter else content.split()
            for k, cell in enumerate(cells):
                if not is_number(cell.strip()):
                    column = repr(header[k]) if header is not None and k < len(header) else k + 1
                    raise InputError(
                        f"{where} line {line}, column {column}: {cell.strip()!r} is not a "
                        f"number (values separated by {sep})"
                    ) from None
            raise InputError(f"{where} line {line}: {e} (values separated by {sep})") from None
        if width is not None and len(row) != width:
            raise InputError(
                f"{where} line {line} holds {len(row)} values, line {numbered[0][0]} "
                f"{width}: every row needs as many"
            )
        width = len(row)


def read_array(
    path: str | os.PathLike[str], what: str = "--input", *, name: str | None = None
) -> NDArray[np.float64]:
    """The float64 array in the file at ``path``, read in the format its suffix names: of a
    ``.npz`` archive, the one array it holds, or the one called ``name`` among several (the
    joint values ``q`` that ``poekin ik`` writes beside its flags, the poses ``T``).

    Raises:
        InputError: unknown suffix, no such file, not that format, no values (an empty array:
            a command has no rows to compute), or values that are not real numbers (a complex
            array is refused, not truncated). Never a pickle.
    """
    suffix, p, where = _existing(path, what)
    if suffix == ".npy":
        arr = _read_npy(p, where)
    elif suffix == ".npz":
        arr = _read_npz(p, where, name)
    else:
        arr = _read_text(p, where, "," if suffix == ".csv" else None).values
    if arr.size == 0:  # as an empty text file: no rows to compute, nothing to write
        raise InputError(f"{where} holds no numbers (an array of shape {arr.shape})")
    return _numbers(arr, where)


# --- writing -----------------------------------------------------------------------------------


@functools.cache
def _new_file_mode() -> int:
    """The permissions ``open()`` gives a new file: ``0o666`` less the process's umask (read
    by setting it and setting it back, once)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def _replacing(p: pathlib.Path, what: str) -> Iterator[IO[bytes]]:
    """A binary file in ``p``'s folder that replaces ``p`` when the block ends without error,
    with the permissions a file made by ``open()`` would have. What the OS refuses, while the
    block writes or after, becomes :class:`InputError` (:func:`cannot_write`); ``p`` is left
    as it was and no temporary file stays."""
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".part")
    except OSError as e:
        raise InputError(cannot_write(p, what, e)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            if hasattr(os, "fchmod"):  # POSIX (Windows: Python 3.13 on)
                os.fchmod(f.fileno(), _new_file_mode())
            yield f
        os.replace(tmp, p)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise InputError(cannot_write(p, what, e)) from None
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
    extras: Mapping[str, ArrayLike] | None = None,
    what: str = "",
) -> pathlib.Path:
    """Write ``array`` to ``path`` in the format its suffix names, replacing any file there.

    Args:
        path: the file; its suffix must be one of :data:`ARRAY_FORMATS` (checked first).
        array: ``(N, ...)`` results, one configuration per leading index.
        name: the array's name in a ``.npz`` archive (``"T"``).
        columns: one name per value of a configuration, for the text formats' header.
        extras: arrays stored beside it in a ``.npz`` archive: names (``{"frames": ...}``),
            flags, residuals.
        what: what it is, for an error message (``"poses"``); default ``"<name> array"``.

    Returns:
        The path written.

    Raises:
        InputError: an unknown suffix, or what the OS refuses (:func:`cannot_write`); the file
            at ``path`` is then left as it was.
    """
    suffix = array_format(path, "output")
    p = pathlib.Path(path)
    with _replacing(p, f"the {what or name + ' array'}") as f:
        if suffix == ".npy":
            np.save(f, array)
        elif suffix == ".npz":
            arrays: dict[str, Any] = {name: array}
            arrays.update({k: np.asarray(v) for k, v in (extras or {}).items()})
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


def save_figure(
    figure: Any, path: str | os.PathLike[str], *, dpi: float, what: str = "figure"
) -> pathlib.Path:
    """Save the matplotlib ``figure`` to ``path`` in the format its suffix names
    (:data:`FIGURE_FORMATS`), replacing any file there, as :func:`write_array` writes.

    Raises:
        InputError: an unknown suffix, or what the OS refuses (:func:`cannot_write`).
    """
    file_format = figure_format(path, what)
    p = pathlib.Path(path)
    with _replacing(p, f"the {what}") as f:
        figure.savefig(f, format=file_format, dpi=dpi)
    return p


def write_text(path: str | os.PathLike[str], text: str, *, what: str = "file") -> pathlib.Path:
    """Write ``text`` (UTF-8) to ``path``, replacing any file there in one step (see the module
    docstring). Returns the path written."""
    p = pathlib.Path(path)
    with _replacing(p, f"the {what}") as f:
        f.write(text.encode())
    return p


def finite_json(obj: Any) -> Any:
    """Replace non-finite floats (unlimited joints) with None so the output is strict JSON."""
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [finite_json(v) for v in obj]
    return obj
