"""Counter-based random numbers for the solvers' starts: the same bits in NumPy and in C.

Every random number is a pure function of ``(seed, target, q0, attempt, joint)``, never of a
generator's state, so a target gets the same starts alone or anywhere in any batch, on any
thread: SplitMix64's finaliser (Steele, Lea and Flood 2014; the mixer of ``java.util.
SplittableRandom``) in wrapping ``uint64`` arithmetic, which ``_ik_core.h`` repeats.

* :func:`target_keys`: a key per target, mixed from the seed and the bits of the target's top
  three rows (12 doubles, row-major), then of ``q0``'s values if given;
* :func:`uniform`: ``u in [0, 1)`` for one attempt and joint, from the key.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["GOLDEN", "mix", "target_keys", "uniform"]

U64 = NDArray[np.uint64]

GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_SHIFTS = (np.uint64(30), np.uint64(27), np.uint64(31))
_JOINT_BITS = np.uint64(16)  # a counter is attempt << 16 | joint
_MANTISSA = np.uint64(11)  # the top 53 bits make the double
_ULP = 2.0**-53


def mix(x: U64) -> U64:
    """SplitMix64's next output for state ``x``: ``z = x + golden``, then two xor-shift-multiply
    rounds and a last xor-shift (wrapping uint64)."""
    z = np.asarray(x, dtype=np.uint64) + GOLDEN
    z = (z ^ (z >> _SHIFTS[0])) * _M1
    z = (z ^ (z >> _SHIFTS[1])) * _M2
    out: U64 = z ^ (z >> _SHIFTS[2])
    return out


def target_keys(seed: int, T: NDArray[np.float64], q0: NDArray[np.float64] | None) -> U64:
    """``(N,)`` keys of ``(N, 4, 4)`` targets ``T`` (C-contiguous float64) and ``(N, n)``
    starts ``q0`` (or None): ``k = mix(seed)``, then ``k = mix(k ^ bits)`` for each double."""
    with np.errstate(over="ignore"):
        key = np.broadcast_to(mix(np.uint64(seed)), (T.shape[0],))
        rows = np.ascontiguousarray(T[:, :3, :]).reshape(T.shape[0], 12).view(np.uint64)
        for j in range(12):
            key = mix(key ^ rows[:, j])
        if q0 is not None:
            bits = np.ascontiguousarray(q0).view(np.uint64)
            for j in range(bits.shape[1]):
                key = mix(key ^ bits[:, j])
        return np.array(key, dtype=np.uint64)


def uniform(key: U64, attempt: NDArray[np.int64], joint: int) -> NDArray[np.float64]:
    """``u in [0, 1)`` for each key at its attempt (``< 2**48``) and ``joint`` (``< 2**16``):
    the top 53 bits of ``mix(key ^ mix(attempt << 16 | joint))``, times ``2**-53``."""
    with np.errstate(over="ignore"):
        counter = (attempt.astype(np.uint64) << _JOINT_BITS) | np.uint64(joint)
        bits = mix(key ^ mix(counter)) >> _MANTISSA
    out: NDArray[np.float64] = bits.astype(np.float64) * _ULP
    return out
