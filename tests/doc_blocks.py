"""The documentation's code blocks: parse them, run them, and compare what they print with what
the page shows. The pages are README.md and every ``docs/**/*.md``; each runs on its own, top to
bottom, in a scratch folder of its own, as a reader following along would.

Block kinds (the fence's language):

* ``python``: run in the page's order, in one namespace per page. A block whose first line is
  ``# needs: jax`` (or ``torch``, ...) is skipped when that module is missing, unless
  ``POEKIN_REQUIRE_EXTRAS=1``.
* ``console``: ``$ command`` lines, each followed by the output the page shows for it. The
  commands run with stdout and stderr together as on a terminal, and the output is compared line
  by line: numbers to their last printed digit (plus or minus one unit), figures at
  float-rounding level (below 1e-10) to an order of magnitude, other text exactly (runs of spaces
  count as one); a line ``...`` stands for any lines, and ``...`` inside a line for any text. The
  exit code must be 0 or 1 (verify and diagnose say FAIL or MISMATCH with 1); to show a command
  that fails, end it with ``; echo "exit $?"`` and show the exit line.
* ``bash``: commands run for their exit code only (0).
* ``text``, or no language: shown only (formulas, file layouts); never a command. Any other
  language (``json``, ``yaml``) only with the directive ``file`` below.

An HTML comment on the line before a fence changes how it is run:

* ``<!-- readme: ci -->``: not run here; each of its commands must appear in ``.ci/run``, which CI
  runs (the install and test commands);
* ``<!-- readme: offline -->``: run without ``MENAGERIE_ROOT``, with an empty Menagerie download
  cache and no address to download from, as on a fresh machine;
* no directive: run with ``MENAGERIE_ROOT`` as the tests set it (``src/poekin/data``, poekin's
  built-in copies, XML only, read as a clone). The UR5e there loads with a kinematics-only note
  that the reader never sees (poekin's built-in copy, or a clone with the meshes, loads
  silently): that note is ignored;
* ``<!-- readme: file NAME -->``: the block (a parameter file, say) is written to ``NAME`` in the
  scratch folder, for the commands after it;
* ``<!-- readme: not run -->``: shown only (a server that runs until stopped); say why beside it.

A command that an earlier page already ran, with the same environment and the same files that
it names, is not run again: its output, and the files it wrote, are taken from that run.

``python tests/doc_blocks.py --update [PAGE ...]`` runs the pages (default: all) and writes each
console command's output into its page (lines ``...`` that the page shows are kept where they
stand in for output).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib.util
import io
import math
import os
import pathlib
import re
import shlex
import subprocess
import sys
import traceback
import warnings
from collections.abc import Iterator, Sequence

REPO = pathlib.Path(__file__).resolve().parents[1]
README = REPO / "README.md"
DOCS = REPO / "docs"

#: fence languages: run (python, console, bash) or shown only (text, or none)
RUN_KINDS = ("python", "console", "bash")
SHOWN_KINDS = ("text", "")
DIRECTIVES = ("", "ci", "offline", "not run", "file")

_FENCE = re.compile(r"^(\s*)```(\w*)\s*$")
_DIRECTIVE = re.compile(r"^\s*<!--\s*readme:\s*(.+?)\s*-->\s*$")
_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")
_ECHO_EXIT = re.compile(r'^(?P<command>.*?)\s*;\s*echo "exit \$\?"$')
_ROUNDING_LEVEL = 1e-10


def pages() -> list[pathlib.Path]:
    """README, then every page of ``docs/`` (sorted by path)."""
    return [README, *sorted(DOCS.rglob("*.md"))]


def name(page: pathlib.Path) -> str:
    """A page's path relative to the checkout, as failures and test ids name it."""
    return page.relative_to(REPO).as_posix() if page.is_relative_to(REPO) else str(page)


