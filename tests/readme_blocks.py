"""README's code blocks: parse them, run them, and compare what they print with what README shows.

Block kinds (the fence's language):

* ``python``: run in order, in one namespace. A block whose first line is ``# needs: jax`` (or
  ``torch``, ...) is skipped when that module is missing, unless ``POEKIN_REQUIRE_EXTRAS=1``.
* ``console``: ``$ command`` lines, each followed by the output README shows for it. The commands
  run in order in one scratch folder, with stdout and stderr together as on a terminal, and the
  output is compared line by line: numbers to their last printed digit (plus or minus one unit),
  figures at float-rounding level (below 1e-10) to an order of magnitude, other text exactly
  (runs of spaces count as one); a line ``...`` stands for any lines, and ``...`` inside a line
  for any text.
* ``bash``: commands run for their exit code only (0), in the same scratch folder.

An HTML comment on the line before a fence changes how it is run:

* ``<!-- readme: ci -->``: not run here; each of its commands must appear in ``.ci/run``, which CI
  runs (the install and test commands);
* ``<!-- readme: offline -->``: run without ``MENAGERIE_ROOT``, with an empty Menagerie download
  cache and no address to download from, as on a fresh machine;
* no directive: run with ``MENAGERIE_ROOT`` as the tests set it (``tests/data/menagerie``, XML
  only). The UR5e there loads with a kinematics-only note that README's reader never sees
  (poekin's built-in copy, or a clone with the meshes, loads silently): that note is ignored;
* ``<!-- readme: not run -->``: shown only (a server that runs until stopped); say why beside it.

``python tests/readme_blocks.py --update`` runs every console block and writes the output into
README (lines ``...`` that README shows are kept where they stand in for output).
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import math
import os
import pathlib
import re
import shlex
import subprocess
import sys
import warnings
from collections.abc import Iterator, Sequence

REPO = pathlib.Path(__file__).resolve().parents[1]
README = REPO / "README.md"

_FENCE = re.compile(r"^```(\w*)\s*$")
_DIRECTIVE = re.compile(r"^<!--\s*readme:\s*(.+?)\s*-->\s*$")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
_ROUNDING_LEVEL = 1e-10


@dataclasses.dataclass(frozen=True)
class Block:
    kind: str
    directive: str
    start: int  # line index of the first line inside the fence
    lines: tuple[str, ...]

    @property
    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def blocks(text: str | None = None) -> list[Block]:
    """Every fenced block of README, with the directive on the line before it."""
    lines = (README.read_text() if text is None else text).splitlines()
    found, i = [], 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m or not m.group(1):
            i += 1
            continue
        before = _DIRECTIVE.match(lines[i - 1]) if i else None
        j = i + 1
        while not lines[j].startswith("```"):
            j += 1
        found.append(
            Block(m.group(1), before.group(1) if before else "", i + 1, tuple(lines[i + 1 : j]))
        )
        i = j + 1
    return found


def commands(block: Block) -> list[tuple[str, list[str]]]:
    """A console block as ``(command, expected output lines)`` pairs."""
    pairs: list[tuple[str, list[str]]] = []
    for line in block.lines:
        if line.startswith("$ "):
            pairs.append((line[2:], []))
        elif pairs:
            pairs[-1][1].append(line)
        else:
            raise ValueError(f"README line {block.start + 1}: output before any '$ ' command")
    return pairs


# --- running -----------------------------------------------------------------------------------


def scratch(folder: pathlib.Path) -> pathlib.Path:
    """``folder`` set up as a reader's checkout for README's commands: ``examples/`` and
    ``benchmarks/`` link to this checkout's, and what the commands write stays in ``folder``."""
    for name in ("examples", "benchmarks"):
        link = folder / name
        if not link.exists():
            link.symlink_to(REPO / name, target_is_directory=True)
    return folder


@contextlib.contextmanager
def environment(offline: bool, scratch: pathlib.Path) -> Iterator[None]:
    """Variables for a block: offline (no MENAGERIE_ROOT, no cache, nowhere to download from);
    else the tests' Menagerie copies, without the note of their UR5e's missing meshes (for the
    commands run in this process)."""
    import poekin

    saved = dict(os.environ)
    try:
        with warnings.catch_warnings():
            if offline:
                os.environ.pop("MENAGERIE_ROOT", None)
                os.environ["MENAGERIE_CACHE_DIR"] = str(scratch / ".menagerie-cache")
                os.environ["MENAGERIE_BASE_URL"] = (scratch / ".nowhere").as_uri()
            else:
                warnings.filterwarnings(
                    "ignore", r"ur5e\.xml: loaded for kinematics only", poekin.AssetsStrippedWarning
                )
            yield
    finally:
        os.environ.clear()
        os.environ.update(saved)


