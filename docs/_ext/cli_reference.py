"""``{cli-reference}``: a command line's usage, description and options, read from its parser.

Usage in MyST::

    ```{cli-reference} fem.modal_cli:build_parser
    ```

    ```{cli-reference} impact.__main__:_sweep
    :argv: --help-is-not-needed
    ```

The argument names ``module:callable``. A callable that returns an :class:`argparse.ArgumentParser`
is used as is (the ``build_parser`` functions). Any other callable is a command whose parser is
built inline: it is called with ``:argv:`` (split on spaces; default none) while
``ArgumentParser.parse_args`` is replaced by a hook that hands back the parser before anything
runs, so the page shows exactly the parser the command parses with. Help texts are never copied
into the pages: a changed option changes the page at the next build.
"""

from __future__ import annotations

import argparse
import importlib
import shlex

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.errors import ExtensionError
from sphinx.util.docutils import SphinxDirective

from ._doctable import code, table


class _Captured(Exception):
    def __init__(self, parser: argparse.ArgumentParser):
        super().__init__(parser.prog)
        self.parser = parser


def parser_for(spec: str, argv: str | None = None) -> argparse.ArgumentParser:
    """The parser named by ``spec`` (``module:callable``), see the module docstring."""
    module, _, name = spec.partition(":")
    if not name:
        raise ExtensionError(f"cli-reference: {spec!r} must be 'module:callable'")
    fn = getattr(importlib.import_module(module), name)
    args = shlex.split(argv) if argv else []

    def grab(self, *_a, **_k):
        raise _Captured(self)

    saved = argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args
    argparse.ArgumentParser.parse_args = grab
    argparse.ArgumentParser.parse_known_args = grab
    try:
        made = fn(args) if argv is not None or not _takes_no_argument(fn) else fn()
    except _Captured as caught:
        return caught.parser
    finally:
        argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args = saved
    if isinstance(made, argparse.ArgumentParser):
        return made
    raise ExtensionError(f"cli-reference: {spec} neither returned a parser nor parsed a command line")


def _takes_no_argument(fn) -> bool:
    import inspect

    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return False
    return all(p.default is not inspect.Parameter.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
               for p in params)


def option_rows(parser: argparse.ArgumentParser) -> list[tuple[str, list[tuple[str, str, str, str]]]]:
    """``[(group title, [(option, argument, default, help)])]`` of every documented action."""
    fmt = parser._get_formatter()
    out = []
    for group in parser._action_groups:
        rows = []
        for action in group._group_actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._HelpAction):
                continue
            help_text = fmt._expand_help(action) if action.help else ""
            if not help_text.strip():
                help_text = "(the parser gives no help text for this option)"
            if action.option_strings:
                name = ", ".join(action.option_strings)
                arg = "" if action.nargs == 0 else fmt._format_args(action, fmt._get_default_metavar_for_optional(action))
            else:
                name = action.metavar or action.dest
                arg = ""
            if action.choices is not None and not isinstance(action.choices, dict):
                arg = "{" + ",".join(str(c) for c in action.choices) + "}"
            rows.append((name, arg, _default(action), help_text))
        if rows:
            out.append((group.title or "", rows))
    return out


def _default(action: argparse.Action) -> str:
    if action.required:
        return "required"
    d = action.default
    if d is None or d == argparse.SUPPRESS or action.nargs == 0 and d is False:
        return ""
    if isinstance(d, list) and not d:
        return ""
    return str(d)


class CliReference(SphinxDirective):
    required_arguments = 1
    option_spec = {"argv": directives.unchanged}
    has_content = False

    def run(self):
        parser = parser_for(self.arguments[0], self.options.get("argv"))
        out: list[nodes.Node] = []
        if parser.description:
            out.append(nodes.paragraph(text=parser.description, support_smartquotes=False))
        usage = parser.format_usage().strip()
        out.append(nodes.literal_block(usage, usage, language="text"))
        for title, rows in option_rows(parser):
            if title:
                out.append(nodes.rubric(text=title))
            cells = [[code(name), code(arg) if arg else "", code(default) if default else "", help_text]
                     for name, arg, default, help_text in rows]
            out.append(table(("Option", "Argument", "Default", "Meaning"), cells, widths=(22, 16, 12, 50)))
        if parser.epilog:
            out.append(nodes.paragraph(text=parser.epilog))
        return out


def setup(app):
    app.add_directive("cli-reference", CliReference)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