@dataclasses.dataclass(frozen=True)
class Block:
    kind: str
    directive: str
    start: int  # line index of the first line inside the fence
    lines: tuple[str, ...]
    indent: str = ""  # a fence inside a list item or admonition is indented

    @property
    def text(self) -> str:
        return "\n".join(self.lines) + "\n"

    @property
    def file(self) -> str | None:
        """The scratch file a ``file NAME`` directive writes the block to."""
        words = self.directive.split()
        return words[1] if len(words) == 2 and words[0] == "file" else None


def blocks(text: str | None = None) -> list[Block]:
    """Every fenced block of a page (README by default), with the directive on the line before."""
    lines = (README.read_text() if text is None else text).splitlines()
    found, i = [], 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent = m.group(1)
        before = _DIRECTIVE.match(lines[i - 1]) if i else None
        j = i + 1
        while not lines[j].startswith(indent + "```"):
            j += 1
        body = tuple(ln[len(indent) :] if ln.startswith(indent) else ln for ln in lines[i + 1 : j])
        found.append(Block(m.group(2), before.group(1) if before else "", i + 1, body, indent))
        i = j + 1
    return found


def problems(page: pathlib.Path) -> list[str]:
    """What is wrong with a page's blocks before anything runs: unknown kinds or directives."""
    found = []
    for block in blocks(page.read_text()):
        where = f"{name(page)}:{block.start}"
        if block.kind not in RUN_KINDS + SHOWN_KINDS and block.file is None:
            found.append(f"{where}: unknown block kind {block.kind!r}: use one of {RUN_KINDS}")
        directive = block.directive.split()[0] if block.directive else ""
        if block.directive not in DIRECTIVES and (directive != "file" or block.file is None):
            found.append(f"{where}: unknown directive {block.directive!r}")
        runs = block.kind == "console" and block.directive not in ("ci", "not run")
        if runs and block.lines and not block.lines[0].startswith("$ "):
            found.append(f"{where}: output before any '$ ' command")
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
            raise ValueError(f"line {block.start + 1}: output before any '$ ' command")
    return pairs


# --- running -----------------------------------------------------------------------------------


def scratch(folder: pathlib.Path) -> pathlib.Path:
    """``folder`` set up as a reader's checkout for the pages' commands: ``examples/`` and
    ``benchmarks/`` link to this checkout's, and what the commands write stays in ``folder``."""
    for sub in ("examples", "benchmarks"):
        link = folder / sub
        if not link.exists():
            link.symlink_to(REPO / sub, target_is_directory=True)
    return folder


@contextlib.contextmanager
def environment(offline: bool, scratch: pathlib.Path) -> Iterator[None]:
    """Variables for a block: offline (no MENAGERIE_ROOT, no cache, nowhere to download from);
    else the tests' Menagerie copies, without the note of their UR5e's missing meshes (for the
    commands run in this process): a reader loads poekin's built-in UR5e, or a clone with the
    meshes, and sees no note."""
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


@contextlib.contextmanager
def _inside(folder: pathlib.Path) -> Iterator[None]:
    here = os.getcwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(here)


