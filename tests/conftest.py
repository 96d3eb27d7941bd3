"""Test configuration: tests read the Menagerie models from ../shared/menagerie (never copied)."""

from __future__ import annotations

import os
import pathlib
import signal

REPO = pathlib.Path(__file__).resolve().parents[1]
os.environ.setdefault("MENAGERIE_ROOT", str(REPO.parent / "shared" / "menagerie"))

# Tests stop `poekin view` processes with Ctrl-C (SIGINT). A shell without job control starts a
# background command (`pytest &` in a script) with SIGINT ignored, and an ignored signal stays
# ignored in every child, so those processes would never stop: give the children Python's own
# handler whatever the suite was started from.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
