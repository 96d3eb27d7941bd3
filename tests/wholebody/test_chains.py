"""Chain.ik with a posture (poekin.wholebody.chains): the chain solved as a tree whose FK is
its product of exponentials; the answer checked by MuJoCo, and the posture's optimum checked
by its own condition: no move along the target's null space brings q nearer q0."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import MJ_TOL, load_quiet, mj_pose

import poekin
from poekin.errors import InputError
from poekin.wholebody.chains import chain_tree


@pytest.mark.parametrize(
    ("robot", "frame"),
    [("franka_emika_panda", "hand"), ("universal_robots_ur5e", "attachment_site")],
)
def test_the_chains_tree_has_the_chains_fk(robot: str, frame: str) -> None:
    chain = poekin.load_tree(load_quiet(robot)).chain(frame)
    tree = chain_tree(chain)
    q = poekin.sample_joint_values(chain, 200, seed=1)
    np.testing.assert_allclose(tree.fk(q)[:, -1], chain.fk(q), atol=1e-14, rtol=0)
    assert chain_tree(chain) is tree  # kept with the chain


def test_panda_posture_reaches_the_configuration_nearest_q0() -> None:
    loaded = load_quiet("franka_emika_panda")
    chain = poekin.load_tree(loaded).chain("hand")
    rng = np.random.default_rng(2)
    q0 = np.array([0.3, -0.5, 0.2, -2.0, 0.1, 1.5, 0.7])
    far = q0 + rng.normal(0.0, 0.3, (20, 7))
    T = chain.fk(np.clip(far, chain.limits[:, 0], chain.limits[:, 1]))
    found = chain.ik(T, q0, posture=1.0)
    assert found.success.all() and found.q.shape == (20, 7)
    full = np.concatenate([found.q, np.zeros((20, 2))], axis=1)  # the fingers at 0
    pos, ori = poekin.pose_errors(T, mj_pose(loaded.model, full, "hand"))
    assert pos.max() <= 1e-10 + MJ_TOL and ori.max() <= 1e-10 + MJ_TOL
    # the optimum of min |q - q0| on the solutions: (q - q0) has no part along J's null space
    J = chain.jacobian_space(found.q)
    for Jk, qk in zip(J, found.q, strict=True):
        null = np.linalg.svd(Jk)[2][6:]  # (1, 7): one redundant direction
        assert abs(float((null @ (qk - q0))[0])) <= 1e-8
    plain = chain.ik(T, q0)
    assert np.all(
        np.linalg.norm(found.q - q0, axis=1) <= np.linalg.norm(plain.q - q0, axis=1) + 1e-9
    )


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
def test_posture_needs_q0_and_numpy() -> None:
    chain = poekin.load("universal_robots_ur5e")
    T = chain.fk(np.zeros(6))
    with pytest.raises(InputError, match="posture pulls toward q0: give q0"):
        chain.ik(T, posture=0.5)
    with pytest.raises(InputError, match="posture must be a weight >= 0, or 6 of them"):
        chain.ik(T, np.zeros(6), posture=[0.5, 0.5])
    with pytest.raises(
        InputError, match="it takes no max_total_iterations, params or nearest_branch"
    ):
        chain.ik(T, np.zeros(6), posture=0.5, nearest_branch=True)


def test_as_tree_example_runs() -> None:
    import doctest

    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    tests = doctest.DocTestFinder().find(poekin.Chain.as_tree, globs={"poekin": poekin, "np": np})
    assert tests and tests[0].examples
    for test in tests:
        runner.run(test)
    assert runner.failures == 0
