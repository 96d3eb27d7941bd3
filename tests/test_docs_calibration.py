"""docs/calibration.md cannot go stale: its blocks run in order in one scratch folder, as a reader
following along would (the console commands read what the Python blocks wrote), and each
command prints what the page shows (the rules of ``readme_blocks.py``). After a change that
alters an output, ``python tests/test_docs_calibration.py --update`` rewrites the page from real
runs.
"""

from __future__ import annotations

import contextlib
import difflib
import importlib.util
import os
import pathlib
import re
import sys
import warnings
from collections.abc import Iterator

import readme_blocks as rb

import poekin

PAGE = rb.REPO / "docs" / "calibration.md"


@contextlib.contextmanager
def _inside(folder: pathlib.Path) -> Iterator[None]:
    here = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(here)


def run_page(folder: pathlib.Path) -> tuple[list[str], list[str]]:
    """Run every block of the page in ``folder``. Returns the failures, and the page's lines
    with each console block's output replaced by what its commands printed."""
    text = PAGE.read_text()
    lines = text.splitlines()
    failures: list[str] = []
    updates: list[tuple[rb.Block, list[str]]] = []
    scope: dict[str, object] = {}
    required = os.environ.get("POEKIN_REQUIRE_EXTRAS") == "1"
    with _inside(folder), warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        for block in rb.blocks(text):
            where = f"docs/calibration.md:{block.start + 1}"
            if block.kind == "python":
                needs = re.match(r"# needs: (\w+)", block.lines[0]) if block.lines else None
                if needs and importlib.util.find_spec(needs.group(1)) is None and not required:
                    continue
                exec(compile(block.text, where, "exec"), scope)
            elif block.kind == "console":
                new: list[str] = []
                for command, expected in rb.commands(block):
                    code, out = rb.run(command, folder)
                    actual = out.splitlines()
                    new += [f"$ {command}", *rb._refresh(expected, actual)]
                    if code not in (0, 1) or not rb.output_agrees(expected, actual):
                        diff = "\n".join(
                            difflib.unified_diff(expected, actual, "page", "printed", lineterm="")
                        )
                        failures.append(f"{where}: $ {command} (exit {code})\n{diff}")
                updates.append((block, new))
    for block, new in reversed(updates):
        lines[block.start : block.start + len(block.lines)] = new
    return failures, lines


def test_the_calibration_page_runs_and_prints_what_it_shows(tmp_path: pathlib.Path) -> None:
    kinds = [b.kind for b in rb.blocks(PAGE.read_text())]
    assert kinds.count("python") >= 3 and kinds.count("console") >= 2
    failures, _ = run_page(tmp_path)
    assert not failures, "\n\n".join(failures)


if __name__ == "__main__":
    import tempfile

    if sys.argv[1:] != ["--update"]:
        sys.exit("usage: python tests/test_docs_calibration.py --update")
    sys.path.insert(0, str(rb.REPO / "tests"))
    import conftest  # noqa: F401  MENAGERIE_ROOT as the tests set it

    with tempfile.TemporaryDirectory() as folder:
        _, page = run_page(pathlib.Path(folder))
    PAGE.write_text("\n".join(page) + "\n")
    print(f"updated {PAGE}")
