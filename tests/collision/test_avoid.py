"""poekin.collision.avoid: the pairs' distance Jacobians against central differences of the
distances MuJoCo measures, and the active-set programme of poekin.ik.collision_free against
the QP solver daqp (through qpsolvers, as mink uses it)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import load_quiet, ur5e_obstacles
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

import poekin
from poekin.collision.avoid import damper_rows, pair_rows
from poekin.errors import InputError
from poekin.ik.collision_free import inequality_qp

FloatArray = NDArray[np.float64]
FD_STEP = 1e-6
# the cylinder's pairs are MuJoCo's GJK, to its 1e-6 tolerance: the differences of two such
# distances over 2e-6 rad are good to about 1e-6 m/rad
FD_TOL = 1e-5


@pytest.fixture(scope="module")
def ur5e() -> poekin.Tree:
    return poekin.load_tree(load_quiet("universal_robots_ur5e"))


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_jacobian_is_the_distances_derivative(ur5e: poekin.Tree, shape: tuple[int, ...]) -> None:
    """Each row against central differences of tree.distances, column by column, over every
    pair of the robot, a world box and capsule and a sphere held by the tool."""
    rng = np.random.default_rng(len(shape))
    q = rng.uniform(-2.5, 2.5, (*shape, 6))
    found = pair_rows(ur5e, q, ur5e_obstacles())
    P = len(found.pairs)
    assert found.distance.shape == (*shape, P) and found.jacobian.shape == (*shape, P, 6)
    touching = np.abs(found.distance) < 1e-4  # no normal to speak of
    for k in range(6):
        dq = np.zeros(6)
        dq[k] = FD_STEP
        up = ur5e.distances(q + dq, ur5e_obstacles()).distance
        down = ur5e.distances(q - dq, ur5e_obstacles()).distance
        fd = (up - down) / (2 * FD_STEP)
        err = np.where(touching, 0.0, np.abs(fd - found.jacobian[..., k]))
        assert err.max() < FD_TOL, k


def test_fixed_pairs_and_far_pairs_have_zero_rows(ur5e: poekin.Tree) -> None:
    """A pair farther than the activation distance is not measured (inf, zero row); the
    world's obstacles never move, so a row only holds the joints that move the robot's geom."""
    q = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
    found = pair_rows(ur5e, q, ur5e_obstacles(), activation=0.05)
    far = ~np.isfinite(found.distance)
    assert far.any() and np.all(found.jacobian[far] == 0)
    near = np.isfinite(found.distance)
    assert near.any() and np.all(found.distance[near] < 0.05)
    shoulder = found.pairs.index(("shoulder_link", "table"))
    everything = pair_rows(ur5e, q, ur5e_obstacles())
    # the shoulder turns with joint 1 only
    assert np.all(everything.jacobian[shoulder, 1:] == 0)


def test_damper_rows() -> None:
    """``h = -gain (d - margin)``, and no bound for a pair not measured."""
    rows = pair_rows(
        poekin.load_tree(load_quiet("universal_robots_ur5e")),
        np.zeros(6),
        activation=0.1,
    )
    G, h = damper_rows(rows, 0.005, 0.5)
    measured = np.isfinite(rows.distance)
    assert np.array_equal(G, rows.jacobian)
    assert np.allclose(h[measured], -0.5 * (rows.distance[measured] - 0.005), rtol=0, atol=1e-15)
    assert np.all(h[~measured] == -np.inf)


def _programme(
    seed: int, n: int, m: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """A random strictly convex programme whose rows ``x = 0`` meets (h <= 0)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n + 2, n))
    H = A.T @ A + 1e-3 * np.eye(n)
    g = rng.normal(size=n) * 3
    lo = -rng.uniform(0.05, 1.0, n)
    hi = rng.uniform(0.05, 1.0, n)
    lo[rng.random(n) < 0.2] = -np.inf
    G = rng.normal(size=(m, n))
    h = -rng.uniform(0.0, 0.3, m)
    return H, g, lo, hi, G, h


def _check_against_daqp(seed: int, n: int, m: int) -> None:
    qpsolvers = pytest.importorskip("qpsolvers")
    H, g, lo, hi, G, h = _programme(seed, n, m)
    x = inequality_qp(H, g, lo, hi, G, h)
    ref = qpsolvers.solve_qp(
        H, -g, -G if m else None, -h if m else None, lb=lo, ub=hi, solver="daqp"
    )
    assert ref is not None
    assert np.abs(x - ref).max() < 1e-6
    assert np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12)
    assert np.all(G @ x >= h - 1e-12)


# derandomized: a fresh clone draws the same 60 programmes every run
@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.integers(0, 2**32 - 1), st.integers(2, 7), st.integers(0, 6))
def test_inequality_qp_against_daqp(seed: int, n: int, m: int) -> None:
    """The same minimiser as daqp's, within its tolerance."""
    _check_against_daqp(seed, n, m)


# programmes that ended on a vertex of as many working rows as unknowns, where the step the
# KKT system gives is some 4e-14 of rounding: tested against a tolerance of 1e-14, it was taken
# as a step, for ever, and the multipliers never read (stopping 0.04 to 0.16 short)
@pytest.mark.parametrize(("seed", "n", "m"), [(3, 4, 4), (514, 6, 6), (1119, 6, 6)])
def test_inequality_qp_on_a_vertex(seed: int, n: int, m: int) -> None:
    _check_against_daqp(seed, n, m)


def test_inequality_qp_with_a_row_broken_at_zero() -> None:
    """A row that ``x = 0`` breaks is met when the box allows (its slack costs most), and
    broken as little as the box leaves it otherwise."""
    H, g = np.eye(2), np.zeros(2)
    met = inequality_qp(H, g, -np.ones(2), np.ones(2), np.array([[1.0, 0.0]]), np.array([0.5]))
    assert abs(met[0] - 0.5) < 1e-6 and abs(met[1]) < 1e-12
    cut = inequality_qp(H, g, -np.ones(2), np.ones(2), np.array([[1.0, 0.0]]), np.array([2.0]))
    assert abs(cut[0] - 1.0) < 1e-6 and cut[0] <= 1.0  # as far as the box goes


def test_bad_activation(ur5e: poekin.Tree) -> None:
    with pytest.raises(InputError, match="pair_rows: margin must be a number"):
        pair_rows(ur5e, np.zeros(6), activation="near")  # type: ignore[arg-type]
