"""The literate examples in results/examples/ run as a user runs them (a fresh interpreter, an
empty working folder) with their ``--fast`` settings, as the documentation's gallery runs them,
and what they print and write holds numbers that agree with independent checks.
"""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "results" / "examples"


def _run(name, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, str(EXAMPLES / name), "--fast"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout, tmp_path / "example_output"


def test_every_example_is_tested():
    names = sorted(p.name for p in EXAMPLES.glob("ex*.py"))
    tested = sorted(re.findall(r'_run\("(ex\d\d_\w+\.py)"', Path(__file__).read_text()))
    assert names == tested and len(names) >= 8


def test_every_example_has_a_gallery_title():
    # sphinx-gallery takes the page title from the docstring's first line, underlined with "="
    for path in sorted(EXAMPLES.glob("ex*.py")):
        lines = path.read_text().split("\n")
        title = lines[0].removeprefix('"""')
        assert title and lines[1] == "=" * len(lines[1]) and len(lines[1]) >= len(title), path.name


def test_gallery_shows_the_pictures_an_example_writes(tmp_path):
    # renders close their plotters, so the gallery shows the written PNGs: each new one once,
    # none left from an earlier run
    pytest.importorskip("sphinx_gallery")
    from sphinx_gallery.scrapers import ImagePathIterator

    sys.path.insert(0, str(ROOT / "docs"))
    try:
        import _gallery_hooks as hooks
    finally:
        sys.path.remove(str(ROOT / "docs"))
    written = tmp_path / "example_output" / "renders"
    written.mkdir(parents=True)
    stale = tmp_path / "example_output" / "stale.png"
    stale.write_bytes(b"from an earlier run")
    os.utime(stale, ns=(0, 0))
    render = written / "mode.png"
    render.write_bytes(b"this run's picture")
    (tmp_path / "images").mkdir()
    block_vars = {"src_file": str(tmp_path / "ex99_demo.py"),
                  "image_path_iterator": ImagePathIterator(tmp_path / "images" / "sphx_glr_ex99_demo_{0:03}.png")}
    rst = hooks.saved_pictures_scraper(None, block_vars, {"src_dir": str(tmp_path)})
    assert "sphx_glr_ex99_demo_001.png" in rst and "002" not in rst
    assert (tmp_path / "images" / "sphx_glr_ex99_demo_001.png").read_bytes() == render.read_bytes()
    assert hooks.saved_pictures_scraper(None, block_vars, {"src_dir": str(tmp_path)}) == ""
    assert hooks.reset_argv({}, {}) == ["--fast"]


def test_ex01_modal(tmp_path):
    out, folder = _run("ex01_modal.py", tmp_path)
    f_r, f_a, k = map(float, re.search(r"f_r = ([\d.]+) Hz, f_a = ([\d.]+) Hz, k_eff = ([\d.]+)", out).groups())
    # the default design is matched to 20 kHz on its default mesh; on the coarse mesh the
    # longitudinal mode stays within 2 %, with the coupling of a PZT-8 Langevin drill
    assert f_r == pytest.approx(20e3, rel=0.02) and f_a > f_r and 0.25 < k < 0.5
    record = json.loads((folder / "modal_result.json").read_text())
    assert any(m["f_r_hz"] == pytest.approx(f_r, abs=0.05) and m["label"] == "longitudinal"
               for m in record["modes"])
    for name in ("working_mode.png", "modal_result.npz", "modes.vtu"):
        assert (folder / name).stat().st_size > 10_000, name


def test_ex02_own_design(tmp_path):
    out, folder = _run("ex02_own_design.py", tmp_path)
    peak, dip, f_r, f_a = map(float, re.search(
        r"peak at ([\d.]+) Hz and dip at ([\d.]+) Hz \(modal: ([\d.]+) / ([\d.]+) Hz\)", out).groups())
    # the admittance extrema of the (lossy, sampled) sweep sit on the lossless modal pair
    assert peak == pytest.approx(f_r, rel=2e-3) and dip == pytest.approx(f_a, rel=2e-3)
    # half-wave sandwich: 2 x 40 mm steel + 10 mm PZT-8, about 25 kHz
    assert f_r == pytest.approx(24.3e3, rel=0.03)
    assert (folder / "langevin_admittance.png").stat().st_size > 10_000


def test_ex03_impact_statistics(tmp_path):
    out, folder = _run("ex03_impact_statistics.py", tmp_path)
    record = json.loads((folder / "ensemble_stats.json").read_text())
    assert record["converged"] and record["scenario"] == "device"
    for q in ("tool_impact_rate_hz", "mean_tool_ke_after_j", "tool_power_w"):
        e = record[q]
        assert e["ci95_half_width"] <= 0.10 * e["mean"], q
    # every member's raw numbers are saved, and they give the printed mean back
    import numpy as np

    with np.load(folder / "ensemble_stats.npz") as z:
        assert z["members"].shape[0] == record["members"]
    ke = record["mean_tool_ke_after_j"]
    assert f"{ke['mean'] * 1e3:.2f} ± {ke['ci95_half_width'] * 1e3:.2f} mJ" in out


def test_ex04_pipeline(tmp_path):
    out, folder = _run("ex04_pipeline.py", tmp_path)
    summary = json.loads((folder / "pipeline" / "summary.json").read_text())
    assert summary["design"]["name"] == "longer_coupler"
    rows = {r["m_free_kg"]: r["device_fe"]["mean_tool_ke_after_j"] for r in summary["kinetic_energy_table"]}
    assert rows[0.008]["ci95"][0] > rows[0.004]["ci95"][1] > 0      # heavier free mass, more energy
    assert out.count("PipelineResult(") == 1


def test_ex05_own_horn(tmp_path):
    out, folder = _run("ex05_own_horn.py", tmp_path)
    f_r = {name: float(f) for name, f in re.findall(r"^(\S+) +horn [\d.]+ mm: .*f_r = ([\d.]+) Hz", out, flags=re.M)}
    assert set(f_r) == {"rpud-default", "longer_horn"}
    # the default drill is matched to 20 kHz; a 10 mm longer horn (on a drill 140 mm long)
    # lowers the working resonance by a few per cent
    assert f_r["rpud-default"] == pytest.approx(20e3, rel=0.02)
    assert 0.02 < 1 - f_r["longer_horn"] / f_r["rpud-default"] < 0.12
    import geometry

    design = geometry.load_design(folder / "longer_horn.toml")
    base = geometry.default_design()
    assert design.name == "longer_horn" and design.horn.length == pytest.approx(base.horn.length + 0.010)
    assert design.coupler == base.coupler and design.stack == base.stack
    assert (folder / "longer_horn_mode.png").stat().st_size > 10_000


def test_ex06_preload_stress(tmp_path):
    out, folder = _run("ex06_preload_stress.py", tmp_path)
    # the preload's mean pressure is the force over the ring face, pi/4 (D^2 - d^2) of the stack
    import math

    import geometry

    st = geometry.default_design().stack
    area_mm2 = math.pi / 4 * (st.outer_diameter ** 2 - st.inner_diameter ** 2) * 1e6
    mpa, area = map(float, re.search(r"([\d.]+) MPa on the ([\d.]+) mm\^2 ring face", out).groups())
    assert area == pytest.approx(area_mm2, abs=0.05) and mpa == pytest.approx(20e3 / area_mm2, abs=0.05)
    rings = re.findall(r"(ring_\d): tension ([\d.]+) % of its rating without preload, ([\d.]+) % with", out)
    assert len(rings) == st.n_rings
    for ring, bare, pre in rings:
        assert float(pre) < float(bare), ring            # the preload keeps the ceramic compressed
    assert out.count("region (part, material)") == 2   # both tables printed
    assert (folder / "stress_preloaded.png").stat().st_size > 10_000


def test_ex07_study_on_dask(tmp_path):
    import csv

    out, folder = _run("ex07_study_on_dask.py", tmp_path)
    with open(folder / "study_small" / "table.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    # one design: every point shares the mesh and the FE results
    assert len({r["f_r_hz"] for r in rows}) == 1 and len({r["tetrahedra"] for r in rows}) == 1
    ke = {(float(r["in.impact.m_free"]), float(r["in.drive.voltage"])): (float(r["tool_ke_j"]), float(r["tool_ke_j_ci95"]))
          for r in rows}
    for v in (150.0, 225.0):           # a heavier free mass, more tool energy (disjoint 95 % CIs)
        (lo, lo_hw), (hi, hi_hw) = ke[(0.004, v)], ke[(0.008, v)]
        assert hi - hi_hw > lo + lo_hw > 0
    for m in (0.004, 0.008):           # a higher drive, more tool energy
        assert ke[(m, 225.0)][0] > ke[(m, 150.0)][0]
    for (m, v), (k, hw) in ke.items():
        assert f"{m * 1e3:g} g at {v:g} V:" in out and f"tool KE {k * 1e3:.3f} ± {hw * 1e3:.3f} mJ" in out
    assert (folder / "study_small" / "figures").is_dir()


def test_ex08_drilling(tmp_path):
    out, folder = _run("ex08_drilling.py", tmp_path)
    est = r"([\d.]+) ± ([\d.]+)"
    depth = {float(m): (float(d), float(hw)) for m, d, hw in re.findall(
        r"^ +(\d+) g .* " + est + r"  \d+$", out, flags=re.M)}
    assert set(depth) == {0.0, 2.0, 8.0}
    assert depth[0.0] == (0.0, 0.0)    # no free mass, no blow: 7 N is below the crushing threshold
    (d2, h2), (d8, h8) = depth[2.0], depth[8.0]
    assert d8 - h8 > d2 + h2 > 0       # deeper with the heavier free mass (the article's trend)
    (soft, _), (hard, _) = [(float(d), float(hw)) for d, hw in re.findall(r"depth " + est + " mm", out.strip().splitlines()[-1])]
    assert soft == pytest.approx(d8) and hard < soft
    assert (folder / "depth_vs_free_mass.png").stat().st_size > 10_000
