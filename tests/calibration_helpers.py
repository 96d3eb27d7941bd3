"""A plain maximum-likelihood calibration, written independently of poekin.calibration.

The reference for "within 1.25x of a plain fit" (issue #22): a complete PoE-equivalent model
with no attempt at minimality, fitted with ``scipy.optimize.least_squares`` and finite
differences. Each joint gets a free rigid transform before it, as MuJoCo's bodies have::

    T(q) = B exp(d_B) L_1 exp(d_1) J_1(q_1) ... L_n exp(d_n) J_n(q_n) L_tool exp(d_tool)

with ``J_i`` a turn about (or slide along) z, ``L_i`` the model's link transforms, every
``d`` a free twist (6 each: ``6 n + 12`` parameters, redundant). Redundant parameters change
nothing measurable, so its predictions are those of any complete model's maximum-likelihood
fit; the solver's damping keeps the steps finite. Used by the calibration tests and by
``benchmarks/bench_calibrate.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

FloatArray = NDArray[np.float64]


# the keys issue #22 asks of `poekin calibrate --json` and `Calibration.summary()`
JSON_KEYS = (
    "parameters",
    "identifiable",
    "expected_identifiable",
    "condition_number",
    "residual_rms_m",
    "residual_rms_rad",
    "heldout_rms_m",
    "heldout_rms_rad",
    "unidentifiable",
    "std",
    "changes",
)


def _exp(xi: FloatArray) -> FloatArray:
    """A rigid transform from a rotation vector and a translation (not SE(3)'s exp: any smooth
    chart will do)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(xi[:3]).as_matrix()
    T[:3, 3] = xi[3:]
    return T


def _joint(kind: str, q: FloatArray) -> FloatArray:
    """``(N, 4, 4)``: a turn about z, or a slide along z."""
    T = np.zeros((len(q), 4, 4))
    T[:, 3, 3] = 1.0
    if kind == "revolute":
        c, s = np.cos(q), np.sin(q)
        T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1], T[:, 2, 2] = c, -s, s, c, 1.0
    else:
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = 1.0
        T[:, 2, 3] = q
    return T


def _frame(axis: FloatArray, point: FloatArray) -> FloatArray:
    """A frame with z along ``axis`` at ``point``."""
    z = axis / np.linalg.norm(axis)
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = point
    return T


def kabsch(a: FloatArray, b: FloatArray) -> FloatArray:
    """The rigid transform taking points ``a`` onto ``b`` in least squares."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    T = np.eye(4)
    T[:3, :3] = Vt.T @ D @ U.T
    T[:3, 3] = cb - T[:3, :3] @ ca
    return T


def plain_fit(
    screws: FloatArray,
    home: FloatArray,
    joint_types: tuple[str, ...],
    q: FloatArray,
    measured: FloatArray,
    sigma_pos: float,
    sigma_ori: float,
) -> Callable[[FloatArray], FloatArray]:
    """Fit the model of the module docstring to poses ``(N, 4, 4)`` or positions ``(N, 3)``
    (weights ``1/sigma``), starting from the nominal screws and home pose; returns the fitted
    FK, ``q (M, n) -> (M, 4, 4)`` in the measuring frame."""
    n = len(joint_types)
    frames = []
    for S, kind in zip(screws, joint_types, strict=True):
        if kind == "revolute":
            w = S[:3]
            frames.append(_frame(w, np.cross(w, S[3:])))
        else:
            frames.append(_frame(S[3:], np.zeros(3)))
    links = [frames[0]] + [np.linalg.inv(frames[i - 1]) @ frames[i] for i in range(1, n)]
    tool = np.linalg.inv(frames[-1]) @ home
    pose = measured.ndim == 3
    p_meas = measured[:, :3, 3] if pose else measured

    def fk(x: FloatArray, qq: FloatArray, base: FloatArray) -> FloatArray:
        d = x.reshape(n + 2, 6)
        T = np.broadcast_to(base @ _exp(d[0]), (len(qq), 4, 4))
        for i in range(n):
            T = T @ (links[i] @ _exp(d[i + 1])) @ _joint(joint_types[i], qq[:, i])
        return np.asarray(T @ (tool @ _exp(d[n + 1])), dtype=np.float64)

    x0 = np.zeros(6 * (n + 2))
    base = kabsch(fk(x0, q, np.eye(4))[:, :3, 3], p_meas)
    # the measured point's offset from the model's end frame, solved once for the start
    T0 = fk(x0, q, base)
    A = T0[:, :3, :3].reshape(-1, 3)
    offset = np.linalg.lstsq(A, (p_meas - T0[:, :3, 3]).reshape(-1), rcond=None)[0]
    x0[-3:] = offset
    base = kabsch(fk(x0, q, np.eye(4))[:, :3, 3], p_meas)

    def residuals(x: FloatArray) -> FloatArray:
        T = fk(x, q, base)
        r = [((p_meas - T[:, :3, 3]) / sigma_pos).reshape(-1)]
        if pose:
            dR = measured[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)
            r.append((Rotation.from_matrix(dR).as_rotvec() / sigma_ori).reshape(-1))
        return np.concatenate(r)

    solution = least_squares(
        residuals, x0, method="trf", x_scale=1e-3, xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200
    )
    return lambda qq: fk(solution.x, np.atleast_2d(qq), base)
