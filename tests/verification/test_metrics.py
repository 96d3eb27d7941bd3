"""The metrics CSV: header once, append-only, exact round-trips, clear one-line errors."""

from __future__ import annotations

import csv
import datetime
import os
import pathlib
import re

import numpy as np
import pytest

from poekin.errors import InputError, MetricsFileError
from poekin.verification import metrics
from poekin.verification.metrics import (
    METRICS_HEADER,
    MetricRow,
    append_metrics,
    new_run_id,
    sha256_files,
    today,
)

HEADER_LINE = ",".join(METRICS_HEADER) + "\n"


def _row(**kw: object) -> MetricRow:
    fields: dict[str, object] = {
        "run_id": "abc123def456",
        "date": "2026-11-21",
        "day": "Saturday",
        "experiment": "fk_verify_ur5e",
        "model_sha": "0123456789abcdef",
        "seed": 7,
        "robot": "universal_robots_ur5e",
        "method": "space_poe",
        "n_samples": 1000,
        "passed": True,
        "metric": "max_pos_err_m",
        "value": 1.2e-16,
        "notes": "frame=attachment_site",
    }
    fields.update(kw)
    return MetricRow(**fields)  # type: ignore[arg-type]


def _read(path: pathlib.Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f)
        assert tuple(reader.fieldnames or ()) == METRICS_HEADER
        return list(reader)


def _assert_row_equal(got: dict[str, str], want: MetricRow) -> None:
    assert got["run_id"] == want.run_id
    assert got["date"] == want.date
    assert got["day"] == want.day
    assert got["experiment"] == want.experiment
    assert got["model_sha"] == want.model_sha
    assert int(got["seed"]) == want.seed
    assert got["robot"] == want.robot
    assert got["method"] == want.method
    assert int(got["n_samples"]) == want.n_samples
    assert got["passed"] == ("true" if want.passed else "false")
    assert got["metric"] == want.metric
    assert float(got["value"]) == want.value
    assert got["notes"] == want.notes


def test_header_matches_the_dataclass_fields() -> None:
    assert tuple(MetricRow.__dataclass_fields__) == METRICS_HEADER


