"""JAX's transformations through poekin: jit, vmap, grad, jacfwd/jacrev, parameters as a
pytree, and a batch sharded over 8 host devices (bit for bit one device's, no collective)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from typing import Any

import numpy as np
import pytest
from array_libs import load
from helpers import assert_close

from poekin.chain import Chain, ChainParams
from poekin.tree import Tree
from poekin.verification.verify import sample_qpos

LIB_TOL = 1e-15  # as in test_arrays.py
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope="module")
def jax() -> Any:
    return load("jax").module


@pytest.mark.slow
def test_jit_vmap_and_their_compositions(jax: Any, ur5e: Chain, go2: Tree) -> None:
    """jit(fk), vmap(fk), jit(vmap(fk)) on (4, 6) and (2, 2, 6), tree too: the NumPy path's
    poses, each compiled once."""
    q = np.random.default_rng(20).uniform(-6, 6, (4, 6))
    jitted = jax.jit(ur5e.fk)
    batched = jax.jit(jax.vmap(ur5e.fk))
    for x in (q, q.reshape(2, 2, 6)):
        assert_close("jit", np.asarray(jitted(x)), ur5e.fk(x), LIB_TOL)
    assert_close("jit(vmap)", np.asarray(batched(q)), ur5e.fk(q), LIB_TOL)
    assert_close(
        "vmap(vmap)",
        np.asarray(jax.vmap(jax.vmap(ur5e.fk))(q.reshape(2, 2, 6))),
        ur5e.fk(q).reshape(2, 2, 4, 4),
        LIB_TOL,
    )
    qpos = sample_qpos(go2, 4, seed=20)
    tree_fk = jax.jit(jax.vmap(lambda x: go2.fk(x, form="pos_quat")))
    assert_close("tree", np.asarray(tree_fk(qpos)), go2.fk(qpos, form="pos_quat"), LIB_TOL)
    calf = jax.jit(lambda x: go2.jacobian(x, "FL_calf"))
    assert_close("tree jacobian", np.asarray(calf(qpos)), go2.jacobian(qpos, "FL_calf"), LIB_TOL)


@pytest.mark.slow
def test_jacfwd_and_jacrev_agree_with_each_other_and_grad(jax: Any, ur5e: Chain) -> None:
    """A scalar loss's grad equals the contraction of jacrev, and jacfwd equals jacrev."""
    q = np.random.default_rng(21).uniform(-3, 3, 6)
    fwd = np.asarray(jax.jacfwd(ur5e.fk_body)(q))
    rev = np.asarray(jax.jacrev(ur5e.fk_body)(q))
    assert_close("jacfwd vs jacrev", fwd, rev, 1e-14)
    grad = np.asarray(jax.grad(lambda x: ur5e.fk_body(x)[:3, 3].sum())(q))
    assert_close("grad", grad, rev[:3, 3].sum(axis=0), 1e-14)


def test_parameters_are_a_pytree(jax: Any, ur5e: Chain) -> None:
    """ChainParams goes through jax.tree and grad as a container of two arrays (jit: see
    test_first_call_compiles_once), and a calibration step moves the screws."""
    params = ur5e.parameters(like=jax.numpy.zeros(()))
    leaves, treedef = jax.tree.flatten(params)
    assert len(leaves) == 2 and jax.tree.unflatten(treedef, leaves) == params
    q = np.random.default_rng(22).uniform(-3, 3, (8, 6))
    target = ur5e.fk(q)

    def loss(p: ChainParams) -> Any:
        return ((ur5e.fk(q, params=p) - target) ** 2).sum()

    grads = jax.grad(loss)(params)
    assert isinstance(grads, ChainParams) and grads.screws.shape == (6, 6)
    assert float(loss(params)) < 1e-24 and float(jax.numpy.abs(grads.screws).max()) < 1e-10
    moved = jax.tree.map(lambda p: p + 1e-3, params)
    assert float(loss(moved)) > 1e-6


def test_first_call_compiles_once(jax: Any, ur5e: Chain) -> None:
    """jit traces poekin's Python once per shape: later calls do not re-trace."""
    traces = []

    def fk(x: Any) -> Any:
        traces.append(1)
        return ur5e.fk(x)

    jitted = jax.jit(fk)
    for seed in range(3):
        jitted(np.random.default_rng(seed).uniform(-3, 3, (5, 6)))
    assert len(traces) == 1


SHARDED = textwrap.dedent(
    """
    import json, os, re, sys, warnings
    os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=8"
    warnings.simplefilter("ignore")
    import jax, numpy as np, poekin
    from jax import shard_map
    from jax.sharding import NamedSharding, PartitionSpec as P
    jax.config.update("jax_enable_x64", True)
    ur5e, go2 = poekin.load("universal_robots_ur5e"), poekin.load_tree("unitree_go2")
    mesh = jax.make_mesh((8,), ("batch",))
    batch = NamedSharding(mesh, P("batch"))
    q = np.random.default_rng(0).uniform(-6, 6, (1024, 6))
    qpos = poekin.sample_qpos(go2, 1024, seed=0)
    cases = {
        "fk": (ur5e.fk, q),
        "fk_body pos_quat": (lambda x: ur5e.fk_body(x, form="pos_quat"), q),
        "jacobian_world": (ur5e.jacobian_world, q),
        "tree.fk": (go2.fk, qpos),
        "tree.jacobian": (lambda x: go2.jacobian(x, "FL_calf", "body"), qpos),
    }
    out = {"devices": jax.device_count()}
    for name, (f, x) in cases.items():
        one = np.asarray(jax.jit(f)(jax.device_put(x, jax.devices()[0])))
        sharded = jax.jit(shard_map(f, mesh=mesh, in_specs=P("batch"), out_specs=P("batch")))
        by_map = sharded(jax.device_put(x, batch))
        auto = jax.jit(f, in_shardings=batch, out_shardings=batch)
        hlo = sharded.lower(jax.device_put(x, batch)).compile().as_text()
        hlo += auto.lower(x).compile().as_text()
        by_auto = np.asarray(auto(x))
        out[name] = {
            "shard_map_equal": bool(np.array_equal(one, np.asarray(by_map))),
            "spread_over": len(by_map.sharding.device_set),
            "auto_max_diff": float(np.abs(one - by_auto).max()),
            "collectives": sorted(set(re.findall(
                r"all-reduce|all-gather|collective-permute|all-to-all|reduce-scatter", hlo
            ))),
        }
    print(json.dumps(out))
    """
)


@pytest.mark.slow
def test_a_batch_sharded_over_8_devices_is_one_devices_bit_for_bit(jax: Any) -> None:
    """shard_map runs the same program on each device's slice: bit for bit the one-device
    result. jit with a NamedSharding lets XLA re-fuse the partitioned program, and XLA on the
    CPU contracts multiply-adds into FMAs where its fusion allows, so results may differ from
    one device's in the last bit (2.2e-16 measured). Neither has any cross-device
    communication. XLA_FLAGS must be set before JAX starts: a fresh process."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([os.path.join(REPO, "src"), *sys.path])}
    done = subprocess.run(
        [sys.executable, "-c", SHARDED], capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out.pop("devices") == 8
    for name, result in out.items():
        assert result["shard_map_equal"], name
        assert result["spread_over"] == 8, name
        assert result["auto_max_diff"] <= 4.5e-16, (name, result["auto_max_diff"])
        assert result["collectives"] == [], (name, result["collectives"])
