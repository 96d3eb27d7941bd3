"""Test configuration: tests read the Menagerie models from ../shared/menagerie (never copied)."""

from __future__ import annotations

import os
import pathlib

REPO = pathlib.Path(__file__).resolve().parents[1]
os.environ.setdefault("MENAGERIE_ROOT", str(REPO.parent / "shared" / "menagerie"))