def test_new_file_gets_header_once_then_rows(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    rows = [_row(), _row(method="body_poe", passed=False, value=0.4)]
    assert append_metrics(path, rows) == path
    text = path.read_text(encoding="utf-8")
    assert text.startswith(HEADER_LINE)
    assert text.count(HEADER_LINE) == 1
    got = _read(path)
    assert len(got) == 2
    for g, w in zip(got, rows, strict=True):
        _assert_row_equal(g, w)


def test_existing_empty_file_gets_header(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    path.touch()
    append_metrics(str(path), [_row()])
    assert path.read_text(encoding="utf-8").startswith(HEADER_LINE)
    assert len(_read(path)) == 1


def test_empty_batch_on_new_file_writes_header_only(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    append_metrics(path, [])
    assert path.read_text(encoding="utf-8") == HEADER_LINE


def test_second_append_adds_rows_only(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    first = [_row(run_id="run1")]
    second = [_row(run_id="run2", metric=m, value=v) for m, v in [("a", 3e-17), ("b", 0.0)]]
    append_metrics(path, first)
    before = path.read_bytes()
    append_metrics(path, second)
    after = path.read_bytes()
    assert after.startswith(before)  # nothing before the new rows changed
    assert after.count(HEADER_LINE.encode()) == 1
    got = _read(path)
    assert len(got) == 3
    for g, w in zip(got, first + second, strict=True):
        _assert_row_equal(g, w)


@pytest.mark.parametrize(
    "value",
    [1.2e-16, 0.1 + 0.2, 2.220446049250313e-16, 5e-324, 1.7976931348623157e308, 0.0, -0.0, 3.0],
)
def test_values_round_trip_exactly(tmp_path: pathlib.Path, value: float) -> None:
    path = tmp_path / "m.csv"
    append_metrics(path, [_row(value=value)])
    text = _read(path)[0]["value"]
    assert float(text) == value
    assert text == repr(value)


def test_numpy_scalars_are_written_as_plain_numbers(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    row = _row(value=np.float64(1.2e-16), seed=np.int64(3), passed=np.bool_(False))
    append_metrics(path, [row])
    got = _read(path)[0]
    assert got["value"] == "1.2e-16"
    assert got["seed"] == "3"
    assert got["passed"] == "false"


@pytest.mark.parametrize(
    "notes",
    ["a, b, c", "say \"hi\", then 'bye'", "line one\nline two", "crlf\r\nend", "", "ünïcødé ✓"],
)
def test_notes_round_trip(tmp_path: pathlib.Path, notes: str) -> None:
    path = tmp_path / "m.csv"
    append_metrics(path, [_row(notes=notes), _row(notes="after")])
    got = _read(path)
    assert [g["notes"] for g in got] == [notes, "after"]


def test_bad_field_type_writes_nothing(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    with pytest.raises(InputError, match="value"):
        append_metrics(path, [_row(), _row(value="1e-16")])
    with pytest.raises(InputError, match="passed"):
        append_metrics(path, [_row(passed="false")])
    assert not path.exists()


def test_different_header_is_refused_and_file_unchanged(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    original = b"name,score\nalice,3\n"
    path.write_bytes(original)
    with pytest.raises(MetricsFileError) as info:
        append_metrics(path, [_row()])
    msg = str(info.value)
    assert "\n" not in msg
    assert "header differs" in msg
    assert "'name,score'" in msg
    assert "new file path" in msg
    assert path.read_bytes() == original


def test_long_foreign_header_is_quoted_truncated(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    original = ("x" * 500 + "\n").encode()
    path.write_bytes(original)
    with pytest.raises(MetricsFileError) as info:
        append_metrics(path, [_row()])
    assert "x" * 60 + "..." in str(info.value)
    assert "x" * 61 not in str(info.value)
    assert path.read_bytes() == original


def test_header_with_extra_column_is_refused(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    original = (",".join(METRICS_HEADER) + ",extra\n").encode()
    path.write_bytes(original)
    with pytest.raises(MetricsFileError, match="header differs"):
        append_metrics(path, [_row()])
    assert path.read_bytes() == original


def test_file_without_final_newline_is_refused(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    append_metrics(path, [_row()])
    with path.open("ab") as f:
        f.write(b"cut,short")
    before = path.read_bytes()
    with pytest.raises(MetricsFileError, match="newline"):
        append_metrics(path, [_row()])
    assert path.read_bytes() == before


def test_crlf_header_is_accepted(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    path.write_bytes((",".join(METRICS_HEADER) + "\r\n").encode())
    append_metrics(path, [_row()])
    assert len(_read(path)) == 1


def test_missing_directory(tmp_path: pathlib.Path) -> None:
    missing = tmp_path / "no" / "such"
    with pytest.raises(MetricsFileError) as info:
        append_metrics(missing / "m.csv", [_row()])
    msg = str(info.value)
    assert str(missing) in msg
    assert "does not exist" in msg
    assert "\n" not in msg
    assert not missing.exists()


def test_directory_as_path(tmp_path: pathlib.Path) -> None:
    with pytest.raises(MetricsFileError, match="directory") as info:
        append_metrics(tmp_path, [_row()])
    assert str(tmp_path) in str(info.value)


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root ignores file permissions"
)
def test_read_only_file(tmp_path: pathlib.Path) -> None:
    path = tmp_path / "m.csv"
    append_metrics(path, [_row()])
    before = path.read_bytes()
    path.chmod(0o444)
    try:
        with pytest.raises(
            MetricsFileError, match=r"is not writable \(permission denied\)"
        ) as info:
            append_metrics(path, [_row()])
        assert str(path) in str(info.value)
    finally:
        path.chmod(0o644)
    assert path.read_bytes() == before


def test_permission_denied_from_the_os(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The same path as the chmod test, but also when running as root.
    def denied(*args: object, **kwargs: object) -> int:
        raise PermissionError(13, "Permission denied")

    path = tmp_path / "m.csv"
    monkeypatch.setattr(metrics.os, "open", denied)
    with pytest.raises(MetricsFileError) as info:
        append_metrics(path, [_row()])
    monkeypatch.undo()
    assert str(info.value) == (
        f"cannot write metrics to {path}: folder {tmp_path} is not writable (permission denied)"
    )


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_disk_full_is_a_metrics_error() -> None:
    with pytest.raises(MetricsFileError, match="No space left on device") as info:
        append_metrics("/dev/full", [_row()])
    assert "/dev/full" in str(info.value)


def test_failed_header_write_leaves_no_file(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def disk_full(fd: int, data: bytes) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(metrics, "_write_line", disk_full)
    path = tmp_path / "m.csv"
    with pytest.raises(MetricsFileError, match="No space left on device"):
        append_metrics(path, [_row()])
    assert not path.exists()


def test_each_row_is_one_write_of_a_whole_line(
    tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    writes: list[bytes] = []
    real = os.write

    def spy(fd: int, data: bytes | memoryview) -> int:
        writes.append(bytes(data))
        return real(fd, data)

    monkeypatch.setattr(metrics.os, "write", spy)
    path = tmp_path / "m.csv"
    append_metrics(path, [_row(notes="two\nlines"), _row()])
    monkeypatch.undo()
    assert len(writes) == 3  # header, row, row
    assert all(w.endswith(b"\n") for w in writes)
    assert b"".join(writes) == path.read_bytes()


_PROCESSES, _BATCHES, _BATCH = 10, 20, 10


def _append_batches(path: str, who: int, start: object) -> None:
    """One of the concurrent writers: waits for the others, then appends its batches."""
    start.wait()  # type: ignore[attr-defined]
    for b in range(_BATCHES):
        rows = [_row(run_id=f"p{who}", seed=b, notes=f"{who}/{b}/{i}") for i in range(_BATCH)]
        append_metrics(path, rows)


def test_concurrent_appends_lose_nothing_and_do_not_interleave(tmp_path: pathlib.Path) -> None:
    """Ten processes append to one new file at once: one header, every row whole and present,
    and each call's rows together (the file lock spans the header check and the batch)."""
    import multiprocessing

    path = tmp_path / "m.csv"
    ctx = multiprocessing.get_context("fork" if hasattr(os, "fork") else "spawn")
    start = ctx.Barrier(_PROCESSES)
    procs = [
        ctx.Process(target=_append_batches, args=(str(path), k, start)) for k in range(_PROCESSES)
    ]
    for proc in procs:
        proc.start()
    for proc in procs:
        proc.join(60)
        assert proc.exitcode == 0, f"writer {proc.name} exited {proc.exitcode}"
    with path.open(newline="") as f:
        table = list(csv.reader(f))
    assert table[0] == list(METRICS_HEADER)
    rows = table[1:]
    assert len(rows) == _PROCESSES * _BATCHES * _BATCH, "rows lost or header repeated"
    assert all(len(r) == len(METRICS_HEADER) for r in rows), "a row was cut or merged"
    notes = [r[-1] for r in rows]
    assert sorted(notes) == sorted(
        f"{w}/{b}/{i}" for w in range(_PROCESSES) for b in range(_BATCHES) for i in range(_BATCH)
    )
    for k in range(0, len(notes), _BATCH):  # batches are whole and in order
        batch = notes[k : k + _BATCH]
        who, b = batch[0].split("/")[:2]
        assert batch == [f"{who}/{b}/{i}" for i in range(_BATCH)], f"batch at row {k} interleaved"


def test_new_run_id() -> None:
    a, b = new_run_id(), new_run_id()
    assert re.fullmatch(r"[0-9a-f]{12}", a)
    assert a != b


def test_today() -> None:
    date, day = today()
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}", date)
    d = datetime.date.fromisoformat(date)
    assert abs((d - datetime.date.today()).days) <= 1  # a run across midnight
    weekdays = ("Monday", "Tuesday", "Wednesday", "Thursday", "Friday", "Saturday", "Sunday")
    assert day == weekdays[d.weekday()]


# --- sha256_files ---------------------------------------------------------------------------


def _model(root: pathlib.Path) -> list[pathlib.Path]:
    (root / "assets").mkdir(parents=True)
    files = [root / "robot.xml", root / "assets" / "link0.stl", root / "assets" / "link1.stl"]
    files[0].write_text("<mujoco/>")
    files[1].write_bytes(b"\x00\x01\x02" * 100)
    files[2].write_bytes(b"mesh")
    return files


def test_sha_is_16_hex_and_order_independent(tmp_path: pathlib.Path) -> None:
    files = _model(tmp_path)
    h = sha256_files(files, tmp_path)
    assert re.fullmatch(r"[0-9a-f]{16}", h)
    assert sha256_files(reversed(files), tmp_path) == h
    assert sha256_files(iter([files[1], files[2], files[0]]), tmp_path) == h
    assert sha256_files(files + files[:1], tmp_path) == h  # a duplicate counts once


def test_sha_changes_when_one_byte_changes(tmp_path: pathlib.Path) -> None:
    files = _model(tmp_path)
    h = sha256_files(files, tmp_path)
    data = bytearray(files[1].read_bytes())
    data[150] ^= 0x01
    files[1].write_bytes(bytes(data))
    assert sha256_files(files, tmp_path) != h


def test_sha_changes_when_a_file_is_renamed(tmp_path: pathlib.Path) -> None:
    files = _model(tmp_path)
    h = sha256_files(files, tmp_path)
    renamed = files[2].with_name("link2.stl")
    files[2].rename(renamed)
    assert sha256_files([files[0], files[1], renamed], tmp_path) != h


def test_sha_changes_when_a_file_is_left_out(tmp_path: pathlib.Path) -> None:
    files = _model(tmp_path)
    assert sha256_files(files[:2], tmp_path) != sha256_files(files, tmp_path)


def test_sha_does_not_depend_on_where_root_is(tmp_path: pathlib.Path) -> None:
    a, b = tmp_path / "a", tmp_path / "elsewhere" / "b"
    assert sha256_files(_model(a), a) == sha256_files(_model(b), b)


def test_sha_boundaries_are_unambiguous(tmp_path: pathlib.Path) -> None:
    # Same concatenated bytes, split differently between two files: must differ.
    (tmp_path / "x").mkdir()
    (tmp_path / "y").mkdir()
    (tmp_path / "x" / "f1").write_bytes(b"ab")
    (tmp_path / "x" / "f2").write_bytes(b"c")
    (tmp_path / "y" / "f1").write_bytes(b"a")
    (tmp_path / "y" / "f2").write_bytes(b"bc")
    hx = sha256_files([tmp_path / "x" / "f1", tmp_path / "x" / "f2"], tmp_path / "x")
    hy = sha256_files([tmp_path / "y" / "f1", tmp_path / "y" / "f2"], tmp_path / "y")
    assert hx != hy
