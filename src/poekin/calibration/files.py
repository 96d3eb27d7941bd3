"""Calibration files: measurements in (CSV, ``.npz``) and the calibrated parameters out (JSON).

Measurements, one pose per row:

* ``.csv``: a header naming the chain's joints (any order), then ``x, y, z`` (metres) and
  optionally ``qw, qx, qy, qz`` (the measured frame's orientation, a unit quaternion); joint
  readings in radians (metres for prismatic joints), or degrees for revolute joints with
  ``deg=True``. Lines starting with ``#`` are comments.
* ``.npz``: an array ``q`` ``(N, n)`` and either ``T`` ``(N, 4, 4)`` or ``p`` ``(N, 3)``.

Quaternions are normalised; one whose norm is off by more than ``1e-4`` is refused.
"""

from __future__ import annotations

import csv
import io
import json
import os
import pathlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from poekin import lie
from poekin.errors import InputError, did_you_mean
from poekin.io.fileio import is_number

if TYPE_CHECKING:
    from poekin.calibration.report import Calibration
    from poekin.chain import Chain

__all__ = [
    "MEASUREMENT_FORMATS",
    "params_document",
    "read_measurements",
    "write_json",
    "write_measurements",
]

FloatArray = NDArray[np.float64]
MEASUREMENT_FORMATS = (".csv", ".npz")
POSITION = ("x", "y", "z")
QUATERNION = ("qw", "qx", "qy", "qz")
_QUAT_TOL = 1e-4


def read_measurements(
    path: str | os.PathLike[str], chain: Chain, *, deg: bool = False
) -> tuple[FloatArray, FloatArray]:
    """Joint readings ``(N, n)`` (radians, metres) and measured poses ``(N, 4, 4)`` or positions
    ``(N, 3)`` from a ``.csv`` or ``.npz`` file (see the module docstring).

    Raises:
        InputError: unknown suffix, no such file, a missing joint column (naming the nearest),
            an unknown column, a value that is not a number, NaN, or a quaternion that is not
            unit length.
    """
    p = pathlib.Path(path)
    where = f"--measurements {os.fspath(path)}"
    suffix = p.suffix.lower()
    if suffix not in MEASUREMENT_FORMATS:
        said = f"its suffix {p.suffix!r}" if p.suffix else "it has no suffix"
        raise InputError(f"{where}: {said}; measurements are a .csv or .npz file")
    if not p.is_file():
        raise InputError(f"{where}: no such file")
    revolute = np.array([t == "revolute" for t in chain.joint_types])
    if suffix == ".npz":
        q, measured = _read_npz(p, where, chain.n_joints)
    else:
        q, measured = _read_csv(p, where, chain.joint_names)
    if deg:
        q = np.where(revolute, np.radians(q), q)
    return q, measured


def _finite(a: FloatArray, where: str, what: str) -> None:
    bad = ~np.isfinite(a)
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise InputError(f"{where}: {what} of row {row} (from 0) contains NaN or inf")


def _read_npz(p: pathlib.Path, where: str, n: int) -> tuple[FloatArray, FloatArray]:
    try:
        with np.load(p, allow_pickle=False) as archive:
            arrays = {k: np.asarray(archive[k]) for k in archive}
    except (ValueError, OSError) as e:
        raise InputError(f"{where} is not a readable .npz archive: {e}") from None
    if "q" not in arrays or ("T" not in arrays) == ("p" not in arrays):
        listed = ", ".join(repr(k) for k in arrays) or "none"
        raise InputError(
            f"{where} holds {listed}; it needs 'q' (N, {n}) and either 'T' (N, 4, 4) or 'p' (N, 3)"
        )
    key = "T" if "T" in arrays else "p"
    q, m = arrays["q"], arrays[key]
    for name, a in (("q", q), (key, m)):
        if a.dtype.kind not in "biuf":
            raise InputError(f"{where}: {name!r} holds {a.dtype} values, not real numbers")
    q, m = np.asarray(q, dtype=np.float64), np.asarray(m, dtype=np.float64)
    shape = (len(q), 4, 4) if key == "T" else (len(q), 3)
    if q.ndim != 2 or q.shape[1] != n or m.shape != shape:
        raise InputError(
            f"{where}: 'q' must be (N, {n}) and {key!r} {shape[1:]} per pose, got {q.shape} "
            f"and {m.shape}"
        )
    _finite(q, where, "'q'")
    _finite(m.reshape(len(m), -1), where, repr(key))
    return q, m


