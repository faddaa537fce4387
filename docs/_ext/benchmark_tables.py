"""Benchmarks page: the benchmark scripts' own tables, read from their JSON output.

Each ``benchmarks/bench_*.py`` prints its tables through ``benchmarks/_table.py``, which also writes
them, with the machine, load, date, version and commit of the run, to
``benchmarks/results/<script>.json`` (committed). The ``benchmark-tables`` directive renders one
script's file: the script's docstring (what is measured, against which baseline), the tables, and
where they were measured. A script without a file is shown as not measured, with the command that
measures it: the page never carries a number the script did not write.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.errors import ExtensionError
from sphinx.util.docutils import SphinxDirective

ROOT = Path(__file__).resolve().parent.parent.parent
BENCH = ROOT / "benchmarks"
RESULTS = BENCH / "results"


def _cell(text: str) -> str:
    """A table cell: pipes escaped so a value cannot split the row."""
    return str(text).replace("|", "\\|")


def table_markdown(table: dict) -> list[str]:
    """One recorded table as Markdown lines."""
    headers = table["headers"]
    lines = ["| " + " | ".join(_cell(h) for h in headers) + " |", "|" + "---|" * len(headers)]
    for row in table["rows"]:
        lines.append("| " + " | ".join(_cell(c) for c in row) + " |")
    return lines


def where_markdown(doc: dict) -> str:
    """The sentence that says where and when a table was measured."""
    m, p = doc.get("machine", {}), doc.get("provenance", {})
    parts = [f"{m.get('cpu', 'unknown processor')}, {m.get('cores', '?')} cores, {m.get('os', '?')}, "
             f"Python {m.get('python', '?')}"]
    if m.get("load_average_1min") is not None:
        parts.append(f"1-minute load average {m['load_average_1min']:.1f} when written")
    parts.append(f"rpud {p.get('rpud_version', '?')}, commit `{p.get('git_commit') or 'unknown'}`")
    parts.append(f"{p.get('date_utc', 'date unknown')}")
    cmd = p.get("command")
    return ("Measured on " + "; ".join(parts) + "." + (f" Command: `{cmd}`." if cmd else ""))


def script_summary(script: Path) -> str:
    """First paragraph of a script's module docstring (what it measures), read without importing it."""
    doc = ast.get_docstring(ast.parse(script.read_text())) or ""
    return " ".join(doc.split("\n\n")[0].split())


def render(name: str, results: Path = RESULTS, bench: Path = BENCH) -> tuple[str, Path | None]:
    """Markdown for one script (``bench_impact``) and the JSON file it came from (None if absent)."""
    script = bench / f"{name}.py"
    if not script.exists():
        raise ExtensionError(f"benchmark-tables: no script {script}")
    lines = [script_summary(script), ""]
    path = results / f"{name}.json"
    if not path.exists():
        lines += [f"*Not measured in the committed results:* run `python benchmarks/{name}.py` (it writes "
                  f"`benchmarks/results/{name}.json`, which this page then shows)."]
        return "\n".join(lines), None
    doc = json.loads(path.read_text())
    for table in doc["tables"]:
        lines += table_markdown(table) + [""]
    lines.append(where_markdown(doc))
    return "\n".join(lines), path


class BenchmarkTables(SphinxDirective):
    """``{benchmark-tables} bench_impact``: that script's tables from benchmarks/results/."""

    required_arguments = 1

    def run(self):
        text, path = render(self.arguments[0])
        self.env.note_dependency(str(BENCH / f"{self.arguments[0]}.py"))
        if path is not None:
            self.env.note_dependency(str(path))
        node = nodes.container()
        self.state.nested_parse(StringList(text.splitlines()), self.content_offset, node)
        return node.children


def setup(app):
    app.add_directive("benchmark-tables", BenchmarkTables)
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}
