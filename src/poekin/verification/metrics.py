"""The metrics CSV: one row per (run, method, metric), only ever appended to.

This is the only module that writes metrics files. A file is created with :data:`METRICS_HEADER`
as its first line; later runs append rows below it and never rewrite, truncate or reorder what is
already there. A file whose first line is not that header is refused, untouched.

Columns (:class:`MetricRow` has one field per column, in this order):

========== ======= ==========================================================================
run_id     str     one id per ``poekin`` invocation (:func:`new_run_id`)
date       str     local date, ISO 8601 (``2026-11-21``)
day        str     English weekday name of ``date`` (``Saturday``), see :func:`today`
experiment str     what was run (``fk_verify_ur5e``)
model_sha  str     content hash of the model's files (:func:`sha256_files`)
seed       int     random seed of the joint samples
robot      str     Menagerie name or model file name
method     str     ``space_poe``, ``body_poe``, ...
n_samples  int     number of joint samples
passed     bool    written ``true`` / ``false``
metric     str     ``max_pos_err_m``, ``median_ori_err_rad``, ... (unit in the name)
value      float   written with ``repr`` precision, so ``float(text) == value`` exactly
notes      str     free text; commas, quotes and newlines are quoted by :mod:`csv`
========== ======= ==========================================================================
"""

from __future__ import annotations

import csv
import dataclasses
import datetime
import hashlib
import io
import numbers
import os
import pathlib
import uuid
from collections.abc import Iterable, Sequence

import numpy as np

from poekin.errors import InputError, MetricsFileError, ModelError
from poekin.io.fileio import cannot_write, check_writable
from poekin.verification.verify import VerifyReport

__all__ = [
    "METRICS_HEADER",
    "MetricRow",
    "append_metrics",
    "check_metrics_file",
    "metric_rows",
    "new_run_id",
    "sha256_files",
    "today",
]

METRICS_HEADER: tuple[str, ...] = (
    "run_id",
    "date",
    "day",
    "experiment",
    "model_sha",
    "seed",
    "robot",
    "method",
    "n_samples",
    "passed",
    "metric",
    "value",
    "notes",
)

_HEADER_LINE = ",".join(METRICS_HEADER)
_WEEKDAYS = ("Monday", "Tuesday", "Wednesday", "Thursday", "Friday", "Saturday", "Sunday")
# How much of an existing file's first line is read, and quoted back in an error message.
_FIRST_LINE_READ = 4096
_FIRST_LINE_QUOTED = 60


@dataclasses.dataclass(frozen=True)
class MetricRow:
    """One line of the metrics CSV. Field order and names are :data:`METRICS_HEADER`."""

    run_id: str
    date: str
    day: str
    experiment: str
    model_sha: str
    seed: int
    robot: str
    method: str
    n_samples: int
    passed: bool
    metric: str
    value: float
    notes: str


def new_run_id() -> str:
    """A fresh run id: the first 12 hex characters of a random UUID4 (48 random bits)."""
    return uuid.uuid4().hex[:12]


def today() -> tuple[str, str]:
    """``(date, day)`` for the local date now: ``("2026-11-21", "Saturday")``.

    ``date`` is ISO 8601 (``YYYY-MM-DD``); ``day`` is the English weekday name of that date,
    whatever the process locale is.
    """
    d = datetime.date.today()
    return d.isoformat(), _WEEKDAYS[d.weekday()]


def _csv_line(fields: Sequence[str]) -> bytes:
    """One complete CSV record, ``\\n``-terminated, UTF-8 encoded (``csv`` does the quoting)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(fields)
    return buf.getvalue().encode("utf-8")


def _row_fields(row: MetricRow) -> list[str]:
    """The 13 column texts of ``row``, after checking the non-string fields' types."""
    for name in ("seed", "n_samples"):
        v = getattr(row, name)
        if isinstance(v, bool) or not isinstance(v, numbers.Integral):
            raise InputError(f"MetricRow.{name} must be an int, got {v!r}")
    if not isinstance(row.passed, (bool, np.bool_)):
        raise InputError(f"MetricRow.passed must be a bool, got {row.passed!r}")
    if isinstance(row.value, bool) or not isinstance(row.value, numbers.Real):
        raise InputError(f"MetricRow.value must be a float, got {row.value!r}")
    out: list[str] = []
    for name in METRICS_HEADER:
        v = getattr(row, name)
        if name in ("seed", "n_samples"):
            out.append(str(int(v)))
        elif name == "passed":
            out.append("true" if v else "false")
        elif name == "value":
            out.append(repr(float(v)))  # shortest text that round-trips; also for np.float64
        else:
            out.append(str(v))
    return out


