"""README's install and test commands, every ``--help`` example, and the rules that compare
what a page shows with what a command prints (``doc_blocks.py``; ``tests/test_docs.py`` runs the
code blocks of README and of every page of ``docs/``).
"""

from __future__ import annotations

import contextlib
import functools
import io
import os
import pathlib
import re
import select
import shlex
import signal
import subprocess
import sys

import doc_blocks as db
import numpy as np
import pytest
from trajectory_helpers import quintic

import poekin
from poekin.cli import _build_parser
from poekin.io.trajectory import Trajectory


def test_readme_has_what_the_brief_asks() -> None:
    """The install and test commands, marked for CI (tests/test_docs.py checks them against
    .ci/run, and runs every other block of README and docs/)."""
    blocks = db.blocks()
    kinds = [b.kind for b in blocks]
    assert "python" in kinds and "console" in kinds
    ci = [b for b in blocks if b.directive == "ci"]
    assert any("pip install" in b.text for b in ci), "the install command"
    assert any(re.search(r"^pytest\b", b.text, re.M) for b in ci), "the test command"


# --- every --help example runs -------------------------------------------------------------------


def _examples() -> list[tuple[str, str]]:
    parser = _build_parser()
    found = [("poekin", line) for line in (parser.epilog or "").splitlines()]
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():  # type: ignore[union-attr]
        found += [(name, line) for line in (p.epilog or "").splitlines()]
    # `poekin --help` repeats one of verify's: run it once, as verify's
    once = {line.strip(): name for name, line in found if line.strip().startswith("poekin ")}
    return [(name, example) for example, name in once.items()]


EXAMPLES = _examples()


@functools.cache
def _tracker() -> tuple[np.ndarray, np.ndarray]:
    """Joint readings and tracker poses of a simulated UR5e (MuJoCo on a perturbed model)."""
    from poekin.calibration.simulate import simulate_robot

    chain = poekin.load("universal_robots_ur5e")
    q = poekin.sample_joint_values(chain, 40, seed=1)
    return q, simulate_robot("universal_robots_ur5e", seed=1).measure(q, seed=2)


def _fixtures(folder: pathlib.Path) -> None:
    """The files the examples read: joint values for the UR5e and the go2, UR5e poses to solve
    (T.npy, from joint values within the limits), a parameter file, a calibration's
    measurements (tracker.csv), and a trajectory (traj.npz)."""
    from poekin.calibration.files import params_document, write_json, write_measurements

    write_measurements(folder / "tracker.csv", poekin.load("universal_robots_ur5e"), *_tracker())
    rng = np.random.default_rng(0)
    np.save(folder / "q.npy", rng.uniform(-3, 3, (20, 6)))
    ur5e = poekin.load("universal_robots_ur5e")
    np.save(folder / "T.npy", ur5e.fk(poekin.sample_joint_values(ur5e, 20, within_limits=True)))
    tree = poekin.load_tree("unitree_go2")
    np.save(folder / "qpos.npy", poekin.sample_qpos(tree, 20))
    g1 = poekin.load_tree("unitree_g1")  # both feet where they stand, the pelvis 5 cm lower
    T = g1.fk(g1.qpos0)
    targets = {f: T[g1.frame_index(f)].tolist() for f in ("left_foot", "right_foot", "pelvis")}
    targets["pelvis"][2][3] -= 0.05
    (folder / "g1_targets.json").write_text(__import__("json").dumps(targets))
    (folder / "my_ur5e.json").write_text(
        __import__("json").dumps(poekin.named_params("ur5e-dh").describe())
    )
    # a trajectory file (poekin plot-trajectory, poekin view --play): a UR5e quintic
    t, q, qd, qdd = quintic()
    Trajectory(t, q, qd, qdd, robot="universal_robots_ur5e", joint_names=ur5e.joint_names).save(
        folder / "traj.npz"
    )
    calibration = db.REPO / "tests" / "data" / "ur" / "ur5e_calibration.yaml"  # synthetic
    (folder / "my_robot_calibration.yaml").write_text(calibration.read_text())
    # what `poekin calibrate ... --output my_robot.json` writes, under the names the examples use
    fitted = params_document(poekin.calibrate(ur5e, *_tracker()))
    for name in ("my_robot.json", "my_calibrated_ur5e.json"):
        write_json(folder / name, fitted)


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
    words = shlex.split(example)
    if "--output" in words:  # the example writes this file itself (calibrate's my_robot.json)
        (tmp_path / words[words.index("--output") + 1]).unlink(missing_ok=True)
    if command == "view":
        pytest.importorskip("viser")
        code, out = _serve_then_stop(example, tmp_path)
        assert code == 130 and "poekin view: http://127.0.0.1:" in out, out
        assert "Traceback" not in out and "poekin: error:" not in out, out
        return
    code, out = db.run_once(example, tmp_path, offline=False)  # the pages may have run it
    assert code in (0, 1), f"{example}: exit {code}\n{out}"  # 1: verify/diagnose found a mismatch
    assert "Traceback" not in out and "poekin: error:" not in out, out
    if command == "verify" and "--params" not in example:
        assert "PASS" in out or '"passed": true' in out, out
    assert shlex.split(example)[1] == command or command == "poekin"


