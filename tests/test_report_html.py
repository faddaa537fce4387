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

import base64
import io
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

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


def test_report_carries_headline_and_provenance(written, summary):
    md = (written / "report.md").read_text()
    assert md.split("\n")[2].startswith("**Headline (device scenario, 8 g free mass):**")
    assert "26.46 ± 0.64 mJ" in md.split("\n")[2]            # the 8 g device row of the committed summary
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


# ---- the browser -----------------------------------------------------------------------------

def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        exe = shutil.which(name)
        if exe:
            return exe
    pytest.fail("Chromium is not installed: the report.html check needs a real headless browser "
                "(apt-get install -y --no-install-recommends chromium; CI does this in .ci/run)")


def _onto_3_and_4(read_end: int, write_end: int) -> None:
    """In the child before exec: the pipe ends as fd 3 and 4, inheritable (the originals close on exec)."""
    a, b = os.dup(read_end), os.dup(write_end)          # copies first, so neither end is clobbered
    os.dup2(a, 3)
    os.dup2(b, 4)
    os.set_inheritable(3, True)
    os.set_inheritable(4, True)


class _Browser:
    """A headless Chromium driven over the DevTools pipe; one page target."""

    def __init__(self, tmp: Path):
        to_chrome_r, self._w = os.pipe()
        self._r, from_chrome_w = os.pipe()
        self.proc = subprocess.Popen(
            [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--disable-dev-shm-usage", "--hide-scrollbars", f"--user-data-dir={tmp / 'profile'}",
             "--remote-debugging-pipe", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=lambda: _onto_3_and_4(to_chrome_r, from_chrome_w))
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            if time.monotonic() > deadline:
                raise TimeoutError("Chromium did not answer in time")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise RuntimeError(f"Chromium closed the DevTools pipe (exit code {self.proc.poll()})")
            self._buf += chunk
        msg, _, self._buf = self._buf.partition(b"\0")
        return json.loads(msg)

    def call(self, method: str, params: dict | None = None, *, session: bool = False, timeout: float = 30.0):
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            m = self._read(deadline)
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m["result"]
            self.events.append(m)

    def wait_for(self, method: str, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        for i, m in enumerate(self.events):
            if m.get("method") == method:
                return self.events.pop(i)
        while True:
            m = self._read(deadline)
            if m.get("method") == method:
                return m
            self.events.append(m)

    def close(self):
        try:
            self.call("Browser.close", timeout=5)
        except Exception:                       # the browser may already be gone; it is killed below
            pass
        for fd in (self._w, self._r):
            os.close(fd)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def _inspect(page: Path) -> dict:
    """Load ``page`` in headless Chromium; return what a reader would see and what went wrong."""
    with tempfile.TemporaryDirectory() as tmp:
        b = _Browser(Path(tmp))
        try:
            for domain in ("Page", "Runtime", "Log", "Network"):
                b.call(f"{domain}.enable", session=True)
            b.call("Emulation.setDeviceMetricsOverride",
                   {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False}, session=True)
            b.call("Page.navigate", {"url": page.resolve().as_uri()}, session=True)
            b.wait_for("Page.loadEventFired")
            probe = b.call("Runtime.evaluate", {"returnByValue": True, "awaitPromise": True, "expression": """
                (async () => {
                  const imgs = Array.from(document.images);
                  await Promise.all(imgs.map(i => i.decode().catch(() => null)));
                  const h = document.getElementById('headline');
                  return {images: imgs.map(i => [i.alt, i.complete, i.naturalWidth]),
                          headline: h ? h.innerText : null, tables: document.querySelectorAll('table').length,
                          title: document.title, height: document.body.scrollHeight};
                })()"""}, session=True)["result"]["value"]
            shot = base64.b64decode(b.call("Page.captureScreenshot", {"format": "png"}, session=True)["data"])
            time.sleep(0.2)                     # let late console messages arrive before reading them
            b.call("Runtime.evaluate", {"expression": "0"}, session=True)
        finally:
            b.close()
    errors, urls = [], []
    for m in b.events:
        p, meth = m.get("params", {}), m.get("method")
        if meth == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            errors.append("console: " + " ".join(str(a.get("value", a.get("description"))) for a in p["args"]))
        elif meth == "Runtime.exceptionThrown":
            errors.append("exception: " + p["exceptionDetails"].get("text", ""))
        elif meth == "Log.entryAdded" and p["entry"]["level"] == "error":
            errors.append("log: " + p["entry"]["text"])
        elif meth == "Network.requestWillBeSent":
            urls.append(p["request"]["url"])
        elif meth == "Network.loadingFailed":
            errors.append("network: " + p.get("errorText", ""))
    return {**probe, "errors": errors, "urls": urls, "screenshot": shot}


def _colours(png: bytes) -> int:
    from PIL import Image

    im = Image.open(io.BytesIO(png)).convert("RGB")
    return len(im.getcolors(maxcolors=1 << 16) or range(1 << 16))


def test_report_html_in_a_real_browser(written, summary):
    seen = _inspect(written / "report.html")
    assert seen["errors"] == []
    assert seen["images"] and all(ok and w > 0 for _, ok, w in seen["images"]), seen["images"]
    assert len(seen["images"]) == len(summary["files"]["figures"]) + len(summary["files"]["renders"]) + 1
    assert seen["headline"] and seen["headline"].startswith("Headline (device scenario, 8 g free mass):")
    assert "26.46 ± 0.64 mJ" in seen["headline"]
    assert seen["tables"] >= 5 and seen["title"].startswith("RPUD end-to-end run")
    assert all(u.startswith(("file:", "data:", "about:")) for u in seen["urls"]), seen["urls"]
    assert seen["screenshot"].startswith(b"\x89PNG") and _colours(seen["screenshot"]) > 1


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
