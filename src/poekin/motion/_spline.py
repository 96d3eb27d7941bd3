"""The cubic spline through waypoints at uniform parameter, as toppra's ``SplineInterpolator``
builds it (scipy's ``CubicSpline(np.linspace(0, 1, N), q, bc_type="not-a-knot")``), in NumPy.

Knots ``s_k = k / (N - 1)``. On ``[s_k, s_k+1]`` joint ``j`` is
``c[0] d^3 + c[1] d^2 + c[2] d + c[3]`` with ``d = s - s_k`` (scipy's ``PPoly`` layout). The
derivatives at the knots solve scipy's tridiagonal system (its not-a-knot end rows included,
Thomas' elimination instead of LAPACK's banded solve); two waypoints give the straight line and
three the parabola through them, as scipy does.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

__all__ = ["Spline", "not_a_knot"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


@dataclasses.dataclass(frozen=True)
class Spline:
    """A piecewise cubic in ``s`` on ``[0, 1]``.

    Attributes:
        knots: ``(N,)`` the breakpoints, ``linspace(0, 1, N)``.
        c: ``(4, N - 1, n)`` each interval's coefficients, highest power first.
    """

    knots: FloatArray
    c: FloatArray

    def interval(self, s: FloatArray) -> IntArray:
        """``(...)`` the interval each ``s`` (``(...)``, in ``[0, 1]``) lies in."""
        idx = np.searchsorted(self.knots, s, side="right") - 1
        out: IntArray = np.clip(idx, 0, len(self.knots) - 2)
        return out

    def __call__(self, s: FloatArray, order: int = 0) -> FloatArray:
        """The ``order``-th derivative (0 to 3) with respect to ``s`` at ``s`` (``(...)``):
        ``(..., n)``."""
        idx = self.interval(s)
        d = (s - self.knots[idx])[..., None]
        c0, c1, c2, c3 = (self.c[p][idx] for p in range(4))
        if order == 0:
            out = ((c0 * d + c1) * d + c2) * d + c3
        elif order == 1:
            out = (3.0 * c0 * d + 2.0 * c1) * d + c2
        elif order == 2:
            out = 6.0 * c0 * d + 2.0 * c1
        else:
            out = 6.0 * c0 + 0.0 * d
        return np.asarray(out, dtype=np.float64)


def _slopes(x: FloatArray, y: FloatArray) -> FloatArray:
    """``(N, n)`` the first derivatives at the knots (scipy's not-a-knot system)."""
    n = len(x)
    dx = np.diff(x)[:, None]
    slope = np.diff(y, axis=0) / dx
    if n == 2:
        return np.repeat(slope, 2, axis=0)
    if n == 3:  # the parabola through the three points
        A = np.array(
            [[1.0, 1.0, 0.0], [dx[1, 0], 2.0 * (dx[0, 0] + dx[1, 0]), dx[0, 0]], [0.0, 1.0, 1.0]]
        )
        b = np.stack([2.0 * slope[0], 3.0 * (dx[0] * slope[1] + dx[1] * slope[0]), 2.0 * slope[1]])
        out: FloatArray = np.linalg.solve(A, b)
        return out
    lower = np.empty(n)  # row i: lower[i] m[i-1] + diag[i] m[i] + upper[i] m[i+1] = b[i]
    diag = np.empty(n)
    upper = np.empty(n)
    b = np.empty_like(y)
    diag[1:-1] = 2.0 * (dx[:-1, 0] + dx[1:, 0])
    upper[1:-1] = dx[:-1, 0]
    lower[1:-1] = dx[1:, 0]
    b[1:-1] = 3.0 * (dx[1:] * slope[:-1] + dx[:-1] * slope[1:])
    d = x[2] - x[0]
    diag[0], upper[0] = dx[1, 0], d
    b[0] = ((dx[0] + 2.0 * d) * dx[1] * slope[0] + dx[0] ** 2 * slope[1]) / d
    d = x[-1] - x[-3]
    diag[-1], lower[-1] = dx[-2, 0], d
    b[-1] = (dx[-1] ** 2 * slope[-2] + (2.0 * d + dx[-1]) * dx[-2] * slope[-1]) / d
    for i in range(1, n):  # Thomas: eliminate the lower diagonal
        w = lower[i] / diag[i - 1]
        diag[i] -= w * upper[i - 1]
        b[i] -= w * b[i - 1]
    m = np.empty_like(y)
    m[-1] = b[-1] / diag[-1]
    for i in range(n - 2, -1, -1):
        m[i] = (b[i] - upper[i] * m[i + 1]) / diag[i]
    return m


def not_a_knot(y: FloatArray) -> Spline:
    """The not-a-knot cubic spline through ``y`` (``(N, n)``, ``N >= 2``) at ``s =
    linspace(0, 1, N)``."""
    x = np.linspace(0.0, 1.0, len(y))
    m = _slopes(x, y)
    dx = np.diff(x)[:, None]
    slope = np.diff(y, axis=0) / dx
    t = (m[:-1] + m[1:] - 2.0 * slope) / dx
    c = np.stack([t / dx, (slope - m[:-1]) / dx - t, m[:-1], y[:-1]])
    return Spline(knots=x, c=c)
