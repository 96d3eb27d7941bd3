"""docs/ik.md cannot go stale: its Python blocks run in order, in one namespace, and what they
show is checked here (the block conventions of readme_blocks.py)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import readme_blocks as rb

import poekin

PAGE = rb.REPO / "docs" / "ik.md"


@pytest.fixture(scope="module")
def scope() -> dict[str, object]:
    found: dict[str, object] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        for block in rb.blocks(PAGE.read_text()):
            assert block.kind in ("python", "bash"), f"docs/ik.md:{block.start}: {block.kind}"
            if block.kind == "bash":
                assert block.directive == "not run", "a bash block here is shown, not run"
                continue
            exec(compile(block.text, f"docs/ik.md:{block.start + 1}", "exec"), found)
    return found


def test_every_example_does_what_the_page_says(scope: dict) -> None:
    assert scope["found"].success and scope["found"].pos_err < 1e-15
    np.testing.assert_allclose(scope["found"].q, [0.3, -1.2, 1.4, -0.5, 1.1, 0.2], atol=1e-14)
    assert scope["batch"].success.all() and scope["batch"].q.shape == (1000, 6)
    assert 12 <= scope["batch"].iterations.mean() <= 15
    assert max(scope["steps"]) < 0.1
    assert scope["answer"].success.all() and scope["inside"]
    assert not scope["miss"].success and scope["miss"].attempts == 100
    assert round(float(scope["miss"].pos_err), 2) == 1.58
    assert scope["reach"].success.all()
    assert scope["one"].iterations == scope["batch"].iterations[17]
    assert scope["arm"].success and scope["leg"].success and scope["leg"].iterations == 1