def run(command: str, cwd: pathlib.Path) -> tuple[int, str]:
    """Run a command in ``cwd``: ``poekin ...`` without shell syntax in this process (fast,
    stdout and stderr in order; also with ``; echo "exit $?"`` after it), anything else in bash.
    Returns the exit code and the output."""
    echo = _ECHO_EXIT.match(command)
    if echo:
        code, out = run(echo.group("command"), cwd)
        if _in_process(echo.group("command")):
            return 0, f"{out}exit {code}\n"
    if _in_process(command):
        from poekin.cli import main

        buffer = io.StringIO()
        with (
            _inside(cwd),
            contextlib.redirect_stdout(buffer),
            contextlib.redirect_stderr(buffer),
            warnings.catch_warnings(),
        ):
            # as in a new process: a note shown to an earlier command is shown again (a change
            # of the filters empties every module's record of the warnings it has shown;
            # appended, it overrides none of the filters in force)
            warnings.simplefilter("default", append=True)
            try:
                code = main(shlex.split(command, comments=True)[1:])
            except SystemExit as e:  # argparse: --help, usage errors
                code = int(e.code or 0)
        return code, buffer.getvalue()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    bindir = str(pathlib.Path(sys.executable).parent)
    env["PATH"] = bindir + os.pathsep + env.get("PATH", "")
    proc = subprocess.run(
        ["bash", "-c", command], cwd=cwd, env=env, check=False,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    return proc.returncode, proc.stdout


def _in_process(command: str) -> bool:
    words = shlex.split(command, comments=True)
    return bool(words) and words[0] == "poekin" and not re.search(r"[|<>;&$`]", command)


# A command's result, keyed by what it can see: the command, offline or not, and the contents of
# the scratch files whose names appear in it. The files it wrote or changed come with it.
_Key = tuple[str, bool, tuple[tuple[str, str], ...]]
_RUNS: dict[_Key, tuple[int, str, dict[str, bytes]]] = {}


def _files(folder: pathlib.Path) -> dict[str, tuple[int, int]]:
    """Each file under ``folder`` (not through its links) with its modification time and size."""
    found = {}
    for root, dirs, files in os.walk(folder):
        dirs[:] = [d for d in dirs if d != ".menagerie-cache"]
        for f in files:
            path = pathlib.Path(root, f)
            if not path.is_symlink():
                stat = path.stat()
                found[path.relative_to(folder).as_posix()] = (stat.st_mtime_ns, stat.st_size)
    return found


def run_once(command: str, cwd: pathlib.Path, offline: bool) -> tuple[int, str]:
    """:func:`run`, or the result of the same command run earlier (by any page) in the same
    environment on the same named files, whose written files are copied into ``cwd``."""
    named = []
    for word in sorted(set(re.findall(r"[\w.][\w./-]*", command))):
        path = cwd / word
        if path.is_file():
            named.append((word, hashlib.sha256(path.read_bytes()).hexdigest()))
    key = (command, offline, tuple(named))
    if key not in _RUNS:
        before = _files(cwd)
        code, out = run(command, cwd)
        after = _files(cwd)
        wrote = {f: (cwd / f).read_bytes() for f, stamp in after.items() if before.get(f) != stamp}
        _RUNS[key] = (code, out, wrote)
    code, out, wrote = _RUNS[key]
    for f, data in wrote.items():
        (cwd / f).parent.mkdir(parents=True, exist_ok=True)
        (cwd / f).write_bytes(data)
    return code, out


@dataclasses.dataclass(frozen=True)
class Outcome:
    """One command (or python block) of a page, what the page shows and what it did."""

    where: str  # page:line
    block: Block
    command: str  # the console or bash command; "" for a python block
    expected: tuple[str, ...]
    code: int
    output: str

    @property
    def ok(self) -> bool:
        if self.block.kind == "console":
            return self.code in (0, 1) and output_agrees(self.expected, self.output.splitlines())
        return self.code == 0

    def failure(self) -> str:
        import difflib

        if self.block.kind == "python":
            return f"{self.where}: python block failed\n{self.output}"
        if self.block.kind == "bash":
            return f"{self.where}: {self.command!r} exit {self.code}\n{self.output}"
        diff = difflib.unified_diff(
            list(self.expected), self.output.splitlines(), "page", "printed", lineterm=""
        )
        return f"{self.where}: $ {self.command} (exit {self.code})\n" + "\n".join(diff)


def _needs_missing(block: Block) -> bool:
    needs = re.match(r"# needs: (\w+)", block.lines[0]) if block.lines else None
    if needs is None or os.environ.get("POEKIN_REQUIRE_EXTRAS") == "1":
        return False
    return importlib.util.find_spec(needs.group(1)) is None


def _exec(block: Block, where: str, scope: dict[str, object], cwd: pathlib.Path) -> Outcome:
    import poekin

    printed = io.StringIO()
    try:
        with _inside(cwd), warnings.catch_warnings(), contextlib.redirect_stdout(printed):
            warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
            exec(compile(block.text, where, "exec"), scope)
    except Exception:
        return Outcome(where, block, "", (), 1, printed.getvalue() + traceback.format_exc())
    return Outcome(where, block, "", (), 0, printed.getvalue())


def run_page(page: pathlib.Path, folder: pathlib.Path) -> list[Outcome]:
    """Run a page's blocks top to bottom in ``folder`` (set up by :func:`scratch`)."""
    scope: dict[str, object] = {"__name__": "__docs__"}
    outcomes = []
    for block in blocks(page.read_text()):
        where = f"{name(page)}:{block.start + 1}"
        if block.file is not None:
            (folder / block.file).write_text(block.text)
            continue
        if block.kind not in RUN_KINDS or block.directive in ("ci", "not run"):
            continue
        if block.kind == "python":
            if not _needs_missing(block):
                outcomes.append(_exec(block, where, scope, folder))
            continue
        offline = block.directive == "offline"
        with environment(offline, folder):
            if block.kind == "bash":
                for k, line in enumerate(block.lines):
                    if line.split("#")[0].strip():
                        code, out = run_once(line, folder, offline)
                        at = f"{name(page)}:{block.start + 1 + k}"
                        outcomes.append(Outcome(at, block, line, (), code, out))
                continue
            for command, expected in commands(block):
                code, out = run_once(command, folder, offline)
                outcomes.append(Outcome(where, block, command, tuple(expected), code, out))
    return outcomes


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


# --- updating pages ----------------------------------------------------------------------------


def _refresh(expected: Sequence[str], actual: list[str]) -> list[str]:
    """A page's lines for a command's output: the real output, keeping a trailing ``...`` the
    page shows in place of lines it leaves out, and its lines with ``...`` inside (a path that
    differs between machines) where they still agree with what is printed."""
    if expected and expected[-1].strip() == "..." and len(expected) >= 2:
        kept = len(expected) - 1
        actual = [*actual[:kept], "..."] if len(actual) > kept else actual
    wild = [e for e in expected if "..." in e and e.strip() != "..."]
    return [next((e for e in wild if line_agrees(e, a)), a) for a in actual]


def update(page: pathlib.Path, folder: pathlib.Path) -> str:
    """The page with every console block's output replaced by what its commands print now."""
    lines = page.read_text().splitlines()
    outcomes = run_page(page, folder)
    for failed in (o for o in outcomes if o.block.kind != "console" and not o.ok):
        print(failed.failure(), file=sys.stderr)
    by_block: dict[int, list[Outcome]] = {}
    for o in outcomes:
        if o.block.kind == "console":
            by_block.setdefault(o.block.start, []).append(o)
    for block in reversed(blocks("\n".join(lines))):
        if block.start not in by_block:
            continue
        new: list[str] = []
        for o in by_block[block.start]:
            new += [f"$ {o.command}", *_refresh(o.expected, o.output.splitlines())]
        lines[block.start : block.start + len(block.lines)] = [
            block.indent + ln if ln else ln for ln in new
        ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    import tempfile

    args = sys.argv[1:]
    if args[:1] != ["--update"]:
        sys.exit("usage: python tests/doc_blocks.py --update [PAGE ...]")
    sys.path.insert(0, str(REPO / "tests"))
    import conftest  # noqa: F401  MENAGERIE_ROOT as the tests set it

    chosen = [pathlib.Path(p).resolve() for p in args[1:]] or pages()
    for page in chosen:
        with tempfile.TemporaryDirectory() as folder:
            page.write_text(update(page, scratch(pathlib.Path(folder))))
        print(f"updated {name(page)}")
