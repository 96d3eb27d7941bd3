"""Small linear algebra on one BLAS thread.

Calibration and pose planning work on matrices of a few hundred rows by a few dozen columns,
where a thread pool has nothing to share out. OpenBLAS still splits some of their LAPACK calls
(the SVD of a 300 x 30 identification Jacobian) over its threads, and on a machine whose cores
are busy with other work each such call then waits for a core to come free: a 50-pose
calibration of the UR5e took 100 ms of CPU and 220 ms of wall time instead of 20 ms and 30 ms
(a busy 2-core Intel Xeon with AVX-512). :func:`one_thread` runs a block on one BLAS
thread (``threadpoolctl``, which knows OpenBLAS, MKL and BLIS) and restores the count after it.

The limit is process-wide while the block runs: NumPy work in another Python thread runs on one
BLAS thread meanwhile.
"""

from __future__ import annotations

import contextlib
import functools
from typing import Any

__all__ = ["one_thread"]


@functools.cache
def _controller() -> Any:
    """The BLAS libraries NumPy has loaded (found once: ``poekin`` imports NumPy first)."""
    import threadpoolctl

    return threadpoolctl.ThreadpoolController()


def one_thread() -> contextlib.AbstractContextManager[Any]:
    """A context in which BLAS and LAPACK calls run on one thread."""
    limiter: contextlib.AbstractContextManager[Any] = _controller().limit(limits=1, user_api="blas")
    return limiter
