"""``python -m geometry``: outputs, report contents, bad input = one line + exit 2 + no file."""

import json
import os
import subprocess
import sys
from pathlib import Path

import meshio
import numpy as np
import pytest

from geometry.__main__ import main
from rpud_common import run_cli
from geometry.design import load_design

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "geometry" / "examples.toml"


def _run(args, capsys):
    code = run_cli(main, args, prog="python -m geometry")
    out, err = capsys.readouterr()
    return code, out, err


def test_write_default_then_build_everything(tmp_path, capsys):
    design = tmp_path / "design.toml"
    assert _run(["--write-default", str(design), "-q"], capsys)[0] == 0
    d = load_design(design)
    outs = {k: tmp_path / f"rpud.{k}" for k in ("msh", "vtu", "json", "png")}
    code, out, err = _run(["--design", str(design), "--mesh", str(outs["msh"]), "--vtu", str(outs["vtu"]),
                           "--json", str(outs["json"]), "--png", str(outs["png"]), "--mesh-size", "0.012", "-q"], capsys)
    assert code == 0, err
    assert "horn" in out and "1-D first longitudinal mode" in out
    rep = json.loads(outs["json"].read_text())
    assert set(rep["parts"]) == {"coupler", "stack", "flange", "horn", "bolt"}      # the default carries its stack bolt
    for part, p in rep["parts"].items():
        assert abs(p["volume_error"]) < 0.005 and p["mass_kg"] > 0, part
    assert rep["parts"]["horn"]["mass_kg"] == pytest.approx(d.part_masses()["horn"], rel=0.005)
    groups = rep["physical_groups"]
    assert {"horn_tip", "teeth_tops", "flange", "electrode_0", "electrode_4", "ring_1", "coupler"} <= set(groups)
    assert all(g["entities"] > 0 for g in groups.values())
    assert rep["mesh"]["n_elements"] > 0 and rep["mesh"]["n_nodes"] > rep["mesh"]["n_elements"]
    assert {"min_sicn", "median_sicn", "min_gamma", "median_gamma"} <= set(rep["quality"])
    assert rep["timings_s"]["total"] > 0 and 15e3 < rep["f1_1d_hz"] < 25e3
    back = meshio.read(outs["msh"])
    assert "tetra10" in back.cells_dict and "horn_tip" in back.field_data
    assert "tetra10" in meshio.read(outs["vtu"]).cells_dict
    # the picture is a real picture
    import pyvista as pv

    img = pv.read(str(outs["png"]))
    arr = np.asarray(img.point_data[img.point_data.keys()[0]], dtype=float)
    assert img.dimensions[:2] == (1400, 700) and arr.std() > 10
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["design.toml"] + [p.name for p in outs.values()])


def test_examples_select_order_1(tmp_path, capsys):
    out_json = tmp_path / "k31.json"
    code, out, err = _run(["--design", str(EXAMPLES), "--select", "k31_bar", "--order", "1",
                           "--json", str(out_json), "-q"], capsys)
    assert code == 0, err
    rep = json.loads(out_json.read_text())
    assert rep["mesh"]["order"] == 1 and [e["role"] for e in rep["electrodes"]] == ["ground", "hot"]


@pytest.mark.parametrize("toml, words", [
    ("[coupler]\nslot_depth = 0.012\n", "coupler.slot_depth = 0.012: must be < wall thickness"),
    ("[horn]\nlength = -0.05\n", "horn.length = -0.05"),
    ("[coupler]\nn_teeth = 30\n", "coupler.n_teeth = 30: more teeth than fit"),
    ("bore_diameter = 0.02\n", "bore_diameter = 0.02: bore larger than the ring"),
    ("[horn]\nmaterial = \"brass\"\n", "horn.material = 'brass': unknown"),
    ("[horn]\nlenght = 0.05\n", "horn.lenght"),
    ("kind = \"stack\"\n[[segments]]\nname = \"a\"\nlength = 0.1\nouter_diameter = 0.01\n"
     "[[segments]]\nname = \"b\"\nlength = 0.1\nouter_diameter = 0.01\nstart = 0.05\n", "overlapping parts"),
])
def test_bad_designs_exit_2_with_one_line_and_no_file(tmp_path, capsys, toml, words):
    design = tmp_path / "bad.toml"
    design.write_text(toml)
    outs = [tmp_path / "o.msh", tmp_path / "o.json", tmp_path / "o.png", tmp_path / "o.vtu"]
    code, out, err = _run(["--design", str(design), "--mesh", str(outs[0]), "--json", str(outs[1]),
                           "--png", str(outs[2]), "--vtu", str(outs[3])], capsys)
    assert code == 2
    lines = [l for l in err.splitlines() if l.strip()]
    assert len(lines) == 1 and words in lines[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_bad_options_exit_2(tmp_path, capsys):
    assert _run(["--json", str(tmp_path / "x.txt")], capsys)[0] == 2
    assert _run(["--design", str(tmp_path / "missing.toml")], capsys)[0] == 2
    assert _run(["--design", str(EXAMPLES)], capsys)[0] == 2  # several designs, none selected
    assert list(tmp_path.iterdir()) == []
    proc = subprocess.run([sys.executable, "-m", "geometry", "--order", "3"], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1


def test_gmsh_time_limit_ends_in_one_line(tmp_path):
    """Gmsh cannot be stopped, so the process ends by os._exit after the line: no crash, no file."""
    proc = subprocess.run([sys.executable, "-m", "geometry", "--json", "o.json", "--mesh", "o.msh",
                           "--gmsh-timeout", "0.3"], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "--gmsh-timeout = 0.3: Gmsh did not finish 'rpud-default' within the limit" in proc.stderr
    assert list(tmp_path.iterdir()) == []
