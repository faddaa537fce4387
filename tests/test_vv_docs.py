"""The V&V recorder (tests/conftest.py) and the docs extensions that render its records and the
benchmark scripts' JSON (docs/_ext/vv_pages.py, docs/_ext/benchmark_tables.py)."""

import json
import sys
from pathlib import Path

import pytest

from conftest import VVRecorder

ROOT = Path(__file__).resolve().parent.parent
sphinx_errors = pytest.importorskip("sphinx.errors")
sys.path.insert(0, str(ROOT / "docs"))
from _ext import benchmark_tables, vv_pages  # noqa: E402


def _record(rec, check_id, target, computed, tol, kind="relative"):
    return rec.record(check_id, title="t", description="d", reference="r", assumptions="a", target=target,
                      computed=computed, tolerance=tol, unit="Hz", tolerance_kind=kind)


def test_recorder_writes_ratio_and_the_tests_own_verdict(tmp_path):
    rec = VVRecorder(tmp_path, "tests/x.py::test_y")
    ok = _record(rec, "VV-T-01", 100.0, 100.4, 0.005)
    bad = _record(rec, "VV-T-02", 100.0, 101.0, 0.5, kind="absolute")
    assert ok["ratio"] == pytest.approx(1.004) and ok["passed"]
    assert bad["deviation"] == pytest.approx(1.0) and not bad["passed"]
    on_disk = json.loads((tmp_path / "VV-T-01.json").read_text())
    assert on_disk == ok and on_disk["test"] == "tests/x.py::test_y"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["VV-T-01.json", "VV-T-02.json"]   # no temporaries
    with pytest.raises(ValueError, match="tolerance_kind"):
        _record(rec, "VV-T-03", 1.0, 1.0, 0.1, kind="percent")


def test_vv_pages_refuse_an_empty_manual_and_render_the_numbers(tmp_path):
    with pytest.raises(sphinx_errors.ExtensionError, match="no V&V records"):
        vv_pages.load_records(tmp_path)
    rec = VVRecorder(tmp_path, "tests/x.py::test_y")
    _record(rec, "VV-T-02", 100.0, 101.0, 0.5, kind="absolute")
    _record(rec, "VV-T-01", 100.0, 100.4, 0.005)
    recs = vv_pages.load_records(tmp_path)
    assert [r["id"] for r in recs] == ["VV-T-01", "VV-T-02"]
    page = vv_pages.render_page(recs[0])
    for section in ("## Description", "## Reference", "## Analysis assumptions", "## Results comparison"):
        assert section in page
    assert "| 100 | 100.4 | 1.004000000 |" in page
    summary = vv_pages.summary_markdown(recs)
    assert "**FAIL**" in summary and "1 of 2 checks within their tolerance" in summary


def test_benchmark_tables_render_the_json_or_say_how_to_measure(tmp_path):
    bench = tmp_path / "benchmarks"
    results = bench / "results"
    results.mkdir(parents=True)
    (bench / "bench_x.py").write_text('"""Speed of x against y.\n\nMore."""\n')
    text, path = benchmark_tables.render("bench_x", results, bench)
    assert path is None and "python benchmarks/bench_x.py" in text and "|" not in text
    (results / "bench_x.json").write_text(json.dumps({
        "tables": [{"headers": ["case", "time"], "rows": [["a|b", "1.5 s"]]}],
        "machine": {"cpu": "CPU X", "cores": 2, "os": "Linux", "python": "3.11", "load_average_1min": 0.5},
        "provenance": {"rpud_version": "0.1.0", "git_commit": "abc", "date_utc": "D", "command": "c"}}))
    text, path = benchmark_tables.render("bench_x", results, bench)
    assert text.startswith("Speed of x against y.")
    assert "| a\\|b | 1.5 s |" in text and "CPU X, 2 cores" in text and "load average 0.5" in text
