"""Comments, docstrings and pages say why, not when.

A pointer to an issue number, a date or a "used to" ages the moment it is written and tells a
reader nothing the code does not; the reason behind the code is what stays true. The history
belongs in git and in the changelog (docs/changelog.md, not scanned). Every offending line is
named as ``file:line: text``.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

TREES = ("geometry", "fem", "impact", "results", "rpud_common", "tests", "benchmarks", "docs")
"""Source trees scanned (their .py, .md and .toml files), and README.md."""

SKIP_DIRS = {"__pycache__", "_build", "gallery", "_generated", ".ipynb_checkpoints", "out"}
"""Generated folders: the Sphinx build, sphinx-gallery's output, pages written at build time,
benchmark output."""

SKIP_FILES = {Path("docs/changelog.md"), Path("results/default"), Path("tests/test_no_history.py")}
"""History is the changelog's subject; results/default/ is a generated, committed run; this file
shows what it refuses."""

_AUX = r"(?<!\bis )(?<!\bare )(?<!\bwas )(?<!\bwere )(?<!\bbe )(?<!\bbeen )(?<!\bbeing )(?<!\bget )(?<!\bgets )"

PATTERNS = {
    "issue number": re.compile(r"\bissues?\s*#?\d+", re.I),
    "date": re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b"),
    "since a year": re.compile(r"\bsince (?:(?:jan|feb|mar|apr|may|jun|jul|aug|sep|oct|nov|dec)\w* )?20\d\d\b", re.I),
    "used to (then, not now)": re.compile(
        _AUX + r"\bused to (?:be|behave|crash|fail|hang|happen|exist|work|do|give|return|raise)\b", re.I),
    "the earlier path/code": re.compile(r"\bthe (?:earlier|old|previous) (?:path|code|default|behaviou?r|version)\b",
                                        re.I),
    "before/after the fix": re.compile(r"\b(?:before|after|since) the fix\b", re.I),
    "previously / formerly": re.compile(r"\b(?:previously|formerly)\b", re.I),
}
"""What marks a line as history rather than reason. "used to" only with an auxiliary-free verb
of the past habit ("it used to crash"); "is used to compute" states a purpose and passes."""


def _files() -> list[Path]:
    out = [ROOT / "README.md"]
    for tree in TREES:
        for path in sorted((ROOT / tree).rglob("*")):
            rel = path.relative_to(ROOT)
            if (path.suffix not in (".py", ".md", ".toml") or not path.is_file()
                    or SKIP_DIRS.intersection(rel.parts[:-1])
                    or any(rel == s or s in rel.parents for s in SKIP_FILES)):
                continue
            out.append(path)
    return out


def history_lines(paths) -> list[str]:
    """``file:line: [kind] text`` of every line of ``paths`` that says when instead of why."""
    hits = []
    for path in paths:
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        for n, line in enumerate(text.splitlines(), 1):
            for kind, rx in PATTERNS.items():
                if rx.search(line):
                    hits.append(f"{path.relative_to(ROOT)}:{n}: [{kind}] {line.strip()[:160]}")
                    break
    return hits


def test_patterns_catch_history_and_pass_reasons(tmp_path):
    bad = ["# drilling under load (issue 16)", "see Issue #3", "Measured 2026-11-26 on this machine",
           "(It used to crash one run in five)", "kept since 2025", "ARPACK, the earlier path",
           "this was previously the default", "before the fix the file was empty"]
    good = ["the hot column is used to compute z", "values are used to refuse an inexact morph",
            "an issue with the mesh", "19 682.31 Hz", "time 2026 s", "a fix for the pivot is applied"]
    for i, line in enumerate(bad + good):
        (tmp_path / f"f{i}.py").write_text(line + "\n")
    found = {h.split(":")[0] for h in _hits_in(tmp_path)}
    assert found == {f"f{i}.py" for i in range(len(bad))}


def _hits_in(folder: Path) -> list[str]:
    hits = []
    for path in sorted(folder.glob("*.py")):
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if any(rx.search(line) for rx in PATTERNS.values()):
                hits.append(f"{path.name}:{n}")
    return hits


def test_code_and_docs_say_why_not_when():
    files = _files()
    assert len(files) > 100 and ROOT / "README.md" in files           # the scan does reach the trees
    hits = history_lines(files)
    assert not hits, "history in code or docs (say why, not when):\n" + "\n".join(hits)
