"""Docutils tables for the generated reference pages (not an extension: its name starts with ``_``).

The generators build node trees directly rather than reStructuredText text, so help strings and
docstrings holding ``*``, backticks or ``|`` render as written instead of as markup.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from docutils import nodes

Cell = "str | nodes.Node | list[nodes.Node]"


def cell_nodes(value) -> list[nodes.Node]:
    """A table cell's content: plain text becomes a paragraph, nodes are kept."""
    if isinstance(value, nodes.Node):
        return [value]
    if isinstance(value, list):
        return value
    return [nodes.paragraph(text=str(value))] if str(value) else []


def code(text: str) -> nodes.Node:
    """Inline literal in a paragraph (option names, keys, defaults)."""
    para = nodes.paragraph()
    para += nodes.literal(text=text)
    return para


_INLINE = re.compile(r"``([^`]+)``|:[a-z:]+:`~?([^`]+)`")


def inline(text: str) -> nodes.paragraph:
    """A paragraph of docstring text with its ````literals```` and ``:role:`targets``` as code."""
    para = nodes.paragraph()
    at = 0
    for m in _INLINE.finditer(text):
        if m.start() > at:
            para += nodes.Text(text[at:m.start()])
        para += nodes.literal(text=m.group(1) or m.group(2).split(".")[-1] if m.group(2) else m.group(1))
        at = m.end()
    if at < len(text):
        para += nodes.Text(text[at:])
    return para


def table(headers: Sequence[str], rows: Sequence[Sequence], widths: Sequence[int] | None = None,
          classes: Sequence[str] = ()) -> nodes.table:
    """A docutils table with one header row."""
    widths = list(widths or [1] * len(headers))
    # help texts and docstrings name options (``--horn-law``): no typographic dashes or quotes
    tab = nodes.table(classes=list(classes), support_smartquotes=False)
    group = nodes.tgroup(cols=len(headers))
    tab += group
    for w in widths:
        group += nodes.colspec(colwidth=w)
    head = nodes.thead()
    group += head
    row = nodes.row()
    for h in headers:
        entry = nodes.entry()
        entry += nodes.paragraph(text=h)
        row += entry
    head += row
    body = nodes.tbody()
    group += body
    for values in rows:
        row = nodes.row()
        for v in values:
            entry = nodes.entry()
            entry.extend(cell_nodes(v))
            row += entry
        body += row
    return tab
