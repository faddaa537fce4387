"""``{summary-schema}``: the structure of the pipeline's ``summary.json``, read from a committed one.

Usage in MyST (the content gives one line ``key: meaning`` per top-level key)::

    ```{summary-schema} results/default/summary.json
    :opaque: design materials
    design: the design as run ...
    ```

The table lists every key path (nested tables joined by ``.``, list items as ``[]``) with its
JSON type and, where the key's suffix states one (``_hz``, ``_m``, ``_j``, ``_s``, ``_w`` ...),
its unit. A top-level key without a meaning, or a meaning for a key the file no longer has,
stops the build: the page follows the file. ``:optional:`` names keys the pipeline writes only
on request (or a newer run than the committed file), documented in advance. ``:opaque:`` keys (at any depth) are listed but not
expanded: their inner keys are names (materials) or another page's schema (a design).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import directives
from sphinx.errors import ExtensionError
from sphinx.util.docutils import SphinxDirective

from ._doctable import code, table


def _root() -> Path:
    """The repository: the folder holding the ``results`` package (paths are relative to it)."""
    import results

    return Path(results.__file__).resolve().parents[1]

SUFFIX_UNITS = [
    ("_ns_per_m", "N s/m"), ("_per_m", "1/m"), ("_hz", "Hz"), ("_kg", "kg"), ("_m3", "m^3"), ("_m", "m"),
    ("_j", "J"), ("_mj", "mJ"), ("_s", "s"), ("_w", "W"), ("_v", "V"), ("_a", "A"), ("_pa", "Pa"),
    ("_deg", "degrees"), ("_rel", "1 (relative)"), ("_ratio", "1"), ("_n", "N"), ("_ohm", "ohm"),
]
"""Key suffix -> unit, the longest suffix first (``_ns_per_m`` before ``_m``)."""

MAX_DEPTH = 3


def unit_of(key: str) -> str:
    """The unit a key's suffix states (``f_r_hz`` -> Hz), or ``""``."""
    if key == "seconds":
        return "s"
    key = key.removesuffix("_error")      # an estimate's error has the estimate's unit
    for suffix, unit in SUFFIX_UNITS:
        if key.endswith(suffix):          # case-sensitive: ``eps_S`` is no time
            return unit
    return ""


def _type(v) -> str:
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, (int, float)):
        return "number"
    if v is None:
        return "null"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        inner = sorted({_type(x) for x in v})
        return "list of " + " / ".join(inner) if inner else "list"
    return "table"


def walk(value, path: str = "", depth: int = 0, opaque=frozenset(), out=None) -> list[tuple[str, str, str]]:
    """``[(key path, type, unit)]`` of every key under ``value`` (lists: the union of their items)."""
    out = [] if out is None else out
    name = path.rsplit(".", 1)[-1].removesuffix("[]")
    if name in opaque:
        return out
    if isinstance(value, dict) and depth < MAX_DEPTH:
        for k, v in value.items():
            sub = f"{path}.{k}" if path else k
            if not any(row[0] == sub for row in out):
                out.append((sub, _type(v), unit_of(k)))
            walk(v, sub, depth + 1, opaque, out)
    elif isinstance(value, list) and depth < MAX_DEPTH:
        for item in value:
            if isinstance(item, dict):
                walk(item, f"{path}[]", depth, opaque, out)
    return out


def meanings(lines) -> dict[str, str]:
    out = {}
    for line in lines:
        if not line.strip():
            continue
        key, sep, text = line.partition(":")
        if not sep or not text.strip():
            raise ExtensionError(f"summary-schema: line {line!r} is not 'key: meaning'")
        out[key.strip()] = text.strip()
    return out


def check(summary: dict, meaning: dict[str, str], where: str) -> None:
    """Every top-level key has a meaning and every meaning a key (else the build stops)."""
    missing = [k for k in summary if k not in meaning]
    stale = [k for k in meaning if k not in summary]
    problems = []
    if missing:
        problems.append("undocumented top-level keys: " + ", ".join(missing))
    if stale:
        problems.append("documented keys the file does not have: " + ", ".join(stale))
    if problems:
        raise ExtensionError(f"summary-schema {where}: " + "; ".join(problems))


class SummarySchema(SphinxDirective):
    required_arguments = 1
    has_content = True
    option_spec = {"opaque": directives.unchanged, "optional": directives.unchanged}

    def run(self):
        path = _root() / self.arguments[0]
        self.env.note_dependency(str(path))
        summary = json.loads(path.read_text())
        meaning = meanings(self.content)
        optional = set((self.options.get("optional") or "").split())
        check(summary, {k: v for k, v in meaning.items() if k in summary or k not in optional}, self.arguments[0])
        opaque = frozenset((self.options.get("opaque") or "").split())
        out: list[nodes.Node] = []
        top = [[code(k), _type(v), meaning[k]] for k, v in summary.items()]
        out.append(table(("Key", "Type", "Meaning"), top, widths=(20, 12, 68)))
        for key, value in summary.items():
            rows = walk(value, key, 1, opaque)
            if not rows:
                continue
            out.append(nodes.rubric(text=key))
            out.append(table(("Key", "Type", "Unit"), [[code(p), t, u] for p, t, u in rows], widths=(60, 25, 15)))
        return out


def setup(app):
    app.add_directive("summary-schema", SummarySchema)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
