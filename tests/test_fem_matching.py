"""Resonance matching, the V-LT coupler's twist, and the ``python -m fem.modal`` CLI.

References: the target frequency itself (the match must land on it), independence of the
tuned design from the starting point (a second and third run), and the symmetry argument that
axial slots (angle 0) cannot turn an axial wave into torsion.
"""

import subprocess
import sys

import numpy as np
import pytest

import geometry
from rpud_common import ParameterError
from fem.assembly import assemble
from fem.matching import MatchSettings, front_half, match, nodal_plane, working_mode
from fem.modal import modal_analysis
from fem.modeshape import energy_shares, surface_motion
from geometry.examples import article_design

# a coarse variant of the default drill: plain coupler (no slots, no teeth), 6 mm rings
COARSE = dict(mesh_size=0.008)


def _coarse_design():
    return geometry.filleted(article_design(), 0.0).replace(
        {"coupler.n_slots": 0, "coupler.n_teeth": 0, "stack.ring_thickness": 0.006})


@pytest.fixture(scope="module")
def perturbed_matches():
    d0 = _coarse_design()
    out = []
    for scale in (0.9, 1.1):
        start = d0.replace({"horn.length": d0.horn.length * scale, "coupler.length": d0.coupler.length * scale})
        out.append(match(start, MatchSettings(**COARSE)))
    return out


def test_match_converges_to_the_same_design_from_perturbed_starts(perturbed_matches):
    a, b = perturbed_matches
    for r in (a, b):
        assert r.converged
        assert r.matched_hz == pytest.approx(20e3, rel=5e-3)          # the tolerance
        assert r.matched_hz == pytest.approx(20e3, rel=2e-4)          # what the root finding achieves
        assert [it["stage"] for it in r.iterations][0] == "horn"
    for path in ("horn.length", "coupler.length"):
        assert abs(a.tuned[path] - b.tuned[path]) < 1e-4                 # 0.1 mm
    # the starts were 10 % off on both lengths: the match really moved them
    assert abs(a.tuned["horn.length"] - a.start["horn.length"]) > 3e-3


def test_matched_mode_has_its_node_in_the_stack(perturbed_matches):
    r = perturbed_matches[0]
    w = r.working_index
    assert r.modal.labels[w] == "longitudinal"
    z_node = nodal_plane(r.design)
    shape = r.modal.shapes[w]
    nodes = r.system.nodes
    # mean axial displacement in thin slabs: it changes sign across the cut plane
    below = np.abs(nodes[:, 2] - (z_node - 0.004)) < 0.001
    above = np.abs(nodes[:, 2] - (z_node + 0.004)) < 0.001
    assert np.sign(shape[below, 2].mean()) != np.sign(shape[above, 2].mean())
    assert abs(r.node_ratio) < 0.25                                  # the flange moves little


def test_front_half_cuts_at_the_middle_electrode():
    d = article_design().replace({"stack.bolt_diameter": 0.0})       # the cut's areas: the rings' only
    assert nodal_plane(d) == pytest.approx(2 * d.stack.ring_thickness)
    mesh = geometry.build_mesh(d)
    half = front_half(mesh, nodal_plane(d))
    assert half.points[:, 2].min() == pytest.approx(nodal_plane(d), abs=1e-12)
    assert {r.name for r in half.regions} == {"ring_3", "ring_4", "flange_disc", "horn"}
    assert len(half.facets("node_plane")) > 0 and "horn_tip" in half.facet_sets
    with pytest.raises(ParameterError, match="z_cut"):
        front_half(mesh, 1.0)


def _teeth_twist(design):
    mesh = geometry.build_mesh(design)
    system = assemble(mesh)
    res = modal_analysis(system, 20e3, 4, open_circuit=False)
    w = working_mode(system, res.f_r_hz, res.vectors, 20e3)
    teeth = surface_motion(mesh, res.shapes[w], "teeth_tops")
    shares = energy_shares(mesh, res.shapes[w : w + 1]).parts["coupler"]
    return teeth["tangential"] / teeth["axial"], float(shares.torsional[0])


def test_inclined_slots_twist_the_teeth_and_axial_slots_do_not():
    d = article_design().replace({"stack.bolt_diameter": 0.0})       # the measured twists' design
    ratio_30, tors_30 = _teeth_twist(d)
    ratio_0, tors_0 = _teeth_twist(d.replace({"coupler.slot_angle_deg": 0.0}))
    assert ratio_30 > 0.02 and tors_30 > 1e-3          # an ellipse: tangential and axial both present
    assert ratio_0 < 0.05 * ratio_30                   # axial slots: no twist, up to mesh asymmetry
    assert tors_0 < 0.01 * tors_30


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "fem.modal", *args], capture_output=True, text=True, cwd=cwd)


def test_cli_bad_input_is_one_line_and_exit_2(tmp_path):
    r = _cli("--match", "--tune", "horn.lenght,coupler.length", "--json", "m.json", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "horn.lenght" in r.stderr
    assert not (tmp_path / "m.json").exists()
    bad = tmp_path / "bad.toml"
    d = article_design()
    bad.write_text(d.to_toml().replace(f"length = {d.horn.length}", "length = -0.01", 1))
    r = _cli("--match", "--design", str(bad), cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "horn.length" in r.stderr
    coarse = tmp_path / "coarse.toml"
    _coarse_design().save(coarse)
    r = _cli("--match", "--design", str(coarse), "--mesh-size", "0.008", "--target", "40000",
             "--bracket", "0.9,1.1", "--json", "m.json", cwd=tmp_path)
    assert r.returncode == 2 and "outside the bracket" in r.stderr
    assert r.stderr.strip().count("\n") == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "coarse.toml"]
