"""Numbers and tables as the command line prints them: aligned columns, a chosen number of
decimals, no rounding noise (``0.816999999999999`` prints as ``0.817000``, ``-0.0`` as ``0.0``).
JSON output never goes through here: it keeps every bit."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

__all__ = ["DEFAULT_PRECISION", "fixed", "matrix_lines", "sig", "table"]

#: Decimals printed by default: micrometres and microradians.
DEFAULT_PRECISION = 6


def fixed(x: float, precision: int) -> str:
    """``x`` with ``precision`` decimals; a value that rounds to zero prints without a sign."""
    return f"{round(float(x), precision) + 0.0:.{precision}f}"


def sig(x: float) -> str:
    """``x`` with 3 significant digits (an error figure)."""
    return f"{x:.3g}"


def table(
    rows: Sequence[Sequence[str]], *, left: Iterable[int] = (0,), indent: int = 2
) -> list[str]:
    """``rows`` of cells as lines with aligned columns, two spaces apart; the columns in ``left``
    are aligned left, the others right (numbers line up on their decimal point)."""
    if not rows:
        return []
    widths = [max(len(r[c]) for r in rows if c < len(r)) for c in range(max(map(len, rows)))]
    flush_left = set(left)
    lines = []
    for row in rows:
        cells = [
            cell.ljust(widths[c]) if c in flush_left else cell.rjust(widths[c])
            for c, cell in enumerate(row)
        ]
        lines.append((" " * indent + "  ".join(cells)).rstrip())
    return lines


def matrix_lines(M: Any, precision: int, *, indent: int = 2) -> list[str]:
    """The rows of a 2-D array, aligned, with ``precision`` decimals."""
    rows = [[fixed(x, precision) for x in row] for row in np.asarray(M, dtype=np.float64)]
    return table(rows, left=(), indent=indent)