def _lock(fd: int) -> None:
    """Hold an exclusive lock on the whole file until ``fd`` is closed (``flock``, advisory:
    every poekin writer takes it). Without ``fcntl`` (Windows) nothing is locked and appends
    rely on ``O_APPEND`` alone."""
    try:
        import fcntl
    except ImportError:
        return
    fcntl.flock(fd, fcntl.LOCK_EX)


def _write_line(fd: int, data: bytes) -> None:
    """Append ``data`` with one ``write(2)``; finish a short write (only seen as the disk fills)."""
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _os_reason(e: OSError) -> str:
    return e.strerror or str(e) or type(e).__name__


def _read_head(fd: int, size: int) -> tuple[str, bool]:
    """``(first line without its line ending, whether the file ends with a newline)``."""
    os.lseek(fd, 0, os.SEEK_SET)
    head = os.read(fd, _FIRST_LINE_READ)
    first = head.split(b"\n", 1)[0].rstrip(b"\r").decode("utf-8", errors="replace")
    os.lseek(fd, size - 1, os.SEEK_SET)
    ends_with_newline = os.read(fd, 1) == b"\n"
    return first, ends_with_newline


def _check_head(p: pathlib.Path, fd: int, size: int) -> None:
    """Raise MetricsFileError unless the open, non-empty file ``fd`` is a poekin metrics CSV."""
    first, ends_with_newline = _read_head(fd, size)
    if first != _HEADER_LINE:
        cut = len(first) > _FIRST_LINE_QUOTED
        shown = first[:_FIRST_LINE_QUOTED] + ("..." if cut else "")
        raise MetricsFileError(
            f"{p} is not a poekin metrics file: its header differs (found {shown!r}, "
            f"expected '{METRICS_HEADER[0]},{METRICS_HEADER[1]},...'); "
            "poekin only appends to its own metrics files: pass a new file path"
        )
    if not ends_with_newline:
        raise MetricsFileError(
            f"{p} does not end with a newline (was a write cut short?); "
            "repair its last line or pass a new file path"
        )


def _check_location(p: pathlib.Path) -> None:
    where = f"cannot write metrics to {p}"
    if not p.parent.is_dir():
        raise MetricsFileError(
            f"{where}: directory {p.parent} does not exist; create it or choose another path"
        )
    if p.is_dir():
        raise MetricsFileError(f"{where}: it is a directory; pass a file path")


def check_metrics_file(path: str | os.PathLike[str]) -> None:
    """Fail early, without writing, if :func:`append_metrics` would refuse ``path``.

    Raises:
        MetricsFileError: the directory does not exist, ``path`` is a directory, the file or
            its folder is not writable (:func:`poekin.io.fileio.check_writable`), or an existing
            file is not a poekin metrics CSV.
    """
    p = pathlib.Path(path)
    _check_location(p)
    check_writable(p, "metrics", append=True, error=MetricsFileError)
    if not p.is_file() or p.stat().st_size == 0:
        return
    try:
        fd = os.open(p, os.O_RDONLY)
    except OSError as e:
        raise MetricsFileError(f"cannot read metrics file {p}: {_os_reason(e)}") from None
    try:
        _check_head(p, fd, os.fstat(fd).st_size)
    finally:
        os.close(fd)


