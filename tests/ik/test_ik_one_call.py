"""One call at a time (issue 26, item 6): ``chain.ik`` and ``chain.ik_all`` of one target take
a short way to the kernel; they must give what the usual way gives, bit for bit, and leave
every argument they do not take (the same messages, the same warnings) to the usual way."""

from __future__ import annotations

import numpy as np
import pytest

import poekin
from poekin.chain import Chain
from poekin.errors import InputError
from poekin.ik import analytic, numerical

pytestmark = pytest.mark.skipif(not poekin.compiled_kernel(), reason="needs the compiled kernel")


def _targets(chain: Chain, n: int) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = chain.limits[:, 0], chain.limits[:, 1]
    q = np.random.default_rng(26).uniform(lo, hi, (n, chain.n_joints))
    return q, chain.fk(q)


def _same(a: object, b: object) -> None:
    x, y = np.atleast_1d(a), np.atleast_1d(b)
    assert x.shape == y.shape and x.dtype == y.dtype
    assert np.array_equal(x.view(np.uint8), y.view(np.uint8))


def test_one_target_gives_the_usual_bits(ur5e: Chain) -> None:
    q, T = _targets(ur5e, 6)
    near = np.clip(q + 0.01, ur5e.limits[:, 0], ur5e.limits[:, 1])
    for k in range(len(T)):
        for q0 in (None, near[k]):
            quick = ur5e.ik(T[k], q0)
            usual = numerical.solve(ur5e, T[k], q0, options=numerical.settings())
            for name in ("q", "success", "pos_err", "ori_err", "iterations", "attempts"):
                _same(getattr(quick, name), getattr(usual, name))
            assert type(quick) is numerical.IKResult


def test_options_change_between_calls(ur5e: Chain) -> None:
    _, T = _targets(ur5e, 1)
    ur5e.ik(T[0], pos_tol=1e-6)
    ur5e.ik(T[0], pos_tol=1.0)  # an int-valued float: fine
    with pytest.raises(InputError, match="pos_tol must be a number"):
        ur5e.ik(T[0], pos_tol=True)  # == 1, never taken for the 1.0 seen before
    with pytest.raises(InputError, match="max_attempts must be an integer"):
        ur5e.ik(T[0], max_attempts=1.0)
    with pytest.raises(InputError, match="pos_tol must be a number"):
        ur5e.ik(T[0], pos_tol=[1e-6])  # type: ignore[arg-type]  # unhashable
    with pytest.raises(InputError, match="seed must be an integer"):
        ur5e.ik(T[0], seed=-1)
    with pytest.raises(InputError, match="seed must be an integer"):
        ur5e.ik(T[0], seed=True)
    assert ur5e.ik(T[0], max_attempts=1).attempts == 1
    _same(ur5e.ik(T[0], seed=np.uint64(3)).q, ur5e.ik(T[0], seed=3).q)


def test_bad_input_goes_the_usual_way(ur5e: Chain) -> None:
    _, T = _targets(ur5e, 1)
    bad = T[0].copy()
    bad[0, 0] = 2.0
    with pytest.raises(InputError, match="not a rigid transform"):
        ur5e.ik(bad)
    with pytest.raises(InputError, match=r"target pose \(\) is not a rigid transform"):
        ur5e.ik_all(bad)
    with pytest.warns(poekin.JointLimitsWarning):
        ur5e.ik(T[0], ur5e.limits[:, 1] + 0.1)
    _same(ur5e.ik(T[0].T.copy().T).q, ur5e.ik(T[0]).q)  # not C-contiguous: converted


def test_ik_all_of_one_target_is_its_row_of_a_batch(ur5e: Chain) -> None:
    _, T = _targets(ur5e, 5)
    batch = ur5e.ik_all(T)
    for k in range(len(T)):
        one = ur5e.ik_all(T[k])
        _same(one.q, batch.q[k])
        _same(one.valid, batch.valid[k])
        _same(one.pos_err, batch.pos_err[k])
        assert one.geometry is batch.geometry
    shaped = ur5e.ik_all(T.reshape(5, 1, 4, 4))
    _same(shaped.q, batch.q.reshape(5, 1, 8, 6))
    _same(ur5e.ik_all(T[0].tolist()).q, batch.q[0])  # a list: the usual way
    found = analytic.ik_all(ur5e, T[0], refine=False)  # the usual way
    _same(found.q, batch.q[0])


def test_the_call_in_c_gives_the_usual_bits_and_leaves_the_rest_to_python() -> None:
    """After its first call a chain answers ``ik(T[, q0])`` and ``ik_all(T)`` in C (the
    armed ``_ik_quick`` and ``_ik_all_quick``): the same bits as the Python way (a keyword
    the C call does not take), and what it does not take goes to Python as before."""
    from helpers import load_quiet

    chain = poekin.load(load_quiet("universal_robots_ur5e"))  # a chain of its own: not armed
    assert chain._ik_quick is None and chain._ik_all_quick is None
    q, T = _targets(chain, 4)
    first = chain.ik(T[0])
    assert chain._ik_quick is not None
    chain.ik_all(T[0])  # finds the geometry
    chain.ik_all(T[0])  # and the short way's call arms the C one
    assert chain._ik_all_quick is not None
    _same(chain.ik(T[0]).q, first.q)
    for k in range(len(T)):
        for q0 in (None, q[k] + 0.01):
            quick = chain.ik(T[k], q0)
            usual = chain.ik(T[k], q0, seed=0)  # a keyword: the Python way
            assert type(quick) is numerical.IKResult
            for name in ("q", "success", "pos_err", "ori_err", "iterations", "attempts"):
                _same(getattr(quick, name), getattr(usual, name))
            _same(chain.ik(T=T[k], q0=q0).q, usual.q)
        all_quick, all_usual = chain.ik_all(T[k]), chain.ik_all(T[k], refine=True)
        assert type(all_quick) is analytic.IKSolutions
        _same(all_quick.q, all_usual.q)
        _same(all_quick.valid, all_usual.valid)
        _same(all_quick.ori_err, all_usual.ori_err)
        assert all_quick.geometry is all_usual.geometry and all_quick.collides is None
    with pytest.raises(TypeError, match="positional"):
        chain.ik_all(T[0], q[0])  # type: ignore[misc]  # near is keyword-only, in C as in Python
    with pytest.raises(TypeError, match="positional"):
        chain.ik(T[0], q[0], 3)  # type: ignore[misc]
    with pytest.raises(InputError, match="target"):
        chain.ik(T[0][:3])
    ordered = chain.ik_all(T[0], near=q[0])  # near: the Python way orders the branches
    assert np.allclose(ordered.q[0], q[0], atol=1e-8)


def test_an_armed_chain_pickles_and_keeps_its_signature() -> None:
    import inspect
    import pickle

    from helpers import load_quiet

    chain = poekin.load(load_quiet("universal_robots_ur5e"))
    _, T = _targets(chain, 2)
    before, before_all = chain.ik(T[1]), chain.ik_all(T[1])
    again = pickle.loads(pickle.dumps(chain))
    _same(again.ik(T[1]).q, before.q)
    _same(again.ik_all(T[1]).q, before_all.q)
    params = inspect.signature(Chain.ik).parameters
    assert list(params)[:3] == ["self", "T", "q0"] and params["seed"].default == 0
    assert "numerical inverse kinematics" in (Chain.ik.__doc__ or "")
    assert list(inspect.signature(Chain.ik_all).parameters)[:3] == ["self", "T", "near"]
