"""The IK solvers' counter-based random numbers (poekin.ik._rng): SplitMix64's published
outputs, uniform numbers in [0, 1), keys that depend on every bit of a target and q0."""

from __future__ import annotations

import numpy as np

from poekin.ik import _rng

# SplitMix64 from seed 1234567: the first five outputs of the reference implementation
# (Vigna, splitmix64.c; the same as java.util.SplittableRandom's mixer)
REFERENCE = [
    6457827717110365317,
    3203168211198807973,
    9817491932198370423,
    4593380528125082431,
    16408922859458223821,
]


def test_mix_is_splitmix64() -> None:
    state = np.uint64(1234567)
    outs = []
    with np.errstate(over="ignore"):
        for _ in REFERENCE:
            outs.append(int(_rng.mix(state)))
            state = state + _rng.GOLDEN
    assert outs == REFERENCE


def test_uniform_numbers_fill_zero_to_one() -> None:
    keys = _rng.target_keys(0, np.tile(np.eye(4), (20_000, 1, 1)), None)
    assert len(set(keys.tolist())) == 1  # the same target, the same key
    keys = _rng.mix(np.arange(20_000, dtype=np.uint64))
    u = _rng.uniform(keys, np.zeros(20_000, dtype=np.int64), 3)
    assert u.min() >= 0.0 and u.max() < 1.0
    counts, _ = np.histogram(u, bins=10, range=(0.0, 1.0))
    assert np.all(np.abs(counts - 2_000) < 5 * np.sqrt(2_000))  # uniform, to 5 sigma


def test_keys_change_with_any_bit_of_the_target_q0_or_seed() -> None:
    T = np.tile(np.eye(4), (4, 1, 1))
    T[1, 0, 3] = np.nextafter(0.0, 1.0)  # the smallest change of one entry
    T[2, 2, 2] = -T[2, 2, 2]
    T[3, 0, 3] = -0.0  # the sign of zero is a bit too
    keys = _rng.target_keys(0, T, None)
    assert len(set(keys.tolist())) == 4
    q0 = np.zeros((4, 6))
    assert (
        len(
            set(
                _rng.target_keys(
                    0, np.tile(np.eye(4), (4, 1, 1)), q0 + np.arange(4)[:, None]
                ).tolist()
            )
        )
        == 4
    )
    assert _rng.target_keys(1, T[:1], None)[0] != keys[0]
    assert _rng.target_keys(0, T[:1], q0[:1])[0] != keys[0]


def test_attempts_and_joints_draw_different_numbers() -> None:
    key = _rng.target_keys(7, np.eye(4)[None], None)
    draws = {float(_rng.uniform(key, np.array([a]), j)[0]) for a in range(20) for j in range(7)}
    assert len(draws) == 140