def append_metrics(path: str | os.PathLike[str], rows: Sequence[MetricRow]) -> pathlib.Path:
    """Append ``rows`` to the metrics CSV at ``path``; write the header first if it is new.

    A missing or empty file gets :data:`METRICS_HEADER` as its first line. An existing file is
    only appended to (``O_APPEND``; never truncated, rewritten or reordered), and only if its
    first line is exactly that header and its last byte is a newline. Each row goes to the OS
    as one ``write`` of its complete CSV line (unbuffered, so nothing is left in a Python buffer
    when this returns). The file is locked (``flock``) from the header check to the last row, so
    processes appending at once neither write the header twice nor interleave their batches.

    All rows are formatted before the file is opened, so a row with a bad field never leaves
    a partial batch. If the header of a file created here cannot be written (e.g. the disk is
    full), the file is removed again.

    Args:
        path: the CSV file; its directory must exist.
        rows: the rows to append, in order (may be empty: the header is still written).

    Returns:
        ``path`` as a :class:`pathlib.Path`.

    Raises:
        MetricsFileError: the directory does not exist, ``path`` is a directory, the file's
            first line is not the metrics header, or the OS refuses (permission, disk full...).
        InputError: a row field of the wrong type (nothing is written then).
    """
    p = pathlib.Path(path)
    lines = [_csv_line(_row_fields(r)) for r in rows]
    where = f"cannot write metrics to {p}"
    _check_location(p)

    flags = os.O_RDWR | os.O_APPEND | os.O_CREAT | getattr(os, "O_BINARY", 0)
    created = False
    try:
        try:
            fd = os.open(p, flags | os.O_EXCL, 0o666)
            created = True
        except FileExistsError:
            fd = os.open(p, flags)
    except IsADirectoryError:
        raise MetricsFileError(f"{where}: it is a directory; pass a file path") from None
    except OSError as e:
        raise MetricsFileError(cannot_write(p, "metrics", e)) from None

    try:
        _lock(fd)  # header check, header and rows as one step among concurrent writers
        size = os.fstat(fd).st_size
        if size > 0:
            _check_head(p, fd, size)
        else:
            try:
                _write_line(fd, _csv_line(METRICS_HEADER))
            except OSError:
                if created:  # leave no empty or half-written file behind
                    os.close(fd)
                    fd = -1
                    p.unlink(missing_ok=True)
                raise
        for line in lines:
            _write_line(fd, line)
    except OSError as e:
        raise MetricsFileError(cannot_write(p, "metrics", e)) from None
    finally:
        if fd >= 0:
            os.close(fd)
    return p


def _relative_posix(file: pathlib.Path, root: pathlib.Path) -> str:
    """``file`` relative to ``root`` in posix form; ``../`` for files outside ``root``."""
    f, r = file.resolve(), root.resolve()
    try:
        return f.relative_to(r).as_posix()
    except ValueError:
        try:
            return pathlib.Path(os.path.relpath(f, r)).as_posix()
        except ValueError:  # another drive on Windows: no relative path exists
            return f.as_posix()


def sha256_files(paths: Iterable[pathlib.Path], root: pathlib.Path) -> str:
    """Content hash of a set of files, for the ``model_sha`` column: 16 hex characters.

    SHA-256 over, for each file in order of its path relative to ``root`` (posix form, so the
    hash is the same on every OS and wherever ``root`` lies), the UTF-8 relative path, a NUL
    byte, the file size in bytes as decimal ASCII, a NUL byte, then the file's bytes. So the
    hash changes when any byte, file name or the set of files changes, and not when only the
    order of ``paths`` or the location of ``root`` does. A path given twice counts once.
    Symlinks are resolved first; a file outside ``root`` is named with ``../``.

    Returns:
        The first 16 hex characters (64 bits) of the digest.

    Raises:
        ModelError: a file cannot be read.
    """
    by_name = {_relative_posix(pathlib.Path(f), root): pathlib.Path(f) for f in paths}
    h = hashlib.sha256()
    for name in sorted(by_name):
        try:
            data = by_name[name].read_bytes()
        except OSError as e:
            raise ModelError(f"cannot hash model file {by_name[name]}: {_os_reason(e)}") from None
        h.update(name.encode("utf-8"))
        h.update(b"\0")
        h.update(str(len(data)).encode("ascii"))
        h.update(b"\0")
        h.update(data)
    return h.hexdigest()[:16]


def metric_rows(
    report: VerifyReport,
    *,
    experiment: str,
    model_sha: str,
    notes: str = "",
    run_id: str | None = None,
) -> list[MetricRow]:
    """One row per (method, metric) of a verification report, all with one run id and date.

    Methods are written in snake case (``space_poe``, ``body_poe``); metrics are
    ``max_pos_err_m``, ``median_pos_err_m``, ``max_ori_err_rad`` and ``median_ori_err_rad``.
    """
    run_id = run_id or new_run_id()
    date, day = today()
    return [
        MetricRow(
            run_id=run_id,
            date=date,
            day=day,
            experiment=experiment,
            model_sha=model_sha,
            seed=report.seed,
            robot=report.robot,
            method=method.replace(" ", "_").lower(),
            n_samples=report.samples,
            passed=report.passed,
            metric=metric,
            value=value,
            notes=notes,
        )
        for method, stats in report.per_method().items()
        for metric, value in stats.items()
    ]
