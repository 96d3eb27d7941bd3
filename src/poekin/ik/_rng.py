"""Counter-based random numbers for the solvers' starts: the same bits in NumPy and in C.

Every random number is a pure function of ``(seed, target, q0, attempt, joint)``, never of a
generator's state, so a target gets the same starts alone or anywhere in any batch, on any
thread: SplitMix64's finaliser (Steele, Lea and Flood 2014; the mixer of ``java.util.
SplittableRandom``) in wrapping ``uint64`` arithmetic, which ``_ik_core.h`` repeats.

One implementation for NumPy (the kernel's reference), JAX (``uint64`` words, inside
``jax.enable_x64``) and PyTorch (``int64`` words with wrapping arithmetic):

* :func:`target_keys`: a key per target, mixed from the seed and the bits of the target's top
  three rows (12 doubles, row-major), then of ``q0``'s values if given;
* :func:`uniform`: ``u in [0, 1)`` for one attempt and joint, from the key.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from numpy.typing import NDArray

from poekin import arrays

__all__ = ["GOLDEN", "mix", "target_keys", "uniform"]

U64 = NDArray[np.uint64]

_GOLDEN = 0x9E3779B97F4A7C15
GOLDEN = np.uint64(_GOLDEN)
_M1 = 0xBF58476D1CE4E5B9
_M2 = 0x94D049BB133111EB
_SHIFTS = (30, 27, 31)
_JOINT_BITS = 16  # a counter is attempt << 16 | joint
_MANTISSA = 11  # the top 53 bits make the double
_ULP = 2.0**-53

# Words are uint64 for NumPy and JAX (JAX inside ``jax.enable_x64``: the caller's job), int64
# for PyTorch (it has no uint64 arithmetic): the same bits, with wrapping + and *; a right
# shift is logical in both (masked after PyTorch's arithmetic shift).


def _signed(x: Any) -> bool:
    return arrays.kind_of(x) == "torch"


def _word(c: int, like: Any, xp: Any) -> Any:
    """The 64-bit constant ``c`` as a word of ``like``'s kind."""
    if xp is np:
        return np.uint64(c)
    if _signed(like):
        return xp.asarray(c - (1 << 64) if c >= 1 << 63 else c, dtype=xp.int64, device=like.device)
    return xp.asarray(c, dtype=xp.uint64)


def _shr(z: Any, k: int, xp: Any) -> Any:
    """``z >> k``, logical."""
    if xp is np:
        return z >> np.uint64(k)
    if _signed(z):
        return (z >> k) & ((1 << (64 - k)) - 1)
    return z >> k


def mix(x: Any, xp: Any = np) -> Any:
    """SplitMix64's next output for state ``x`` (words): ``z = x + golden``, then two
    xor-shift-multiply rounds and a last xor-shift (wrapping 64-bit arithmetic)."""
    if xp is np:
        with np.errstate(over="ignore"):  # NumPy warns of wrapping on scalars
            return _mix(np.asarray(x, dtype=np.uint64), np)
    return _mix(x, xp)


def _mix(z: Any, xp: Any) -> Any:
    z = z + _word(_GOLDEN, z, xp)
    z = (z ^ _shr(z, _SHIFTS[0], xp)) * _word(_M1, z, xp)
    z = (z ^ _shr(z, _SHIFTS[1], xp)) * _word(_M2, z, xp)
    return z ^ _shr(z, _SHIFTS[2], xp)


def bits(x: Any, xp: Any = np) -> Any:
    """The IEEE-754 bits of ``x``'s values as float64, as words (a float32 value's are those
    of the same number in float64: the conversion is exact)."""
    if xp is np:
        return np.ascontiguousarray(x, dtype=np.float64).view(np.uint64)
    wide = xp.astype(x, xp.float64)
    if _signed(x):
        return wide.contiguous().view(xp.int64)
    jax = sys.modules["jax"]
    return jax.lax.bitcast_convert_type(wide, xp.uint64)


def target_keys(seed: int, T: Any, q0: Any | None, xp: Any = np) -> Any:
    """``(...,)`` keys of ``(..., 4, 4)`` targets ``T`` and ``(..., n)`` starts ``q0`` (or
    None), of the same batch shape: ``k = mix(seed)``, then ``k = mix(k ^ bits)`` for each
    double of ``T``'s top three rows (row-major), then of ``q0``'s values."""
    values = [T[..., i, j] for i in range(3) for j in range(4)]
    if q0 is not None:
        values += [q0[..., j] for j in range(q0.shape[-1])]
    key = mix(_word(seed, values[0], xp), xp)
    for value in values:
        key = mix(key ^ bits(value, xp), xp)
    return key


def uniform(key: Any, attempt: Any, joint: int, xp: Any = np) -> Any:
    """``u in [0, 1)`` (float64) for each key at its attempt (integers ``< 2**48``) and
    ``joint`` (``< 2**16``): the top 53 bits of ``mix(key ^ mix(attempt << 16 | joint))``,
    times ``2**-53``."""
    if xp is np:
        counter = (attempt.astype(np.uint64) << np.uint64(_JOINT_BITS)) | np.uint64(joint)
        top: Any = mix(key ^ mix(counter)) >> np.uint64(_MANTISSA)
        return top.astype(np.float64) * _ULP
    counter = (xp.astype(attempt, key.dtype) << _JOINT_BITS) | _word(joint, key, xp)
    top = _shr(mix(key ^ mix(counter, xp), xp), _MANTISSA, xp)
    return xp.astype(top, xp.float64) * _ULP
