"""Test configuration: the tests read the Menagerie models by name from poekin's built-in copies
(src/poekin/data: XML only, laid out as a Menagerie clone, so the suite passes offline in any
clone; a user's MENAGERIE_ROOT is not read), through MENAGERIE_ROOT as a user's clone is read;
``fresh_machine`` reads them as a user without one does. And the models many test modules
share, loaded once. The few tests that need meshes find them with helpers.mesh_menagerie."""

from __future__ import annotations

import os
import pathlib
import re
import signal
import sys
from typing import Any

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
os.environ["MENAGERIE_ROOT"] = str(REPO / "src" / "poekin" / "data")

# Tests stop `poekin view` processes with Ctrl-C (SIGINT). A shell without job control starts a
# background command (`pytest &` in a script) with SIGINT ignored, and an ignored signal stays
# ignored in every child, so those processes would never stop: give the children Python's own
# handler whatever the suite was started from.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


# README: Test. The command that installs what the tests import.
DEV_INSTALL = 'pip install -e ".[dev,jax,torch]"'


@pytest.hookimpl(tryfirst=True)  # before the terminal reports the module's own error
def pytest_collectreport(report: pytest.CollectReport) -> None:
    """A test module that cannot import a package (the suite run without poekin's development
    install, or by the pytest of another Python, which then fails to collect every module):
    stop at the first, with one line that names the package, the Python and the install.
    Under pytest-xdist the controller says it, not each worker."""
    if not report.failed or os.environ.get("PYTEST_XDIST_WORKER"):
        return
    missing = re.search(r"No module named '([\w.]+)'", report.longreprtext)
    if missing is None:
        return
    pytest.exit(
        f"{report.nodeid} cannot import {missing.group(1)!r} in {sys.executable}: the tests need "
        f"poekin's development install in the Python that runs them: in the checkout, "
        f"{DEV_INSTALL} (README: Test), then pytest",
        returncode=pytest.ExitCode.USAGE_ERROR,
    )


@pytest.fixture
def fresh_machine(tmp_path: pathlib.Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A user's fresh machine with no network: no MENAGERIE_ROOT, an empty download cache and
    an address nothing answers at. Menagerie names resolve to poekin's built-in robots
    (silently, as a user gets them), and any other robot fails instead of downloading.
    Subprocesses started by the test inherit it."""
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
