"""Test configuration: tests read the Menagerie models from ../shared/menagerie (never copied),
and the models many test modules share, loaded once."""

from __future__ import annotations

import os
import pathlib
import signal
from typing import Any

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
os.environ.setdefault("MENAGERIE_ROOT", str(REPO.parent / "shared" / "menagerie"))

# Tests stop `poekin view` processes with Ctrl-C (SIGINT). A shell without job control starts a
# background command (`pytest &` in a script) with SIGINT ignored, and an ignored signal stays
# ignored in every child, so those processes would never stop: give the children Python's own
# handler whatever the suite was started from.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def ur5e() -> Any:
    """The Menagerie UR5e's chain to ``attachment_site`` (a Chain: immutable, so shared)."""
    from helpers import load_quiet

    import poekin

    return poekin.load(load_quiet("universal_robots_ur5e"))


@pytest.fixture(scope="session")
def go2() -> Any:
    """The Menagerie go2's whole tree (a Tree: immutable, so shared)."""
    from helpers import load_quiet

    import poekin

    return poekin.load_tree(load_quiet("unitree_go2"))
