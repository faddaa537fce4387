"""The generated Reference pages cover what the code accepts: every command line, every design
table and every field, every top-level key of summary.json (without building the site)."""

from __future__ import annotations

import dataclasses
import re
import sys
import typing
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
REF = ROOT / "docs" / "reference"
sys.path.insert(0, str(ROOT / "docs"))

from _ext import cli_reference, schema_tables, summary_schema  # noqa: E402

DIRECTIVE = re.compile(r"```\{(?P<name>[a-z-]+)\} (?P<arg>\S+)\n(?P<body>(?:(?!```).*\n)*?)```", re.M)


def directives(page: str, name: str) -> list[tuple[str, str]]:
    return [(m["arg"], m["body"]) for m in DIRECTIVE.finditer((REF / page).read_text()) if m["name"] == name]


def _dataclasses_reachable(cls, seen: set) -> None:
    if cls in seen or not dataclasses.is_dataclass(cls):
        return
    seen.add(cls)
    for tp in typing.get_type_hints(cls).values():
        for arg in (tp, *typing.get_args(tp)):
            for inner in (arg, *typing.get_args(arg)):
                if isinstance(inner, type):
                    _dataclasses_reachable(inner, seen)


def test_every_design_table_has_a_schema_table_and_every_field_a_row():
    from geometry.design import KINDS
    from geometry.materials import Material

    classes: set = set()
    for cls in KINDS.values():
        _dataclasses_reachable(cls, classes)
    classes.add(Material)
    documented = {spec: schema_tables.resolve(spec) for spec, _ in directives("design-files.md", "schema-table")}
    missing = {c.__qualname__ for c in classes} - {c.__qualname__ for c in documented.values()}
    assert not missing, f"design tables without a schema table in design-files.md: {sorted(missing)}"
    for spec, cls in documented.items():
        rows = {r[0] for r in schema_tables.schema_rows(spec)}
        fields = {f.name for f in dataclasses.fields(cls) if not f.name.startswith("_")}
        assert rows == fields, spec


def test_schema_rows_quote_the_validators():
    rows = {r[0]: r for r in schema_tables.schema_rows("geometry.design_rpud:HornDesign")}
    assert rows["length"][2] == "m" and "[0.0001, 2] m" in rows["length"][4]
    assert rows["step_fraction"][4] == "must lie in [0.05, 0.95]"
    assert rows["profile"][4].startswith("one of")


@dataclasses.dataclass(frozen=True)
class _Undocumented:
    """A record.

    Attributes
    ----------
    width : float
        Width, m.
    """

    width: float = 1.0
    height: float = 1.0


@dataclasses.dataclass(frozen=True)
class _Unitless:
    """A record.

    Attributes
    ----------
    width : float
        A width.
    """

    width: float = 1.0


@pytest.mark.parametrize("cls, field", [(_Undocumented, "height"), (_Unitless, "width")])
def test_a_field_without_meaning_or_unit_stops_the_build(cls, field):
    from sphinx.errors import ExtensionError

    with pytest.raises(ExtensionError, match=field):
        schema_tables.schema_rows(f"{__name__}:{cls.__name__}")


def test_every_command_line_is_on_the_cli_page():
    progs = set()
    for path in [*ROOT.glob("geometry/*.py"), *ROOT.glob("fem/*.py"), *ROOT.glob("impact/*.py"),
                 *ROOT.glob("results/*.py")]:
        text = path.read_text()
        progs |= set(re.findall(r'CliParser\(\s*prog="([^"]+)"', text))
        progs |= set(re.findall(r'def build_parser\(prog="([^"]+)"', text))
    assert "python -m geometry" in progs and "python -m impact sweep" in progs
    shown = {cli_reference.parser_for(spec, "" if ":argv:" in body else None).prog
             for spec, body in directives("cli.md", "cli-reference")}
    assert progs <= shown, f"commands missing from docs/reference/cli.md: {sorted(progs - shown)}"


def test_cli_rows_carry_help_and_defaults():
    rows = {name: (arg, default, text) for _t, group in
            cli_reference.option_rows(cli_reference.parser_for("results.__main__:build_parser"))
            for name, arg, default, text in group}
    assert rows["--voltage"][1] == "225.0" and "V" in rows["--voltage"][2]


def test_summary_page_documents_every_top_level_key():
    import json

    (spec, body), = directives("summary-json.md", "summary-schema")
    lines = [line for line in body.splitlines() if not line.startswith(":")]
    meaning = summary_schema.meanings(lines)
    summary = json.loads((ROOT / spec).read_text())
    summary_schema.check(summary, {k: v for k, v in meaning.items() if k in summary}, spec)
    from sphinx.errors import ExtensionError

    with pytest.raises(ExtensionError, match="undocumented top-level keys: brand_new"):
        summary_schema.check({**summary, "brand_new": 1}, meaning, spec)
    assert summary_schema.unit_of("f_r_hz") == "Hz" and summary_schema.unit_of("tip_per_volt_m_error") == "m"
    assert summary_schema.unit_of("eps_S") == ""
