"""A griffe extension for the API pages: poekin's docstrings name objects the Sphinx way
(``:class:`~poekin.dh.DHTable```, ``:meth:`fk```); mkdocstrings renders Markdown, where those
would show as typed. Each becomes a code span of the name as Sphinx shows it (``DHTable``,
``fk``). The docstrings themselves stay as they are, for ``help()`` and editors."""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:class|meth|func|data|mod|attr|exc|obj|const):`(~?)([^`]+)`")


def _span(match: re.Match[str]) -> str:
    target = match.group(2)
    return f"`{target.rsplit('.', 1)[-1] if match.group(1) else target}`"


class SphinxRoles(griffe.Extension):
    """Sphinx cross-reference roles in docstrings as Markdown code spans."""

    def on_object(self, *, obj: griffe.Object, **_: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _ROLE.sub(_span, obj.docstring.value)
