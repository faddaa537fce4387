"""The swept mesher (``mesher="revolve"``, geometry/revolve.py): element cuts, the mesh it builds,
and the working mode against the converged axisymmetric answer.

References: the prism/pyramid cuts against the element volumes and each other (a shared
quadrilateral cut the same way from both sides, the Dompierre et al. rule); the swept mesh's
part volumes against the closed forms (quadratic arcs of 30 degrees: 3e-4; the free coupler 1e-3); the working mode of the
default design without slots and teeth against the independent (r, z) model's converged
f_r / f_a (tests/test_axisym_reference.py): 0.05 %, the swept mesher's accuracy target (measured
+0.041 % / +0.044 %).
"""

import itertools
from pathlib import Path

import numpy as np
import pytest

import fem
from geometry.builder import build
from geometry.examples import article_design
from geometry.design_rpud import filleted
from geometry.report import mesh_part_volumes
from geometry.revolve import (prism_tets, _pyramid_tets, jacobian_ratio, orient, sectors_per_quarter, split_to_tets,
                              straighten)
from rpud_common import ParameterError

import axisym_reference as ar
from reference_designs import reference_default

AXISYM_CONVERGED = (19682.31, 21410.33)
"""Converged f_r, f_a (Hz) of the default design without slots and teeth (the (r, z) model of
tests/axisym_reference.py, reproduced to 2e-5 in tests/test_axisym_reference.py)."""

TOL_REVOLVE = 5e-4
"""The swept mesher's accuracy target: 0.05 % on f_r and f_a."""

TOL_BENDING = 2.5e-3
"""Bending pairs of the swept default mesh against the converged (r, z) harmonic n = 1 (measured
+0.194 % / +0.128 %; the 0.1 % aimed for is not met)."""

TOL_TORSION = 1e-3
"""First torsion against the converged harmonic n = 0 (measured +0.069 %; 0.1 % aimed for)."""

_PRISM = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1.0]])


def _volume(p):
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6


def _faces_on(tets, quad):
    """Triangles of ``tets`` (global tags) whose three corners are corners of ``quad``."""
    out = set()
    for t in tets:
        for f in itertools.combinations(t, 3):
            if set(f) <= set(quad):
                out.add(frozenset(f))
    return out


def test_prism_cuts_fill_the_prism_and_agree_across_shared_faces():
    rng = np.random.default_rng(3)
    # two prisms sharing the quad face (1, 2 | 4, 5): bottom 0 1 2 / 6 2 1, top 3 4 5 / 7 5 4
    points = np.vstack([_PRISM, [[1, 1, 0], [1, 1, 1]]])
    prisms = np.array([[0, 1, 2, 3, 4, 5], [6, 2, 1, 7, 5, 4]])
    for _ in range(200):
        tags = rng.permutation(8)
        glob = tags[prisms]
        cuts = prism_tets(glob)
        tets = [[glob[e, c] for c in cut] for e in range(2) for cut in cuts[e]]
        inv = np.argsort(tags)
        corners = points[inv[np.array(tets)]]
        vol = np.abs(_volume(corners))
        assert vol.sum() == pytest.approx(1.0, abs=1e-12) and vol.min() > 0.1   # 2 prisms of 1/2, no sliver
        shared = [tags[i] for i in (1, 2, 4, 5)]
        a = _faces_on(tets[:3], shared)
        b = _faces_on(tets[3:], shared)
        assert a == b and len(a) == 2


def test_pyramid_cut_agrees_with_the_prism_behind_it():
    rng = np.random.default_rng(4)
    for _ in range(100):
        tags = rng.permutation(7)
        prism = tags[[0, 1, 2, 3, 4, 5]][None]
        pyramid = tags[[1, 2, 5, 4, 6]][None]           # base = the prism's face (1, 2, 5, 4), apex 6
        tp = [[prism[0, c] for c in cut] for cut in prism_tets(prism)[0]]
        ty = [[pyramid[0, c] for c in cut] for cut in _pyramid_tets(pyramid)[0]]
        quad = pyramid[0, :4]
        assert _faces_on(tp, quad) == _faces_on(ty, quad)


