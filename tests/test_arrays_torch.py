"""PyTorch through poekin: autograd, torch.func, nn.Parameter leaves, torch.compile with
fullgraph=True (no graph break) and torch.export of functions that call chain.fk and tree.fk."""

from __future__ import annotations

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


@pytest.fixture(scope="module")
def torch() -> Any:
    return load("torch").module


def test_autograd_backward_equals_the_jacobian(torch: Any, ur5e: Chain) -> None:
    """loss = sum of the end positions: its gradient is the sum of the world Jacobian's
    linear rows, configuration by configuration."""
    q = np.random.default_rng(30).uniform(-6, 6, (5, 6))
    x = torch.tensor(q, requires_grad=True)
    ur5e.fk(x)[..., :3, 3].sum().backward()
    expected = ur5e.jacobian_world(q)[..., 3:, :].sum(axis=-2)
    assert_close("grad", x.grad.numpy(), expected, 1e-12)


def test_nn_parameters_calibrate(torch: Any, ur5e: Chain) -> None:
    """Parameters as nn.Parameter leaves: one optimiser step towards poses of a perturbed
    chain lowers the loss, and the leaves' gradients are finite."""
    q = torch.tensor(np.random.default_rng(31).uniform(-3, 3, (16, 6)))
    true = ur5e.parameters(like=q)
    target = ur5e.fk(q, params=ChainParams(true.screws, true.home + 0.01))
    home = torch.nn.Parameter(true.home.clone())
    optimiser = torch.optim.SGD([home], lr=0.01)
    losses = []
    for _ in range(2):
        optimiser.zero_grad()
        loss = ((ur5e.fk(q, params=ChainParams(true.screws, home)) - target) ** 2).sum()
        loss.backward()
        assert torch.isfinite(home.grad).all()
        optimiser.step()
        losses.append(float(loss.detach()))
    assert losses[1] < losses[0]


def test_torch_func_vmap_jacrev_and_grad(torch: Any, ur5e: Chain, go2: Tree) -> None:
    q = np.random.default_rng(32).uniform(-6, 6, (4, 6))
    x = torch.tensor(q)
    assert_close("vmap", torch.func.vmap(ur5e.fk)(x).numpy(), ur5e.fk(q), LIB_TOL)
    J = torch.func.vmap(torch.func.jacrev(ur5e.fk))(x)
    assert tuple(J.shape) == (4, 4, 4, 6)
    qpos = sample_qpos(go2, 3, seed=32)
    got = torch.func.vmap(lambda y: go2.jacobian(y, "FL_calf"))(torch.tensor(qpos))
    assert_close("vmap tree jacobian", got.numpy(), go2.jacobian(qpos, "FL_calf"), LIB_TOL)
    grads = torch.func.grad(lambda p: ur5e.fk(x, params=p).sum())(ur5e.parameters(like=x))
    assert isinstance(grads, ChainParams) and tuple(grads.home.shape) == (4, 4)


@pytest.mark.slow
def test_compile_fullgraph_has_no_graph_break(torch: Any, ur5e: Chain, go2: Tree) -> None:
    """torch.compile(fullgraph=True) raises at the first graph break. chain.fk and a Jacobian,
    forward and backward, through Dynamo and AOTAutograd (the aot_eager backend); tree.fk and
    tree.jacobian through Dynamo (the eager backend: a graph break is Dynamo's). Inductor, the
    default backend, compiles the same graphs to C++, which takes seconds for a chain and
    minutes for a tree on two cores: the benchmark times it."""
    q = torch.tensor(np.random.default_rng(33).uniform(-6, 6, (4, 6)), requires_grad=True)
    qpos = torch.tensor(sample_qpos(go2, 4, seed=33))
    torch._dynamo.reset()

    def chain(q: Any) -> Any:
        return ur5e.fk(q).sum() + ur5e.jacobian_body(q).sum()

    value = torch.compile(chain, fullgraph=True, backend="aot_eager")(q)
    assert abs(float(value.detach()) - float(chain(q).detach())) < 1e-12
    value.backward()
    assert torch.isfinite(q.grad).all()

    def tree(qpos: Any) -> Any:
        return go2.fk(qpos, form="pos_quat"), go2.jacobian(qpos, "FL_calf")

    got = torch.compile(tree, fullgraph=True, backend="eager")(qpos)
    bound = torch.compile(go2.fk, fullgraph=True, backend="eager")  # a bound method itself
    assert_close("compiled go2.fk", bound(qpos).numpy(), go2.fk(qpos.numpy()), LIB_TOL)
    assert_close("tree.fk", got[0].numpy(), go2.fk(qpos.numpy(), form="pos_quat"), LIB_TOL)
    assert_close("tree.jacobian", got[1].numpy(), go2.jacobian(qpos.numpy(), "FL_calf"), LIB_TOL)


@pytest.mark.slow
def test_compile_fullgraph_as_the_first_torch_call() -> None:
    """torch.compile(fullgraph=True) of chain.fk and tree.fk as a process's first torch
    computation (issue #20): poekin then resolves PyTorch's array-API namespace inside Dynamo's
    trace, where an import through importlib is refused. A fresh process, since in this one an
    earlier test has already resolved it; the eager backend, since a graph break is Dynamo's."""
    code = textwrap.dedent(
        """
        import sys, warnings
        import numpy as np
        import poekin
        from poekin.verification.verify import sample_qpos
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        chain = poekin.load("universal_robots_ur5e")
        tree = poekin.load_tree("unitree_go2")
        q, qpos = np.random.default_rng(36).uniform(-6, 6, (4, 6)), sample_qpos(tree, 4, seed=36)
        import torch
        print(sorted(m for m in ("array_api_compat", "torch._dynamo") if m in sys.modules))
        fk = torch.compile(chain.fk, fullgraph=True, backend="eager")(torch.tensor(q))
        tree_fk = torch.compile(tree.fk, fullgraph=True, backend="eager")(torch.tensor(qpos))
        print(abs(fk.numpy() - chain.fk(q)).max(), abs(tree_fk.numpy() - tree.fk(qpos)).max())
        """
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    first, errors = done.stdout.splitlines()
    assert first == "[]", f"torch.compile was not the first call: {first} imported before it"
    assert max(map(float, errors.split())) <= LIB_TOL, errors


@pytest.mark.parametrize("strict", [False, True])
def test_export(torch: Any, ur5e: Chain, strict: bool) -> None:
    """torch.export of a module calling chain.fk: the exported program gives the same poses on
    new inputs (strict: traced by Dynamo; non-strict: by Python itself)."""

    class Pose(torch.nn.Module):  # type: ignore[misc]
        def forward(self, q: Any) -> Any:
            return ur5e.fk(q, form="3x4")

    q = np.random.default_rng(34).uniform(-6, 6, (3, 6))
    exported = torch.export.export(Pose(), (torch.tensor(q),), strict=strict)
    again = np.random.default_rng(35).uniform(-6, 6, (3, 6))
    got = exported.module()(torch.tensor(again)).numpy()
    assert_close("exported", got, ur5e.fk(again, form="3x4"), LIB_TOL)
