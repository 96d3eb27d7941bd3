"""The command-line reference, generated from poekin's own argparse parser so it cannot drift.

An MkDocs hook (``hooks:`` in mkdocs.yml): in ``docs/cli.md`` the line ``<!-- cli-reference -->``
is replaced, at build time, by each command's description, usage, options and examples, read
from :func:`poekin.cli._build_parser`. The examples are those ``--help`` prints, and
``tests/test_readme.py`` runs each one.
"""

from __future__ import annotations

import argparse
import html
import os
import re
from typing import Any

MARKER = "<!-- cli-reference -->"
PAGE = "cli.md"
# the usage lines' width: fixed, so the page does not depend on the terminal it was built in,
# and within the ~85 characters the page's code boxes show
WIDTH = 80


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _summaries(parser: argparse.ArgumentParser) -> dict[str, str]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {c.dest: c.help or "" for c in action._choices_actions}


def _escape(text: str) -> str:
    """Plain help text as Markdown: ``*``, ``_``, ``<`` and friends shown as typed."""
    return re.sub(r"([\\`*_\[\]])", r"\\\1", html.escape(text, quote=False))


def _options(parser: argparse.ArgumentParser) -> list[str]:
    formatter = parser._get_formatter()
    lines = []
    for action in parser._actions:
        if action.help == argparse.SUPPRESS:
            continue
        invocation = formatter._format_action_invocation(action)  # "--frame F", "SOURCE"
        text = formatter._expand_help(action) if action.help else ""
        lines.append(f"- `{invocation}`: {_escape(' '.join(text.split()))}")
    return lines


def _examples(parser: argparse.ArgumentParser) -> list[str]:
    return [
        f"$ {line.strip()}"
        for line in (parser.epilog or "").splitlines()
        if line.strip().startswith("poekin ")
    ]


def _section(title: str, parser: argparse.ArgumentParser, summary: str) -> list[str]:
    out = [f"## `{title}`", ""]
    if summary:
        out += [f"{_escape(summary[0].upper() + summary[1:])}.", ""]
    if parser.description:
        out += [_escape(" ".join(parser.description.split())), ""]
    out += ["```text", parser.format_usage().rstrip(), "```", "", *_options(parser), ""]
    examples = _examples(parser)
    if examples:
        out += ["Examples:", "", "```console", *examples, "```", ""]
    return out


def markdown(parser: argparse.ArgumentParser | None = None) -> str:
    """The reference for ``poekin`` and each of its commands, as Markdown."""
    if parser is None:
        from poekin.cli import _build_parser

        saved = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = str(WIDTH + 2)  # argparse's formatter reads the width here
        try:
            parser = _build_parser()
            return markdown(parser)
        finally:
            if saved is None:
                os.environ.pop("COLUMNS", None)
            else:
                os.environ["COLUMNS"] = saved
    out = _section("poekin", parser, "")
    summaries = _summaries(parser)
    for command, sub in _subparsers(parser).items():
        out += _section(sub.prog, sub, summaries.get(command, ""))
    return "\n".join(out)


def on_page_markdown(markdown_text: str, page: Any, **_: Any) -> str:
    """MkDocs hook: the reference in place of the marker on ``cli.md``."""
    if page.file.src_uri != PAGE:
        return markdown_text
    if MARKER not in markdown_text:
        raise ValueError(f"docs/{PAGE} lost its line {MARKER}")
    return markdown_text.replace(MARKER, markdown())
