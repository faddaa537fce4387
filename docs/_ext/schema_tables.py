"""``{schema-table}``: one table per design-file table (field, type, unit, default, allowed range, meaning).

Usage in MyST::

    ```{schema-table} geometry.design_rpud:HornDesign
    ```

Everything in a row is read from the code, so the page cannot drift from what the loaders accept:

- the fields and defaults are the dataclass's own (:func:`dataclasses.fields`);
- the meaning is the field's entry in the class docstring's numpydoc ``Attributes`` section;
- the allowed range is what the validator itself says when it refuses a value: the class is
  built from a valid base (:data:`BASES`) with the one field set to a probe (NaN, a tiny or a
  huge number, a bad name) and the :class:`~rpud_common.errors.ParameterError` that names the
  field is quoted; material records quote :data:`geometry.materials.FIELD_RANGES`; ``Literal``
  fields list their choices;
- the unit is the one the validator's message states, else the one the docstring states.

A field without a meaning, or a number without a unit (``dimensionless`` counts as one), stops
the build with an error naming the field: a field added to a dataclass is documented or the
documentation does not build.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import re
import types
import typing
from collections.abc import Mapping

from docutils import nodes
from sphinx.errors import ExtensionError
from sphinx.util.docutils import SphinxDirective

from ._doctable import code, inline, table

BASES: dict[str, list[dict]] = {
    "geometry.design_stack:Segment": [
        {"name": "s", "length": 0.01, "outer_diameter": 0.02},
        {"name": "s", "length": 0.01, "kind": "cone", "outer_diameter": 0.02, "end_diameter": 0.01},
        {"name": "s", "length": 0.01, "kind": "box", "thickness": 0.01, "width": 0.01},
    ],
    "geometry.design_stack:ElectrodeSpec": [{"name": "e", "segment": "s"}],
    "geometry.design_cad:LengthRule": [{"name": "l", "z0": 0.0, "z1": 0.01, "part": "horn"}],
    "geometry.design_cad:SizeRule": [{"size": 0.001, "region": "r"}],
    "geometry.design_cad:Plane": [{"normal": (0.0, 0.0, 1.0), "offset": 0.0}],
    "geometry.design_cad:Selector": [{"name": "x"}],
}
"""Valid keyword arguments to probe a class's validators from (its defaults when absent here);
several bases for fields that only some variants check (a cone's ``end_diameter``)."""

_UNIT = re.compile(r"(?<![\w/^.'])(kg/m\^3|m\^3|m\^2|m/s|1/Pa|C/m\^2|C/N|V/m|Hz|kg|Pa|m|s|N|V|W|J|degrees"
                   r"|dimensionless)(?![\w/^])")
"""Units a message or a docstring may state, the first one found is the field's."""


def resolve(spec: str):
    module, _, name = spec.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise ExtensionError(f"schema-table: cannot import {spec}: {exc}") from None


def descriptions(cls) -> dict[str, tuple[str, str]]:
    """``{field: (type text, meaning)}`` from the numpydoc ``Attributes`` section of ``cls``."""
    from numpydoc.docscrape import NumpyDocString

    doc = NumpyDocString(inspect.getdoc(cls) or "")
    out = {}
    for entry in doc["Attributes"]:
        for name in entry.name.split(","):
            out[name.strip()] = (entry.type, " ".join(entry.desc).strip())
    return out


def _base(spec: str, cls) -> list[dict]:
    return BASES.get(spec, [{}])


def _probe_values(tp) -> list:
    args = set(typing.get_args(tp)) | {tp}
    if bool in args:
        return []
    if float in args:
        return [math.nan, 1e-9, 1e30]
    if int in args:
        return [10 ** 9, -10 ** 9]
    if str in args:
        return ["../bad name"]
    return []


def probe(spec: str, cls, name: str, tp) -> list[str]:
    """What the validators say when field ``name`` gets a bad value (each distinct message once)."""
    from rpud_common import ParameterError

    said: list[str] = []
    for base in _base(spec, cls):
        for bad in _probe_values(tp):
            try:
                cls(**{**base, name: bad})
            except ParameterError as exc:
                where = exc.name.split(":")[-1].strip()
                if (where == name or where.endswith("." + name)) and exc.allowed not in said:
                    said.append(exc.allowed)
            except (TypeError, ValueError):
                continue
    return said


def _type_text(tp) -> str:
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return "string"
    if origin in (typing.Union, types.UnionType):
        parts = [_type_text(a) for a in typing.get_args(tp) if a is not type(None)]
        return " or ".join(parts) + " (optional)"
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list of {_type_text(args[0])}"
        return f"list of {len(args)} {_type_text(args[0])}"
    if origin in (dict, Mapping) or tp is Mapping:
        return "table"
    if dataclasses.is_dataclass(tp):
        return f"table ({tp.__name__})"
    return getattr(tp, "__name__", str(tp))


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        d = f.default
    elif f.default_factory is not dataclasses.MISSING:
        d = f.default_factory()
    else:
        return "required"
    if dataclasses.is_dataclass(d):
        return f"the {type(d).__name__} defaults"
    if d is None:
        return "absent"
    if isinstance(d, (tuple, list, dict)) and not d:
        return "empty"
    if isinstance(d, bool):
        return "true" if d else "false"
    if isinstance(d, str):
        return repr(d).replace("'", '"')
    return f"{d:g}" if isinstance(d, float) else str(d)


def _numeric(tp) -> bool:
    """A number or an optional number (not a table of numbers)."""
    if tp in (float, int):
        return True
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        return set(typing.get_args(tp)) - {type(None)} <= {float, int}
    return False


def schema_rows(spec: str) -> list[tuple[str, str, str, str, str, str]]:
    """``[(field, type, unit, default, allowed range, meaning)]`` of the class named by ``spec``.

    Raises
    ------
    sphinx.errors.ExtensionError
        A field has no meaning in the class docstring, or a number states no unit.
    """
    cls = resolve(spec)
    if not dataclasses.is_dataclass(cls):
        raise ExtensionError(f"schema-table: {spec} is not a dataclass")
    hints = typing.get_type_hints(cls)
    docs = descriptions(cls)
    ranges = _material_ranges() if cls.__name__ == "Material" else {}
    rows, missing = [], []
    for f in dataclasses.fields(cls):
        if f.name.startswith("_"):
            continue
        tp = hints[f.name]
        doc_type, meaning = docs.get(f.name, ("", ""))
        if not meaning:
            missing.append(f"{f.name}: no meaning in the Attributes section of {cls.__name__}'s docstring")
            continue
        said = probe(spec, cls, f.name, tp) if _numeric(tp) or tp is str else []
        if f.name in ranges:
            said = [ranges[f.name]] + said
        if typing.get_origin(tp) is typing.Literal:
            said.append("one of " + ", ".join(f'"{c}"' for c in typing.get_args(tp)))
        elif tp is bool:
            said.append("true or false")
        unit = ""
        for text in (said + [meaning]) if _numeric(tp) else []:
            m = _UNIT.search(text)
            if m:
                unit = m.group(1)
                break
        if not unit and (tp is int):
            unit = "dimensionless"           # a count
        if not unit and _numeric(tp):
            missing.append(f"{f.name}: a number without a unit (state it in the validator's message or the "
                           f"docstring; 'dimensionless' when it has none)")
            continue
        rows.append((f.name, _type_text(tp), "1" if unit == "dimensionless" else unit, _default(f),
                     "; ".join(said), meaning))
    if missing:
        raise ExtensionError(f"schema-table {spec}: " + "; ".join(missing))
    return rows


def _material_ranges() -> dict[str, str]:
    from geometry.materials import FIELD_RANGES, POISSON_RANGE, TABLE_RANGES

    out = {name: f"[{lo:g}, {hi:g}]{' ' + unit if unit else ''} ({why})"
           for name, (lo, hi, unit, why) in FIELD_RANGES.items()}
    out["poisson_ratio"] = f"({POISSON_RANGE[0]:g}, {POISSON_RANGE[1]:g}) dimensionless, bounds excluded"
    for name, prefix in (("c_E", "c"), ("s_E", "s"), ("e", "e"), ("d", "d"), ("eps_S", "eps"), ("eps_T", "eps")):
        lo, hi, unit, why = TABLE_RANGES[prefix]
        out[name] = f"entries in [{lo:g}, {hi:g}] {unit} ({why})"
    return out


class SchemaTable(SphinxDirective):
    required_arguments = 1
    has_content = False

    def run(self):
        rows = schema_rows(self.arguments[0])
        cells = [[code(name), tp, unit, code(default) if default else "", allowed, inline(meaning)]
                 for name, tp, unit, default, allowed, meaning in rows]
        return [table(("Field", "Type", "Unit", "Default", "Allowed", "Meaning"), cells,
                      widths=(14, 10, 6, 10, 25, 35))]


def setup(app):
    app.add_directive("schema-table", SchemaTable)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
