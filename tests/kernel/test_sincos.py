"""poekin.kernel._sincos: the compiled kernel's sine and cosine as array arithmetic, bit for bit the
kernel's (read back through a one-joint chain's FK) and within an ulp of the C library's."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import poekin
from poekin.chain import Chain
from poekin.kernel import _sincos

# a rotation about z: the pose's R[0, 0] is cos q and R[1, 0] is sin q, as the kernel made them
TURN = Chain(("j",), ("revolute",), np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0]]), np.eye(4))
needs_kernel = pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the kernel")


def kernel_sincos(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    T = TURN.fk(x[:, None])
    return T[:, 1, 0], T[:, 0, 0]


@needs_kernel
@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-6e5, 6e5, allow_nan=False), min_size=1, max_size=40))
def test_the_port_gives_the_kernels_bits(values: list[float]) -> None:
    x = np.array(values)
    s, c = _sincos.sincos_one(x, np)
    ks, kc = kernel_sincos(x)
    assert np.array_equal(s.view(np.uint64), ks.view(np.uint64))
    assert np.array_equal(c.view(np.uint64), kc.view(np.uint64))


@needs_kernel
def test_quadrant_edges_and_special_values() -> None:
    k = np.arange(-64, 65)
    x = np.concatenate([k * np.pi / 2, np.nextafter(k * np.pi / 2, np.inf), [0.0, -0.0, 1e-300]])
    s, c = _sincos.sincos_one(x, np)
    ks, kc = kernel_sincos(x)
    assert np.array_equal(s, ks) and np.array_equal(c, kc)


def test_within_an_ulp_of_the_c_library() -> None:
    x = np.random.default_rng(0).uniform(-1e3, 1e3, 100_000)
    s, c = _sincos.sincos(list(x[None]), np)
    spacing = np.spacing(np.maximum(np.abs(np.sin(x)), np.abs(np.cos(x))))
    assert np.all(np.abs(s[0] - np.sin(x)) <= spacing)
    assert np.all(np.abs(c[0] - np.cos(x)) <= spacing)
