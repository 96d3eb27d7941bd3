"""The documentation cannot go stale: every code block of README.md and of each ``docs/**/*.md``
page runs, and what its console blocks show is what the commands print (rules in
``doc_blocks.py``; after a change that alters an output, ``python tests/doc_blocks.py --update``
rewrites the pages from real runs). The site itself is built by CI (``mkdocs build --strict``).
"""

from __future__ import annotations

import importlib.util
import pathlib
import re
import types

import doc_blocks as db
import pytest
import yaml

from poekin.cli import _build_parser

PAGES = db.pages()


@pytest.mark.parametrize("page", PAGES, ids=db.name)
def test_page_runs_and_prints_what_it_shows(page: pathlib.Path, tmp_path: pathlib.Path) -> None:
    """Top to bottom in a folder of its own, as a reader following along would."""
    outcomes = db.run_page(page, db.scratch(tmp_path))
    failures = [o.failure() for o in outcomes if not o.ok]
    assert not failures, "\n\n".join(failures)


def test_every_block_is_one_the_tests_know() -> None:
    assert [p for page in PAGES for p in db.problems(page)] == []


def test_the_pages_have_blocks_that_run() -> None:
    """Not all shown-only: the tutorial and README run python and console blocks."""
    for page in (db.README, db.DOCS / "getting-started.md"):
        kinds = {b.kind for b in db.blocks(page.read_text()) if not b.directive}
        assert {"python", "console"} <= kinds, db.name(page)


def test_install_and_test_commands_are_what_ci_runs() -> None:
    ci_run = (db.REPO / ".ci" / "run").read_text()
    for page in PAGES:
        for block in (b for b in db.blocks(page.read_text()) if b.directive == "ci"):
            for line in block.lines:
                command = line.split("#")[0].strip()
                if command:
                    assert command in ci_run, f"{db.name(page)}: {command!r} is not in .ci/run"


def _nav_pages(nav: object) -> list[str]:
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, dict):
        return [p for v in nav.values() for p in _nav_pages(v)]
    if isinstance(nav, list):
        return [p for v in nav for p in _nav_pages(v)]
    return []


def test_every_page_is_in_the_navigation_and_every_entry_is_a_page() -> None:
    """A new page needs its line in mkdocs.yml's nav; an entry without its page fails too."""
    config = yaml.safe_load((db.REPO / "mkdocs.yml").read_text())
    nav = _nav_pages(config["nav"])
    on_disk = sorted(p.relative_to(db.DOCS).as_posix() for p in db.DOCS.rglob("*.md"))
    assert sorted(nav) == on_disk
    assert len(nav) == len(set(nav))


def test_the_site_builds_offline() -> None:
    """No web fonts or CDN: the theme's Google fonts are off, and no page loads a script."""
    config = yaml.safe_load((db.REPO / "mkdocs.yml").read_text())
    assert config["theme"]["font"] is False
    assert "extra_javascript" not in config and "extra_css" not in config
    for page in PAGES[1:]:
        prose = re.sub(r"^(\s*)```.*?^\1```", "", page.read_text(), flags=re.M | re.S)
        assert not re.search(r"<script|<link |<iframe", prose), db.name(page)


def test_links_between_pages_resolve() -> None:
    """README's links into docs/ (which read on GitHub) and the pages' links to each other
    point to files that exist (mkdocs build --strict checks the pages' anchors too)."""
    for page in PAGES:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if re.match(r"[a-z]+://", target):
                continue
            assert (page.parent / target).exists(), f"{db.name(page)} links to {target}"


def test_readme_is_a_front_page() -> None:
    text = db.README.read_text()
    assert len(text.splitlines()) <= 300
    for heading in ("## Install", "## Test", "## The main command: `poekin verify`"):
        assert heading in text
    assert "docs/view_ur5e.png" in text


# --- the machinery can fail --------------------------------------------------------------------


def test_a_command_runs_once_and_its_files_come_with_it(tmp_path: pathlib.Path) -> None:
    for folder in ("a", "b", "c"):
        (tmp_path / folder).mkdir()
    first, second, third = (db.scratch(tmp_path / f) for f in ("a", "b", "c"))
    command = "echo $RANDOM$RANDOM > n.txt; cat n.txt"
    code, out = db.run_once(command, first, offline=False)
    assert code == 0 and (first / "n.txt").read_text() == out
    assert db.run_once(command, second, offline=False) == (0, out)  # not run again
    assert (second / "n.txt").read_text() == out
    (third / "n.txt").write_text("mine\n")  # a file it names differs: it runs
    assert db.run_once(command, third, offline=False)[1] != out


def test_a_page_that_drifted_fails_and_update_rewrites_it(tmp_path: pathlib.Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "Text.\n\n```console\n$ poekin fk universal_robots_ur5e --q 0 0 0 0 0 0 --precision 2\n"
        "T_world_attachment_site =\n  1.00  0.00  0.00  -0.80\n...\n```\n"
        "\n```python\nx = 1\n```\n"
    )
    outcomes = db.run_page(page, db.scratch(tmp_path))
    assert [o.ok for o in outcomes] == [False, True]  # -0.82, not -0.80
    page.write_text(db.update(page, tmp_path))
    assert "  1.00  0.00   0.00  -0.82\n..." in page.read_text()
    assert all(o.ok for o in db.run_page(page, tmp_path))


def test_unknown_kinds_and_directives_are_reported(tmp_path: pathlib.Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(
        "```pyhton\nx = 1\n```\n\n<!-- readme: offlien -->\n```console\n$ poekin --version\n```\n"
        "\n<!-- readme: file a.json -->\n```json\n{}\n```\n"
    )
    found = db.problems(page)
    assert len(found) == 2 and "'pyhton'" in found[0] and "'offlien'" in found[1]


# --- the command-line reference ----------------------------------------------------------------


def _hook() -> types.ModuleType:
    path = db.DOCS / "hooks" / "cli_reference.py"
    spec = importlib.util.spec_from_file_location("cli_reference", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_cli_reference_has_every_command_option_and_example() -> None:
    hook = _hook()
    text = hook.markdown()
    parser = _build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():  # type: ignore[union-attr]
        assert f"## `poekin {name}`" in text
        section = text.split(f"## `poekin {name}`")[1].split("\n## ")[0]
        listed = [ln.split("`")[1] for ln in section.splitlines() if ln.startswith("- `")]
        for action in p._actions:
            for option in action.option_strings or [action.metavar or action.dest]:
                assert any(
                    option in item.split(", ") or item.startswith(f"{option} ") or item == option
                    for item in listed
                ), (name, option)
        for line in (p.epilog or "").splitlines():
            if line.strip().startswith("poekin "):
                assert f"$ {line.strip()}" in section
    assert hook.MARKER in (db.DOCS / "cli.md").read_text()


def test_the_cli_reference_replaces_only_its_marker() -> None:
    hook = _hook()
    page = types.SimpleNamespace(file=types.SimpleNamespace(src_uri="cli.md"))
    other = types.SimpleNamespace(file=types.SimpleNamespace(src_uri="index.md"))
    out = hook.on_page_markdown(f"intro\n\n{hook.MARKER}\n", page=page)
    assert out.startswith("intro\n\n## `poekin`") and hook.MARKER not in out
    assert hook.on_page_markdown(hook.MARKER, page=other) == hook.MARKER
    with pytest.raises(ValueError, match="cli-reference"):
        hook.on_page_markdown("no marker", page=page)
