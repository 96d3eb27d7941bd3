"""The compiled kernel's sine and cosine, as array arithmetic: the same bits as ``_kernel.c``.

The kernel computes ``sin`` and ``cos`` itself (``sincos_fast`` in ``_kernel_core.h``): a
Cody-Waite reduction ``x = n pi/2 + (y0 + y1)`` with ``pi/2`` to 99 bits, then fdlibm's
``__kernel_sin`` and ``__kernel_cos`` polynomials (error below 1 ulp). This module does the
same operations in the same order with ``+ - * /`` and ``floor`` on arrays of any library, so
a computation that needs the kernel's bits on its reference path (the inverse kinematics
solver, :mod:`poekin.ik.numerical`) gets them: the kernel is built without fused multiply-add,
and every operation here is one IEEE-754 operation.

Beyond ``|x| >= 2**19`` rad the kernel calls the C library's ``sin`` and ``cos`` and this
module the array library's: there the two may differ in the last bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["REDUCE_MAX", "sincos", "sincos_one"]

INV_PIO2 = 6.36619772367581382433e-01  # 2 / pi
PIO2_1 = 1.57079632673412561417e00  # first 33 bits of pi/2
PIO2_2 = 6.07710050630396597660e-11  # next 33 bits
PIO2_3 = 2.02226624871116645580e-21  # next 33 bits
ROUND_MAGIC = 6755399441055744.0  # 1.5 * 2^52: adding it rounds to an integer
REDUCE_MAX = 524288.0  # 2^19: the reduction is exact below this

S1 = -1.66666666666666324348e-01
S2 = 8.33333333332248946124e-03
S3 = -1.98412698298579493134e-04
S4 = 2.75573137070700676789e-06
S5 = -2.50507602534068634195e-08
S6 = 1.58969099521155010221e-10
C1 = 4.16666666666666019037e-02
C2 = -1.38888888888741095749e-03
C3 = 2.48015872894767294178e-05
C4 = -2.75573143513906633035e-07
C5 = 2.08757232129817482790e-09
C6 = -1.13596475577881948265e-11


def sincos_one(x: Any, xp: Any) -> tuple[Any, Any]:
    """``(sin x, cos x)`` for an array ``x`` of float64, as the kernel computes them."""
    shifted = x * INV_PIO2 + ROUND_MAGIC
    fn = shifted - ROUND_MAGIC  # the nearest integer n to x / (pi/2)
    quadrant = fn - 4.0 * xp.floor(fn * 0.25)  # n mod 4, exactly (the kernel: its low bits)
    r1 = x - fn * PIO2_1  # exact
    w2 = fn * PIO2_2  # exact
    r2 = r1 - w2  # r1 - w2 = r2 + e2 exactly (two-sum)
    bv = r2 - r1
    e2 = (r1 - (r2 - bv)) + (-w2 - bv)
    tail = e2 - fn * PIO2_3
    y0 = r2 + tail  # fast two-sum: |r2| >= |tail|
    y1 = tail - (y0 - r2)
    z = y0 * y0
    v = z * y0
    rs = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
    sr = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * S1)
    rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    cr = w + (((1.0 - w) - hz) + (z * rc - y0 * y1))
    odd = (quadrant == 1.0) | (quadrant == 3.0)
    ss, cc = xp.where(odd, cr, sr), xp.where(odd, sr, cr)
    s = xp.where(quadrant >= 2.0, -ss, ss)
    c = xp.where((quadrant == 1.0) | (quadrant == 2.0), -cc, cc)
    huge = ~(xp.abs(x) < REDUCE_MAX)  # as the kernel's fixup (NaN included)
    return xp.where(huge, xp.sin(x), s), xp.where(huge, xp.cos(x), c)


def sincos(angles: Sequence[Any], xp: Any) -> tuple[list[Any], list[Any]]:
    """The sines and cosines of ``angles``, as :func:`poekin._pose.sincos` returns them."""
    pairs = [sincos_one(a, xp) for a in angles]
    return [s for s, _ in pairs], [c for _, c in pairs]