def test_the_comparison_can_fail() -> None:
    """The rules are strict enough to catch drift."""
    assert db.output_agrees(["max error 0.0968 m"], ["max error 0.0969 m"])
    assert not db.output_agrees(["max error 0.0968 m"], ["max error 0.0971 m"])
    assert db.output_agrees(["err 1.83e-15 m"], ["err 4.1e-15 m"])
    assert not db.output_agrees(["err 1.83e-15 m"], ["err 3e-13 m"])
    assert not db.output_agrees(["d1: 0.089 m"], ["d4: 0.089 m"])
    assert not db.output_agrees(["PASS"], ["PASS", "extra line"])
    assert db.output_agrees(["a", "...", "z"], ["a", "b", "c", "z"])
    assert db.output_agrees(["model: ... (clone)"], ["model: /x/y.xml (clone)"])
    assert not db.output_agrees(["model: ... (clone)"], ["model: /x/y.xml (cache)"])
    with contextlib.redirect_stdout(io.StringIO()):
        assert db.run("poekin --version", pathlib.Path.cwd())[0] == 0


def test_without_the_development_install_the_tests_say_what_to_install(
    tmp_path: pathlib.Path,
) -> None:
    """README: Test. A suite run where a package it imports is missing (the wheel install, or
    the pytest of another Python) stops at the first module with one line that names the
    package and the install command, instead of a collection error per module (issue #26)."""
    fake = tmp_path / "hypothesis"
    fake.mkdir()
    (fake / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'hypothesis'\", name='hypothesis')\n"
    )
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith(("PYTEST_", "COV_CORE_"))  # not this run's xdist worker, coverage
    }
    env["PYTHONPATH"] = f"{tmp_path}:{db.REPO / 'src'}"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            *["-p", "no:cacheprovider", "-p", "no:hypothesispytest", "-p", "no:xdist", "-q"],
            *["tests/test_lie.py", "tests/test_chain.py"],
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=db.REPO,
        env=env,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == pytest.ExitCode.USAGE_ERROR, out
    assert "ERROR collecting" not in out and "Traceback" not in out, out
    assert (
        f"tests/test_lie.py cannot import 'hypothesis' in {sys.executable}: the tests need "
        "poekin's development install in the Python that runs them: in the checkout, "
        'pip install -e ".[dev,jax,torch]" (README: Test), then pytest' in out
    ), out
    readme = db.README.read_text()
    assert 'pip install -e ".[dev,jax,torch]"\npytest\n' in readme  # the command it names
