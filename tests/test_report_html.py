"""The run report: Markdown tables that render, and a self-contained ``report.html`` checked in a
real headless Chromium (it loads, logs no error, every image decodes, the headline is shown, the
page is not blank, nothing is fetched from outside the file).

The report is written from the committed ``results/default`` summary and figures, so no pipeline
runs here. Chromium is driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``:
fd 3 in, fd 4 out, NUL-terminated JSON), standard library only. A missing Chromium fails the test
with the reason: CI installs it (``.ci/run``), and a skipped browser check would hide a broken
report.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from browser import BrowserMissing, colours, inspect_page
from results.report import escape_table_pipes, markdown_to_html, report_lines, table_cells, write_report

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ROOT / "results" / "default"


@pytest.fixture(scope="module")
def summary() -> dict:
    return json.loads((DEFAULT / "summary.json").read_text())


@pytest.fixture(scope="module")
def written(summary, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    write_report(summary, out / "report.md", asset_dir=DEFAULT)
    return out


def _tables(lines: list[str]) -> list[list[str]]:
    blocks, cur = [], []
    for ln in [*lines, ""]:
        if ln.strip().startswith("|"):
            cur.append(ln)
        elif cur:
            blocks.append(cur)
            cur = []
    return blocks


def test_every_markdown_table_row_has_its_header_column_count(written):
    lines = (written / "report.md").read_text().split("\n")
    tables = _tables(lines)
    assert len(tables) >= 5                                   # quantities, KE, coupled, stress, timings, provenance
    for t in tables:
        widths = [len(table_cells(r)) for r in t]
        assert len(set(widths)) == 1, (t[0], widths)
        assert all(re.fullmatch(r":?-{3,}:?", c) for c in table_cells(t[1]))
    stress = next(t for t in tables if "utilisation" in t[0])
    assert any(table_cells(r)[1] == "|E|" for r in stress)     # the field magnitude survives as one cell


def test_escape_is_idempotent_and_leaves_prose_alone():
    row = "| ring_1 | |E| | 0.1 kV/mm |"
    once = escape_table_pipes(row)
    assert once == "| ring_1 | \\|E\\| | 0.1 kV/mm |" and escape_table_pipes(once) == once
    assert table_cells(once) == ["ring_1", "|E|", "0.1 kV/mm"]
    assert escape_table_pipes("principal stress and |E| per ring") == "principal stress and |E| per ring"
    assert escape_table_pipes("|---|---|") == "|---|---|"


def _headline_ke(summary: dict) -> str:
    """The headline's tool energy as the report must print it: the committed summary's headline
    record (the compliant model at the reference free mass), mean ± 95 % CI ± model form in mJ."""
    from results.report import headline_text

    rec = summary["headline"]["mean_tool_ke_after_j"]
    text = headline_text(summary)
    mean = f"{rec['mean'] * 1e3:.3g}"
    assert mean in text          # the sentence carries the record's mean, to its three digits
    return text[text.index(mean):text.index(" mJ")]


def test_report_carries_headline_and_provenance(written, summary):
    md = (written / "report.md").read_text()
    assert md.split("\n")[2].startswith("**Headline (compliant contacts, device scenario, 8 g free mass):**")
    assert _headline_ke(summary) in md.split("\n")[2]       # the committed summary's headline record
    prov = md[md.index("## Provenance"):]
    for item in ("rpud version", "git commit", "command line", "date (UTC)"):
        assert f"| {item} |" in prov


def test_html_is_self_contained_with_every_table_and_figure(written, summary):
    page = (written / "report.html").read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//|file:)""", page)
    assert "<link" not in page and "<script" not in page
    n_figs = len(summary["files"]["figures"]) + len(summary["files"]["renders"]) + 1   # + the stress render
    assert page.count('src="data:image/png;base64,') == n_figs
    md_tables = _tables((written / "report.md").read_text().split("\n"))
    assert page.count("<table>") == len(md_tables)
    assert "<td>|E|</td>" in page


def test_a_missing_figure_is_an_error_not_a_broken_image(summary, tmp_path):
    with pytest.raises(FileNotFoundError):
        markdown_to_html(report_lines(summary), tmp_path)


def _inspect(page: Path) -> dict:
    try:
        return inspect_page(page)
    except BrowserMissing as exc:
        pytest.fail(str(exc))


def test_report_html_in_a_real_browser(written, summary):
    seen = _inspect(written / "report.html")
    assert seen["errors"] == []
    assert seen["images"] and all(ok and w > 0 for _, ok, w in seen["images"]), seen["images"]
    assert len(seen["images"]) == len(summary["files"]["figures"]) + len(summary["files"]["renders"]) + 1
    assert seen["headline"] and seen["headline"].startswith("Headline (compliant contacts, device scenario, 8 g free mass):")
    assert _headline_ke(summary) in seen["headline"]
    assert seen["tables"] >= 5 and seen["title"].startswith("RPUD end-to-end run")
    assert all(u.startswith(("file:", "data:", "about:")) for u in seen["urls"]), seen["urls"]
    assert seen["screenshot"].startswith(b"\x89PNG") and colours(seen["screenshot"]) > 1


def test_the_browser_check_sees_a_broken_page(tmp_path):
    """The harness itself: a missing image, a console error and a blank body are all caught."""
    page = tmp_path / "broken.html"
    page.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"><title>x</title></head><body>'
                    '<img src="missing.png" alt="gone"><script>console.error("boom")</script></body></html>')
    seen = _inspect(page)
    assert any("boom" in e for e in seen["errors"])
    assert seen["images"] == [["gone", True, 0]]
    assert seen["headline"] is None


# ---- the figures the report embeds -------------------------------------------------------------

def test_ke_figure_marks_the_headline_and_draws_ci_bars_above_the_markers():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import impact
    from results.figures import kinetic_energy

    tiny = impact.StatsSettings(rel_tol=0.5, n_start=4, n_max=4)
    sweeps = {k: impact.sweep(impact.ImpactParams(), [0.004, 0.008], scenario=sc, settings=tiny)
              for k, sc in (("device_fe", "device"), ("article_fe", "article"))}
    ax = kinetic_energy(sweeps, True)
    try:
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert sum(t.startswith("headline: device") for t in labels) == 1
        assert not any(t.startswith("headline:") and "article" in t.split("(")[0] for t in labels)
        for c in ax.containers:                              # every errorbar: bars and caps over the markers
            line, caps, bars = c
            assert caps and all(a.get_zorder() > line.get_zorder() for a in (*caps, *bars))
        heavy = [c.lines[0].get_linewidth() for c in ax.containers]
        assert heavy[0] > heavy[1]                           # the headline line is the heavy one
    finally:
        plt.close(ax.figure)


def test_explore_axes_carry_words_and_units():
    from results.explore_figures import axis_label, param_scale
    from results.study import OUTPUTS

    for name in OUTPUTS:
        label = axis_label(name)
        assert label != name and re.search(r"\([^()]+\)$", label), label
    assert axis_label("tool_ke_j") == "tool kinetic energy after impact (mJ)"
    assert axis_label("f_r_hz").endswith("(kHz)") and axis_label("tool_rate_hz").endswith("(Hz)")
    assert param_scale("impact.m_free") == (1e3, "free mass (g)")
    assert param_scale("horn.length") == (1e3, "horn length (mm)")
    assert param_scale("coupler.slot_angle_deg") == (1.0, "coupler slot angle (deg)")