def _read_csv(p: pathlib.Path, where: str, joints: Sequence[str]) -> tuple[FloatArray, FloatArray]:
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{where} is not a text file (it is not UTF-8)") from None
    numbered = [
        (k + 1, ln)
        for k, ln in enumerate(text.splitlines())
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not numbered:
        raise InputError(f"{where} is empty; write a header and one row per pose")
    line = [k for k, _ in numbered[1:]]  # each row's line in the file, as messages name it
    table = list(csv.reader(io.StringIO("\n".join(ln for _, ln in numbered))))
    header = [h.strip() for h in table[0]]
    known = [*joints, *POSITION, *QUATERNION]
    for h in header:
        if h not in known:
            if is_number(h):
                raise InputError(
                    f"{where}: the first line must be a header naming the columns: "
                    f"{', '.join(joints)}, x, y, z (and qw, qx, qy, qz)"
                )
            raise InputError(f"{where}: unknown column {h!r}: {did_you_mean(h, known)}")
    if len(set(header)) != len(header):
        twice = next(h for h in header if header.count(h) > 1)
        raise InputError(f"{where}: column {twice!r} appears twice")
    for name in [*joints, *POSITION]:
        if name not in header:
            raise InputError(
                f"{where}: no column {name!r}; the header names every joint "
                f"({', '.join(joints)}), then x, y, z (and qw, qx, qy, qz)"
            )
    quats = [h for h in QUATERNION if h in header]
    if quats and len(quats) != 4:
        missing = [h for h in QUATERNION if h not in header]
        raise InputError(
            f"{where}: an orientation needs qw, qx, qy, qz; missing {', '.join(missing)}"
        )
    values = np.zeros((len(table) - 1, len(header)))
    for r, row in enumerate(table[1:]):
        if len(row) != len(header):
            raise InputError(
                f"{where}: line {line[r]} has {len(row)} values, the header {len(header)} columns"
            )
        for c, cell in enumerate(row):
            try:
                values[r, c] = float(cell)
            except ValueError:
                raise InputError(
                    f"{where}: line {line[r]}, column {header[c]!r}: {cell.strip()!r} is not "
                    "a number"
                ) from None
    if not len(values):
        raise InputError(f"{where} has a header but no rows")
    col = {h: c for c, h in enumerate(header)}
    for name in header:
        bad = ~np.isfinite(values[:, col[name]])
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise InputError(f"{where}: line {line[k]}, column {name!r} is NaN or inf")
    q = values[:, [col[j] for j in joints]]
    pos = values[:, [col[k] for k in POSITION]]
    if not quats:
        return q, pos
    quat = values[:, [col[k] for k in QUATERNION]]
    norm = np.linalg.norm(quat, axis=1)
    off = np.abs(norm - 1.0)
    if (off > _QUAT_TOL).any():
        k = int(np.flatnonzero(off > _QUAT_TOL)[0])
        raise InputError(
            f"{where}: line {line[k]}: the quaternion (qw, qx, qy, qz) has norm {norm[k]:.6g}, "
            "not 1; give a unit quaternion, w first"
        )
    T = np.zeros((len(q), 4, 4))
    T[:, :3, :3] = lie.quat_to_rotation(quat / norm[:, None])
    T[:, :3, 3] = pos
    T[:, 3, 3] = 1.0
    return q, T


def write_measurements(
    path: str | os.PathLike[str],
    chain: Chain,
    q: ArrayLike,
    measured: ArrayLike,
    *,
    force: bool = False,
) -> pathlib.Path:
    """Write joint readings ``(N, n)`` and measured poses ``(N, 4, 4)`` or positions ``(N, 3)``
    as the ``.csv`` :func:`read_measurements` reads (17 significant digits: the same float64
    numbers read back). An existing file is replaced only with ``force=True``.

    Raises:
        InputError: ``q`` not ``(N, n)`` for the chain's ``n`` joints, measurements that are not
            ``N`` finite rigid poses or positions, NaN or inf anywhere, or ``path`` taken.
    """
    from poekin._poe import as_joint_values
    from poekin.calibration import check_measurements
    from poekin.io.fileio import check_writable, write_text

    q_arr = as_joint_values(q, chain.n_joints, what="joint readings")
    if q_arr.ndim != 2:
        raise InputError(f"joint readings must be (N, {chain.n_joints}), got shape {q_arr.shape}")
    _finite(q_arr, "write_measurements", "the joint readings")
    measured = check_measurements(measured, len(q_arr))
    target = pathlib.Path(path)
    if target.exists() and not force:
        raise InputError(
            f"{target} already exists; pass force=True to replace it, or choose another path"
        )
    check_writable(target, "the measurements")
    pose = measured.ndim == 3
    columns = [*chain.joint_names, *POSITION, *(QUATERNION if pose else ())]
    values = [q_arr, measured[:, :3, 3] if pose else measured]
    if pose:
        values.append(np.asarray(lie.rotation_to_quat(measured[:, :3, :3]), dtype=np.float64))
    rows = np.concatenate(values, axis=1)
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows([[f"{x:.17g}" for x in row] for row in rows])
    return write_text(path, text.getvalue())


def params_document(result: Calibration) -> dict[str, Any]:
    """The calibrated robot in its own base frame as a PoE parameter file (what
    ``Chain.describe()`` writes, which :func:`poekin.load_params` and ``--params`` read), its
    FK for the encoder readings being the measured frame in the robot's base frame
    (:attr:`~poekin.calibration.Calibration.robot`); beside it, ``registration``: the base
    frame in the measuring frame with its standard errors (:func:`poekin.load_registration`
    reads it; ``fk``, ``diagnose`` and the other commands leave it aside), and ``calibration``,
    the fit's summary (ignored when read)."""
    from poekin.io.fileio import finite_json

    summary = result.summary()
    keep = (
        "robot",
        "frame",
        "measure",
        "poses",
        "identifiable",
        "expected_identifiable",
        "residual_rms_m",
        "residual_rms_rad",
        "heldout_rms_m",
        "heldout_rms_rad",
        "offsets",
    )
    std = result.std()

    def errors(keys: tuple[str, ...]) -> list[float] | None:
        return [std[k] for k in keys] if all(k in std for k in keys) else None

    doc = result.robot.describe()
    doc["registration"] = {
        "note": "T_meas_base: the robot's base frame in the measuring frame (the tracker's), "
        "T_meas_frame(q) = T_meas_base fk(q); std_m, std_rad: its standard errors along and "
        "about the measuring frame's axes",
        "T_meas_base": result.base.tolist(),
        "std_m": errors(("base.x", "base.y", "base.z")),
        "std_rad": errors(("base.rx", "base.ry", "base.rz")),
    }
    doc["calibration"] = {
        "note": "FK of this chain, for the encoder readings, is the measured frame in the "
        "robot's base frame; the joint offsets are in the screws",
        **{k: summary[k] for k in keep},
    }
    return dict(finite_json(doc))


def write_json(path: pathlib.Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` to ``path`` as JSON through a temporary file that replaces it in one step
    (:func:`poekin.io.fileio.write_text`)."""
    from poekin.io.fileio import write_text

    write_text(path, json.dumps(doc, indent=1) + "\n")