def run(command: str, cwd: pathlib.Path) -> tuple[int, str]:
    """Run a README command in ``cwd``: ``poekin ...`` without shell syntax in this process (fast,
    stdout and stderr in order), anything else in bash. Returns the exit code and the output."""
    words = shlex.split(command, comments=True)
    if words and words[0] == "poekin" and not re.search(r"[|<>;&$`]", command):
        from poekin.cli import main

        buffer = io.StringIO()
        here = os.getcwd()
        os.chdir(cwd)
        try:
            with contextlib.redirect_stdout(buffer), contextlib.redirect_stderr(buffer):
                try:
                    code = main(words[1:])
                except SystemExit as e:  # argparse: --help, usage errors
                    code = int(e.code or 0)
        finally:
            os.chdir(here)
        return code, buffer.getvalue()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    bindir = str(pathlib.Path(sys.executable).parent)
    env["PATH"] = bindir + os.pathsep + env.get("PATH", "")
    proc = subprocess.run(
        ["bash", "-c", command], cwd=cwd, env=env, capture_output=False, check=False,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    return proc.returncode, proc.stdout


# --- comparing ---------------------------------------------------------------------------------


def _last_digit(token: str) -> float:
    """One unit in the last digit ``token`` prints: ``0.0968`` -> 1e-4, ``1.5e-06`` -> 1e-7."""
    mantissa, _, exponent = token.lower().partition("e")
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (-decimals + (int(exponent) if exponent else 0))


def numbers_agree(expected: str, actual: str) -> bool:
    e, a = float(expected), float(actual)
    if abs(e) < _ROUNDING_LEVEL and abs(a) < _ROUNDING_LEVEL:
        if e == 0 or a == 0:
            return e == a or max(abs(e), abs(a)) < _ROUNDING_LEVEL
        return abs(math.log10(abs(a) / abs(e))) <= 1.0
    return abs(e - a) <= 1.0001 * _last_digit(expected)


def line_agrees(expected: str, actual: str) -> bool:
    if "..." in expected:  # a wildcard: the rest of the line as written, exactly
        parts = [re.escape(" ".join(p.split())) for p in expected.split("...")]
        return re.fullmatch(".*".join(parts), " ".join(actual.split())) is not None
    e_parts = _NUMBER.split(" ".join(expected.split()))
    a_parts = _NUMBER.split(" ".join(actual.split()))
    e_nums, a_nums = (
        _NUMBER.findall(" ".join(expected.split())),
        _NUMBER.findall(" ".join(actual.split())),
    )
    return (
        e_parts == a_parts
        and len(e_nums) == len(a_nums)
        and all(numbers_agree(x, y) for x, y in zip(e_nums, a_nums, strict=True))
    )


def output_agrees(expected: Sequence[str], actual: Sequence[str]) -> bool:
    """Line by line, a line ``...`` standing for any number of lines."""
    if not expected:
        return not actual
    if expected[0].strip() == "...":
        return any(output_agrees(expected[1:], actual[k:]) for k in range(len(actual) + 1))
    return (
        bool(actual)
        and line_agrees(expected[0], actual[0])
        and output_agrees(expected[1:], actual[1:])
    )


# --- updating README ---------------------------------------------------------------------------


def _refresh(expected: list[str], actual: list[str]) -> list[str]:
    """README's lines for a command's output: the real output, keeping a trailing ``...`` README
    shows in place of lines it leaves out, and README's lines with ``...`` inside (a path that
    differs between machines) where they still agree with what is printed."""
    if expected and expected[-1].strip() == "..." and len(expected) >= 2:
        kept = len(expected) - 1
        actual = [*actual[:kept], "..."] if len(actual) > kept else actual
    wild = [e for e in expected if "..." in e and e.strip() != "..."]
    return [next((e for e in wild if line_agrees(e, a)), a) for a in actual]


def update(scratch: pathlib.Path) -> str:
    """README with every console block's output replaced by what its commands print now."""
    text = README.read_text()
    lines = text.splitlines()
    for block in reversed(blocks(text)):
        if block.kind != "console" or block.directive.startswith(("ci", "not run")):
            continue
        new: list[str] = []
        with environment(block.directive == "offline", scratch):
            for command, expected in commands(block):
                _, out = run(command, scratch)
                new += [f"$ {command}", *_refresh(expected, out.splitlines())]
        lines[block.start : block.start + len(block.lines)] = new
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    import tempfile

    if sys.argv[1:] != ["--update"]:
        sys.exit("usage: python tests/readme_blocks.py --update")
    sys.path.insert(0, str(REPO / "tests"))
    import conftest  # noqa: F401  MENAGERIE_ROOT as the tests set it

    with tempfile.TemporaryDirectory() as folder:
        README.write_text(update(scratch(pathlib.Path(folder))))
    print(f"updated {README}")
