"""Test configuration: the tests read the Menagerie models by name from tests/data/menagerie
(XML-only copies, so the suite passes offline in any clone; a user's MENAGERIE_ROOT is not
read), and the models many test modules share, loaded once. The few tests that need meshes
find them with helpers.mesh_menagerie."""

from __future__ import annotations

import os
import pathlib
import signal
from typing import Any

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
os.environ["MENAGERIE_ROOT"] = str(REPO / "tests" / "data" / "menagerie")

# Tests stop `poekin view` processes with Ctrl-C (SIGINT). A shell without job control starts a
# background command (`pytest &` in a script) with SIGINT ignored, and an ignored signal stays
# ignored in every child, so those processes would never stop: give the children Python's own
# handler whatever the suite was started from.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def fresh_machine(tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A user's fresh machine with no network: no MENAGERIE_ROOT, an empty download cache and
    an address nothing answers at. Menagerie names resolve to poekin's built-in UR5e (silently,
    as a user gets it), and any other robot fails instead of downloading. Subprocesses started
    by the test inherit it."""
    monkeypatch.delenv("MENAGERIE_ROOT")
    monkeypatch.setenv("MENAGERIE_CACHE_DIR", str(tmp_path / "menagerie-cache"))
    monkeypatch.setenv("MENAGERIE_BASE_URL", (tmp_path / "nowhere").as_uri())


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
