"""README cannot go stale: every code block and every ``--help`` example runs, and what the
console blocks show is what the commands print (rules in ``readme_blocks.py``; after a change
that alters an output, ``python tests/readme_blocks.py --update`` rewrites README from real runs).
"""

from __future__ import annotations

import contextlib
import difflib
import importlib.util
import io
import os
import pathlib
import re
import select
import shlex
import signal
import subprocess
import sys
import warnings

import numpy as np
import pytest
import readme_blocks as rb

import poekin
from poekin.cli import _build_parser

ALL = rb.blocks()


def test_readme_has_what_the_brief_asks() -> None:
    kinds = [b.kind for b in ALL]
    assert "python" in kinds and "console" in kinds
    ci = [b for b in ALL if b.directive == "ci"]
    assert any("pip install" in b.text for b in ci), "the install command"
    assert any(re.search(r"^pytest\b", b.text, re.M) for b in ci), "the test command"


def test_the_install_and_test_commands_are_what_ci_runs() -> None:
    ci_run = (rb.REPO / ".ci" / "run").read_text()
    for block in (b for b in ALL if b.directive == "ci"):
        for line in block.lines:
            command = line.split("#")[0].strip()
            if command:
                assert command in ci_run, f"README's {command!r} is not what .ci/run runs"


def test_python_blocks_run() -> None:
    scope: dict[str, object] = {}
    required = os.environ.get("POEKIN_REQUIRE_EXTRAS") == "1"
    ran = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", poekin.AssetsStrippedWarning)
        for block in (b for b in ALL if b.kind == "python"):
            needs = re.match(r"# needs: (\w+)", block.lines[0]) if block.lines else None
            if needs and importlib.util.find_spec(needs.group(1)) is None and not required:
                continue
            exec(compile(block.text, f"README.md:{block.start + 1}", "exec"), scope)
            ran += 1
    assert ran >= 1
    assert scope["T_world_ee"].shape == (1000, 4, 4)  # type: ignore[attr-defined]
    assert scope["report"].passed  # type: ignore[attr-defined]


def test_console_and_bash_blocks_print_what_readme_shows(tmp_path: pathlib.Path) -> None:
    """Run in README's order in one folder, as a reader following along would."""
    rb.scratch(tmp_path)
    failures = []
    for block in ALL:
        if block.kind not in ("console", "bash") or block.directive in ("ci", "not run"):
            continue
        assert block.directive in ("", "offline"), f"unknown directive {block.directive!r}"
        with rb.environment(block.directive == "offline", tmp_path):
            if block.kind == "bash":
                for line in block.lines:
                    if line.split("#")[0].strip():
                        code, out = rb.run(line, tmp_path)
                        if code != 0:
                            failures.append(
                                f"README.md:{block.start + 1}: {line!r} exit {code}\n{out}"
                            )
                continue
            for command, expected in rb.commands(block):
                code, out = rb.run(command, tmp_path)
                actual = out.splitlines()
                if code not in (0, 1) or not rb.output_agrees(expected, actual):
                    diff = "\n".join(
                        difflib.unified_diff(expected, actual, "README", "printed", lineterm="")
                    )
                    failures.append(
                        f"README.md:{block.start + 1}: $ {command} (exit {code})\n{diff}"
                    )
    assert not failures, "\n\n".join(failures)


# --- every --help example runs -------------------------------------------------------------------


def _examples() -> list[tuple[str, str]]:
    parser = _build_parser()
    found = [("poekin", line) for line in (parser.epilog or "").splitlines()]
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():  # type: ignore[union-attr]
        found += [(name, line) for line in (p.epilog or "").splitlines()]
    return [(name, line.strip()) for name, line in found if line.strip().startswith("poekin ")]


EXAMPLES = _examples()


def _fixtures(folder: pathlib.Path) -> None:
    """The files the examples read: joint values for the UR5e and the go2, a parameter file."""
    rng = np.random.default_rng(0)
    np.save(folder / "q.npy", rng.uniform(-3, 3, (20, 6)))
    tree = poekin.load_tree("unitree_go2")
    np.save(folder / "qpos.npy", poekin.sample_qpos(tree, 20))
    (folder / "my_ur5e.json").write_text(
        __import__("json").dumps(poekin.named_params("ur5e-dh").describe())
    )


def test_every_command_has_examples() -> None:
    commands = {name for name, _ in EXAMPLES}
    assert commands >= {"verify", "screws", "fk", "jacobian", "dh", "diagnose"}


def _serve_then_stop(example: str, folder: pathlib.Path) -> tuple[int, str]:
    """A ``poekin view`` example serves until Ctrl-C: run it (without opening a browser) until
    it prints its URL line, then press Ctrl-C. Returns the exit code and the output."""
    argv = [sys.executable, "-m", "poekin", *shlex.split(example)[1:], "--no-browser"]
    proc = subprocess.Popen(
        argv, cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    assert proc.stdout is not None
    lines = []
    try:
        while select.select([proc.stdout], [], [], 120)[0]:
            line = proc.stdout.readline()
            lines.append(line)
            if not line or line.startswith("poekin view: http://"):
                break
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=60)
    finally:
        proc.kill()
    return proc.returncode, "".join(lines) + (rest or "")


@pytest.mark.filterwarnings("ignore::poekin.AssetsStrippedWarning")
# `poekin view` examples take port 8080 (or the next free one) and 8081: one xdist worker runs
# them all (pytest -n 2 --dist loadgroup), one after the other
@pytest.mark.parametrize(
    ("command", "example"),
    [
        pytest.param(c, e, marks=[pytest.mark.xdist_group("view ports")] if c == "view" else [])
        for c, e in EXAMPLES
    ],
    ids=[e for _, e in EXAMPLES],
)
def test_help_example_runs(command: str, example: str, tmp_path: pathlib.Path) -> None:
    _fixtures(tmp_path)
    if command == "view":
        pytest.importorskip("viser")
        code, out = _serve_then_stop(example, tmp_path)
        assert code == 130 and "poekin view: http://127.0.0.1:" in out, out
        assert "Traceback" not in out and "poekin: error:" not in out, out
        return
    code, out = rb.run(example, tmp_path)
    assert code in (0, 1), f"{example}: exit {code}\n{out}"  # 1: verify/diagnose found a mismatch
    assert "Traceback" not in out and "poekin: error:" not in out, out
    if command == "verify" and "--params" not in example:
        assert "PASS" in out or '"passed": true' in out, out
    assert shlex.split(example)[1] == command or command == "poekin"


def test_the_comparison_can_fail() -> None:
    """The rules are strict enough to catch drift."""
    assert rb.output_agrees(["max error 0.0968 m"], ["max error 0.0969 m"])
    assert not rb.output_agrees(["max error 0.0968 m"], ["max error 0.0971 m"])
    assert rb.output_agrees(["err 1.83e-15 m"], ["err 4.1e-15 m"])
    assert not rb.output_agrees(["err 1.83e-15 m"], ["err 3e-13 m"])
    assert not rb.output_agrees(["d1: 0.089 m"], ["d4: 0.089 m"])
    assert not rb.output_agrees(["PASS"], ["PASS", "extra line"])
    assert rb.output_agrees(["a", "...", "z"], ["a", "b", "c", "z"])
    assert rb.output_agrees(["model: ... (clone)"], ["model: /x/y.xml (clone)"])
    assert not rb.output_agrees(["model: ... (clone)"], ["model: /x/y.xml (cache)"])
    with contextlib.redirect_stdout(io.StringIO()):
        assert rb.run("poekin --version", pathlib.Path.cwd())[0] == 0