def test_split_keeps_mid_nodes_and_orient_makes_volumes_positive():
    # one 18-node prism: its 3 tetrahedra of 10 nodes take the prism's edge and face nodes
    ref = np.array([[0, 0, -1], [1, 0, -1], [0, 1, -1], [0, 0, 1], [1, 0, 1], [0, 1, 1], [.5, 0, -1], [0, .5, -1],
                    [0, 0, 0], [.5, .5, -1], [1, 0, 0], [0, 1, 0], [.5, 0, 1], [0, .5, 1], [.5, .5, 1], [.5, 0, 0],
                    [0, .5, 0], [.5, .5, 0]], dtype=float)
    nodes = np.arange(18)[None]
    tets = split_to_tets({13: (6, ref)}, {13: nodes})[13]
    assert tets.shape == (3, 10)
    tets = orient(tets, ref)
    assert (_volume(ref[tets[:, :4]]) > 0).all()
    # every mid node is the midpoint of its edge, so the straight P2 map has a constant Jacobian
    assert np.allclose(jacobian_ratio(ref, tets), 1.0)


def test_stepwise_straightening_unfolds_and_keeps_what_curvature_it_can():
    """A 10-node element folded by one bent edge (its mid-node pushed across the element): whole
    edges (step 1) put the node on the chord; steps of 1/8 stop at the first pull that clears the
    threshold, between the arc and the chord."""
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    edges = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
    pts = np.vstack([corners, [0.5 * (corners[i] + corners[j]) for i, j in edges]])
    pts[4] += [0.0, 0.45, 0.45]                 # edge 0-1 bent deep into the element
    cells = np.arange(10)[None, :]
    free = np.array([True])
    assert jacobian_ratio(pts, cells)[0] < 0.05
    whole, n_whole = straighten(pts, cells, free)
    assert n_whole == 1 and np.array_equal(whole[4], [0.5, 0.0, 0.0])
    part, n_part = straighten(pts, cells, free, rounds=12, step=0.125)
    pull = np.linalg.norm(part[4] - [0.5, 0, 0]) / np.linalg.norm(pts[4] - [0.5, 0, 0])
    assert n_part == 1 and jacobian_ratio(part, cells)[0] >= 0.05
    assert 0 < pull < 1 and pull * 8 == pytest.approx(round(pull * 8), abs=1e-12)   # whole 1/8 steps
    assert np.array_equal(part[[0, 1, 2, 3, 5, 6, 7, 8, 9]], pts[[0, 1, 2, 3, 5, 6, 7, 8, 9]])


def test_sectors_scale_with_refine():
    assert [sectors_per_quarter(f) for f in (5.0, 2.0, 1.0, 0.8, 0.5)] == [1, 2, 3, 4, 6]


@pytest.fixture(scope="module")
def axisymmetric_build():
    design = filleted(reference_default(), 0.0).replace({"coupler.n_slots": 0, "coupler.n_teeth": 0,
                                                        "stack.bolt_diameter": 0.0})    # the references' design
    return design, *build(design, mesher="revolve")


