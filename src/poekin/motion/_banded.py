"""Symmetric positive definite block-pentadiagonal systems, solved in ``O(T)``.

The normal equations of a clip couple each frame's variables with those of the two frames on
either side (velocity costs join neighbours, acceleration costs frames two apart): a matrix of
``T x T`` blocks of size ``n`` whose only nonzero blocks are ``H[t, t]``, ``H[t, t + 1]`` and
``H[t, t + 2]`` (and their transposes). Pairs of frames grouped into one block of size ``2n``
make it block-tridiagonal, which block Gaussian elimination without pivoting solves (the block
Thomas algorithm; stable, each Schur complement of a positive definite matrix being positive
definite) with ``T / 2`` solves of size ``2n``, never the dense ``(T n)^2`` matrix.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["solve_pentadiagonal"]

FloatArray = NDArray[np.float64]


def solve_pentadiagonal(D: FloatArray, U1: FloatArray, U2: FloatArray, r: FloatArray) -> FloatArray:
    """``x (T, n)`` with ``H x = r`` for the symmetric positive definite block matrix ``H``.

    Args:
        D: ``(T, n, n)`` the diagonal blocks ``H[t, t]``.
        U1: ``(T - 1, n, n)`` the blocks ``H[t, t + 1]``.
        U2: ``(T - 2, n, n)`` the blocks ``H[t, t + 2]`` (``(0, n, n)`` for ``T < 3``).
        r: ``(T, n)`` the right-hand side.

    Returns:
        ``(T, n)`` the solution.
    """
    T, n = r.shape
    K = (T + 1) // 2  # super-blocks of two frames; an odd clip gets one padding frame
    S = np.zeros((K, 2 * n, 2 * n))
    S[:, n:, n:] = np.eye(n)  # the padding frame, decoupled, solves to 0
    rhs = np.zeros((K, 2 * n))
    S[:, :n, :n] = D[0::2]
    S[: T // 2, n:, n:] = D[1::2]
    S[: T // 2, :n, n:] = U1[0::2]
    S[: T // 2, n:, :n] = np.swapaxes(U1[0::2], 1, 2)
    rhs.reshape(K * 2, n)[:T] = r
    B = np.zeros((max(K - 1, 0), 2 * n, 2 * n))  # H[super k, super k + 1]
    B[:, :n, :n] = U2[0::2][: K - 1]
    B[:, n:, :n] = U1[1::2][: K - 1]
    odd = U2[1::2][: K - 1]
    B[: len(odd), n:, n:] = odd
    x = _tridiagonal(S, B, rhs)
    out: FloatArray = x.reshape(K * 2, n)[:T].copy()
    return out


def _tridiagonal(S: FloatArray, B: FloatArray, y: FloatArray) -> FloatArray:
    """``x (K, m)`` with ``B[k-1]^T x[k-1] + S[k] x[k] + B[k] x[k+1] = y[k]``: block Gaussian
    elimination forward (``S[k]`` replaced by its Schur complement), then back-substitution.
    (Cyclic reduction, the same in ``log2(K)`` batched rounds, was half as fast here: it does
    twice the arithmetic, and solves of this size are bound by it.)"""
    K = len(S)
    G = np.empty_like(B)  # S_k^-1 B_k, S_k the Schur complement
    w = np.empty_like(y)  # S_k^-1 y_k
    Sk, yk = S[0], y[0]
    for k in range(K - 1):
        sol = np.linalg.solve(Sk, np.concatenate([B[k], yk[:, None]], axis=1))
        G[k], w[k] = sol[:, :-1], sol[:, -1]
        Sk = S[k + 1] - B[k].T @ G[k]
        yk = y[k + 1] - B[k].T @ w[k]
    x = np.empty_like(y)
    x[K - 1] = np.linalg.solve(Sk, yk)
    for k in range(K - 2, -1, -1):
        x[k] = w[k] - G[k] @ x[k + 1]
    return x
