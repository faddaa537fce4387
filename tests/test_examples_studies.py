"""Examples 5-8 of results/examples/ (own horn, preload stress, a study on Dask, drilling) run as a
user runs them with their ``--fast`` settings, and what they print and write holds numbers that
agree with independent checks (examples 1-4 and the gallery: tests/test_examples.py).
"""

import re

import pytest

from examples_run import run_example


def test_ex05_own_horn(tmp_path):
    out, folder = run_example("ex05_own_horn.py", tmp_path)
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
    out, folder = run_example("ex06_preload_stress.py", tmp_path)
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

    out, folder = run_example("ex07_study_on_dask.py", tmp_path)
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
    out, folder = run_example("ex08_drilling.py", tmp_path)
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