def test_swept_mesh_volumes_groups_and_quality(axisymmetric_build):
    design, tm, rep = axisymmetric_build
    volumes, _ = mesh_part_volumes(tm)
    for part, v in design.part_volumes().items():
        # quadratic arcs over 30 degrees hold a circle's area to ~1.5e-4; the free coupler: a few
        # elements straightened at its bore next to the first ring
        assert volumes[part] == pytest.approx(v, rel=1e-3 if part == "coupler" else 3e-4), part
    q = rep.quality
    assert q["n_inverted"] == 0 and q["swept_min_jacobian"] > 0.2
    assert q["swept_elements"] > 0.8 * tm.n_cells
    assert set(tm.facet_sets) == {"horn_tip", "teeth_tops", "flange"} | {f"electrode_{k}" for k in range(5)}
    # conformal: no duplicated node, the swept stack shares nodes with the free coupler
    keys = np.round(tm.points / 1e-9).astype(np.int64)
    assert len(np.unique(keys, axis=0)) == tm.n_points
    coupler = set(np.unique(tm.cells[tm.cells_in(part="coupler")]).tolist())
    stack = set(np.unique(tm.cells[tm.cells_in(part="stack")]).tolist())
    assert len(coupler & stack) > 50
    # each electrode's triangles cover its ring face: P1 chords of a 12-gon, area ratio 12 sin(30 deg) / (2 pi)
    r_in, r_out = design.stack.inner_diameter / 2, design.stack.outer_diameter / 2
    polygon = 12 * np.sin(np.pi / 6) / (2 * np.pi)
    for name in ("electrode_1", "electrode_2"):
        p = tm.points[tm.facet_sets[name]]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
        assert area == pytest.approx(polygon * np.pi * (r_out ** 2 - r_in ** 2), rel=1e-9), name


def test_working_mode_within_the_target_of_the_converged_answer(axisymmetric_build):
    _design, tm, _rep = axisymmetric_build
    system = fem.assemble(tm)
    res = fem.modal_analysis(system, 20e3, 8)
    w = fem.working_mode(system, res.f_r_hz, res.vectors, 20e3)
    f_r, f_a = float(res.f_r_hz[w]), float(res.f_a_hz[w])
    assert abs(f_r / AXISYM_CONVERGED[0] - 1) < TOL_REVOLVE, f_r
    assert abs(f_a / AXISYM_CONVERGED[1] - 1) < TOL_REVOLVE, f_a
    # the two-level estimator on the swept mesh (one solve at refine 1.4, order 2 of a graded
    # mesh) bounds the true error and stays within 4x of it (measured 19 / 24 Hz against 8.1 / 9.5 Hz)
    from fem.errors import estimate

    est = estimate(_design, {"f_r_hz": f_r, "f_a_hz": f_a}, system.ndof, harmonic=False, n_modes=8,
                   mesher="revolve")
    for key, value, exact in (("f_r_hz", f_r, AXISYM_CONVERGED[0]), ("f_a_hz", f_a, AXISYM_CONVERGED[1])):
        assert abs(value - exact) <= est.error(key) <= 4 * abs(value - exact), (key, est.error(key))


def test_bending_and_torsion_against_the_converged_harmonics(axisymmetric_build):
    """The swept mesh's non-axisymmetric modes against the (r, z) harmonics n = 1 / n = 0
    (tests/axisym_reference.py, converged to ~1e-5): stiff (too high) and within TOL_BENDING /
    TOL_TORSION. Measured +0.194 % / +0.128 % (first / second bending pair), +0.069 % (torsion):
    the 0.1 % aimed for holds for torsion, not for the bending pairs (3 sectors per quarter and the
    horn's 6.3 mm section size; see README, "true errors")."""
    _design, tm, _rep = axisymmetric_build
    res = fem.modal_analysis(fem.assemble(tm), 8e3, 12)
    f = np.asarray(res.f_r_hz)
    bend = np.sort(f[[k for k, lab in enumerate(res.labels) if lab == "bending"]])
    tors = np.sort(f[[k for k, lab in enumerate(res.labels) if lab == "torsional"]])
    assert len(bend) >= 4 and len(tors) >= 1, res.labels
    assert bend[1] / bend[0] - 1 < 1e-4 and bend[3] / bend[2] - 1 < 1e-4          # degenerate pairs
    for value, ref, tol in ((bend[:2].mean(), ar.BENDING_19[0], TOL_BENDING),
                            (bend[2:4].mean(), ar.BENDING_19[1], TOL_BENDING),
                            (tors[0], ar.TORSION_19, TOL_TORSION)):
        assert 0 < value / ref - 1 < tol, (value, ref)


def test_revolve_refuses_a_loft_horn_in_one_line():
    design = article_design().replace({"horn.profile": "exponential"})
    with pytest.raises(ParameterError, match="--mesher.*stepped or conical"):
        build(design, mesher="revolve")
    with pytest.raises(ParameterError, match="--mesher"):
        build(article_design(), mesher="swept")


def test_matching_on_the_swept_mesh_agrees_with_a_fresh_mesh_of_the_tuned_design(tmp_path):
    """``--match --mesher revolve`` (refused before: scikit-fem's facet basis stalled on the swept
    flange, fem.facets): the tuned design meshed afresh, not morphed, resonates at the target too.
    Measured at refine 2: 20 001.3 Hz against 20 000.0 (6.5e-5)."""
    import json
    import subprocess
    import sys

    out = tmp_path / "m.json"
    r = subprocess.run([sys.executable, "-m", "fem.modal", "--mesher", "revolve", "--match", "--refine", "2",
                        "--error", "--json", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    m = json.loads(out.read_text())
    assert m["mesher"] == "revolve" and m["converged"]
    # the error estimate's coarse mesh is swept too (order 2; a free one would assume order 1 here)
    assert "order 2" in m["discretisation_error"]["method"], m["discretisation_error"]["method"]
    assert m["matched_hz"] == pytest.approx(20e3, rel=2e-4)
    assert 0 < abs(m["flange_to_tip_axial_ratio"]) < 0.25                    # the flange facets integrate
    tuned = tmp_path / "rpud-default-tuned.toml"
    r = subprocess.run([sys.executable, "-m", "fem.modal", "--design", str(tuned), "--mesher", "revolve",
                        "--sectors", "off", "--refine", "2", "--modes", "4", "--json", str(tmp_path / "fresh.json")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    fresh = json.loads((tmp_path / "fresh.json").read_text())
    f_fresh = next(x["f_r_hz"] for x in fresh["modes"] if x["label"] == "longitudinal")
    assert f_fresh == pytest.approx(20e3, rel=5e-4)


def test_auto_mesher_sweeps_what_it_can_and_studies_mesh_freely():
    """The command lines' default: swept for a stepped/conical RPUD, free for any other design
    and under --match (the matching meshes freely unless --mesher revolve); the library stays free."""
    import argparse
    import inspect

    from geometry.design import load_design
    from geometry.options import add_design_options, mesh_options
    from geometry.revolve import resolve_mesher

    parser = add_design_options(argparse.ArgumentParser(), include=("refine", "grade", "mesher"))
    ns = parser.parse_args([])
    assert ns.mesher == "auto"
    rpud, cone = article_design(), article_design().replace({"horn.profile": "conical"})
    loft = article_design().replace({"horn.profile": "exponential"})
    stack = load_design(Path(__file__).resolve().parents[1] / "geometry" / "examples.toml", select="langevin")
    assert mesh_options(ns, rpud)["mesher"] == mesh_options(ns, cone)["mesher"] == "revolve"
    assert "mesher" not in mesh_options(ns, loft) and "mesher" not in mesh_options(ns, stack)
    assert mesh_options(ns)["mesher"] == "auto" and resolve_mesher(stack, "auto") == "free"
    assert "mesher" not in mesh_options(argparse.Namespace(mesher="auto", match=True), rpud)
    # python -m results matches unless --no-match: auto is free there too
    assert "mesher" not in mesh_options(argparse.Namespace(mesher="auto", no_match=False), rpud)
    assert mesh_options(argparse.Namespace(mesher="auto", no_match=True), rpud)["mesher"] == "revolve"
    for study in ("converge", "error"):
        assert mesh_options(argparse.Namespace(mesher="auto", **{study: 1e-3}), rpud)["mesher"] == "revolve"
    assert inspect.signature(build).parameters["mesher"].default == "free"
